"""The experimental leg-grope walk (paper, "Experiments": steps A', B', C, D'-1, D'-2) as
a pure-JAX position controller, for the simulated robot of `model.py`.

For each groping leg g in the order L2, L1, L3, L4 (phases as `PHASES`):
  A'    move the body (four legs) so that the COG is `safe_blend` of the way (or more)
        from the grope's COG target towards the centroid of the other three footholds,
        inside their admissible COG region pi_g by `swing_margin` (`swing_cog`; Fig. 10:
        "moves the COG inside of the admissible region of the COG"): deeper inside the
        support triangle for the swing, no stance leg over R_ref. (The centroid itself
        is out of the legs' reach for these sprawled footstep designs at R_ref = M g
        cos(theta) / 2: blend 1 drags the toes.)
  B'    raise toe g along its foothold normal until its measured normal force is ~0;
  C     swing it (minimum jerk, lifted by `swing_height`) to above the target foothold,
  C*    then lower it along the normal until it touches (normal force > f_touch);
  D'-1  move the body to the COG position for the grope (from `gait.plan_cycle`): the
        groping leg's normal force grows as the COG approaches;
  D'-2  push toe g down along the normal until its normal force is over (1 +
        `grope_overshoot`) R_ref (the push pauses while another leg is unloaded), while
        the body creeps (`v_creep`) towards the groped foothold, at most `grope_blend` of
        the way from the COG target to it; then hold still for `grope_hold` and accept
        the foothold. Why the creep: the legs are stiff servos and the body is rigid, so
        pushing one toe of a four-leg stance loads it and its diagonal and unloads the
        other two (a twist); once one of them lifts off, more push only tilts the body.
        Creeping only while pushing moves the COG no farther than needed, and pausing
        the push keeps the stance from twisting off a leg. With the literal design's COG
        (region margin -1.7 mm) the L1 grope stalls near 0.95 R_ref; the mirrored
        design's COG targets have 11 mm of grope-region margin (`gait.GaitDesign`).
In A', D'-1 and after the cycle (four legs down) the controller relaxes the stance's
twist with the toe force sensors (`twist_relief`, ours: the paper's flexible legs do this
by themselves, our stiff servos do not) and shares the in-plane load between the toes in
proportion to their normal loads (`shear_relief`, ours: without it the most lightly
loaded toe slips first and the stance creeps downhill).
The leg numbering, footsteps, COG rule, fallback directions and grope overshoot come from
a `gait.GaitDesign` (default: the mirrored reading's forward crawl along x_R).
If the normal force of the groping leg collapses during C*/D'-1/D'-2 (it falls below
`collapse_fraction` of its peak, or the toe finds nothing within `probe_depth`), the
foothold is taken as collapsed: the robot stays on its three other legs. With `regrope`
= 0 the walk stops there (status "stopped_on_collapse", the paper's experiment);
otherwise it moves its body back to the A' position and gropes a fallback foothold
`fallback_distance` from the target (`GaitDesign.fallback`) (one retry; a second collapse
stops the walk, status "no_foothold"). COG targets of every primary/fallback combination
are planned at init (16 plans), so the step function has fixed shapes and no search.

The controller knows what the real robot knows: its joint angles, toe force sensors,
IMU, the slope map (foothold positions and normals) and the plan; the body pose it
commands is the planned one (open loop in the world, as a position-controlled robot).
Frames: world Sigma_G; forces are ground reactions on the toes [N].
"""

from __future__ import annotations

from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco import geometry as geo
from jaxloco import linalg
from jaxloco.robots.leggrope import gait, kinematics, regions
from jaxloco.robots.leggrope.model import TOE_RADIUS
from jaxloco.robots.leggrope.params import G, LegGropeParams, default_params

Array = jax.Array

PHASES = ("A'", "B'", "C", "C*", "D'-1", "D'-2", "done", "stopped")
A, B, C, TOUCH, D1, D2, DONE, STOPPED = range(8)
STATUSES = ("ok", "no_foothold", "timeout", "stopped_on_collapse")


@dataclass(frozen=True)
class GropeSettings:
    """Static settings of the controller (SI units)."""

    control_dt: float = 0.02  # control period [s]
    v_lift: float = 0.02  # B': toe raise speed [m/s]
    f_zero: float = 0.03  # B': "normal force 0" threshold, fraction of M g
    f_touch: float = 0.06  # C*: touchdown threshold, fraction of M g
    v_touch: float = 0.03  # C*: toe lowering speed [m/s]
    # C*: ... but within `touch_band` of the foothold's mapped surface the toe comes down
    # at `v_contact` [m/s]. The touchdown is declared on the filtered force, so a stiff leg
    # meeting the surface at 0.03 m/s already pressed 0.15 M g when D'-1 began, and in a
    # four-leg stance its diagonal leg carries that: 5-10 % past its probe at R_ref = 0.4
    # M g cos(theta) (docs/leggrope.md). Slow only near the surface, so that a toe that
    # finds nothing (a collapsed pad) still reaches `probe_depth` well inside
    # `phase_timeout`. Defaults (ours).
    v_contact: float = 0.01
    touch_band: float = 0.005
    clearance: float = 0.01  # C: the swing ends this far above the target [m]
    probe_depth: float = 0.03  # C*: give up (no foothold) this far below the target [m]
    v_push: float = 0.01  # D'-2: toe push speed [m/s]
    v_creep: float = 0.005  # D'-2: body creep speed towards `body_reach` [m/s]
    push_depth: float = 0.03  # D'-2: deepest push below the touchdown point [m]
    swing_time: float = 0.8  # C [s]
    settle: float = 0.2  # pause at the end of A' and D'-1 [s]
    collapse_fraction: float = 0.3  # normal force below this fraction of its peak: collapsed
    # D'-2 ends once the filtered normal force is over (1 + overshoot) R_ref (paper: "until
    # the normal reaction of a groping leg is over R_ref"); None: the design's
    # (`gait.GaitDesign.grope_overshoot`)
    grope_overshoot: float | None = None
    # D'-2 holds this long once over the threshold, without pushing, before it accepts the
    # foothold: a collapse in the hold is detected as one. (The controller reads filtered
    # forces; the raw load runs ahead of them, so without the hold a foothold a few per
    # cent stronger than R_ref broke just after its grope had accepted it: 3 "late"
    # collapses in a walk of `leggrope_probe`.)
    grope_hold: float = 0.15
    # once a grope is accepted, its toe's command returns from the depth it was pushed to
    # onto the foothold surface at this speed [m/s] (ours). At once (a step), the body
    # dropped onto a corner whose leg the push had lifted: 1.39 R_ref on the foothold just
    # probed at 1.1. Slower keeps the pushed leg loaded into A': on sound footholds at
    # R_ref = M g cos(theta) / 2, load/probe 0.99 at 0.01 m/s, 0.97 at 0.03, 0.92 at 0.1.
    v_release: float = 0.1
    phase_timeout: float = 4.0  # any phase longer than this stops the walk [s]
    force_filter: float = 0.05  # time constant of the toe-force low-pass filter [s]
    collapse_min_peak: float = 0.15  # collapse detection needs a peak above this, fraction of M g


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class WalkTargets:
    """Everything the walk needs that depends on the simulation's parameters (world frame).

    feet0: initial footholds (4, 3); cand: primary/fallback footholds of each leg
    (4, 2, 3); normals0, cand_normals: their unit normals; body0: initial body origin;
    body_grope/body_safe: body origin for D'-1 / A' of grope k (0..3) under each of the
    16 primary/fallback combinations (bit g set: leg g used its fallback), (16, 4, 3);
    body_reach: the farthest the body creeps during D'-2 (COG `grope_blend` of the way
    from the grope's COG target towards the groped foothold), (16, 4, 3);
    R_GR: body attitude (parallel to the slope); r_ref [N]; margin: the plan's smallest
    geometric margin [m] (primary footholds)."""

    feet0: Array
    normals0: Array
    cand: Array
    cand_normals: Array
    body0: Array
    body_grope: Array
    body_safe: Array
    body_reach: Array
    R_GR: Array
    r_ref: Array
    margin: Array


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class GropeState:
    k: Array  # grope index 0..3 (4: cycle done)
    phase: Array
    tau: Array  # time in the phase [s]
    cand: Array  # 0 primary foothold, 1 fallback
    bits: Array  # legs (bit mask) that moved to their fallback
    body_from: Array  # (3,) body origin at the start of the phase
    body_cmd: Array  # (3,) commanded body origin
    toe_from: Array  # (3,) groping toe centre at the start of the phase
    toe_cmd: Array  # (4, 3) commanded toe centres
    release: Array  # (4, 3) what remains of each toe command's return from its grope's push [m]
    f_peak: Array  # peak normal force of the groping leg since touchdown [N]
    hold: Array  # time in D'-2 since the normal force went over the threshold [s] (-1: not yet)
    collapses: Array  # collapses met
    status: Array  # index into STATUSES
    grope_force: Array  # (4,) peak normal force of each leg's grope (C* to D'-2) [N]
    grope_time: Array  # (4,) when each leg's D'-2 ended [s] (inf: not yet)
    force: Array  # (4, 3) low-pass filtered toe forces (world) [N]
    targets: WalkTargets = field(default=None)


def robot_params(p: dict) -> LegGropeParams:
    """The Table 1 robot with the simulation's mu and R_ref factor."""
    return default_params().with_(mu=p["mu"], r_ref_factor=p["r_ref_factor"])


def walk_targets(p: dict, key: Array, design: gait.GaitDesign = gait.DESIGNS["mirrored"]) -> WalkTargets:
    """Plan the cycle for one simulation's parameters `p` (theta, psi, stride,
    swing_height, facet_spread, fallback_distance, safe_blend, grope_blend, r_ref_factor,
    mu), terrain key and leg numbering / footstep design. The step function also reads
    p["regrope"]."""
    robot = robot_params(p)
    walk = design.walk(stride=p["stride"], swing_height=p["swing_height"])
    config = design.config()
    terrain = terrain_of(p, key)
    dtype = jnp.asarray(p["theta"]).dtype
    primary, fallback = foothold_steps(p, walk, design, dtype)
    combos = np.array([[(c >> g) & 1 for g in range(4)] for c in range(16)], bool)
    steps = jnp.where(jnp.asarray(combos)[:, :, None], fallback[None], primary[None])  # (16, 4, 2)
    # one plan at a time (lax.map, not vmap): XLA keeps every vmapped plan's COG-lattice search
    # live at once, 33 MB per simulation (34 GB for a batch of 1,024 rows)
    plans = jax.lax.map(lambda s: gait.plan_cycle(robot, walk, terrain, config, steps=s), steps)

    def blended_bodies(plan):
        """Body origins (4, 3) for A' (COG towards the centroid of the three stance feet,
        inside their pi_g: `swing_cog`) and D'-1 (COG towards the groped foothold) of
        each grope."""

        def one(k):
            g = jnp.asarray(design.order)[k]
            cog = plan.cog_target[k + 1]
            safe = swing_cog(robot, terrain, plan, design.order, k, p["safe_blend"], p["swing_margin"])
            reach = cog + p["grope_blend"] * (plan.feet[k + 1, g, :2] - cog)
            return (gait.place_body(robot, terrain, plan.R_GR, plan.feet[k], safe, 5),
                    gait.place_body(robot, terrain, plan.R_GR, plan.feet[k + 1], reach, 5))

        return jax.vmap(one)(jnp.arange(4))

    body_safe, body_reach = jax.vmap(blended_bodies)(plans)
    full = plans.feet[15, 4]  # every leg on its fallback
    cand = jnp.stack([plans.feet[0, 4], full], axis=1)  # (4, 2, 3)
    normals0 = terrain.normals[0]
    cand_normals = jnp.stack([terrain.normals[1], terrain.normals[1]], axis=1)
    return WalkTargets(
        feet0=plans.feet[0, 0],
        normals0=normals0,
        cand=cand,
        cand_normals=cand_normals,
        body0=plans.body[0, 0],
        body_grope=plans.body[:, 1:],
        body_reach=body_reach,
        body_safe=body_safe,
        R_GR=plans.R_GR[0],
        r_ref=robot.r_ref_factor * robot.total_mass * G * jnp.cos(p["theta"]),
        margin=jax.tree.map(lambda x: x[0], plans).rule_margin(design.cog_rule),
    )


def foothold_steps(p: dict, walk: gait.WalkParams, design: gait.GaitDesign, dtype) -> tuple[Array, Array]:
    """Each leg's primary and fallback step (4, 2) [m] (u forward, v left in the walking
    frame): the stride with the leg's lateral offset, and that moved by
    p["fallback_distance"] along the design's fallback direction."""
    primary = jnp.stack([jnp.full(4, walk.stride, dtype), jnp.asarray(walk.lateral, dtype)], axis=1)
    return primary, primary + p["fallback_distance"] * jnp.asarray(design.fallback, dtype)


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class Footholds:
    """The footholds of one simulation's cycle and the robot's start (world frame), the
    fields of `WalkTargets` that need no COG plan: feet0, normals0 (4, 3); cand,
    cand_normals (4, 2, 3) (primary, fallback); body0 (3,); R_GR (3, 3)."""

    feet0: Array
    normals0: Array
    cand: Array
    cand_normals: Array
    body0: Array
    R_GR: Array


def walk_footholds(p: dict, key: Array, design: gait.GaitDesign = gait.DESIGNS["mirrored"]) -> Footholds:
    """`walk_targets`' footholds, start pose and attitude without its 16 COG plans: the
    terrain (pads) and the initial state need only these, and a rollout traced with
    `walk_targets` three times (initial state, controller, environment) took twice as
    long to compile for MJX. The same operations as `gait.plan_cycle`'s feet and body0."""
    robot = robot_params(p)
    walk = design.walk(stride=p["stride"], swing_height=p["swing_height"])
    terrain = terrain_of(p, key)
    dtype = jnp.asarray(p["theta"]).dtype
    to_world = jax.vmap(lambda uv: gait.slope_to_world(terrain, jnp.concatenate([uv, jnp.zeros(1, dtype)])))
    uv = jnp.asarray(walk.stance, dtype)
    primary, fallback = foothold_steps(p, walk, design, dtype)
    feet0 = to_world(uv)
    R_GR = gait.body_rotation(terrain, walk)
    body0 = gait.place_body(robot, terrain, R_GR, feet0, gait.uv_to_world_xy(terrain, jnp.mean(uv, axis=0)),
                            design.config().fixed_point_iters)
    cand = jnp.stack([to_world(uv + primary), to_world(uv + fallback)], axis=1)
    return Footholds(feet0=feet0, normals0=terrain.normals[0], cand=cand,
                     cand_normals=jnp.stack([terrain.normals[1], terrain.normals[1]], axis=1), body0=body0, R_GR=R_GR)


SWING_BLENDS = 17  # candidate A' blends between safe_blend and 1 (`swing_cog`)


def swing_cog(robot: LegGropeParams, terrain: gait.SlopeTerrain, plan: gait.CyclePlan, order: tuple[int, ...],
              k: Array, safe_blend: Array, swing_margin: Array) -> Array:
    """The A' COG (world xy) for grope k of `plan`: the paper's step A' "moves the COG
    inside of the admissible region of the COG" pi_g of the three legs that stay down
    (Fig. 10, Eqs. 2-6: every stance leg's normal force <= R_ref while g swings).

    From the grope's COG target c towards the centroid of the three stance footholds,
    the smallest blend b >= `safe_blend` (of SWING_BLENDS candidates up to 1) that puts
    the COG at least `swing_margin` [m, slope plane] inside pi_g both before the swing
    and after it (the swinging leg's mass moves the COG); if no candidate does, the
    one with the largest margin. At R_ref = M g cos(theta) / 2, pi_g is the medial
    triangle and `safe_blend` alone usually suffices; at smaller R_ref pi_g shrinks
    towards the centroid (`leggrope_fragile` at 0.4: loads of 1.23 R_ref in the swing
    without this rule)."""
    order_arr = jnp.asarray(order)
    g = order_arr[k]
    feet = plan.feet[k]
    moved = jnp.argsort(order_arr) < k
    h = jnp.where(moved, plan.h_ref[1], plan.h_ref[0])
    stance = jnp.asarray([[n for n in range(4) if n != leg] for leg in range(4)])[g]
    to_uv = jax.vmap(lambda xy: gait.world_xy_to_uv(terrain, xy))
    feet_uv = to_uv(feet[stance, :2])
    region, ok = regions.cog_region(feet_uv[0], feet_uv[1], feet_uv[2], h[stance[0]], h[stance[1]], h[stance[2]])
    body = plan.body[k + 1]
    shift = (gait.whole_body_cog(robot, plan.R_GR, body, plan.feet[k + 1])
             - gait.whole_body_cog(robot, plan.R_GR, body, feet))[:2]
    cog = plan.cog_target[k + 1]
    centroid = jnp.mean(feet[stance, :2], axis=0)
    blends = safe_blend + (1.0 - safe_blend) * jnp.linspace(0.0, 1.0, SWING_BLENDS)
    cand = cog[None] + blends[:, None] * (centroid - cog)[None]

    def margin(c):
        inside = lambda q: geo.polygon_signed_distance(gait.world_xy_to_uv(terrain, q), region, ok)
        return jnp.minimum(inside(c), inside(c + shift))

    m = jax.vmap(margin)(cand)
    good = m >= swing_margin
    best = jnp.where(jnp.any(good), jnp.argmax(good), jnp.argmax(m))
    return cand[best]


def terrain_of(p: dict, key: Array) -> gait.SlopeTerrain:
    """The slope under the footholds: simple (facet_spread 0) or irregular."""
    return gait.irregular_slope(p["theta"], p["psi"], p["facet_spread"], key)


def joint_targets(robot: LegGropeParams, R_GR: Array, body: Array, toes: Array) -> Array:
    """Joint angles (12,) (legs L1..L4, yaw/pitch/knee) putting the toe centres `toes`
    (4, 3, world) at their places for the body origin `body` with attitude R_GR."""
    q, _ = jax.vmap(lambda leg, t: kinematics.inverse_kinematics(robot, leg, t))(jnp.arange(4), (toes - body) @ R_GR)
    return q.reshape(12)


def make_controller(settings: GropeSettings = GropeSettings(), design: gait.GaitDesign = gait.DESIGNS["mirrored"]):
    """(init, step) of the leg-grope walk controller (see the module docstring) for a leg
    numbering and footstep design (`gait.DESIGNS`).

    obs: dict with "foot_force" (4, 3) world ground reactions [N] and "time" [s].
    params: dict with the keys of `walk_targets` and "key" (2,) uint32 (terrain)."""
    s_ = settings
    dt = s_.control_dt
    overshoot = design.grope_overshoot if s_.grope_overshoot is None else s_.grope_overshoot
    order = jnp.asarray(design.order, jnp.int32)  # int32 like the state's indices (a scan keeps dtypes)

    def init(p, obs):
        t = walk_targets(p, p["key"], design)
        toes = t.feet0 + TOE_RADIUS * t.normals0
        dtype = t.body0.dtype
        z = jnp.zeros((), dtype)
        i0 = jnp.zeros((), jnp.int32)
        return GropeState(k=i0, phase=i0, tau=z, cand=i0, bits=i0, body_from=t.body0, body_cmd=t.body0,
                          toe_from=toes[design.order[0]], toe_cmd=toes, release=jnp.zeros_like(toes), f_peak=z,
                          hold=-jnp.ones((), dtype),
                          collapses=i0, status=i0,
                          grope_force=jnp.zeros(4, dtype), grope_time=jnp.full(4, jnp.inf, dtype),
                          force=jnp.asarray(obs["foot_force"], dtype), targets=t)

    def step(p, s: GropeState, obs):
        robot = robot_params(p)
        t = s.targets
        mg = robot.total_mass * G
        kk = jnp.minimum(s.k, 3)
        g = order[kk]
        combo = s.bits | (s.cand << g)
        b_safe, b_grope, b_reach = t.body_safe[combo, kk], t.body_grope[combo, kk], t.body_reach[combo, kk]
        n_tgt = t.cand_normals[g, s.cand]
        n_now = jnp.where(s.phase <= B, t.normals0[g], n_tgt)  # the foothold toe g is on / aims at
        target = t.cand[g, s.cand] + TOE_RADIUS * n_tgt
        above = target + s_.clearance * n_tgt
        # toe forces through a first-order low-pass (light, stiff contacts chatter at
        # the physics rate; real force sensors are filtered too)
        alpha = dt / (s_.force_filter + dt)
        force = s.force + alpha * (obs["foot_force"] - s.force)
        f_n = jnp.dot(force[g], n_now)
        tau = s.tau + dt
        robot_a = (robot.a_max, robot.v_max)

        # the commanded body and groping toe in each phase, and whether the phase is over
        body_a, t_a = _move(s.body_from, b_safe, tau, *robot_a)
        body_d1, t_d1 = _move(s.body_from, b_grope, tau, *robot_a)
        creep = b_reach - s.body_cmd
        creep_len = jnp.linalg.norm(creep)
        body_d2 = s.body_cmd + creep * jnp.minimum(1.0, s_.v_creep * dt / jnp.where(creep_len > 0, creep_len, 1.0))
        toe_b = s.toe_cmd[g] + s_.v_lift * dt * n_now
        frac = jnp.clip(tau / s_.swing_time, 0.0, 1.0)
        lift = p["swing_height"] * jnp.sin(jnp.pi * frac)
        toe_c = s.toe_from + (above - s.toe_from) * gait.min_jerk(frac) + lift * n_tgt
        toe_touch = touch_command(s.toe_cmd[g], above, n_tgt, s_)
        # D'-2 pushes only while the other three legs all carry load: once one lifts
        # off, more push would only tilt the body, and the body's creep does the rest
        others_loaded = jnp.min(jnp.where(jnp.arange(4) == g, jnp.inf, force @ n_now)) > s_.f_zero * mg
        # over the threshold, D'-2 holds still (no push, no creep) for grope_hold
        over = (s.phase == D2) & ((s.hold >= 0) | (f_n >= (1.0 + overshoot) * t.r_ref))
        hold = jnp.where(over, jnp.where(s.hold >= 0, s.hold + dt, 0.0), -1.0)
        body_d2 = jnp.where(over, s.body_cmd, body_d2)
        toe_push = s.toe_cmd[g] - jnp.where(others_loaded & ~over, s_.v_push * dt, 0.0) * n_tgt
        depth = jnp.dot(above - s.toe_cmd[g], n_tgt)  # how far below `above` the toe is commanded

        ph = s.phase
        body = jnp.select([ph == A, ph == D1, ph == D2], [body_a, body_d1, body_d2], s.body_cmd)
        toe_g = jnp.select([ph == B, ph == C, ph == TOUCH, ph == D2], [toe_b, toe_c, toe_touch, toe_push], s.toe_cmd[g])
        f_peak = jnp.where((ph == D1) | (ph == D2) | (ph == TOUCH), jnp.maximum(s.f_peak, f_n), 0.0)

        finished = jnp.select(
            [ph == A, ph == B, ph == C, ph == TOUCH, ph == D1, ph == D2],
            [tau >= t_a + s_.settle, f_n < s_.f_zero * mg, tau >= s_.swing_time, f_n > s_.f_touch * mg,
             tau >= t_d1 + s_.settle, hold >= s_.grope_hold - 1e-9],
            False,
        )
        lost = (f_peak > s_.collapse_min_peak * mg) & (f_n < s_.collapse_fraction * f_peak) & ((ph == D1) | (ph == D2))
        missed = (ph == TOUCH) & (depth > s_.clearance + s_.probe_depth) & ~finished
        pushed_out = (ph == D2) & (depth > s_.clearance + s_.push_depth) & ~finished
        collapsed = lost | missed
        rejected = collapsed | pushed_out  # the foothold could not be verified: try the fallback
        timeout = (tau > s_.phase_timeout) & (ph < DONE) & ~finished

        # transitions
        grope_done = (ph == D2) & finished & ~rejected
        # regrope 0: stop at the first collapse, as in the paper's collapse experiment
        # ("The robot stops walking after the detection of the foothold collapse")
        stop = collapsed & (p["regrope"] < 0.5)
        retry = rejected & (s.cand == 0) & ~stop
        give_up = rejected & ((s.cand == 1) | stop)
        nxt = jnp.where(grope_done, A, jnp.where(finished, ph + 1, ph))
        k = jnp.where(grope_done, s.k + 1, s.k)
        nxt = jnp.where(grope_done & (k >= 4), DONE, nxt)
        nxt = jnp.where(retry, A, nxt)
        nxt = jnp.where(give_up | timeout, STOPPED, nxt)
        changed = nxt != ph
        bits = jnp.where(grope_done, s.bits | (s.cand << g), s.bits)
        cand = jnp.where(retry, 1, jnp.where(grope_done, 0, s.cand))
        status = jnp.where(stop, 3, jnp.where(give_up, 1, jnp.where(timeout, 2, s.status)))
        # once probed, the groping toe's command goes back to the foothold surface, at
        # v_release: a command left pushed into the ground would keep loading that leg
        # for the rest of the walk (position control of an over-constrained four-leg
        # stance; leaving it to the twist relief instead was worse: load/probe up to 1.01
        # at R_ref = M g cos(theta) / 2, where the return gives 0.94)
        toe_cmd = s.toe_cmd.at[g].set(toe_g)
        release = s.release.at[g].set(jnp.where(grope_done, target - toe_g, s.release[g]))
        release_step = release_step_of(release, s_.v_release * dt)
        toe_cmd, release = toe_cmd + release_step, release - release_step
        # A', D'-1 and after the cycle the robot stands on four legs: relax the stance's
        # twist (`twist_relief`)
        four_legs = (ph == A) | (ph == D1) | (ph == DONE)
        relief = twist_relief(force[:, 2], s.toe_cmd[:, :2], p["twist_relief"] * dt / mg)
        toe_cmd = toe_cmd + jnp.where(four_legs, relief, 0.0)[:, None] * jnp.array([0.0, 0.0, 1.0], toe_cmd.dtype)
        # ... and share its in-plane load by the toes' normal loads (`shear_relief`), in
        # the body frame (parallel to the slope)
        shear = shear_relief(force @ t.R_GR, s.toe_cmd @ t.R_GR, p["shear_relief"] * dt / mg) @ t.R_GR.T
        toe_cmd = toe_cmd + jnp.where(four_legs, shear, 0.0)
        next_g = order[jnp.minimum(k, 3)]
        grope_force = jnp.where(grope_done, s.grope_force.at[g].set(f_peak), s.grope_force)
        grope_time = jnp.where(grope_done, s.grope_time.at[g].set(obs["time"]), s.grope_time)
        new = GropeState(
            k=k,
            phase=nxt,
            tau=jnp.where(changed, 0.0, tau),
            cand=cand,
            bits=bits,
            body_from=jnp.where(changed, body, s.body_from),
            body_cmd=body,
            toe_from=jnp.where(changed, toe_cmd[next_g], s.toe_from),
            toe_cmd=toe_cmd,
            release=release,
            f_peak=jnp.where(changed, 0.0, f_peak),
            hold=jnp.where(changed, -1.0, hold),
            collapses=s.collapses + collapsed.astype(s.collapses.dtype),
            status=status,
            grope_force=grope_force,
            grope_time=grope_time.astype(s.grope_time.dtype),
            force=force,
            targets=t,
        )
        return new, joint_targets(robot, t.R_GR, body, toe_cmd)

    return init, step


def release_step_of(release: Array, max_step: Array) -> Array:
    """This period's part (4, 3) [m] of each toe command's remaining return `release`
    (4, 3) [m] from its grope's push: all of it, or `max_step` [m] along it if it is
    longer (a straight return at v_release). Differentiable at release = 0 (no return
    pending: the norm's derivative there is 0/0)."""
    length = jnp.sqrt(jnp.maximum(jnp.sum(release * release, axis=1, keepdims=True), 1e-24))
    return release * jnp.minimum(1.0, max_step / jnp.maximum(length, 1e-12))


def touch_command(toe: Array, above: Array, normal: Array, settings: GropeSettings) -> Array:
    """C*: the groping toe's next command (3,) [m, world], lowered along the target
    foothold's unit `normal` for one control period from `toe`: at `v_touch`, but at
    `v_contact` while the command is within `touch_band` of the foothold's mapped surface
    (`clearance` below `above`, the swing's end point), so that the stiff leg meets the
    surface slowly and a toe that finds nothing below it still goes on at full speed."""
    depth = jnp.dot(above - toe, normal)  # how far below the swing's end point the toe is commanded
    near_surface = jnp.abs(depth - settings.clearance) < settings.touch_band
    speed = jnp.where(near_surface, settings.v_contact, settings.v_touch)
    return toe - speed * settings.control_dt * normal


def twist_mode(xy: Array) -> Array:
    """Unit twist mode (4,) of a four-leg stance with toes at horizontal positions xy
    (4, 2): the vertical loads n that change neither the total force nor the moments
    about the horizontal axes (the null space of [1; x; y], signs alternating around
    the stance). A rigid body on four stiff position-controlled legs can carry any
    amount of it: it is set by millimetre errors in the toe heights."""
    A = jnp.concatenate([jnp.ones((1, 4), xy.dtype), xy.T], axis=0)  # (3, 4)
    cof = jnp.stack([(-1.0) ** i * linalg.det_3x3(jnp.delete(A, i, axis=1, assume_unique_indices=True))
                     for i in range(4)])
    return cof / jnp.maximum(jnp.linalg.norm(cof), 1e-12)


def twist_relief(f_z: Array, xy: Array, gain: Array) -> Array:
    """Vertical toe offsets (4,) [m] for one control period that relax the measured
    twist of a four-leg stance: toes carrying the excess rise, the others lower, by
    `gain` [m/N] times the twist load (n . f_z) along the twist mode. The offsets sum to
    zero (the mode's entries do), so the stance's mean toe height is unchanged.

    Not in the paper: its robot's legs are flexible ("back-lash of joints, flexibility
    of joints induced by PD controller"), which spreads a four-leg stance's load by
    itself. Our stiff servos (`model.KP`) do not: without this, a leg carried up to
    1.14 R_ref in A' at R_ref = 0.4 M g cos theta, more than its grope had verified.
    It uses the toe force sensors the robot has; `twist_relief` = 0 turns it off."""
    n = twist_mode(xy)
    return gain * jnp.dot(n, f_z) * n


def shear_relief(force: Array, toes: Array, gain: Array) -> Array:
    """In-plane toe offsets (4, 3) [m] for one control period that share a four-leg
    stance's in-plane load in proportion to the toes' normal loads, so that every toe
    uses the same fraction of its friction cone.

    force: the toes' ground reactions (4, 3) [N] and toes: their positions (4, 3) [m],
    both in a frame whose z axis is the slope normal (the offsets are in that frame, z
    zero); gain [m/N]. Each toe's offset is `gain` times its in-plane reaction less its
    share N_i / sum N of the resultant, without the part that would turn the stance about
    the normal axis (so the offsets sum to zero and do not yaw the stance). A toe that
    carries more than its share has its command moved along its excess reaction, i.e.
    towards where its leg pushes it, which unloads it.

    Not in the paper (its flexible legs comply); our stiff servos share the slope's
    tangential load by stiffness, not by normal load: at R_ref = 0.4 M g cos(theta) the
    lightly loaded toes sat at the friction limit and the stance crept off its pads
    (docs/leggrope.md). `shear_relief` = 0 turns it off."""
    xy = toes[:, :2] - jnp.mean(toes[:, :2], axis=0)
    normal = jnp.maximum(force[:, 2], 0.0)
    share = normal / jnp.maximum(jnp.sum(normal), 1e-9)
    tangential = force[:, :2]
    excess = tangential - share[:, None] * jnp.sum(tangential, axis=0)[None]
    turn = jnp.stack([-xy[:, 1], xy[:, 0]], axis=1)  # rigid rotation about the toes' centroid
    excess = excess - jnp.sum(excess * turn) / jnp.maximum(jnp.sum(turn * turn), 1e-12) * turn
    return gain * jnp.concatenate([excess, jnp.zeros((4, 1), xy.dtype)], axis=1)


def _move(start: Array, end: Array, tau: Array, a_max: Array, v_max: Array) -> tuple[Array, Array]:
    """Point on the straight rest-to-rest move start -> end at time tau (trapezoidal
    speed) and the move's duration."""
    dist = jnp.linalg.norm(end - start)
    s, total = gait.trapezoid(tau, dist, a_max, v_max)
    direction = (end - start) / jnp.where(dist > 0, dist, 1.0)
    return start + s * direction, total
