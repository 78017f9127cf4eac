"""`jaxloco view`: a replay in MuJoCo's interactive passive viewer, looped in real time
(times `speed`), with the overlay text in the viewer's top-left corner.

Needs a display: on Linux without $DISPLAY / $WAYLAND_DISPLAY it refuses with one line
pointing at `jaxloco render` (offscreen, MUJOCO_GL=egl or osmesa). On macOS the passive
viewer needs the script to run under `mjpython`.
"""

from __future__ import annotations

import time
from pathlib import Path

from jaxloco.errors import SpecError
from jaxloco.render import gl

NO_DISPLAY = ("no display ($DISPLAY and $WAYLAND_DISPLAY are unset): `jaxloco view` needs a desktop; write a video "
              "instead with `MUJOCO_GL=egl jaxloco render SPEC_OR_TABLE --row N --out run.gif` (osmesa on CPU-only "
              "machines)")


def check_display() -> None:
    if not gl.has_display():
        raise SpecError(NO_DISPLAY)


def view_row(source: str | Path, row: int, *, speed: float = 1.0, every: int | None = None,
             seconds: float | None = None, loops: int | None = None) -> None:
    """Open the viewer on row `row` of `source` and loop its states until the window is
    closed (or `loops` times)."""
    if not speed > 0:
        raise SpecError(f"--speed: expected a positive factor, got {speed}")
    check_display()
    import mujoco
    import mujoco.viewer

    from jaxloco.render.replay import frame_indices, replay_row
    from jaxloco.render.rows import load_row
    from jaxloco.render.video import make_camera, overlay_lines

    replay = replay_row(load_row(source, row))
    indices = frame_indices(replay.times, seconds, every if every is not None else 1, max_frames=replay.n_states)
    model = replay.model
    data = mujoco.MjData(model)
    camera = make_camera(replay, "track", data, indices)
    try:
        handle = mujoco.viewer.launch_passive(model, data)
    except Exception as exc:  # noqa: BLE001 - a GUI that cannot start is the user's setup
        raise SpecError(f"cannot open the MuJoCo viewer: {type(exc).__name__}: {exc}") from None
    count = 0
    with handle:
        handle.cam.type = camera.cam.type
        handle.cam.distance, handle.cam.azimuth, handle.cam.elevation = (
            camera.cam.distance, camera.cam.azimuth, camera.cam.elevation)
        while handle.is_running() and (loops is None or count < loops):
            start = time.perf_counter()
            t0 = replay.times[indices[0]]
            for i in indices:
                if not handle.is_running():
                    break
                with handle.lock():
                    replay.set_state(data, int(i))
                    handle.cam.lookat[:] = data.subtree_com[replay.track_body]
                handle.set_texts((None, None, "\n".join(overlay_lines(replay, int(i), speed)), None))
                handle.sync()
                wait = (replay.times[i] - t0) / speed - (time.perf_counter() - start)
                if wait > 0:
                    time.sleep(wait)
            count += 1
