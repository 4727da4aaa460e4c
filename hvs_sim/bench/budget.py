"""`hvs-sim budget`: what accuracy will 6-DOF servoing reach with this camera, this target, at this standoff?

The answer computed here is the Cramér–Rao bound (control/bound.py) on the camera's pose at the goal: the goal view
rendered as the camera sees it (its auto-exposure gain, the sRGB curve), the template region the loop tracks (the
target inset by GOAL_ROI_INSET_PX), each pixel's noise from the camera model (shot and read noise through the gain,
quantisation, and JPEG's error measured on the view itself). It is given for one frame, for the frames the loop's
feature filter effectively averages, and as the floor the goal template's own noise leaves (the goal image averages
GOAL_FRAMES frames; its noise is frozen into the template: a bias no filtering removes). A bound, not a prediction of
what a given tracker reaches: biases (exposure changes between the goal image and the live frames, the target's
relief) come on top; `experiments/servo_goal_noise.py` measures them.

On top of the bound, `measure` finds what the loop's tracker (the homography hybrid) does with this camera and
target, and `predict` turns it into the final pose error to expect:
- held at the goal for HOLD_FRAMES frames: its bias (the goal template's frozen noise, exposure changes seen through
  JPEG) and its frame-to-frame noise, along L's two weakest directions (sideways shift traded against tilt), where
  the loop's last millimetres lie;
- around the goal, on clean renders (the `ideal` camera at this size: no noise at all): the error a view a few
  millimetres off the goal leaves along those directions (NEAR_POSES views, ±NEAR_LATERAL_M of translation each),
  a deterministic floor that no filter averages (`experiments/servo_pose_bias.py`);
- the prediction: the median length of bias + noise (averaged by the feature filter) + near-goal error, the last
  two drawn as Gaussians of the measured spreads (PREDICTION_SAMPLES draws, seeded).
`closed_loop` runs a few servo episodes (the benchmark's `clear` start poses) for the figure to compare with.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from hvs_sim.control.bound import PoseBound, pose_bound
from hvs_sim.control.feature_filter import FEATURE_FILTER_ALPHA
from hvs_sim.control.features import interaction_matrix
from hvs_sim.control.laws.dvs import gradients
from hvs_sim.errors import ConfigError, InputError
from hvs_sim.geometry import offset_pose
from hvs_sim.sensor import jpeg_variance, output_variance, sensor_preset, steady_gain
from hvs_sim.servo.config import GOAL_ROI_INSET_PX, LoopConfig
from hvs_sim.servo.parts import GOAL_FRAMES, NEAR_GOAL_AUTO, NEAR_GOAL_SCALE
from hvs_sim.servo.teach import box_in_view, near_goal_growth
from hvs_sim.tracking.frames import inset_roi, roi_corners, roi_from_corners
from hvs_sim.tracking.warp import perspective_transform

GREY = np.array([0.299, 0.587, 0.114])  # the trackers' grey (OpenCV's RGB→grey weights)
FIGURE_STANDOFFS = (0.5, 0.65, 0.8, 1.0, 1.2)  # m: the figure's accuracy against standoff ...
FIGURE_WIDTHS = (0.10, 0.15, 0.30)  # m: ... for these target widths
HOLD_FRAMES = 90  # frames the camera is held at the goal (3 s at 30 Hz) for the tracker's bias and noise there
NEAR_POSES = 24  # clean views around the goal along L's two weakest directions ...
NEAR_LATERAL_M = 0.005  # ... each up to this much translation from it (the loop's last millimetres)
WEAK = 2  # L's weakest directions measured
PREDICTION_SAMPLES = 20000  # draws of the final pose error for its predicted median
# the tracked corners must follow the camera's offset at least this much (eigenvalues of I + G, real part) for the
# loop to have a stable place to stop; below it no prediction
MIN_SEEN_GAIN = 0.1
MIN_NEAR_POSES = 8  # the near-goal fit has three unknowns per direction: enough views left over to measure the rest
EPISODE_SEED0 = 200  # closed-loop episodes use the servo benchmark's `clear` start poses from this seed
BUDGET_TRACKER, BUDGET_WARP = "hybrid", "homography"  # the loop's tracker on six DOF


def filter_frames(alpha: float = FEATURE_FILTER_ALPHA) -> float:
    """Frames an exponential filter of gain α effectively averages at steady state: its output's variance is
    α / (2 − α) of one frame's."""
    return (2.0 - alpha) / alpha


def goal_view(scenario, near_goal: int | str | None = None):
    """(clean frame uint8, its per-pixel grey variance, K, template ROI, its inset, why it is not grown) of the camera
    held at the reference pose; the template the loop tracks at the goal with LoopConfig.near_goal_inset_px =
    `near_goal` (near_goal_inset)."""
    from hvs_sim.render.renderer import Renderer
    from hvs_sim.scene.world import Scene
    from hvs_sim.sensor import encode

    scene = Scene(scenario)
    r = Renderer(scene, people=False)
    with scene.posed(scene.reference_configuration()):
        linear = r.linear_light()
        corners = r.ground_truth(occlusion=False).corners
    model = scenario.camera.sensor
    gain = steady_gain(model, linear)
    clean = encode(linear * np.float32(gain))
    var = output_variance(model, linear, gain) + jpeg_variance(clean, model.jpeg_quality)
    grey_var = (var * GREY ** 2).sum(axis=2)
    template_roi(corners, scenario.standoff)  # the loop's first template, which brings the camera near: trackable?
    inset, why = near_goal_inset(corners, scenario.camera, near_goal)
    return clean, grey_var, r.K, template_roi(corners, scenario.standoff, inset, scenario.camera), inset, why


def near_goal_inset(corners: np.ndarray, camera, near_goal: int | str | None) -> tuple[int, str | None]:
    """The inset of the template the loop tracks at the goal (the target's corners there, LoopConfig's
    near_goal_inset_px): the grown one's (negative), or GOAL_ROI_INSET_PX and why where there is none."""
    if near_goal is None:
        return GOAL_ROI_INSET_PX, None
    if near_goal != NEAR_GOAL_AUTO:
        return int(near_goal), None
    growth, why = near_goal_growth(roi_from_corners(corners), camera)
    return (GOAL_ROI_INSET_PX, why) if growth is None else (growth, None)


def template_roi(corners: np.ndarray, standoff: float, inset: int = GOAL_ROI_INSET_PX,
                 camera=None) -> tuple[int, int, int, int]:
    """The template the loop tracks: the target's outline inset by `inset` px (GOAL_ROI_INSET_PX, the loop's; negative:
    grown beyond it, which must stay inside `camera`'s image as the loop asks, loop.box_in_view); a clear error when
    that is too small to track or runs off the image."""
    try:
        roi = inset_roi(roi_from_corners(corners), inset)
    except InputError:
        raise ConfigError(f"the target is too small in the image at {standoff} m to be tracked (its template "
                          f"would be under the trackers' minimum); give a larger target or a shorter standoff") from None
    if inset < 0 and camera is not None and not box_in_view(roi, camera):
        raise ConfigError(f"the template grown {-inset} px beyond the target's outline ({roi[2]}×{roi[3]} px) runs "
                          f"off the {camera.width}×{camera.height} image at {standoff} m: grow it less, or give a "
                          "smaller target or a longer standoff")
    return roi


def weak_directions(K: np.ndarray, corners_px: np.ndarray, depth: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """L's WEAK weakest directions at four corners (pixels) of a fronto-parallel target at `depth`, weakest first:
    (U (8, WEAK), the corner motions; Vt (WEAK, 6), the camera twists; mm of camera translation per px along each)."""
    xy = (np.asarray(corners_px, float) - K[:2, 2]) / np.diag(K)[:2]
    U, S, Vt = np.linalg.svd(interaction_matrix(xy, np.full(len(xy), depth)))
    idx = [len(S) - 1 - k for k in range(WEAK)]
    mm = np.array([1e3 * np.linalg.norm(Vt[i][:3]) / (K[0, 0] * S[i]) for i in idx])
    return U[:, idx], Vt[idx], mm


def weak_offset(a: np.ndarray, Vt: np.ndarray) -> np.ndarray:
    """The camera offset (dx, dy, dz, roll, pitch, yaw; `geometry.offset_pose`'s order) a along the weak directions
    `Vt` (weak_directions), each scaled so that a_k is metres of translation; small angles."""
    twist = sum(a[k] * Vt[k] / np.linalg.norm(Vt[k][:3]) for k in range(len(a)))
    return np.r_[twist[:3], twist[5], twist[3], twist[4]]  # the twist's (wx, wy, wz) are pitch, yaw, roll


def view_bound(clean: np.ndarray, grey_var: np.ndarray, K: np.ndarray, roi, depth: float) -> PoseBound:
    """The 6-DOF bound from the template region of a clean view and its per-pixel grey noise variance."""
    grey = clean.astype(np.float64) @ GREY
    gx, gy = gradients(grey)
    x0, y0, w, h = roi
    v, u = np.mgrid[y0:y0 + h, x0:x0 + w]
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    return pose_bound(gx[v, u] * fx, gy[v, u] * fy, (u - cx) / fx, (v - cy) / fy, depth, grey_var[v, u])


@dataclasses.dataclass(frozen=True)
class Budget:
    camera: str
    target: str
    target_width_m: float
    standoff_m: float
    template_px: tuple[int, int]
    noise_levels: float  # median 1-σ of the template's grey pixels, 8-bit levels
    one_frame: PoseBound
    filtered: PoseBound  # over filter_frames() frames
    template_floor: PoseBound  # the goal template's own noise (GOAL_FRAMES frames averaged)
    filter_frames: float
    measured: Measured | None = None  # the loop's tracker with this camera (measure), when asked for
    predicted_mm: float | None = None  # predict(measured)
    closed_loop: tuple[dict, ...] = ()  # closed_loop's episodes
    # px the template lies inside the target's outline: the loop's GOAL_ROI_INSET_PX, or negative, the near-goal
    # template grown beyond it (LoopConfig.near_goal_inset_px), which the loop tracks at the goal
    template_inset_px: int = GOAL_ROI_INSET_PX
    near_goal: int | str | None = NEAR_GOAL_AUTO  # LoopConfig.near_goal_inset_px as asked: the episodes run with it
    near_goal_off: str | None = None  # why NEAR_GOAL_AUTO grew no template here (the default one is tracked)

    @property
    def closed_loop_median_mm(self) -> float | None:
        return float(np.median([r["final_pose_error_mm"] for r in self.closed_loop])) if self.closed_loop else None

    def row(self) -> dict:
        return {"camera": self.camera, "target": self.target, "target_width_m": self.target_width_m,
                "standoff_m": self.standoff_m, "template_px": list(self.template_px),
                "template_inset_px": self.template_inset_px, "near_goal": self.near_goal,
                "near_goal_off": self.near_goal_off,
                "noise_levels": self.noise_levels, "pixels": self.one_frame.pixels,
                "one_frame_mm": self.one_frame.translation_mm, "one_frame_deg": self.one_frame.rotation_deg,
                "filtered_mm": self.filtered.translation_mm, "filtered_deg": self.filtered.rotation_deg,
                "filter_frames": self.filter_frames,
                "template_floor_mm": self.template_floor.translation_mm,
                "template_floor_deg": self.template_floor.rotation_deg,
                "one_frame_per_dof": self.one_frame.per_dof(),
                "measured": self.measured.row() if self.measured is not None else None,
                "predicted_median_mm": self.predicted_mm, "closed_loop": list(self.closed_loop),
                "closed_loop_median_mm": self.closed_loop_median_mm}


def budget_scenario(camera: str, standoff: float, supersample: int = 1, **scene):
    """The still scene the budget is computed in: `clear`, the camera on the arm (make_scenario's `arm` and target
    settings in `scene`), the goal at `standoff`."""
    from hvs_sim.scene.scenarios import CameraConfig, make_scenario

    return make_scenario("clear", mount="arm", camera=CameraConfig(sensor=sensor_preset(camera), supersample=supersample),
                         standoff=standoff, **scene)


def budget(camera: str = "phone_handheld", standoff: float = 0.8, near_goal_inset_px: int | str | None = NEAR_GOAL_AUTO,
           **scene) -> Budget:
    """The bound for a camera preset and a target (make_scenario's target and arm settings) at a standoff, on the
    template the loop tracks at the goal with LoopConfig.near_goal_inset_px = `near_goal_inset_px`: the grown one it
    switches to there (NEAR_GOAL_AUTO, the loop's default, or a negative growth), or with None its one template;
    `estimate` adds what the loop reaches."""
    sensor = sensor_preset(camera)
    near_goal = LoopConfig(near_goal_inset_px=near_goal_inset_px).near_goal_inset_px  # checked ("off" as None)
    scen = budget_scenario(camera, standoff, **scene)
    clean, grey_var, K, roi, inset, why = goal_view(scen, near_goal)
    x0, y0, w, h = roi
    patch = grey_var[y0:y0 + h, x0:x0 + w]
    if not np.isfinite(patch).any():
        raise ConfigError("every pixel of the template is saturated at this camera's exposure")
    one = view_bound(clean, grey_var, K, roi, standoff)
    n = filter_frames()
    return Budget(sensor.name, scen.target_label, scen.target_width, standoff, (w, h),
                  float(np.sqrt(np.median(patch[np.isfinite(patch)]))), one, one.scaled(n), one.scaled(GOAL_FRAMES), n,
                  template_inset_px=inset, near_goal=near_goal, near_goal_off=why)


@dataclasses.dataclass(frozen=True)
class Measured:
    """The loop's tracker with this camera and target, along L's WEAK weakest directions (mm of camera translation,
    weakest first)."""
    mm_per_px: tuple[float, ...]
    bias_mm: tuple[float, ...]  # held at the goal: the mean error over the frames
    noise_mm: tuple[float, ...]  # held at the goal: the frame-to-frame sd
    # clean views around the goal: the error as a linear function of the camera's offset along the directions
    # (near_gain: mm of error per mm of offset, rows the error's direction) and what that leaves (root mean square)
    near_gain: tuple[tuple[float, ...], ...]
    near_offset_mm: tuple[float, ...]  # the fit's constant: the near-goal error at the goal itself
    near_mm: tuple[float, ...]
    hold_frames: int
    near_poses: int
    unaligned: int = 0  # frames held at the goal and near-goal views where the tracker did not align (mode)

    def row(self) -> dict:
        return dataclasses.asdict(self)


def _goal_tracker(goal: np.ndarray, roi, inset: int):
    """The loop's tracker on the template: on a grown one at the working scale the loop tracks it at (NEAR_GOAL_SCALE)."""
    from hvs_sim.tracking import make_tracker

    tracker = make_tracker(BUDGET_TRACKER, warp=BUDGET_WARP, **({"scale": NEAR_GOAL_SCALE} if inset < 0 else {}))
    tracker.init(goal, roi)
    return tracker


def track_still(tracker, frame: np.ndarray, roi0: np.ndarray, truth: np.ndarray):
    """The tracker's Track on one frame of a still camera, seeded at the template box's true corners `truth` (its
    corners `roi0` in the template): twice, the second from the first's answer, as the loop tracks a still camera."""
    tracker.seed(perspective_transform(roi0, truth))
    for _ in range(2):
        track = tracker.update(frame)
    return track


def measure(scenario, hold_frames: int = HOLD_FRAMES, near_poses: int = NEAR_POSES, seed: int = 0,
            inset: int = GOAL_ROI_INSET_PX) -> Measured:
    """The tracker held at the goal through the scenario's camera, and on clean views around the goal, on the template
    `inset` px inside the target's outline (template_roi)."""
    from hvs_sim.render.renderer import Renderer
    from hvs_sim.scene.world import Scene
    from hvs_sim.tracking.base import Mode

    for name, value, least in (("hold_frames", hold_frames, 2), ("near_poses", near_poses, MIN_NEAR_POSES)):
        if isinstance(value, bool) or not isinstance(value, int) or value < least:
            raise ConfigError(f"{name} must be a whole number of at least {least}, got {value!r}")
    scene = Scene(scenario)
    q0 = scene.reference_configuration()
    with scene.posed(q0):  # the goal image as the loop takes it; then time runs with the arm held there
        teacher = Renderer(scene, people=False)
        goal, c0 = teacher.still_average(GOAL_FRAMES), teacher.ground_truth(occlusion=False).corners
        roi = template_roi(c0, scenario.standoff, inset, scenario.camera)
        roi0 = roi_corners(roi)
        U, Vt, mm = weak_directions(teacher.K, roi0, scenario.standoff)
        camera = Renderer(scene, people=False)
        tracker = _goal_tracker(goal, roi, inset)
        tracker.seed(np.eye(3))
        held, unaligned = [], 0
        for _ in range(hold_frames):
            scene.advance(None)
            frame, gt = camera.rgb(), camera.ground_truth(occlusion=False).corners
            track = tracker.update(frame)
            unaligned += track.mode != Mode.ALIGN
            held.append((track.corners - camera.transfer(c0, gt, roi0)).ravel() @ U)
    held = np.array(held) * mm
    # the same target through a camera without noise, blur or exposure changes, at the same size and field of view
    clean = Scene(dataclasses.replace(scenario, camera=dataclasses.replace(scenario.camera, sensor="ideal")))
    r = Renderer(clean, people=False)
    with clean.posed(q0):
        goal, c0 = r.rgb(), r.ground_truth(occlusion=False).corners
    tracker = _goal_tracker(goal, roi, inset)
    ref = clean.reference_pose()
    rng = np.random.default_rng([seed, 35])
    near, offsets = [], []
    for _ in range(near_poses):  # a twist along the weak directions, each scaled to NEAR_LATERAL_M of translation
        a = rng.uniform(-NEAR_LATERAL_M, NEAR_LATERAL_M, WEAK)
        offsets.append(1e3 * a)
        q = clean.solve_ik(*offset_pose(*ref, weak_offset(a, Vt)), q0=q0)
        with clean.posed(q):
            frame, gt = r.rgb(), r.ground_truth(occlusion=False).corners
        truth = r.transfer(c0, gt, roi0)
        track = track_still(tracker, frame, roi0, truth)
        unaligned += track.mode != Mode.ALIGN
        near.append((track.corners - truth).ravel() @ U)
    near = np.array(near) * mm
    A = np.c_[np.array(offsets), np.ones(near_poses)]
    coef, *_ = np.linalg.lstsq(A, near, rcond=None)  # near ≈ offsets @ G.T + c
    gain, rest = coef[:WEAK].T, near - A @ coef
    return Measured(tuple(mm.tolist()), tuple(held.mean(axis=0).tolist()), tuple(held.std(axis=0).tolist()),
                    tuple(tuple(g) for g in gain.tolist()), tuple(coef[WEAK].tolist()),
                    tuple(np.sqrt(np.mean(rest ** 2, axis=0)).tolist()), hold_frames, near_poses, int(unaligned))


def predict(m: Measured, frames: float) -> float | None:
    """The median final pose error to expect (mm). The loop stops where the tracked corners say the camera is at the
    goal: offset a with a + G a + e = 0, G the near-goal gain and e the held bias plus the near-goal fit's constant
    plus the noise averaged over `frames` plus what the fit leaves of the near-goal error, the last two drawn as
    Gaussians of their measured spreads along each direction; the median length of a = −(I + G)⁻¹ e over the draws.
    None where I + G has an eigenvalue under MIN_SEEN_GAIN."""
    spread = np.sqrt(np.square(m.noise_mm) / frames + np.square(m.near_mm))
    e = np.asarray(m.bias_mm) + np.asarray(m.near_offset_mm) + np.random.default_rng(0).standard_normal((PREDICTION_SAMPLES, WEAK)) * spread
    seen = np.eye(WEAK) + np.asarray(m.near_gain)  # how the tracked corners move with the camera, per mm
    if np.linalg.eigvals(seen).real.min() < MIN_SEEN_GAIN:  # barely or wrongly seen: the loop has no stable stop
        return None
    a = np.linalg.solve(seen, e.T).T
    return float(np.median(np.linalg.norm(a, axis=1)))


def closed_loop(camera: str, standoff: float, episodes: int, progress=None, seed0: int = EPISODE_SEED0,
                supersample: int = 1, near_goal_inset_px: int | str | None = NEAR_GOAL_AUTO, **scene) -> list[dict]:
    """`episodes` servo runs of the loop's tracker on six DOF from the servo benchmark's `clear` start poses (seeds
    seed0…), each as long as the benchmark's (with LoopConfig.near_goal_inset_px = `near_goal_inset_px`); their
    final pose errors. `progress(k)` after each."""
    from hvs_sim.bench.servo import EXTRA_STEPS, episode_scenario
    from hvs_sim.runner import run_episode
    from hvs_sim.scene.scenarios import CameraConfig
    from hvs_sim.servo.config import LoopConfig

    if not isinstance(episodes, int) or episodes < 0:
        raise ConfigError(f"episodes must be a whole number ≥ 0, got {episodes!r}")
    runs = []
    for k in range(episodes):
        seed = seed0 + k
        scen = episode_scenario("clear", seed, camera=CameraConfig(sensor=sensor_preset(camera), supersample=supersample),
                                standoff=standoff, **scene)
        summary, _ = run_episode(scen, BUDGET_TRACKER, LoopConfig(steps=scen.n_frames + EXTRA_STEPS, keep_frames=False,
                                                                  evaluate=False, near_goal_inset_px=near_goal_inset_px),
                                 progress=False, tracker_settings={"warp": BUDGET_WARP})
        runs.append({"seed": seed, "final_pose_error_mm": summary["final_pose_error_mm"],
                     "final_pose_error_deg": summary["final_pose_error_deg"], "held_to_end": summary["held_to_end"],
                     "near_goal_switched_at_step": (summary["near_goal"] or {}).get("switched_at_step")})
        if progress is not None:
            progress(k + 1)
    return runs


def estimate(b: Budget, episodes: int, progress=None, **scene) -> Budget:
    """`b` with the tracker measured, the prediction, and `episodes` closed-loop runs (0: none)."""
    m = measure(budget_scenario(b.camera, b.standoff_m, **scene), inset=b.template_inset_px)
    runs = closed_loop(b.camera, b.standoff_m, episodes, progress, near_goal_inset_px=b.near_goal, **scene)
    return dataclasses.replace(b, measured=m, predicted_mm=predict(m, b.filter_frames), closed_loop=tuple(runs))


def _pair(values, spec: str = ".2f") -> str:
    return " / ".join(f"{v:{spec}}" for v in values)


def estimate_table(rows: list[Budget]) -> str:
    """What the loop reaches, for the rows that were estimated (along L's two weakest directions, weakest first)."""
    lines = [("| camera | target | width (m) | held at the goal: bias (mm) | noise a frame (mm) | around the goal, "
              "clean (mm) | predicted median final error (mm) | closed loop: median final error (mm), episodes |"),
             "|---|---|---|---|---|---|---|---|"]
    for b in rows:
        m = b.measured
        if m is None:
            continue
        loop = (f"{b.closed_loop_median_mm:.2f} ({len(b.closed_loop)})" if b.closed_loop else "not run")
        predicted = (f"**{b.predicted_mm:.2f}**" if b.predicted_mm is not None
                     else "none: the tracker does not follow the camera near the goal")
        if m.unaligned:
            predicted += f" (the tracker did not align on {m.unaligned} of {m.hold_frames + m.near_poses} views)"
        lines.append(f"| {b.camera} | {b.target} | {b.target_width_m:g} | {_pair(m.bias_mm, '+.2f')} | "
                     f"{_pair(m.noise_mm)} | {_pair(m.near_mm)} | {predicted} | {loop} |")
    return "\n".join(lines) + "\n"


def table(rows: list[Budget]) -> str:
    lines = [("| camera | target | width (m) | standoff (m) | template (px) | noise (levels) | one frame (mm / °) | "
             "filtered, ~N frames (mm / °) | goal-template floor (mm / °) |"), "|---|---|---|---|---|---|---|---|---|"]
    for b in rows:
        lines.append(f"| {b.camera} | {b.target} | {b.target_width_m:g} | {b.standoff_m:g} | "
                     f"{b.template_px[0]}×{b.template_px[1]} ({b.template_inset_px:+d}) | {b.noise_levels:.2f} | "
                     f"{b.one_frame.translation_mm:.3f} / {b.one_frame.rotation_deg:.4f} | "
                     f"{b.filtered.translation_mm:.3f} / {b.filtered.rotation_deg:.4f} (N {b.filter_frames:.0f}) | "
                     f"{b.template_floor.translation_mm:.3f} / {b.template_floor.rotation_deg:.4f} |")
    return "\n".join(lines) + "\n"


def figure(camera: str, path, near_goal_inset_px: int | str | None = NEAR_GOAL_AUTO, **scene) -> dict:
    """Accuracy (filtered bound, mm) against standoff for FIGURE_WIDTHS target widths, on the template `budget` takes
    with `near_goal_inset_px`; returns the numbers (a point where the template is too small or runs off the image is
    left out)."""
    import matplotlib

    near_goal_inset_px = LoopConfig(near_goal_inset_px=near_goal_inset_px).near_goal_inset_px  # checked ("off": None)
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    curves = {}
    for width in FIGURE_WIDTHS:
        pts = []
        for z in FIGURE_STANDOFFS:
            try:
                pts.append((z, budget(camera, z, near_goal_inset_px, target_width=width, **scene)
                            .filtered.translation_mm))
            except ConfigError:  # too small to track there: no point
                continue
        curves[width] = pts
    fig, ax = plt.subplots(figsize=(6, 4))
    for width, pts in curves.items():
        if pts:
            ax.plot(*zip(*pts, strict=True), marker="o", label=f"target {100 * width:.0f} cm wide")
    ax.set(yscale="log", xlabel="standoff (m)", ylabel="pose bound, translation 1-σ (mm)",
           title=f"{camera}: Cramér–Rao bound after the feature filter"
                 + ("" if near_goal_inset_px is None else "\n(the near-goal template: a quarter of the image where it fits)"
                    if near_goal_inset_px == NEAR_GOAL_AUTO else f"\n(template grown {-near_goal_inset_px} px)"))
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    from hvs_sim.outputs import save_figure

    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return {str(w): pts for w, pts in curves.items()}
