"""The OCTOPUS getting over steps (paper, "Tasks setting" and "Experimental setting") as
`jaxloco.sim.Scenario`s, native backend.

Kinds (terrain `jaxloco.sim.terrain.steps`, risers across +x, the robot starts on the
floor at the origin heading +x, yawed by `yaw`):
  * "step1": a one-terrace step of total height `height` (paper: 400 mm);
  * "step2_front": two terraces of `height` / 2 each, `TERRACE_DEPTH` deep, from the front;
  * "step2_side": two terraces whose heights differ under the left (y > 0) and right
    crawlers: total `height` on the left, `side_ratio` * `height` on the right (the
    paper's "from the side" task, where the terraces under the two crawlers differ);
  * "block": rough-ground test of the paper ("Passing through rough road", Figs. 19-20):
    a concrete block of `height` (paper: 500 mm), `BLOCK_SIZE` long and wide, standing
    `block_gap` (paper: about 10 mm) beside the robot's right side (its right crawler
    wheels, `ROBOT_SIDE`), its near face at x = `distance`; the right arms run into it;
  * "flat": the floor only (`tr.flat`);
  * "pit": the robot starts on a platform of `height` whose far edge is at x =
    `distance`; beyond it there is no ground (a deep pit: the arm stop Case 3, "a new
    target point will be selected"). Success: the robot stays on the platform, its COG
    short of the edge.
Every terrain parameter is per simulation (mocap poses, no recompiling): `height`,
`distance` (x of the first riser, i.e. horizontal distance from the chassis origin {R}
to the step edge at t = 0), `yaw` (initial heading [rad]), `side_ratio`, and `mu` (the
terrain friction, a `ModelField` on the terrain geoms' sliding friction).

Observation (what a controller sees): time, IMU quaternion, flipper angles and torques,
arm joint angles and torques, crawler track speeds, the contact-point sites
(`CONTACT_SITES`: crawler end axles, flipper tips, arm rollers) in the world frame,
`touch` [N] (MuJoCo touch sensors: the normal contact force on every wheel and roller,
`SUPPORT_TOUCH`, in `SUPPORT_BODIES` order: first those of the CONTACT_SITES in that
order, i.e. the main end wheels, flipper tip wheels and rollers, then the other wheels)
and `track_load` [N] (2 sides x 3 segments of the bottom line: rear flipper, main
crawler, front flipper; the summed touch of the wheels on the segment, `SEGMENT_WHEELS`).
Records: rpy (IMU), chassis position, COG, flipper angles and torques, arm joint angles
and torques, touch (every wheel and roller), track_load, `contact_points` (N, 3) and
their `contact` mask (N,): the support set below, N = len(SUPPORT_BODIES) = 28 in
`SUPPORT_BODIES` order, so [:len(CONTACT_SITES)] are the wheels and rollers of the
CONTACT_SITES in that order and the arm rollers the last N_ARM_SITES of those (unlike
the observation's `contact_points`, the sites themselves, these are points on the
terrain: an arm entry is where its roller touches, not the roller centre), controller
phase (if it has one).

Support set (`contact_points`, `contact`): every wheel and roller (`SUPPORT_BODIES`, 28)
at its contact point, the point of the terrain nearest to its centre
(`terrain_contacts`; the terrain is a union of boxes placed from the same parameters as
the simulated one, so for a sphere touching it this is where it touches, as MuJoCo puts
it within 1 mm): centre - radius * z on a flat top, the corner on a step edge, the face
on a riser. (The centre projected to its lowest point, centre - radius * z, is exact on
flat ground only: on an edge the corner lies up to a radius, 90 mm, horizontally from
the centre; in a CLM climb of a 200 mm step wheels rest on the edge 27-48 mm from their
centres' vertical.) A wheel or roller counts when it carries a normal force above
`LOAD_MIN` (its touch sensor) or is seated, within `SEAT_TOL` of the terrain (distance
from its centre minus its radius). The second case is for the MuJoCo
artefact of a rigid body on many soft contacts: its load distribution is indeterminate
and contacts that touch (gap < 0.5 mm) often carry nothing while their neighbours take
the load (CCM stance on flat ground: the rear end wheels 0 N, 0.06 mm up; in a CCM climb
a whole crawler side 0 N, 0.02-0.07 mm up, which left the support polygon a line). A
roller hovering a few mm above the ground is no support. The robot collides with the
terrain only (never with itself), and its wheels and rollers are the parts meant to
touch it, so the loaded or seated ones are its whole support (the chassis box, booms
or forearms resting on an edge would not be in the set). The crawler bottom line
between two wheels touches nothing in the model (sphere wheels, no belt), so there are
no edge contacts between wheels: a wheel resting on a step edge is a support point at
the edge.

Metrics (`summarize`): success (the COG ends `pass_distance` beyond the last riser on top
of the step, no tipping: max |roll| < `roll_limit`, max nose-up pitch < `pitch_limit` over
the run, no divergence), max_pitch (nose up), max_abs_roll, min_margin (static stability
margin over the support set, the loaded or seated wheels and rollers, samples with
>= 3 of them, `jaxloco.sim.metrics.support_margins`), climb_time (first time the success
position holds), shortfall (how far the COG still had to go, at its nearest, to the
success line: 0 once there), final_x, final_z, tipped, status (0 ok, 1 failed), arm_over_obstacle
(an arm roller carried load on top of an obstacle, >= OBSTACLE_MIN above the floor, and
later on the floor again: the block task's arm sequence, Figs. 19-20).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from jaxloco.robots.octopus import ccm, clm, model, operator, params
from jaxloco.sim import metrics as sm
from jaxloco.sim import terrain as tr
from jaxloco.sim.data import SimData, sensor_slice
from jaxloco.sim.scenario import Controller, InitialState, Scenario, friction_field
from jaxloco.sim.scenario import params_batch as sim_params_batch

KINDS = ("step1", "step2_front", "step2_side", "block", "flat", "pit")
TERRACE_DEPTH = 0.8  # [m] depth of the first terrace of the two-terrace steps
MAX_HEIGHT = params.MAX_HEIGHT  # [m] highest step the terrain boxes allow
PIT_PLATFORM = 5.0  # [m] length of the platform the robot starts on in "pit" (its far edge at `distance`)
PIT_BOTTOM = -10.0  # [m] the "height" reported beyond the pit's edge (there is no ground there)
# How far the robot can drive within the longest horizon a sweep allows, at the crawlers'
# top speed [m]: every terrain reaches this far beyond its start, ahead and to the sides,
# so that a long run ends where the robot drove, not over the edge of the world. (Until
# 7 Dec 2026 the step tops were 5 m long and the steps 2 m wide: the CCM, at 63 mm/s,
# drove off the top of a step it had climbed after about 95 s, and every such run of a
# 150 s sweep ended "diverged".)
REACH = params.PARAMETERS["horizon"].hi * params.CRAWLER_MAX_SPEED + 2.0
# the block (the paper gives its height only): a 0.5 m concrete cube
BLOCK_SIZE = 0.5  # [m] length (x) and width (y)
ROBOT_SIDE = params.CRAWLER_Y + params.MAIN_WHEEL_RADIUS  # [m] |y| of the crawlers' outer side
OBSTACLE_MIN = 0.1  # [m] an arm contact this high above the floor is on top of an obstacle
FLOOR_TOL = 0.02  # [m] an arm contact this low is on the floor
# Normal force a contact must carry to count as support [N]: 1 % of the weight, default
# (ours). At rest on flat ground in the CLM start pose (Table 2, arms on the ground) the
# least loaded roller carries 19.7 N (2.0 % of the weight; the four carry 20-34 N), so
# 2 % would drop it; a hovering roller carries 0. 9.8 N is half that and twice the
# roller's own weight (4.9 N).
LOAD_MIN = 0.01 * params.TOTAL_MASS * params.G
# A wheel or roller this close to the terrain counts even when it carries less [m],
# default (ours): in CCM / CLM runs on flat ground and steps the gaps of unloaded contacts
# within 20 mm of the terrain cluster below 0.5 mm (touching, the load on neighbouring
# contacts; contact penetration is 0.1-0.7 mm) and spread from 1 to 20 mm (lifting,
# hovering).
SEAT_TOL = 0.001
CONTACT_SITES = (
    tuple(f"crawler_{s}_{e}" for s in "lr" for e in ("front", "rear"))
    + tuple(f"{f}_tip" for f in params.FLIPPER_NAMES)
    + tuple(f"{a}_tip" for a in params.ARM_NAMES)
)
N_ARM_SITES = 4  # the last CONTACT_SITES are the arm roller centres
# the arm rollers among the CONTACT_SITES, hence also among the support set (SUPPORT_BODIES order)
# and the touch sensors (`model.touch_names` order), which both start with them
ROLLERS = slice(len(CONTACT_SITES) - N_ARM_SITES, len(CONTACT_SITES))
# the touch sensors of the CONTACT_SITES, in that order (`model.touch_names`): main
# end wheels, flipper tip wheels, rollers
CONTACT_TOUCH = tuple(n.removesuffix("_tip") + "_touch" for n in CONTACT_SITES)
# every touch sensor (one per wheel and roller), `model.touch_names` order: those of
# the CONTACT_SITES (CONTACT_TOUCH), then the other wheels
SUPPORT_TOUCH = model.touch_names()
# the wheel and roller bodies of the SUPPORT_TOUCH sensors, in that order: the support set
_BODY_OF_TOUCH = {model.touch_name(b): b for b in
                  [w for s in "lr" for w in model.wheel_names(s)] + [f"{a}_roller" for a in params.ARM_NAMES]}
SUPPORT_BODIES = tuple(_BODY_OF_TOUCH[n] for n in SUPPORT_TOUCH)
# the wheel bodies of each segment of the bottom line (`track_load`): side (l, r) x (rear
# flipper, main crawler, front flipper); a flipper segment has the flipper's wheels and
# the main end wheel it pivots on
SEGMENT_WHEELS = tuple(
    (tuple(f"flipper_r{s}_w{k + 1}" for k in range(params.FLIPPER_WHEELS)) + (f"wheel_{s}1",),
     tuple(f"wheel_{s}{k + 1}" for k in range(params.MAIN_WHEELS)),
     (f"wheel_{s}{params.MAIN_WHEELS}",) + tuple(f"flipper_f{s}_w{k + 1}" for k in range(params.FLIPPER_WHEELS)))
    for s in "lr"
)
STATUSES = ("ok", "failed")

PARAM_DEFAULTS: dict[str, float] = {
    # terrain and physics
    "height": params.PARAMETERS.default("height"),  # [m] total step height
    "distance": params.PARAMETERS.default("distance"),  # [m] chassis origin to the first riser at t = 0
    "yaw": params.PARAMETERS.default("yaw"),  # [rad] initial heading
    "side_ratio": params.PARAMETERS.default("side_ratio"),  # step2_side: right rise / left rise
    "block_gap": params.PARAMETERS.default("block_gap"),  # [m] block: gap between the robot's right side and the block
    "mu": params.PARAMETERS.default("mu"),  # terrain friction
    # success test
    "pass_distance": 0.3,  # [m] the COG beyond the last riser (paper: S = 0.3 m)
    "roll_limit": 0.5,  # [rad]
    "pitch_limit": 1.2,  # [rad] nose up
    # controllers (the CCM baseline, the CLM and the operator layer; their keys do not overlap)
    **ccm.PARAM_DEFAULTS,
    **clm.PARAM_DEFAULTS,
    **operator.PARAM_DEFAULTS,
}


def build_model(kind: str) -> tuple[mujoco.MjModel, tr.Terrain]:
    """The robot (`models/octopus.xml`) with the terrain of `kind`."""
    if kind not in KINDS:
        raise ValueError(f"kind: expected one of {', '.join(KINDS)}, got {kind!r}")
    spec = model.load_spec()
    if kind == "flat":
        terrain = tr.flat(half_extent=REACH, half_depth=0.5)
    elif kind == "block":
        terrain = tr.blocks(n=1, half_size=(0.5 * BLOCK_SIZE, 0.5 * BLOCK_SIZE, 0.5 * MAX_HEIGHT),
                            floor_half_extent=REACH)
    elif kind == "pit":
        terrain = tr.steps(n_terraces=1, max_height=MAX_HEIGHT, last_length=PIT_PLATFORM, half_width=REACH)
    else:  # the last terrace's top reaches REACH beyond the riser; the floor, behind, the start
        terrain = tr.steps(n_terraces=1 if kind == "step1" else 2, depth=TERRACE_DEPTH, max_height=MAX_HEIGHT,
                           last_length=REACH, half_width=REACH)
    terrain.add_to(spec, friction=(PARAM_DEFAULTS["mu"], 0.005, 0.0001))
    return spec.compile(), terrain


def _heights(kind: str, p) -> tuple[jax.Array, jax.Array]:
    """Total rise of the left and right staircases [m]."""
    h = jnp.asarray(p["height"], jnp.result_type(float))
    if kind in ("flat", "block"):  # no steps to climb
        return 0.0 * h, 0.0 * h
    if kind == "step2_side":
        return h, h * p["side_ratio"]
    return h, h


def terrain_values(kind: str, p) -> dict[str, jax.Array]:
    """The terrain placement values of one simulation's params."""
    if kind == "flat":
        return {"height": 0.0 * jnp.asarray(p["height"], jnp.result_type(float))}
    if kind == "block":
        h = jnp.asarray(p["height"], jnp.result_type(float))
        return {
            "block0_x": p["distance"] + 0.5 * BLOCK_SIZE,
            "block0_y": -(ROBOT_SIDE + p["block_gap"] + 0.5 * BLOCK_SIZE),
            "block0_height": h,
            "block0_yaw": 0.0 * h,
        }
    left, right = _heights(kind, p)
    start = jnp.asarray(p["distance"], left.dtype) - (PIT_PLATFORM if kind == "pit" else 0.0)
    return {"height_left": left, "height_right": right, "start": start}


def terrain_height(kind: str, p, xy: jax.Array) -> jax.Array:
    """Terrain surface height [m] below the points xy (..., 2) (world frame)."""
    left, right = _heights(kind, p)
    if kind == "flat":
        return jnp.zeros(xy.shape[:-1], left.dtype)
    if kind == "block":
        dx = xy[..., 0] - p["distance"]
        dy = -(ROBOT_SIDE + p["block_gap"]) - xy[..., 1]
        inside = (dx >= 0.0) & (dx <= BLOCK_SIZE) & (dy >= 0.0) & (dy <= BLOCK_SIZE)
        return jnp.where(inside, jnp.asarray(p["height"], left.dtype), 0.0)
    if kind == "pit":  # the platform up to its edge, then nothing
        return jnp.where(xy[..., 0] <= p["distance"], left, PIT_BOTTOM)
    n = 1 if kind == "step1" else 2
    rise = jnp.where(xy[..., 1] >= 0.0, left, right)
    x = xy[..., 0] - p["distance"]
    terraces = jnp.clip(jnp.floor(x / TERRACE_DEPTH) + 1.0, 0.0, n) if n > 1 else jnp.where(x >= 0.0, 1.0, 0.0)
    return rise * terraces / n


def terrain_contacts(terrain: tr.Terrain, values, centres: jax.Array, radii) -> tuple[jax.Array, jax.Array]:
    """Contact points of spheres (centres (N, 3), radii (N,) [m], world frame) with the
    terrain placed by `values` (`terrain_values`): for each sphere the point of the
    terrain (a union of boxes, `terrain.place`) nearest to its centre, and its gap [m]
    (distance from the centre minus the radius; < 0: penetrating). For a sphere that
    touches the terrain this is where it touches, exact on every face and edge of the
    boxes (on a flat top the centre minus radius * z; on a step edge the corner, up to a
    radius horizontally from the centre). Pure JAX, fixed shapes."""
    pos, quat = terrain.place(values)
    centres = jnp.asarray(centres)
    pos = pos.astype(centres.dtype)
    rot = tr.quat_to_matrix(quat.astype(centres.dtype))  # (P, 3, 3), columns: box axes
    half = jnp.asarray([piece.half_size for piece in terrain.pieces], centres.dtype)
    local = jnp.einsum("pji,npj->npi", rot, centres[:, None, :] - pos[None])  # box frames
    near = pos[None] + jnp.einsum("pij,npj->npi", rot, jnp.clip(local, -half, half))  # (N, P, 3)
    dist = jnp.sqrt(jnp.sum((centres[:, None, :] - near) ** 2, axis=-1))
    k = jnp.argmin(dist, axis=1)
    point = jnp.take_along_axis(near, k[:, None, None], axis=1)[:, 0]
    return point, jnp.min(dist, axis=1) - jnp.asarray(radii, centres.dtype)


def top_x(kind: str, p) -> jax.Array:
    """x of the last riser [m] (the edge the COG must pass; block: its far face)."""
    d = jnp.asarray(p["distance"], jnp.result_type(float))
    if kind == "block":  # passed: beyond the block's far face
        return d + BLOCK_SIZE
    if kind == "pit":  # the platform's edge
        return d
    return d + (TERRACE_DEPTH if kind in ("step2_front", "step2_side") else 0.0)


def make_scenario(
    kind: str = "step1",
    controller: Controller | None = None,
    horizon_s: float = 60.0,
    record_every: int = 5,
    initial_pose: str | None = None,
) -> Scenario:
    """The OCTOPUS on terrain `kind` (see the module docstring), driven by `controller`
    (default: the CCM baseline `ccm.make_controller()`), for `horizon_s` seconds at the
    50 Hz control rate, recording every `record_every` control periods.

    initial_pose: "ccm" (arms stowed clear of the ground, `ccm.ARMS_STOWED`, front
    flippers at params["front_up"]) or "clm" (arms on the ground in the Table 2 initial
    pose, `clm.start_pose`, front flippers at params["front_start"]); default: the one
    of the controller (by its name; "ccm" for any other controller)."""
    m, terrain = build_model(kind)
    controller = controller or ccm.make_controller()
    pose = initial_pose or ("clm" if controller.name == "clm" else "ccm")
    if pose not in ("ccm", "clm"):
        raise ValueError(f"initial_pose: expected 'ccm' or 'clm', got {initial_pose!r}")
    arms0 = clm.start_pose()[0] if pose == "clm" else ccm.ARMS_STOWED
    front_key = "front_start" if pose == "clm" else "front_up"
    substeps = round(ccm.CONTROL_DT / m.opt.timestep)
    horizon = max(record_every, round(horizon_s / ccm.CONTROL_DT))
    horizon -= horizon % record_every
    control_dt = substeps * m.opt.timestep
    rows = tr.mocap_ids(m, terrain)
    terrain_geoms = np.array([m.geom(n).id for n in terrain.body_names()])
    chassis = m.body("chassis").id
    quat_s = sensor_slice(m, "imu_quat")
    flip_q = [sensor_slice(m, f"{n}_pos") for n in params.FLIPPER_NAMES]
    flip_tau = [sensor_slice(m, f"{n}_torque") for n in params.FLIPPER_NAMES]
    arm_q = [sensor_slice(m, f"{a}_{j}_pos") for a in params.ARM_NAMES for j in params.ARM_JOINTS]
    arm_tau = [sensor_slice(m, f"{a}_{j}_torque") for a in params.ARM_NAMES for j in params.ARM_JOINTS]
    track_v = [sensor_slice(m, f"{c}_vel") for c in params.CRAWLER_NAMES]
    sites = np.array([m.site(n).id for n in CONTACT_SITES])
    touch_adr = np.array([sensor_slice(m, n).start for n in SUPPORT_TOUCH])
    support = np.array([m.body(b).id for b in SUPPORT_BODIES])
    radii = np.array([_sphere_radius(m, b) for b in support])
    segment_sum = np.array([[[b in seg for b in SUPPORT_BODIES] for seg in side] for side in SEGMENT_WHEELS], float)
    qpos0, ctrl0 = model.pose_qpos_ctrl(m, arms0, [PARAM_DEFAULTS[front_key]] * 2 + [0.0, 0.0])
    qpos0, ctrl0 = jnp.asarray(qpos0), jnp.asarray(ctrl0)
    flip_adr = np.array([m.joint(n).qposadr[0] for n in params.FLIPPER_NAMES])
    flip_act = np.array([m.actuator(n).id for n in params.FLIPPER_NAMES])

    def initial_state(p, key):
        pos, quat = terrain.place(terrain_values(kind, p))
        full_pos = jnp.zeros((m.nmocap, 3), pos.dtype).at[rows].set(pos)
        full_quat = jnp.zeros((m.nmocap, 4), pos.dtype).at[rows].set(quat)
        front = p[front_key]
        flips = jnp.stack([front, front, 0.0 * front, 0.0 * front])
        qpos = qpos0.astype(pos.dtype).at[3:7].set(tr.quat_z(p["yaw"])).at[flip_adr].set(flips)
        if kind == "pit":  # on the platform
            qpos = qpos.at[2].add(p["height"])
        ctrl = ctrl0.astype(pos.dtype).at[flip_act].set(flips)
        return InitialState(qpos=qpos, qvel=jnp.zeros(m.nv, pos.dtype), ctrl=ctrl, mocap_pos=full_pos,
                            mocap_quat=full_quat)

    def observe(data: SimData):
        def read(slices):
            return jnp.stack([data.sensordata[s][0] for s in slices])

        return {
            "time": data.time,
            "quat": data.sensordata[quat_s],
            "flipper_q": read(flip_q),
            "flipper_tau": read(flip_tau),
            "arm_q": read(arm_q),
            "arm_tau": read(arm_tau),
            "track_speed": read(track_v),
            "contact_points": data.site_xpos[sites],
            "touch": data.sensordata[touch_adr],
            "track_load": jnp.asarray(segment_sum, data.sensordata.dtype) @ data.sensordata[touch_adr],
        }

    def record(p, data: SimData, obs, c, e):
        phase = _phase(c)
        # the support set (module docstring): every wheel and roller, at its contact point;
        # those that carry load or sit on the terrain count
        pts, gap = terrain_contacts(terrain, terrain_values(kind, p), data.xpos[support], radii)
        on = (obs["touch"] > LOAD_MIN) | (gap < SEAT_TOL)
        return {
            "rpy": sm.quat_to_rpy(obs["quat"]),
            "pos": data.xpos[chassis],
            "cog": data.subtree_com[chassis],
            "flipper_q": obs["flipper_q"],
            "flipper_tau": obs["flipper_tau"],
            "arm_tau": obs["arm_tau"],
            "arm_q": obs["arm_q"],
            "touch": obs["touch"],
            "track_load": obs["track_load"],
            "contact_points": pts,
            "contact": on,
            "phase": phase,
        }

    def summarize(p, r, final):
        n_rec = r["rpy"].shape[0]
        times = jnp.arange(n_rec) * (record_every * control_dt)
        valid = jnp.ones(n_rec, bool)
        roll, nose_up = r["rpy"][:, 0], -r["rpy"][:, 1]
        max_roll = sm.masked_max(jnp.abs(roll), valid, 0.0)
        max_pitch = jnp.max(nose_up)
        tipped = (max_roll > p["roll_limit"]) | (max_pitch > p["pitch_limit"])
        cog = r["cog"]
        left, right = _heights(kind, p)
        top = jnp.minimum(left, right)
        ground = terrain_height(kind, p, cog[:, :2])
        # how far the COG still has to go to where success is counted [m], < 0 once there:
        # pass_distance beyond the last riser, on its top; pit: the task is to stay on the
        # platform, short of its edge
        if kind == "pit":
            to_go = cog[:, 0] - top_x(kind, p)
            on_top = (to_go < 0.0) & (cog[:, 2] > top)
        else:
            to_go = top_x(kind, p) + p["pass_distance"] - cog[:, 0]
            on_top = (to_go < 0.0) & (ground >= top - 1e-6)
        shortfall = jnp.min(jnp.maximum(to_go, 0.0))  # at its nearest
        ok_att = (jnp.abs(roll) < p["roll_limit"]) & (nose_up < p["pitch_limit"])
        there = on_top & ok_att
        success = there[-1] & ~tipped & final.alive
        contacts = r["contact"]
        margins = sm.support_margins(cog, r["contact_points"], contacts)
        use = (jnp.sum(contacts, axis=1) >= 3).at[0].set(False)
        # the block task's arm sequence (Figs. 19-20): an arm roller loaded on top of an
        # obstacle (its contact >= OBSTACLE_MIN above the floor) and later on the floor again
        arm_on = contacts[:, ROLLERS]
        arm_z = r["contact_points"][:, ROLLERS, 2]
        up = arm_on & (arm_z > OBSTACLE_MIN)
        down = arm_on & (arm_z < FLOOR_TOL)
        first_up = jnp.where(jnp.any(up, axis=0), jnp.argmax(up, axis=0), n_rec)
        later_down = jnp.any(down & (jnp.arange(n_rec)[:, None] > first_up[None, :]), axis=0)
        return {
            "arm_over_obstacle": jnp.any(later_down),
            "success": success,
            "max_pitch": max_pitch,
            "max_abs_roll": max_roll,
            "min_margin": jnp.where(jnp.any(use), sm.masked_min(margins, use), jnp.nan),
            "climb_time": sm.first_time(there, times),
            "shortfall": shortfall,
            "final_x": cog[-1, 0],
            "final_z": cog[-1, 2],
            "tipped": tipped,
            "status": jnp.where(success, 0, 1),
        }

    return Scenario(
        name=f"octopus.{kind}",
        model=m,
        controller=controller,
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


def _phase(c) -> jax.Array:
    """The controller phase of a controller state: its `phase` field (ccm.CcmState,
    clm.ClmState); -1 for a controller without phases."""
    return getattr(c, "phase", jnp.asarray(-1, jnp.int32))


def _sphere_radius(m: mujoco.MjModel, body: int) -> float:
    """Radius [m] of the one colliding sphere of a wheel or roller body."""
    geoms = [g for g in range(m.ngeom) if m.geom_bodyid[g] == body and m.geom_contype[g]]
    if len(geoms) != 1 or m.geom_type[geoms[0]] != mujoco.mjtGeom.mjGEOM_SPHERE:
        raise ValueError(f"body {m.body(body).name}: expected one colliding sphere")
    return float(m.geom_size[geoms[0], 0])


def params_batch(n: int = 1, **overrides) -> dict[str, jax.Array]:
    """A batch of n identical parameter dicts (defaults with `overrides`); overrides may
    be arrays of length n to vary one parameter."""
    return sim_params_batch(PARAM_DEFAULTS, n, overrides)
