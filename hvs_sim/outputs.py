"""Output paths are checked before any long work starts, so a bad path cannot cost a finished run."""

from __future__ import annotations

import tempfile
from pathlib import Path

from hvs_sim.errors import ConfigError, OutputError


def prepare_out_dir(out, flag: str = "--out") -> Path:
    """Create the output folder and prove it is writable."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ConfigError(f"{flag} {out} is a file; give a folder (it is created when missing)")
    try:
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=out):
            pass
    except OSError as exc:
        raise ConfigError(f"cannot write to the {flag} folder {out} ({exc.strerror or exc}); "
                          f"give a folder you can create and write to") from None
    return out


def check_output_file(path, flag: str) -> Path | None:
    """A file the run will write at its end: refuse a folder or an unwritable place now."""
    if path is None:
        return None
    path = Path(path)
    if path.is_dir():
        raise ConfigError(f"{flag} {path} is a folder; give a file name such as {path / ('run' + _suffix(flag))}")
    prepare_out_dir(path.parent, f"{flag}'s")
    return path


def _suffix(flag: str) -> str:
    return {"--json": ".json", "--rrd": ".rrd"}.get(flag, "")


def fresh_out_dir(out, overwrite: bool, outputs: tuple[str, ...], flag: str = "--out", clear: bool = True) -> Path:
    """An output folder for a new run: empty, or with --overwrite the files this command writes
    (glob patterns `outputs`) removed first (`clear`; a command that renames its outputs into place at the end
    leaves them until then), so no stale result stays beside new ones. Anything else in the folder is left alone."""
    out = prepare_out_dir(out, flag)
    entries = sorted(p.name for p in out.iterdir())
    if entries and not overwrite:
        shown = ", ".join(entries[:5]) + (", …" if len(entries) > 5 else "")
        raise ConfigError(f"{flag} {out} is not empty ({len(entries)} entries: {shown}); pass --overwrite to replace "
                          "this command's results there, or choose another folder")
    if overwrite and clear:
        for pattern in outputs:
            for p in out.glob(pattern):
                if p.is_file():
                    p.unlink()
    return out


def write_atomic(path, text: str) -> None:
    """Write through a temporary file in the same folder (named by this process), then rename: a reader never sees
    half a file, and an interrupted write leaves the old one."""
    path = Path(path)
    tmp = temporary_beside(path)
    try:
        tmp.write_text(text)
        settle(tmp, path, keep=True)
    except OSError as exc:  # a full disk, a folder gone: say which file, keep the one that was there
        raise OutputError(f"could not write {path} ({exc.strerror or exc}); "
                          + ("the previous complete file is kept" if path.exists() else "nothing was written")) from None
    finally:
        tmp.unlink(missing_ok=True)


def temporary_beside(path) -> Path:
    """A unique temporary name in `path`'s folder, with its suffix kept (writers such as OpenCV's pick the format
    from it), for a file renamed into place when complete (`os.replace`)."""
    import os

    path = Path(path)
    return path.with_name(f".{path.stem}.{os.getpid()}.tmp{path.suffix}")


def settle(tmp: Path, final, keep: bool) -> None:
    """A temporary written beside its target (temporary_beside; a file, or a folder such as a ROS 2 bag), renamed
    into place when `keep`, else removed."""
    import os
    import shutil

    if keep:
        os.replace(tmp, final)
    elif Path(tmp).is_dir() and not Path(tmp).is_symlink():
        shutil.rmtree(tmp, ignore_errors=True)
    else:
        Path(tmp).unlink(missing_ok=True)


def check_apart(inputs, outputs: dict[str, Path | None]) -> None:
    """Refuse, before any work, an output that is an input or lies inside an input folder, two outputs that are one
    file, and an output that exists and is not a regular file (a device, a FIFO, a folder). Paths are compared
    resolved (links followed)."""
    ins = [Path(p).resolve() for p in inputs]
    seen: dict[Path, str] = {}
    for what, path in outputs.items():
        if path is None:
            continue
        real = Path(path).resolve()
        if real.is_dir():
            raise ConfigError(f"{what} {path} is a folder; give a file name")
        if real.exists() and not real.is_file():
            raise ConfigError(f"{what} {path} exists and is not a regular file (a device, a pipe); give a new file name")
        for inp in ins:
            if real == inp or inp in real.parents:
                where = "is" if real == inp else "lies inside"
                raise ConfigError(f"{what} {path} {where} the input {inp}: an output may not overwrite or be written "
                                  "into what is read; give another path")
        if real in seen:
            raise ConfigError(f"{what} and {seen[real]} are one file ({path}); give each output its own path")
        seen[real] = what
