"""RGB and segmentation renders of the eye camera, and exact per-frame ground truth.

RGB frames go through the scenario's camera model (`hvs_sim.sensor`): motion blur (along the image motion
field of one render, `hvs_sim.render.blur`, or from sub-frame renders over the exposure), lens distortion, auto-exposure, sensor noise, JPEG. Ground
truth comes from geometry only; with lens distortion it is projected through the same model.
"""

from __future__ import annotations

import time
from collections.abc import Iterator

import cv2
import mujoco
import numpy as np
from dm_control.mujoco import engine
from dm_control.mujoco.wrapper import core as mj_core

from hvs_sim.gl import check_not_forked_after_rendering, note_rendering
from hvs_sim.render.blur import (
    FIELD_STRIDE,
    Rigid,
    blur_along_paths,
    camera_motion,
    combine_subframes,
    displacement,
    exposure_motion_px,
    motion_paths,
    moving_labels,
    pixel_rays,
    taps_for,
)
from hvs_sim.render.camera import MAX_STILL_FRAMES, CameraPose, intrinsics, project, transfer_points
from hvs_sim.render.truth import GroundTruth, boxes_may_cover, count_inside, outline_box
from hvs_sim.scene.parts import OCCLUDER_GROUP, TARGET_GROUP
from hvs_sim.scene.world import Scene
from hvs_sim.sensor import (
    STILL_STREAM,
    SUBFRAME_SMALL_MIN,
    SensorModel,
    SensorState,
    decode,
    distort_points,
    distortion_maps,
    encode,
    light_scale,
)
from hvs_sim.validate import check_number

SCENE_VIEW_AZIMUTH_DEG = 50.0  # the third-person view looks past the arm's side at the wall ...
SCENE_VIEW_ELEVATION_DEG = -20.0  # ... from a little above ...
SCENE_VIEW_DISTANCE = 2.6  # ... this many camera-to-target distances away


class Renderer:
    """Renders the scene's eye camera. Segmentation renders give the exact occlusion fraction."""

    _view: engine.MovableCamera  # scene_view's camera, set at its first call (absent before)

    def __init__(self, scene: Scene, people: bool = True, noise_seed: int | None = None):
        """people=False: the people are left out of the RGB frames (a capture of the clear scene, such as
        the goal image a user takes before servoing); ground truth and segmentation are unchanged.
        noise_seed: seeds the camera model's noise, exposure drift and light changes (None: the scenario's seed), so
        that episodes of one scene, such as the gym env's with a fixed look, differ in them."""
        check_not_forked_after_rendering()
        self.scene, self.people = scene, people
        cam = scene.scenario.camera
        self.width, self.height = cam.width, cam.height
        self.K = self.intrinsics_of(scene.scenario)
        self._camera_id = scene.physics.bind(scene.camera).element_id
        self._target_id = scene.physics.bind(scene.wall.target).element_id
        m = scene.physics.model
        self._occluder_geom = np.asarray(m.geom_group) == OCCLUDER_GROUP  # by geom id: hides the target as a person
        self._show_people = mj_core.MjvOption()
        self._show_people.geomgroup[OCCLUDER_GROUP] = 1
        self._hide_people = mj_core.MjvOption()
        self._hide_people.geomgroup[OCCLUDER_GROUP] = 0
        self.sensor: SensorModel = cam.sensor  # type: ignore[assignment]  # CameraConfig resolves a preset name
        self._ideal = self.sensor.is_ideal  # frozen: checked once, not per frame
        self._noise_seed = None if noise_seed is None else int(noise_seed)
        self._state = None if self._ideal else SensorState(self.sensor, self.noise_seed, (self.height, self.width))
        # the lights as modelled; flicker and dimming scale them during a capture and put them back after
        self._maps = distortion_maps(self.K, self.sensor.distortion, self.width, self.height) if self.sensor.distortion else None
        self._light0 = (m.light_diffuse.copy(), m.light_ambient.copy(), m.vis.headlight.diffuse.copy(),
                        m.vis.headlight.ambient.copy())
        self._last: tuple[tuple[int, int], np.ndarray] | None = None  # ((scene resets, frame), frame): one capture a frame
        self.blur_samples = 1  # sub-frame renders used for the last frame (diagnostics)
        self.blur_taps = 1  # field blur: taps along each pixel's motion in the last frame (1: sharp)
        self._rays: np.ndarray | None = None  # field blur: the grid's rays (_field_rays)
        self._only_people = mj_core.MjvOption()
        self._target_and_people = mj_core.MjvOption()  # all that can be over the target's pixels (occlusion_counts)
        for g in range(len(self._only_people.geomgroup)):
            self._only_people.geomgroup[g] = int(g == OCCLUDER_GROUP)
            self._target_and_people.geomgroup[g] = int(g in (OCCLUDER_GROUP, TARGET_GROUP))
        self._cam: engine.Camera | None = None  # made at the first render (the fork check ran in __init__)
        self.stage_ms: dict[str, float] = {}  # the last new frame's ms per stage (rgb)
        self.supersample = cam.supersample
        self._cam_ss: engine.Camera | None = None  # the colour renders at supersample× the size (supersample > 1)
        self._cam_small: engine.Camera | None = None  # sub-frames at 1/blur_subframe_scale the size (_small_subframes)

    @staticmethod
    def intrinsics_of(scenario) -> np.ndarray:
        cam = scenario.camera
        return intrinsics(cam.width, cam.height, cam.fovy)

    def _camera(self) -> engine.Camera:
        """One dm_control Camera for every render of this renderer. `Physics.render` builds a Camera (an
        MjvScene and its buffers) per call: 3–4 ms of a 640×480 frame's ~18 ms on Mesa here."""
        note_rendering()
        if self._cam is None:
            self._cam = engine.Camera(self.scene.physics, self.height, self.width, self._camera_id)
        return self._cam

    def _render(self) -> np.ndarray:
        # the Camera returns a flipped view of its own buffer, which the next render overwrites
        return self._camera().render(scene_option=self._show_people if self.people else self._hide_people).copy()

    def _render_linear(self) -> np.ndarray:
        """H×W×3 linear float32 light of one colour render; with supersampling, the mean of each pixel's k×k samples
        (rendered at k× the size; the mean is taken in linear light, as a pixel integrates light)."""
        k = self.supersample
        if k == 1:
            return decode(self._render())
        if self._cam_ss is None:
            note_rendering()
            self._cam_ss = engine.Camera(self.scene.physics, self.height * k, self.width * k, self._camera_id)
        big = self._cam_ss.render(scene_option=self._show_people if self.people else self._hide_people)
        return cv2.resize(decode(big), (self.width, self.height), interpolation=cv2.INTER_AREA)

    def rgb(self) -> np.ndarray:
        """H×W×3 uint8 RGB frame as the camera delivers it (the raw render for the `ideal` model; supersampled, its
        mean per pixel). `stage_ms` then holds where a new frame's time went: "light", the renders and what is done
        to the light (motion blur, flicker, the lens), and "sensor", the camera's electronics (noise, gain, the ADC,
        the sRGB curve, JPEG)."""
        t0 = time.perf_counter()
        if self._ideal:
            frame = self._render() if self.supersample == 1 else encode(self._render_linear())
            self.stage_ms = {"light": 1e3 * (time.perf_counter() - t0), "sensor": 0.0}
            return frame
        scene = self.scene
        key = (scene.resets, scene.frame_index)
        if self._last is not None and self._last[0] == key:
            return self._last[1].copy()  # auto-exposure and noise advance once per frame
        if self._last is not None and self._last[0][0] != key[0]:
            self._state = SensorState(self.sensor, self.noise_seed, (self.height, self.width))  # a new episode
        linear = self._exposure()
        t1 = time.perf_counter()
        # _state is None only for the ideal camera, whose frames return before
        frame = self._state.capture(  # type: ignore[union-attr]
            linear, scene.frame_index, scene.time, 1.0 / scene.scenario.fps)
        self.stage_ms = {"light": 1e3 * (t1 - t0), "sensor": 1e3 * (time.perf_counter() - t1)}
        self._last = (key, frame)
        return frame.copy()

    def depth(self) -> np.ndarray:
        """H×W float32 depth (m along the optical axis) of the eye camera's view, people included when they are shown
        in the frames; the lens's distortion is not applied (a calibrated depth camera's undistorted image)."""
        cam = self._camera()
        return cam.render(depth=True, scene_option=self._show_people if self.people else self._hide_people).copy()

    def scene_view(self, width: int, height: int) -> np.ndarray:
        """H×W×3 uint8 third-person view of the scene (arm, wall, people) from beside the arm, looking at the
        midpoint of the camera and the target: what the gym env's render() shows."""
        note_rendering()
        if getattr(self, "_view", None) is None or self._view.width != width or self._view.height != height:
            self._view = engine.MovableCamera(self.scene.physics, height, width)
        cam_pos = self.camera_pose().t
        target = self.scene.target_center_world()
        span = float(np.linalg.norm(target - cam_pos))
        d = target - cam_pos
        azimuth = float(np.degrees(np.arctan2(d[1], d[0]))) + SCENE_VIEW_AZIMUTH_DEG
        self._view.set_pose((cam_pos + target) / 2, SCENE_VIEW_DISTANCE * max(span, 0.5), azimuth,
                            SCENE_VIEW_ELEVATION_DEG)
        return self._view.render(scene_option=self._show_people).copy()

    def linear_light(self) -> np.ndarray:
        """The light this frame's exposure collects (H×W×3 linear float32), before noise, gain, the sRGB curve and
        JPEG: what the camera model's noise is computed on (bench/budget.py)."""
        return self._exposure()

    def _exposure(self) -> np.ndarray:
        """The light the sensor collects over the exposure (H×W×3 linear float32): sub-frame renders averaged
        (motion blur, the lights' flicker and dimming), then the lens distortion."""
        scene = self.scene
        samples = self.sensor.samples_for_motion(self._exposure_motion_px())
        self.blur_taps = 1
        if samples > 1 and self.sensor.blur == "field":
            self.blur_samples = 1
            linear = self._field_exposure()
            if self._maps is not None:
                linear = cv2.remap(linear, *self._maps, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
            return linear
        offsets = self.sensor.exposure_offsets(samples)
        self.blur_samples = len(offsets)
        if len(offsets) >= SUBFRAME_SMALL_MIN and self.sensor.blur_subframe_scale > 1 and self.supersample == 1:
            linear = self._small_subframes(offsets)
        else:
            linear = None  # type: ignore[assignment]  # the first sub-frame's render replaces it
            try:
                for dt in offsets:
                    with scene.rewound(float(dt)):
                        self._set_lights(scene.time - float(dt))
                        sub = self._render_linear()
                    linear = sub if linear is None else cv2.add(linear, sub, dst=linear)
            finally:
                self._set_lights(None)
            if len(offsets) > 1:
                linear /= np.float32(len(offsets))
        if self._maps is not None:
            linear = cv2.remap(linear, *self._maps, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        return linear

    def _small_subframes(self, offsets: np.ndarray) -> np.ndarray:
        """The exposure from sub-frames rendered at 1/blur_subframe_scale the size, the middle one at full size too
        (`blur.combine_subframes`; SensorModel.blur_subframe_scale)."""
        scene, scale = self.scene, self.sensor.blur_subframe_scale
        if self._cam_small is None:
            note_rendering()
            self._cam_small = engine.Camera(self.scene.physics, max(1, round(self.height / scale)),
                                            max(1, round(self.width / scale)), self._camera_id)
        option = self._show_people if self.people else self._hide_people
        mid, small = len(offsets) // 2, []
        full = None
        try:
            for j, dt in enumerate(offsets):
                with scene.rewound(float(dt)):
                    self._set_lights(scene.time - float(dt))
                    small.append(decode(self._cam_small.render(scene_option=option)))
                    if j == mid:
                        full = decode(self._render())
        finally:
            self._set_lights(None)
        return combine_subframes(full, small, mid)  # type: ignore[arg-type]  # set at j == mid

    def _field_exposure(self) -> np.ndarray:
        """The exposure as one render at its middle, blurred along each pixel's image motion (`render.blur`)."""
        scene, exposure, k = self.scene, self.sensor.exposure_ms * 1e-3, FIELD_STRIDE
        try:
            with scene.rewound(exposure / 2):
                self._set_lights(scene.time - exposure / 2)
                linear = decode(self._render())
                raw = self._depth_buffer()[::k, ::k]  # of the render just made: no second render
                points = self._field_rays() * self._metres(raw)[..., None]  # camera frame, every k-th pixel
                labels = moving_labels(self, raw, points, k)
                cam_mid, bodies_mid = self._poses()
        finally:
            self._set_lights(None)
        maps = []
        for dt in (exposure, 0.0):  # the exposure's start, then its end (the frame time)
            with scene.rewound(dt):
                cam, bodies = self._poses()
            maps.append([camera_motion(cam_mid, cam)]
                        + [camera_motion(cam_mid, cam, b0, b1) for b0, b1 in zip(bodies_mid, bodies)])
        v = displacement(*motion_paths(points, labels, self.K, *maps), (self.height, self.width), k)
        self.blur_taps = taps_for(v, self.sensor.blur_max_samples)
        return blur_along_paths(linear, v, self.blur_taps) if self.blur_taps > 1 else linear

    def _depth_buffer(self, option=None) -> np.ndarray:
        """(H, W) float32 raw depth buffer (0 near … 1 far), image rows top down: of the render just made, or
        (option) of a new, flat-shaded render of what `option` shows (the depth is the same, the fragments cheaper)."""
        raw = np.empty((self.height, self.width), np.float32)
        if option is None:
            self._read_back(depth=raw)
        else:
            self._draw(option, (mujoco.mjtRndFlag.mjRND_SEGMENT,), depth=raw)
        return np.flipud(raw)

    def _draw(self, option, flags_on: tuple, rgb: np.ndarray | None = None, depth: np.ndarray | None = None) -> None:
        """Render what `option` shows with the render flags `flags_on` set (put back after) and read the buffers asked
        for back (bottom row first): the segmentation and depth passes dm_control's Camera.render would decode in
        full."""
        cam = self._camera()
        cam.update(scene_option=option)
        flags = cam.scene.flags
        saved = [int(flags[k]) for k in flags_on]
        physics = self.scene.physics
        try:
            for k in flags_on:
                flags[k] = 1
            with physics.contexts.gl.make_current() as ctx:
                ctx.call(mujoco.mjr_render, self._rect(), cam.scene.ptr, physics.contexts.mujoco.ptr)
            self._read_back(rgb, depth)
        finally:
            for k, v in zip(flags_on, saved):
                flags[k] = v

    def _read_back(self, rgb: np.ndarray | None = None, depth: np.ndarray | None = None) -> None:
        """The last render's colour and/or depth buffers into `rgb` / `depth` (bottom row first)."""
        physics = self.scene.physics
        with physics.contexts.gl.make_current() as ctx:
            ctx.call(mujoco.mjr_readPixels, rgb, depth, self._rect(), physics.contexts.mujoco.ptr)

    def _rect(self) -> mujoco.MjrRect:
        return mujoco.MjrRect(0, 0, self.width, self.height)

    def _metres(self, raw: np.ndarray) -> np.ndarray:
        """Raw depth buffer values → m along the optical axis, as dm_control's Camera.render(depth=True) has them."""
        m = self.scene.physics.model
        near, far = m.vis.map.znear * m.stat.extent, m.vis.map.zfar * m.stat.extent
        return (near / (1 - raw * (1 - near / far))).astype(np.float32)

    def _moving_bodies(self) -> list:
        """The bodies that move by themselves: the people shown in the frames, then the wall if it slides."""
        bodies = [p.body for p in self.scene.people] if self.people else []
        return bodies + ([self.scene.wall.body] if any(self.scene.scenario.wall_motion) else [])

    def _poses(self) -> tuple[Rigid, list[Rigid]]:
        """The eye camera's pose and the moving bodies' poses now."""
        pose = self.camera_pose()
        bind = self.scene.physics.bind
        bodies = [Rigid(bind(b).xmat.reshape(3, 3).copy(), bind(b).xpos.copy()) for b in self._moving_bodies()]
        return Rigid(pose.R, pose.t), bodies

    def _field_rays(self) -> np.ndarray:
        """The rays of every FIELD_STRIDE-th pixel (made at the first blurred frame)."""
        if self._rays is None:
            self._rays = pixel_rays(self.K, self.width, self.height)[::FIELD_STRIDE, ::FIELD_STRIDE].copy()
        return self._rays

    def still_average(self, n: int) -> np.ndarray:
        """The mean of `n` frames of the scene held still (uint8 RGB), as a user teaching a goal image grabs a
        few frames at the goal and averages them: the camera's noise, which a single frame freezes into a
        template, falls by ~√n (with the JPEG artefacts it causes; those of the clean picture stay). Each frame
        has its own noise (sensor.STILL_STREAM, apart from the episode's frames). The `ideal` camera's
        frames are all the same render."""
        check_number("still frames", n, 1, MAX_STILL_FRAMES, integer=True)
        if self._ideal:
            return self.rgb()
        acc = np.zeros((self.height, self.width, 3), np.float32)
        for frame in self.still_frames(n):
            acc += frame
        return np.rint(acc / np.float32(n)).astype(np.uint8)

    def still_frames(self, n: int) -> Iterator[np.ndarray]:
        """`n` frames (uint8 RGB) of the scene held still, each with its own noise (sensor.STILL_STREAM), as
        still_average averages them: what a tracker sees frame by frame from a camera that does not move."""
        check_number("still frames", n, 1, MAX_STILL_FRAMES, integer=True)
        return self._still_frames(n)

    def _still_frames(self, n: int) -> Iterator[np.ndarray]:
        if self._ideal:
            frame = self.rgb()
            for _ in range(n):
                yield frame.copy()
            return
        scene = self.scene
        linear = self._exposure()  # nothing moves between the frames: one exposure, n captures
        for k in range(n):
            yield self._state.capture(linear, k, scene.time, 1.0 / scene.scenario.fps,  # type: ignore[union-attr]
                                      stream=STILL_STREAM)  # (not ideal: returned above)

    @property
    def noise_seed(self) -> int:
        """The seed of the camera model's noise, drift and light changes: the scene's scenario's unless given."""
        return self.scene.scenario.seed if self._noise_seed is None else self._noise_seed

    def _set_lights(self, t: float | None) -> None:
        """Scale the scene's lights for the camera model's flicker / dimming at time t; None puts them back."""
        if not self.sensor.lights_change:
            return
        k = 1.0 if t is None else light_scale(self.sensor, self.noise_seed, t)
        m = self.scene.physics.model
        m.light_diffuse[:] = self._light0[0] * k
        m.light_ambient[:] = self._light0[1] * k
        m.vis.headlight.diffuse[:] = self._light0[2] * k
        m.vis.headlight.ambient[:] = self._light0[3] * k

    def _exposure_motion_px(self) -> float:
        """Largest image motion during the exposure (`blur.exposure_motion_px`; 0 when nothing can blur)."""
        if self.sensor.exposure_ms <= 0 or self.sensor.blur_max_samples == 1:
            return 0.0
        return exposure_motion_px(self.scene, self.K, self.people, self.sensor.exposure_ms * 1e-3,
                                  (self.width, self.height))

    def transfer(self, corners_from: np.ndarray, corners_to: np.ndarray, pts: np.ndarray) -> np.ndarray:
        """`transfer_points` through this camera's lens (exact with distortion too)."""
        return transfer_points(corners_from, corners_to, pts, self.K, self.sensor.distortion)

    def project(self, pose: CameraPose, points_world: np.ndarray) -> np.ndarray:
        """Where world points appear in this camera's frames: pinhole, then the lens distortion if any."""
        uv = project(self.K, pose, points_world)
        return distort_points(self.K, self.sensor.distortion, uv) if self.sensor.distortion else uv

    def _segment(self, hide_people: bool = False, option=None, box=None) -> tuple[np.ndarray, np.ndarray]:
        """(object id, object type) per pixel of a segmentation render of the (undistorted) view (option: what it
        shows, instead of everything with or without the people; box: (rows, cols) slices, the part decoded).
        MuJoCo's ID colours are read back and decoded here, in `box` only: dm_control's Camera.render decodes the
        whole frame, 8 of its 11 ms at 640×480 (the render itself is 2.4 ms)."""
        if option is None:
            option = self._hide_people if hide_people else self._show_people
        if getattr(self, "_seg_buf", None) is None:
            self._seg_buf = np.empty((self.height, self.width, 3), np.uint8)
        self._draw(option, (mujoco.mjtRndFlag.mjRND_SEGMENT, mujoco.mjtRndFlag.mjRND_IDCOLOR), rgb=self._seg_buf)
        rgb = np.flipud(self._seg_buf)  # the buffer's first row is the image's bottom one
        if box is not None:
            rgb = rgb[box]
        code = rgb[..., 0].astype(np.int32) | (rgb[..., 1].astype(np.int32) << 8) | (rgb[..., 2].astype(np.int32) << 16)
        scn = self._camera().scene
        table = np.full((scn.ngeom + 1, 2), -1, np.int32)  # ID colour (segid + 1; 0: nothing) → (id, type)
        for g in scn.geoms[:scn.ngeom]:
            if g.segid != -1:
                table[g.segid + 1] = (g.objid, g.objtype)
        seg = table[code]
        return seg[..., 0], seg[..., 1]

    def target_mask(self, hide_people: bool = False) -> np.ndarray:
        """Boolean mask of the target's pixels not hidden by anything (by anything but people: hide_people)."""
        ids, types = self._segment(hide_people)
        return (ids == self._target_id) & (types == int(mujoco.mjtObj.mjOBJ_GEOM))

    def target_mask_distorted(self) -> np.ndarray:
        """The target's unhidden pixels in the camera's (distorted) image; equals `target_mask` without distortion."""
        mask = self.target_mask()
        if self._maps is None:
            return mask
        return cv2.remap(mask.astype(np.uint8), *self._maps, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT) > 0

    def camera_pose(self) -> CameraPose:
        """The eye camera's pose now (the scene's forward kinematics), as the projections here take it."""
        pos, R = self.scene.camera_pose_cv()
        return CameraPose(R, pos)

    def target_outline(self, pose: CameraPose, corners_world: np.ndarray | None = None) -> np.ndarray:
        """The target's corners (4, 2) in the undistorted view the segmentation renders show (NaN behind the camera);
        corners_world: `Scene.target_corners_world()` when the caller already has them."""
        return project(self.K, pose, self.scene.target_corners_world() if corners_world is None else corners_world)

    def occlusion_counts(self, outline_px: np.ndarray) -> tuple[int, int]:
        """(visible, full) pixel counts of the target from ONE segmentation render; outline_px: `target_outline`.

        visible: the target's pixels. full: those plus the pixels of people (geom group OCCLUDER_GROUP)
        inside the target's projected outline, rasterised at 1/16 px. Only where a person's outline crosses
        the target's edge can a pixel be counted differently from a second render with the people hidden
        (test_render: within 0.01 of occlusion); with no person on the target the two agree exactly.
        """
        box = outline_box(outline_px, self.width, self.height)
        # the target and the people only (nothing else is ever in front of the target: a render of them shades few
        # fragments), decoded within the target's outline box, where all its pixels are (the counts are those of
        # the whole view; 15 → 3 ms at 640×480 with a person in view); without an outline, the whole frame
        ids, types = self._segment(option=self._target_and_people, box=box)
        is_geom = types == int(mujoco.mjtObj.mjOBJ_GEOM)
        visible = int(np.count_nonzero((ids == self._target_id) & is_geom))
        if not self.scene.people or box is None or ids.size == 0:
            return visible, visible
        person = self._occluder_geom[np.clip(ids, 0, len(self._occluder_geom) - 1)] & is_geom & (ids >= 0)
        return visible, visible + count_inside(person, outline_px, box)

    def people_may_cover_target(self, pose: CameraPose, outline_px: np.ndarray) -> bool:
        """False only when no person's geom can appear over the target in the (undistorted) view
        (`truth.boxes_may_cover`; outline_px: `target_outline`)."""
        if not self.scene.people:
            return False
        return boxes_may_cover(self.scene.physics.model, self.scene.physics.data, self._occluder_geom, pose, self.K,
                               outline_px)

    def ground_truth(self, occlusion: bool = True, counts: bool = True) -> GroundTruth:
        """Projected target geometry and (if asked) the occlusion from one segmentation render
        (`occlusion_counts`). Without occlusion it renders nothing: geometry only, occlusion NaN.
        counts=False (the closed loop needs the fraction only): when no person can be over the target
        (`people_may_cover_target`) the occlusion is 0 exactly, without rendering, and the pixel counts are None."""
        pose = self.camera_pose()
        corners_w = self.scene.target_corners_world()
        corners = self.project(pose, corners_w)
        centre_w = corners_w.mean(axis=0)
        center = self.project(pose, centre_w)[0]
        visible = full = 0
        occ = float("nan")
        outline = self.target_outline(pose, corners_w) if occlusion else None
        # outline is set whenever occlusion is
        if occlusion and not counts and not self.people_may_cover_target(pose, outline):  # type: ignore[arg-type]
            visible = full = None  # type: ignore[assignment]  # not counted (GroundTruth's None)
            occ = 0.0
        elif occlusion:
            visible, full = self.occlusion_counts(outline)  # type: ignore[arg-type]
            occ = 1.0 - visible / full if full > 0 else 1.0
        return GroundTruth(
            frame=self.scene.frame_index, time=self.scene.time, center=center, corners=corners,
            occlusion=occ, visible_px=visible, full_px=full, camera=pose,
            target_depth=float(pose.to_camera(centre_w)[0, 2]), joint_positions=self.scene.joint_positions,
            target_world=corners_w)
