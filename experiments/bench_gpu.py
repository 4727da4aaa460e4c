"""On a machine with an NVIDIA GPU: rendering through EGL on the GPU, the hybrid's networks on CUDA against the same
machine's CPU, and the demo's loop (walk_by on the arm, the hybrid, evaluation on, no recording) in steps/s with the
tracker on either, sequential and pipelined; one run, figures in a JSON file. The project never needs a GPU: this is
for the figures docs/results.md gives beside the CPU ones.

    MUJOCO_GL=egl PYOPENGL_PLATFORM=egl python experiments/bench_gpu.py experiments/results/gpu/h100.json

PYOPENGL_PLATFORM must be egl before anything imports OpenGL. The run behind experiments/results/gpu/h100.json was on
one H100 with 16 CPU cores (Python 3.12, torch 2.11 + CUDA 13), with mujoco 3.17.0, dm-control 1.0.50 and the
glvnd EGL loader (Debian's libegl1) installed beside NVIDIA's driver.
"""
import json
import os
import sys
import time
import traceback

import numpy as np

out_path = sys.argv[1] if len(sys.argv) > 1 else "experiments/results/gpu/gpu.json"
res = {"env": {"MUJOCO_GL": os.environ.get("MUJOCO_GL")}}


def save():
    with open(out_path + ".tmp", "w") as f:
        json.dump(res, f, indent=1)
    os.replace(out_path + ".tmp", out_path)


def part(name):
    """Run `fn` now and keep its result (or its error, so that one broken part leaves the others' figures)."""
    def deco(fn):
        t0 = time.perf_counter()
        try:
            res[name] = fn()
        except Exception as exc:  # noqa: BLE001 - record and go on: each part stands alone
            res[name] = {"error": f"{type(exc).__name__}: {exc}", "trace": traceback.format_exc()[-1500:]}
        res[name + "_wall_s"] = time.perf_counter() - t0
        print(name, json.dumps(res[name])[:600], flush=True)
        save()
    return deco


@part("devices")
def _():
    import torch
    from OpenGL import GL  # noqa: F401
    return {"torch": torch.__version__, "cuda": torch.cuda.is_available(),
            "gpu": torch.cuda.get_device_name(0) if torch.cuda.is_available() else None,
            "cpu_threads": torch.get_num_threads(), "cpus": os.cpu_count()}


@part("gl_vendor")
def _():
    from OpenGL import GL

    from hvs_sim.render.renderer import Renderer
    from hvs_sim.scene.scenarios import make_scenario
    from hvs_sim.scene.world import Scene
    r = Renderer(Scene(make_scenario("walk_by", mount="handheld", seed=0)))
    r.rgb()
    return {"vendor": GL.glGetString(GL.GL_VENDOR).decode(), "renderer": GL.glGetString(GL.GL_RENDERER).decode()}


@part("render")
def _():
    from hvs_sim.render.renderer import Renderer
    from hvs_sim.scene.scenarios import CameraConfig, make_scenario
    from hvs_sim.scene.world import Scene
    from hvs_sim.sensor import sensor_preset
    rows = {}
    for preset in ("ideal", "webcam", "phone_handheld", "robot_cell", "low_light"):
        scene = Scene(make_scenario("walk_by", mount="handheld", camera=CameraConfig(sensor=sensor_preset(preset))))
        r = Renderer(scene)
        ms, light, sensor = [], [], []
        for k in range(81):
            t = time.perf_counter()
            r.rgb()
            if k:
                ms.append(1e3 * (time.perf_counter() - t))
                light.append(r.stage_ms["light"])
                sensor.append(r.stage_ms["sensor"])
            scene.advance()
        rows[preset] = {"mean_ms": float(np.mean(ms)), "median_ms": float(np.median(ms)),
                        "light_ms": float(np.mean(light)), "sensor_ms": float(np.mean(sensor))}
    ideal = rows["ideal"]["mean_ms"]
    for p in rows.values():
        p["ratio_to_ideal"] = p["mean_ms"] / ideal
    rows["realistic_mean_ratio"] = float(np.mean([rows[p]["ratio_to_ideal"] for p in rows if p != "ideal"]))
    return rows


@part("tracker")
def _():
    from hvs_sim.render.renderer import Renderer
    from hvs_sim.scene.scenarios import make_scenario
    from hvs_sim.scene.world import Scene
    from hvs_sim.tracking import make_tracker
    from hvs_sim.tracking.frames import roi_from_corners
    scene = Scene(make_scenario("walk_by", mount="handheld", seed=0))
    r = Renderer(scene)
    frames = []
    for _ in range(151):
        frames.append((r.rgb(), r.ground_truth(occlusion=False).corners))
        scene.advance()
    roi = roi_from_corners(frames[0][1])
    rows = {}
    for warp in ("similarity", "homography"):
        for device in ("cpu", "cuda"):
            tr = make_tracker("hybrid", warp=warp, device=device)
            for _ in range(2):  # the second, warm, counts
                tr.init(frames[0][0], roi)
                ms = [tr.update(f).ms for f, _ in frames[1:]]
            rows[f"{warp}:{device}"] = {"median_ms": float(np.median(ms)), "mean_ms": float(np.mean(ms))}
    return rows


@part("loop")
def _():
    from hvs_sim.runner import run_episode
    from hvs_sim.scene.scenarios import make_scenario
    from hvs_sim.servo.config import LoopConfig
    rows = {}
    for device in ("cpu", "cuda"):
        for pipeline in (False, True):
            summary, recs = run_episode(make_scenario("walk_by", mount="arm", seed=0), "hybrid",
                                        LoopConfig(steps=240, evaluate=True, keep_frames=False, pipeline=pipeline),
                                        progress=False, keep_records=True, tracker_settings={"device": device})
            step = np.array([x.wall_ms for x in recs])
            rows[f"{device}:{'pipelined' if pipeline else 'sequential'}"] = {
                "steps_per_second": summary["steps_per_second"],
                "after_step0": float(1e3 / step[1:].mean()),
                "render_ms": summary["timing"]["render"]["mean_ms"], "track_ms": summary["timing"]["track"]["mean_ms"],
                "converged": summary["converged"], "final_error_px": summary["final_error_px"]}
    return rows


print("done", flush=True)
