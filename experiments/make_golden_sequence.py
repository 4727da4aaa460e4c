"""Write the hybrid's golden regression sequence: a short stretch of hand-held `pause` (the person
walks in, fills most of the view, leaves), its ground-truth track,
and the hybrid's per-frame error on it. tests/test_golden.py holds every later hybrid to that
envelope, so a change that alters the tracker's behaviour shows up as a failing test.

    python experiments/make_golden_sequence.py     # → tests/data/golden_pause.mp4 + golden_pause.npz
    python experiments/make_golden_sequence.py --envelope-only   # the error again, on the committed video

Frames (clean renders) are stored as an MPEG-4 video so that the file stays small; the test decodes
the same file, so what it tracks is exactly what the envelope was measured on. Re-run this (and say why in
the commit) only when a change to the hybrid is meant to change its behaviour.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np
import torch

from hvs_sim.bench.sequences import make_sequence
from hvs_sim.outputs import settle, temporary_beside
from hvs_sim.render.camera import transfer_points
from hvs_sim.scene.scenarios import CameraConfig, make_scenario
from hvs_sim.tracking import make_tracker
from hvs_sim.tracking.frames import roi_center, roi_from_corners

SCENARIO, SEED = "pause", 101  # a benchmark seed whose person fills the view: every path of the hybrid runs
FIRST, COUNT = 45, 95  # the frames kept: before the person arrives to after they leave
CROP = (slice(0, 480), slice(0, 640))  # the whole view: the scene-motion path needs the wall around the target
CAMERA = "ideal"  # the codec adds its own artefacts; sensor noise would only cost bytes


def write_video(frames: np.ndarray, path: Path) -> None:
    """MPEG-4 (OpenCV's bundled encoder): a tenth of the size of JPEG frames, with real codec artefacts."""
    h, w = frames.shape[1:3]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, (w, h))
    for f in frames:
        writer.write(cv2.cvtColor(f, cv2.COLOR_RGB2BGR))
    writer.release()


def decode(path: Path) -> np.ndarray:
    """The video's frames as (N, H, W, 3) uint8 RGB."""
    cap = cv2.VideoCapture(str(path))
    frames = []
    while True:
        ok, f = cap.read()
        if not ok:
            break
        frames.append(cv2.cvtColor(f, cv2.COLOR_BGR2RGB))
    cap.release()
    return np.stack(frames)


def track_errors(frames: np.ndarray, roi, gt: np.ndarray) -> tuple[np.ndarray, list[str]]:
    torch.set_num_threads(1)
    tracker = make_tracker("hybrid")
    tracker.init(frames[0], roi)
    err, modes = [0.0], ["init"]
    for k in range(1, len(frames)):
        tk = tracker.update(frames[k])
        err.append(float(np.linalg.norm(tk.center - gt[k])))
        modes.append(str(tk.mode))
    return np.array(err), modes


def save(path: Path, **arrays) -> None:
    """The envelope file written whole: under a temporary name, renamed into place when complete."""
    tmp, done = temporary_beside(path), False
    try:
        np.savez_compressed(tmp, **arrays)
        done = True
    finally:
        settle(tmp, path, keep=done)


def remeasure(path: Path) -> None:
    """The envelope written again for a hybrid meant to behave differently, on the very frames of the committed video."""
    g = np.load(path)
    frames = decode(path.parent / str(g["video"]))
    err, modes = track_errors(frames, tuple(int(v) for v in g["roi"]), g["gt"])
    kept = {k: g[k] for k in g.files if k not in ("error", "modes")}
    save(path, **kept, error=err, modes=np.array(modes))
    print(f"{path}: hybrid error median {np.median(err):.3f} px (was {np.median(g['error']):.3f}), max {err.max():.2f} "
          f"px (was {g['error'].max():.2f}), {int((err > 2).sum())} frames over 2 px (was {int((g['error'] > 2).sum())})")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="tests/data/golden_pause.npz")
    ap.add_argument("--envelope-only", action="store_true",
                    help="re-measure the hybrid's error on the committed video and keep everything else (no render: "
                         "the renderer's pixels may have moved since the video was made)")
    args = ap.parse_args()
    if args.envelope_only:
        remeasure(Path(args.out))
        return
    seq = make_sequence(make_scenario(SCENARIO, mount="handheld", seed=SEED, camera=CameraConfig(sensor=CAMERA)),
                        n_frames=FIRST + COUNT)
    rendered = seq.frames[FIRST:FIRST + COUNT][:, CROP[0], CROP[1]]
    video = Path(args.out).with_suffix(".mp4")
    write_video(rendered, video)
    frames = decode(video)
    # the ROI is the target's outline at the first kept frame; the truth is that ROI's centre carried on
    shift = np.array([CROP[1].start, CROP[0].start], float)  # full frame → crop pixels
    corners = seq.corners[FIRST:FIRST + COUNT]
    roi_full = roi_from_corners(corners[0])
    gt = np.array([transfer_points(corners[0], c, roi_center(roi_full)[None], seq.K, seq.distortion)[0] for c in corners])
    gt -= shift
    roi = (roi_full[0] - CROP[1].start, roi_full[1] - CROP[0].start, roi_full[2], roi_full[3])
    err, modes = track_errors(frames, roi, gt)
    occlusion = seq.occlusion[FIRST:FIRST + COUNT]
    save(Path(args.out), video=video.name, roi=np.array(roi), gt=gt, occlusion=occlusion, error=err,
         modes=np.array(modes), source=f"{SCENARIO} hand-held seed {SEED}, frames {FIRST}-{FIRST + COUNT - 1}")
    print(f"{video}: {len(frames)} frames, {video.stat().st_size / 1e6:.2f} MB; hybrid error median "
          f"{np.median(err):.3f} px, max {err.max():.2f} px, {int((err > 2).sum())} frames over 2 px; modes "
          f"{ {m: modes.count(m) for m in set(modes)} }; peak occlusion {occlusion.max():.2f}")


if __name__ == "__main__":
    main()
