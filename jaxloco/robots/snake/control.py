"""T² Snake-3 task-space control with switching wheel modes (Tanaka et al., IEEE T-RO
35(1), 2019, Sec. III-B and IV-C): pure JAX, the mode is data (fixed shapes: jit, vmap
and grad work through a change of mode).

    u = u_sigma + u_sigma_ker                                            (Eq. 12)
    u_sigma = B~^{W#} A~ { w~_d_dot - K (w~ - w~_d) }                    (Eq. 13)
    u_sigma_ker = -k_eta (I - B~^{W#} B~) eta,   eta = dV/dvarphi        (Eqs. 14, 17)
    B~^{W#} = W^-1 B~^T (B~ W^-1 B~^T)^-1                                (weighted pseudo-inverse)
    V = phi^T K_V phi                                                    (Eq. 19)
    V = a1 phi^T K_V phi + a2 / ||d||_2                                  (Eq. 20)

u = [phi_dot (12), rho_dot (7)] (joint and base active-wheel speeds, rad/s);
w~ = [w (6), psi_3] with w the pose of the controlled point (`kinematics`: gripper
tip or head) and psi_3 the shape-controllable point (SCP, Sec. IV-C3).

Readings and choices (the paper does not give them):
  * Masked rows. `kinematics.augmented_matrices` keeps the rows that a mode eliminates
    as zeros (fixed shape 18 x 19), which makes B~ W^-1 B~^T singular. We add 1 on the
    diagonal of the eliminated rows: M = B~ W^-1 B~^T + diag(1 - keep). Those rows of
    B~ and of A~ are zero, so the solve gives exactly the paper's pseudo-inverse on the
    kept rows (tested against the compacted matrices).
  * W (weights of the weighted pseudo-inverse, Sec. III-B: "the angular velocity of
    the wheel becomes dominant at the input norm depending on the link length and the
    wheel radius"): W = diag(l^2 I_12, r^2 I_7), so that u^T W u weighs every input by
    the speed [m/s] it gives a point one link length from a joint or the rim of a
    wheel. K = 1 /s on every controlled variable, k_eta = 0.1: first choices, swept and
    tuned in `snake.kv`. `w_wheel` scales the wheels' part: it sets which joints the
    null-space term moves first (docs/snake.md, "the order of the joints"). The
    paper's reason for W bounds it: W = I lets the wheel speeds dominate the norm, so
    its W weighs the wheels less than W = I does (our reading), i.e. `w_wheel` below
    l^2 / r^2 = 3.28; ours (1) is.
  * eta (Eq. 17) is the partial derivative of V with respect to varphi = [phi, rho] at
    a fixed w, as Eq. 18 splits dV/dt; V does not depend on rho (zeros).
  * Eq. 20: d_i is the signed distance of the projected centre of mass P_G from the
    line of the i-th side of the support polygon of the grounded wheels (both wheels of
    every grounded base pair, `stability.support_edge_distances`). 1/||d||_2 with every
    side in the norm; a2 = 0 is Eq. 19.
  * Angle errors of w~ - w~_d are wrapped to (-pi, pi].
  * Mode switching (Sec. IV-C5): the fixing state uses `fixed_mode` (sigma = 1); the
    switching state cycles `mode_order` (2, 3, 4, 5, 6), one mode per Delta T counted
    from the moment the state was entered. The state is entered on command (t >=
    `switch_at`, the operator's joystick; it then stays) or when a joint of phi reaches
    `enter_ratio` of its limit (Table I; the SCP psi_3 excepted) and is left, when not commanded, once every
    joint is back below `exit_ratio` of its limit ("until the robot becomes operable").
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco import linalg, stability
from jaxloco.robots.snake import kinematics
from jaxloco.robots.snake import params as snake_params

Array = jax.Array

N_TASK = 6 + kinematics.M_SCP  # 7: w~ = [w, psi_3]
N_ORDER = snake_params.N_MODES - 1  # 5 modes in the switching state
ANGLE_TASK = np.array([False, False, False, True, True, True, True])  # wrapped errors
PHI_LIMITS = np.array(
    [
        snake_params.PITCH_LIMIT if snake_params.JOINT_IS_PITCH[k] else snake_params.YAW_LIMIT
        for k in snake_params.PHI_JOINTS
    ]
)  # (12,) [rad], Table I

MODE_ORDERS = np.array(
    [
        [2, 3, 4, 5, 6],  # 0: the paper's, lifting from the tail towards the head
        [6, 5, 4, 3, 2],  # 1: from the head towards the tail
        [2, 4, 6, 3, 5],  # 2: interleaved
    ]
)  # switching orders (rows), `ControlParams.mode_order` takes one

# Sec. V-B, Figs. 8-10: K_V = diag(15, 0.015, 15, 0.015, 15, 0.015, 9.6, ..., 0.3) (params.PARAMETERS)
_P = snake_params.PARAMETERS
PAPER_KV_HEAD_YAW = _P.default("kv_head_yaw")
PAPER_KV_HEAD_PITCH = _P.default("kv_head_pitch")
PAPER_KV_BASE = _P.default("kv_base")  # theta_4, the head end of the base part
PAPER_KV_RATIO = _P.default("kv_ratio")  # each base weight is half the one ahead of it (tail-wards)


def kv_diagonal(
    head_yaw: Array = PAPER_KV_HEAD_YAW,
    head_pitch: Array = PAPER_KV_HEAD_PITCH,
    base: Array = PAPER_KV_BASE,
    ratio: Array = PAPER_KV_RATIO,
) -> Array:
    """The diagonal of K_V (12,) from four numbers: the head part's yaw (theta_1..3) and
    pitch (psi_1..3) weights, the base weight of theta_4 and the factor from one base
    joint to the next towards the tail (the paper: 15, 0.015, 9.6, 0.5)."""
    head_yaw, head_pitch, base, ratio = jnp.broadcast_arrays(
        *(jnp.asarray(x, jnp.result_type(float)) for x in (head_yaw, head_pitch, base, ratio))
    )
    head = jnp.stack([head_yaw, head_pitch] * (snake_params.N_H // 2))
    tail = base * ratio ** jnp.arange(snake_params.N_B, dtype=base.dtype)
    return jnp.concatenate([head, tail])


def default_weights(params: snake_params.SnakeParams | None = None, w_wheel: Array = 1.0) -> Array:
    """W (19,) = [l^2 (12), w_wheel r^2 (7)] (module docstring; w_wheel = 1 is ours)."""
    params = snake_params.default_params() if params is None else params
    l2 = jnp.asarray(params.link_length) ** 2
    r2 = jnp.asarray(params.wheel_radius) ** 2 * w_wheel
    return jnp.concatenate([jnp.full(snake_params.N_PHI, l2), jnp.full(snake_params.N_W, r2)])


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class ControlParams:
    """Gains and mode schedule of the controller (every field a leaf: vmap a batch of
    them for sweeps; differentiate the float ones for tuning). SI units, radians."""

    gain: Array = field(default_factory=lambda: jnp.ones(N_TASK))  # K (7,) [1/s]
    weights: Array = field(default_factory=default_weights)  # W (19,)
    k_eta: Array = _P.default("k_eta")  # k_eta
    kv: Array = field(default_factory=kv_diagonal)  # diag K_V (12,)
    a1: Array = 1.0  # Eq. 20 weight of phi^T K_V phi
    a2: Array = _P.default("a2")  # Eq. 20 weight of 1 / ||d|| [m]; 0 gives Eq. 19
    delta_t: Array = _P.default("delta_t")  # Delta T [s], switching period
    mode_order: Array = field(default_factory=lambda: jnp.arange(2, snake_params.N_MODES + 1))  # (5,) sigma values
    fixed_mode: Array = 1  # sigma of the fixing state
    switch_at: Array = jnp.inf  # [s] operator's command of the switching state
    enter_ratio: Array = 0.99  # auto switching: |phi_i| >= ratio * limit_i (> 1: off)
    exit_ratio: Array = 0.9  # ... left when every |phi_i| <= ratio * limit_i

    def with_(self, **changes) -> ControlParams:
        return replace(self, **changes)


def paper_params(**changes) -> ControlParams:
    """The joint-limit experiment's settings (Sec. V-B): Delta T = 1 s, K_V of the
    paper; `changes` override fields."""
    return ControlParams().with_(**changes)


# ------------------------------------------------------------------------ cost function
def cost_joint(phi: Array, kv: Array) -> Array:
    """Eq. 19: V = phi^T K_V phi with K_V = diag(kv)."""
    return jnp.sum(kv * phi * phi)


def support_distances(
    w_h: Array,
    phi: Array,
    grounded: Array,
    params: snake_params.SnakeParams | None = None,
) -> tuple[Array, Array, Array]:
    """Signed distances of the projected centre of mass P_G from the support polygon's
    side lines (Fig. 15): (d (14, 14), edges (14, 14) bool, static margin [m]). The
    polygon spans both wheels of every grounded base pair (`grounded` (7,))."""
    joints = kinematics.full_joint_angles(phi)
    cog = kinematics.center_of_mass(w_h, joints, params)
    pts = kinematics.wheel_contacts(w_h, joints, params).reshape(-1, 3)
    mask = jnp.repeat(jnp.asarray(grounded, bool), 2)
    d, E = stability.support_edge_distances(cog, pts, mask)
    return d, E, stability.static_margin(cog, pts, mask)


def support_norm(w_h: Array, phi: Array, grounded: Array, params=None) -> Array:
    """||d||_2 of Eq. 20 [m]: the root of the summed squared distances from P_G to
    every side line of the support polygon."""
    d, E, _ = support_distances(w_h, phi, grounded, params)
    return jnp.sqrt(jnp.sum(jnp.where(E, d * d, 0.0)) + jnp.finfo(d.dtype).tiny)


def cost(
    w: Array,
    phi: Array,
    grounded: Array,
    cp: ControlParams,
    params: snake_params.SnakeParams | None = None,
    point: str = "tip",
) -> Array:
    """V of Eq. 20 (Eq. 19 when a2 = 0) at the controlled-point pose w and joints phi."""
    v = cp.a1 * cost_joint(phi, cp.kv)
    w_h = kinematics.point_to_head(w, point, params)
    # always evaluated (no branch on a2): V is affine in a2, and its derivative in a2
    # at a2 = 0 is 1 / ||d||, which a branch would hide from gradient tuning
    return v + jnp.asarray(cp.a2, v.dtype) / support_norm(w_h, phi, grounded, params)


def eta(
    w: Array,
    phi: Array,
    grounded: Array,
    cp: ControlParams,
    params: snake_params.SnakeParams | None = None,
    point: str = "tip",
) -> Array:
    """Eq. 17: eta = dV/dvarphi (19,), varphi = [phi, rho], at fixed w (zeros for rho)."""
    g = jax.grad(cost, argnums=1)(w, phi, grounded, cp, params, point)
    return jnp.concatenate([g, jnp.zeros(snake_params.N_W, g.dtype)])


# ------------------------------------------------------------------ control law (12-14)
def weighted_pinv(Bt: Array, weights: Array, keep: Array) -> Array:
    """B~^{W#} (19, 18) = W^-1 B~^T (B~ W^-1 B~^T)^-1 on the kept rows: rows that the
    mode eliminated (zero in B~) get 1 on the diagonal of the inverted matrix and a zero
    column in the result."""
    winv = 1.0 / weights
    BW = Bt * winv[None, :]  # B~ W^-1 (18, 19)
    M = BW @ Bt.T + jnp.diag(jnp.where(keep, 0.0, 1.0).astype(Bt.dtype))
    return linalg.spd_solve(M, BW).T


def keep_rows(grounded: Array) -> Array:
    """(18,) rows of A~ / B~ kept in a mode: `kinematics.row_mask` plus the SCP row."""
    return jnp.concatenate([kinematics.row_mask(grounded), jnp.ones(kinematics.M_SCP, bool)])


def task_error(wt: Array, wt_d: Array) -> Array:
    """w~ - w~_d (7,) with the angle entries wrapped to (-pi, pi]."""
    e = wt - wt_d
    wrapped = jnp.arctan2(jnp.sin(e), jnp.cos(e))
    return jnp.where(jnp.asarray(ANGLE_TASK), wrapped, e)


def controlled_variable(w: Array, phi: Array) -> Array:
    """w~ = [w, S phi] (7,): the controlled-point pose and the SCP psi_3."""
    return jnp.concatenate([w, phi[snake_params.SCP_INDEX : snake_params.SCP_INDEX + 1]])


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class ControlTerms:
    """The parts of one control input (for tests and plots)."""

    u: Array  # (19,) Eq. 12
    u_task: Array  # (19,) Eq. 13
    u_null: Array  # (19,) Eq. 14
    eta: Array  # (19,) Eq. 17
    error: Array  # (7,) w~ - w~_d (angles wrapped)
    cost: Array  # V


def control_terms(
    w: Array,
    phi: Array,
    wt_d: Array,
    wt_d_dot: Array,
    grounded: Array,
    cp: ControlParams,
    params: snake_params.SnakeParams | None = None,
    point: str = "tip",
    matrices: tuple[Array, Array] | None = None,
) -> ControlTerms:
    """Eqs. 12-14 at the controlled-point pose w (6,) and joints phi (12,) in the mode
    with grounded base pairs `grounded` (7,); targets w~_d (7,) and w~_d_dot (7,).
    `matrices` = (A~, B~) from `kinematics.augmented_matrices` if already computed."""
    At, Bt = (
        kinematics.augmented_matrices(w, phi, grounded, params=params, point=point)
        if matrices is None
        else matrices
    )
    pinv = weighted_pinv(Bt, cp.weights, keep_rows(grounded))
    err = task_error(controlled_variable(w, phi), wt_d)
    u_task = pinv @ (At @ (wt_d_dot - cp.gain * err))
    h = eta(w, phi, grounded, cp, params, point)
    u_null = -cp.k_eta * (h - pinv @ (Bt @ h))
    V = cost(w, phi, grounded, cp, params, point)
    return ControlTerms(u_task + u_null, u_task, u_null, h, err, V)


def control_input(w, phi, wt_d, wt_d_dot, grounded, cp, params=None, point="tip", matrices=None) -> Array:
    """u (19,) of Eq. 12 (see `control_terms`)."""
    return control_terms(w, phi, wt_d, wt_d_dot, grounded, cp, params, point, matrices).u


# ------------------------------------------------------------------------ mode switching
@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class ModeState:
    """Fixing (False) or switching (True) state and when the latter was entered [s]."""

    switching: Array
    t_enter: Array


def initial_mode_state(dtype=None) -> ModeState:
    dtype = dtype or jnp.result_type(float)
    return ModeState(jnp.asarray(False), jnp.asarray(0.0, dtype))


NOT_SCP = np.arange(snake_params.N_PHI) != snake_params.SCP_INDEX  # the SCP psi_3 is held near its limit on purpose


def limit_ratio(phi: Array) -> Array:
    """max_i |phi_i| / limit_i over the joints of phi but the SCP psi_3 (its target,
    110 deg, is 97 % of the limit by design, Sec. IV-C3): 1 at a joint limit (Table I)."""
    r = jnp.abs(phi) / jnp.asarray(PHI_LIMITS, phi.dtype)
    return jnp.max(jnp.where(jnp.asarray(NOT_SCP), r, 0.0), axis=-1)


def update_mode(t: Array, phi: Array, state: ModeState, cp: ControlParams) -> tuple[ModeState, Array]:
    """Next (ModeState, sigma) at time t [s] with joints phi (module docstring)."""
    ratio = jax.lax.stop_gradient(limit_ratio(phi))
    commanded = t >= cp.switch_at
    switching = commanded | (ratio >= cp.enter_ratio) | (state.switching & (ratio > cp.exit_ratio))
    t_enter = jnp.where(switching & ~state.switching, t, state.t_enter)
    k = jnp.floor((t - t_enter) / cp.delta_t + 1e-9).astype(jnp.int32)
    order = jnp.asarray(cp.mode_order)
    sigma = jnp.where(switching, order[jnp.mod(k, order.shape[0])], cp.fixed_mode)
    return ModeState(switching, t_enter.astype(state.t_enter.dtype)), sigma.astype(jnp.int32)


def grounded_of(sigma: Array) -> Array:
    """Table II row of mode sigma (1-based): (7,) bool, True = grounded."""
    return jnp.asarray(snake_params.MODES)[jnp.asarray(sigma) - 1]
