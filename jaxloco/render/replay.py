"""Replaying one sweep row as a sequence of MuJoCo states (qpos and mocap poses per frame).

`replay_row(row)` looks the row's analysis up in `REPLAYS` (name -> "module:function",
imported lazily, like `jaxloco.analysis`) and returns a `Replay`: the model to draw, the
full trajectory (every recorded state, times in seconds from the start), the metrics the
replay itself recomputed, what to write on the frames and where the camera looks.

Two kinds of replay:
  * simulated analyses (`leggrope.fragile_walk`, `octopus.step_climb`, and any other
    analysis with `simulate`): the analysis runs the row once (batch of 1, the row's
    seed) through the same `Analysis.batch_fn` as the sweep, on a simulator
    (`jaxloco.sim.rollout.Simulator`) with the row's backend that records every state
    (`record_state`). The metrics therefore come from the analysis' own code, and the
    states are those its metrics were computed from;
  * kinematic analyses (`jaxloco.render.kinematic`): the robot's own JAX code computes the
    row's trajectory or posture, which is written into the MJCF model's qpos.

Frames: `frame_indices` picks the states to draw: all of them up to `seconds`, every
`every`-th, or (default) at most `MAX_FRAMES` evenly spread over the run, ends included.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from jaxloco.errors import SpecError
from jaxloco.registry import Registry, robot_entries
from jaxloco.render.rows import Row

if TYPE_CHECKING:
    from jaxloco.sim.rollout import Run

MAX_FRAMES = 150  # default cap of a video's frames (a GIF of 480x360 renders in well under a minute)


@dataclass
class Replay:
    """A row replayed as MuJoCo states (numpy; world frame, SI units).

    qpos (T, nq), mocap_pos (T, nmocap, 3) and mocap_quat (T, nmocap, 4) (None: the
    model's own), times (T,) [s]. metrics: what the replay recomputed (a subset of the
    analysis' metrics), status: its status (None: not recomputed). headline: the 2-4
    metrics drawn on the frames. captions: one line per state (phase, step, live
    values) or None. markers: (T, K, 3) world points drawn as spheres (targets) or None.
    track_body: the body whose subtree centre of mass the tracking camera follows.
    """

    row: Row
    model: Any
    qpos: np.ndarray
    times: np.ndarray
    metrics: dict[str, Any]
    status: str | None
    headline: tuple[str, ...]
    kind: str
    mocap_pos: np.ndarray | None = None
    mocap_quat: np.ndarray | None = None
    captions: Sequence[str] | None = None
    markers: np.ndarray | None = None
    marker_rgba: tuple[float, float, float, float] = (0.9, 0.1, 0.1, 0.8)
    marker_size: float = 0.02
    track_body: int | None = None
    camera: dict[str, float] = field(default_factory=dict)  # azimuth, elevation, distance overrides

    def __post_init__(self) -> None:
        self.qpos = np.asarray(self.qpos, float)
        self.times = np.asarray(self.times, float)
        n = self.qpos.shape[0]
        if self.qpos.ndim != 2 or self.qpos.shape[1] != self.model.nq or self.times.shape != (n,):
            raise ValueError(f"replay: qpos {self.qpos.shape} and times {self.times.shape} do not match nq = "
                             f"{self.model.nq}")
        if self.track_body is None:
            self.track_body = root_body(self.model)

    @property
    def n_states(self) -> int:
        return int(self.qpos.shape[0])

    def set_state(self, data: Any, i: int) -> None:
        """Write state i into MjData `data` and run mj_forward (positions, frames, COM)."""
        import mujoco

        data.qpos[:] = self.qpos[i]
        data.qvel[:] = 0.0
        if self.mocap_pos is not None:
            data.mocap_pos[:] = self.mocap_pos[i]
            data.mocap_quat[:] = self.mocap_quat[i]
        data.time = float(self.times[i])
        mujoco.mj_forward(self.model, data)

    def shown_metrics(self) -> dict[str, Any]:
        """The headline metrics to draw: the table's values when the row has them, else
        the replay's."""
        table = self.row.metrics or {}
        return {name: table.get(name, self.metrics.get(name)) for name in self.headline
                if name in table or name in self.metrics}

    def shown_status(self) -> str | None:
        return self.row.status if self.row.status is not None else self.status

    def mismatches(self, rtol: float = 1e-4, atol: float = 1e-6) -> list[str]:
        """Metrics (and the status) on which the replay and the table row disagree."""
        table = self.row.metrics
        if table is None:
            return []
        out = []
        for name, mine in self.metrics.items():
            if name not in table:
                continue
            theirs = table[name]
            if not _close(mine, theirs, rtol, atol):
                out.append(f"{name}: replay {_short(mine)}, table {_short(theirs)}")
        if self.status is not None and self.row.status is not None and self.status != self.row.status:
            out.append(f"status: replay {self.status!r}, table {self.row.status!r}")
        return out


def _short(x: Any) -> str:
    return f"{x:.6g}" if isinstance(x, float) else repr(x)


def _close(a: Any, b: Any, rtol: float, atol: float) -> bool:
    if a is None or b is None:
        return a is b
    if isinstance(a, (bool, np.bool_)) or isinstance(b, (bool, np.bool_)):
        return bool(a) == bool(b)
    a, b = float(a), float(b)
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return math.isclose(a, b, rel_tol=rtol, abs_tol=atol)


def root_body(model: Any) -> int:
    """The root body of the model's first free joint (the robot), else the world (0)."""
    import mujoco

    free = np.flatnonzero(np.asarray(model.jnt_type) == mujoco.mjtJoint.mjJNT_FREE)
    if not free.size:
        return 0
    return int(model.body_rootid[model.jnt_bodyid[free[0]]])


def frame_indices(times: np.ndarray, seconds: float | None = None, every: int | None = None,
                  max_frames: int = MAX_FRAMES) -> np.ndarray:
    """Indices of the states to draw (see the module docstring)."""
    times = np.asarray(times, float)
    n = times.shape[0]
    last = n if seconds is None else int(np.searchsorted(times, times[0] + seconds + 1e-9, side="right"))
    last = max(1, min(n, last))
    if every is not None:
        return np.arange(0, last, int(every))
    count = min(last, max_frames)
    return np.unique(np.round(np.linspace(0, last - 1, count)).astype(int))


def model_copy(model: Any) -> Any:
    """A copy of an MjModel that rendering may modify (lights, framebuffer size)."""
    return copy.deepcopy(model)


# --------------------------------------------------------------------- simulated rows
def run_host_row(row: Row) -> tuple[dict[str, Any], str, Run]:
    """Run a simulated analysis on one row as the sweep does (batch of 1, the row's PRNG
    key, the row's backend) on a simulator that records every state: (metrics, status,
    the first rollout it ran, states included)."""
    from jaxloco.sim.rollout import simulator_for

    analysis = row.analysis
    simulator = simulator_for(row.values, record_state=True)
    out = analysis.batch_fn(dict(row.values), simulator)({}, row.key[None])
    if not simulator.runs:
        raise SpecError(f"analysis {analysis.name} has no replay yet (it ran no simulation for this row)")
    metrics = {m.name: np.asarray(out[m.name])[0].item() for m in analysis.metrics if m.name in out}
    status = analysis.statuses[int(np.asarray(out["status"])[0])]
    return metrics, status, simulator.runs[0]


def _row_params(run: Run, i: int = 0) -> dict[str, Any]:
    return {k: np.asarray(v)[i] for k, v in run.params.items()}


def simulated_model(run: Run) -> Any:
    """A copy of the scenario's model with the row's per-simulation model fields written in."""
    import mujoco

    model = model_copy(run.scenario.model)
    params = _row_params(run)
    set_const = False
    for f in run.scenario.model_fields:
        arr = getattr(model, f.name)
        index = f.index if isinstance(f.index, tuple) else (f.index,)
        arr[index] = np.asarray(f.value(params))
        set_const |= f.needs_set_const
    if set_const:
        mujoco.mj_setConst(model, mujoco.MjData(model))
    return model


def simulated_replay(row: Row, headline: Sequence[str] = (),
                     caption: Callable[[Row, Mapping[str, np.ndarray]], Sequence[str]] | None = None,
                     **extra: Any) -> Replay:
    """The replay of a host analysis (module docstring). caption(row, records) gives one
    line per recorded state from the scenario's own records (without the batch axis)."""
    metrics, status, run = run_host_row(row)
    state = {k: np.asarray(v)[0] for k, v in run.result.states.items()}
    records = {k: np.asarray(v)[0] for k, v in run.result.records.items()}
    headline = tuple(headline) or tuple(m.name for m in row.analysis.metrics[:3])
    return Replay(
        row=row,
        model=simulated_model(run),
        qpos=state["qpos"],
        times=state["time"] - state["time"][0],
        mocap_pos=state["mocap_pos"],
        mocap_quat=state["mocap_quat"],
        metrics=metrics,
        status=status,
        headline=headline,
        kind={"native": "native MuJoCo simulation", "mjx": "MJX simulation"}.get(run.result.backend, "simulation"),
        captions=None if caption is None else list(caption(row, records)),
        **extra,
    )


def octopus_step_climb(row: Row) -> Replay:
    """`octopus.step_climb`, `octopus.paper`: the CLM/CCM climb, captioned with the controller phase."""
    from jaxloco.robots.octopus import ccm, clm

    controller = row.values.get("controller", "clm")
    if "task" in row.values:  # octopus.paper: the task fixes the controller
        from jaxloco.robots.octopus.paper_analysis import TASKS

        controller = TASKS[str(row.values["task"])].controller
    names = clm.PHASE_NAMES if controller == "clm" else ccm.PHASE_NAMES

    def caption(row: Row, records: Mapping[str, np.ndarray]) -> list[str]:
        phase = np.asarray(records["phase"]).astype(int)
        pitch = -np.degrees(np.asarray(records["rpy"])[:, 1])
        x = np.asarray(records["cog"])[:, 0]
        return [f"phase {names[p] if 0 <= p < len(names) else '-'}  pitch {a:+.0f} deg  COG x {c:.2f} m"
                for p, a, c in zip(phase, pitch, x)]

    return simulated_replay(row, ("success", "climb_time", "min_margin", "max_pitch"), caption,
                            camera={"azimuth": 60.0, "elevation": -15.0, "distance": 3.4})


def leggrope_fragile_walk(row: Row) -> Replay:
    """`leggrope.fragile_walk`: the simulated leg-grope cycle, captioned with grope and phase."""
    from jaxloco.robots.leggrope import control

    def caption(row: Row, records: Mapping[str, np.ndarray]) -> list[str]:
        phase = np.asarray(records["phase"]).astype(int)
        leg = np.asarray(records["leg"]).astype(int)
        grope = np.asarray(records["grope"]).astype(int)
        collapsed = np.asarray(records["collapsed"]).astype(int)
        # records["leg"] is the paper's label of the groping leg in the row's numbering
        return [f"grope {min(g, 3) + 1}/4 L{l + 1}  phase {control.PHASES[p]}  collapsed {c}"
                for g, l, p, c in zip(grope, leg, phase, collapsed)]

    return simulated_replay(row, ("success", "completed_gropes", "max_attitude_change", "min_margin"), caption,
                            camera={"azimuth": 150.0, "elevation": -25.0})


def titan_walk(row: Row) -> Replay:
    """`titan.walk`: the planned walk in MuJoCo, captioned with the step, the swinging leg
    and the simulated NE margin."""
    legs = ("LF", "RF", "LR", "RR")

    def caption(row: Row, records: Mapping[str, np.ndarray]) -> list[str]:
        step, swing, nesm = (np.asarray(records[k]) for k in ("step", "swing", "nesm"))
        return [f"step {k + 1}  {'swing ' + legs[u] if u >= 0 else 'COG shift' if k >= 0 else 'settling'}"
                f"  NESM {m:.4f} m" for k, u, m in zip(step.astype(int), swing.astype(int), nesm)]

    return simulated_replay(row, ("success", "sim_min_nesm", "distance", "feet_on_frames"), caption,
                            camera={"azimuth": 135.0, "elevation": -25.0, "distance": 14.0})


def snake_operation(row: Row) -> Replay:
    """`snake.operations`: an operation of T² Snake-3 (Sec. V-D), captioned with the mode
    state, the tip's distance from the operator's intended position and the object."""
    import mujoco

    from jaxloco.robots.snake import operations

    name = str(row.values["operation"])
    fixture = {"pick": ("pipe height", "m", 2), "valve": ("valve", "rad", 0), "door": ("door", "rad", 0)}[name]

    def caption(row: Row, records: Mapping[str, np.ndarray]) -> list[str]:
        error = 1000 * operations.tip_distance(records)
        switching = operations.switching(records)
        thing = np.asarray(records["fixture"])[:, fixture[2]]
        return [f"{name}  {'switching modes' if s else 'fixing state'}  tip error {e:.0f} mm  {fixture[0]} {a:.2f} "
                f"{fixture[1]}" for s, e, a in zip(switching, error, thing)]

    replay = simulated_replay(row, ("success", "max_tip_error", "stalls"), caption,
                              camera={"azimuth": 215.0, "elevation": -20.0, "distance": 1.8})
    replay.track_body = mujoco.mj_name2id(replay.model, mujoco.mjtObj.mjOBJ_BODY, "link1")
    return replay


def generic_host(row: Row) -> Replay:
    """Any other host analysis that runs a `jaxloco.sim` rollout: its first three metrics."""
    return simulated_replay(row)


# -------------------------------------------------------------------------- registry
# Built-in replays come from the robots' entries modules (jaxloco.registry).
REPLAYS: Registry[Callable[[Row], Replay]] = Registry("replay", lambda: robot_entries("REPLAYS"), callable)


def register(name: str, fn: Callable[[Row], Replay]) -> None:
    """Add (or replace) the replay of analysis `name` (plugins, tests)."""
    REPLAYS.register(name, fn)


def replay_fn(analysis: Any) -> Callable[[Row], Replay]:
    """The replay function of an analysis; SpecError (one line) when it has none."""
    name = analysis.name
    if name in REPLAYS:
        return REPLAYS.get(name)
    no_replay = robot_entries("NO_REPLAY")
    if name not in no_replay and analysis.executor == "host":
        return generic_host
    why = f" ({no_replay[name]})" if name in no_replay else ""
    raise SpecError(f"analysis {name} has no replay yet{why}; replays exist for: {', '.join(REPLAYS.names())} and "
                    "simulated (host) analyses")


def replay_row(row: Row) -> Replay:
    """Replay one row (see the module docstring)."""
    from jaxloco import runtime

    fn = replay_fn(row.analysis)
    runtime.configure(x64=row.analysis.x64, cache_dir=True)
    return fn(row)

