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


GL_PROBE_TIMEOUT_S = 60  # a back-end whose probe has not made a context by then is taken as not working
_PROBE = "from mujoco.{0} import GLContext\nc = GLContext(8, 8)\nc.make_current()\nc.free()\n"


def _probe(backend: str) -> bool:
    """Whether `backend` makes a GL context, tried in a child process: a context made here would leave the driver
    initialised in this process, and a process forked from it (gymnasium's AsyncVectorEnv with its default 'fork')
    would then hang for ever making its own."""
    import subprocess
    import sys

    os.environ.setdefault("PYOPENGL_PLATFORM", backend)
    env = {**os.environ, "PYOPENGL_PLATFORM": os.environ["PYOPENGL_PLATFORM"], "MUJOCO_GL": backend}
    try:
        done = subprocess.run([sys.executable, "-c", _PROBE.format(backend)], env=env, capture_output=True,
                              timeout=GL_PROBE_TIMEOUT_S, check=False)
    except (OSError, subprocess.SubprocessError):
        return False
    return done.returncode == 0


_RENDERED_IN: int | None = None  # pid of the process that first rendered with MuJoCo's GL context


def note_rendering() -> None:
    """Called on a render: remembers which process holds GL state."""
    global _RENDERED_IN
    if _RENDERED_IN is None:
        _RENDERED_IN = os.getpid()


def check_not_forked_after_rendering() -> None:
    """A process forked from one that had rendered inherits its GL state half-initialised, and
    creating a new context there hangs for ever (seen with gymnasium's AsyncVectorEnv and the
    default fork start method). Refuse with a clear error instead."""
    if _RENDERED_IN is not None and os.getpid() != _RENDERED_IN:
        raise RenderError(f"this process was forked from process {_RENDERED_IN} after it had rendered with MuJoCo; "
                          "a GL context cannot be created here. Start workers with the 'spawn' method, e.g. "
                          "gymnasium.vector.AsyncVectorEnv(fns, context='spawn') or "
                          "multiprocessing.get_context('spawn')")


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
