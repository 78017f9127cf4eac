"""The leg-grope quadruped walking one cycle over fragile footholds on a slope, as a
`jaxloco.sim.Scenario` (both backends).

Terrain (`jaxloco.sim.terrain`): a slope box whose surface lies `PAD_THICKNESS` below the
footholds, and 12 fragile pads (mocap bodies with touch sensors) whose top faces are the
footholds of the plan: pads 0-3 the initial footholds of L1..L4, 4-7 their primary
targets, 8-11 their fallback targets. Each pad's top face is tilted to its facet normal
(`facet_spread` > 0 makes the paper's irregular slope: same inclination, scattered
gradient directions). A pad collapses (drops away, `terrain.drop_away`) once its touch
sensor reads more than its R_break; R_break is infinite for the initial pads and, for
the target pads, Mg U(r_break_lo, r_break_hi) with probability p_weak (else infinite);
`weak_leg` (0..3 for L1..L4) makes that leg's primary target weak for certain.

Parameters (one dict per simulation, see `PARAM_DEFAULTS`): theta, psi [rad]; mu;
r_ref_factor (R_ref = factor M g cos theta); stride, swing_height [m]; facet_spread
[rad]; fallback_distance [m]; safe_blend, swing_margin [m], twist_relief and
shear_relief [m/s per M g], grope_blend; p_weak; r_break_lo, r_break_hi [M g]; weak_leg (int, -1 none);
regrope (int: 1 regropes a fallback after a collapse, 0 stops).
"""

from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from jaxloco import geometry as geo
from jaxloco.robots.leggrope import control, gait, kinematics, model
from jaxloco.robots.leggrope.params import LEG_NAMES, PARAMETERS, G, default_params
from jaxloco.sim import metrics as sm
from jaxloco.sim import terrain as tr
from jaxloco.sim.data import SimData, sensor_slice
from jaxloco.sim.scenario import (
    Controller,
    Environment,
    InitialState,
    Scenario,
    friction_field,
)
from jaxloco.sim.scenario import params_batch as sim_params_batch

PAD_THICKNESS = 0.04  # [m] pads stand this far out of the slope
PAD_HALF = 0.018  # [m] pad half side
N_PADS = 12
UNBREAKABLE = 1e9  # [N]
FELL_TILT = 0.35  # [rad] an attitude change beyond this counts as a fall
CONTACT_FORCE = 1.0  # [N] a toe with more normal force than this is a support point
COLLAPSE_WINDOW = 0.2  # [s] `collapse_tilt`: the attitude change over this long after a collapse

# the simulation's params (`params.PARAMETERS`); its default slope is 15 deg, not the
# force-distribution model's level ground
PARAM_DEFAULTS: dict[str, float] = PARAMETERS.defaults((
    "theta", "psi", "mu", "r_ref_factor", "stride", "swing_height", "facet_spread", "fallback_distance", "safe_blend",
    "swing_margin", "twist_relief", "shear_relief", "grope_blend", "p_weak", "r_break_lo", "r_break_hi", "weak_leg",
    "regrope",
)) | {"theta": float(np.pi / 12)}


def build_model(robot_xml: str | Path | None = None, mjx_contacts: bool = False
                ) -> tuple[mujoco.MjModel, tr.Terrain]:
    """The robot (`models/leggrope.xml` unless given) on the slope-and-pads terrain;
    mjx_contacts: the MJX variant's contact options (`model.use_mjx_contacts` with
    `model.MJX_IMPRATIO` and `model.MJX_MAX_CONTACTS`: pyramidal cone, no no-slip solver)."""
    spec = model.load_spec(robot_xml)
    if mjx_contacts:
        model.use_mjx_contacts(spec, model.MJX_IMPRATIO, model.MJX_MAX_CONTACTS)
    terrain = tr.combine(tr.slope(1.5, 1.0), tr.footholds(N_PADS, half_size=PAD_HALF, thickness=PAD_THICKNESS))
    terrain.add_to(spec, friction=(PARAM_DEFAULTS["mu"], 0.005, 0.0001))
    for name in terrain.body_names():
        geom = spec.geom(name)
        geom.solref = list(model.CONTACT_SOLREF)
        geom.solimp = list(model.CONTACT_SOLIMP)
    return spec.compile(), terrain


def make_scenario(
    horizon_s: float = 30.0,
    record_every: int = 5,
    settings: control.GropeSettings | None = None,
    robot_xml: str | Path | None = None,
    numbering: str = "mirrored",
    mjx_contacts: bool = False,
) -> Scenario:
    """The fragile-slope walk scenario (control period settings.control_dt) for a leg
    numbering (`gait.DESIGNS`: "literal" walks along y_R, "mirrored" along x_R). Leg
    labels in parameters and metrics (`weak_leg`, `collapsed_leg`) are the paper's L1..L4
    of that numbering. mjx_contacts: the MJX variant (`build_model`; the same controller,
    terrain and metrics), named "leggrope.fragile_slope_mjx"; its toes creep more (no
    no-slip solver), see docs/simulation.md."""
    settings = settings or control.GropeSettings()
    design = gait.gait_design(numbering)
    physical = jnp.asarray(design.legs)  # physical leg of the paper's L1..L4
    label = jnp.argsort(physical)  # paper label of each physical leg
    m, terrain = build_model(robot_xml, mjx_contacts)
    substeps = round(settings.control_dt / m.opt.timestep)
    horizon = round(horizon_s / settings.control_dt)
    horizon -= horizon % record_every
    mocap = tr.mocap_ids(m, terrain)
    slope_row, pad_rows = int(mocap[0]), mocap[1:]
    touch = [sensor_slice(m, n) for n in terrain.touch_sensor_names()]
    force = [sensor_slice(m, f"{leg}_force") for leg in LEG_NAMES]
    quat_s = sensor_slice(m, "imu_quat")
    toe_sites = np.array([m.site(f"{leg}_toe").id for leg in LEG_NAMES])
    torso = m.body("torso").id
    terrain_geoms = np.array([m.geom(n).id for n in terrain.body_names()])
    slope_half = terrain.pieces[0].half_size
    init_ctrl, step_ctrl = control.make_controller(settings, design)
    mass = float(default_params().total_mass)

    def poses(p, key):
        """Mocap poses (nmocap) of the slope and the intact pads, and the footholds."""
        t = control.walk_footholds(p, key, design)
        n_slope = tr.slope_normal(p["theta"], jnp.zeros_like(p["theta"]))
        s_pos, s_quat = tr.box_pose_from_top(-PAD_THICKNESS * n_slope, n_slope, 0.0, jnp.asarray(slope_half))
        centres = jnp.concatenate([t.feet0, t.cand[:, 0], t.cand[:, 1]])
        normals = jnp.concatenate([t.normals0, t.cand_normals[:, 0], t.cand_normals[:, 1]])
        p_pos, p_quat = tr.pad_poses(centres, normals, PAD_THICKNESS)
        pos = jnp.zeros((m.nmocap, 3), p_pos.dtype).at[slope_row].set(s_pos).at[pad_rows].set(p_pos)
        quat = jnp.zeros((m.nmocap, 4), p_pos.dtype).at[slope_row].set(s_quat).at[pad_rows].set(p_quat)
        return pos, quat, t

    def r_break(p, key):
        k1, k2 = jax.random.split(jax.random.fold_in(key, 7))
        weak = jax.random.uniform(k1, (8,)) < p["p_weak"]
        weak_pad = physical[jnp.clip(p["weak_leg"], 0, 3)]
        weak = weak | ((jnp.arange(8) == weak_pad) & (p["weak_leg"] >= 0))
        level = mass * G * jax.random.uniform(k2, (8,), minval=p["r_break_lo"], maxval=p["r_break_hi"])
        targets = jnp.where(weak, level, UNBREAKABLE)
        return jnp.concatenate([jnp.full(4, UNBREAKABLE), targets])

    def initial_state(p, key):
        pos, quat, t = poses(p, key)
        toes = t.feet0 + model.TOE_RADIUS * t.normals0
        q = control.joint_targets(control.robot_params(p), t.R_GR, t.body0, toes)
        qpos = jnp.concatenate([t.body0, _matrix_to_quat(t.R_GR), q])
        return InitialState(qpos=qpos, qvel=jnp.zeros(m.nv), ctrl=q, mocap_pos=pos, mocap_quat=quat)

    def env_init(p, data: SimData):
        pos, quat, _ = poses(p, p["key"])
        return {"pos": pos, "quat": quat, "collapsed": jnp.zeros(N_PADS, bool), "r_break": r_break(p, p["key"]),
                "t_collapse": jnp.full(N_PADS, jnp.nan)}

    def env_step(p, e, data: SimData):
        loads = jnp.stack([data.sensordata[s][0] for s in touch])
        collapsed = tr.collapse_update(e["collapsed"], loads, e["r_break"])
        pad_pos = tr.drop_away(e["pos"][pad_rows], e["quat"][pad_rows], collapsed)
        t_collapse = jnp.where(collapsed & ~e["collapsed"], data.time, e["t_collapse"])
        new = {**e, "collapsed": collapsed, "t_collapse": t_collapse}
        return new, e["pos"].at[pad_rows].set(pad_pos), e["quat"]

    def observe(data: SimData):
        # the force sensor gives the interaction force between the (massless) toe body and
        # the shank in the toe site frame, pointing from the toe to the shank: minus the
        # ground reaction on the toe. Ground reaction, world frame:
        f_site = jnp.stack([data.sensordata[s] for s in force])
        f_world = -jnp.einsum("lij,lj->li", data.site_xmat[toe_sites], f_site)
        return {"time": data.time, "foot_force": f_world, "quat": data.sensordata[quat_s],
                "q": data.qpos[7:], "dq": data.qvel[6:]}

    def record(p, data: SimData, obs, c: control.GropeState, e):
        t = c.targets
        moved = _moved_legs(c.k, design.order)
        on_fallback = (c.bits >> jnp.arange(4)) & 1
        normals = jnp.where(moved[:, None], t.cand_normals[jnp.arange(4), on_fallback], t.normals0)
        centres = jnp.where(moved[:, None], t.cand[jnp.arange(4), on_fallback], t.feet0)
        return {
            "rpy": sm.quat_to_rpy(obs["quat"]),
            "quat": obs["quat"],
            "normal_force": jnp.einsum("li,li->l", obs["foot_force"], normals),
            "foot_force": obs["foot_force"],
            "toe_pos": data.site_xpos[toe_sites],
            # each toe's contact point off the centre of the foothold it stands on, in
            # the foothold's plane [m] (the pads are 2 PAD_HALF wide)
            "foothold_offset": _in_plane_offset(data.site_xpos[toe_sites] - model.TOE_RADIUS * normals, centres,
                                                normals),
            "cog": data.subtree_com[torso],
            "phase": c.phase,
            "retry": c.cand,  # 1 while the groping leg tries its fallback foothold
            "grope": c.k,
            "leg": label[jnp.asarray(design.order)[jnp.minimum(c.k, 3)]],  # paper label 0..3 = L1..L4
            "collapsed": jnp.sum(e["collapsed"]),
            "r_ref": t.r_ref,
        }

    def summarize(p, r, final):
        c: control.GropeState = final.ctrl_state
        e = final.env_state
        alive_t = jnp.ones(r["phase"].shape[0], bool)
        rpy = r["rpy"]
        att = sm.attitude_extremes(rpy, alive_t)
        tilt = sm.tilt_change(r["quat"], r["quat"][0])
        fell = (jnp.max(tilt) > FELL_TILT) | ~final.alive
        # "outside groping": every leg, outside the leg-grope step D' (paper: "the
        # magnitude of the normal forces except for Step D are less than R_ref")
        groping = (r["phase"] == control.D1) | (r["phase"] == control.D2)
        outside = ((r["phase"] < control.DONE) & ~groping)[:, None] & jnp.ones((1, 4), bool)
        fn = r["normal_force"]
        contacts = fn > CONTACT_FORCE
        margins = sm.support_margins(r["cog"], r["toe_pos"], contacts)
        margin_ok = (r["phase"] < control.DONE) & (jnp.sum(contacts, axis=1) >= 3)
        margin_ok = margin_ok.at[0].set(False)  # t = 0: the robot is placed, not yet loaded
        t = c.targets
        done = c.k >= 4
        survived = jnp.where(fell, 0, c.collapses)
        # collapses of pads that were not being groped at the time (should not happen)
        groped_pads = jnp.zeros(N_PADS, bool).at[4:].set(True)
        unexpected = jnp.sum(e["collapsed"] & ~groped_pads)
        # the load a probed foothold takes later, against the force its grope verified:
        # > 1 means the walk put more on it than it was probed with (at the records' rate)
        probed = _moved_legs(r["grope"][:, None], design.order)  # (n_rec, 4): the leg's grope is done
        window = round(COLLAPSE_WINDOW / (record_every * settings.control_dt))
        probe = _probe_forces(r, fn, c.grope_force, design.order)
        per_probe = fn / jnp.where(probe > 0, probe, jnp.inf)[None, :]
        load_over_probe = _peak(per_probe, probed)
        # the same without the impulse of a collapse (the paper's Fig. 14: "less than R_ref
        # ... except for the impulse"): records within COLLAPSE_WINDOW after any collapse
        steady = probed & ~_after_collapse(r["collapsed"], window)[:, None]
        load_over_probe_steady = _peak(per_probe, steady)
        t_end = sm.first_time(r["phase"] >= control.DONE, jnp.arange(r["phase"].shape[0]) * (
            record_every * settings.control_dt))
        collapsed_leg, collapse_tilt = _first_collapse(r, window)
        late, late_weak, weak_accepted = _probe_outcomes(c, e)
        # the largest offset of a loaded toe from its foothold's centre; not the groping
        # leg from its touchdown to the end of its grope (C* to D'-2, the foothold is being
        # found), while it retries after a collapse (its toe may rest in the hole) or once
        # the walk has stopped;
        # past PAD_HALF the toe has slid off its (probed) foothold
        groping_leg = jnp.arange(4)[None, :] == jnp.asarray(design.order)[jnp.minimum(r["grope"], 3)][:, None]
        finding = (((r["phase"] >= control.TOUCH) & (r["phase"] <= control.D2)) | (r["phase"] == control.STOPPED)
                   | (r["retry"] == 1))
        standing = contacts & ~(groping_leg & finding[:, None])
        offset = _peak(r["foothold_offset"], standing)
        off = offset > PAD_HALF
        return {
            "success": done & ~fell & (c.status == 0) & ~off,
            "completed_gropes": c.k,
            "max_attitude_change": jnp.max(tilt),
            "max_abs_roll": att["max_abs_roll"],
            "max_abs_pitch": att["max_abs_pitch"],
            "max_normal_ratio": sm.force_ratio(fn, t.r_ref, outside),
            "grope_ratio_min": jnp.min(jnp.where(jnp.arange(4) < 4, c.grope_force / t.r_ref, jnp.inf)),
            "max_load_over_probe": load_over_probe,
            "max_load_over_probe_steady": load_over_probe_steady,
            "min_margin": jnp.where(jnp.any(margin_ok), sm.masked_min(margins, margin_ok), jnp.nan),
            "collapses_met": c.collapses,
            "collapses_survived": survived,
            "unexpected_collapses": unexpected,
            "fell": fell,
            "cycle_time": t_end,
            "plan_margin": t.margin,
            "collapsed_leg": collapsed_leg,
            "collapse_tilt": collapse_tilt,
            "late_collapses": late,
            "late_weak_collapses": late_weak,
            "max_foothold_offset": offset,
            "off_foothold": off,
            "weak_accepted": weak_accepted,
            "status": jnp.where(done, 0, jnp.where(c.status > 0, c.status, 2)),
        }

    return Scenario(
        name="leggrope.fragile_slope_mjx" if mjx_contacts else "leggrope.fragile_slope",
        model=m,
        controller=Controller(init_ctrl, step_ctrl, name="leg-grope walk"),
        initial_state=initial_state,
        observe=observe,
        record=record,
        summarize=summarize,
        horizon=horizon,
        substeps=substeps,
        record_every=record_every,
        environment=Environment(env_init, env_step),
        model_fields=(friction_field(terrain_geoms),),
        statuses=control.STATUSES,
    )


# ------------------------------------------------------------------ standing (tests, benchmarks)
STAND_HEIGHT = 0.10  # [m] body height of `standing_scenario`


def _standing_q() -> np.ndarray:
    """Joint angles (12,) with every toe centre 0.2 m out from its hip on the ground."""
    params = default_params()
    hips = np.asarray(params.hips())
    mounts = np.asarray(params.mount_angles())
    qs = []
    for leg in range(4):
        toe = hips[leg] + 0.2 * np.array([np.cos(mounts[leg]), np.sin(mounts[leg]), 0.0])
        toe[2] = -STAND_HEIGHT + model.TOE_RADIUS
        q, reach = kinematics.inverse_kinematics(params, leg, jnp.asarray(toe))
        assert float(reach) > 0
        qs.append(np.asarray(q))
    return np.concatenate(qs)


def standing_scenario(horizon: int = 10, substeps: int = 5, record_every: int = 1, mjx_contacts: bool = True
                      ) -> Scenario:
    """A small scenario for tests and benchmarks: stand on a flat box (top at params['ground'] m), joint targets =
    standing pose plus params['offset'] on every knee, with a 2 Hz wiggle of the L1 yaw joint; params
    ['kick'] is added to the initial vertical body velocity.

    mjx_contacts: contacts that both backends simulate alike (pyramidal cone, no
    no-slip solver; MJX has no no-slip solver, and its elliptic cone gives NaN
    forward-mode derivatives even with no contact active, measured with mujoco-mjx
    3.x); False keeps the robot model's own contact options."""
    spec = model.load_spec()
    if mjx_contacts:
        model.use_mjx_contacts(spec)
    ground = tr.flat(half_extent=2.0, half_depth=0.2)
    ground.add_to(spec)
    m = spec.compile()
    geom = m.geom(ground.body_names()[0]).id
    q0 = jnp.asarray(_standing_q())
    knees = np.arange(2, 12, 3)

    def initial_state(p, key):
        pos, quat = ground.place({"height": p["ground"]})
        qpos = jnp.concatenate([jnp.array([0.0, 0.0, STAND_HEIGHT]) + jnp.array([0, 0, 1.0]) * p["ground"],
                                jnp.array([1.0, 0, 0, 0]), q0])
        qvel = jnp.zeros(m.nv).at[2].set(p["kick"])
        return InitialState(qpos=qpos, qvel=qvel, ctrl=q0, mocap_pos=pos, mocap_quat=quat)

    def init(p, obs):
        return jnp.zeros(())

    def step(p, t, obs):
        action = q0.at[knees].add(p["offset"]).at[0].add(0.2 * jnp.sin(2 * jnp.pi * 2.0 * obs["time"]))
        return t + 1, action

    def observe(data):
        return {"time": data.time, "q": data.qpos[7:]}

    def record(p, data, obs, c, e):
        return {"qpos": data.qpos, "height": data.qpos[2]}

    def summarize(p, r, final):
        return {"final_height": final.data.qpos[2], "mean_height": jnp.mean(r["height"])}

    return Scenario(
        name="test.standing",
        model=m,
        controller=Controller(init, step),
        initial_state=initial_state,
        observe=observe,
        record=record,
        summarize=summarize,
        horizon=horizon,
        substeps=substeps,
        record_every=record_every,
        model_fields=(friction_field([geom]),),
    )



def _first_collapse(r, window: int) -> tuple[jax.Array, jax.Array]:
    """The leg (0..3 = the paper's L1..L4) that was groping when a foothold first collapsed (-1: none)
    and the attitude change [rad] from the record before that collapse to `window` records
    after it (the paper's Fig. 13: about 2 deg for L1; nan without a collapse)."""
    hit = r["collapsed"] >= 1
    any_hit = jnp.any(hit)
    n = hit.shape[0]
    k = jnp.argmax(hit)
    before = r["quat"][jnp.maximum(k - 1, 0)]
    after = r["quat"][jnp.minimum(k + window, n - 1)]
    tilt = sm.tilt_change(after[None], before)[0]
    return jnp.where(any_hit, r["leg"][k], -1), jnp.where(any_hit, tilt, jnp.nan)


def _in_plane_offset(points: jax.Array, centres: jax.Array, normals: jax.Array) -> jax.Array:
    """Distances (4,) [m] of `points` from `centres` within the planes of unit `normals`
    (all (4, 3))."""
    in_plane = jax.vmap(geo.project_to_plane, in_axes=(0, 0, None))(points - centres, normals, 0.0)
    return jnp.linalg.norm(in_plane, axis=-1)


def _peak(x: jax.Array, valid: jax.Array) -> jax.Array:
    """The largest entry of x where `valid` (nan if none is)."""
    return jnp.where(jnp.any(valid), sm.masked_max(x, valid), jnp.nan)


def _after_collapse(collapsed: jax.Array, window: int) -> jax.Array:
    """Records (n_rec,) within `window` records after a foothold collapsed (the count of
    collapsed pads rose in this record or in one of the `window` before it)."""
    rose = jnp.diff(collapsed, prepend=collapsed[:1]) > 0
    count = jnp.cumsum(rose)
    before = jnp.concatenate([jnp.zeros(window + 1, count.dtype), count])[: count.shape[0]]
    return count - before > 0


def _probe_forces(r, fn: jax.Array, grope_force: jax.Array, order) -> jax.Array:
    """The normal force [N] each leg's foothold bore during its grope (4,): the larger of
    the controller's (the filtered force's peak, `GropeState.grope_force`) and the raw
    load recorded while that leg groped (C* to D'-2, at the records' rate, the rate the
    later loads are compared at). The filter lags the raw load by a few per cent, and
    the foothold bore the raw load."""
    rank = jnp.argsort(jnp.asarray(order))
    ph = r["phase"][:, None]
    groping = (r["grope"][:, None] == rank[None, :]) & (ph >= control.TOUCH) & (ph <= control.D2)
    return jnp.maximum(grope_force, jnp.max(jnp.where(groping, fn, 0.0), axis=0))


def _probe_outcomes(c: control.GropeState, e) -> tuple[jax.Array, jax.Array, jax.Array]:
    """How well the gropes verified the footholds the walk stands on. Each leg's groped
    foothold is its fallback pad (8 + leg) if it moved there, else its primary (4 + leg).
    late: groped footholds that collapsed once their grope had accepted them (in the
    period it ended, or later), under a load the grope did not verify; late_weak: those
    of them weaker than R_ref (R_break < R_ref: the grope should have broken them, the
    method's premise says never); weak_accepted: groped footholds weaker than R_ref
    that their grope accepted and that still stand."""
    legs = jnp.arange(4)
    t_done = c.grope_time  # (4,) when each leg's grope ended (inf: not yet)
    pad = jnp.where((c.bits >> legs) & 1, 8 + legs, 4 + legs)
    t_col = e["t_collapse"][pad]
    late = jnp.isfinite(t_col) & (t_col >= t_done)
    weak = e["r_break"][pad] < c.targets.r_ref
    accepted = jnp.isfinite(t_done) & ~e["collapsed"][pad]
    return jnp.sum(late), jnp.sum(late & weak), jnp.sum(accepted & weak)


def _moved_legs(k, order):
    """Which physical legs (4,) have finished their grope after k gropes in the groping
    `order` (physical legs); k of shape (..., 1) gives (..., 4)."""
    rank = jnp.argsort(jnp.asarray(order))  # position of each leg in the order
    return rank < k


def _matrix_to_quat(R):
    """Unit quaternion (w, x, y, z) of a rotation matrix (robust for any angle)."""
    m00, m11, m22 = R[0, 0], R[1, 1], R[2, 2]
    w = jnp.sqrt(jnp.maximum(0.0, 1 + m00 + m11 + m22)) / 2
    x = jnp.sqrt(jnp.maximum(0.0, 1 + m00 - m11 - m22)) / 2
    y = jnp.sqrt(jnp.maximum(0.0, 1 - m00 + m11 - m22)) / 2
    z = jnp.sqrt(jnp.maximum(0.0, 1 - m00 - m11 + m22)) / 2
    x = jnp.copysign(x, R[2, 1] - R[1, 2])
    y = jnp.copysign(y, R[0, 2] - R[2, 0])
    z = jnp.copysign(z, R[1, 0] - R[0, 1])
    q = jnp.stack([w, x, y, z])
    return q / jnp.linalg.norm(q)


def params_batch(n: int = 1, **overrides) -> dict[str, jax.Array]:
    """A batch of n identical parameter dicts (defaults with `overrides`); overrides may
    be arrays of length n to vary one parameter."""
    return sim_params_batch(PARAM_DEFAULTS, n, overrides, int_keys=("weak_leg", "regrope"))
