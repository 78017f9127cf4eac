"""Frames of a replay (offscreen MuJoCo rendering) with the row's key metrics drawn on
them, written as a GIF (Pillow), an MP4 (imageio + imageio-ffmpeg) or a PNG still.

Cameras (`--camera`): "track" (default: follows the centre of mass of the robot's root
body subtree from the replay's preferred azimuth and elevation), "side", "front", "top"
(the same tracking camera from fixed directions), "free" (a still camera framing the
whole run), or the name of a camera of the model. Distance: the replay's preference, else
about three times the robot's radius; tracking cameras aim a little (LIFT x distance)
above the centre of mass, so that the robot sits below the overlay. The empty background (depth at the far plane) is
painted with a light sky gradient; the headlight is brightened (the MJCF models have no
lights of their own).

Overlay (top left, semi-transparent box): analysis, row, seed; the swept parameters;
time (the speed-up of the video over the motion, the frame number); the replay's caption (phase,
step); status; the 2-4 headline metrics (the table's values when the row has them).
"""

from __future__ import annotations

import importlib.util
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from jaxloco import paths
from jaxloco.errors import SpecError
from jaxloco.render.replay import Replay, frame_indices

CAMERAS = ("track", "side", "front", "top", "free")
LIFT = 0.08  # tracking cameras aim LIFT x distance above the robot's centre of mass
SUFFIXES = (".gif", ".mp4", ".png")
SKY_TOP = np.array([168.0, 190.0, 216.0])
SKY_BOTTOM = np.array([232.0, 236.0, 242.0])
MP4_HINT = 'writing .mp4 needs imageio-ffmpeg: pip install "jaxloco[render]" (or write a .gif)'


# ---------------------------------------------------------------------------- options
def has_ffmpeg() -> bool:
    """Whether imageio can write MP4 (the imageio-ffmpeg package is installed)."""
    return importlib.util.find_spec("imageio_ffmpeg") is not None


def check_options(*, fps: int = 15, width: int = 480, height: int = 360, every: int | None = None,
                  seconds: float | None = None, out: Path | None = None) -> None:
    """One SpecError line for a bad command-line value."""
    if fps < 1 or fps > 120:
        raise SpecError(f"--fps: expected 1..120, got {fps}")
    for name, value in (("--width", width), ("--height", height)):
        if value < 16 or value > 4096:
            raise SpecError(f"{name}: expected 16..4096 pixels, got {value}")
    if every is not None and every < 1:
        raise SpecError(f"--every: expected an integer >= 1, got {every}")
    if seconds is not None and not (seconds > 0 and math.isfinite(seconds)):
        raise SpecError(f"--seconds: expected a positive number of seconds, got {seconds}")
    if out is not None and out.suffix.lower() not in SUFFIXES:
        raise SpecError(f"--out: expected a .gif, .mp4 or .png file name, got '{out}'")
    if out is not None:
        paths.exists(out, where="--out")  # a name the system refuses fails now, not after the replay


# ---------------------------------------------------------------------------- camera
def robot_radius(model: Any, data: Any, root: int) -> float:
    """Radius [m] of the robot (geoms of bodies under `root`) about its centre of mass."""
    bodies = np.asarray(model.body_rootid)[np.asarray(model.geom_bodyid)]
    mine = bodies == root if root > 0 else np.ones(model.ngeom, bool)
    if not mine.any():
        return float(model.stat.extent)
    centre = data.subtree_com[root]
    dist = np.linalg.norm(data.geom_xpos[mine] - centre, axis=1) + np.asarray(model.geom_rbound)[mine]
    return float(np.max(dist))


@dataclass
class Camera:
    """A MuJoCo camera and how it follows the replay (`update(data)` before each frame)."""

    cam: Any
    track_body: int | None
    lift: float = 0.0  # [m] the camera aims this far above the tracked point (the overlay covers the top)

    def update(self, data: Any) -> None:
        if self.track_body is not None:
            self.cam.lookat[:] = data.subtree_com[self.track_body]
            self.cam.lookat[2] += self.lift


def make_camera(replay: Replay, name: str, data: Any, indices: Sequence[int]) -> Camera:
    """The camera `name` (module docstring) for `replay`; SpecError for an unknown name."""
    import mujoco

    model = replay.model
    cam = mujoco.MjvCamera()
    if name not in CAMERAS:
        cam_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, name)
        if cam_id < 0:
            own = [model.camera(i).name for i in range(model.ncam)]
            listed = ", ".join(CAMERAS + tuple(own))
            raise SpecError(f"--camera: unknown camera '{name}' (choose from: {listed})")
        cam.type = mujoco.mjtCamera.mjCAMERA_FIXED
        cam.fixedcamid = cam_id
        return Camera(cam, None)
    replay.set_state(data, int(indices[0]))
    root = int(replay.track_body)
    pref = replay.camera
    distance = float(pref.get("distance", 3.0 * robot_radius(model, data, root)))
    azimuth = float(pref.get("azimuth", 135.0))
    elevation = float(pref.get("elevation", -20.0))
    if name == "side":
        azimuth, elevation = 90.0, -10.0
    elif name == "front":
        azimuth, elevation = 180.0, -15.0
    elif name == "top":
        elevation = -89.0
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.distance, cam.azimuth, cam.elevation = distance, azimuth, elevation
    if name != "free":
        return Camera(cam, root, float(pref.get("lift", LIFT * distance)))
    path = []
    for i in indices:
        replay.set_state(data, int(i))
        path.append(np.array(data.subtree_com[root]))
    path = np.asarray(path)
    lo, hi = path.min(axis=0), path.max(axis=0)
    cam.lookat[:] = 0.5 * (lo + hi)
    cam.distance = max(distance, 1.3 * float(np.linalg.norm(hi - lo)))
    return Camera(cam, None)


def _add_markers(scene: Any, points: np.ndarray, rgba: Sequence[float], size: float) -> None:
    import mujoco

    for p in np.asarray(points, float).reshape(-1, 3):
        if scene.ngeom >= scene.maxgeom:
            return
        mujoco.mjv_initGeom(scene.geoms[scene.ngeom], mujoco.mjtGeom.mjGEOM_SPHERE, np.array([size, 0.0, 0.0]),
                            p, np.eye(3).reshape(-1), np.asarray(rgba, np.float32))
        scene.ngeom += 1


# ---------------------------------------------------------------------------- overlay
def _fmt(value: Any, unit: str = "") -> str:
    if value is None:
        return "-"
    if isinstance(value, (bool, np.bool_)):
        return "yes" if value else "no"
    if isinstance(value, (int, np.integer)):
        text = str(int(value))
    elif isinstance(value, (float, np.floating)):
        text = "nan" if math.isnan(value) else f"{value:.4g}"
    else:
        text = str(value)
    return f"{text} {unit}".strip() if unit and unit not in ("", "1") else text


def _wrap(parts: Sequence[str], width: int) -> list[str]:
    lines, line = [], ""
    for part in parts:
        if line and len(line) + 2 + len(part) > width:
            lines.append(line)
            line = part
        else:
            line = f"{line}  {part}" if line else part
    if line:
        lines.append(line)
    return lines


def overlay_lines(replay: Replay, i: int, speed: float | None = None, width_chars: int = 60,
                  frame: tuple[int, int] | None = None) -> list[str]:
    """The text drawn on state `i` (module docstring); `frame` = (k, n): frame k of n."""
    row = replay.row
    analysis = row.analysis
    units = {p.name: p.unit for p in analysis.params} | {m.name: m.unit for m in analysis.metrics}
    lines = [f"{analysis.name}  row {row.index}/{row.n_rows - 1}  seed {row.seed}"]
    lines += _wrap([f"{n} = {_fmt(row.values[n], units.get(n, ''))}" for n in row.swept if n in row.values],
                   width_chars)
    t, total = float(replay.times[i]), float(replay.times[-1])
    clock = f"t = {t:.1f} / {total:.1f} s"
    if speed is not None and speed > 1.05:
        clock += f"  ({speed:.3g}x)"
    if frame is not None:  # also keeps consecutive frames distinct (a GIF writer merges equal ones)
        clock += f"  frame {frame[0] + 1}/{frame[1]}"
    lines.append(clock)
    if replay.captions is not None:
        lines.append(str(replay.captions[i]))
    status = replay.shown_status()
    if status is not None:
        lines.append(f"status: {status}")
    lines += _wrap([f"{n} = {_fmt(v, units.get(n, ''))}" for n, v in replay.shown_metrics().items()], width_chars)
    return lines


def font_size(height: int) -> int:
    return max(8, round(height / 30))


def draw_overlay(frame: np.ndarray, lines: Sequence[str], size: int | None = None) -> np.ndarray:
    """`frame` (H, W, 3) uint8 with `lines` in a semi-transparent box at the top left."""
    from PIL import Image, ImageDraw, ImageFont

    h, w = frame.shape[:2]
    size = size or font_size(h)
    try:
        font = ImageFont.load_default(size=size)
    except TypeError:  # Pillow without FreeType sizes
        font = ImageFont.load_default()
    base = Image.fromarray(np.ascontiguousarray(frame)).convert("RGBA")
    layer = Image.new("RGBA", base.size, (0, 0, 0, 0))
    draw = ImageDraw.Draw(layer)
    pad, step = max(2, size // 3), size + max(1, size // 5)
    widths = [draw.textlength(line, font=font) for line in lines]
    box_w = min(w - 1, int(max(widths, default=0)) + 2 * pad)
    box_h = min(h - 1, len(lines) * step + 2 * pad)
    draw.rectangle([0, 0, box_w, box_h], fill=(0, 0, 0, 150))
    for k, line in enumerate(lines):
        draw.text((pad, pad + k * step), line, font=font, fill=(255, 255, 255, 255))
    return np.asarray(Image.alpha_composite(base, layer).convert("RGB"))


def overlay_width_chars(width: int, size: int) -> int:
    return max(20, int(width / (0.55 * size)) - 2)


# ---------------------------------------------------------------------------- rendering
def _light(model: Any) -> None:
    model.vis.headlight.ambient[:] = 0.45
    model.vis.headlight.diffuse[:] = 0.55
    model.vis.headlight.specular[:] = 0.15


def _sky(height: int, width: int) -> np.ndarray:
    rows = np.linspace(0.0, 1.0, height)[:, None, None]
    grad = SKY_TOP[None, None] * (1.0 - rows) + SKY_BOTTOM[None, None] * rows
    return np.broadcast_to(grad, (height, width, 3)).astype(np.uint8)


def render_frames(replay: Replay, indices: Sequence[int], *, width: int = 480, height: int = 360,
                  camera: str = "track", overlay: bool = True, fps: int = 15) -> list[np.ndarray]:
    """RGB frames (H, W, 3) uint8 of the replay's states `indices`."""
    import mujoco

    from jaxloco.render import gl

    indices = [int(i) for i in indices]
    model = replay.model
    _light(model)
    data = mujoco.MjData(model)
    cam = make_camera(replay, camera, data, indices)
    renderer = gl.make_renderer(model, height, width)
    far = float(model.vis.map.zfar * model.stat.extent)
    sky = _sky(height, width)
    size = font_size(height)
    chars = overlay_width_chars(width, size)
    frames = []
    try:
        for k, i in enumerate(indices):
            replay.set_state(data, i)
            cam.update(data)
            renderer.update_scene(data, cam.cam)
            if replay.markers is not None:
                _add_markers(renderer.scene, replay.markers[i], replay.marker_rgba, replay.marker_size)
            rgb = np.array(renderer.render())
            renderer.enable_depth_rendering()
            depth = renderer.render()
            renderer.disable_depth_rendering()
            rgb = np.where((depth >= 0.999 * far)[..., None], sky, rgb)
            if overlay:
                speed = None
                if len(indices) > 1:
                    j = min(k + 1, len(indices) - 1)
                    dt = (replay.times[indices[j]] - replay.times[indices[j - 1]])
                    speed = float(dt * fps) if dt > 0 else None
                rgb = draw_overlay(rgb, overlay_lines(replay, i, speed, chars, (k, len(indices))), size)
            frames.append(rgb)
    finally:
        renderer.close()
    return frames


# ---------------------------------------------------------------------------- files
def write_frames(path: Path, frames: Sequence[np.ndarray], fps: int = 15) -> None:
    """A .gif (Pillow, looping; Pillow merges identical consecutive frames into one longer
    frame), .mp4 (imageio-ffmpeg, H.264) or .png (the last frame)."""
    from PIL import Image

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise SpecError(f"--out: expected a .gif, .mp4 or .png file name, got '{path}'")
    if not frames:
        raise SpecError("no frames to write (is --seconds shorter than the first frame?)")
    if suffix == ".mp4" and not has_ffmpeg():
        raise SpecError(MP4_HINT)
    path.parent.mkdir(parents=True, exist_ok=True)
    if suffix == ".png":
        Image.fromarray(frames[-1]).save(path)
    elif suffix == ".gif":
        images = [Image.fromarray(f) for f in frames]
        images[0].save(path, save_all=True, append_images=images[1:], duration=round(1000 / fps), loop=0)
    else:
        import imageio.v2 as imageio

        with warnings.catch_warnings():  # JAX warns about any fork; ffmpeg is fork + exec
            warnings.filterwarnings("ignore", message="os.fork", category=RuntimeWarning)
            with imageio.get_writer(str(path), format="FFMPEG", mode="I", fps=fps, codec="libx264",
                                    pixelformat="yuv420p", macro_block_size=2) as writer:
                for f in frames:
                    writer.append_data(f)


@dataclass(frozen=True)
class RenderResult:
    path: Path
    n_frames: int
    width: int
    height: int
    fps: int
    replay: Replay
    indices: np.ndarray

    @property
    def span(self) -> float:
        """Motion time covered by the frames [s]."""
        return float(self.replay.times[self.indices[-1]] - self.replay.times[self.indices[0]])


def render_row(source: str | Path, row: int, out: str | Path, *, fps: int = 15, width: int = 480,
               height: int = 360, camera: str = "track", every: int | None = None,
               seconds: float | None = None) -> RenderResult:
    """Replay row `row` of the sweep `source` (spec or table) and write `out`."""
    from jaxloco.render import gl
    from jaxloco.render.replay import replay_row
    from jaxloco.render.rows import load_row

    out = Path(out)
    check_options(fps=fps, width=width, height=height, every=every, seconds=seconds, out=out)
    if out.suffix.lower() == ".mp4" and not has_ffmpeg():  # before the replay, which takes a while
        raise SpecError(MP4_HINT)
    gl.check_context()  # sets MUJOCO_GL if needed (before mujoco is imported); fails before the long replay
    loaded = load_row(source, row)
    replay = replay_row(loaded)
    indices = frame_indices(replay.times, seconds, every)
    if out.suffix.lower() == ".png":  # a still: the last frame only
        indices = indices[-1:]
    frames = render_frames(replay, indices, width=width, height=height, camera=camera, fps=fps)
    write_frames(out, frames, fps)
    return RenderResult(out, len(frames), width, height, fps, replay, indices)
