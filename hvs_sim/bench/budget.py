"""`hvs-sim budget`: what accuracy will 6-DOF servoing reach with this camera, this target, at this standoff?

The answer computed here is the Cramér–Rao bound (control/bound.py) on the camera's pose at the goal: the goal view
rendered as the camera sees it (its auto-exposure gain, the sRGB curve), the template region the loop tracks (the
target inset by GOAL_ROI_INSET_PX), each pixel's noise from the camera model (shot and read noise through the gain,
quantisation, and JPEG's error measured on the view itself). It is given for one frame, for the frames the loop's
feature filter effectively averages, and as the floor the goal template's own noise leaves (the goal image averages
GOAL_FRAMES frames; its noise is frozen into the template: a bias no filtering removes). A bound, not a prediction of
what a given tracker reaches: biases (exposure changes between the goal image and the live frames, the target's
relief) come on top; `experiments/servo_goal_noise.py` measures them.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from hvs_sim.camera_model import jpeg_variance, output_variance, sensor_preset, steady_gain
from hvs_sim.control.bound import PoseBound, pose_bound
from hvs_sim.control.dvs import gradients
from hvs_sim.control.feature_filter import FEATURE_FILTER_ALPHA
from hvs_sim.errors import ConfigError, InputError
from hvs_sim.loop import GOAL_ROI_INSET_PX
from hvs_sim.loopparts import GOAL_FRAMES
from hvs_sim.tracking.frames import inset_roi, roi_from_corners

GREY = np.array([0.299, 0.587, 0.114])  # the trackers' grey (OpenCV's RGB→grey weights)
FIGURE_STANDOFFS = (0.5, 0.65, 0.8, 1.0, 1.2)  # m: the figure's accuracy against standoff ...
FIGURE_WIDTHS = (0.10, 0.15, 0.30)  # m: ... for these target widths


def filter_frames(alpha: float = FEATURE_FILTER_ALPHA) -> float:
    """Frames an exponential filter of gain α effectively averages at steady state: its output's variance is
    α / (2 − α) of one frame's."""
    return (2.0 - alpha) / alpha


def goal_view(scenario):
    """(clean frame uint8, its per-pixel grey variance, K, template ROI) of the camera held at the reference pose."""
    from hvs_sim.camera_model import encode
    from hvs_sim.render.renderer import Renderer
    from hvs_sim.scene.world import Scene

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
    try:
        roi = inset_roi(roi_from_corners(corners), GOAL_ROI_INSET_PX)
    except InputError:
        raise ConfigError(f"the target is too small in the image at {scenario.standoff} m to be tracked (its template "
                          f"would be under the trackers' minimum); give a larger target or a shorter standoff") from None
    return clean, grey_var, r.K, roi


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

    def row(self) -> dict:
        return {"camera": self.camera, "target": self.target, "target_width_m": self.target_width_m,
                "standoff_m": self.standoff_m, "template_px": list(self.template_px),
                "noise_levels": self.noise_levels, "pixels": self.one_frame.pixels,
                "one_frame_mm": self.one_frame.translation_mm, "one_frame_deg": self.one_frame.rotation_deg,
                "filtered_mm": self.filtered.translation_mm, "filtered_deg": self.filtered.rotation_deg,
                "filter_frames": self.filter_frames,
                "template_floor_mm": self.template_floor.translation_mm,
                "template_floor_deg": self.template_floor.rotation_deg,
                "one_frame_per_dof": self.one_frame.per_dof()}


def budget(camera: str = "phone_handheld", standoff: float = 0.8, **scene) -> Budget:
    """The bound for a camera preset and a target (make_scenario's target settings) at a standoff."""
    from hvs_sim.scene.scenarios import CameraConfig, make_scenario

    sensor = sensor_preset(camera)
    scen = make_scenario("clear", mount="arm", camera=CameraConfig(sensor=sensor), standoff=standoff, **scene)
    clean, grey_var, K, roi = goal_view(scen)
    x0, y0, w, h = roi
    patch = grey_var[y0:y0 + h, x0:x0 + w]
    if not np.isfinite(patch).any():
        raise ConfigError("every pixel of the template is saturated at this camera's exposure")
    one = view_bound(clean, grey_var, K, roi, standoff)
    n = filter_frames()
    return Budget(sensor.name, scen.target_label, scen.target_width, standoff, (w, h),
                  float(np.sqrt(np.median(patch[np.isfinite(patch)]))), one, one.scaled(n), one.scaled(GOAL_FRAMES), n)


def table(rows: list[Budget]) -> str:
    lines = [("| camera | target | width (m) | standoff (m) | template (px) | noise (levels) | one frame (mm / °) | "
             "filtered, ~N frames (mm / °) | goal-template floor (mm / °) |"), "|---|---|---|---|---|---|---|---|---|"]
    for b in rows:
        lines.append(f"| {b.camera} | {b.target} | {b.target_width_m:g} | {b.standoff_m:g} | "
                     f"{b.template_px[0]}×{b.template_px[1]} | {b.noise_levels:.2f} | "
                     f"{b.one_frame.translation_mm:.3f} / {b.one_frame.rotation_deg:.4f} | "
                     f"{b.filtered.translation_mm:.3f} / {b.filtered.rotation_deg:.4f} (N {b.filter_frames:.0f}) | "
                     f"{b.template_floor.translation_mm:.3f} / {b.template_floor.rotation_deg:.4f} |")
    return "\n".join(lines) + "\n"


def figure(camera: str, path, **scene) -> dict:
    """Accuracy (filtered bound, mm) against standoff for FIGURE_WIDTHS target widths; returns the numbers."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    curves = {}
    for width in FIGURE_WIDTHS:
        pts = []
        for z in FIGURE_STANDOFFS:
            try:
                pts.append((z, budget(camera, z, target_width=width, **scene).filtered.translation_mm))
            except ConfigError:  # too small to track there: no point
                continue
        curves[width] = pts
    fig, ax = plt.subplots(figsize=(6, 4))
    for width, pts in curves.items():
        if pts:
            ax.plot(*zip(*pts, strict=True), marker="o", label=f"target {100 * width:.0f} cm wide")
    ax.set(yscale="log", xlabel="standoff (m)", ylabel="pose bound, translation 1-σ (mm)",
           title=f"{camera}: Cramér–Rao bound after the feature filter")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return {str(w): pts for w, pts in curves.items()}
