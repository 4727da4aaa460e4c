"""Render: the eye camera's frames, its intrinsics and exact ground truth per frame."""

from hvs_sim.gl import configure_gl

configure_gl()  # before anything imports dm_control, which fixes its GL back-end at import
