"""Replaying one row of a sweep in MuJoCo: `jaxloco render` (a GIF, MP4 or PNG with the
row's key metrics drawn on it) and `jaxloco view` (MuJoCo's interactive viewer).

    result = render_row("results/x/table.parquet", row=3, out="run.gif")

Modules: `rows` (a row from a table or from a spec's grid), `replay` (the per-analysis
replay registry; simulated rows rerun on native MuJoCo with their states recorded),
`kinematic` (replays of kinematic analyses from the robots' own JAX code), `video`
(offscreen rendering, overlay, GIF/MP4/PNG), `viewer` (the passive viewer), `gl`
(the OpenGL backend).

Offscreen rendering and MUJOCO_GL: MuJoCo takes its OpenGL backend from MUJOCO_GL
("egl": GPU or headless server; "osmesa": CPU only, slower; "glfw": a desktop). When it
is unset on Linux without a display, rendering sets MUJOCO_GL=egl, and falls back to
osmesa with a message if EGL cannot create a context (`gl.choose_backend`); a value set
by the user is kept, and a backend that fails gives one error line. Importing this
package does not import JAX or MuJoCo.
"""

from __future__ import annotations

from typing import Any


def render_row(*args: Any, **kwargs: Any):
    """`jaxloco.render.video.render_row` (lazy import)."""
    from jaxloco.render.video import render_row as impl

    return impl(*args, **kwargs)


__all__ = ["render_row"]
