"""`jaxloco render` / `view` (jaxloco.render): replays of sweep rows checked against the
sweep's own table and against MuJoCo's forward kinematics of the replayed states, frame
sizes and motion, the overlay, the GIF the CLI writes, and the one-line errors.

Render tests are skipped when no OpenGL backend can create an offscreen context."""

from __future__ import annotations

import itertools
import math
import os
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest
from typer.testing import CliRunner

from jaxloco.cli import app
from jaxloco.errors import SpecError
from jaxloco.render import gl, video
from jaxloco.render.replay import frame_indices, replay_row
from jaxloco.render.rows import load_row
from jaxloco.sweep import run, spec_from_dict

REPO = Path(__file__).resolve().parents[1]
W, H = 160, 120

SPECS = {
    # TITAN: one gait cycle (6 steps) on the 0.2 m frames every 2 m, two strides
    "titan": {"sweep": {"analysis": "titan.stride", "chunk_size": 2},
              "fixed": {"n_cycles": 1, "map_nx": 80, "map_ny": 60},
              "params": {"l_std": [0.4, 0.5]}},
    # T2 Snake-3: 2 s of the joint-limit run (fixing state, then the first switch)
    "snake": {"sweep": {"analysis": "snake.kv", "chunk_size": 2},
              "fixed": {"horizon": 2.0, "switch_at": 0.5, "delta_t": 0.5},
              "params": {"k_eta": [0.1, 1.0]}},
    # OCTOPUS: the first 3 s of the CLM run towards a 0.3 m step (native MuJoCo)
    "octopus": {"sweep": {"analysis": "octopus.step_climb", "chunk_size": 1, "seeds": [0, 1]},
                "fixed": {"horizon": 3.0, "nthread": 1, "distance_jitter": 0.1, "height": 0.3}},
    # leg-grope: the first 3 s of the simulated cycle on a 15 deg slope (native MuJoCo)
    "leggrope": {"sweep": {"analysis": "leggrope.fragile_walk", "chunk_size": 1},
                 "fixed": {"horizon": 3.0, "nthread": 1},
                 "params": {"theta": [0.0, 0.2617993877991494]}},
}


@pytest.fixture(scope="module")
def gl_ok():
    saved = os.environ.get("MUJOCO_GL")
    try:
        gl.check_context()
    except SpecError as exc:
        pytest.skip(f"no OpenGL context for offscreen rendering: {exc}")
    yield
    if saved is None:
        os.environ.pop("MUJOCO_GL", None)
    else:
        os.environ["MUJOCO_GL"] = saved


@pytest.fixture(scope="module")
def tables(tmp_path_factory):
    """name -> table.parquet of the tiny sweeps in SPECS (run lazily, once). A replay of a
    simulated row reuses the sweep's traced and compiled rollout (tracing the leg-grope
    controller alone takes ~30 s): on the native backend the states are copied from the
    batch, not recorded by the compiled tick."""
    root = tmp_path_factory.mktemp("render")
    made: dict[str, Path] = {}

    def get(name: str) -> Path:
        if name not in made:
            doc = {**SPECS[name], "sweep": {**SPECS[name]["sweep"], "output": str(root / name)}}
            result = run(spec_from_dict(doc, source=name), progress=False)
            made[name] = result.table_path
        return made[name]

    return get


@pytest.fixture(scope="module")
def titan_replay(tables):
    return replay_row(load_row(tables("titan"), 1))


def _metric(replay, name):
    return replay.row.metrics[name]


def _site(data, name):
    return np.array(data.site(name).xpos)


# ----------------------------------------------------------------------------- replays
def test_titan_replay_is_the_rows_plan(titan_replay):
    r = titan_replay
    assert r.row.values["l_std"] == 0.5 and r.mismatches() == []
    assert r.metrics["min_nesm"] == pytest.approx(_metric(r, "min_nesm"), rel=1e-9)
    data = mujoco.MjData(r.model)
    # independent: the trunk's displacement in MuJoCo along the walking direction (map +x,
    # up the slope) over the cycle is the table's distance per cycle (1 cycle, none failed)
    r.set_state(data, 0)
    start = np.array(data.body("body").xpos)
    r.set_state(data, r.n_states - 1)
    end = np.array(data.body("body").xpos)
    slope = r.row.values["slope"]
    d = np.array([math.cos(slope), 0.0, math.sin(slope)])
    assert _metric(r, "n_failures") == 0
    assert (end - start) @ d == pytest.approx(_metric(r, "distance_per_cycle"), abs=1e-9)
    # the legs reach the planned footholds: MuJoCo's foot sites at the end of each step are
    # the plan's foot centres (IK in jaxloco, FK in MuJoCo), relative to the trunk
    from jaxloco.render.kinematic import titan_plan
    from jaxloco.robots.titan import kinematics

    start_state, plan, _, _ = titan_plan(r.row.values)
    feet = np.concatenate([np.asarray(start_state.feet)[None], np.asarray(plan.feet)])
    cog = np.concatenate([np.asarray(start_state.cog)[None], np.asarray(plan.cog)])
    rot = np.array([[math.cos(slope), 0, -math.sin(slope)], [0, 1, 0], [math.sin(slope), 0, math.cos(slope)]])
    per = (r.n_states - 1) // (feet.shape[0] - 1)
    for k in range(feet.shape[0]):
        r.set_state(data, k * per)
        mj = np.stack([_site(data, f"{leg}_foot") for leg in kinematics.LEG_NAMES]) - data.body("body").xpos
        want = (feet[k] - cog[k]) @ rot.T + kinematics.FOOT_RADIUS * rot[:, 2]
        np.testing.assert_allclose(mj, want, atol=1e-5)  # the MJCF stores lengths to ~1e-6 m


def test_snake_replay_matches_table_and_mujoco_kinematics(tables):
    r = replay_row(load_row(tables("snake"), 1))
    assert r.row.values["k_eta"] == 1.0 and r.mismatches() == []
    assert r.n_states == round(2.0 / 0.02) + 1
    data = mujoco.MjData(r.model)
    target = r.markers[0, 0]
    tips, base_z = [], []
    for i in range(r.n_states):
        r.set_state(data, i)
        tips.append(_site(data, "tip"))
        base_z.append([_site(data, f"pair{p}_contact")[2] for p in range(3, 10)])
    # MuJoCo's gripper tip against the held target: the table's largest position error
    err = np.linalg.norm(np.asarray(tips) - target, axis=1)
    assert err.max() == pytest.approx(_metric(r, "max_pos_error"), rel=1e-6, abs=1e-9)
    # the kinematic plant keeps the base part's wheels on the ground z = 0
    np.testing.assert_allclose(base_z, 0.0, atol=1e-9)


def test_octopus_replay_reruns_the_row(tables):
    r = replay_row(load_row(tables("octopus"), 1))
    assert r.row.seed == 1 and r.mismatches() == []
    assert r.metrics["final_x"] == _metric(r, "final_x")  # same run, bit for bit
    data = mujoco.MjData(r.model)
    r.set_state(data, r.n_states - 1)
    chassis = r.model.body("chassis").id
    # the last recorded state's centre of mass (MuJoCo, from the recorded qpos) is the
    # table's final COG; records read the COM one physics substep (2 ms) earlier
    np.testing.assert_allclose(data.subtree_com[chassis][[0, 2]],
                               [_metric(r, "final_x"), _metric(r, "final_z")], atol=2e-3)
    assert r.times[0] == 0.0 and r.times[-1] == pytest.approx(3.0 - 0.1)


def test_leggrope_replay_reruns_the_row(tables):
    r = replay_row(load_row(tables("leggrope"), 1))
    assert r.row.values["theta"] > 0.26 and r.mismatches() == []
    # the torso's tilt change from the recorded qpos: the table's max attitude change
    z = []
    for q in r.qpos[:, 3:7]:
        mat = np.zeros(9)
        mujoco.mju_quat2Mat(mat, q)
        z.append(mat.reshape(3, 3)[:, 2])
    tilt = np.arccos(np.clip(np.asarray(z) @ z[0], -1.0, 1.0))
    assert tilt.max() == pytest.approx(_metric(r, "max_attitude_change"), abs=2e-3)


# ----------------------------------------------------------------------------- frames
def test_frame_selection():
    t = np.arange(1001) * 0.1
    idx = frame_indices(t)
    assert len(idx) == 150 and idx[0] == 0 and idx[-1] == 1000 and np.all(np.diff(idx) > 0)
    assert list(frame_indices(t, seconds=1.0, every=4)) == [0, 4, 8]
    assert list(frame_indices(t, seconds=0.35)) == [0, 1, 2, 3]


def test_frames_have_the_size_and_show_motion(gl_ok, titan_replay):
    idx = frame_indices(titan_replay.times, every=50)
    frames = video.render_frames(titan_replay, idx, width=W, height=H, overlay=False)
    assert len(frames) == len(idx) == 4
    assert all(f.shape == (H, W, 3) and f.dtype == np.uint8 for f in frames)
    diff = [np.abs(a.astype(int) - b.astype(int)).mean() for a, b in itertools.pairwise(frames)]
    assert min(diff) > 0.5  # the robot moves between frames (the camera follows it)


def test_overlay_draws_the_text_box(gl_ok, titan_replay):
    i = [titan_replay.n_states - 1]
    plain = video.render_frames(titan_replay, i, width=W, height=H, overlay=False)[0]
    drawn = video.render_frames(titan_replay, i, width=W, height=H, overlay=True)[0]
    lines = video.overlay_lines(titan_replay, i[0])
    assert lines[0].startswith("titan.stride  row 1/1") and any("min_nesm" in s for s in lines)
    box = (slice(0, 20), slice(0, 60))
    assert np.abs(drawn[box].astype(int) - plain[box].astype(int)).mean() > 10
    np.testing.assert_array_equal(drawn[-10:, -10:], plain[-10:, -10:])  # nothing drawn elsewhere


def test_cli_writes_a_gif(gl_ok, tables, titan_replay, tmp_path):
    from PIL import Image

    out = tmp_path / "titan.gif"
    result = CliRunner().invoke(app, ["render", str(tables("titan")), "--row", "1", "--out", str(out),
                                      "--width", str(W), "--height", str(H), "--every", "30", "--fps", "5"])
    assert result.exit_code == 0, result.output
    n = len(frame_indices(titan_replay.times, every=30))
    assert f"wrote {out}" in result.stdout and "warning" not in result.output
    with Image.open(out) as im:
        assert im.size == (W, H) and im.n_frames == n == 6


@pytest.mark.skipif(not video.has_ffmpeg(), reason="imageio-ffmpeg is not installed")
@pytest.mark.filterwarnings("ignore:os.fork:RuntimeWarning")  # reading the MP4 back runs ffmpeg
def test_cli_writes_an_mp4_and_a_still(gl_ok, tables, titan_replay, tmp_path):
    import imageio.v3 as iio
    from PIL import Image

    table = str(tables("titan"))
    mp4, png = tmp_path / "titan.mp4", tmp_path / "titan.png"
    for out in (mp4, png):
        result = CliRunner().invoke(app, ["render", table, "--row", "1", "--out", str(out), "--width", str(W),
                                          "--height", str(H), "--every", "50"])
        assert result.exit_code == 0, result.output
    assert iio.imread(mp4).shape == (4, H, W, 3)
    with Image.open(png) as im:
        assert im.size == (W, H)
    last = frame_indices(titan_replay.times, every=50)[-1]  # a still is the last frame of the selection
    assert last == 150 and f"a still at t = {titan_replay.times[last]:.1f} s" in result.stdout


# ----------------------------------------------------------------------------- errors
def _error(*args):
    result = CliRunner().invoke(app, list(args))
    lines = result.stderr.strip().splitlines()
    assert result.exit_code == 2 and len(lines) == 1 and lines[0].startswith("error: "), result.output
    return lines[0]


def test_errors_are_one_line(gl_ok, tables, tmp_path, monkeypatch):
    table = str(tables("titan"))
    assert "--row: 5 is out of range" in _error("render", table, "--row", "5", "--out", str(tmp_path / "a.gif"))
    assert "no such file" in _error("render", str(tmp_path / "none.parquet"), "--out", str(tmp_path / "a.gif"))
    assert ".gif, .mp4 or .png" in _error("render", table, "--out", str(tmp_path / "a.avi"))
    assert "--fps" in _error("render", table, "--fps", "0", "--out", str(tmp_path / "a.gif"))
    spec = tmp_path / "sigma.toml"
    spec.write_text('[sweep]\nanalysis = "octopus.terrain_classification"\n[params]\nsigma1 = [0.02, 0.05]\n')
    assert "analysis octopus.terrain_classification has no replay yet" in _error(
        "render", str(spec), "--row", "1", "--out", str(tmp_path / "a.gif"))
    monkeypatch.setattr(video, "has_ffmpeg", lambda: False)
    assert 'pip install "jaxloco[render]"' in _error("render", table, "--out", str(tmp_path / "a.mp4"))
    monkeypatch.setenv("MUJOCO_GL", "bogus")
    assert "MUJOCO_GL=bogus" in _error("render", table, "--out", str(tmp_path / "a.gif"))


def test_view_without_display(monkeypatch, tmp_path):
    monkeypatch.setattr(sys, "platform", "linux")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    line = _error("view", str(tmp_path / "none.toml"), "--row", "0")
    assert "no display" in line and "jaxloco render" in line and "MUJOCO_GL=egl" in line


class FakeViewer:
    """Stands in for mujoco.viewer.launch_passive's handle: records what view shows."""

    def __init__(self, model, data):
        self.model, self.data, self.cam = model, data, mujoco.MjvCamera()
        self.synced, self.texts, self.lookats = [], [], []

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def is_running(self):
        return True

    def lock(self):
        import contextlib

        return contextlib.nullcontext()

    def set_texts(self, texts):
        self.texts.append(texts[2])

    def sync(self):
        self.synced.append(float(self.data.time))
        self.lookats.append(np.array(self.cam.lookat))


def test_view_loops_the_replay(tables, titan_replay, monkeypatch):
    import mujoco.viewer

    from jaxloco.render import viewer

    monkeypatch.setenv("DISPLAY", ":99")
    seen = []
    monkeypatch.setattr(mujoco.viewer, "launch_passive", lambda m, d: seen.append(FakeViewer(m, d)) or seen[-1])
    viewer.view_row(tables("titan"), 1, speed=1e4, every=50, loops=2)
    handle = seen[0]
    times = titan_replay.times[frame_indices(titan_replay.times, every=50)]
    assert handle.synced == pytest.approx(list(times) * 2)  # every state shown, in order, twice
    assert "titan.stride  row 1/1" in handle.texts[0] and handle.cam.distance == pytest.approx(16.0)
    assert not np.allclose(handle.lookats[0], handle.lookats[-1])  # the camera follows the robot


def test_no_headless_gl_at_all(monkeypatch):
    monkeypatch.setattr(sys, "platform", "linux")
    for name in ("MUJOCO_GL", "DISPLAY", "WAYLAND_DISPLAY"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setattr(gl, "probe", lambda backend: (False, f"no {backend} here"))
    with pytest.raises(SpecError, match="MUJOCO_GL=egl failed \\(no egl here\\).*osmesa failed"):
        gl.choose_backend()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glfw without $DISPLAY fails on Linux only")
@pytest.mark.filterwarnings("ignore:os.fork:RuntimeWarning")
def test_unusable_backend_fails_in_one_line(tmp_path):
    """A real failure (glfw with no display), in a subprocess: a failed OpenGL setup
    cannot be undone inside this process."""
    spec = tmp_path / "s.toml"
    spec.write_text('[sweep]\nanalysis = "snake.kv"\n[params]\nk_eta = [0.1]\n')
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env["MUJOCO_GL"] = "glfw"
    done = subprocess.run([sys.executable, "-m", "jaxloco.cli", "render", str(spec), "--out",
                           str(tmp_path / "a.gif")], env=env, capture_output=True, text=True, timeout=120, cwd=REPO,
                          check=False)
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1, done.stderr
    assert lines[0].startswith("error: cannot create an OpenGL context with MUJOCO_GL=glfw")


def test_osmesa_hint_names_libosmesa_and_not_osmesa():
    """The advice after MUJOCO_GL=osmesa failed names the missing library and how to get
    it, and suggests egl instead of osmesa; other backends keep the general hint."""
    for found, state in ((False, "was not found"), (True, "was found but does not work")):
        text = gl.hint("osmesa", osmesa_found=found)
        assert text == (f"libOSMesa (the OSMesa library that MUJOCO_GL=osmesa loads) {state}: install it with "
                        "apt install libosmesa6 (Debian/Ubuntu), dnf install mesa-libOSMesa (Fedora) or "
                        "conda install -c conda-forge mesalib; or use MUJOCO_GL=egl (GPU or headless server)")
        assert "use MUJOCO_GL=osmesa" not in text and "or MUJOCO_GL=osmesa" not in text
    assert gl.hint("egl") == gl.hint("glfw") == gl.HINT


def test_a_failed_osmesa_backend_names_libosmesa(monkeypatch):
    """_bind's one line when importing mujoco's OSMesa backend fails (as it does, with an
    AttributeError from PyOpenGL, when libOSMesa is missing)."""
    from types import SimpleNamespace

    from mujoco.rendering.classic import gl_context

    def no_osmesa(name):
        raise AttributeError("'NoneType' object has no attribute 'glGetError'")

    monkeypatch.setattr(gl_context, "GLContext", None, raising=False)
    monkeypatch.setattr(gl, "importlib", SimpleNamespace(import_module=no_osmesa))
    monkeypatch.setattr(gl, "has_osmesa", lambda: False)
    with pytest.raises(SpecError) as info:
        gl._bind("osmesa")
    assert str(info.value) == (
        "MUJOCO_GL=osmesa cannot be used: AttributeError: 'NoneType' object has no attribute 'glGetError'; "
        + gl.hint("osmesa", osmesa_found=False))


@pytest.mark.skipif(not sys.platform.startswith("linux") or gl.has_osmesa(), reason="needs Linux without libOSMesa")
@pytest.mark.filterwarnings("ignore:os.fork:RuntimeWarning")
def test_osmesa_without_libosmesa_fails_in_one_line(tmp_path):
    """The real failure, in a subprocess (a failed OpenGL setup cannot be undone here)."""
    spec = tmp_path / "s.toml"
    spec.write_text('[sweep]\nanalysis = "snake.kv"\n[params]\nk_eta = [0.1]\n')
    env = dict(os.environ, MUJOCO_GL="osmesa")
    env.pop("PYOPENGL_PLATFORM", None)
    done = subprocess.run([sys.executable, "-m", "jaxloco.cli", "render", str(spec), "--out",
                           str(tmp_path / "a.gif")], env=env, capture_output=True, text=True, timeout=120, cwd=tmp_path,
                          check=False)
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1, done.stderr
    assert lines[0].startswith("error: MUJOCO_GL=osmesa") and "libOSMesa" in lines[0], lines[0]
    assert "apt install libosmesa6" in lines[0] and "use MUJOCO_GL=osmesa" not in lines[0]
