"""Which files in a folder hvs_sim wrote: a hidden manifest (MANIFEST_NAME) in each folder it writes into, so that an
--overwrite removes only those (never by a name pattern, never through a link, never an input of the command).

Apart from outputs.py (checking output paths and writing files whole) because it is the record the writers keep and
--overwrite reads, with its own lock against other hvs_sim processes; it writes nothing but the manifest itself.
"""

from __future__ import annotations

import contextlib
import json
import os
from pathlib import Path

MANIFEST_NAME = ".hvs_sim-outputs"  # in each folder hvs_sim writes into: the files it wrote there (JSON; no .json
# suffix, so that a glob of a folder's *.json, e.g. a sweep's tasks, does not meet it)
MANIFEST_VERSION = 1


def _manifest_path(folder) -> Path:
    return Path(folder) / MANIFEST_NAME


def manifest_files(folder) -> set[str]:
    """The files (relative to `folder`) hvs_sim recorded writing there; an unreadable manifest lists none."""
    p = _manifest_path(folder)
    if p.is_symlink() or not p.is_file():
        return set()
    try:
        data = json.loads(p.read_text())
    except (OSError, ValueError):
        return set()
    files = data.get("files") if isinstance(data, dict) else None
    return {f for f in files if isinstance(f, str)} if isinstance(files, list) else set()


@contextlib.contextmanager
def _locked(folder: Path):
    """The folder locked against other hvs_sim processes updating its manifest (flock on the folder itself)."""
    import fcntl

    fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)


def _update_manifest(folder: Path, add=(), remove=()) -> None:
    with _locked(folder):
        files = (manifest_files(folder) | set(add)) - set(remove)
        target = _manifest_path(folder)
        if target.is_symlink():
            target.unlink()
        tmp = folder / f".{MANIFEST_NAME}.{os.getpid()}.tmp"
        try:
            tmp.write_text(json.dumps({"tool": "hvs_sim", "version": MANIFEST_VERSION, "files": sorted(files)},
                                      indent=1))
            os.replace(tmp, target)
        except OSError as exc:  # the outputs themselves are whole: an unlisted one is only never removed (safe)
            tmp.unlink(missing_ok=True)
            import sys

            print(f"hvs-sim: warning: could not update {target} ({exc.strerror or exc}); hvs_sim's files there are "
                  "not listed, so a later --overwrite leaves them in place", file=sys.stderr)


def record(paths) -> None:
    """Note in each file's folder that hvs_sim wrote it (once it is whole there), so that a later --overwrite may
    remove it."""
    by_folder: dict[Path, list[str]] = {}
    for p in paths:
        p = Path(p).absolute()
        by_folder.setdefault(p.parent, []).append(p.name)
    for folder, names in by_folder.items():
        if folder.is_dir():
            _update_manifest(folder, add=names)


def written_by_hvs_sim(path) -> bool:
    p = Path(path).absolute()
    return p.name in manifest_files(p.parent)


def clear_written(out, inputs=()) -> list[Path]:
    """Remove the regular files hvs_sim's manifests in `out` (and its sub-folders' manifests, not through links)
    list, except inputs of this command; returns what was removed. Nothing else is touched."""
    out = Path(out).absolute()
    ins = [Path(p).resolve() for p in inputs]
    removed = []
    for folder in [out, *_subfolders(out)]:
        names = manifest_files(folder)
        gone = []
        for name in sorted(names):
            p = folder / name
            if "/" in name or name in ("", ".", "..") or not p.exists() or p.is_symlink() or not p.is_file():
                gone.append(name)
                continue
            real = p.resolve()
            if any(real == i or i in real.parents for i in ins):
                continue  # an input of this command: kept (and still listed)
            p.unlink()
            removed.append(p)
            gone.append(name)
        if gone:
            _update_manifest(folder, remove=gone)
    return removed


def _subfolders(out: Path) -> list[Path]:
    """The real folders below `out` (no link followed) that hold a manifest."""
    found = []
    for root, dirs, files in os.walk(out, followlinks=False):
        dirs[:] = [d for d in dirs if not (Path(root) / d).is_symlink()]
        if Path(root) != out and MANIFEST_NAME in files:
            found.append(Path(root))
    return found
