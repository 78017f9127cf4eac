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

The executor (pure JAX, `Controller`): after `settle_time`, step k runs from
settle_time + k step_time for `step_time` seconds.
  * body shift (swing -1): the body target moves along the straight line from the
    previous body position to body[k] (smoothstep in time), all four feet held at their
    world positions;
  * swing of leg u (Sec. 6.4.1, rectangular trajectory, body still): the foot centre
    rises along the body z axis (the virtual contact plane's normal) to `swing_height`
    above the higher of its start and target, moves parallel to the plane above the
    target, then descends to the target and PRESS below it; as soon as its touch sensor
    reads more than `contact_force` (fraction of M g) in the descent, the foot target
    stops there ("lower until contact", the unevenness-absorbing gait of Fig. 6);
  * the swing target is offset by the mean in-plane deviation of the supporting feet
    from their targets (slip, the body correction below), so that the foot lands at
    its planned world position;
  * joint targets: `kinematics.legs_inverse_kinematics` of the foot targets in the
    commanded body frame, with the body placed at its target plus a correction `corr`
    that integrates the error of the whole-robot centre of mass (in the plane) and of
    the body origin (along the normal) against the planned body position (gain
    `body_gain` [1/s], at most MAX_CORR per axis): the plan's body position is the
    planner's COG, the legs (450 kg each) move the centre of mass off the trunk's by up
    to ~7 cm, and the servos sag under the 7 t load; likewise the commanded attitude is
    turned by a small rotation `corr_rot` integrating the body attitude error (same
    gain, at most MAX_CORR_ROT per axis): without it the body pitched 0.03 rad down
    the 30 deg slope over four cycles.

Records (every control period): body position and quaternion, rpy, COG (whole-robot
centre of mass), foot centres and their targets, touch forces and contacts, NESM
(`jaxloco.stability.ne_stability_margin` over the planned support's ground points,
`up` against gravity plus tether force), step index, swing leg, clearance of each leg to the
frames (`leg_clearance`: min distance from the leg's thigh, shank and foot to the frame
beams, capsules sampled at N_SAMPLES points; < 0 means penetration) and of each foot
alone (`foot_clearance`).

Metrics (`summarize`): min_nesm (during the plan, over the planned support: every leg
but the swinging one, at the measured foot positions and whole-robot COG; a resting
foot counts even while a touchdown transient briefly unloads it; min_nesm_swing the
same during swings only, i.e. on the three-leg support), nesm_ok
(min_nesm >= s_ne_c - nesm_tol: the servos' compliance costs a few mm), max_touchdown_error (foot centre vs target at the end of each
swing), swing_collision (the swinging leg touched a frame: clearance < 0 while
swinging), min_swing_clearance, forbidden_landing (a foot in contact touching a frame),
max_cycle_error (whole-robot COG vs the planned body position at the ends of cycles, in
the plane), max_path_deviation (that COG off the cycle's path line, in the plane), final_progress (body
displacement along the path), foot_slip (largest horizontal motion of a supporting
foot while it stays in contact), fell (tilt > FELL_TILT or body > FELL_DROP below its
target or diverged), success, status (0 ok, 1 failed).

`demo_crawl_plan` is a hand-made STANDARD intermittent crawl gait for tests and demos
(flat ground or a plain slope, no terrain adaptation): it is NOT the paper's planner
(`gait.py`).
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from jaxloco import geometry as geo
from jaxloco import stability
from jaxloco.robots.titan import kinematics as K
from jaxloco.robots.titan import model as titan_model
from jaxloco.robots.titan import params as P
from jaxloco.sim import metrics as sm
from jaxloco.sim import terrain as tr
from jaxloco.sim.data import SimData, sensor_slice
from jaxloco.sim.scenario import Controller, InitialState, Scenario, friction_field
from jaxloco.sim.scenario import params_batch as sim_params_batch

N_BEAMS = 6  # beams each way
MAX_SPACING = 3.0  # [m]
MAX_BEAM_HEIGHT = 0.3  # [m]
HALF_EXTENT = 12.0  # [m] half size of the ground plane
CONTROL_DT = 0.04  # [s]
PRESS = 0.03  # [m] the descent goes this far below the target if no contact comes first
N_SAMPLES = 16  # points per leg link for the clearance
MAX_CORR = 0.2  # [m] largest body position correction per axis
MAX_CORR_ROT = 0.1  # [rad] largest body attitude correction per axis
FELL_TILT = 0.3  # [rad]
FELL_DROP = 0.5  # [m]
STATUSES = ("ok", "failed")

PARAM_DEFAULTS: dict[str, float] = {
    "theta": 0.0,  # [rad] slope inclination
    "direction": 0.0,  # [rad] uphill azimuth
    "spacing": 2.0,  # [m] frame grid
    "beam_height": 0.0,  # [m] frame protrusion (0: plain ground)
    "mu": 0.6,  # terrain friction
    "tether": 1.0,  # tether force / (M g sin(theta)), up the fall line
    "heading": 0.0,  # [rad] body yaw about the plane normal
    "step_time": 3.0,  # [s] per step (swing or body shift)
    "settle_time": 1.0,  # [s] standing before the first step
    "swing_height": 0.5,  # [m] lift above the higher of start and target
    "contact_force": 0.05,  # touch above this fraction of M g = contact
    "body_gain": 3.0,  # [1/s] integral gain of the body position correction
    "s_ne_c": float(P.S_NE_C),  # [m] critical NE stability margin
    "nesm_tol": 0.005,  # [m] success: min_nesm >= s_ne_c - nesm_tol (servo compliance)
    "touchdown_tol": 0.1,  # [m] success: largest touchdown error
    "path_tol": 0.1,  # [m] success: largest path deviation at cycle ends
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


def hold_plan(n_steps: int, height: float = K.HOME_HEIGHT) -> Plan:
    """Standing still in the home pose at the origin for n_steps body "shifts" of length 0."""
    feet0 = np.asarray(P.NEUTRAL_FEET, float).copy()
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
    l_std: float = float(P.L_STD),
    w_std: float = float(P.W_STD),
    height: float = K.HOME_HEIGHT,
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
    neutral = np.asarray(P.NEUTRAL_FEET, float).copy()
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


# ----------------------------------------------------------------------------- model
def build_model(
    beam_width: float = float(P.FRAME_SMALL),
) -> tuple[mujoco.MjModel, tr.Terrain]:
    """The robot (`models/titan_xi.xml`) on the frames-on-a-plane terrain."""
    spec = titan_model.load_spec()
    terrain = tr.frames_on_slope(
        nx=N_BEAMS,
        ny=N_BEAMS,
        beam_width=beam_width,
        max_spacing=MAX_SPACING,
        max_beam_height=MAX_BEAM_HEIGHT,
        half_length=HALF_EXTENT,
        half_width=HALF_EXTENT,
    )
    terrain.add_to(spec, friction=(PARAM_DEFAULTS["mu"], 0.005, 0.0001))
    return spec.compile(), terrain


def body_quat(theta, direction, heading):
    """Commanded body attitude: z_b along the plane normal, yawed by `heading`."""
    n = tr.slope_normal(theta, direction)
    return tr.quat_mul(tr.quat_tilt(n), tr.quat_z(heading))


def _smooth(s):
    s = jnp.clip(s, 0.0, 1.0)
    return s * s * (3.0 - 2.0 * s)


def _box_distance(points, centres, rots, halves):
    """Signed distance (n_points, n_boxes) from points (n, 3) to oriented boxes."""
    local = jnp.einsum("bji,pbj->pbi", rots, points[:, None, :] - centres[None])
    q = jnp.abs(local) - halves[None]
    outside = jnp.linalg.norm(jnp.maximum(q, 0.0) + 1e-12, axis=-1)
    inside = jnp.minimum(jnp.max(q, axis=-1), 0.0)
    return outside + inside


def make_scenario(
    n_steps: int,
    horizon_s: float | None = None,
    beam_width: float = float(P.FRAME_SMALL),
    record_every: int = 1,
    step_time: float = PARAM_DEFAULTS["step_time"],
    settle_time: float = PARAM_DEFAULTS["settle_time"],
) -> Scenario:
    """The footstep executor for plans of `n_steps` steps. horizon_s default: the plan
    at (step_time, settle_time) plus 1 s (the params may change the timing, not the
    horizon)."""
    m, terrain = build_model(beam_width)
    substeps = round(CONTROL_DT / m.opt.timestep)
    if horizon_s is None:
        horizon_s = settle_time + n_steps * step_time + 1.0
    horizon = round(horizon_s / CONTROL_DT)
    horizon -= horizon % record_every
    mocap = tr.mocap_ids(m, terrain)
    frame_rows = mocap[1:]
    frame_halves = jnp.asarray([p.half_size for p in terrain.pieces[1:]])
    terrain_geoms = np.array([m.geom(n).id for n in terrain.body_names()])
    body_id = m.body("body").id
    foot_sites = np.array([m.site(f"{leg}_foot").id for leg in K.LEG_NAMES])
    hips = np.array([m.body(f"{leg}_hip").id for leg in K.LEG_NAMES])
    knees = np.array([m.body(f"{leg}_shank").id for leg in K.LEG_NAMES])
    touch = [sensor_slice(m, f"{leg}_touch") for leg in K.LEG_NAMES]
    quat_s = sensor_slice(m, "imu_quat")
    mass = float(m.body_subtreemass[body_id])
    weight = mass * float(P.G)
    r_foot = K.FOOT_RADIUS
    radii = jnp.concatenate(
        [
            jnp.full(N_SAMPLES, titan_model.THIGH_RADIUS),
            jnp.full(N_SAMPLES, titan_model.SHANK_RADIUS),
            jnp.full(1, float(P.FOOT_RADIUS)),  # the pad
        ]
    )
    steps = jnp.arange(n_steps)
    lag = jnp.asarray(
        np.tile(np.asarray(titan_model.KV) / np.asarray(titan_model.KP), 4)
    )  # [s]

    def frames(p):
        n = tr.slope_normal(p["theta"], p["direction"])
        R = tr.quat_to_matrix(body_quat(p["theta"], p["direction"], p["heading"]))
        return n, R

    def tether_force(p):
        uphill, _ = tr.slope_axes(p["theta"], p["direction"])
        return p["tether"] * weight * jnp.sin(p["theta"]) * uphill

    def terrain_values(p):
        return {k: p[k] for k in ("theta", "direction", "spacing", "beam_height")}

    def leg_targets(p, feet_c, body_c, rot=None):
        """Joint targets (12,) for foot centres feet_c (4, 3), body position body_c and
        the commanded attitude turned by the small world-frame rotation `rot` (3,)."""
        _, R = frames(p)
        if rot is not None:
            R = geo.rpy_to_matrix(rot[0], rot[1], rot[2]) @ R
        local = (feet_c - body_c[None]) @ R
        q, _ = K.legs_inverse_kinematics(local)
        return q.reshape(-1)

    def initial_state(p, key):
        pos, quat = terrain.place(terrain_values(p), key)
        n, _ = frames(p)
        feet_c = p["plan_feet0"] + r_foot * n
        q = leg_targets(p, feet_c, p["plan_body0"])
        quat_b = body_quat(p["theta"], p["direction"], p["heading"])
        qpos = jnp.concatenate([p["plan_body0"], quat_b, q])
        ctrl = jnp.concatenate([q, tether_force(p)])
        return InitialState(
            qpos=qpos, qvel=jnp.zeros(m.nv), ctrl=ctrl, mocap_pos=pos, mocap_quat=quat
        )

    def observe(data: SimData):
        return {
            "time": data.time,
            "feet": data.site_xpos[foot_sites],
            "touch": jnp.stack([data.sensordata[s][0] for s in touch]),
            "body": data.qpos[:3],
            "com": data.subtree_com[body_id],
            "quat": data.sensordata[quat_s],
        }

    def targets(p, c, obs):
        """Step index, swing leg, foot centre targets (4, 3), body target (3,), whether
        the swing foot is descending, and the next controller state."""
        n, _ = frames(p)
        t = obs["time"] - p["settle_time"]
        k_raw = jnp.floor(t / p["step_time"]).astype(jnp.int32)
        k = jnp.clip(k_raw, -1, n_steps)
        phase = jnp.where(
            (k_raw >= 0) & (k_raw < n_steps), t / p["step_time"] - k_raw, 1.0
        )
        # a new step: bank the previous one (its final targets become the start)
        new = k != c["k"]
        feet_prev = jnp.where(new, c["feet_end"], c["feet"])
        body_prev = jnp.where(new, c["body_end"], c["body"])
        latched = jnp.where(new, False, c["latched"])
        hold = jnp.where(new, c["hold"] * 0.0, c["hold"])
        kk = jnp.clip(k, 0, n_steps - 1)
        active = (k >= 0) & (k < n_steps)
        u = jnp.where(active, p["plan_swing"][kk], -1)
        body_goal = jnp.where(active & (u < 0), p["plan_body"][kk], body_prev)
        body_t = body_prev + (body_goal - body_prev) * _smooth(phase)
        # swing foot (rectangular trajectory along n)
        uu = jnp.maximum(u, 0)
        start = feet_prev[uu]
        # where the supporting feet really are against their targets (in the plane):
        # the offset of the commanded frame from the world (foot slip, the body
        # correction); the swing foot aims off by the same so that it lands at its
        # planned world position
        support = (jnp.arange(4) != u)[:, None]
        drift = jnp.sum(jnp.where(support, obs["feet"] - feet_prev, 0.0), axis=0)
        drift = drift / jnp.sum(support)
        drift = drift - (drift @ n) * n
        goal = p["plan_feet"][kk, uu] + r_foot * n - drift
        top = jnp.maximum(
            jnp.maximum(start @ n, goal @ n) + p["swing_height"],
            p["plan_swing_top"][kk] + r_foot,
        )
        start_top = start + (top - start @ n) * n
        goal_top = goal + (top - goal @ n) * n
        bottom = goal - PRESS * n
        a = 0.25
        up = start + (start_top - start) * _smooth(phase / a)
        across = start_top + (goal_top - start_top) * _smooth((phase - a) / (1 - 2 * a))
        down = goal_top + (bottom - goal_top) * _smooth((phase - (1 - a)) / a)
        descending = (u >= 0) & (phase >= 1 - a)
        foot = jnp.where(phase < a, up, jnp.where(phase < 1 - a, across, down))
        touched = obs["touch"][uu] > p["contact_force"] * weight
        first = descending & touched & ~latched
        hold = jnp.where(first, foot, hold)
        latched = latched | first
        foot = jnp.where(latched, hold, foot)
        feet_t = jnp.where((jnp.arange(4) == u)[:, None], foot[None], feet_prev)
        # where this step ends
        feet_end = jnp.where(
            (jnp.arange(4) == u)[:, None],
            jnp.where(latched, hold, bottom)[None],
            feet_prev,
        )
        state = {
            "k": k,
            "feet": feet_prev,
            "body": body_prev,
            "feet_end": feet_end,
            "body_end": body_goal,
            "latched": latched,
            "hold": hold,
        }
        return k, u, feet_t, body_t, descending, state

    def end_time(p):
        return p["settle_time"] + n_steps * p["step_time"]

    def init(p, obs):
        n, _ = frames(p)
        feet = p["plan_feet0"] + r_foot * n
        body = p["plan_body0"]
        return {
            "k": jnp.asarray(-1, jnp.int32),
            "feet": feet,
            "body": body,
            "feet_end": feet,
            "body_end": body,
            "latched": jnp.asarray(False),
            "hold": jnp.zeros(3, feet.dtype),
            "corr": jnp.zeros(3, feet.dtype),
            "corr_rot": jnp.zeros(3, feet.dtype),
        }

    def step(p, c, obs):
        # the servos' damping acts on the joint speed (MuJoCo position actuators have no
        # speed input): feed the planned speed forward through the position target,
        # ctrl = q(t + dt/2) + (kv / kp) dq/dt, so that kp (ctrl - q) - kv dq = kp (q_d - q)
        # + kv (dq_d - dq); without it the legs lag by (kv / kp) dq (6 cm in a swing) and
        # the lags of the four supporting legs differ, pushing the feet to slip
        _, _, feet_t, body_t, _, state = targets(p, c, obs)
        # integral action (the legs' servo sag under load and the touchdown latches
        # would otherwise add up over the plan; the legs' mass moves the centre of mass
        # off the trunk's): the legs are commanded as if the body were at the target +
        # corr, which drives the whole-robot centre of mass onto the planned COG in the
        # plane and the body origin to its planned height along the normal
        n, _ = frames(p)
        err = body_t - obs["com"]
        err = err + ((obs["com"] - obs["body"]) @ n) * n
        running = (obs["time"] > p["settle_time"]) & (obs["time"] < end_time(p))
        corr = c["corr"] + jnp.where(running, p["body_gain"] * CONTROL_DT * err, 0.0)
        corr = jnp.clip(corr, -MAX_CORR, MAX_CORR)
        # and on the attitude: the small rotation (world frame) from the measured body
        # attitude to the commanded one
        _, R_plan = frames(p)
        M_err = R_plan @ tr.quat_to_matrix(obs["quat"]).T
        e_rot = 0.5 * jnp.array(
            [
                M_err[2, 1] - M_err[1, 2],
                M_err[0, 2] - M_err[2, 0],
                M_err[1, 0] - M_err[0, 1],
            ]
        )
        rot = c["corr_rot"] + jnp.where(
            running, p["body_gain"] * CONTROL_DT * e_rot, 0.0
        )
        rot = jnp.clip(rot, -MAX_CORR_ROT, MAX_CORR_ROT)
        state = {**state, "corr": corr, "corr_rot": rot}
        q0 = leg_targets(p, feet_t, body_t + corr, rot)
        later = {**obs, "time": obs["time"] + CONTROL_DT}
        _, _, feet_1, body_1, _, _ = targets(p, c, later)
        q1 = leg_targets(p, feet_1, body_1 + corr, rot)
        q = 0.5 * (q0 + q1) + lag * (q1 - q0) / CONTROL_DT
        return state, jnp.concatenate([q, tether_force(p)])

    def record(p, data: SimData, obs, c, e):
        n, _ = frames(p)
        k, u, feet_t, body_t, descending, _ = targets(p, c, obs)
        feet = obs["feet"]
        contact = obs["touch"] > p["contact_force"] * weight
        cog = data.subtree_com[body_id]
        g_eff = jnp.array([0.0, 0.0, -weight]) + tether_force(p)  # gravity + tethers
        up = -g_eff / jnp.linalg.norm(g_eff)
        # the support: every leg but the one swinging (a foot resting on the ground is a
        # support point even while touchdown transients briefly unload it)
        support = jnp.arange(4) != u
        nesm = stability.ne_stability_margin(cog, feet - r_foot * n, support, up=up)
        # clearance of each leg to the frame beams
        pts_a, pts_b = data.xpos[hips], data.xpos[knees]
        s = jnp.linspace(0.0, 1.0, N_SAMPLES)
        thigh = pts_a[:, None] + s[None, :, None] * (pts_b - pts_a)[:, None]
        shank = pts_b[:, None] + s[None, :, None] * (feet - pts_b)[:, None]
        pts = jnp.concatenate([thigh, shank, feet[:, None]], axis=1)  # (4, 2S+1, 3)
        rots = tr.quat_to_matrix(data.mocap_quat[frame_rows])
        dist = _box_distance(
            pts.reshape(-1, 3), data.mocap_pos[frame_rows], rots, frame_halves
        )
        dist = jnp.min(dist, axis=1).reshape(4, -1) - radii[None]
        dist = jnp.where(
            p["beam_height"] > 1e-6, dist, jnp.inf
        )  # flush beams: no frames
        return {
            "body_pos": obs["body"],
            "body_quat": obs["quat"],
            "rpy": sm.quat_to_rpy(obs["quat"]),
            "cog": cog,
            "feet": feet,
            "feet_target": feet_t,
            "body_target": body_t,
            "touch": obs["touch"],
            "contact": contact,
            "nesm": nesm,
            "step": k,
            "swing": u,
            "descending": descending,
            "leg_clearance": jnp.min(dist, axis=1),
            "foot_clearance": dist[:, -1],
        }

    def summarize(p, r, final):
        n, _ = frames(p)
        k, u = r["step"], r["swing"]
        running = (k >= 0) & (k < n_steps)
        alive = final.alive
        margin_ok = running
        min_nesm = jnp.where(
            jnp.any(margin_ok), sm.masked_min(r["nesm"], margin_ok), jnp.nan
        )
        on_three = margin_ok & (u >= 0)  # the planned three-leg support of the swings
        min_nesm_swing = jnp.where(
            jnp.any(on_three), sm.masked_min(r["nesm"], on_three), jnp.nan
        )
        # the last record of each step
        idx = jnp.arange(k.shape[0])
        last = jnp.max(
            jnp.where(k[None, :] == steps[:, None], idx[None, :], -1), axis=1
        )  # (n_steps,)
        reached = last >= 0
        lastc = jnp.maximum(last, 0)
        sw = p["plan_swing"]
        swc = jnp.maximum(sw, 0)
        goal = p["plan_feet"][steps, swc] + r_foot * n
        td_err = jnp.linalg.norm(r["feet"][lastc, swc] - goal, axis=-1)
        td_mask = reached & (sw >= 0)
        max_td = sm.masked_max(td_err, td_mask, 0.0)
        # the swinging leg's clearance to the frames
        swinging = running & (u >= 0)
        clear_sw = jnp.take_along_axis(
            r["leg_clearance"], jnp.maximum(u, 0)[:, None], axis=1
        )[:, 0]
        min_clear = sm.masked_min(clear_sw, swinging, jnp.inf)
        collision = jnp.any(swinging & (clear_sw < 0.0))
        forbidden = jnp.any(
            running[:, None] & r["contact"] & (r["foot_clearance"] < 0.0)
        )
        # cycle ends: body vs plan and vs the path line, in the plane
        # the whole-robot centre of mass, in the plane (what the body correction tracks)
        body_end = r["cog"][lastc]
        ce = reached & p["plan_cycle_end"]
        cyc = body_end - p["plan_body"]
        cyc_err = jnp.linalg.norm(cyc - (cyc @ n)[:, None] * n, axis=-1)
        d = p["plan_path_dir"] / jnp.linalg.norm(
            p["plan_path_dir"], axis=-1, keepdims=True
        )  # (n_steps, 3)
        rel = body_end - p["plan_path_origin"]
        along = jnp.sum(rel * d, axis=-1)
        off = rel - along[:, None] * d - (rel @ n)[:, None] * n
        path_dev = jnp.linalg.norm(off, axis=-1)
        max_cyc = sm.masked_max(cyc_err, ce, 0.0)
        max_path = sm.masked_max(path_dev, ce, 0.0)
        # progress along the first step's path direction
        progress = (r["body_pos"][-1] - r["body_pos"][0]) @ d[0]
        # supporting feet slipping: horizontal motion between consecutive records in contact
        both = r["contact"][1:] & r["contact"][:-1]
        dfeet = r["feet"][1:] - r["feet"][:-1]
        dfeet = dfeet - (dfeet @ n)[..., None] * n
        slip = jnp.sum(jnp.where(both, jnp.linalg.norm(dfeet, axis=-1), 0.0), axis=0)
        tilt = sm.tilt_change(r["body_quat"], r["body_quat"][0])
        sag = jnp.max((r["body_target"] - r["body_pos"]) @ n)
        fell = (jnp.max(tilt) > FELL_TILT) | (sag > FELL_DROP) | ~alive
        completed = jnp.all(reached)
        nesm_ok = min_nesm >= p["s_ne_c"] - p["nesm_tol"]
        success = (
            completed
            & ~fell
            & nesm_ok
            & ~collision
            & ~forbidden
            & (max_td < p["touchdown_tol"])
            & (max_path < p["path_tol"])
        )
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

    return Scenario(
        name="titan.footsteps",
        model=m,
        controller=Controller(init, step, name="quasi-static footstep executor"),
        initial_state=initial_state,
        observe=observe,
        record=record,
        summarize=summarize,
        horizon=horizon,
        substeps=substeps,
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
