"""The hand-held photographs' dev split (../shared/devsets/handheld_photos.py) at another frame rate: a dev check,
run from the repository root like the dev split itself.

    python experiments/dev_framerate.py --fps 10 --frames 80 --method hybrid --seed 7 --no-ref

The same camera path in seconds and the same 12 ms exposure, sampled at `--fps`: at 10 fps the view moves 3× as far
between frames (up to ~19 px a frame) as at the dev split's 30 fps, as real hand-held footage at 10 fps does, and 80
frames cover the same 8 s (the occluders keep their timing in seconds). Every other option is the dev split's own,
and it prints the dev split's JSON line. The dev split is not part of this project: it is read from ../shared when
this runs, and its figures are dev figures, never test figures.
"""

from __future__ import annotations

import argparse
import sys
import types
from pathlib import Path

DEV_SPLIT = Path(__file__).resolve().parent.parent.parent / "shared" / "devsets" / "handheld_photos.py"
# the two lines of the dev split that set the frame rate and the exposure's share of a frame (12 ms of a 33 ms frame)
FPS_LINE, EXPOSURE_LINE = "FPS = 30.0", "exposure_frac = 0.36"
EXPOSURE_S = 0.012


def load(fps: float) -> types.ModuleType:
    """The dev split as a module, its frame rate set to `fps` and its exposure kept at EXPOSURE_S."""
    if not DEV_SPLIT.is_file():
        raise SystemExit(f"dev_framerate: the dev split is not at {DEV_SPLIT} (run from a checkout beside ../shared)")
    src = DEV_SPLIT.read_text()
    if FPS_LINE not in src or EXPOSURE_LINE not in src:
        raise SystemExit(f"dev_framerate: {DEV_SPLIT} no longer has the lines {FPS_LINE!r} and {EXPOSURE_LINE!r} "
                         "this check changes")
    src = src.replace(FPS_LINE, f"FPS = {fps!r}").replace(EXPOSURE_LINE, f"exposure_frac = {EXPOSURE_S * fps!r}")
    module = types.ModuleType("handheld_photos_dev")
    module.__file__ = str(DEV_SPLIT)
    exec(compile(src, str(DEV_SPLIT), "exec"), module.__dict__)  # noqa: S102 (the dev split, read as it is run)
    return module


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--fps", type=float, default=10.0, help="frames a second (the dev split's own: 30)")
    args, rest = ap.parse_known_args()
    if not 1.0 <= args.fps <= 240.0 or args.fps * EXPOSURE_S > 1.0:
        ap.error(f"--fps must be in [1, 240] with the 12 ms exposure within a frame, got {args.fps}")
    split = load(args.fps)
    sys.argv = [str(DEV_SPLIT), *rest]
    split.main()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
