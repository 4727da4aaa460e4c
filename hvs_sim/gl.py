"""Pick a headless OpenGL back-end for MuJoCo before dm_control is imported.

dm_control reads MUJOCO_GL once, at import. If the user set it we respect it; otherwise we try
EGL, then OSMesa, and raise a RenderError that says what to install when neither starts.
"""

from __future__ import annotations

import os

from hvs_sim.errors import RenderError

_INSTALL_HINT = (
    "install an EGL driver (Debian/Ubuntu: apt-get install libegl1 libgl1-mesa-dri) "
    "or OSMesa (apt-get install libosmesa6), or set MUJOCO_GL to a working back-end"
)


def _probe(backend: str) -> bool:
    try:
        if backend == "egl":
            os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
            from mujoco.egl import GLContext
        else:
            os.environ.setdefault("PYOPENGL_PLATFORM", "osmesa")
            from mujoco.osmesa import GLContext
        ctx = GLContext(8, 8)
        ctx.make_current()
        ctx.free()
        return True
    except Exception:  # noqa: BLE001 - any failure means "this back-end is not usable here"
        return False


def configure_gl() -> str:
    """Make sure MUJOCO_GL names a working headless back-end and return it."""
    chosen = os.environ.get("MUJOCO_GL")
    if chosen:
        return chosen
    for backend in ("egl", "osmesa"):
        if _probe(backend):
            os.environ["MUJOCO_GL"] = backend
            return backend
        os.environ.pop("PYOPENGL_PLATFORM", None)
    raise RenderError(f"no headless OpenGL back-end works (tried egl, osmesa): {_INSTALL_HINT}")
