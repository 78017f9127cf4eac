"""T² Snake-3 kinematics (pure JAX): the chain's forward kinematics, the head and
gripper-tip poses, the wheel contact points and the velocity constraints of Eqs. 2-11
of Tanaka et al. (IEEE T-RO 35(1), 2019) for each mode of Table II.

Chain (layout and signs in `params`): links 1 (head) .. 18 (tail), joint k between
links k and k+1, alternating theta_1, psi_1, ..., psi_8, theta_9. Link j's frame is at
its front end (the joint with link j - 1; for the head, the head point), x forward,
y left, z up; its rear end (the next joint) is at (-l, 0, 0). The root of the chain is
the head: the generalized coordinates are the paper's q = [w, phi] with w the pose of
the controlled point (gripper tip, or head for the accuracy experiments of Sec. V-A)
and phi = [phi_h, phi_b] = [theta_1, psi_1, theta_2, psi_2, theta_3, psi_3,
theta_4, ..., theta_9] (12). The base pitch angles psi_b = psi_4..psi_8 only lift
wheels and are assumed not to move the links (Sec. II-A); they are a fixed argument
(default 0), never differentiated. Poses w = [x, y, z, roll, pitch, yaw] with
R = Rz(yaw) Ry(pitch) Rx(roll) (`geometry.rpy_to_matrix`), so w_dot holds Euler-angle
rates as the paper's w_dot does.

    R_{k+1} = R_k Rz(-theta)   (yaw joint: theta > 0 turns the front link left)
    R_{k+1} = R_k Ry(+psi)     (pitch joint: psi > 0 raises the front link)
    p_{k+1} = p_k + R_k (-l, 0, 0)

The MJCF (`model.py`) uses the same frames (hinge axes -z and +y), which the tests
check against `mj_kinematics`.

Velocity constraints (Sec. III-A). Reading of the paper and derivation used here:

  * No skid, Eq. 2 rows 1..n_b+1 (side slip): the base part, flat on the ground, is
    n_b + 1 = 7 rigid planar segments between the yaw joints theta_4..theta_9; each
    carries one wheel pair (base pair i, Table II numbering; pair 1 at psi_3, pair 7 at
    the tail). With c_i(q) the wheel contact point (body-fixed on the carrying link,
    r below the axle midpoint along the link z) and y_i the axle direction,

        y_i . (dc_i/dq) q_dot = 0,   dc_i/dq = jax.jacfwd of c_i(w, phi).

    Both wheels of a pair have the same lateral velocity (the offset +-d y_i does not
    change y_i . v), and the wheel's own spin adds nothing along y_i, so one row per
    pair is the side-slip condition of the pair's two contact points.
  * Eq. 2 rows n_b+2..n_b+4 (the base part stays on the plane): with psi_b frozen the
    base is one planar chain; it stays on z = 0 iff its first link (link 7) keeps
    z_dot = 0 at the psi_3 axle and its world angular velocity has no x and y part:
    three rows [v_z, omega_x, omega_y] of link 7, omega from dR/dq R^T (autodiff).
  * Eq. 3 (rolling of the active wheels, n_w = 7, one per base pair): the material
    point of the active wheel at its contact a_i = c_i + d y_i (d = wheel_y, the active
    wheel on the left) has no forward velocity,
        x_i . (da_i/dq) q_dot - r rho_dot_i = 0
    (wheel spin rho about +y_i; rho_dot > 0 drives forward). The offset d matters: a
    segment turning at omega_z moves a_i forward by -d omega_z relative to c_i, so the
    rolling rows depend on which side of the pair is active (Fig. 4(b)).
  * Writing each row as a_row w_dot + b_row phi_dot + c_row rho_dot = 0, the paper's
    A w_dot = B u with u = [phi_dot, rho_dot] (12 + 7 = 19) gives A = a,
    B = -[b, c]. Eq. 5-6: A is (n_b + n_w + 4) x 6 = 17 x 6, B is 17 x (n_h + n_b +
    n_w) = 17 x 19, rows ordered [side slip (7), plane (3), rolling (7)] = [A_a; A_b].
    Eq. 6 prints B = [[B_a, 0], [B_b]]: B_a is (n_b+4) x (n_h+n_b) and the zero block is
    (n_b+4) x n_w (the side-slip and plane rows do not depend on rho_dot).
  * Modes (Eqs. 7-8, Table II): in mode sigma the lifted pairs n'_k drop their side-slip
    row and their active wheel n''_k drops its rolling row (a lifted pair lifts its
    active wheel, so n_bar = n_tilde = 2 for every mode of Table II). Here sigma is data:
    `params.MODES[sigma - 1]` is a (7,) grounded mask, and an eliminated row is set to
    zero instead of removed, so every mode has the fixed shape 17 x 6 / 17 x 19 (jit /
    vmap over modes). `compact_rows` removes the zero rows to get the paper's
    (n_b - n_bar + n_w - n_tilde + 4) = 13-row matrices. Redundancy (columns of B minus
    rows): 19 - 13 = 6 = n_h + n_bar + n_tilde - 4 as the paper states.
  * Eqs. 9-11 with the SCP of Sec. IV-C3 (m = 1, phi_tilde = S phi = psi_3 = phi[5]):
        A_tilde = [[A_sigma, 0], [0, I_m]]      (17 + 1) x (6 + 1)
        B_tilde = [[B_sigma], [S, 0]]           (17 + 1) x 19
    Eq. 10 prints the row count as (n_b - n_bar + n_w - n_tilde + 4 + m), i.e. for the
    compacted matrices; ours carry the eliminated rows as zeros.
  * Sec. IV-C3 writes "define phi = psi_{n_h/2}" for the SCP; read phi_tilde (phi is the
    joint vector), a typo.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco import geometry as geo
from jaxloco.robots.snake import params as snake_params

Array = jax.Array

N_ROWS = snake_params.N_PAIRS_BASE + 3 + snake_params.N_W  # 17 = n_b + n_w + 4
N_U = snake_params.N_PHI + snake_params.N_W  # 19 = n_h + n_b + n_w
M_SCP = 1
SELECTION = np.eye(snake_params.N_PHI)[[snake_params.SCP_INDEX]]  # S (1, 12)
_BASE_LINK = int(snake_params.PAIR_LINKS[snake_params.BASE_PAIRS[0]]) - 1  # link 7 (0-based 6)
_PAIR_LINK_IDX = np.asarray(snake_params.PAIR_LINKS) - 1  # 0-based link of each of the 9 pairs
# the links behind the base's twist hinges (`scenarios.twisting_base`), one behind each base yaw joint theta_4 ..
# theta_9: links 8, 10, ..., 18 (0-based 7, 9, ..., 17)
TWIST_LINKS = tuple(_BASE_LINK + 1 + 2 * k for k in range(snake_params.N_B))


def _dtype(x: Array) -> jnp.dtype:
    return jnp.result_type(x, jnp.float32)


def full_joint_angles(phi: Array, psi_b: Array | None = None) -> Array:
    """The 17 joint angles theta_1, psi_1, ..., theta_9 from phi (12,) and psi_b (5,)
    (default zeros)."""
    phi = jnp.asarray(phi)
    q = jnp.zeros(snake_params.N_JOINTS, _dtype(phi)).at[snake_params.PHI_JOINTS].set(phi)
    if psi_b is not None:
        q = q.at[snake_params.PSI_B_JOINTS].set(jnp.asarray(psi_b, q.dtype))
    return q


def pose_matrix(w: Array) -> tuple[Array, Array]:
    """(R (3, 3), p (3,)) of a pose w = [x, y, z, roll, pitch, yaw]."""
    return geo.rpy_to_matrix(w[3], w[4], w[5]), w[:3]


def link_frames(
    w_h: Array, joints: Array, params: snake_params.SnakeParams | None = None, twist: Array | None = None
) -> tuple[Array, Array]:
    """World frames of the 18 links: rotations (18, 3, 3) and origins (18, 3), from the
    head pose w_h (6,) and the 17 joint angles [rad]; `twist` (6,) [rad]: the base's
    twists behind theta_4 .. theta_9 (`twisted`; None: a rigid base, the model's default)."""
    params = snake_params.default_params() if params is None else params
    w_h = jnp.asarray(w_h)
    joints = jnp.asarray(joints, w_h.dtype)
    l = jnp.asarray(params.link_length, w_h.dtype)
    R0, p0 = pose_matrix(w_h)
    is_pitch = jnp.asarray(snake_params.JOINT_IS_PITCH)

    def step(carry, inp):
        R, p = carry
        angle, pitch = inp
        rel = jnp.where(pitch, geo.rot_y(angle), geo.rot_z(-angle))
        p_next = p - l * R[:, 0]
        R_next = R @ rel
        return (R_next, p_next), (R_next, p_next)

    _, (Rs, ps) = jax.lax.scan(step, (R0, p0), (joints, is_pitch))
    Rs, ps = jnp.concatenate([R0[None], Rs]), jnp.concatenate([p0[None], ps])
    return (Rs, ps) if twist is None else twisted(Rs, ps, twist)


def twisted(Rs: Array, ps: Array, twist: Array) -> tuple[Array, Array]:
    """The link frames (Rs (18, 3, 3), ps (18, 3), world) with the base's twists applied:
    twist (6,) [rad], twist[k] turns link 8 + 2k and every link behind it about that
    link's x axis through its origin (the axle of theta_{4+k}; `scenarios.twisting_base`,
    the MuJoCo hinge after theta_{4+k} in that link's body)."""
    twist = jnp.asarray(twist, Rs.dtype)
    for k in range(len(TWIST_LINKS) - 1, -1, -1):  # the tail's first: each turn carries the twists behind it
        link = TWIST_LINKS[k]
        R, p = Rs[link], ps[link]
        turn = R @ geo.rot_x(twist[k]) @ R.T  # world frame
        behind = np.arange(Rs.shape[0]) >= link
        Rs = jnp.where(behind[:, None, None], turn @ Rs, Rs)
        ps = jnp.where(behind[:, None], p + (ps - p) @ turn.T, ps)
    return Rs, ps


def tip_from_head(w_h: Array, params: snake_params.SnakeParams | None = None) -> Array:
    """Gripper-tip pose w (6,) from the head pose w_h: the tip is `gripper_tip` ahead
    of the head frame along its x, same attitude."""
    params = snake_params.default_params() if params is None else params
    R, p = pose_matrix(w_h)
    return jnp.concatenate([p + params.gripper_tip * R[:, 0], w_h[3:]])


def head_from_tip(w: Array, params: snake_params.SnakeParams | None = None) -> Array:
    """Inverse of `tip_from_head`."""
    params = snake_params.default_params() if params is None else params
    R, p = pose_matrix(w)
    return jnp.concatenate([p - params.gripper_tip * R[:, 0], w[3:]])


def wheel_pairs(
    w_h: Array, joints: Array, params: snake_params.SnakeParams | None = None, twist: Array | None = None
) -> tuple[Array, Array, Array]:
    """All 9 wheel pairs (psi_1..psi_8, tail): axle midpoints (9, 3), contact points
    (9, 3) (r below the axle along the carrying link's z) and the carrying links'
    rotations (9, 3, 3) (columns: forward x, axle y, up z); `twist`: `link_frames`."""
    params = snake_params.default_params() if params is None else params
    Rs, ps = link_frames(w_h, joints, params, twist)
    R = Rs[_PAIR_LINK_IDX]
    off = jnp.asarray(snake_params.PAIR_OFFSETS, ps.dtype)
    off = jnp.where(off < 0, -params.tail_axle, off)  # tail pair: -tail_axle
    axle = ps[_PAIR_LINK_IDX] + off[:, None] * R[:, :, 0]
    contact = axle - params.wheel_radius * R[:, :, 2]
    return axle, contact, R


def base_frame_pose(
    base: Array,
    phi: Array,
    psi_b: Array | None = None,
    params: snake_params.SnakeParams | None = None,
) -> Array:
    """Head pose w_h (6,) that puts the base part flat on the ground z = 0: base =
    [x, y, heading] of the first base link (link 7, origin on the psi_3 axle, wheel
    radius above the ground)."""
    params = snake_params.default_params() if params is None else params
    base = jnp.asarray(base)
    zero = jnp.zeros(6, base.dtype)
    Rs, ps = link_frames(zero, full_joint_angles(phi, psi_b), params)
    R_rel, p_rel = Rs[_BASE_LINK], ps[_BASE_LINK]  # link 7 in the head frame
    R_b = geo.rot_z(base[2])
    p_b = jnp.stack([base[0], base[1], jnp.asarray(params.wheel_radius, base.dtype)])
    R_h = R_b @ R_rel.T
    p_h = p_b - R_h @ p_rel
    return jnp.concatenate([p_h, geo.matrix_to_rpy(R_h)])


def _vee(W: Array) -> Array:
    return jnp.stack([W[2, 1], W[0, 2], W[1, 0]])


def constraint_matrices(
    w: Array,
    phi: Array,
    psi_b: Array | None = None,
    params: snake_params.SnakeParams | None = None,
    point: str = "tip",
) -> tuple[Array, Array]:
    """A (17, 6) and B (17, 19) of Eqs. 4-6 (all base wheels grounded): A w_dot = B u,
    u = [phi_dot (12), rho_dot (7)], rows [side slip of base pairs 1..7, plane (v_z,
    omega_x, omega_y of link 7), rolling of active wheels 1..7]. `w` is the pose of the
    controlled point: the gripper tip (`point="tip"`, the paper's w) or the head
    (`point="head"`, w_h of Sec. V-A)."""
    params = snake_params.default_params() if params is None else params
    w = jnp.asarray(w)
    phi = jnp.asarray(phi, w.dtype)
    to_head = (lambda x: head_from_tip(x, params)) if point == "tip" else (lambda x: x)
    if point not in ("tip", "head"):
        raise ValueError(f"point must be 'tip' or 'head', not {point!r}")

    def geometry(w_, phi_):
        joints = full_joint_angles(phi_, psi_b)
        Rs, _ = link_frames(to_head(w_), joints, params)
        _, contact, R = wheel_pairs(to_head(w_), joints, params)
        base = snake_params.BASE_PAIRS
        active = contact + (snake_params.ACTIVE_SIDE * pair_wheel_y(params, contact.dtype))[:, None] * R[:, :, 1]
        return contact[base], active[base], R[base], Rs[_BASE_LINK]

    _, _, R, R7 = geometry(w, phi)
    (jw, jp), (aw, ap) = jax.jacfwd(lambda a, b: geometry(a, b)[:2], argnums=(0, 1))(
        w, phi
    )
    # (7, 3, 6), (7, 3, 12): contact point velocity = jw w_dot + jp phi_dot (pair
    # midpoint), aw w_dot + ap phi_dot (active wheel's contact point)
    x_ax, y_ax = R[:, :, 0], R[:, :, 1]
    slip_a = jnp.einsum("ik,ikn->in", y_ax, jw)
    slip_b = jnp.einsum("ik,ikn->in", y_ax, jp)
    roll_a = jnp.einsum("ik,ikn->in", x_ax, aw)
    roll_b = jnp.einsum("ik,ikn->in", x_ax, ap)
    # plane rows: v_z of the psi_3 contact point, omega_x, omega_y of link 7 (world)
    dRw, dRp = jax.jacfwd(lambda a, b: geometry(a, b)[3], argnums=(0, 1))(w, phi)
    om_w = jax.vmap(lambda d: _vee(d @ R7.T), in_axes=2, out_axes=1)(dRw)  # (3, 6)
    om_p = jax.vmap(lambda d: _vee(d @ R7.T), in_axes=2, out_axes=1)(dRp)  # (3, 12)
    plane_a = jnp.concatenate([jw[0, 2:3], om_w[:2]])
    plane_b = jnp.concatenate([jp[0, 2:3], om_p[:2]])
    n_w = snake_params.N_W
    r = jnp.asarray(params.wheel_radius, w.dtype)
    A = jnp.concatenate([slip_a, plane_a, roll_a])
    B_phi = -jnp.concatenate([slip_b, plane_b, roll_b])
    B_rho = jnp.concatenate(
        [jnp.zeros((snake_params.N_PAIRS_BASE + 3, n_w), w.dtype), r * jnp.eye(n_w, dtype=w.dtype)]
    )  # -(-r rho_dot): rolling row a w_dot + b phi_dot - r rho_dot = 0
    return A, jnp.concatenate([B_phi, B_rho], axis=1)


def row_mask(grounded: Array) -> Array:
    """Rows of (A, B) kept in a mode: grounded (7,) bool -> (17,) bool ([pairs, plane,
    active wheels])."""
    grounded = jnp.asarray(grounded, bool)
    return jnp.concatenate([grounded, jnp.ones(3, bool), grounded])


def mode_matrices(
    w: Array,
    phi: Array,
    grounded: Array,
    psi_b: Array | None = None,
    params: snake_params.SnakeParams | None = None,
    point: str = "tip",
) -> tuple[Array, Array]:
    """A_sigma (17, 6), B_sigma (17, 19) of Eqs. 7-8 with the eliminated rows of the
    lifted pairs / active wheels set to zero; `grounded` (7,) = params.MODES[sigma-1]."""
    A, B = constraint_matrices(w, phi, psi_b, params, point)
    keep = row_mask(grounded)[:, None]
    return jnp.where(keep, A, 0.0), jnp.where(keep, B, 0.0)


def augmented_matrices(
    w: Array,
    phi: Array,
    grounded: Array,
    psi_b: Array | None = None,
    params: snake_params.SnakeParams | None = None,
    point: str = "tip",
) -> tuple[Array, Array]:
    """A_tilde (18, 7) and B_tilde (18, 19) of Eqs. 10-11 with the SCP psi_3 (m = 1):
    A_tilde [w_dot; psi_3_dot] = B_tilde u."""
    A, B = mode_matrices(w, phi, grounded, psi_b, params, point)
    dt = A.dtype
    S = jnp.asarray(SELECTION, dt)
    At = jnp.block(
        [
            [A, jnp.zeros((N_ROWS, M_SCP), dt)],
            [jnp.zeros((M_SCP, 6), dt), jnp.eye(M_SCP, dtype=dt)],
        ]
    )
    Bt = jnp.concatenate([B, jnp.concatenate([S, jnp.zeros((M_SCP, snake_params.N_W), dt)], 1)])
    return At, Bt


def constraint_on_velocity(
    w: Array,
    phi: Array,
    grounded: Array,
    psi_b: Array | None = None,
    params: snake_params.SnakeParams | None = None,
    point: str = "tip",
) -> Array:
    """C_sigma = [A_sigma, -B_sigma] (17, 25): C [w_dot; phi_dot; rho_dot] = 0 is the
    mode's constraint on the generalized velocity."""
    A, B = mode_matrices(w, phi, grounded, psi_b, params, point)
    return jnp.concatenate([A, -B], axis=1)


def compact_rows(M: np.ndarray, grounded: np.ndarray, extra: int = 0) -> np.ndarray:
    """The paper's shape: remove the eliminated rows (numpy, not traceable); `extra`
    trailing rows (the SCP rows of A_tilde / B_tilde) are kept."""
    keep = np.concatenate([np.asarray(row_mask(grounded)), np.ones(extra, bool)])
    return np.asarray(M)[keep]


def point_to_head(w: Array, point: str, params: snake_params.SnakeParams | None = None) -> Array:
    """Head pose w_h of a controlled-point pose `w` (`point` "tip": the gripper tip,
    "head": w is already w_h)."""
    if point == "tip":
        return head_from_tip(w, params)
    if point == "head":
        return w
    raise ValueError(f"point must be 'tip' or 'head', not {point!r}")


def head_to_point(w_h: Array, point: str, params: snake_params.SnakeParams | None = None) -> Array:
    """Inverse of `point_to_head`."""
    if point == "tip":
        return tip_from_head(w_h, params)
    if point == "head":
        return w_h
    raise ValueError(f"point must be 'tip' or 'head', not {point!r}")


def base_of(
    w_h: Array,
    phi: Array,
    psi_b: Array | None = None,
    params: snake_params.SnakeParams | None = None,
) -> Array:
    """Planar pose [x, y, heading] (3,) of the first base link (link 7, origin on the
    psi_3 axle) from the head pose and phi: the inverse of `base_frame_pose` for a base
    flat on the ground (world frame, m and rad)."""
    Rs, ps = link_frames(w_h, full_joint_angles(phi, psi_b), params)
    R, p = Rs[_BASE_LINK], ps[_BASE_LINK]
    return jnp.stack([p[0], p[1], jnp.arctan2(R[1, 0], R[0, 0])])


def wheel_contacts(
    w_h: Array,
    joints: Array,
    params: snake_params.SnakeParams | None = None,
) -> Array:
    """Ground contact points (7, 2, 3) of both wheels of base pairs 1..7 (index 0: the
    active, left wheel; 1: the passive one), world frame: each pair's contact point
    offset by +-wheel_y along its axle."""
    params = snake_params.default_params() if params is None else params
    _, contact, R = wheel_pairs(w_h, joints, params)
    c, y = contact[snake_params.BASE_PAIRS], R[snake_params.BASE_PAIRS][:, :, 1]
    d = (snake_params.ACTIVE_SIDE * pair_wheel_y(params, c.dtype)[snake_params.BASE_PAIRS])[:, None]
    return jnp.stack([c + d * y, c - d * y], axis=1)


def pair_wheel_y(params: snake_params.SnakeParams, dtype=None) -> Array:
    """(9,) each pair's wheel centres from its axle midpoint [m] (`params.wheel_y`, a
    scalar is the same for every pair)."""
    return jnp.broadcast_to(jnp.asarray(params.wheel_y, dtype), (snake_params.N_PAIRS,))


def center_of_mass(
    w_h: Array,
    joints: Array,
    params: snake_params.SnakeParams | None = None,
) -> Array:
    """Whole-robot centre of mass (3,), world frame [m], with the masses of `params`
    (module docstring there; the same as the MJCF): each link's box centre l/2 behind
    its frame, the 18 wheels at the axle ends, the batteries beside the wide pairs' passive
    wheels, the gripper's centre on the head x axis."""
    params = snake_params.default_params() if params is None else params
    Rs, ps = link_frames(w_h, joints, params)
    dt = ps.dtype
    l = jnp.asarray(params.link_length, dt)
    links = ps - 0.5 * l * Rs[:, :, 0]
    link_m = jnp.full(snake_params.N_LINKS, snake_params.LINK_MASS, dt).at[0].set(snake_params.HEAD_MASS)
    axle, _, R = wheel_pairs(w_h, joints, params)
    y = jnp.asarray(snake_params.PAIR_WHEEL_Y, dt)[:, None] * R[:, :, 1]
    wheels = jnp.concatenate([axle + y, axle - y])
    wide = np.asarray(snake_params.WIDE_PAIRS)
    batteries = axle[wide] - snake_params.ACTIVE_SIDE * jnp.asarray(snake_params.BATTERY_Y, dt) * R[wide][:, :, 1]
    grip_c = ps[0] + (snake_params.GRIPPER_TIP - 0.5 * snake_params.GRIPPER_LENGTH) * Rs[0][:, 0]
    total = (
        jnp.sum(link_m)
        + 2 * snake_params.N_PAIRS * snake_params.WHEEL_MASS
        + len(wide) * snake_params.BATTERY_MASS
        + snake_params.GRIPPER_MASS
    )
    moment = (
        link_m @ links
        + snake_params.WHEEL_MASS * jnp.sum(wheels, axis=0)
        + snake_params.BATTERY_MASS * jnp.sum(batteries, axis=0)
        + snake_params.GRIPPER_MASS * grip_c
    )
    return moment / total
