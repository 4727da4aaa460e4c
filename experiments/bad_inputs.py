"""Bad inputs across the public API, the CLI and the gym env, each classified: a clear error (an
HvsError, or exit 2 with a message), a raw traceback (any other exception), or silently accepted.

    python experiments/bad_inputs.py --json experiments/results/bad_inputs.json

The CLI's long work (benchmarks, episodes, rendering) is replaced by stubs, as in tests/test_fuzz.py,
so only the option handling runs. Targets: 0 raw tracebacks, 0 silent acceptances.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
import tempfile
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from hvs_sim.errors import HvsError

OUTCOMES = ("clear", "raw traceback", "silently accepted", "data lost", "hang")
HANG_S = 120  # a case that has not returned after this long counts as a hang


class _Hang(Exception):
    pass


def _snapshot(root: Path | None) -> dict:
    """Every regular file under root (the inputs a case could destroy) → its bytes' hash."""
    import hashlib

    if root is None:
        return {}
    return {p: hashlib.sha1(p.read_bytes()).hexdigest() for p in sorted(root.rglob("*")) if p.is_file()}


def _full_disk(where: Path) -> bool:
    """A 64 kB tmpfs at `where`, filled (unmounted at exit); False where mounting is not allowed (not root)."""
    import atexit
    import subprocess

    where.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(where)], capture_output=True,
                      check=False).returncode:
        return False
    atexit.register(subprocess.run, ["umount", "-l", str(where)], check=False)
    with contextlib.suppress(OSError), open(where / "filler", "wb") as f:
        for _ in range(64):
            f.write(b"\0" * 4096)
            f.flush()
    return True


def classify(fn, inputs: Path | None = None) -> tuple[str, str]:
    """clear / raw traceback / silently accepted; "data lost" when a file under `inputs` changed or vanished, "hang"
    when the case ran past HANG_S."""
    import signal

    err = io.StringIO()
    before = _snapshot(inputs)

    def on_alarm(signum, frame):
        raise _Hang()

    previous = signal.signal(signal.SIGALRM, on_alarm)
    signal.alarm(HANG_S)
    try:
        outcome = _classify(fn, err)
    except _Hang:
        outcome = ("hang", f"no answer after {HANG_S} s")
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    after = _snapshot(inputs)
    lost = [str(p) for p, h in before.items() if after.get(p) != h]
    return ("data lost", f"changed or removed: {', '.join(lost)[:100]}") if lost else outcome


def _classify(fn, err) -> tuple[str, str]:
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            out = fn()
    except _Hang:
        raise
    except HvsError as exc:
        return "clear", str(exc)[:120]
    except Exception as exc:  # noqa: BLE001 - what is being counted
        return "raw traceback", f"{type(exc).__name__}: {exc}"[:120]
    if isinstance(out, int) and out == 2 and err.getvalue().strip():
        return "clear", err.getvalue().strip().splitlines()[-1][:120]
    return "silently accepted", repr(out)[:120]


def tracker_cases():
    from hvs_sim.scene.textures import natural_texture
    from hvs_sim.tracking import make_tracker

    bad_settings = {
        "sift": [{"min_inliers": 0}, {"ransac_px": math.nan}, {"ratio": 2.0}, {"ratio": math.nan}, {"bogus": 1}],
        "ecc": [{"gauss": 4}, {"eps": -1.0}, {"iterations": 0}, {"iterations": 2.5}, {"bogus": 1}],
        "deep_lk": [{"tau_pix": -1}, {"margin": -5}, {"scale": 5.0}, {"match_threshold": math.nan},
                    {"reinit_px": math.inf}, {"max_scale_step": 0.0}, {"device": "tpu"}, {"weights": "/nope.npz"}],
        "hybrid": [{"occlusion_gate": 0.0}, {"max_predict_frames": 0}, {"reacquire_px": -1.0},
                   {"background_gate_px": math.nan}, {"predictor": "kalman"}, {"occlusion_gat": 0.3},
                   {"reacquire_frames": 0}, {"gru_weights": "/nope.pt"}],
        "hybrid_residual": [{"residual_weights": "/nope.pt"}],
    }
    for name, settings in bad_settings.items():
        for s in settings:
            yield f"make_tracker({name!r}, {s})", lambda name=name, s=s: make_tracker(name, **s)
    img = natural_texture("brick", 640, 480, 3)
    roi = (250, 170, 120, 84)
    frames = {"float in [0, 1]": img / 255.0, "int32": img.astype(np.int32), "grey 2-D": img[..., 0],
              "NaN": np.where(np.arange(3) == 0, np.nan, img.astype(float)), "a string": "frame",
              "4 channels": np.dstack([img, img[..., :1]]), "10×10": img[:10, :10]}
    for label, frame in frames.items():
        yield f"init with a {label} frame", lambda frame=frame: make_tracker("hybrid").init(frame, roi)
    for label, r in {"outside": (600, 400, 100, 100), "floats": (10.5, 10, 50, 40), "tiny": (10, 10, 12, 40),
                     "3 numbers": (1, 2, 3), "None": None}.items():
        yield f"init with a {label} ROI", lambda r=r: make_tracker("deep_lk").init(img, r)

    def wrong_size():
        tr = make_tracker("ecc")
        tr.init(img, roi)
        return tr.update(img[:400])
    yield "update with another frame size", wrong_size
    yield "update before init", lambda: make_tracker("hybrid").update(img)
    flat = img.copy()
    flat[150:280, 230:400] = (135, 180, 235)
    yield "init on plain sky", lambda: make_tracker("hybrid").init(flat, roi)


def control_cases():
    from hvs_sim.control.laws.ibvs import IBVSConfig, IBVSController

    K = np.array([[500.0, 0, 319.5], [0, 500.0, 239.5], [0, 0, 1]])
    D = np.array([[270.0, 200], [370, 200], [370, 280], [270, 280]])
    for s in ({"gain": math.nan}, {"gain_inf": 5.0}, {"gain_slope": math.nan}, {"max_linear": math.nan},
              {"max_angular": -1.0}, {"predict_gain": 2.0}, {"interaction": "x"}, {"dofs": ("vq",)}):
        yield f"IBVSConfig({s})", lambda s=s: IBVSConfig(**s)
    yield "IBVSController with a NaN K", lambda: IBVSController(np.full((3, 3), np.nan), D, 0.5)
    yield "IBVSController with a singular K", lambda: IBVSController(np.zeros((3, 3)), D, 0.5)
    yield "IBVSController with coincident desired points", lambda: IBVSController(K, np.tile(D[:1], (4, 1)), 0.5)
    yield "IBVSController with depth 0", lambda: IBVSController(K, D, 0.0)
    yield "compute with NaN features", lambda: IBVSController(K, D, 0.5).compute(D * np.nan)


def env_cases():
    from hvs_sim.envs.visual_servo import VisualServoEnv

    for s in ({"max_offset": math.nan}, {"max_offset": -0.1}, {"hold_steps": 0}, {"max_linear": math.nan},
              {"width": 8}, {"converge_px": 0.0}, {"reward": "score"}, {"render_mode": "human"},
              {"scenario": "nope"}, {"camera": "nope"}):
        yield f"VisualServoEnv({s})", lambda s=s: VisualServoEnv(**s)
    env = VisualServoEnv(width=96, height=72)
    env.reset(seed=0)
    for label, a in {"NaN": [np.nan] * 6, "3 values": np.zeros(3), "(6, 1)": np.zeros((6, 1)), "text": "go",
                     "inf": [np.inf] * 6}.items():
        yield f"env.step({label} action)", lambda a=a: env.step(a)
    yield "step before reset", lambda: VisualServoEnv(width=96, height=72).step(np.zeros(6))


def cli_cases(tmp: Path):
    from hvs_sim.cli import main

    stubbed = _stub_cli()
    nonempty = tmp / "full"
    nonempty.mkdir()
    (nonempty / "old.png").write_text("x")
    cases = [
        ["run", "--mount", "handheld"], ["run", "--json", str(tmp)], ["run", "--steps", "0"], ["run", "--tracker", "kcf"],
        ["run", "--scenario", "nope"], ["run", "--camera", "nope"], ["run", "--set", "nonsense=1"],
        ["run", "--set", "novalue"], ["run", "--tracker", "ground_truth", "--set", "scale=1"],
        ["run", "--width", "8"], ["run", "--fovy", "nan"], ["run", "--spawn"],
        ["scene", "--frames", "0", "--out", str(tmp / "s")], ["scene", "--out", str(nonempty)],
        ["scene", "--target-image", "/nope.png", "--out", str(tmp / "s2")],
        ["bench", "servo", "--episodes", "0", "--out", str(tmp / "b1")],
        ["bench", "track", "--smoke", "--methods", "hybird", "--out", str(tmp / "b2")],
        ["bench", "servo", "--mounts", "arm", "--out", str(tmp / "b3")],
        ["bench", "servo", "--episodes", "2", "--seeds", "1", "--out", str(tmp / "b4")],
        ["bench", "track", "--episodes", "3", "--out", str(tmp / "b5")],
        ["bench", "track", "--workers", "0", "--out", str(tmp / "b6")],
        ["bench", "track", "--out", str(nonempty)],
        ["bench", "track", "--imagery", "natural", "--sources", "astronaut", "--out", str(tmp / "b7")],
        ["bench", "track", "--imagery", "natural", "--mounts", "arm", "--out", str(tmp / "b8")],
        ["bench", "track", "--scenarios", "nope", "--out", str(tmp / "b9")],
        ["bench", "track", "--seeds", "-1", "--out", str(tmp / "b10")],
        ["track", "/nope.mp4", "--roi", "1,2,30,30"], ["track", str(tmp), "--roi", "1,2,30,30"],
        ["train", "gru", "--out", str(nonempty / "old.png")],
    ]
    import os

    env = {k: os.environ.pop(k) for k in ("DISPLAY", "WAYLAND_DISPLAY") if k in os.environ}  # --spawn: no display
    try:
        for argv in cases:
            yield "hvs-sim " + " ".join(argv), lambda argv=argv: main(argv)
    finally:
        os.environ.update(env)
        stubbed()


def safety_cases(tmp: Path):
    """Outputs that would destroy inputs, outside methods, sweep specs, hostile files, argument types."""
    import os
    import struct
    import zlib

    import cv2

    from hvs_sim.cli import main
    from hvs_sim.envs.visual_servo import VisualServoEnv
    from hvs_sim.sweep import parse_spec, run_sweep
    from hvs_sim.tracking import make_tracker

    frames = tmp / "inputs" / "frames"  # the inputs, watched for loss (main: classify's `inputs`)
    frames.mkdir(parents=True)
    for k in range(3):
        cv2.imwrite(str(frames / f"f{k}.png"), np.random.default_rng(k).integers(0, 255, (64, 64, 3), np.uint8))
    video = tmp / "inputs" / "clip.mp4"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"mp4v"), 30, (64, 64))
    for k in range(3):
        writer.write(cv2.imread(str(frames / f"f{k}.png")))
    writer.release()
    used = tmp / "inputs" / "used"
    used.mkdir()
    (used / "track.csv").write_text("frame\n")
    huge = tmp / "huge.png"
    _, buf = cv2.imencode(".png", np.zeros((8, 8, 3), np.uint8))
    data = bytearray(buf.tobytes())
    data[16:24] = struct.pack(">II", 100_000, 100_000)
    data[29:33] = struct.pack(">I", zlib.crc32(bytes(data[12:29])))
    huge.write_bytes(bytes(data))
    fifo = tmp / "pipe.mp4"
    os.mkfifo(fifo)
    roi = ["--roi", "10,10,30,30"]
    for label, argv in {
        "track --rrd naming an input frame": ["track", str(frames), *roi, "--rrd", str(frames / "f1.png")],
        "track --rrd naming the input video": ["track", str(video), *roi, "--rrd", str(video), "--out", str(tmp / "o1")],
        "track its own output video": ["track", str(used / "track.csv"), *roi, "--out", str(used)],
        "track into a used --out": ["track", str(frames), *roi, "--out", str(used)],
        "track --rrd equal to --out/track.csv": ["track", str(frames), *roi, "--out", str(tmp / "o2"), "--rrd",
                                                 str(tmp / "o2" / "track.csv")],
        "track --rrd a device": ["track", str(frames), *roi, "--out", str(tmp / "o3"), "--rrd", "/dev/null"],
        "run --json X --rrd X": ["run", "--json", str(tmp / "x.json"), "--rrd", str(tmp / "x.json")],
        "track a FIFO named .mp4": ["track", str(fifo), *roi, "--out", str(tmp / "o4")],
        "track a 100 000² PNG header": ["track", str(huge.parent / "hugefolder"), *roi],
        "run --target-image 100 000² header": ["run", "--target-image", str(huge)],
        "run --tracker nosuch.mod:make": ["run", "--tracker", "nosuch.mod:make"],
        "run --controller os:getcwd (not a law)": ["run", "--tracker", "ground_truth", "--controller", "os:getcwd"],
        "run --tracker json:nothing": ["run", "--tracker", "json:nothing"],
        "bench servo --methods {x:y}:affine": ["bench", "servo", "--methods", "{x:y}:affine", "--out", str(tmp / "b")],
        "bench servo --suite quick --seeds 3": ["bench", "servo", "--suite", "quick", "--seeds", "3"],
        "bench compare with one folder": ["bench", "compare", str(tmp)],
    }.items():
        if "hugefolder" in argv[1]:
            Path(argv[1]).mkdir(exist_ok=True)
            (Path(argv[1]) / "f0.png").write_bytes(huge.read_bytes())
        yield "hvs-sim " + label, lambda argv=argv: main(argv)
    full = tmp / "full_disk"
    if _full_disk(full):  # root only: a mounted tmpfs filled to the last byte
        yield "hvs-sim track --rrd onto a full disk", lambda: main(["track", str(frames), *roi, "--out", str(tmp / "o5"),
                                                                    "--rrd", str(full / "x.rrd")])
    for label, text in {"evaluate = ['no']": 'evaluate = ["no"]', "hold_steps = [2.5]": "hold_steps = [2.5]",
                        "converge_px = [nan]": "converge_px = [nan]", "gain = [2, 2.0]": "gain = [2, 2.0]",
                        "tracker = ['nosuch.mod:make']": 'tracker = ["nosuch.mod:make"]'}.items():
        yield f"sweep spec {label}", lambda text=text: parse_spec(f'kind = "servo"\n[axes]\n{text}\n')
    grid = parse_spec('kind = "servo"\n[axes]\nseed = [' + ", ".join(map(str, range(200))) + "]\ngain = ["
                      + ", ".join(str(1 + k / 100) for k in range(100)) + "]\n")
    yield "sweep of 20 000 tasks", lambda: run_sweep(grid, tmp / "grid", progress=False)
    yield "make_tracker(['hybrid'])", lambda: make_tracker(["hybrid"])
    yield "make_tracker('hybrid', 5)", lambda: make_tracker("hybrid", 5)
    env = VisualServoEnv(width=96, height=72)
    yield "env.render() before reset", env.render
    yield "env.reset(seed=True)", lambda: env.reset(seed=True)
    yield "env.reset(seed=-3)", lambda: env.reset(seed=-3)
    env.reset(seed=0)
    yield "env.step(string action)", lambda: env.step(["0.1"] * 6)
    yield "env.step(complex action)", lambda: env.step(np.full(6, 0.1 + 0.1j))
    yield "track --roi with Arabic-Indic digits", lambda: main(["track", str(frames), "--roi", "١٠,10,30,30"])


def issue53_cases(tmp: Path):
    """The cases an independent sweep found losing data, hanging, crashing or accepted in silence (issue 53); the
    inputs under tmp/inputs are watched for loss (tests/test_outputs.py and tests/test_refusals.py run them too)."""
    import os

    import cv2
    import torch

    from hvs_sim.cli import main
    from hvs_sim.plugins import build
    from hvs_sim.tracking import make_tracker

    stubbed = _stub_cli()
    root = tmp / "inputs" / "i53"
    png = cv2.imencode(".png", np.random.default_rng(0).integers(0, 255, (96, 128, 3), np.uint8))[1].tobytes()

    def put(path: Path, data: bytes = png) -> Path:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
        return path

    small = ["--width", "160", "--height", "120", "--frames", "2"]
    for name in ("preview.png", "frames.mp4"):
        put(root / "d" / name)
    put(root / "b" / "budget.png")
    for k in range(12):
        put(root / "w" / "frames" / f"wall{k:02d}.png")
    put(root / "precious" / "00000.png")
    (root / "l").mkdir()
    (root / "l" / "frames").symlink_to(root / "precious")
    put(root / "r" / "r_steps.csv", b"mine")
    put(root / "fig" / "frames.png")
    put(root / "demo" / "run.json", b"mine")
    put(root / "sw" / "results.csv", b"mine")
    spec = put(tmp / "s.toml", b'kind = "servo"\n[axes]\nseed = [1]\n[fixed]\nsteps = 2\n')
    put(tmp / "tasks_file" / "tasks", b"a file")
    loop = tmp / "loop.mp4"
    loop.symlink_to(loop)
    cut = put(tmp / "cut.jpg", cv2.imencode(".jpg", np.random.default_rng(1).integers(0, 255, (240, 320, 3), np.uint8))[1]
              .tobytes()[:4000])
    fifo = tmp / "gru.pt"
    os.mkfifo(fifo)
    evil_npz = tmp / "evil.npz"
    np.savez(evil_npz, conv1_1_w=np.array([object()], dtype=object), conv1_1_b=np.zeros(64))
    evil_pt = tmp / "evil.pt"
    torch.save({"x": SimpleNamespace(a=1)}, evil_pt)
    exits = put(tmp / "exits.py", b"import sys\nsys.exit(0)\n")
    exits_in_factory = put(tmp / "exits_later.py", b"import sys\ndef make(**kw):\n    sys.exit(0)\n")
    cli = {
        "--overwrite with an input named preview.png": ["scene", *small, "--target-image", str(root / "d" / "preview.png"),
                                                        "--out", str(root / "d"), "--overwrite"],
        "--overwrite with an input named frames.mp4": ["scene", *small, "--target-image", str(root / "d" / "frames.mp4"),
                                                       "--out", str(root / "d"), "--overwrite"],
        "budget --target-image o/budget.png --out o --overwrite": ["budget", "--bound-only", "--target-image",
                                                                   str(root / "b" / "budget.png"), "--out",
                                                                   str(root / "b"), "--overwrite"],
        "scene --wall-images o/frames --out o --overwrite": ["scene", *small, "--format", "png", "--wall-images",
                                                             str(root / "w" / "frames"), "--out", str(root / "w"),
                                                             "--overwrite"],
        "scene --out o --overwrite, o/frames a link": ["scene", *small, "--format", "png", "--out", str(root / "l"),
                                                       "--overwrite"],
        "run --json r.json beside a user's r_steps.csv": ["run", "--json", str(root / "r" / "r.json")],
        "run --figures fig holding a user's frames.png": ["run", "--figures", str(root / "fig")],
        "demo --out o holding a user's run.json": ["demo", "--out", str(root / "demo")],
        "sweep --out o holding a user's results.csv": ["sweep", str(spec), "--out", str(root / "sw")],
        "sweep --out o whose tasks is a file": ["sweep", str(spec), "--out", str(tmp / "tasks_file")],
        "run --tracker hybrid --set scale=abc": ["run", "--tracker", "hybrid", "--set", "scale=abc"],
        "run --tracker hybrid --set scale=nan": ["run", "--tracker", "hybrid", "--set", "scale=nan"],
        "run --tracker /etc/passwd:root": ["run", "--tracker", "/etc/passwd:root"],
        "run --tracker plug/../../../etc/passwd:x": ["run", "--tracker", "plug/../../../../../../etc/passwd:x"],
        "scene --out o --mcap o": ["scene", *small, "--out", str(tmp / "same"), "--mcap", str(tmp / "same")],
        "run --json with a 300-character name": ["run", "--json", str(tmp / ("r" * 300 + ".json"))],
        "track a symlink loop": ["track", str(loop), "--roi", "1,1,30,30", "--out", str(tmp / "t1")],
        "scene --frames 100000000": ["scene", "--frames", "100000000", "--out", str(tmp / "big")],
        "track --out ''": ["track", str(root / "w" / "frames"), "--roi", "1,1,30,30", "--out", ""],
        "scene --target-image a truncated JPEG": ["scene", "--width", "160", "--height", "120", "--frames", "1",
                                                 "--target-image", str(cut), "--out", str(tmp / "cut")],
        "run --tracker a file calling sys.exit at import": ["run", "--tracker", f"{exits}:make"],
        "run --roi 5 (an abbreviation of --roi-inset)": ["run", "--roi", "5"],
    }
    try:
        for label, argv in cli.items():
            yield f"hvs-sim {label}", lambda argv=argv: main(argv)
    finally:
        stubbed()
    yield "make_tracker(gru_weights=a FIFO)", lambda: make_tracker("hybrid", gru_weights=str(fifo))
    yield "make_tracker(weights=an .npz of object arrays)", lambda: make_tracker("hybrid", weights=str(evil_npz))
    yield "make_tracker(gru_weights=a pickled object .pt)", lambda: make_tracker("hybrid", gru_weights=str(evil_pt))
    yield "a plugin factory calling sys.exit", lambda: build("tracker", f"{exits_in_factory}:make")


def _stub_cli():
    """Replace the long work behind the commands (as tests/test_fuzz.py does); returns an undo."""
    from hvs_sim import runner
    from hvs_sim.bench import natural, servo, track
    from hvs_sim.render import sequence

    saved = [(m, n, getattr(m, n)) for m, n in ((track, "run_track_bench"), (servo, "run_servo_bench"),
                                                (natural, "run_natural_bench"), (runner, "run_episode"),
                                                (sequence, "write_sequence"), (sequence, "iterate_sequence"))]

    def bench(summary):
        def run(cfg, out, progress=True):
            Path(out, "summary.json").write_text("{}")
            return summary
        return run

    track.run_track_bench = bench({"occlusion_scenarios": {}, "target_set": {}})
    servo.run_servo_bench = bench({"results": {}})
    natural.run_natural_bench = bench({"overall": {}, "visible_lt_40": {}, "timing": {}, "per_kind": {}})
    brief = dict.fromkeys(("converged", "held_to_end", "steps_to_converge", "final_error_px",
                           "max_error_px_during_occlusion", "final_pose_error_mm", "final_pose_error_deg",
                           "controlled_dofs", "lost_steps", "predict_steps", "fault_steps", "steps_per_second"), 0)
    brief.update(not_converged_because="image 1.00 px > 0.5 px", faults=[])
    from hvs_sim.servo.plan import loop_tracker

    def run_episode(scenario, tracker, *a, tracker_settings=None, **k):  # the checks it makes before any scene
        loop_tracker(tracker, tracker_settings or {})
        return brief, []

    runner.run_episode = run_episode
    sequence.write_sequence = lambda *a, **k: {"frames": 1, "peak_occlusion": 0.0}
    gt = SimpleNamespace(corners=np.array([[1.0, 1], [9, 1], [9, 9], [1, 9]]), center=np.array([5.0, 5.0]))
    sequence.iterate_sequence = lambda *a, **k: iter([(np.zeros((16, 16, 3), np.uint8), gt)])

    def undo():
        for m, n, f in saved:
            setattr(m, n, f)
    return undo


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--json", default="experiments/results/bad_inputs.json")
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory(ignore_cleanup_errors=True) as tmp:  # a full-disk mount may stay busy
        for area, cases in (("trackers", tracker_cases()), ("control", control_cases()), ("env", env_cases()),
                            ("cli", cli_cases(Path(tmp))), ("outputs, plugins, files", safety_cases(Path(tmp))),
                            ("outputs, plugins, files (issue 53)", issue53_cases(Path(tmp)))):
            for label, fn in cases:
                outcome, detail = classify(fn, Path(tmp) / "inputs" if area.startswith("outputs") else None)
                rows.append({"area": area, "input": label, "outcome": outcome, "detail": detail})
    table = {}
    for r in rows:
        t = table.setdefault(r["area"], dict.fromkeys(OUTCOMES, 0) | {"tried": 0})
        t["tried"] += 1
        t[r["outcome"]] += 1
    total = {k: sum(t[k] for t in table.values()) for k in ("tried", *OUTCOMES)}
    print("| area | tried | clear errors | raw tracebacks | silently accepted | data lost | hangs |\n"
          "|---|---|---|---|---|---|---|")
    for area, t in {**table, "all": total}.items():
        print(f"| {area} | {t['tried']} | {t['clear']} | {t['raw traceback']} | {t['silently accepted']} | "
              f"{t['data lost']} | {t['hang']} |")
    for r in rows:
        if r["outcome"] != "clear":
            print(f"  {r['outcome']}: {r['input']} -> {r['detail']}")
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps({"summary": table, "total": total, "cases": rows}, indent=2))


if __name__ == "__main__":
    main()
