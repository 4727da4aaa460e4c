"""The one output layer every writer goes through, so that a command cannot lose what it did not write.

- Paths are checked before any long work (`prepare_out_dir`, `check_output_file`, `check_apart`,
  `check_replaceable`): no output is an input, none is written through a symbolic link, and a file hvs_sim did not
  write is not replaced unless the user named it or passed --overwrite.
- Each folder hvs_sim writes into keeps a hidden manifest (manifest.py) of the files hvs_sim wrote there; an
  --overwrite removes only those (never by a name pattern, never through a link, never an input).
- Every file is written under a temporary name and renamed into place when whole (`temporary_beside`, `settle`,
  `write_atomic`, `write_with`); a failed write (a full disk, a read-only disk, a name too long, no permission)
  becomes an `OutputError` that names the file, removes the partial temporary and says which outputs are complete.
- Native writers that could crash on a full disk (HDF5, FFmpeg) call `ensure_space` before each chunk.
"""

from __future__ import annotations

import contextlib
import errno
import os
import shutil
import tempfile
from pathlib import Path

from hvs_sim.errors import ConfigError, OutputError
from hvs_sim.manifest import MANIFEST_NAME, clear_written, record, written_by_hvs_sim

TEMPORARY_STEM, TEMPORARY_SUFFIX = 100, 20  # a temporary's name keeps this much of its target's: always a legal name
MIN_FREE_BYTES = 8 << 20  # a native writer stops before a chunk that would leave less than this free
OUTPUT_ERRNOS = frozenset({errno.ENOSPC, errno.EROFS, errno.ENAMETOOLONG, errno.EACCES, errno.EDQUOT, errno.EFBIG})

_completed: list[Path] = []  # the outputs this command settled, in order (what an error message says is complete)
_command: list[bool] = []  # non-empty while a CLI command runs (begin_command .. end_command): then the note is given
_pending: dict[Path, Path] = {}  # temporaries written and not yet settled → their final names (removed on failure)


# ---------------------------------------------------------------------------- the command's bookkeeping


def begin_command() -> None:
    """A new command: forget what an earlier one (in the same process) wrote."""
    _completed.clear()
    _pending.clear()
    _command[:] = [True]


def end_command() -> None:
    _command.clear()


def complete_note() -> str:
    """Which outputs of this command are whole on disk, for an error message (outside a command: nothing to say)."""
    if not _command:
        return ""
    if not _completed:
        return "no output of this command is complete"
    names = [str(p) for p in dict.fromkeys(_completed)]
    shown = ", ".join(names[:8]) + (f" and {len(names) - 8} more" if len(names) > 8 else "")
    return f"complete: {shown}"


def discard_pending() -> None:
    """Remove every temporary this command left unsettled (a write that failed part-way)."""
    for tmp in sorted(_pending, reverse=True):
        with contextlib.suppress(OSError):
            if tmp.is_dir() and not tmp.is_symlink():
                shutil.rmtree(tmp, ignore_errors=True)
            else:
                tmp.unlink(missing_ok=True)
    _pending.clear()


def shown_name(path) -> Path | None:
    """The file the user asked for, where `path` is one of this command's temporaries (temporary_beside)."""
    if path is None:
        return path
    return _pending.get(Path(path).absolute(), Path(path))


def output_error(path, exc: BaseException) -> OutputError:
    """An OSError (or a native writer's failure) while writing `path` (or its temporary) as the OutputError the user
    sees."""
    path = shown_name(path)
    why = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
    if getattr(exc, "errno", None) == errno.ENAMETOOLONG:
        why += f" (a file name may have at most {_name_max(path)} bytes)"
    try:
        there = "the previous complete file is kept" if Path(path).is_file() else "nothing was written there"
    except OSError:
        there = "nothing was written there"
    return OutputError("; ".join(filter(None, (f"could not write {path} ({why})", there, complete_note()))))


def is_output_failure(exc: BaseException) -> bool:
    """An OSError a write gets from a full, read-only or refusing file system (not a bug)."""
    return isinstance(exc, OSError) and getattr(exc, "errno", None) in OUTPUT_ERRNOS


def _name_max(path) -> int:
    folder = Path(path).parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    try:
        return os.pathconf(folder, "PC_NAME_MAX")
    except (OSError, ValueError):
        return 255


# ---------------------------------------------------------------------------- checks before any work


def _has_link_below(root: Path, path: Path) -> bool:
    """Whether a component of `path` from `root` down (root itself excluded) is a symbolic link."""
    root, path = Path(root).absolute(), Path(path).absolute()
    try:
        rel = path.relative_to(root)
    except ValueError:
        return False
    cur = root
    for part in rel.parts:
        cur = cur / part
        if cur.is_symlink():
            return True
    return False


def prepare_out_dir(out, flag: str = "--out") -> Path:
    """Create the output folder and prove it is writable."""
    if str(out).strip() == "":
        raise ConfigError(f"{flag} is empty; give a folder (it is created when missing)")
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
    """A file the run will write at its end: refuse a folder, a name too long, a link or an unwritable place now."""
    if path is None:
        return None
    if str(path).strip() == "":
        raise ConfigError(f"{flag} is empty; give a file name")
    path = Path(path)
    check_name_length(path, flag)
    if path.is_dir():
        raise ConfigError(f"{flag} {path} is a folder; give a file name such as {path / ('run' + _suffix(flag))}")
    prepare_out_dir(path.parent, f"{flag}'s")
    if path.is_symlink():
        raise ConfigError(f"{flag} {path} is a symbolic link; hvs_sim does not write through links: give a new name")
    return path


def check_name_length(path, flag: str) -> None:
    """A name the file system cannot hold (with the temporary's longer name beside it) is refused before the run."""
    limit = _name_max(path)
    length = len(os.fsencode(Path(path).name))
    if length > limit:
        raise ConfigError(f"{flag} {path}: the file name is too long ({length} bytes; this file system takes names "
                          f"up to {limit} bytes); give a shorter name")


def _suffix(flag: str) -> str:
    return {"--json": ".json", "--rrd": ".rrd"}.get(flag, "")


def check_replaceable(paths: dict[str, Path | None], overwrite: bool = False, root=None, hint: str = "") -> None:
    """Refuse, before any work, an output that exists and that hvs_sim did not write (a sidecar such as run's
    r_steps.csv, --figures' frames.png) unless `overwrite`; and always an output that is a symbolic link or lies in a
    linked folder below `root` (the --out the user chose; a folder such as scene's frames/ that hvs_sim writes into).
    `paths`: what each is, for the message → the path."""
    for what, path in paths.items():
        if path is None:
            continue
        path = Path(path)
        if path.is_symlink() or (root is not None and _has_link_below(Path(root), path.parent)):
            raise ConfigError(f"{what} {path} is or lies in a symbolic link; hvs_sim does not write through links (what "
                              "it points to would be replaced): remove the link or give another path")
        if path.exists() and not overwrite and not written_by_hvs_sim(path):
            raise ConfigError(f"{what} {path} exists and was not written by hvs_sim; move it away"
                              + (hint or ", or give another path") + " (nothing was written)")


def check_apart(inputs, outputs: dict[str, Path | None]) -> None:
    """Refuse, before any work, an output that is an input or lies inside an input folder, two outputs that are one
    file, one inside another, an output whose name is too long, and an output that exists and is not a regular file
    (a device, a FIFO, a folder). Paths are compared resolved (links followed)."""
    ins = [_resolve(p, "input") for p in inputs]
    seen: dict[Path, str] = {}
    for what, path in outputs.items():
        if path is None:
            continue
        check_name_length(path, what)
        real = _resolve(path, what)
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
        for other, other_what in seen.items():  # a new folder (a ROS 2 bag) cannot hold another output
            if other in real.parents or real in other.parents:
                inner, outer = (what, other_what) if other in real.parents else (other_what, what)
                raise ConfigError(f"{inner} would lie inside {outer} ({path}): a ROS 2 bag is a folder of its own; "
                                  "give each output its own path")
        seen[real] = what


def _resolve(path, what: str) -> Path:
    try:
        return Path(path).resolve()
    except (RuntimeError, OSError) as exc:  # a symlink loop
        raise ConfigError(f"{what} {path} cannot be resolved ({exc}); a symbolic link loop? give another path") from None


def fresh_out_dir(out, overwrite: bool, outputs: tuple[str, ...] = (), flag: str = "--out", clear: bool = True,
                  inputs=()) -> Path:
    """An output folder for a new run: empty, or with --overwrite the files an earlier hvs_sim command recorded
    writing there removed first (`clear`; a command that renames its outputs into place at the end leaves them
    until then), so no stale result stays beside new ones. Only files in the folder's manifests go, never by name
    pattern, never through a symbolic link, never an `inputs` path; anything else is left alone. `outputs` (the
    names, or folder/pattern, this command writes there): none may be a link or lie in a linked folder."""
    out = prepare_out_dir(out, flag)
    for name in outputs:
        target = out / name
        if any(c in target.name for c in "*?["):
            target = target.parent / "_"  # a pattern: its folder is what must not be a link
        check_replaceable({f"{flag}'s {name}": target}, overwrite=True, root=out)
    entries = sorted(p.name for p in out.iterdir() if p.name != MANIFEST_NAME)
    if entries and not overwrite:
        shown = ", ".join(entries[:5]) + (", …" if len(entries) > 5 else "")
        raise ConfigError(f"{flag} {out} is not empty ({len(entries)} entries: {shown}); pass --overwrite to replace "
                          "this command's results there, or choose another folder")
    if overwrite and clear:
        clear_written(out, inputs)
    return out


# ---------------------------------------------------------------------------- writing


def temporary_beside(path) -> Path:
    """A unique temporary name in `path`'s folder, with its suffix kept (writers such as OpenCV's pick the format
    from it), for a file renamed into place when complete (`os.replace`). It is removed if the command fails."""
    path = Path(path)
    tmp = path.with_name(f".{path.stem[:TEMPORARY_STEM]}.{os.getpid()}.tmp{path.suffix[:TEMPORARY_SUFFIX]}")
    _pending[tmp.absolute()] = path
    return tmp


def settle(tmp: Path, final, keep: bool, recorded: bool | None = False) -> None:
    """A temporary written beside its target (temporary_beside; a file, or a folder such as a ROS 2 bag), renamed
    into place when `keep` and recorded in the folder's manifest (`recorded`: True when the caller records a batch
    itself, None for a file hvs_sim manages without a manifest, such as a sweep's task records), else removed."""
    tmp, final = Path(tmp), Path(final)
    _pending.pop(tmp.absolute(), None)
    if keep:
        try:
            os.replace(tmp, final)
        except OSError as exc:
            _remove(tmp)
            raise output_error(final, exc) from None
        _completed.append(final)
        if recorded is False and not final.is_dir():  # a folder (a ROS 2 bag) is never removed, so not listed
            record([final])
    else:
        _remove(tmp)


def _remove(tmp: Path) -> None:
    if tmp.is_dir() and not tmp.is_symlink():
        shutil.rmtree(tmp, ignore_errors=True)
    else:
        tmp.unlink(missing_ok=True)


def write_atomic(path, text: str, recorded: bool | None = False) -> None:
    """Write through a temporary file in the same folder (named by this process), then rename: a reader never sees
    half a file, and an interrupted write leaves the old one (`recorded`: as settle's)."""
    path = Path(path)
    tmp = temporary_beside(path)
    with _settling(tmp, path):
        with open_output(tmp) as f:
            f.write(text)
        settle(tmp, path, keep=True, recorded=recorded)


@contextlib.contextmanager
def _settling(tmp: Path, path: Path):
    """The body writes `tmp` and settles it as `path`. On any failure, an interrupt included, the temporary goes
    (the file that was there is kept), and an OSError that is not an OutputError yet becomes one naming `path` (a
    full disk, a folder gone)."""
    try:
        yield
    except BaseException as exc:
        _pending.pop(tmp.absolute(), None)
        _remove(tmp)
        if isinstance(exc, OSError) and not isinstance(exc, OutputError):
            raise output_error(path, exc) from None
        raise


def write_with(path, write, need_bytes: int = 0) -> Path:
    """A file made by a library writer (`write(tmp)`: savefig, imwrite, savez, torch.save) under a temporary name,
    then renamed into place: a failure (an OSError, or a writer that returns False) is an OutputError naming `path`,
    with no partial file left."""
    path = Path(path)
    tmp = temporary_beside(path)
    with _settling(tmp, path):
        ensure_space(tmp, need_bytes, native=False)  # these writers are Python's: a full disk is their OSError
        ok = write(tmp)
        if ok is False or not tmp.exists():
            raise OSError(errno.EIO, "the writer could not write it (disk full or folder not writable?)", str(path))
        account(tmp, tmp.stat().st_size)
        settle(tmp, path, keep=True)
    return path


def save_figure(fig, path, **kwargs) -> Path:
    """A matplotlib figure written whole (write_with), in the format of `path`'s suffix."""
    fmt = Path(path).suffix.lstrip(".") or "png"
    return write_with(path, lambda tmp: fig.savefig(tmp, format=fmt, **kwargs))


def write_image(path, bgr, recorded: bool | None = False) -> Path:
    """An image (BGR, as OpenCV) encoded in memory and written whole by the layer: a full disk fails the write
    itself, never leaving a truncated image that the encoder reported as written."""
    import cv2

    path = Path(path)
    ok, data = cv2.imencode(path.suffix or ".png", bgr)
    if not ok:
        raise OutputError(f"could not encode {path} as {path.suffix or '.png'}")
    tmp = temporary_beside(path)
    with _settling(tmp, path):
        with open_output(tmp, "wb") as f:
            f.write(data.tobytes())
        settle(tmp, path, keep=True, recorded=recorded)
    return path


class _CountedFile:
    """A text or binary file whose every write first asks `ensure_space` (the fault-injection point of the tests)."""

    def __init__(self, f, path: Path):
        self._f, self._path = f, path

    def write(self, data):
        n = len(data.encode() if isinstance(data, str) else data)
        try:
            ensure_space(self._path, n, native=False)
            return self._f.write(data)
        except OSError as exc:
            if isinstance(exc, OutputError):
                raise
            raise output_error(self._path, exc) from None

    def close(self) -> None:
        """Close; the last buffered bytes meeting a full disk are an OutputError too."""
        try:
            self._f.close()
        except OSError as exc:
            raise output_error(self._path, exc) from None

    def __getattr__(self, name):
        return getattr(self._f, name)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


def open_output(path, mode: str = "w", **kwargs):
    """A file opened for writing by the layer (a temporary: see temporary_beside); never through a link."""
    path = Path(path)
    if path.is_symlink():
        raise ConfigError(f"{path} is a symbolic link; hvs_sim does not write through links")
    kwargs.setdefault("newline", "" if "b" not in mode else None)
    if "b" in mode:
        kwargs.pop("newline")
    return _CountedFile(open(path, mode, **kwargs), path)


def ensure_space(path, need_bytes: int, native: bool = True) -> None:
    """Before a native writer's next chunk (an FFmpeg frame, an HDF5 episode): fail cleanly with ENOSPC rather than
    let the library crash on a full disk. Python writes (`native` False) get the OS's own error instead."""
    if not native:
        return
    folder = Path(path).parent
    try:
        free = shutil.disk_usage(folder).free
    except OSError:
        return
    if free < need_bytes + MIN_FREE_BYTES:
        raise OSError(errno.ENOSPC, f"No space left on device (only {free // 1024} kB free, fewer than "
                                    f"{(need_bytes + MIN_FREE_BYTES) // 1024} kB for the next part)", str(path))


def account(path, nbytes: int) -> None:
    """Bytes a writer put on disk (a hook: the tests' full-disk fixture counts them)."""
