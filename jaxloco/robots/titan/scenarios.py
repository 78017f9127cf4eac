"""TITAN XI executing a footstep plan quasi-statically in MuJoCo (Sections 6.4, 7, 8.3,
8.4), as a `jaxloco.sim.Scenario` (native and MJX backends).

Terrain (`jaxloco.sim.terrain.frames_on_slope`, every parameter per simulation): a
plane with inclination `theta` and uphill azimuth `direction` (0: flat ground) carrying
a grid of concrete frames (beams `beam_width` wide, fixed when the model is built: 0.2
or 0.3 m) with `spacing` (Sec. 7: 2.0 or 3.0 m; Sec. 8.4: 1.5 m) and `beam_height` (Sec.
7: 0.2 or 0.3 m; 0 gives plain ground, the beams flush with the plane). N_BEAMS beams
each way, centred on the origin (beam centres at +-spacing/2, +-3 spacing/2, ...).
Friction `mu` on every terrain geom. Tethers (Sec. 8.1): a force `tether` M g sin(theta)
up the fall line at the body (`model.py`: the tether actuators), so `tether` = 1 offsets
the slope-parallel component of gravity exactly.

The plan (fixed-shape arrays, world frame, metres; see `Plan`): `feet0` (4, 3) and
`body0` (3,), the footholds (ground contact points under the foot centres) and the body
position at the start; `feet` (n_steps, 4, 3) and `body` (n_steps, 3) after each step;
`swing` (n_steps,) int, the leg (0 LF, 1 RF, 2 LR, 3 RR, `params.LEG_NAMES`) swung at
that step or -1 for a body (COG) shift; `cycle_end` (n_steps,) bool, the steps that end a
gait cycle (where the COG must be back on the commanded path); `path_origin`,
`path_dir` (3,) or one per step (n_steps, 3), the commanded walking path L_G (a line;
per step: the line of that step's cycle, for changes of direction); `swing_top`
(n_steps,) optional, the planned height of the swing's top (ground point of the foot,
along the plane normal, e.g. the planner's frame clearance; the executor lifts to the
higher of that and its own `swing_height` rule). The body attitude is fixed
for the whole plan: the slope plane's (z_b along its normal) turned by `heading` about
it. `Plan.params()` gives the params entries; `params_batch(n, plan, **scalars)` a batch.

The executor (`control.py`, pure JAX): after `settle_time`, step k runs from
settle_time + k step_time for `step_time` seconds; body shifts move the body along a
straight line, swings follow the rectangular trajectory of Sec. 6.4.1 and stop at
touchdown, and an integral correction drives the whole-robot centre of mass and the
body attitude onto the plan (see there). This module holds the model, the plans and the
scenario's signals (`Layout`, `observe`, `record`, `summarize`), each a module-level
function of the model's `Layout`.

Records (every control period): body position and quaternion, rpy, COG (whole-robot
centre of mass) and the executor's target for it (`cog_target`: the plan's, moved with
the supporting feet, `control.support_shift`), foot centres and their targets, touch forces and contacts, NESM
(`jaxloco.stability.ne_stability_margin` over the planned support's ground points,
`up` against gravity plus tether force), step index, swing leg, clearance of each leg to the
frames (`leg_clearance`: min distance from the leg's thigh, shank and foot to the frame
beams, capsules sampled at N_SAMPLES points; < 0 means penetration) and of each foot
alone (`foot_clearance`).

Metrics (`summarize`): min_nesm (during the plan, over the planned support: every leg
but the swinging one, at the measured foot positions and whole-robot COG; a resting
foot counts even while a touchdown transient briefly unloads it; min_nesm_swing the
same during swings only, i.e. on the three-leg support), nesm_ok
(min_nesm >= s_ne_c - nesm_tol; default 0: the executor keeps the plan's margin,
`control.support_shift`, `control.load_feedforward`),
max_touchdown_error (foot centre vs target at the end of each swing, in the plane: along
the normal the descent stops on contact wherever the ground is, which absorbs a map's
height error), swing_collision (the swinging leg touched a frame: clearance < 0 while
swinging), min_swing_clearance, forbidden_landing (a foot in contact touching a frame),
max_cycle_error (whole-robot COG vs the planned body position at the ends of cycles, in
the plane), max_path_deviation (that COG off the cycle's path line, in the plane), final_progress (body
displacement along the path), foot_slip (largest horizontal motion of a supporting
foot while it stays in contact), fell (tilt > FELL_TILT or body > FELL_DROP below its
target or diverged), success, status (0 ok, 1 failed).

Backends (`make_scenario(..., backend=)`): "native" runs the model as it is; "mjx" its
MJX variant (`mjx_variant`). MJX can collide every pair the model has (the pivot towers,
the only cylinders, are visual; box-box, capsule-box and sphere-box are supported; the
friction cone is pyramidal and there is no no-slip solver), but it has no dynamic broad
phase: it evaluates every robot-terrain pair at every step. On the analysis' grid field
(29 boxes) the trunk, eight leg links and four feet give 696 potential contacts (2,796
constraint rows): 1.8 ms per MJX physics step at batch 1 on a CPU core, against 0.23 ms
for the variant (`benchmarks/titan_mjx_agreement.py --physics`). The variant keeps the
feet only (116 sphere-box pairs there) and MJX's `max_contact_points` keeps the
MJX_MAX_CONTACTS deepest of them in the solver. On the native backend the trunk and the
links touch the terrain only when a walk has already failed (a swinging leg hitting a
frame: `swing_collision`, measured from the geometry on both backends; or a fall); on
MJX they pass through it, so rows that fail that way may go on differently after the
contact. Walks that do not fail agree closely (`docs/simulation.md`).

`demo_crawl_plan` is a hand-made STANDARD intermittent crawl gait for tests and demos
(flat ground or a plain slope, no terrain adaptation): it is NOT the paper's planner
(`gait.py`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from jaxloco import stability
from jaxloco.robots.titan import control, kinematics
from jaxloco.robots.titan import model as titan_model
from jaxloco.robots.titan import params as titan_params
from jaxloco.sim import metrics as sm
from jaxloco.sim import terrain as tr
from jaxloco.sim.backend import BACKENDS
from jaxloco.sim.data import SimData, sensor_slice
from jaxloco.sim.scenario import InitialState, Scenario, friction_field
from jaxloco.sim.scenario import params_batch as sim_params_batch

N_BEAMS = 6  # beams each way
MAX_SPACING = 3.0  # [m]
MAX_BEAM_HEIGHT = 0.3  # [m]
HALF_EXTENT = 12.0  # [m] half size of the ground plane
N_SAMPLES = 16  # points per leg link for the clearance
FELL_TILT = 0.3  # [rad]
FELL_DROP = 0.5  # [m]
STATUSES = ("ok", "failed")
# the MJX variant (`mjx_variant`): the robot's geoms that collide on the native backend only
ROBOT_LINK_GEOMS = ("trunk", *(f"{leg}_{link}" for leg in kinematics.LEG_NAMES for link in ("thigh", "shank")))
MJX_MAX_CONTACTS = 12  # 4 feet x (the plane and the two beams of a crossing)

# one value per simulation (`titan_params.PARAMETERS`); "direction" here is the slope's
# uphill azimuth, not the analyses' walking direction (whose default is also 0)
PARAM_DEFAULTS: dict[str, float] = {
    "theta": titan_params.PARAMETERS.default("theta"),
    "direction": 0.0,  # [rad] uphill azimuth of the slope
    **titan_params.PARAMETERS.defaults((
        "spacing", "beam_height", "mu", "tether", "heading", "step_time", "settle_time", "swing_height",
        "contact_force", "body_gain", "anchor_feet", "support_relative", "load_feedforward", "mass_feedforward",
        "s_ne_c", "nesm_tol", "touchdown_tol", "path_tol",
    )),
}


# ----------------------------------------------------------------------------- plans
@dataclass(frozen=True)
class Plan:
    """A footstep plan (world frame, NumPy; see the module docstring)."""

    feet0: np.ndarray  # (4, 3) ground points under the feet at the start
    body0: np.ndarray  # (3,)
    feet: np.ndarray  # (n_steps, 4, 3)
    body: np.ndarray  # (n_steps, 3)
    swing: np.ndarray  # (n_steps,) int, -1 = body shift
    cycle_end: np.ndarray  # (n_steps,) bool
    path_origin: (
        np.ndarray
    )  # (3,) or (n_steps, 3): a point of L_G (of that step's cycle)
    path_dir: np.ndarray  # (3,) or (n_steps, 3)
    swing_top: np.ndarray | None = None  # (n_steps,) planned top of the swing [m]

    @property
    def n_steps(self) -> int:
        return int(self.swing.shape[0])

    def params(self) -> dict[str, np.ndarray]:
        """The plan's entries of a simulation's params (paths per step)."""
        n = self.n_steps
        top = (
            np.full(n, -np.inf)
            if self.swing_top is None
            else np.asarray(self.swing_top, float)
        )
        return {
            "plan_swing_top": top,
            "plan_path_origin": np.broadcast_to(
                np.asarray(self.path_origin, float), (n, 3)
            ).copy(),
            "plan_path_dir": np.broadcast_to(
                np.asarray(self.path_dir, float), (n, 3)
            ).copy(),
            "plan_feet0": np.asarray(self.feet0, float),
            "plan_body0": np.asarray(self.body0, float),
            "plan_feet": np.asarray(self.feet, float),
            "plan_body": np.asarray(self.body, float),
            "plan_swing": np.asarray(self.swing, np.int32),
            "plan_cycle_end": np.asarray(self.cycle_end, bool),
        }

    def to_world(self, theta: float, direction: float = 0.0) -> Plan:
        """This plan given in slope-frame coordinates (x up the fall line, y across, z
        along the normal; `terrain.slope_axes`) mapped to the world."""
        uphill, across = (np.asarray(a, float) for a in tr.slope_axes(theta, direction))
        normal = np.asarray(tr.slope_normal(theta, direction), float)
        R = np.stack([uphill, across, normal], axis=1)

        def f(x):
            return np.asarray(x, float) @ R.T

        return Plan(
            f(self.feet0),
            f(self.body0),
            f(self.feet),
            f(self.body),
            self.swing,
            self.cycle_end,
            f(self.path_origin),
            f(self.path_dir),
            self.swing_top,
        )


def hold_plan(n_steps: int, height: float = kinematics.HOME_HEIGHT) -> Plan:
    """Standing still in the home pose at the origin for n_steps body "shifts" of length 0."""
    feet0 = np.asarray(titan_params.NEUTRAL_FEET, float).copy()
    feet0[:, 2] = 0.0
    body0 = np.array([0.0, 0.0, height])
    return Plan(
        feet0,
        body0,
        np.broadcast_to(feet0, (n_steps, 4, 3)).copy(),
        np.broadcast_to(body0, (n_steps, 3)).copy(),
        np.full(n_steps, -1, np.int32),
        np.zeros(n_steps, bool),
        body0.copy(),
        np.array([1.0, 0.0, 0.0]),
    )


def demo_crawl_plan(
    n_cycles: int = 1,
    l_std: float = float(titan_params.L_STD),
    w_std: float = float(titan_params.W_STD),
    height: float = kinematics.HOME_HEIGHT,
    start: tuple[float, float] = (0.0, 0.0),
) -> Plan:
    """TEST / DEMO plan, not the paper's planner: the standard intermittent crawl gait
    (Sec. 4.4) along +x on a plane z = 0 with the body never yawing. Per half cycle:
    rear leg, front leg of one side swing forward by 2 l_std, then the COG shifts by
    l_std forward and w_std across (zigzag +-w_std/2 about the path y = start[1]).
    Sequence LR, LF, shift, RR, RF, shift; 6 steps per cycle. At the start the COG sits
    on the right (away from the first swing legs), the left feet are l_std behind
    their neutral position and the right feet at it (the phase of the standard gait)."""
    x0, y0 = start
    neutral = np.asarray(titan_params.NEUTRAL_FEET, float).copy()
    neutral[:, 2] = 0.0
    offset = np.array([x0, y0, 0.0])
    body = np.array([x0, y0 - 0.5 * w_std, height])
    feet = neutral + offset
    feet[[0, 2], 0] -= l_std  # left legs at the rear end of their stroke
    feet0, body0 = feet.copy(), body.copy()
    out_feet, out_body, swing, cyc = [], [], [], []
    for _ in range(n_cycles):
        for side_legs, lateral in (((2, 0), +1.0), ((3, 1), -1.0)):
            for leg in side_legs:
                feet = feet.copy()
                feet[leg, 0] += 2.0 * l_std
                out_feet.append(feet)
                out_body.append(body.copy())
                swing.append(leg)
                cyc.append(False)
            body = body + np.array([l_std, lateral * w_std, 0.0])
            out_feet.append(feet.copy())
            out_body.append(body.copy())
            swing.append(-1)
            cyc.append(lateral < 0)
    return Plan(
        feet0,
        body0,
        np.stack(out_feet),
        np.stack(out_body),
        np.asarray(swing, np.int32),
        np.asarray(cyc, bool),
        # the path: the COG's mean line, through the cycle-end COG positions
        np.array([x0, y0 - 0.5 * w_std, height]),
        np.array([1.0, 0.0, 0.0]),
    )


CONTROL_DT = control.CONTROL_DT  # [s] the executor's control period


# ----------------------------------------------------------------------------- model
class FrameField(NamedTuple):
    """The simulated beams (`terrain.frames_on_slope`, centred on the origin): `n_along`
    beams along x spaced across, `n_across` beams across spaced along x, `max_spacing`
    [m] (the beams' length; a smaller `spacing` param makes them overhang), and the half
    length and width [m] of the ground plane."""

    n_along: int = N_BEAMS
    n_across: int = N_BEAMS
    max_spacing: float = MAX_SPACING
    half_length: float = HALF_EXTENT
    half_width: float = HALF_EXTENT


def mjx_variant(spec: mujoco.MjSpec) -> None:
    """Make `spec` (the robot on its terrain) the MJX variant, in place: only the feet
    collide (the trunk's and leg links' contype and conaffinity set to 0) and MJX keeps
    the MJX_MAX_CONTACTS deepest contacts (its `max_contact_points`; MuJoCo's C engine
    ignores it). See the module docstring, "Backends"."""
    for geom in spec.geoms:
        if geom.name in ROBOT_LINK_GEOMS:
            geom.contype, geom.conaffinity = 0, 0
    spec.add_numeric(name="max_contact_points", data=[float(MJX_MAX_CONTACTS)])


def build_model(
    beam_width: float = float(titan_params.FRAME_SMALL), field: FrameField = FrameField(), backend: str = "native"
) -> tuple[mujoco.MjModel, tr.Terrain]:
    """The robot (`models/titan_xi.xml`) on the frames-on-a-plane terrain `field`; backend
    "mjx": its MJX variant (`mjx_variant`)."""
    if backend not in BACKENDS:
        raise ValueError(f"backend: expected one of {', '.join(BACKENDS)}, got {backend!r}")
    spec = titan_model.load_spec()
    terrain = tr.frames_on_slope(
        nx=field.n_along,
        ny=field.n_across,
        beam_width=beam_width,
        max_spacing=field.max_spacing,
        max_beam_height=MAX_BEAM_HEIGHT,
        half_length=field.half_length,
        half_width=field.half_width,
    )
    terrain.add_to(spec, friction=(PARAM_DEFAULTS["mu"], 0.005, 0.0001))
    if backend == "mjx":
        mjx_variant(spec)
    return spec.compile(), terrain


def _box_distance(points, centres, rots, halves):
    """Signed distance (n_points, n_boxes) from points (n, 3) to oriented boxes."""
    local = jnp.einsum("bji,pbj->pbi", rots, points[:, None, :] - centres[None])
    q = jnp.abs(local) - halves[None]
    outside = jnp.linalg.norm(jnp.maximum(q, 0.0) + 1e-12, axis=-1)
    inside = jnp.minimum(jnp.max(q, axis=-1), 0.0)
    return outside + inside


class Layout(NamedTuple):
    """Where the scenario's signals are in the compiled model (static, NumPy / Python)."""

    terrain: tr.Terrain
    body_id: int
    foot_sites: np.ndarray  # (4,) site ids
    hips: np.ndarray  # (4,) body ids
    knees: np.ndarray  # (4,) body ids (shanks)
    touch: tuple  # 4 sensor slices
    quat: slice  # IMU quaternion sensor slice
    frame_rows: np.ndarray  # mocap rows of the frame beams
    frame_halves: np.ndarray  # (n_beams, 3) beam half sizes
    weight: float  # M g [N]
    n_steps: int


def model_layout(m: mujoco.MjModel, terrain: tr.Terrain, n_steps: int) -> Layout:
    """The `Layout` of the compiled model `m` with `terrain`, for plans of n_steps."""
    body_id = m.body("body").id
    return Layout(
        terrain=terrain,
        body_id=body_id,
        foot_sites=np.array([m.site(f"{leg}_foot").id for leg in kinematics.LEG_NAMES]),
        hips=np.array([m.body(f"{leg}_hip").id for leg in kinematics.LEG_NAMES]),
        knees=np.array([m.body(f"{leg}_shank").id for leg in kinematics.LEG_NAMES]),
        touch=tuple(sensor_slice(m, f"{leg}_touch") for leg in kinematics.LEG_NAMES),
        quat=sensor_slice(m, "imu_quat"),
        frame_rows=tr.mocap_ids(m, terrain)[1:],
        frame_halves=np.asarray([piece.half_size for piece in terrain.pieces[1:]]),
        weight=float(m.body_subtreemass[body_id]) * float(titan_params.G),
        n_steps=n_steps,
    )


def _terrain_values(p) -> dict:
    return {k: p[k] for k in ("theta", "direction", "spacing", "beam_height")}


def initial_state(lay: Layout, nv: int, p, key) -> InitialState:
    """Standing on the plan's start footholds, the terrain placed from params p."""
    pos, quat = lay.terrain.place(_terrain_values(p), key)
    n, _ = control.frames(p)
    feet = p["plan_feet0"] + kinematics.FOOT_RADIUS * n
    body = control.body_for_com(p, feet, p["plan_body0"])
    q = control.leg_targets(p, feet, body)
    quat_b = control.body_quat(p["theta"], p["direction"], p["heading"])
    qpos = jnp.concatenate([body, quat_b, q])
    ctrl = jnp.concatenate([q, control.tether_force(p, lay.weight)])
    return InitialState(qpos=qpos, qvel=jnp.zeros(nv), ctrl=ctrl, mocap_pos=pos, mocap_quat=quat)


def observe(lay: Layout, data: SimData) -> dict:
    """What the executor senses: time, foot centres, foot touch forces, body position,
    whole-robot centre of mass and the IMU quaternion."""
    return {
        "time": data.time,
        "feet": data.site_xpos[lay.foot_sites],
        "touch": jnp.stack([data.sensordata[s][0] for s in lay.touch]),
        "body": data.qpos[:3],
        "com": data.subtree_com[lay.body_id],
        "quat": data.sensordata[lay.quat],
    }


def leg_frame_clearance(lay: Layout, p, data: SimData, feet: jax.Array) -> jax.Array:
    """Clearance (4, 2 N_SAMPLES + 1) of each leg's thigh and shank samples and foot pad
    to the frame beams [m] (< 0: penetration; inf on plain ground)."""
    pts_a, pts_b = data.xpos[lay.hips], data.xpos[lay.knees]
    s = jnp.linspace(0.0, 1.0, N_SAMPLES)
    thigh = pts_a[:, None] + s[None, :, None] * (pts_b - pts_a)[:, None]
    shank = pts_b[:, None] + s[None, :, None] * (feet - pts_b)[:, None]
    pts = jnp.concatenate([thigh, shank, feet[:, None]], axis=1)  # (4, 2S+1, 3)
    rots = tr.quat_to_matrix(data.mocap_quat[lay.frame_rows])
    dist = _box_distance(pts.reshape(-1, 3), data.mocap_pos[lay.frame_rows], rots, jnp.asarray(lay.frame_halves))
    radii = jnp.concatenate(
        [
            jnp.full(N_SAMPLES, titan_model.THIGH_RADIUS),
            jnp.full(N_SAMPLES, titan_model.SHANK_RADIUS),
            jnp.full(1, float(titan_params.FOOT_RADIUS)),
        ]
    )
    dist = jnp.min(dist, axis=1).reshape(4, -1) - radii[None]
    return jnp.where(p["beam_height"] > 1e-6, dist, jnp.inf)  # flush beams: no frames


def record(lay: Layout, p, data: SimData, obs, c: control.ExecutorState, e) -> dict:
    """One record (module docstring, "Records")."""
    n, _ = control.frames(p)
    now, _ = control.step_targets(p, lay.n_steps, lay.weight, c, obs)
    feet = obs["feet"]
    cog = data.subtree_com[lay.body_id]
    g_eff = jnp.array([0.0, 0.0, -lay.weight]) + control.tether_force(p, lay.weight)  # gravity + tethers
    # the support: every leg but the one swinging (a foot resting on the ground is a
    # support point even while touchdown transients briefly unload it)
    support = jnp.arange(4) != now.swing
    nesm = stability.ne_stability_margin(
        cog, feet - kinematics.FOOT_RADIUS * n, support, up=-g_eff / jnp.linalg.norm(g_eff)
    )
    dist = leg_frame_clearance(lay, p, data, feet)
    return {
        "body_pos": obs["body"],
        "body_quat": obs["quat"],
        "rpy": sm.quat_to_rpy(obs["quat"]),
        "cog": cog,
        "feet": feet,
        "feet_target": now.feet,
        "body_target": now.body,
        "cog_target": c.target,
        "touch": obs["touch"],
        "contact": obs["touch"] > p["contact_force"] * lay.weight,
        "nesm": nesm,
        "step": now.k,
        "swing": now.swing,
        "descending": now.descending,
        "leg_clearance": jnp.min(dist, axis=1),
        "foot_clearance": dist[:, -1],
    }


def _cycle_end_errors(p, r, n, last, ce):
    """Largest in-plane error of the whole-robot COG against the planned body position
    and against the cycle's path line, at the cycle ends `ce`, and the path directions."""
    body_end = r["cog"][last]  # the whole-robot centre of mass (what the body correction tracks)
    cyc = body_end - p["plan_body"]
    cyc_err = jnp.linalg.norm(cyc - (cyc @ n)[:, None] * n, axis=-1)
    d = p["plan_path_dir"] / jnp.linalg.norm(p["plan_path_dir"], axis=-1, keepdims=True)  # (n_steps, 3)
    rel = body_end - p["plan_path_origin"]
    along = jnp.sum(rel * d, axis=-1)
    off = rel - along[:, None] * d - (rel @ n)[:, None] * n
    path_dev = jnp.linalg.norm(off, axis=-1)
    return sm.masked_max(cyc_err, ce, 0.0), sm.masked_max(path_dev, ce, 0.0), d


def summarize(lay: Layout, p, r, final) -> dict:
    """The metrics (module docstring, "Metrics") of one simulation's records r."""
    n, _ = control.frames(p)
    steps = jnp.arange(lay.n_steps)
    k, u = r["step"], r["swing"]
    running = (k >= 0) & (k < lay.n_steps)
    min_nesm = jnp.where(jnp.any(running), sm.masked_min(r["nesm"], running), jnp.nan)
    on_three = running & (u >= 0)  # the planned three-leg support of the swings
    min_nesm_swing = jnp.where(jnp.any(on_three), sm.masked_min(r["nesm"], on_three), jnp.nan)
    # the last record of each step
    idx = jnp.arange(k.shape[0])
    last = jnp.max(jnp.where(k[None, :] == steps[:, None], idx[None, :], -1), axis=1)  # (n_steps,)
    reached = last >= 0
    lastc = jnp.maximum(last, 0)
    sw = p["plan_swing"]
    swc = jnp.maximum(sw, 0)
    goal = p["plan_feet"][steps, swc] + kinematics.FOOT_RADIUS * n
    miss = r["feet"][lastc, swc] - goal
    td_err = jnp.linalg.norm(miss - (miss @ n)[:, None] * n, axis=-1)  # in the plane
    max_td = sm.masked_max(td_err, reached & (sw >= 0), 0.0)
    # the swinging leg's clearance to the frames
    swinging = running & (u >= 0)
    clear_sw = jnp.take_along_axis(r["leg_clearance"], jnp.maximum(u, 0)[:, None], axis=1)[:, 0]
    min_clear = sm.masked_min(clear_sw, swinging, jnp.inf)
    collision = jnp.any(swinging & (clear_sw < 0.0))
    forbidden = jnp.any(running[:, None] & r["contact"] & (r["foot_clearance"] < 0.0))
    max_cyc, max_path, d = _cycle_end_errors(p, r, n, lastc, reached & p["plan_cycle_end"])
    # progress along the first step's path direction
    progress = (r["body_pos"][-1] - r["body_pos"][0]) @ d[0]
    # supporting feet slipping: horizontal motion between consecutive records in contact
    both = r["contact"][1:] & r["contact"][:-1]
    dfeet = r["feet"][1:] - r["feet"][:-1]
    dfeet = dfeet - (dfeet @ n)[..., None] * n
    slip = jnp.sum(jnp.where(both, jnp.linalg.norm(dfeet, axis=-1), 0.0), axis=0)
    tilt = sm.tilt_change(r["body_quat"], r["body_quat"][0])
    sag = jnp.max((r["body_target"] - r["body_pos"]) @ n)
    fell = (jnp.max(tilt) > FELL_TILT) | (sag > FELL_DROP) | ~final.alive
    completed = jnp.all(reached)
    nesm_ok = min_nesm >= p["s_ne_c"] - p["nesm_tol"]
    success = (completed & ~fell & nesm_ok & ~collision & ~forbidden & (max_td < p["touchdown_tol"])
               & (max_path < p["path_tol"]))
    return {
        "success": success,
        "min_nesm": min_nesm,
        "nesm_ok": nesm_ok,
        "min_nesm_swing": min_nesm_swing,
        "max_touchdown_error": max_td,
        "swing_collision": collision,
        "min_swing_clearance": min_clear,
        "forbidden_landing": forbidden,
        "max_cycle_error": max_cyc,
        "max_path_deviation": max_path,
        "final_progress": progress,
        "foot_slip": jnp.max(slip),
        "max_tilt": jnp.max(tilt),
        "max_sag": sag,
        "fell": fell,
        "completed": completed,
        "status": jnp.where(success, 0, 1),
    }


def make_scenario(
    n_steps: int,
    horizon_s: float | None = None,
    beam_width: float = float(titan_params.FRAME_SMALL),
    record_every: int = 1,
    step_time: float = PARAM_DEFAULTS["step_time"],
    settle_time: float = PARAM_DEFAULTS["settle_time"],
    field: FrameField = FrameField(),
    backend: str = "native",
) -> Scenario:
    """The footstep executor (`control.py`) for plans of `n_steps` steps on the beams
    `field`, for `backend` ("native" or "mjx": the model's MJX variant, `mjx_variant`).
    horizon_s default: the plan at (step_time, settle_time) plus 1 s (the params may
    change the timing, not the horizon)."""
    m, terrain = build_model(beam_width, field, backend)
    lay = model_layout(m, terrain, n_steps)
    if horizon_s is None:
        horizon_s = settle_time + n_steps * step_time + 1.0
    horizon = round(horizon_s / CONTROL_DT)
    horizon -= horizon % record_every
    terrain_geoms = np.array([m.geom(name).id for name in terrain.body_names()])
    return Scenario(
        name="titan.footsteps",
        model=m,
        controller=control.make_controller(n_steps, lay.weight),
        initial_state=partial(initial_state, lay, m.nv),
        observe=partial(observe, lay),
        record=partial(record, lay),
        summarize=partial(summarize, lay),
        horizon=horizon,
        substeps=round(CONTROL_DT / m.opt.timestep),
        record_every=record_every,
        model_fields=(friction_field(terrain_geoms),),
        statuses=STATUSES,
    )


def params_batch(
    plans: Plan | list[Plan], n: int | None = None, **overrides
) -> dict[str, jax.Array]:
    """A batch of parameter dicts: one plan for all n simulations or one plan per
    simulation (a list of plans with the same n_steps), with the scalar parameters'
    defaults and `overrides` (scalars, or arrays of length n)."""
    plans = [plans] if isinstance(plans, Plan) else list(plans)
    if n is None:
        n = len(plans)
    if len(plans) not in (1, n):
        raise ValueError(f"params_batch: {len(plans)} plans for {n} simulations")
    if len({pl.n_steps for pl in plans}) != 1:
        raise ValueError("params_batch: every plan needs the same number of steps")
    out = sim_params_batch(PARAM_DEFAULTS, n, overrides)
    rows = [pl.params() for pl in plans]
    for key in rows[0]:
        arr = (
            np.stack([r[key] for r in rows])
            if len(rows) == n
            else np.broadcast_to(rows[0][key], (n, *rows[0][key].shape))
        )
        out[key] = jnp.asarray(arr)
    return out
