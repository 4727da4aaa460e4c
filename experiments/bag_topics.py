"""What a ROS 2 bag of a run holds, as `ros2 bag info` would list it: the stand-in for a viewer's screenshot, since
Foxglove's web app (and rviz) cannot run headless on this machine.

    python experiments/bag_topics.py --out experiments/results/bag_topics

Runs `hvs-sim run --scenario walk_by --tracker hybrid --steps 90 --mcap OUT/run_bag` and `hvs-sim scene --scenario
walk_by --mount arm --frames 90 --mcap OUT/scene_bag` (640×480), reads both back with rosbags and writes topics.md:
per topic its message type, count, rate on the simulation clock, and one message's fields.
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
from pathlib import Path

import numpy as np


def _listing(bag: Path) -> list[str]:
    from rosbags.highlevel import AnyReader

    files = ", ".join(sorted(p.name for p in bag.iterdir()))
    size = sum(p.stat().st_size for p in bag.iterdir()) / 1e6
    lines = [f"### `{bag.name}/` ({files}; {size:.1f} MB)", "",
             "| topic | type | messages | rate (Hz, sim clock) | first message |", "|---|---|---|---|---|"]
    with AnyReader([bag]) as reader:
        stamps: dict[str, list[int]] = {}
        first = {}
        for conn, ns, raw in reader.messages():
            stamps.setdefault(conn.topic, []).append(ns)
            if conn.topic not in first:
                first[conn.topic] = _describe(reader.deserialize(raw, conn.msgtype))
        for conn in sorted(reader.connections, key=lambda c: c.topic):
            t = np.asarray(stamps.get(conn.topic, []), float) / 1e9
            rate = f"{(len(t) - 1) / (t[-1] - t[0]):.1f}" if len(t) > 1 and t[-1] > t[0] else "–"
            lines.append(f"| `{conn.topic}` | `{conn.msgtype}` | {len(t)} | {rate} | {first.get(conn.topic, '')} |")
    return [*lines, ""]


def _describe(msg) -> str:
    """A short account of one message: its fields, arrays by shape."""
    parts = []
    for name in getattr(msg, "__dataclass_fields__", {}):
        if name.startswith("__"):  # rosbags' own bookkeeping (the type name, in the table already)
            continue
        v = getattr(msg, name)
        if name == "header":
            parts.append(f"frame_id={v.frame_id!r}")
        elif isinstance(v, np.ndarray):
            parts.append(f"{name}[{v.size}]")
        elif isinstance(v, (str, int, float)):
            parts.append(f"{name}={v!r}"[:40])
        elif isinstance(v, list):
            parts.append(f"{name}[{len(v)}]")
        else:
            parts.append(name)
    return ", ".join(parts)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="out/bag_topics")
    args = ap.parse_args()
    from hvs_sim.cli import main as hvs
    from hvs_sim.outputs import write_atomic

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        run_bag, scene_bag = Path(tmp) / "run_bag", Path(tmp) / "scene_bag"
        commands = [["run", "--scenario", "walk_by", "--tracker", "hybrid", "--steps", "90", "--mcap", str(run_bag)],
                    ["scene", "--scenario", "walk_by", "--mount", "arm", "--frames", "90", "--out",
                     str(Path(tmp) / "scene"), "--mcap", str(scene_bag)]]
        for cmd in commands:
            if hvs(cmd) != 0:
                raise SystemExit(f"hvs-sim {' '.join(cmd)} failed")
        text = ["# What a ROS 2 bag of hvs_sim holds", "",
                "Made by `python experiments/bag_topics.py`; the bags themselves are not kept (a few MB each). Commands:",
                "", *[f"- `hvs-sim {' '.join(c).replace(tmp + '/', '')}`" for c in commands], "",
                *_listing(run_bag), *_listing(scene_bag)]
        shutil.rmtree(Path(tmp) / "scene", ignore_errors=True)
    write_atomic(out / "topics.md", "\n".join(text))
    print("\n".join(text))


if __name__ == "__main__":
    main()
