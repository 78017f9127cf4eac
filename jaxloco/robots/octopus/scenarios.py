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
  * "flat": the floor only (`tr.flat`).
Every terrain parameter is per simulation (mocap poses, no recompiling): `height`,
`distance` (x of the first riser, i.e. horizontal distance from the chassis origin {R}
to the step edge at t = 0), `yaw` (initial heading [rad]), `side_ratio`, and `mu` (the
terrain friction, a `ModelField` on the terrain geoms' sliding friction).

Observation (what a controller sees): time, IMU quaternion, flipper angles and torques,
arm joint angles and torques, crawler track speeds, and the contact-point sites
(`CONTACT_SITES`: crawler end axles, flipper tips, arm rollers) in the world frame.
Records: rpy (IMU), chassis position, COG, flipper angles and torques, arm torques,
contact points (the sites, then the crawler-edge contacts of `edge_contacts`) and their
contact mask, controller phase (if it has one).

Contact test: a contact site is in contact when it is within `CONTACT_TOL` of the terrain
surface below it (arm tips: the roller radius more), with the terrain height computed
from the same parameters that place the terrain; plus the points where the crawler
bottom lines rest on a step edge (`edge_contacts`).

Metrics (`summarize`): success (the COG ends `pass_distance` beyond the last riser on top
of the step, no tipping: max |roll| < `roll_limit`, max nose-up pitch < `pitch_limit` over
the run, no divergence), max_pitch (nose up), max_abs_roll, min_margin (static stability
margin over the sites in contact, samples with >= 3 contacts, `jaxloco.sim.metrics.
support_margins`), climb_time (first time the success position holds), final_x, final_z,
tipped, status (0 ok, 1 failed).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from jaxloco.robots.octopus import ccm, clm
from jaxloco.robots.octopus import model as octo_model
from jaxloco.robots.octopus import params as P
from jaxloco.sim import metrics as sm
from jaxloco.sim import terrain as tr
from jaxloco.sim.data import SimData, sensor_slice
from jaxloco.sim.scenario import Controller, InitialState, Scenario, friction_field
from jaxloco.sim.scenario import params_batch as sim_params_batch

KINDS = ("step1", "step2_front", "step2_side", "block", "flat")
TERRACE_DEPTH = 0.8  # [m] depth of the first terrace of the two-terrace steps
MAX_HEIGHT = 0.6  # [m] highest step the terrain boxes allow
# the block (the paper gives its height only): a 0.5 m concrete cube
BLOCK_SIZE = 0.5  # [m] length (x) and width (y)
ROBOT_SIDE = P.CRAWLER_Y + P.MAIN_WHEEL_RADIUS  # [m] |y| of the crawlers' outer side
CONTACT_TOL = 0.02  # [m]
CONTACT_SITES = (
    tuple(f"crawler_{s}_{e}" for s in "lr" for e in ("front", "rear"))
    + tuple(f"{f}_tip" for f in P.FLIPPER_NAMES)
    + tuple(f"{a}_tip" for a in P.ARM_NAMES)
)
N_ARM_SITES = 4  # the last CONTACT_SITES are the arm roller centres
STATUSES = ("ok", "failed")

PARAM_DEFAULTS: dict[str, float] = {
    # terrain and physics
    "height": 0.4,  # [m] total step height
    "distance": 0.7,  # [m] chassis origin to the first riser at t = 0
    "yaw": 0.0,  # [rad] initial heading
    "side_ratio": 0.5,  # step2_side: right rise / left rise
    "block_gap": 0.01,  # [m] block: gap between the robot's right side and the block
    "mu": 0.8,  # terrain friction
    # success test
    "pass_distance": 0.3,  # [m] the COG beyond the last riser (paper: S = 0.3 m)
    "roll_limit": 0.5,  # [rad]
    "pitch_limit": 1.2,  # [rad] nose up
    # controllers (the CCM baseline and the CLM; their keys do not overlap)
    **ccm.PARAM_DEFAULTS,
    **clm.PARAM_DEFAULTS,
}


def build_model(kind: str) -> tuple[mujoco.MjModel, tr.Terrain]:
    """The robot (`models/octopus.xml`) with the terrain of `kind`."""
    if kind not in KINDS:
        raise ValueError(f"kind: expected one of {', '.join(KINDS)}, got {kind!r}")
    spec = octo_model.load_spec()
    if kind == "flat":
        terrain = tr.flat(half_extent=10.0, half_depth=0.5)
    elif kind == "block":
        terrain = tr.blocks(n=1, half_size=(0.5 * BLOCK_SIZE, 0.5 * BLOCK_SIZE, 0.5 * MAX_HEIGHT))
    elif kind == "step1":
        terrain = tr.steps(n_terraces=1, max_height=MAX_HEIGHT)
    else:
        terrain = tr.steps(n_terraces=2, depth=TERRACE_DEPTH, max_height=MAX_HEIGHT)
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
        return {"block0_x": p["distance"] + 0.5 * BLOCK_SIZE, "block0_y": -(ROBOT_SIDE + p["block_gap"] + 0.5 * BLOCK_SIZE),
                "block0_height": h, "block0_yaw": 0.0 * h}
    left, right = _heights(kind, p)
    return {"height_left": left, "height_right": right, "start": jnp.asarray(p["distance"], left.dtype)}


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
    n = 1 if kind == "step1" else 2
    rise = jnp.where(xy[..., 1] >= 0.0, left, right)
    x = xy[..., 0] - p["distance"]
    terraces = jnp.clip(jnp.floor(x / TERRACE_DEPTH) + 1.0, 0.0, n) if n > 1 else jnp.where(x >= 0.0, 1.0, 0.0)
    return rise * terraces / n


def edge_contacts(kind: str, p, pts: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Where the crawler bottom lines rest on the step edges: for each side, the polyline
    rear flipper tip - main crawler rear - front - front flipper tip (from the contact
    sites `pts`, `CONTACT_SITES` order) is cut with the vertical plane of every riser;
    a crossing within `CONTACT_TOL` of that terrace's top is a contact. Returns the
    points (2 sides x 3 segments x risers, 3) and their mask (fixed shapes)."""
    n = {"flat": 1, "step1": 1, "block": 1}.get(kind, 2)
    left, right = _heights(kind, p)
    risers = jnp.asarray(p["distance"], pts.dtype) + TERRACE_DEPTH * jnp.arange(n, dtype=pts.dtype)
    # site rows: crawler_l_front 0, crawler_l_rear 1, crawler_r_front 2, crawler_r_rear 3,
    # flipper_fl 4, flipper_fr 5, flipper_rl 6, flipper_rr 7
    chains = jnp.asarray([[6, 1, 0, 4], [7, 3, 2, 5]])
    poly = pts[chains]  # (2, 4, 3)
    a, b = poly[:, :-1], poly[:, 1:]  # (2, 3, 3)
    dx = b[..., 0] - a[..., 0]
    safe = jnp.where(jnp.abs(dx) > 1e-9, dx, 1.0)
    s = (risers[None, None, :] - a[..., 0:1]) / safe[..., None]  # (2, 3, n)
    pt = a[..., None, :] + s[..., None] * (b - a)[..., None, :]  # (2, 3, n, 3)
    rise = jnp.where(pt[..., 1] >= 0.0, left, right)
    top = rise * (jnp.arange(n, dtype=pts.dtype) + 1.0) / n
    ok = (jnp.abs(dx) > 1e-9)[..., None] & (s >= 0.0) & (s <= 1.0) & (jnp.abs(pt[..., 2] - top) < CONTACT_TOL)
    ok = ok & (rise > CONTACT_TOL)
    return pt.reshape(-1, 3), ok.reshape(-1)


def top_x(kind: str, p) -> jax.Array:
    """x of the last riser [m] (the edge the COG must pass; block: its far face)."""
    d = jnp.asarray(p["distance"], jnp.result_type(float))
    if kind == "block":  # passed: beyond the block's far face
        return d + BLOCK_SIZE
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
    flip_q = [sensor_slice(m, f"{n}_pos") for n in P.FLIPPER_NAMES]
    flip_tau = [sensor_slice(m, f"{n}_torque") for n in P.FLIPPER_NAMES]
    arm_q = [sensor_slice(m, f"{a}_{j}_pos") for a in P.ARM_NAMES for j in P.ARM_JOINTS]
    arm_tau = [sensor_slice(m, f"{a}_{j}_torque") for a in P.ARM_NAMES for j in P.ARM_JOINTS]
    track_v = [sensor_slice(m, f"{c}_vel") for c in P.CRAWLER_NAMES]
    sites = np.array([m.site(n).id for n in CONTACT_SITES])
    lift = np.zeros(len(CONTACT_SITES))
    lift[-N_ARM_SITES:] = P.ROLLER_RADIUS
    qpos0, ctrl0 = octo_model.pose_qpos_ctrl(m, arms0, [PARAM_DEFAULTS[front_key]] * 2 + [0.0, 0.0])
    qpos0, ctrl0 = jnp.asarray(qpos0), jnp.asarray(ctrl0)
    flip_adr = np.array([m.joint(n).qposadr[0] for n in P.FLIPPER_NAMES])
    flip_act = np.array([m.actuator(n).id for n in P.FLIPPER_NAMES])

    def initial_state(p, key):
        pos, quat = terrain.place(terrain_values(kind, p))
        full_pos = jnp.zeros((m.nmocap, 3), pos.dtype).at[rows].set(pos)
        full_quat = jnp.zeros((m.nmocap, 4), pos.dtype).at[rows].set(quat)
        front = p[front_key]
        flips = jnp.stack([front, front, 0.0 * front, 0.0 * front])
        qpos = qpos0.astype(pos.dtype).at[3:7].set(tr.quat_z(p["yaw"])).at[flip_adr].set(flips)
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
        }

    def record(p, data: SimData, obs, c, e):
        pts = obs["contact_points"]
        gap = pts[:, 2] - jnp.asarray(lift, pts.dtype) - terrain_height(kind, p, pts[:, :2])
        phase = c["phase"] if isinstance(c, dict) and "phase" in c else jnp.asarray(-1, jnp.int32)
        edge_pts, edge_ok = edge_contacts(kind, p, pts)
        return {
            "rpy": sm.quat_to_rpy(obs["quat"]),
            "pos": data.xpos[chassis],
            "cog": data.subtree_com[chassis],
            "flipper_q": obs["flipper_q"],
            "flipper_tau": obs["flipper_tau"],
            "arm_tau": obs["arm_tau"],
            "contact_points": jnp.concatenate([pts, edge_pts]),
            "contact": jnp.concatenate([gap < CONTACT_TOL, edge_ok]),
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
        on_top = (cog[:, 0] > top_x(kind, p) + p["pass_distance"]) & (ground >= top - 1e-6)
        ok_att = (jnp.abs(roll) < p["roll_limit"]) & (nose_up < p["pitch_limit"])
        there = on_top & ok_att
        success = there[-1] & ~tipped & final.alive
        contacts = r["contact"]
        margins = sm.support_margins(cog, r["contact_points"], contacts)
        use = (jnp.sum(contacts, axis=1) >= 3).at[0].set(False)
        return {
            "success": success,
            "max_pitch": max_pitch,
            "max_abs_roll": max_roll,
            "min_margin": jnp.where(jnp.any(use), sm.masked_min(margins, use), jnp.nan),
            "climb_time": sm.first_time(there, times),
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


def params_batch(n: int = 1, **overrides) -> dict[str, jax.Array]:
    """A batch of n identical parameter dicts (defaults with `overrides`); overrides may
    be arrays of length n to vary one parameter."""
    return sim_params_batch(PARAM_DEFAULTS, n, overrides)
