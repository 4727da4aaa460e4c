"""Render a scenario open-loop (no controller) into frames plus ground truth, and write it to disk."""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Iterator
from dataclasses import asdict
from pathlib import Path

import cv2
import numpy as np

from hvs_sim.errors import OutputError
from hvs_sim.manifest import record
from hvs_sim.outputs import settle, temporary_beside, write_atomic, write_image, write_with
from hvs_sim.render.renderer import Renderer
from hvs_sim.render.truth import GroundTruth
from hvs_sim.scene.scenarios import Scenario
from hvs_sim.scene.world import Scene


def iterate_sequence(scenario: Scenario, n_frames: int | None = None, occlusion: bool = True,
                     rgb: bool = True, on_start=None) -> Iterator[tuple[np.ndarray | None, GroundTruth]]:
    """Yield (RGB frame or None, ground truth) per frame; the arm, if any, holds its start pose. `on_start(scene)`
    is called once the scene is built (what a writer needs of it, e.g. the arm's joint names)."""
    scene = Scene(scenario)
    renderer = Renderer(scene)
    if on_start is not None:
        on_start(scene)
    for i in range(scenario.n_frames if n_frames is None else n_frames):
        if i:
            scene.advance()
        yield (renderer.rgb() if rgb else None), renderer.ground_truth(occlusion=occlusion)


def render_sequence(scenario: Scenario, n_frames: int | None = None, progress: bool = False) -> tuple[np.ndarray, list[GroundTruth]]:
    """All frames as one (N, H, W, 3) array and the list of ground truths."""
    from tqdm.auto import tqdm

    total = scenario.n_frames if n_frames is None else n_frames
    frames, gts = [], []
    for frame, gt in tqdm(iterate_sequence(scenario, n_frames), total=total, disable=not progress,
                          desc=f"render {scenario.name}/{scenario.mount}", unit="frame"):
        frames.append(frame)
        gts.append(gt)
    return np.stack(frames), gts


def _json_safe(value):
    """Strict JSON: infinities (e.g. an ideal sensor's `white_e`) become null."""
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def write_sequence(scenario: Scenario, out_dir: Path, fmt: str = "mp4", n_frames: int | None = None,
                   progress: bool = True, on_frame=None, on_start=None) -> dict:
    """Write frames (mp4 or PNGs) and ground_truth.csv / .npz / scenario.json into out_dir, each file whole (written
    under a temporary name, renamed into place): a render that fails or is interrupted leaves no half video.
    `on_start(scene)` and `on_frame(frame, gt)` (iterate_sequence) let the CLI write a ROS 2 bag beside them."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    total = scenario.n_frames if n_frames is None else n_frames
    cam = scenario.camera
    writer = None
    if fmt == "mp4":
        from hvs_sim.videoio import Mp4Writer

        video_tmp = temporary_beside(out_dir / "frames.mp4")  # renamed into place once every frame is in it
        writer = Mp4Writer(video_tmp, scenario.fps, (cam.width, cam.height), shown=out_dir / "frames.mp4")
    else:
        (out_dir / "frames").mkdir(exist_ok=True)
    rows: list[dict] = []
    cams: list[np.ndarray] = []
    joints: list[np.ndarray] = []
    corners: list[np.ndarray] = []
    done = interrupted = False
    try:
        _render_frames(scenario, total, progress, writer, out_dir, rows, cams, joints, corners, on_frame, on_start)
        done = True
    except KeyboardInterrupt:  # Ctrl-C or SIGTERM: the frames rendered so far are kept, with their ground truth
        if not rows:
            raise
        done = interrupted = True
    finally:
        if writer is None:  # the PNGs written whole, in one manifest update rather than one a frame
            record(out_dir / "frames" / f"{i:05d}.png" for i in range(len(rows)))
        if writer is not None:
            closed = False
            try:
                writer.close()
                closed = True
            finally:  # a video whose render or close failed is removed, never renamed into place
                settle(video_tmp, out_dir / "frames.mp4", keep=done and closed)
    _write_ground_truth(scenario, out_dir, rows, cams, joints, corners)
    meta = {"scenario": _json_safe(asdict(scenario)), "frames": len(rows), "format": fmt,
            "peak_occlusion": float(max(r["occlusion"] for r in rows)), "interrupted": interrupted}
    write_atomic(out_dir / "scenario.json", json.dumps(meta, indent=2, allow_nan=False))
    if interrupted:
        raise KeyboardInterrupt
    return meta


def _render_frames(scenario, total, progress, writer, out_dir, rows, cams, joints, corners, on_frame=None,
                   on_start=None) -> None:
    from tqdm.auto import tqdm

    for frame, gt in tqdm(iterate_sequence(scenario, total, on_start=on_start), total=total, disable=not progress,
                          desc=f"render {scenario.name}/{scenario.mount}", unit="frame"):
        if writer is not None:
            writer.write(frame)
        else:
            path = out_dir / "frames" / f"{gt.frame:05d}.png"
            try:  # whole or not at all: a frame the disk could not hold is not left truncated
                write_image(path, cv2.cvtColor(frame, cv2.COLOR_RGB2BGR), recorded=True)
            except OutputError as exc:
                raise OutputError(f"{exc}; frames 0 to {gt.frame - 1} are written whole" if gt.frame else str(exc)) \
                    from None
        if on_frame is not None:
            on_frame(frame, gt)
        rows.append(gt.as_row())
        cams.append(gt.camera.matrix())
        joints.append(gt.joint_positions)
        corners.append(gt.corners)


def _write_ground_truth(scenario, out_dir, rows, cams, joints, corners) -> None:
    """ground_truth.csv and ground_truth.npz, each written whole under a temporary name and renamed into place."""
    import io

    with io.StringIO(newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
        write_atomic(out_dir / "ground_truth.csv", f.getvalue())
    write_with(out_dir / "ground_truth.npz", lambda tmp: np.savez_compressed(
            tmp, time=np.array([r["time"] for r in rows]),
            center=np.array([[r["cx"], r["cy"]] for r in rows]), corners=np.array(corners),
            occlusion=np.array([r["occlusion"] for r in rows]), camera_pose=np.array(cams),
            joint_positions=np.array(joints), K=Renderer.intrinsics_of(scenario),
            distortion=np.array(scenario.camera.sensor.distortion)))
