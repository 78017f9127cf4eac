"""The grid step over intermittent crawl gait of TITAN XI (Hodoshima et al. 2007,
Sections 5-6) in pure JAX: fixed shapes, masks and bounded `lax` loops, so a plan jits
and vmaps over maps and over `TitanParams`.

Frames and units: positions in the map frame (`maps`), SI units, angles in rad. The
body never yaws (crab gait, Sec. 4.4): Sigma_b is the map frame rotated by the constant
`GaitState.yaw` about z, with its origin at the COG. Walking directions are map-frame
angles of the path L_G.

One cycle (Sec. 4.4, 5): r swing, f swing, COG shift G = L + W, r-bar swing, f-bar swing,
COG shift G-bar = L-bar + W-bar: six steps. Readings of the text chosen here:

  * path and COG: L_G passes through the COG at the start of each cycle; W points to the
    side of the leg pair (r, f) that swings first, so the COG zigzags off the path by |W|
    and is back on it at the end of the cycle when |W-bar| = |W| (Sec. 5.5, Fig. 20).
  * leg roles (Sec. 3, 5.1): the body axis (+-x_b, +-y_b) nearest to the walking
    direction decides which legs are "rear" and "front"; r is the rear leg farthest back
    along L_G (5.1, applied at every cycle start: in the standard gait it is the same leg
    every cycle), f the front leg on its side, r-bar and f-bar the other two.
  * Sec. 5.2.1, first condition: the text says "diagonal support line J_r P_f"; with
    leg f lifted the diagonal is J_r P_f-bar (as the second condition and Fig. 10 say),
    so both conditions constrain the line J_r P_f-bar. Instead of the tangent lines to
    the S_NE^c contour we test the equivalent margins directly: the exact NESM
    (`stability.ne_stability_margin`, 3D feet, no virtual-plane approximation) of the
    support {J_r, P_r-bar, P_f-bar} at P_g, and the energy margin of P'_g = P_g + G
    about the axis J_r P_f-bar, both >= S_NE^c.
  * D_r and D_f (Figs. 10, 12) are also restricted (added) to feet that stay reachable
    after the next shift too with only its lateral part (-W, L-bar = 0): each foot
    supports through both COG shifts of its cycle, and without this a foot placed at the
    rear of its area blocks the next shift entirely (Sec. 5.2.3 gives |L| = 0 there).
  * Sec. 5.2.2: D_f = A_f and A_f after the shift (text), plus (added) the S_NE^c test of
    the support {J_r, J_f, P_f-bar} of the r-bar swing at P'_g; the text only checks the
    diagonal for it, which leaves the side and front edges unchecked.
  * D_f (added, two steps ahead as domain prescribing method I does for r): J_f must
    leave r-bar a free, reachable landing (coarse grid about its standard return end)
    that keeps the diagonal J_r-bar J_f clear of the S_NE^c contour about P'_g, so that
    f-bar can swing after r-bar.
  * Sec. 5.2.3: "|L| = min(|l_f-bar|, |l_f-bar|)" is a typo for min(|l_f-bar|, |l_r-bar|),
    capped at L_std.
  * modifications (a), (b) and Sec. 5.5 are a fixed trial order: |L| = L_max (N_L - j)/N_L
    (j outer), |W| = `trial_lateral` (i inner: W_std + i dW for i < N_W, then narrower);
    the first trial whose half cycle
    finds J_r and J_f and whose second half (same |W|, its own L-bar reductions) also
    succeeds is used. No trial left: the cycle fails and the robot holds still.
  * phase-reserved positioning (Sec. 5.3, Fig. 14; the paragraph is garbled): I_u lies
    on the standard stroke of u at the distance s_u* + delta from its return start point,
    where s_u* is how far the swing leg one step before u (f-bar for r, r for f) is from
    its own return start point and delta is the standard phase offset (L_std when a COG
    shift lies between the two swings, else 0). s outside [0, 2 L_std], or the first
    cycle: the return end point.
  * standard strokes: along L_G, centred on the neutral foot shifted W_std / 2 outward
    (to the leg's side of L_G), the V of Fig. 7(b).
  * Sec. 6.3: P_gz = z of the virtual contact plane (least squares through the four feet,
    `geometry.fit_plane`) below the cycle-start COG + H_g, constant within the cycle.
  * Sec. 6.4.1: the return phase is horizontal (constant map z) at the highest map
    height under the foot pad along the return, plus the clearance, and at least
    `swing_min_lift` above the virtual plane.
  * change of direction (added): the first swing of every cycle is checked; when the
    rear pair changed (crossing +-45 deg from a body axis, or reversing) and neither
    rear leg can lift with S_NE^c, the cycle is a single transition COG shift to the
    cycle-start pose of the new roles (counted as one modification); if that is not
    possible either, the cycle fails and the robot holds (never an unsafe step).
  * every direction (added; Sec. 7 walks "in all directions"): the standard stride is
    longer off the body axes (`directional_stride`): with the square stance and no body
    yaw, at 45 deg the lateral shift runs along the swing diagonal and only the stride
    moves the COG off it.
  * deadlocks (added): after the widened |W| trials come narrower ones (`trial_lateral`),
    |L| is reduced in N_L = 6 steps, and when no trial succeeds the transition COG shift
    below is tried as a recovery (if it moves the COG by at least TRANSITION_MIN).
  * gravity: on a slope the tethers cancel `tether` times the slope-parallel component
    (Sec. 8.1), so margins use up = ((1 - tether) sin(slope), 0, cos(slope)) normalized.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco import geometry as geo
from jaxloco import stability as stab
from jaxloco.robots.titan import kinematics, maps
from jaxloco.robots.titan import params as titan_params

Array = jax.Array

# quadrant axes (+x, +y, -x, -y) of Sigma_b, the rear pair and the same-side partner rule
_AXES = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])
_REAR_PAIRS = np.array(
    [[2, 3], [1, 3], [0, 1], [0, 2]]
)  # LR RR | RF RR | LF RF | LF LR
_PARTNER_XOR = np.array([2, 1, 2, 1])  # f = r ^ 2 for +-x, r ^ 1 for +-y


class GaitState(NamedTuple):
    """Feet (4, 3) and COG (3,) in the map frame; body yaw () [rad] (constant); `rear`:
    the leg r of the last cycle (-1: none yet, Sec. 5.1 chooses)."""

    feet: Array
    cog: Array
    yaw: Array
    rear: Array = -1


class HalfCycle(NamedTuple):
    """Result of one half cycle (Sec. 5.2) for given |L| and |W|."""

    ok: Array  # J_r and J_f found and the shift keeps r-bar, f-bar reachable
    found_r: Array
    found_f: Array
    j_r: Array  # (3,) foothold of r
    j_f: Array  # (3,)
    i_r: Array  # (2,) initial foothold-search positions (map xy)
    i_f: Array
    shift: Array  # (3,) COG shift G (z = 0)


class GaitPlan(NamedTuple):
    """Per-step arrays (S = 6 n_cycles steps), per-cycle arrays (C) and metrics."""

    feet: Array  # (S, 4, 3) after each step, map frame
    cog: Array  # (S, 3) after each step, map frame
    feet_world: Array  # (S, 4, 3) world frame (z up)
    cog_world: Array  # (S, 3)
    swing_leg: Array  # (S,) leg index, -1 for a COG shift (or a held step)
    nesm: Array  # (S,) NE stability margin during the step [m]
    long_margin: Array  # (S,) longitudinal margin along L_G during the step [m]
    swing_path: (
        Array  # (S, 4, 3) rectangular swing waypoints (lift-off, 2 top, touch-down)
    )
    failed: Array  # (S,) bool: the cycle of this step failed (robot held)
    modified: (
        Array  # (S,) bool: the cycle used modifications (a)/(b)/5.5 or a transition
    )
    cycle_w: Array  # (C,) |W| used
    cycle_l: Array  # (C, 2) |L|, |L-bar| used
    cycle_trials: Array  # (C, 2) trial index of the first and second half
    cycle_failed: Array  # (C,)
    roles: Array  # (C, 4) legs (r, f, r-bar, f-bar)
    min_nesm: Array
    distance_per_cycle: Array  # mean progress along L_G per cycle [m]
    n_failures: Array  # cycles with no feasible trial
    n_modifications: Array  # sum of trial indices (one W increase or L decrease each; a
    # transition shift counts one)
    path_deviation: Array  # max |lateral offset| of a cycle-end COG from its L_G [m]
    # (0 when |W-bar| = |W|; a transition shift moves the COG off the old path)


# ------------------------------------------------------------------------ geometry
def _rot2(a: Array) -> Array:
    c, s = jnp.cos(a), jnp.sin(a)
    return jnp.stack([jnp.stack([c, -s]), jnp.stack([s, c])])


def _unit(a: Array) -> Array:
    return jnp.stack([jnp.cos(a), jnp.sin(a)])


def _left(v: Array) -> Array:
    return jnp.stack([-v[..., 1], v[..., 0]], axis=-1)


def effective_up(params: titan_params.TitanParams, slope: Array) -> Array:
    """Unit 'up' of the effective gravity in the map frame (tethers, Sec. 8.1)."""
    up = jnp.stack(
        [(1.0 - params.tether) * jnp.sin(slope), jnp.zeros_like(slope), jnp.cos(slope)]
    )
    return up / jnp.linalg.norm(up)


def in_fan(q: Array, leg: Array, params: titan_params.TitanParams) -> Array:
    """Whether body-frame points q (..., 2), relative to the pivot of `leg`, are in its
    fan-shaped reachable area (Fig. 3: R_in <= |q| <= R_out, within R_theta / 2 of the
    leg axis)."""
    axis = jnp.asarray(titan_params.LEG_AXIS_ANGLES, q.dtype)[leg]
    r = jnp.linalg.norm(q, axis=-1)
    ang = jnp.arctan2(q[..., 1], q[..., 0]) - axis
    ang = jnp.arctan2(jnp.sin(ang), jnp.cos(ang))
    return (
        (r >= params.r_in)
        & (r <= params.r_out)
        & (jnp.abs(ang) <= 0.5 * params.r_theta)
    )


def fan_exit_distance(q0: Array, u: Array, leg: Array, params: titan_params.TitanParams) -> Array:
    """Distance a point q0 (2,) (body frame, relative to the pivot of `leg`) can move along
    the unit direction u before leaving the leg's reachable area; 0 if q0 is outside.
    Exact: the fan is the intersection of the R_out disc and the wedge (convex) with the
    outside of the R_in disc, so the exit is the first of the three exits."""
    axis = jnp.asarray(titan_params.LEG_AXIS_ANGLES, q0.dtype)[leg]
    b = jnp.dot(q0, u)
    c_out = jnp.dot(q0, q0) - params.r_out**2
    t_out = -b + jnp.sqrt(jnp.maximum(b * b - c_out, 0.0))
    c_in = jnp.dot(q0, q0) - params.r_in**2
    disc = b * b - c_in
    t_hit = -b - jnp.sqrt(jnp.maximum(disc, 0.0))
    t_in = jnp.where((disc > 0) & (t_hit >= 0), t_hit, jnp.inf)
    half = 0.5 * params.r_theta
    ts = [t_out, t_in]
    for sgn in (1.0, -1.0):  # edge at axis + sgn * half; inside: sgn * cross(e, q) <= 0
        e = _unit(axis + sgn * half)
        rate = sgn * geo.cross2(e, u)
        t_e = -sgn * geo.cross2(e, q0) / jnp.where(rate > 0, rate, 1.0)
        ts.append(jnp.where(rate > 0, jnp.maximum(t_e, 0.0), jnp.inf))
    t = jnp.min(jnp.stack(ts))
    return jnp.where(in_fan(q0, leg, params), t, 0.0)


def virtual_plane(feet: Array) -> tuple[Array, Array]:
    """Virtual contact plane (Sec. 6.1): least squares z = c0 + c1 x + c2 y through the
    four feet, as (unit normal n, offset) with the plane {x : n.x = offset}."""
    return geo.fit_plane(feet)


def plane_height(normal: Array, offset: Array, xy: Array) -> Array:
    """z of the plane {n.x = offset} at xy (..., 2)."""
    return (offset - xy @ normal[:2]) / normal[2]


def swing_cog(cog: Array) -> Array:
    """The whole-robot centre of mass (3,) [m, map frame] while a leg swings, for the
    planned COG `cog` (H_g above the virtual plane): in the plane the executor holds it
    on `cog` (`control.body_for_com`), along the map normal (the body's z_b) the raised
    leg lifts it `kinematics.swing_com_height` above the body origin. Every NE margin of
    a three-leg support in the planner uses it (added: the paper's COG is the body's)."""
    return cog.at[..., 2].add(kinematics.swing_com_height())


def _axis_margin(c: Array, a: Array, b: Array, ref: Array) -> Array:
    """`edge_energy_margin` for points already in a frame whose z is 'up'."""
    rise = stab.axis_energy_rise(c, a, b)
    s_c = geo.cross2(b[:2] - a[:2], c[:2] - a[:2])
    s_ref = geo.cross2(b[:2] - a[:2], ref[:2] - a[:2])
    return jnp.where(s_c * s_ref < 0, rise, -rise)


def edge_energy_margin(cog: Array, a: Array, b: Array, ref: Array, up: Array) -> Array:
    """Energy margin (NE stability margin of one tipping axis, as in
    `stability.ne_stability_margin`) of `cog` about the 3D axis through a and b, signed
    positive when the COG is on the side of the line a-b opposite to the point `ref`
    (horizontal projections along `up`)."""
    B = stab.vertical_frame(up, cog.dtype)
    return _axis_margin(B @ cog, B @ a, B @ b, B @ ref)


# ------------------------------------------------------------------- roles and strokes
def directional_stride(params: titan_params.TitanParams, d_b: Array) -> Array:
    """Standard stride L_std(psi) [m] for the body-frame walking direction d_b (unit, (2,)):
    L_std / m^k with m = max(|cos psi_b|, |sin psi_b|) and k = `stride_exponent` (added;
    the paper gives no stride). L_std along a body axis, L_std / 0.707^k at 45 deg.

    Why: with a square stance the swing of the rear leg at psi_b = 45 deg is supported
    by the two side feet and the front one; their diagonal is normal to the path, so the
    lateral shift W runs along it and only the stride moves the COG off it. With
    L_std = 0.5 m the standard gait's NESM there is about 0.02 m < S_NE^c; k = 1.5 keeps it
    >= 0.035 m on flat ground at every heading (k = 1, the same stride along the nearest
    body axis, does not: `docs/titan.md`)."""
    m = jnp.maximum(jnp.abs(d_b[0]), jnp.abs(d_b[1]))
    return params.l_std / m**params.stride_exponent


def directional_params(params: titan_params.TitanParams, d_b: Array) -> titan_params.TitanParams:
    """`params` with l_std replaced by `directional_stride` for the direction d_b."""
    return params.with_(l_std=directional_stride(params, d_b))


def leg_roles(feet_b: Array, d_b: Array, prev: Array = -1) -> tuple[Array, Array]:
    """Legs (r, f, r-bar, f-bar) (4,) for the body-frame walking direction d_b and the
    body-frame feet (4, >=2) (Sec. 3, 5.1), and the unit lateral direction of W (2,)
    (towards the side of r, normal to d_b). Sec. 5.1 (the rear leg farthest back along
    L_G; ties: the left one for +x) chooses r at the gait start (`prev` < 0) and when the
    rear pair changes with the direction; otherwise r stays the leg `prev` of the last
    cycle (re-choosing every cycle would flip sides on centimetre differences after a
    shortened step and break the zigzag of the COG)."""
    q = jnp.argmax(jnp.asarray(_AXES, d_b.dtype) @ d_b)
    pair = jnp.asarray(_REAR_PAIRS)[q]
    proj = feet_b[pair, :2] @ d_b
    r = jnp.where(proj[1] < proj[0] - 1e-9, pair[1], pair[0])
    r = jnp.where(jnp.any(pair == prev), prev, r)
    rb = jnp.where(r == pair[0], pair[1], pair[0])
    x = jnp.asarray(_PARTNER_XOR)[q]
    roles = jnp.stack([r, r ^ x, rb, rb ^ x])
    axis = jnp.asarray(_AXES, d_b.dtype)[q]
    side = jnp.sign(geo.cross2(axis, jnp.asarray(titan_params.NEUTRAL_FEET[:, :2], d_b.dtype)[r]))
    return roles, side * _left(d_b)


def stroke_centres(params: titan_params.TitanParams, roles: Array, n_r: Array) -> Array:
    """Body-frame centres (4, 2) of the standard strokes: neutral foot + W_std / 2
    outward (+n_r for the legs r, f; -n_r for r-bar, f-bar)."""
    neutral = params.neutral_feet()[:, :2]
    sigma = (
        jnp.zeros(4, n_r.dtype)
        .at[roles]
        .set(jnp.array([1.0, 1.0, -1.0, -1.0], n_r.dtype))
    )
    return neutral + 0.5 * params.w_std * sigma[:, None] * n_r


def initial_search_position(
    params: titan_params.TitanParams,
    centre_u: Array,
    centre_star: Array,
    foot_star_b: Array,
    d_b: Array,
    delta: Array,
    first: Array,
) -> Array:
    """Phase-reserved positioning (Sec. 5.3, Fig. 14): I_u (body frame, (2,)) on the
    standard stroke of u (centre `centre_u`) at s_u* + delta from its return start point;
    the return end point when that is off the stroke or at the start of walking."""
    s_star = jnp.dot(foot_star_b - (centre_star - params.l_std * d_b), d_b)
    s = s_star + delta
    ok = (s >= 0.0) & (s <= 2.0 * params.l_std) & ~first
    s = jnp.where(ok, s, 2.0 * params.l_std)
    return centre_u - params.l_std * d_b + s * d_b


def search_offsets(
    half_rows: int = titan_params.SEARCH_HALF_ROWS, half_cols: int = titan_params.SEARCH_HALF_COLS
) -> np.ndarray:
    """Search order of Sec. 5.3 as integer (along L_G, lateral) offsets (K, 2) from I_u:
    I_u first; along each row +y and -y alternately outwards; rows 0, -1 .. -half_rows
    (towards the rear), then +1 .. +half_rows. Static (numpy)."""
    rows = [0] + [-k for k in range(1, half_rows + 1)] + list(range(1, half_rows + 1))
    cols = [0] + [s * k for k in range(1, half_cols + 1) for s in (1, -1)]
    return np.array([[r, c] for r in rows for c in cols], dtype=np.float64)


def first_valid(valid: Array) -> tuple[Array, Array]:
    """Index of the first True of `valid` (K,) in search order, and whether any is."""
    return jnp.argmax(valid), jnp.any(valid)


# ------------------------------------------------------------------------- half cycle
def half_cycle(
    params: titan_params.TitanParams,
    gmap: maps.GridMap,
    feet: Array,
    cog: Array,
    yaw: Array,
    d_b: Array,
    roles: Array,
    n_r: Array,
    l_len: Array,
    w_len: Array,
    first: Array,
    up: Array,
) -> HalfCycle:
    """Sec. 5.2 for one (|L|, |W|): D_r and J_r, D_f and J_f, G = L + W. `feet`, `cog`
    in the map frame (cog z = P_gz); d_b, n_r body-frame unit vectors."""
    dtype = cog.dtype
    R = _rot2(yaw)
    r, f, rb, fb = roles[0], roles[1], roles[2], roles[3]
    pivots = params.pivots()[:, :2]
    g_b = l_len * d_b + w_len * n_r
    g_map = jnp.concatenate([R @ g_b, jnp.zeros(1, dtype)])
    cog2 = cog + g_map
    feet_b = (feet[:, :2] - cog[:2]) @ R  # R^T applied to rows
    centres = stroke_centres(params, roles, n_r)
    offs = jnp.asarray(search_offsets(), dtype) * params.search_step
    lat = _left(d_b)

    def candidates(i_b):
        c_b = i_b + offs[:, :1] * d_b + offs[:, 1:] * lat
        xy = cog[:2] + c_b @ R.T
        z = maps.sample_height(gmap, xy)
        free = ~maps.sample_forbidden(gmap, xy)
        return c_b, jnp.concatenate([xy, z[:, None]], axis=1), free

    def reach(c_b, leg):
        # A_u now, A'_u after G, and (added) after G and a next shift of -W alone (L-bar = 0):
        # the foot supports through both shifts of the cycle before it swings again.
        p = pivots[leg]
        now = in_fan(c_b - p, leg, params) & in_fan(c_b - g_b - p, leg, params)
        return now & in_fan(c_b - l_len * d_b - p, leg, params)

    # --- leg r: D_r (Sec. 5.2.1, Fig. 10) and J_r
    i_r = initial_search_position(
        params, centres[r], centres[fb], feet_b[fb], d_b, params.l_std, first
    )
    c_b, c3, free = candidates(i_r)
    mask_f = jnp.ones(4, bool).at[f].set(False)

    def cond_r(x):
        sup = feet.at[r].set(x)
        m1 = stab.ne_stability_margin(swing_cog(cog), sup, mask_f, up)
        m2 = edge_energy_margin(swing_cog(cog2), x, feet[fb], feet[rb], up)
        return (m1 >= params.s_ne_c) & (m2 >= params.s_ne_c)

    valid_r = free & reach(c_b, r) & jax.vmap(cond_r)(c3)
    k_r, found_r = first_valid(valid_r)
    j_r = c3[k_r]
    j_r_b = c_b[k_r]

    # --- leg f: D_f (Sec. 5.2.2, Fig. 12) and J_f
    i_f = initial_search_position(
        params, centres[f], centres[r], j_r_b, d_b, 0.0, first
    )
    c_b, c3, free = candidates(i_f)
    mask_rb = jnp.ones(4, bool).at[rb].set(False)

    def cond_f(x):
        sup = feet.at[r].set(j_r).at[f].set(x)
        return stab.ne_stability_margin(swing_cog(cog2), sup, mask_rb, up) >= params.s_ne_c

    # (added) two steps ahead: after the shift r-bar swings, then f-bar with the support
    # {J_r-bar, J_r, J_f}; keep only J_f for which some free, reachable landing of r-bar
    # (coarse grid about its standard return end) keeps P'_g on the J_r side of the
    # diagonal J_r-bar J_f by S_NE^c. Without it a short J_f (a frame ahead) lets the
    # COG advance and the cycle after deadlocks (no J_r can satisfy condition 1).
    q_b = centres[rb] + params.l_std * d_b + g_b  # relative to P_g
    la = jnp.asarray(search_offsets(titan_params.LOOKAHEAD_HALF, titan_params.LOOKAHEAD_HALF), dtype) * (
        2.0 * params.search_step
    )
    y_b = q_b + la[:, :1] * d_b + la[:, 1:] * lat
    y_xy = cog[:2] + y_b @ R.T
    y3 = jnp.concatenate([y_xy, maps.sample_height(gmap, y_xy)[:, None]], axis=1)
    y_ok = ~maps.sample_forbidden(gmap, y_xy) & in_fan(y_b - g_b - pivots[rb], rb, params)

    B = stab.vertical_frame(up, dtype)
    y3u, cog2u, fbu = y3 @ B.T, B @ swing_cog(cog2), B @ feet[fb]

    def ahead(x):
        xu = B @ x
        m = jax.vmap(lambda y: _axis_margin(cog2u, y, xu, fbu))(y3u)
        return jnp.any(y_ok & (m >= params.s_ne_c))

    valid_f = free & reach(c_b, f) & jax.vmap(cond_f)(c3)
    valid_f = valid_f & jax.vmap(ahead)(c3)
    k_f, found_f = first_valid(valid_f)
    j_f = c3[k_f]

    keep = in_fan(feet_b[rb] - g_b - pivots[rb], rb, params) & in_fan(
        feet_b[fb] - g_b - pivots[fb], fb, params
    )
    ok = found_r & found_f & keep & (l_len > 1e-3)
    return HalfCycle(
        ok, found_r, found_f, j_r, j_f, cog[:2] + R @ i_r, cog[:2] + R @ i_f, g_map
    )


def trial_lateral(params: titan_params.TitanParams, i: Array) -> Array:
    """|W| of lateral trial i: W_std + i dW for i < N_W (Sec. 5.2.3, modification (b)),
    then (added) W_std - k dW for k = 1 .. N_W_DOWN."""
    k = i - titan_params.N_W + 1
    return jnp.where(i < titan_params.N_W, params.w_std + i * params.dw, params.w_std - k * params.dw)


def max_longitudinal(params, feet_b, roles, d_b, n_r, w_len) -> Array:
    """|L| limit of Sec. 5.2.3 (Fig. 13): min over r-bar and f-bar of the distance each foot,
    after the -W motion, can move along -L_G within its reachable area; capped at L_std."""
    pivots = params.pivots()[:, :2]
    w_b = w_len * n_r

    def lim(leg):
        return fan_exit_distance(feet_b[leg] - w_b - pivots[leg], -d_b, leg, params)

    return jnp.minimum(jnp.minimum(lim(roles[2]), lim(roles[3])), params.l_std)


# ---------------------------------------------------------------------------- cycle
class _Trial(NamedTuple):
    t: Array
    t2: Array
    done: Array
    h1: HalfCycle
    h2: HalfCycle
    w: Array
    l1: Array
    l2: Array


def plan_cycle(
    params: titan_params.TitanParams,
    gmap: maps.GridMap,
    state: GaitState,
    direction: Array,
    first: Array,
):
    """One gait cycle (Fig. 16) from `state` along the map-frame direction. Returns the
    new state (the old one when no trial succeeds) and the cycle record."""
    dtype = state.cog.dtype
    up = effective_up(params, gmap.slope)
    R = _rot2(state.yaw)
    d_b = _unit(direction - state.yaw)
    params = directional_params(params, d_b)
    feet = state.feet
    nrm, off = virtual_plane(feet)
    cog = state.cog.at[2].set(plane_height(nrm, off, state.cog[:2]) + params.h_g)
    feet_b = (feet[:, :2] - cog[:2]) @ R
    up_ok = lambda rl: (
        stab.ne_stability_margin(swing_cog(cog), feet, jnp.arange(4) != rl[0], up) >= params.s_ne_c
    )
    roles, n_r = leg_roles(feet_b, d_b, state.rear)
    # (added) the first swing of the cycle must itself keep S_NE^c. The previous cycle
    # guarantees it when r is unchanged; after a change of direction that changes the
    # rear pair (or reverses it) Sec. 5.1's leg may not, and the other rear leg is used.
    alt, n_alt = leg_roles(feet_b, d_b, roles[2])
    use_alt = ~up_ok(roles) & up_ok(alt)
    roles = jnp.where(use_alt, alt, roles)
    n_r = jnp.where(use_alt, n_alt, n_r)
    start_ok = up_ok(roles)
    roles2 = jnp.stack([roles[2], roles[3], roles[0], roles[1]])
    n_w, n_l = titan_params.N_W + titan_params.N_W_DOWN, titan_params.N_L

    zero = jnp.zeros((), dtype)
    no = jnp.asarray(False)
    empty = HalfCycle(
        no,
        no,
        no,
        jnp.zeros(3, dtype),
        jnp.zeros(3, dtype),
        jnp.zeros(2, dtype),
        jnp.zeros(2, dtype),
        jnp.zeros(3, dtype),
    )

    def second(h1, w):
        """Second half (Sec. 5.5): same |W| towards the other side, L-bar reductions only."""
        feet1 = feet.at[roles[0]].set(h1.j_r).at[roles[1]].set(h1.j_f)
        cog1 = cog + h1.shift
        fb1 = (feet1[:, :2] - cog1[:2]) @ R
        lmax = max_longitudinal(params, fb1, roles2, d_b, -n_r, w)

        def body(c):
            j = c[0] + 1
            l2 = lmax * (n_l - j) / n_l
            h = half_cycle(
                params, gmap, feet1, cog1, state.yaw, d_b, roles2, -n_r, l2, w, no, up
            )
            return j, h, l2

        init = (jnp.asarray(-1), empty, zero)
        go = lambda c: h1.ok & (~c[1].ok) & (c[0] < n_l - 1)
        j, h, l2 = jax.lax.while_loop(go, body, init)
        return h, l2, jnp.maximum(j, 0)

    def attempt(c):
        t = c.t + 1
        j, i = t // n_w, t % n_w
        w = trial_lateral(params, i)
        lmax = max_longitudinal(params, feet_b, roles, d_b, n_r, w)
        l1 = lmax * (n_l - j) / n_l
        h1 = half_cycle(
            params, gmap, feet, cog, state.yaw, d_b, roles, n_r, l1, w, first, up
        )
        h2, l2, t2 = second(h1, w)
        return _Trial(t, t2, h1.ok & h2.ok, h1, h2, w, l1, l2)

    tr = _Trial(jnp.asarray(-1), jnp.asarray(0), no, empty, empty, zero, zero, zero)
    tr = jax.lax.while_loop(
        lambda c: start_ok & (~c.done) & (c.t < n_w * n_l - 1), attempt, tr
    )
    ok = tr.done & start_ok
    h1, h2 = tr.h1, tr.h2
    # --- the six steps
    f1 = feet.at[roles[0]].set(h1.j_r)
    f2 = f1.at[roles[1]].set(h1.j_f)
    cog1 = cog + h1.shift
    f3 = f2.at[roles[2]].set(h2.j_r)
    f4 = f3.at[roles[3]].set(h2.j_f)
    cog2 = cog1 + h2.shift
    feet_s = jnp.stack([f1, f2, f2, f3, f4, f4])
    cog_s = jnp.stack([cog, cog, cog1, cog1, cog1, cog2])
    before = jnp.stack([feet, f1, f2, f2, f3, f4])
    cog_before = jnp.stack([cog, cog, cog, cog1, cog1, cog1])
    legs = jnp.stack([roles[0], roles[1], -1, roles[2], roles[3], -1])
    d_map = _unit(direction)
    # --- transition (added; the paper has no gait start after a change of direction):
    # when neither rear leg can lift, shift the COG alone to the cycle-start pose of the
    # new roles (as `standard_start`: W_std / 2 from the foot centroid away from the side
    # of r, L_std / 2 ahead), if S_NE^c holds during the shift and for the swing of r
    # after it, and every foot stays reachable. The cycle is then that single shift.
    pivots = params.pivots()[:, :2]

    def transition(rl, nr):
        t_b = (
            jnp.mean(feet_b, axis=0)
            - 0.5 * params.w_std * nr
            + 0.5 * params.l_std * d_b
        )
        cog_t = cog.at[:2].set(cog[:2] + R @ t_b)
        m_shift, _ = _step_margins(feet, cog, cog_t, -1, up, d_map)
        m_swing = stab.ne_stability_margin(swing_cog(cog_t), feet, jnp.arange(4) != rl[0], up)
        legs4 = jnp.arange(4)
        reach = jnp.all(
            jax.vmap(lambda q, i: in_fan(q, i, params))(feet_b - t_b - pivots, legs4)
        )
        return (m_shift >= params.s_ne_c) & (m_swing >= params.s_ne_c) & reach, cog_t

    ok_a, cog_a = transition(roles, n_r)
    ok_b, cog_b = transition(alt, n_alt)
    cog_t = jnp.where(ok_a, cog_a, cog_b)
    moves = jnp.linalg.norm(cog_t[:2] - cog[:2]) > TRANSITION_MIN
    trans = ~ok & (ok_a | ok_b) & moves
    roles = jnp.where(trans & ~ok_a, alt, roles)
    t_s = jnp.stack([cog, cog, cog_t, cog_t, cog_t, cog_t])
    t_before = jnp.stack([cog, cog, cog, cog_t, cog_t, cog_t])
    feet_s = jnp.where(ok, feet_s, feet[None])
    cog_s = jnp.where(ok, cog_s, jnp.where(trans, t_s, cog[None]))
    before = jnp.where(ok, before, feet[None])
    cog_before = jnp.where(ok, cog_before, jnp.where(trans, t_before, cog[None]))
    legs = jnp.where(ok, legs, -1)
    nesm, lm = jax.vmap(
        lambda fb_, c0, c1, leg: _step_margins(fb_, c0, c1, leg, up, d_map)
    )(before, cog_before, cog_s, legs)
    swing = jax.vmap(lambda a, b, leg: swing_path(params, gmap, a, b, leg))(
        before, feet_s, legs
    )
    new_state = GaitState(
        feet_s[-1], cog_s[-1], state.yaw, jnp.where(ok | trans, roles[0], state.rear)
    )
    dxy = cog_s[-1, :2] - cog[:2]
    rec = {
        "feet": feet_s,
        "cog": cog_s,
        "swing_leg": legs,
        "nesm": nesm,
        "long_margin": lm,
        "swing_path": swing,
        "w": tr.w,
        "l": jnp.stack([tr.l1, tr.l2]),
        "trials": jnp.where(
            trans, jnp.array([1, 0]), jnp.stack([jnp.maximum(tr.t, 0), tr.t2])
        ),
        "failed": ~(ok | trans),
        "roles": roles,
        "progress": jnp.where(ok | trans, jnp.dot(dxy, d_map), 0.0),
        "deviation": jnp.abs(geo.cross2(d_map, dxy)),
    }
    return new_state, rec


TRANSITION_MIN = 0.05  # [m] a recovery shift shorter than this is no progress: the cycle fails


def _step_margins(feet_before, cog0, cog1, leg, up, d_map):
    """NESM and longitudinal margin during one step: the three support legs at the
    (static) COG for a swing; for a COG shift the four legs at start, middle and end."""
    mask = jnp.arange(4) != leg
    cogs = jnp.stack([cog0, 0.5 * (cog0 + cog1), cog1])
    cogs = jnp.where(leg >= 0, swing_cog(cogs), cogs)
    ne = jax.vmap(lambda c: stab.ne_stability_margin(c, feet_before, mask, up))(cogs)
    lo = jax.vmap(lambda c: stab.longitudinal_margin(c, feet_before, mask, d_map, up))(
        cogs
    )
    return jnp.min(ne), jnp.min(lo)


def swing_path(
    params: titan_params.TitanParams, gmap: maps.GridMap, before: Array, after: Array, leg: Array
) -> Array:
    """Rectangular swing trajectory (Sec. 6.4.1, Fig. 18) of `leg` from its foot in
    `before` to the one in `after` (4, 3): lift-off, top above lift-off, top above
    touch-down, touch-down (4, 3). The top is at the highest map height under the pad
    along the return (centre line and both pad edges, pad ends included, 24 samples
    each) plus the
    clearance, and at least `swing_min_lift` above the virtual plane of `before`.
    For a COG shift (leg < 0) the four points are all zero."""
    li = jnp.maximum(leg, 0)
    a, b = before[li], after[li]
    dv = b[:2] - a[:2]
    # |dv| floored at 1e-9 m before the square root: also its derivative stays finite at dv = 0
    u = dv / jnp.sqrt(jnp.maximum(dv @ dv, 1e-18))
    s = jnp.linspace(0.0, 1.0, 24, dtype=a.dtype)[:, None]
    a0 = a[:2] - params.foot_radius * u  # the pad's whole footprint, ends included
    seg = a0[None] + s * (b[:2] + params.foot_radius * u - a0)[None]
    n = _left(u) * params.foot_radius
    pts = jnp.concatenate([seg, seg + n, seg - n])
    hmax = jnp.max(maps.sample_height(gmap, pts))
    nrm, off = virtual_plane(before)
    plane_top = (
        jnp.max(plane_height(nrm, off, jnp.stack([a[:2], b[:2]])))
        + params.swing_min_lift
    )
    top = jnp.maximum(
        jnp.maximum(hmax + params.swing_clearance, plane_top), jnp.maximum(a[2], b[2])
    )
    way = jnp.stack([a, a.at[2].set(top), b.at[2].set(top), b])
    return jnp.where(leg >= 0, way, 0.0)


# --------------------------------------------------------------------------- planning
def standard_start(
    params: titan_params.TitanParams,
    gmap: maps.GridMap,
    cog_xy: Array,
    direction: Array = 0.0,
    yaw: Array = 0.0,
) -> GaitState:
    """The standard intermittent crawl gait at the start of a cycle (Fig. 7) for the
    map-frame walking direction: the COG on L_G, off the foot centre by W_std / 2 away
    from the side of r; r and f at the return start points of their strokes, r-bar and
    f-bar at mid stroke (the V apex). Feet on the map, COG H_g above the virtual plane."""
    cog_xy = jnp.asarray(cog_xy)
    dtype = cog_xy.dtype
    direction = jnp.asarray(direction, dtype)
    yaw = jnp.asarray(yaw, dtype)
    d_b = _unit(direction - yaw)
    params = directional_params(params, d_b)
    neutral = params.neutral_feet()[:, :2]
    roles, n_r = leg_roles(neutral, d_b)
    centres = stroke_centres(params, roles, n_r)
    sigma = jnp.zeros(4, dtype).at[roles].set(jnp.array([1.0, 1.0, 0.0, 0.0], dtype))
    # r, f at c - L d; r-bar, f-bar: landed at c + L d, after one shift (L, -W_std):
    # c + L d - L d + W_std n_r = neutral + W_std / 2 n_r, the V apex.
    feet_b = jnp.where(
        sigma[:, None] > 0, centres - params.l_std * d_b, centres + params.w_std * n_r
    )
    xy = cog_xy + feet_b @ _rot2(yaw).T
    feet = jnp.concatenate([xy, maps.sample_height(gmap, xy)[:, None]], axis=1)
    nrm, off = virtual_plane(feet)
    cog = jnp.concatenate([cog_xy, (plane_height(nrm, off, cog_xy) + params.h_g)[None]])
    return GaitState(feet, cog, yaw, roles[0])


def plan_cycles(
    params: titan_params.TitanParams,
    gmap: maps.GridMap,
    start: GaitState,
    n_cycles: int,
    direction: Array = 0.0,
) -> GaitPlan:
    """Plan `n_cycles` (static) cycles from `start`; `direction` is the map-frame angle of
    L_G, a scalar or one per cycle (n_cycles,). Pure: jit / vmap over `gmap`, `params`,
    `start` and `direction`."""
    dtype = start.cog.dtype
    dirs = jnp.broadcast_to(jnp.asarray(direction, dtype), (n_cycles,))

    def step(state, xs):
        k, dk = xs
        return plan_cycle(params, gmap, state, dk, k == 0)

    _, rec = jax.lax.scan(step, start, (jnp.arange(n_cycles), dirs))
    S = 6 * n_cycles
    feet = rec["feet"].reshape(S, 4, 3)
    cog = rec["cog"].reshape(S, 3)
    failed_c = rec["failed"]
    modified_c = (rec["trials"].sum(axis=1) > 0) & ~failed_c
    return GaitPlan(
        feet=feet,
        cog=cog,
        feet_world=maps.map_to_world(gmap, feet),
        cog_world=maps.map_to_world(gmap, cog),
        swing_leg=rec["swing_leg"].reshape(S),
        nesm=rec["nesm"].reshape(S),
        long_margin=rec["long_margin"].reshape(S),
        swing_path=rec["swing_path"].reshape(S, 4, 3),
        failed=jnp.repeat(failed_c, 6),
        modified=jnp.repeat(modified_c, 6),
        cycle_w=rec["w"],
        cycle_l=rec["l"],
        cycle_trials=rec["trials"],
        cycle_failed=failed_c,
        roles=rec["roles"],
        min_nesm=jnp.min(rec["nesm"]),
        distance_per_cycle=jnp.mean(rec["progress"]),
        n_failures=jnp.sum(failed_c),
        n_modifications=jnp.sum(jnp.where(failed_c, 0, rec["trials"].sum(axis=1))),
        path_deviation=jnp.max(rec["deviation"]),
    )


SWEEP_START_X = titan_params.PARAMETERS.default("start_x")  # [m] map x of the start COG of a sweep point
SWEEP_SHAPE = (titan_params.PARAMETERS.default("map_nx"), titan_params.PARAMETERS.default("map_ny"))  # its map cells


def sweep_setup(
    params: titan_params.TitanParams,
    frame_size: Array,
    frame_interval: Array,
    slope: Array,
    direction: Array,
    shape: tuple[int, int] = SWEEP_SHAPE,
    cell: float = titan_params.CELL,
    start_x: Array = SWEEP_START_X,
    field_b: tuple[Array, Array] = (0.0, 1.0),
    mix_block: Array = 0.0,
    phase: Array = (0.0, 0.0),
) -> tuple[maps.GridMap, GaitState]:
    """The map and the standard start of one sweep point: frames of `frame_size` every
    `frame_interval`, centre lines at (k + 1/2) interval, map origin (0, 0), slope angle
    `slope`; with `mix_block` > 0 a checkerboard of blocks of that side alternating with
    the field `field_b` = (frame size, interval) (`maps.mixed_frame_map`); `phase` (2,)
    shifts both grids by that fraction of their intervals. The start COG is at the map's
    x = `start_x`, y = centre, for walking along `direction`."""
    dtype = jnp.asarray(params.l_std).dtype
    _nx, ny = shape
    half = 0.5 + jnp.asarray(phase, dtype)
    gmap = maps.mixed_frame_map(
        shape,
        jnp.zeros(2, dtype),
        jnp.asarray(cell, dtype),
        (frame_size, frame_interval, half * frame_interval),
        (field_b[0], field_b[1], half * field_b[1]),
        jnp.asarray(mix_block, dtype),
        slope,
    )
    start_xy = jnp.stack([jnp.asarray(start_x, dtype), jnp.asarray(0.5 * ny * cell, dtype)])
    return gmap, standard_start(params, gmap, start_xy, direction)


def sweep_plan(
    params: titan_params.TitanParams,
    frame_size: Array,
    frame_interval: Array,
    slope: Array,
    direction: Array,
    n_cycles: int,
    shape: tuple[int, int] = SWEEP_SHAPE,
    cell: float = titan_params.CELL,
    **field,
) -> GaitPlan:
    """The plan of one sweep point (Sec. 4 sweeps): `n_cycles` along `direction` from
    `sweep_setup`'s start on its map (`field`: its start_x, field_b, mix_block). Every
    argument but `n_cycles`, `shape`, `cell` may be traced (vmap over them)."""
    gmap, start = sweep_setup(
        params, frame_size, frame_interval, slope, direction, shape, cell, **field
    )
    return plan_cycles(params, gmap, start, n_cycles, direction)


def sweep_metrics(*args, **kwargs) -> dict[str, Array]:
    """`sweep_plan(*args, **kwargs)`'s min NESM, distance per cycle, number of failed
    cycles and modifications, path deviation."""
    plan = sweep_plan(*args, **kwargs)
    return {
        "min_nesm": plan.min_nesm,
        "distance_per_cycle": plan.distance_per_cycle,
        "n_failures": plan.n_failures,
        "n_modifications": plan.n_modifications,
        "path_deviation": plan.path_deviation,
    }
