"""Run a tracker on your own footage: a video file or a folder of images.

  hvs-sim track PATH --roi x,y,w,h [--start N] [--end M] [--tracker hybrid] [--target auto] [--out DIR]
                [--rrd FILE]

PATH is a video file OpenCV can read, or a folder of images (.png .jpg .jpeg .bmp .tif .tiff,
sorted by file name; other files are ignored; every image must have the size of the first).

Frames are numbered from 0 in the clip. --start N --end M track frames N to M-1 (M exclusive, as a
Python slice); the first tracked frame is N, and the ROI is given in it.

Conventions: pixel centres sit at integer coordinates. The ROI (x, y, w, h) is given in the first
tracked frame and covers pixels x..x+w-1 and y..y+h-1; its centre is (x + (w - 1)/2, y + (h - 1)/2). The
corners are the ROI's outer pixel edges (x - 0.5, y - 0.5) ... under the tracked warp, in the order
top-left, top-right, bottom-right, bottom-left. The pose (tx, ty, theta, scale) is relative to the
ROI at the first frame (theta in radians; positive turns clockwise on screen, as y points down).

Outputs in DIR (default out/track):
  track.csv      one row per frame: frame, cx, cy, tx, ty, theta, scale, mode, occlusion, score, ms
                 (frame: the clip's frame number, N and on with --start N). The first row is the first
                 tracked frame, where the tracker takes its template: its mode is "init",
                 its pose the identity and its ms the time init() took. Later rows have the tracker's
                 mode (align, predict or lost) and ms is the wall time of that update.
  annotated.mp4  the frames with the tracked outline and centre, coloured by mode (init white,
                 align green, predict amber, lost red), at the source's fps (30 for a folder).
  FILE (--rrd)   a rerun recording: the image, the tracked outline and centre, and per-frame plots of
                 occlusion, score, ms and mode. Open it with `rerun FILE`.

What the target does (--target, the hybrid trackers): `static` when it is fixed in the scene (the
surroundings' motion is its motion, and a far jump of the match must be verified), `moving` when it
moves on its own (a confident match is never vetoed, gaps are extrapolated from its own motion), or
`auto` (the default): moving for the first aligned frames, then whichever the target's offset from its
surroundings' motion says; the summary says which was chosen. A scene cut ends in `lost` at the cut.

Bad input (missing path, unreadable video or image, a folder without images, images of different
sizes, a malformed or out-of-frame ROI, an unknown tracker, an output folder that cannot be written)
stops with a message and exit status 2; outputs of a run that failed part-way are removed. Ctrl-C
stops cleanly: the frames tracked so far are kept (CSV and video closed) and the exit status is 130.
"""

# The `hvs-sim track` command: its options and its exit codes. The work is hvs_sim/video.py's `track_footage`; this
# module's docstring is the command's --help.

from __future__ import annotations

import argparse
import sys

from hvs_sim.cliargs import DEFAULT_TRACKER, add_settings_option, parse_settings
from hvs_sim.framesource import IMAGE_SUFFIXES
from hvs_sim.tracking import TRACKER_NAMES
from hvs_sim.tracking.frames import MIN_ROI
from hvs_sim.video import track_footage

EXIT_INTERRUPTED = 130  # the shell's convention for a process stopped by SIGINT


def add_track_parser(sub) -> None:
    """Register `hvs-sim track` on the CLI's subparsers."""
    p = sub.add_parser("track", help="run a tracker on your own video file or folder of images",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("path", help=f"a video file OpenCV can read, or a folder of images ({' '.join(IMAGE_SUFFIXES)})")
    p.add_argument("--roi", required=True, metavar="x,y,w,h", help="the target in the first tracked frame (frame N "
                   "with --start N), integers: covers "
                   f"pixels x..x+w-1, y..y+h-1, centre (x + (w-1)/2, y + (h-1)/2); at least {MIN_ROI}×{MIN_ROI}")
    p.add_argument("--start", type=int, default=0, metavar="N",
                   help="the first frame to track, numbered from 0 in the clip (default 0); the ROI is in this frame")
    p.add_argument("--end", type=int, default=None, metavar="M",
                   help="stop before frame M: frames N..M-1 are tracked (M exclusive; default: to the clip's end)")
    p.add_argument("--tracker", default=DEFAULT_TRACKER, metavar="NAME",
                   help=f"one of: {', '.join(TRACKER_NAMES)} (default {DEFAULT_TRACKER}); or an outside tracker: a "
                        "registered or entry-point name, package.module:callable or path/to/file.py:callable")
    p.add_argument("--out", default="out/track", metavar="DIR",
                   help="folder for track.csv and annotated.mp4, created when missing (default out/track)")
    p.add_argument("--rrd", default=None, metavar="FILE", help="also save a rerun recording here")
    p.add_argument("--mcap", default=None, metavar="DIR", help="also write a ROS 2 bag (MCAP) into this new folder: "
                   "the frames, the tracked corners and the mode")
    p.add_argument("--target", choices=("static", "moving", "auto"), default=None,
                   help="what the target does, for the hybrid trackers: static (fixed in the scene: the surroundings' "
                        "motion is its motion), moving (it moves on its own), or auto (default: chosen from the first "
                        "aligned frames, and said in the summary)")
    p.add_argument("--overwrite", action="store_true",
                   help="track into a non-empty --out (its track.csv and annotated.mp4 are replaced when the run ends)")
    add_settings_option(p)
    p.set_defaults(func=cmd_track)


def cmd_track(args) -> int:
    from hvs_sim.cli.common import stop_reason

    try:
        result = track_footage(args.path, args.roi, args.tracker, args.out, args.rrd,
                               settings=parse_settings(args.set), overwrite=args.overwrite, target=args.target,
                               mcap=args.mcap, start=args.start, end=args.end)
    except KeyboardInterrupt:  # before the first frame was tracked: nothing was written
        print(f"hvs-sim: {stop_reason()} before tracking started; nothing written", file=sys.stderr)
        return EXIT_INTERRUPTED
    print(result.summary())
    if result.interrupted:
        print(f"hvs-sim: {stop_reason()}; the frames tracked so far are kept", file=sys.stderr)
        return EXIT_INTERRUPTED
    return 0
