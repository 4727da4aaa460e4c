"""The sensor's electronics alone (`SensorState.capture`: auto-exposure meter, noise, gain, the 12-bit ADC, the sRGB
curve, JPEG) of this package against an older package's, interleaved call by call on the same rendered light, so
that their ratio holds on a busy machine:

    git archive <old commit> hvs_sim | tar -x -C /tmp/before
    python experiments/bench_sensor.py --before /tmp/before/hvs_sim/camera_model.py \
        --json experiments/results/sensor_speed.json

The older sensor module (sensor.py; camera_model.py before its rename) is loaded from its path under another module
name (it imports only hvs_sim.errors). Each preset is timed with torch on 1 and on 2 threads (the older sensor's arithmetic ran in torch; the closed loop sets 2).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import sys
import time
from pathlib import Path

import numpy as np
import torch

from hvs_sim import sensor
from hvs_sim.render.renderer import Renderer
from hvs_sim.scene.scenarios import make_scenario
from hvs_sim.scene.world import Scene

LIGHT_FRAMES = (10, 40, 70, 95)  # walk_by hand-held frames whose light is captured (the person in view in the last)


def load_older(path: str):
    spec = importlib.util.spec_from_file_location("camera_model_before", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def lights() -> list[np.ndarray]:
    r = Renderer(Scene(make_scenario("walk_by", mount="handheld")))
    out = []
    for k in range(max(LIGHT_FRAMES) + 1):
        if k in LIGHT_FRAMES:
            out.append(sensor.decode(r.rgb()))
        r.scene.advance()
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--before", required=True, help="an older hvs_sim/sensor.py (hvs_sim/camera_model.py before its rename)")
    ap.add_argument("--calls", type=int, default=40, help="captures of each package per preset and thread count")
    ap.add_argument("--json", default="experiments/results/sensor_speed.json")
    args = ap.parse_args()
    before, light = load_older(args.before), lights()
    res = {"before": args.before, "calls": args.calls, "load_average_at_start": list(os.getloadavg()), "presets": {}}
    for threads in (1, 2):
        torch.set_num_threads(threads)
        for name in ("webcam", "phone_handheld", "robot_cell", "low_light"):
            states = {"before": before.SensorState(before.sensor_preset(name), 0, light[0].shape[:2]),
                      "after": sensor.SensorState(sensor.sensor_preset(name), 0, light[0].shape[:2])}
            ms = {k: [] for k in states}
            for call in range(args.calls):
                for label in (("before", "after") if call % 2 else ("after", "before")):
                    t = time.perf_counter()
                    states[label].capture(light[call % len(light)], call, call / 30, 1 / 30)
                    ms[label].append(1e3 * (time.perf_counter() - t))
            row = {k: {"median_ms": float(np.median(v)), "mean_ms": float(np.mean(v))} for k, v in ms.items()}
            row["after_over_before_median_of_pairs"] = float(np.median(np.divide(ms["after"], ms["before"])))
            res["presets"][f"{name}:torch{threads}"] = row
            print(f"{name:15s} torch threads {threads}: before {row['before']['median_ms']:.1f} ms, after "
                  f"{row['after']['median_ms']:.1f} ms (median), after/before pair by pair "
                  f"{row['after_over_before_median_of_pairs']:.2f}", flush=True)
    res["load_average_at_end"] = list(os.getloadavg())
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(res, indent=2))


if __name__ == "__main__":
    main()
