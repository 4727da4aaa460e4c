"""Scene: MJCF world (flag wall, Jaco arm or hand-held camera, people) and scenario presets."""

from hvs_sim.gl import configure_gl

configure_gl()  # before anything imports dm_control, which fixes its GL back-end at import


from hvs_sim.scene.scenarios import (  # noqa: F401
    MOUNTS,
    SCENARIO_NAMES,
    CameraConfig,
    OccluderPlan,
    Scenario,
    make_scenario,
)
