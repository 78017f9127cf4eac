"""The force-distribution QP of the leg-grope walk (paper Eqs. 11-22) at every 15 ms step
of one walk cycle, as a `lax.scan` (pure JAX; vmaps over slopes and parameters).

Dynamics. The robot is 13 rigid parts (body and 12 links, link masses at their
midpoints); the designed motion (`gait.pose_at`) gives their positions, and their
accelerations follow by differentiating twice with respect to time. The six body rows
of the floating-base dynamics (Eq. 11) are the whole-robot Newton-Euler equations
    sum_n F_n = sum_k m_k (a_k - g),   sum_n (P_n - o) x F_n = sum_k m_k (r_k - o) x (a_k - g)
(o = body origin; the body does not rotate and the links' own rotational inertia is
neglected -- the motion is slow, a_max = 0.15 m/s^2). The leg rows (Eq. 12) give the
joint torques tau_n = tau_o,n - J_n^T F_n with tau_o,n = sum_links J_k^T m_k (a_k - g)
(J: world-frame position Jacobians w.r.t. the leg's joints). F_n is the ground reaction
ON the robot; the paper's f is the force the robot applies (its Eq. 11 reads
M q'' + h + g + J f = 0), so f = -F and the friction pyramid (Eqs. 15-18) is written
for F, whose normal component must be >= 0.

Decision variables. The paper optimizes tau (13 with s); tau and F are in one-to-one
linear correspondence (Eq. 14, away from theta_i3 = n pi), so we optimize
x = [F_1..F_4 in their contact frames Sigma_iS (12), s, r, d (3)] with the same cost:
    Phi = h_s s + 1/2 tau^T W_tau tau + 1/2 (tau - tau_b)^T W_c (tau - tau_b)
          + h_r r + 1/2 |d|^2
Constraints: Newton-Euler (6 equalities); per loaded leg the pyramid of Eqs. 17-18;
s >= -s_tol M g. The paper defines s >= 0; imposing it makes "no QP solution" mean "no
slip-free force distribution", which is the sweep's failure test (the sliver s_tol keeps
an interior: at the end of every step D one leg floats with zero load, so s touches 0
by construction, as in the paper's Fig. 8). Additions, all with fixed shapes so the
program compiles once:
  * r >= 0 relaxes Eq. 19 (F_z <= R_ref + r on the free stance legs) and the groping
    ramp (ramp - r <= F_z <= ramp) at a large price h_r. With R_ref = 1/2 M g cos(theta)
    the admissible regions leave only millimetres of room (see `gait`), so leg mass
    and inertia need a few percent more; hard rules would report "infeasible" for
    reasons that have nothing to do with slipping. r is reported, never hidden.
  * d: three dummy variables with unit curvature. The rows pinning the leg in the air
    to zero force take the place of "d_j = 0" rows when no leg is in the air, so the
    equality matrix is always 9 x 17 with full row rank.
  * `QPSettings.capacity`: optionally a second QP per step, max s without Eq. 19 (the
    slip capacity), for diagnostics.
The groping leg on its ramp (steps B, D) keeps its pyramid with zero margin: its normal
force is driven to 0 by design, where any positive margin is impossible.
Torque continuity uses tau_b of the previous step (none at the first step).
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco import geometry as geo
from jaxloco import qp, stability
from jaxloco.robots.leggrope import gait, kinematics
from jaxloco.robots.leggrope.params import G, LegGropeParams

Array = jax.Array

N_VAR = 17  # F (12), s, r, d (3)
I_S, I_R, I_D = 12, 13, 14
N_EQ = 9
N_INEQ = 26  # 6 per leg, r >= 0, s >= floor
SQRT2 = float(np.sqrt(2.0))
# pyramid rows (Eqs. 17-18) for (F_x, F_y) signs
_PYRAMID = np.array([[-1.0, -1.0], [1.0, 1.0], [1.0, -1.0], [-1.0, 1.0]])


@dataclass(frozen=True)
class QPSettings:
    """Static settings of the per-step QP."""

    iterations: int = 20
    tol: float = 1e-6
    h_r: float = 1.0e4  # price of the normal-force relaxation r [per N]
    s_tol: float = 1e-4  # s >= -s_tol * M g is imposed (a sliver of interior; see module doc)
    capacity: bool = False  # also solve the slip-capacity problem (max s) at every step
    capacity_reg: float = 1e-3  # force regularization of the slip-capacity problem


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class StepDynamics:
    """What the QP of one step needs from the kinematics (world frame, SI)."""

    wrench: Array  # (6,) required total force and moment about `origin`
    origin: Array  # (3,) body origin, reference point of the moments
    contacts: Array  # (4, 3) toe positions
    frames: Array  # (4, 3, 3) contact frames (columns: x gradient, y, z normal)
    tau_o: Array  # (12,) joint torques with zero ground force (leg gravity + inertia)
    B: Array  # (12, 3 * 4) d tau / d F (contact-frame components)
    cog: Array  # (3,) whole-body COG
    reach: Array  # () smallest IK reach margin [m]


def step_dynamics(params: LegGropeParams, walk: gait.WalkParams, plan: gait.CyclePlan, terrain: gait.SlopeTerrain,
                  info: gait.StepInfo, config: gait.WalkConfig) -> StepDynamics:
    """Kinematics, required wrench and torque maps at one step of the cycle."""
    R_GR = plan.R_GR
    m = gait.masses(params)
    gvec = jnp.array([0.0, 0.0, -G], R_GR.dtype)

    def positions(tau):
        body, feet = gait.pose_at(params, walk, plan, info, tau, config)
        return gait.mass_positions(params, R_GR, body, feet)

    r = positions(info.tau)
    acc = jax.jacfwd(jax.jacfwd(positions))(info.tau)  # (13, 3)
    body, feet = gait.pose_at(params, walk, plan, info, info.tau, config)
    q, reach = gait.leg_angles(params, R_GR, body, feet)
    load = m[:, None] * (acc - gvec)  # (13, 3) inertial + gravity load of each part
    force = jnp.sum(load, axis=0)
    moment = jnp.sum(jnp.cross(r - body, load), axis=0)

    legs = jnp.arange(4)
    J_links = jax.vmap(lambda n, qq: jax.jacfwd(lambda x: kinematics.link_com_positions(params, n, x))(qq))(legs, q)
    J_links = jnp.einsum("ij,nkjq->nkiq", R_GR, J_links)  # (4 legs, 3 links, 3, 3) world
    tau_o = jnp.einsum("nkiq,nki->nq", J_links, load[1:].reshape(4, 3, 3)).reshape(12)
    J_foot = jnp.einsum("ij,njq->niq", R_GR, jax.vmap(lambda n, qq: kinematics.foot_jacobian(params, n, qq))(legs, q))

    # contact frame of each foot: the facet it stands on (before or after its step)
    order = jnp.asarray(np.array(config.order))
    rank = jnp.argsort(order)  # position of each leg in the groping order
    moved = (rank < info.grope) | ((rank == info.grope) & (info.phase >= 2))
    normals = jnp.where(moved[:, None], terrain.normals[1], terrain.normals[0])
    frames = jax.vmap(geo.contact_frame)(normals)
    blocks = -jnp.einsum("niq,nij->nqj", J_foot, frames)  # (4, 3 joints, 3 components)
    B = jax.scipy.linalg.block_diag(*[blocks[n] for n in range(4)])
    cog = jnp.sum(r * m[:, None], axis=0) / jnp.sum(m)
    return StepDynamics(jnp.concatenate([force, moment]), body, feet, frames, tau_o, B, cog, jnp.min(reach))


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class LegModes:
    """Role of each leg at a step: free stance, groping on a force ramp, or in the air."""

    free: Array  # (4,) bool
    ramp: Array  # (4,) bool
    air: Array  # (4,) bool
    ramp_value: Array  # () prescribed normal force of the groping leg [N]


def leg_modes(info: gait.StepInfo, ramp_value: Array) -> LegModes:
    """Phase A: all free. B, D: the groping leg on its ramp (in the air once the ramp is
    at zero). C: the groping leg in the air."""
    is_g = jnp.arange(4) == info.leg
    on_ramp = ((info.phase == 1) | (info.phase == 3)) & (ramp_value > 0)
    air = is_g & ((info.phase == 2) | (((info.phase == 1) | (info.phase == 3)) & ~on_ramp))
    ramp = is_g & on_ramp
    return LegModes(free=~air & ~ramp, ramp=ramp, air=air, ramp_value=ramp_value)


def build_constraints(
    params: LegGropeParams, dyn: StepDynamics, modes: LegModes, r_ref: Array | None, s_floor: Array | None
):
    """Equality and inequality rows (A, b, G, h) of one step (see module docstring).

    `r_ref=None` drops Eq. 19 on the free stance legs (the slip-capacity problem);
    `s_floor` adds s >= s_floor (the controller problem). Rows per leg: the four pyramid
    rows, then for a free leg -F_z <= 0 and F_z - r <= R_ref, for the groping leg on its
    ramp ramp - r <= F_z <= ramp. A disabled row is all zeros with right-hand side 1."""
    dtype = dyn.B.dtype
    eye = jnp.eye(N_VAR, dtype=dtype)
    # --- equalities: Newton-Euler (6) + the leg in the air (3)
    A = jnp.zeros((N_EQ, N_VAR), dtype)
    for n in range(4):
        R = dyn.frames[n]
        A = A.at[0:3, 3 * n:3 * n + 3].set(R)
        A = A.at[3:6, 3 * n:3 * n + 3].set(geo.skew(dyn.contacts[n] - dyn.origin) @ R)
    b = jnp.concatenate([dyn.wrench, jnp.zeros(3, dtype)])
    g = jnp.argmax(modes.air)
    in_air = jnp.any(modes.air)
    for k, comp in enumerate((2, 0, 1)):
        A = A.at[6 + k].set(jnp.where(in_air, eye[3 * g + comp], eye[I_D + k]))
    # --- inequalities
    zero_row = jnp.zeros(N_VAR, dtype)
    rows, rhs = [], []

    def add(active, row, value):
        rows.append(jnp.where(active, row, zero_row))
        rhs.append(jnp.where(active, value, 1.0))

    for n in range(4):
        fric = modes.free[n] | modes.ramp[n]
        for sx, sy in _PYRAMID:
            row = zero_row.at[3 * n:3 * n + 3].set(jnp.array([sx, sy, -params.mu]) / SQRT2)
            add(fric, row.at[I_S].set(jnp.where(modes.free[n], 1.0, 0.0)), 0.0)
        fz = eye[3 * n + 2]
        ramp = modes.ramp[n]
        add(modes.free[n] | ramp, jnp.where(ramp, -fz - eye[I_R], -fz), jnp.where(ramp, -modes.ramp_value, 0.0))
        cap = modes.free[n] & (r_ref is not None)
        upper = jnp.where(ramp, fz, fz - eye[I_R])
        add(cap | ramp, upper, jnp.where(ramp, modes.ramp_value, r_ref if r_ref is not None else 1.0))
    add(True, -eye[I_R], 0.0)
    add(s_floor is not None, -eye[I_S], -s_floor if s_floor is not None else 1.0)
    return A, b, jnp.stack(rows), jnp.stack(rhs).astype(dtype)


def controller_cost(params: LegGropeParams, dyn: StepDynamics, tau_b: Array, h_c: Array, settings: QPSettings):
    """(Q, q) of the paper's objective (Eqs. 21-22) in x, plus h_r r and |d|^2 / 2."""
    dtype = dyn.B.dtype
    Bx = jnp.zeros((12, N_VAR), dtype).at[:, :12].set(dyn.B)
    W = params.h_tau + h_c
    Q = W * Bx.T @ Bx + jnp.diag(jnp.zeros(N_VAR, dtype).at[I_D:].set(1.0))
    qv = Bx.T @ (params.h_tau * dyn.tau_o + h_c * (dyn.tau_o - tau_b))
    return Q, qv.at[I_S].add(params.h_s).at[I_R].add(settings.h_r)


def capacity_cost(params: LegGropeParams, dtype, settings: QPSettings):
    """(Q, q) of the slip-capacity problem: maximize s (a tiny force regularization
    makes the solution unique; it lowers s by well under 0.1 N)."""
    weight = params.total_mass * G
    diag = jnp.zeros(N_VAR, dtype).at[:12].set(settings.capacity_reg / weight).at[I_D:].set(1.0)
    qv = jnp.zeros(N_VAR, dtype).at[I_S].set(-1.0).at[I_R].set(settings.h_r)
    return jnp.diag(diag), qv


def x_scale(params: LegGropeParams, dtype) -> Array:
    """Typical magnitudes of the variables for the QP layer's scaling."""
    weight = params.total_mass * G
    return jnp.concatenate([jnp.full(14, 1.0, dtype) * weight, jnp.ones(3, dtype)])


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class CycleSummary:
    """Extremes of one cycle (SI units; margins in N or m)."""

    min_capacity: Array  # smallest slip capacity s_max: best achievable margin [N]
    min_s: Array  # smallest friction safety margin s of the controller QP [N]
    min_leg_margin: Array  # smallest per-leg pyramid margin of any loaded leg [N]
    max_friction_use: Array  # largest (|F_x| + |F_y|) / (mu F_z) of a leg carrying >= 10% of M g
    max_normal_ratio: Array  # largest stance normal force / R_ref outside step D
    max_overshoot: Array  # largest relaxation r of Eq. 19 [N]
    n_qp_failed: Array  # steps whose QP found no solution (no slip-free distribution)
    n_capacity_failed: Array  # steps whose slip-capacity QP failed (if solved)
    max_primal_residual: Array  # largest scaled primal residual of any QP
    min_static_margin: Array  # smallest static stability margin of the stance [m]
    min_ne_margin: Array  # smallest NE stability margin of the stance [m]
    max_torque: Array  # largest |tau_ij| [N m]
    min_reach: Array  # smallest IK reach margin [m]


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class _Carry:
    tau_b: Array
    f_prev: Array
    ramp_start: Array
    first: Array
    summary: CycleSummary


def _update(acc: CycleSummary, step: dict) -> CycleSummary:
    """Fold one step's values into the running extremes."""
    return CycleSummary(
        min_capacity=jnp.minimum(acc.min_capacity, jnp.where(step["cap_ok"], step["capacity"], jnp.inf)),
        min_s=jnp.minimum(acc.min_s, jnp.where(step["ok"], step["s"], jnp.inf)),
        min_leg_margin=jnp.minimum(acc.min_leg_margin, step["leg_margin"]),
        max_friction_use=jnp.maximum(acc.max_friction_use, step["friction_use"]),
        max_normal_ratio=jnp.maximum(acc.max_normal_ratio, step["normal_ratio"]),
        max_overshoot=jnp.maximum(acc.max_overshoot, step["r"]),
        n_qp_failed=acc.n_qp_failed + (~step["ok"]).astype(acc.n_qp_failed.dtype),
        n_capacity_failed=acc.n_capacity_failed + (~step["cap_ok"]).astype(acc.n_qp_failed.dtype),
        max_primal_residual=jnp.maximum(acc.max_primal_residual, step["primal_residual"]),
        min_static_margin=jnp.minimum(acc.min_static_margin, step["static_margin"]),
        min_ne_margin=jnp.minimum(acc.min_ne_margin, step["ne_margin"]),
        max_torque=jnp.maximum(acc.max_torque, jnp.max(jnp.abs(step["tau"]))),
        min_reach=jnp.minimum(acc.min_reach, step["reach"]),
    )


def _initial_summary(dtype) -> CycleSummary:
    inf = jnp.asarray(jnp.inf, dtype)
    zero = jnp.zeros((), jnp.int32)
    return CycleSummary(inf, inf, inf, -inf, -inf, -inf, zero, zero, -inf, inf, inf, -inf, inf)


def simulate_cycle(
    params: LegGropeParams,
    walk: gait.WalkParams,
    terrain: gait.SlopeTerrain,
    config: gait.WalkConfig = gait.WalkConfig(),
    settings: QPSettings = QPSettings(),
    record: bool = False,
):
    """Plan one leg-grope walk cycle and solve the force distribution at every step.

    Returns (plan, summary, trace): `trace` is None unless `record`, then a dict of
    per-step arrays (time [s], grope, phase, forces (4, 3) in the contact frames [N],
    s [N], r [N], tau (12,) [N m], normal-force limit R_ref [N], ok, COG (3,) [m])."""
    plan = gait.plan_cycle(params, walk, terrain, config)
    dtype = plan.body.dtype
    weight = params.total_mass * G
    r_ref = params.r_ref_factor * weight * jnp.cos(terrain.theta)

    def step(carry: _Carry, i):
        info = gait.step_info(i, config, params.dt)
        dyn = step_dynamics(params, walk, plan, terrain, info, config)
        start_unload = (info.phase == 1) & (info.local == 0)
        ramp_start = jnp.where(start_unload, carry.f_prev[info.leg, 2], carry.ramp_start)
        ramp_value = jnp.where(info.phase == 1, ramp_start * (1.0 - info.fraction), r_ref * info.fraction)
        modes = leg_modes(info, ramp_value)
        h_c = jnp.where(carry.first, 0.0, params.h_c)
        scale = x_scale(params, dtype)
        solve = lambda Q, q, c: qp.solve(Q, q, *c, x_scale=scale, iterations=settings.iterations, tol=settings.tol)  # noqa: E731
        Q, qv = controller_cost(params, dyn, carry.tau_b, h_c, settings)
        sol = solve(Q, qv, build_constraints(params, dyn, modes, r_ref, -settings.s_tol * weight))
        if settings.capacity:
            cap = solve(*capacity_cost(params, dtype, settings), build_constraints(params, dyn, modes, None, None))
            cap_ok, capacity = cap.ok, cap.x[I_S]
        else:
            cap_ok, capacity = jnp.ones((), bool), jnp.asarray(jnp.inf, dtype)
        f = sol.x[:12].reshape(4, 3)
        tau = dyn.tau_o + dyn.B @ sol.x[:12]
        loaded = modes.free | modes.ramp
        leg_margin = jnp.min(jnp.where(loaded, stability.friction_margins(f, params.mu), jnp.inf))
        normal_ratio = jnp.max(jnp.where(modes.free, f[:, 2], -jnp.inf)) / r_ref
        carrying = loaded & (f[:, 2] >= 0.1 * weight)
        use = (jnp.abs(f[:, 0]) + jnp.abs(f[:, 1])) / (params.mu * jnp.where(carrying, f[:, 2], 1.0))
        friction_use = jnp.max(jnp.where(carrying, use, 0.0))
        contacts_on = ~modes.air
        values = dict(
            cap_ok=cap_ok,
            capacity=capacity,
            ok=sol.ok,
            s=sol.x[I_S],
            r=sol.x[I_R],
            leg_margin=jnp.where(sol.ok, leg_margin, jnp.inf),
            friction_use=jnp.where(sol.ok, friction_use, 0.0),
            normal_ratio=jnp.where(sol.ok, normal_ratio, -jnp.inf),
            primal_residual=sol.primal_residual,
            static_margin=stability.static_margin(dyn.cog, dyn.contacts, contacts_on),
            ne_margin=stability.ne_stability_margin(dyn.cog, dyn.contacts, contacts_on),
            tau=tau,
            reach=dyn.reach,
        )
        new = _Carry(
            tau_b=jnp.where(sol.ok, tau, carry.tau_b),
            f_prev=jnp.where(sol.ok, f, carry.f_prev),
            ramp_start=ramp_start,
            first=jnp.zeros((), bool),
            summary=_update(carry.summary, values),
        )
        out = None
        if record:
            out = dict(time=i * params.dt + params.dt, grope=info.grope, phase=info.phase, forces=f, s=sol.x[I_S],
                       capacity=capacity,
                       r=sol.x[I_R], tau=tau, r_ref=r_ref, ok=sol.ok, cog=dyn.cog, free=modes.free, ramp=modes.ramp)
        return new, out

    init = _Carry(
        tau_b=jnp.zeros(12, dtype),
        f_prev=jnp.zeros((4, 3), dtype).at[:, 2].set(weight / 4),
        ramp_start=jnp.zeros((), dtype),
        first=jnp.ones((), bool),
        summary=_initial_summary(dtype),
    )
    final, trace = jax.lax.scan(step, init, jnp.arange(config.n_steps))
    return plan, final.summary, trace
