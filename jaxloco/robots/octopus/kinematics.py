"""OCTOPUS arm kinematics (Eqs. 1-6, Table 1), terrain exploration from the four arm
endpoints (Cases 1-3, Eqs. 7-9), COG height (Eqs. 10-17), travelled distance (Eq. 18) and
the crawlers' side profile on a step edge (`CrawlerProfile`: what pitch and tail height
put the front main wheel on a step top, at what pitch the robot on its rear flipper tips
turns over backwards, and how far its COG gets ahead of the edge on those tips and the
edge alone; ours, docs/octopus.md "What the geometry asks").

Pure JAX: every function works on one robot with fixed shapes (jit, vmap, grad); SI units
(m, rad). Frames ({R} robot, {J_i} arm joint frame, {C} level frame) and the arm numbering
(1 LF, 2 RF, 3 LR, 4 RR) are defined in `params.py`.

Arm i, joint angles q = (theta_1 swing, theta_2 boom, theta_3 elbow) [rad], EPRA (endpoint
of the robot arm = roller centre) in {J_i}, Eqs. 1-3:
    x' = cos(t1) (l2 cos(t2 + t3) + l1 cos(t2)) + d3 sin(t1)
    y' = sin(t1) (l2 cos(t2 + t3) + l1 cos(t2)) - d3 cos(t1)
    z' = -l2 sin(t2 + t3) - l1 sin(t2)
Eq. 3 is printed with "- l1 cos(t2)": a typo (the term must be l1 sin(t2): with cos the
boom end would not stay at distance l1 from the boom axis, and z' would not vanish at the
zero pose where x', y' give the arm stretched horizontally). theta_1 = 0 points the arm
along +x_R, theta_2 > 0 and theta_3 > 0 turn boom and forearm downwards (Eq. 28 rotates
the booms by +Delta_E to push the body up), and the forearm sits d3 to the right of the
boom. Eqs. 4-6: the EPRA in {R} is the arm base (+-m/2, +-n/2, 0) plus (x', y', z').

Table 1 is printed with its column headers shifted; read as modified (Craig) D-H
parameters (alpha_{i-1}, a_{i-1}, d_i, theta_i) it is (0, 0, 0, t1), (90 deg, 0, 0, t2'),
(0, l1, d3, t3') with the tool offset l2 along x_3. This chain reproduces Eqs. 1-2, and
Eq. 3 with t2' = -t2, t3' = -t3: the paper's boom and elbow angles are measured about
-z_2, -z_3 of the D-H frames. `arm_frames_mdh` evaluates the chain; the tests check it
against the closed form and against MuJoCo.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from jaxloco import geometry as geo
from jaxloco.robots.octopus import params as _params
from jaxloco.robots.octopus.params import OctopusParams

Array = jax.Array

CASE_UNDETECTABLE, CASE_FLAT, CASE_UP, CASE_DOWN = 0, 1, 2, 3
CASE_NAMES = ("undetectable", "flat", "upward step or slope", "downward step or pit")
_FRONT_REAR = (1.0, 1.0, -1.0, -1.0)  # arms 1, 2 front; 3, 4 rear
_LEFT_RIGHT = (1.0, -1.0, 1.0, -1.0)  # arms 1, 3 left; 2, 4 right


# ------------------------------------------------------------------ arm kinematics
def arm_tip_local(params: OctopusParams, q: Array) -> Array:
    """EPRA (roller centre) in the arm's joint frame {J} [m], Eqs. 1-3; q (3,) [rad]."""
    l1, l2, d3 = params.l1, params.l2, params.d3
    c1, s1 = jnp.cos(q[0]), jnp.sin(q[0])
    r = l2 * jnp.cos(q[1] + q[2]) + l1 * jnp.cos(q[1])  # reach in the boom plane
    return jnp.stack([c1 * r + d3 * s1, s1 * r - d3 * c1, -l2 * jnp.sin(q[1] + q[2]) - l1 * jnp.sin(q[1])])


def arm_tip(params: OctopusParams, arm: int | Array, q: Array) -> Array:
    """EPRA of arm `arm` (index 0..3 for arms 1..4) in {R} [m], Eqs. 1-6."""
    return params.arm_bases()[arm] + arm_tip_local(params, q)


def arm_tips(params: OctopusParams, qs: Array) -> Array:
    """EPRAs of all four arms in {R}, (4, 3) [m], for joint angles qs (4, 3) [rad]."""
    return params.arm_bases() + jax.vmap(lambda q: arm_tip_local(params, q))(qs)


def arm_points(params: OctopusParams, arm: int | Array, q: Array) -> Array:
    """Arm base, elbow axis point and EPRA in {R}, (3, 3) [m] (the elbow point is where the
    elbow axis meets the forearm's plane: the boom end shifted d3 to the right)."""
    base = params.arm_bases()[arm]
    c1, s1 = jnp.cos(q[0]), jnp.sin(q[0])
    reach, drop = params.l1 * jnp.cos(q[1]), -params.l1 * jnp.sin(q[1])
    elbow = base + jnp.stack([c1 * reach + params.d3 * s1, s1 * reach - params.d3 * c1, drop])
    return jnp.stack([base, elbow, arm_tip(params, arm, q)])


def _mdh(alpha: Array, a: Array, theta: Array, d: Array) -> Array:
    """Modified (Craig) D-H link transform Rx(alpha) Tx(a) Rz(theta) Tz(d), (4, 4)."""
    ca, sa, ct, st = jnp.cos(alpha), jnp.sin(alpha), jnp.cos(theta), jnp.sin(theta)
    z, o = jnp.zeros_like(ct), jnp.ones_like(ct)
    a, d = a * o, d * o
    return jnp.stack(
        [
            jnp.stack([ct, -st, z, a]),
            jnp.stack([st * ca, ct * ca, -sa * o, -sa * d]),
            jnp.stack([st * sa, ct * sa, ca * o, ca * d]),
            jnp.stack([z, z, z, o]),
        ]
    )


def arm_frames_mdh(params: OctopusParams, arm: int | Array, q: Array) -> Array:
    """Frames of the Table 1 chain in {R}, (5, 4, 4): base, after joints 1, 2, 3, and the
    EPRA (tool offset l2 along x_3). D-H angles are (t1, -t2, -t3) (module docstring)."""
    dt = q.dtype
    zero = jnp.zeros((), dt)
    base = geo.make_transform(jnp.eye(3, dtype=dt), params.arm_bases()[arm].astype(dt))
    rows = (
        (zero, zero, q[0], zero),
        (jnp.asarray(0.5 * jnp.pi, dt), zero, -q[1], zero),
        (zero, jnp.asarray(params.l1, dt), -q[2], jnp.asarray(params.d3, dt)),
    )
    frames = [base]
    T = base
    for alpha, a, theta, d in rows:
        T = T @ _mdh(alpha, a, theta, d)
        frames.append(T)
    tool = geo.make_transform(jnp.eye(3, dtype=dt), jnp.stack([jnp.asarray(params.l2, dt), zero, zero]))
    frames.append(T @ tool)
    return jnp.stack(frames)


def arm_jacobian(params: OctopusParams, arm: int | Array, q: Array) -> Array:
    """d(EPRA in {R})/dq, (3, 3) [m/rad], by forward-mode autodiff of Eqs. 1-6."""
    return jax.jacfwd(lambda qq: arm_tip(params, arm, qq))(q)


def inverse_kinematics(params: OctopusParams, arm: int | Array, target: Array) -> tuple[Array, Array]:
    """Closed-form joint angles putting the EPRA of `arm` at `target` ({R}, [m]).

    Branch: the arm reaches away from its swing axis (r > 0) with the elbow up
    (theta_3 > 0, the forearm folded down from a raised boom, as for every Table 2
    point). Returns (q (3,) [rad], reach_margin [m]): the margin is the smallest of the
    distances of the boom-plane reach D from the 2-link limits [|l1 - l2|, l1 + l2] and of
    the in-plane reach r from the swing axis; negative means unreachable (q is then the
    nearest clipped configuration and stays finite)."""
    dt = target.dtype
    l1, l2, d3 = (jnp.asarray(v, dt) for v in (params.l1, params.l2, params.d3))
    p = target - params.arm_bases()[arm].astype(dt)
    rho2 = p[0] * p[0] + p[1] * p[1]
    r_signed2 = rho2 - d3 * d3
    r = jnp.sqrt(jnp.maximum(r_signed2, 1e-12))
    t1 = jnp.arctan2(p[1], p[0]) + jnp.arctan2(d3, r)
    w = -p[2]  # depth below the boom axis
    dist = jnp.sqrt(r * r + w * w)
    cos3 = jnp.clip((dist * dist - l1 * l1 - l2 * l2) / (2.0 * l1 * l2), -1.0 + 1e-12, 1.0 - 1e-12)
    t3 = jnp.arccos(cos3)
    t2 = jnp.arctan2(w, r) - jnp.arctan2(l2 * jnp.sin(t3), l1 + l2 * jnp.cos(t3))
    margin = jnp.minimum(
        jnp.minimum(l1 + l2 - dist, dist - jnp.abs(l1 - l2)), jnp.sign(r_signed2) * jnp.sqrt(jnp.abs(r_signed2))
    )
    return jnp.stack([_wrap(t1), t2, t3]), margin


def inverse_kinematics_all(params: OctopusParams, targets: Array) -> tuple[Array, Array]:
    """`inverse_kinematics` for arms 1..4: targets (4, 3) -> (qs (4, 3), margins (4,))."""
    return jax.vmap(lambda k, t: inverse_kinematics(params, k, t))(jnp.arange(4), targets)


def _wrap(a: Array) -> Array:
    return jnp.arctan2(jnp.sin(a), jnp.cos(a))


# ------------------------------------------------------------------ attitude, {C}
def attitude_from_quat(quat: Array) -> Array:
    """(A_P, A_R) [rad] in the paper's convention (A_P > 0 nose up, A_R > 0 left side
    down) from the IMU quaternion (w, x, y, z) of {R} in the world: minus the usual z-up
    Z-Y-X pitch and roll. The yaw is dropped (the paper cannot measure it)."""
    w, x, y, z = quat[0], quat[1], quat[2], quat[3]
    n2 = w * w + x * x + y * y + z * z
    r20 = 2.0 * (x * z - w * y) / n2
    r21 = 2.0 * (y * z + w * x) / n2
    r22 = 1.0 - 2.0 * (x * x + y * y) / n2
    pitch = jnp.arcsin(jnp.clip(-r20, -1.0, 1.0))
    roll = jnp.arctan2(r21, r22)
    return jnp.stack([-pitch, -roll])


def level_rotation(a_p: Array, a_r: Array) -> Array:
    """^C_R R = ^C_M R ^M_R R (Eqs. 11-13), (3, 3): maps {R} coordinates to the level
    frame {C}. Equals rot_y(-a_p) @ rot_x(-a_r), the body-to-heading-frame rotation of a
    body with z-up pitch -a_p and roll -a_r."""
    return geo.rot_y(a_p).T @ geo.rot_x(a_r).T


def to_level_frame(points_r: Array, a_p: Array, a_r: Array) -> Array:
    """Points (..., 3) from {R} to {C} (Eq. 15)."""
    return points_r @ level_rotation(a_p, a_r).T


# ------------------------------------------------------------------ terrain exploration
class TerrainEstimate(NamedTuple):
    """Result of `explore_terrain` (scalars, or batch-shaped under vmap)."""

    case: Array  # int32: CASE_UNDETECTABLE 0, CASE_FLAT 1, CASE_UP 2, CASE_DOWN 3
    pitch: Array  # T_P [rad], > 0 when the terrain rises ahead
    roll: Array  # T_R [rad], > 0 when the terrain falls to the left (A_R convention)
    step_height: Array  # H_EST [m], Eq. 9
    diffs: Array  # (z1 - z4, z2 - z3) [m], the Case tests' differences
    tips_c: Array  # the four EPRAs in {C}, (4, 3) [m]


def terrain_case(diffs: Array, sigma: Array) -> Array:
    """Case index (int32) from the differences (z1 - z4, z2 - z3) [m] and thresholds
    sigma = (sigma_1, sigma_2, sigma_3) [m]:
      1 flat:  |z1 - z4| < s1 and |z2 - z3| < s1;
      2 up:    s1 < z1 - z4 < s2 and s1 < z2 - z3 < s2;
      3 down: -s3 < z1 - z4 < -s1 and -s3 < z2 - z3 < -s1;
      0 "undetectable" otherwise (mixed signs, too high or deep, on a threshold): the
        semi-autonomous fallback where the operator decides."""
    s1, s2, s3 = sigma[0], sigma[1], sigma[2]
    flat = jnp.all(jnp.abs(diffs) < s1)
    up = jnp.all((diffs > s1) & (diffs < s2))
    down = jnp.all((diffs > -s3) & (diffs < -s1))
    return jnp.where(flat, CASE_FLAT, jnp.where(up, CASE_UP, jnp.where(down, CASE_DOWN, CASE_UNDETECTABLE))).astype(
        jnp.int32
    )


def explore_terrain(params: OctopusParams, tips_r: Array, a_p: Array = 0.0, a_r: Array = 0.0) -> TerrainEstimate:
    """Terrain from the four EPRAs in contact: Cases 1-3, T_P, T_R (Eqs. 7-8), H_EST (Eq. 9).

    tips_r (4, 3) [m] are the EPRAs in {R} (arms 1..4), (a_p, a_r) the IMU attitude
    (paper convention, `attitude_from_quat`). Readings resolved here:
      * the endpoints are first taken to the level frame {C} (Eq. 15): the paper's
        T_P, T_R are angles "in {W}" and it lists the robot angles R_P, R_R next to
        Eqs. 7-8 without using them; with zero attitude this is the printed formula;
      * Eq. 7 is a slope (dz/dx), not an angle: T_P = atan(...);
      * Eq. 8 is printed (z1 + z4 - z2 - z3)/(x1 + x4 - x2 - x3): with Table 2's
        numbering that is a twist over a near-zero denominator. The roll difference is
        left minus right over y: (z1 + z3 - z2 - z4)/(y1 + y3 - y2 - y4);
      * for layouts that are not symmetric (Table 2's start pose) the two quotients mix
        pitch and roll, so we solve them jointly for the plane z = a + b x + c y:
          [Sx_p Sy_p; Sx_r Sy_r] [b c]^T = [Sz_p Sz_r]^T
        (S._p front minus rear, S._r left minus right sums), which reduces to Eqs. 7-8
        when Sy_p = Sx_r = 0 and is exact for any plane;
      * T_P, T_R are returned as the attitude (paper convention, yaw 0) of a robot resting
        on that plane: T_P = atan(b), T_R = -atan(c cos T_P). A robot standing on a plane
        with its four rollers on it thus has T_P = A_P and T_R = A_R.
    """
    dt = tips_r.dtype
    tips_c = to_level_frame(tips_r, jnp.asarray(a_p, dt), jnp.asarray(a_r, dt))
    x, y, z = tips_c[:, 0], tips_c[:, 1], tips_c[:, 2]
    diffs = jnp.stack([z[0] - z[3], z[1] - z[2]])
    case = terrain_case(diffs, jnp.asarray(params.sigma, dt))
    wp, wr = jnp.asarray(_FRONT_REAR, dt), jnp.asarray(_LEFT_RIGHT, dt)
    a11, a12, b1 = wp @ x, wp @ y, wp @ z
    a21, a22, b2 = wr @ x, wr @ y, wr @ z
    det = a11 * a22 - a12 * a21
    det = jnp.where(jnp.abs(det) < 1e-12, jnp.where(det < 0, -1e-12, 1e-12), det)
    slope_x = (b1 * a22 - a12 * b2) / det
    slope_y = (a11 * b2 - a21 * b1) / det
    pitch = jnp.arctan(slope_x)
    roll = -jnp.arctan(slope_y * jnp.cos(pitch))
    step = 0.5 * (z[0] + z[1] - z[2] - z[3])  # Eq. 9
    return TerrainEstimate(case, pitch, roll, step, diffs, tips_c)


# ------------------------------------------------------------------ COG height, distance
def cog_height(params: OctopusParams, tips_r: Array, a_p: Array, a_r: Array) -> Array:
    """COG height H [m] above the ground under the rear arms (Eqs. 10-17).

    P is the midpoint of the two rear EPRAs (arms 3, 4), G the COG (`params.cog`, fixed in
    {R} as the paper assumes); Eq. 16 gives Z_C of a point. Readings resolved here:
      * Eq. 10 defines H_1 = |Z_C(P)| but Eq. 16 sets H_1 = Z_C(P), which is negative
        (P is below {R}); the height of {R} above P is H_1 = -Z_C(P);
      * "in the same method H_2" is the depth of G below {R}, H_2 = -Z_C(G), so
        H = H_1 - H_2 = Z_C(G) - Z_C(P): the height of G above P, signed (also right if G
        were above {R}, where |.| would not be);
      * our EPRA is the roller centre: the ground contact is one roller radius below it,
        added here (exact when the ground under the rear rollers is level).
    """
    return _cog_height_above(params, 0.5 * (tips_r[2] + tips_r[3]), a_p, a_r)


def cog_height_sides(params: OctopusParams, tips_r: Array, a_p: Array, a_r: Array) -> Array:
    """(2,) COG height [m] above the ground under each side's rear arm (left: arm 3, LR;
    right: arm 4, RR), as `cog_height` with P one rear EPRA instead of their midpoint.

    For the climb's per-side adaptation (paper, "Getting over two-terrace step from the
    side": "the arms and flippers of robot should adapt the terrain separately"): each
    side compares its own H with its own step height (`side_step_heights`). The mean of
    the two is `cog_height` (Eq. 16 is linear in P)."""
    return _cog_height_above(params, tips_r[2:], a_p, a_r)


def side_step_heights(tips_c: Array) -> Array:
    """(2,) step height [m] under each side, left (arms 1, 3) and right (arms 2, 4): the
    front EPRA's height above the rear one's in the level frame {C} (tips_c (4, 3), the
    `TerrainEstimate.tips_c` of `explore_terrain`). Eq. 9's H_EST is their mean."""
    z = tips_c[:, 2]
    return jnp.stack([z[0] - z[2], z[1] - z[3]])


def _cog_height_above(params: OctopusParams, p_r: Array, a_p: Array, a_r: Array) -> Array:
    """Height [m] of the COG above the ground under the EPRAs p_r (..., 3) in {R} (Eq. 16's
    Z_C of both, plus the roller radius), at the IMU attitude (a_p, a_r)."""
    dt = p_r.dtype
    a_p, a_r = jnp.asarray(a_p, dt), jnp.asarray(a_r, dt)
    row = jnp.stack([jnp.sin(a_p), -jnp.cos(a_p) * jnp.sin(a_r), jnp.cos(a_p) * jnp.cos(a_r)])  # Eq. 16
    h1 = -(p_r @ row)
    h2 = -(row @ jnp.asarray(params.cog, dt))
    return h1 - h2 + jnp.asarray(params.roller_radius, dt)


def travelled_distance(step_lengths: Array, pitches: Array, mask: Array | None = None) -> Array:
    """S = sum_i L_i cos(R_P(i)) [m] (Eq. 18): horizontal distance from crawler travel
    L_i [m] per sampling period (no slip) and the robot pitch R_P(i) [rad] in that period.
    `step_lengths` is a scalar or (n,), `pitches` (n,); `mask` (n,) marks real samples."""
    pitches = jnp.asarray(pitches)
    terms = jnp.broadcast_to(jnp.asarray(step_lengths, pitches.dtype), pitches.shape) * jnp.cos(pitches)
    if mask is not None:
        terms = jnp.where(mask, terms, 0.0)
    return jnp.sum(terms)


def travel_update(distance: Array, step_length: Array, pitch: Array) -> Array:
    """One sampling period of Eq. 18: S + L cos(R_P), for a controller's state."""
    return distance + step_length * jnp.cos(pitch)


# ------------------------------------------------------------------ crawler side profile
class CrawlerProfile(NamedTuple):
    """The crawler seen from the side (`params.py`, ours) [m, rad]: the main crawler's end
    axles `axle_spacing` apart with wheels of `wheel_radius`, the flippers pivoting on the
    end axles, `flipper_length` to their tip wheel of `tip_radius`; at flipper angle 0 a
    flipper's centre line dips by `dip` below the main crawler's axis (bottoms in line)."""

    axle_spacing: float = 2.0 * _params.MAIN_AXLE_X
    wheel_radius: float = _params.MAIN_WHEEL_RADIUS
    flipper_length: float = _params.FLIPPER_LENGTH
    tip_radius: float = _params.FLIPPER_TIP_RADIUS
    dip: float = _params.FLIPPER_DIP
    # the COG ahead of and above the rear main axle, in the body's x-z plane (params.COG_R,
    # the Table 2 start pose; the arms moving shift it by centimetres)
    cog_x: float = float(_params.COG_R[0]) + _params.MAIN_AXLE_X
    cog_z: float = float(_params.COG_R[2] + _params.BASE_HEIGHT - _params.MAIN_WHEEL_RADIUS)


def rear_axle_height_on_rear_tips(pitch: Array, rear_flipper: Array, profile: CrawlerProfile = CrawlerProfile()
                                  ) -> Array:
    """Height [m] of the main crawler's rear axle above a flat floor when the robot rests
    on its rear flipper tip wheels, pitched nose-up by `pitch` [rad], the rear flippers at
    `rear_flipper` [rad] (the joint angle: 0 in line with the main crawler, > 0 lifts the
    tip, < 0 turns it down and lifts the tail). Side view, no roll. Valid while the tip
    wheel is the crawler's lowest point (pitch >= rear_flipper)."""
    return profile.tip_radius + profile.flipper_length * jnp.sin(pitch + profile.dip - rear_flipper)


def front_axle_height_on_rear_tips(pitch: Array, rear_flipper: Array, profile: CrawlerProfile = CrawlerProfile()
                                   ) -> Array:
    """Height [m] of the main crawler's front axle above a flat floor, the robot as in
    `rear_axle_height_on_rear_tips`."""
    return rear_axle_height_on_rear_tips(pitch, rear_flipper, profile) + profile.axle_spacing * jnp.sin(pitch)


def rear_axle_height_to_mount(step_height: Array, pitch: Array, profile: CrawlerProfile = CrawlerProfile()) -> Array:
    """Height [m] the rear main axle must have, at nose-up `pitch` [rad], for the front main
    wheel to reach the top of a step `step_height` [m] high (its axle at step_height plus
    the wheel radius): what the arms or rear flippers must lift the tail to."""
    return step_height + profile.wheel_radius - profile.axle_spacing * jnp.sin(pitch)


def mount_pitch_on_rear_tips(step_height: Array, rear_flipper: Array, profile: CrawlerProfile = CrawlerProfile()
                             ) -> Array:
    """The least nose-up pitch [rad] at which the robot, resting on its rear flipper tips
    at `rear_flipper` [rad], holds its front main wheel at the top of a step `step_height`
    [m] high (`front_axle_height_on_rear_tips` = step_height + wheel radius); NaN where no
    pitch does. Closed form: A sin(p) + B cos(p) = C with A = l_f cos(dip - a) + s,
    B = l_f sin(dip - a), C = h + r - r_tip."""
    phi = profile.dip - jnp.asarray(rear_flipper)
    a = profile.flipper_length * jnp.cos(phi) + profile.axle_spacing
    b = profile.flipper_length * jnp.sin(phi)
    c = jnp.asarray(step_height) + profile.wheel_radius - profile.tip_radius
    ratio = c / jnp.hypot(a, b)
    return jnp.where(ratio <= 1.0, jnp.arcsin(jnp.clip(ratio, -1.0, 1.0)) - jnp.arctan2(b, a), jnp.nan)


def tipping_pitch_on_rear_tips(rear_flipper: Array, profile: CrawlerProfile = CrawlerProfile()) -> Array:
    """The nose-up pitch [rad] at which the COG stands right above the rear flipper tips'
    contact, the robot resting on them with its rear flippers at `rear_flipper` [rad]: any
    more and it turns over backwards, unless something ahead pulls it down. Closed form:
    tan(p) = (c_x + l_f cos(dip - a)) / (c_z + l_f sin(dip - a)), (c_x, c_z) the COG from
    the rear axle (`CrawlerProfile.cog_x`, `cog_z`)."""
    phi = profile.dip - jnp.asarray(rear_flipper)
    return jnp.arctan2(profile.cog_x + profile.flipper_length * jnp.cos(phi),
                       profile.cog_z + profile.flipper_length * jnp.sin(phi))


def cog_lead_over_edge_on_rear_tips(step_height: Array, profile: CrawlerProfile = CrawlerProfile(),
                                    n_rear: int = 71, n_pitch: int = 300) -> tuple[Array, Array, Array]:
    """How far [m] the COG can get ahead of a step's edge (negative: it stays behind) while
    the robot rests on two supports only: its rear flipper tips on the floor and the edge
    (`step_height` [m] high) under its main crawler's bottom, between the end axles, up
    to the pitch at which it turns over backwards (`tipping_pitch_on_rear_tips`). Side
    view, horizontal distances. The largest over a grid of rear flipper angles
    (-FLIPPER_LIMIT to 0.3 rad, `n_rear`) and pitches (0.02 rad to the tipping pitch,
    `n_pitch`, with the tip wheel the lowest point: pitch >= rear flipper angle). The
    profile's fields may be traced (vmap over a COG place, for instance). Returns (lead [m], rear flipper angle
    [rad], pitch [rad]) where it is reached; lead -inf where the edge is never under the
    belly. Negative: on these supports the robot cannot tip forward onto the top, so a
    climb needs something on the top to carry it (the front flippers or arms)."""
    rear = jnp.linspace(-_params.FLIPPER_LIMIT, 0.3, n_rear)[:, None]
    tipping = tipping_pitch_on_rear_tips(rear, profile)
    pitch = 0.02 + (tipping - 0.02) * jnp.linspace(0.0, 1.0, n_pitch)[None, :]
    axle = rear_axle_height_on_rear_tips(pitch, rear, profile)
    r = profile.wheel_radius
    # the edge touches the belly `along` [m] from the rear axle: along sin p + axle - r cos p = h
    along = (jnp.asarray(step_height) - axle + r * jnp.cos(pitch)) / jnp.sin(pitch)
    edge_x = along * jnp.cos(pitch) + r * jnp.sin(pitch)
    cog_x = profile.cog_x * jnp.cos(pitch) - profile.cog_z * jnp.sin(pitch)
    valid = (along >= 0.0) & (along <= profile.axle_spacing) & (pitch >= rear)
    lead = jnp.where(valid, cog_x - edge_x, -jnp.inf)
    i, j = jnp.unravel_index(jnp.argmax(lead), lead.shape)
    return lead[i, j], rear[i, 0], pitch[i, j]
