"""One cycle of the leg-grope walk on a slope: footholds, COG targets inside the admissible
regions, and the body/foot motion over time (the paper's Appendix S2 is not available;
this is our design, documented here).

Frames: world Sigma_G (z up). The slope plane passes through the origin with
inclination theta; its gradient (uphill) is world +x, so the slope frame Sigma_S has
x_S = (cos theta, 0, sin theta), z_S its normal: R_GS = rot_y(-theta). The walking
direction makes the angle psi with the gradient (paper Fig. 5); the walking frame
(u forward, v left) is rotated by psi about z_S. The body stays parallel to the slope at
`body_height` along z_S ("the designed movement keeps the robot body parallel to the
surface").

Leg numbering (`GaitDesign`, `DESIGNS`, `CYCLE_DESIGNS`): the analyses walk the mirrored
reading's forward crawl along x_R by default. `WalkParams()` and `WalkConfig()` on their
own are the literal reading's walk. Why that one walks toward +y_R (`heading = pi/2`):
with the paper's numbering read literally (L1..L4 clockwise from the left front seen from
above) and its groping order L2, L1, L3, L4,
every groped foot must land in pi_grp,all of the other three, which for h_ref = 1/2 is
the triangle whose medial triangle the three stance feet form. Its sides pass through
each stance foot parallel to the opposite side, so when L2 and then L1 are groped while
L3 and L4 stand, L1 can never end farther from the line L3-L4 than it started. A walk
along x_R (away from that line) is therefore impossible with this order; along y_R the
same order is the classical crawl sequence (rear-right, front-right, rear-left,
front-left in walking terms). `tests/test_leggrope_gait.py` checks the impossibility on
random stances.

How little room there is: with h_ref = 1/2 the admissible regions are the medial
triangle (COG) and the reflection of the stance triangle through the COG (groped
foot). A joint search over stance, sideways steps and COG targets (`design.py`) finds a
worst-case margin of about +1 to +2 mm on level ground; once the swinging leg's mass
(which moves the COG between steps B and D) and slopes up to 0.5 rad are counted, the
best footsteps reach -1.7 mm. h_ref = 0.45 or 0.55 is worse by about 6 mm. The force
QP therefore reports a small relaxation of the normal-force rules (`forces`).

Cycle (for each groping leg g in order; fixed numbers of 15 ms steps so the whole cycle
is one `lax.scan`):
  A  move the body (four legs) to place the COG at its target, straight line in the
     slope plane, trapezoidal speed profile with a_max, v_max (held still once there);
  B  unload leg g: its normal force ramps linearly to 0, nothing moves;
  C  swing g: minimum-jerk along the slope, lifted by `swing_height` along the normal;
  D  load g: its normal force ramps linearly from 0 to R_ref, nothing moves.
Footsteps: the initial stance and the sideways shift of each step are design inputs
(`WalkParams.stance`, `.lateral`, defaults from `design.py`); every groped foot moves
`stride` forward along the walk plus its sideways shift. COG targets: for each grope,
the point of a barycentric lattice over the stance triangle that maximizes the smaller
of (the step-B COG's distance inside pi_g) and (the groped foothold's distance inside
the step-D region), planned in slope-plane coordinates (see `plan_cycle`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco import geometry as geo
from jaxloco import linalg
from jaxloco.robots.leggrope import kinematics, regions
from jaxloco.robots.leggrope.params import PARAMETERS, G, LegGropeParams

Array = jax.Array

PHASES = ("A", "B", "C", "D")


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class WalkParams:
    """Continuous design parameters of the walk (pytree leaves; sweepable)."""

    stride: jax.Array = PARAMETERS.default("stride")
    # initial footholds (u, v) in the walking frame, legs L1..L4, relative to the
    # initial COG (see `default_stance`)
    stance: jax.Array = field(default_factory=lambda: default_stance())
    # sideways shift (v, metres) of each leg's step, legs L1..L4 (see `default_lateral`)
    lateral: jax.Array = field(default_factory=lambda: default_lateral())
    heading: jax.Array = 0.5 * np.pi  # walking direction in the body frame (from x_R) [rad]
    swing_height: jax.Array = PARAMETERS.default("swing_height")


def default_lateral() -> np.ndarray:
    """Sideways shift [m] of each leg's step (legs L1..L4), designed with the stance."""
    return np.array(DEFAULT_LATERAL)


def default_stance() -> np.ndarray:
    """Initial footholds (u forward, v left) [m] for heading = pi/2 (walk along +y_R):
    L1 front-right, L2 rear-right, L3 rear-left, L4 front-left in walking terms. Chosen
    by `python -m jaxloco.robots.leggrope.design --seed 0` (cross-entropy search) to
    maximize the worst plan margin over slopes |theta| <= 0.5 and several walking
    directions: -1.7 mm (on level ground alone designs reach +1.9 mm). No footstep
    design keeps the vertical-force regions strictly admissible on every slope once the
    swinging leg's mass is counted; see the module docstring."""
    return np.array(DEFAULT_STANCE)


DEFAULT_STANCE = ((0.0917, -0.2548), (-0.0628, -0.2879), (-0.0867, 0.2560), (0.0715, 0.2593))
DEFAULT_LATERAL = (0.0631, 0.0618, -0.0521, -0.0571)


# The mirrored reading's footstep design for the experimental walk (`control.py`), from
#     python -m jaxloco.robots.leggrope.design --numbering mirrored --iterations 200 --seed 3
# (see `design.py`): worst triangle/grope margin MIRRORED_DESIGN_MARGIN over theta = 0 and
# pi/12, psi = 0, stride 0.06 m. The sideways shifts sum to zero (no net drift: the body
# walks straight along x_R), but they differ per leg, so the stance changes shape over the
# cycle: like the literal design it is one cycle, as the paper's experiments (a periodic
# crawl with no sideways shifts reaches only -3 mm). Of the designs from seeds 1-3 (10.2,
# 11.0, 11.0 mm) this one walks most robustly in MuJoCo (4 of 4 perturbed walks at both
# safe_blend 0.25 and 0.4; seed 2's fell 3 times in 4 at 0.4). Physical legs (left front,
# right front, right rear, left rear), walking frame (u forward = x_R, v left = y_R) [m].
MIRRORED_STANCE = ((0.2899, 0.1354), (0.2857, -0.1083), (-0.2648, -0.1561), (-0.2694, 0.1207))
MIRRORED_LATERAL = (-0.0788, 0.0696, 0.0716, -0.0623)
MIRRORED_DESIGN_MARGIN = 11.01e-3


@dataclass(frozen=True)
class GaitDesign:
    """A reading of the paper's leg numbering with its footstep design (static).

    legs[n]: the physical leg (0..3: left front, right front, right rear, left rear, as
    `params.hips`) that the paper calls L(n+1). The groping order is the paper's L2, L1,
    L3, L4. heading: walking direction in the body frame [rad]; stance (4, 2) and lateral
    (4,) per physical leg as `WalkParams`; cog_rule as `WalkConfig.cog_rule`;
    fallback (4, 2): unit directions (u, v) of each physical leg's fallback foothold
    (`control.py`); grope_overshoot: the experimental walk's D'-2 ends once the groping
    leg's filtered normal force is over (1 + grope_overshoot) R_ref.

    * "literal": L1..L4 clockwise from the left front seen from above. With the groping
      order a walk along x_R is impossible (module docstring), so it walks along +y_R.
    * "mirrored": L1..L4 clockwise in a figure drawn from below (L1 left front, L2 left
      rear, L3 right rear, L4 right front seen from above): the same order is the
      classical crawl along +x_R, the paper's forward direction. Its
      footsteps and COG targets are designed for surviving a collapse (`design.py`)."""

    name: str
    legs: tuple[int, int, int, int]
    heading: float
    stance: tuple
    lateral: tuple
    cog_rule: str
    fallback: tuple
    grope_overshoot: float

    @property
    def order(self) -> tuple[int, ...]:
        """Physical legs in the groping order L2, L1, L3, L4."""
        return tuple(self.legs[n] for n in (1, 0, 2, 3))

    def walk(
        self, stride=PARAMETERS.default("stride"), swing_height=PARAMETERS.default("swing_height")
    ) -> "WalkParams":
        return WalkParams(stride=stride, stance=np.asarray(self.stance), lateral=np.asarray(self.lateral),
                          heading=self.heading, swing_height=swing_height)

    def config(self, **overrides) -> "WalkConfig":
        return WalkConfig(order=self.order, cog_rule=self.cog_rule, **overrides)


# Where each leg gropes next when its target foothold fails (`control.py`):
# `fallback_distance` from the target in these directions (walking frame, u forward, v
# left), per physical leg. A fixed-pattern crawl is sensitive to this: a fallback that
# merely shortens the stride (what we tried first) leaves the *next* gropes infeasible
# (plan margins -28 to -30 mm for L4 after L1 falls back, L1 after L2), because the later
# COG targets are planned from the footholds actually taken. For the literal walk a
# search over offsets of 40 mm (pads must not overlap) at theta 0, pi/12, 0.35 and psi
# 0, pi/2 (`benchmarks/leggrope_fallbacks.py`) gives these directions: worst plan margin
# with one leg on its fallback -7.5 mm (L1), -9.3 mm (L2), -3.5 mm (L3) and the primary
# plan's -1.7 mm (L4, nothing after it); with two or three fallbacks in one cycle down to
# -19.8 mm. The mirrored crawl is the literal one mirrored in walking terms (v -> -v), so
# each position in the groping order takes the literal direction of that position with v
# negated (docs/leggrope.md: what that costs, and why the searched ones are not shipped).
_LITERAL_FALLBACK = ((0.0, 1.0), (0.0, -1.0), (0.7071067811865476, 0.7071067811865476), (-1.0, 0.0))


def _mirrored_fallback() -> tuple:
    out = [None] * 4
    for lit, mir in zip((1, 0, 2, 3), (3, 0, 2, 1)):
        u, v = _LITERAL_FALLBACK[lit]
        out[mir] = (u, -v)
    return tuple(out)


DESIGNS = {
    # the literal walk's gropes end at 0.95 R_ref: from its plan's COG (region margin
    # -1.7 mm) the L1 grope stalls just under R_ref (at 0.98 it times out)
    "literal": GaitDesign("literal", (0, 1, 2, 3), 0.5 * np.pi, DEFAULT_STANCE, DEFAULT_LATERAL, "balanced",
                          _LITERAL_FALLBACK, -0.05),
    # the mirrored walk's reach 1.01 R_ref: the 1 % covers the force filter's lag and the
    # later steps' few tenths of a per cent over R_ref, so that no foothold carries more
    # than its grope verified (`max_load_over_probe` <= 1)
    "mirrored": GaitDesign("mirrored", (0, 3, 2, 1), 0.0, MIRRORED_STANCE, MIRRORED_LATERAL, "collapse_safe",
                           _mirrored_fallback(), 0.01),
}


# The mirrored reading's footsteps for the paper's A-D force-distribution cycle
# (`forces.simulate_cycle`, `leggrope.slope_cycle`), where the COG stays still from step B
# to D: from `design.search_footsteps(objective="static")` (the region margins and the
# triangle margin together, zero-mean sideways shifts, over theta 0, +-0.25, +-0.4 and psi
# 0, pi/2; 60 iterations, seed 1, from the collapse-safe design): worst -1.07 mm, against
# the literal design's -1.7 mm. (Searching on, with psi +-pi/4 too, gave -1.4 mm over
# those 20 slopes, but a lower slip limit climbing at psi = -45 deg: the plan margin does
# not predict slip.) The collapse-safe footsteps above do not serve this cycle (region
# margin -11 to -13.5 mm, QP steps without a slip-free distribution), nor these the
# experimental walk (see docs/leggrope.md).
MIRRORED_CYCLE_STANCE = ((0.3107, 0.1449), (0.3025, -0.107), (-0.287, -0.165), (-0.2746, 0.1258))
MIRRORED_CYCLE_LATERAL = (-0.0385, 0.0676, 0.0326, -0.0617)

CYCLE_DESIGNS = {
    "literal": DESIGNS["literal"],
    "mirrored": replace(DESIGNS["mirrored"], stance=MIRRORED_CYCLE_STANCE, lateral=MIRRORED_CYCLE_LATERAL,
                        cog_rule="balanced"),
}


def gait_design(name: str, cycle: bool = False) -> GaitDesign:
    """The named `GaitDesign` ("literal" or "mirrored") of the experimental walk
    (`control.py`), or with `cycle` of the paper's A-D force-distribution cycle
    (`forces.simulate_cycle`); ValueError for another name."""
    if name not in DESIGNS:
        raise ValueError(f"unknown leg numbering {name!r}; expected one of {tuple(DESIGNS)}")
    return (CYCLE_DESIGNS if cycle else DESIGNS)[name]


@dataclass(frozen=True)
class WalkConfig:
    """Discrete (static) settings: they fix array shapes and the compiled program."""

    order: tuple[int, ...] = (1, 0, 2, 3)  # groping order L2, L1, L3, L4 (0-based)
    n_move: int = 100  # steps of phase A (1.5 s at 15 ms)
    n_unload: int = 20  # steps of phase B (0.3 s)
    n_swing: int = 40  # steps of phase C (0.6 s)
    n_load: int = 20  # steps of phase D (0.3 s)
    lattice: int = 32  # barycentric lattice resolution of the COG search
    # how each grope's COG target is chosen (`_search_cog`, `COG_RULES`): "balanced"
    # maximizes the smaller region margin (step-B COG in pi_g, groped foothold in the
    # step-D region), the paper's A-D cycle; "collapse_safe" the smaller of the groped
    # foothold's region margin and the triangle margin (the COG inside the other three
    # legs' triangle, what survives a collapse), the experimental walk, whose step-B COG
    # is its A' position; "static_safe" the smallest of all three
    cog_rule: str = "balanced"
    fixed_point_iters: int = 5  # Newton iterations placing the body under a COG target

    @property
    def steps_per_grope(self) -> int:
        return self.n_move + self.n_unload + self.n_swing + self.n_load

    @property
    def n_steps(self) -> int:
        return 4 * self.steps_per_grope

    def phase_lengths(self) -> tuple[int, int, int, int]:
        return (self.n_move, self.n_unload, self.n_swing, self.n_load)


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class SlopeTerrain:
    """A simple or irregular slope. `normals[c, n]` is the unit normal (world) of the
    facet under leg n's foothold before (c = 0) and after (c = 1) its step."""

    theta: jax.Array  # inclination [rad]
    psi: jax.Array  # walking direction relative to the gradient [rad]
    normals: jax.Array = field(default=None)  # (2, 4, 3)


def facet_normal(theta: Array, azimuth: Array) -> Array:
    """Unit normal of a plane with inclination theta whose uphill gradient points at
    `azimuth` from world x (azimuth 0 is the main slope)."""
    s = jnp.sin(theta)
    return jnp.stack([-s * jnp.cos(azimuth), -s * jnp.sin(azimuth), jnp.cos(theta) * jnp.ones_like(azimuth)], -1)


def simple_slope(theta: Array, psi: Array) -> SlopeTerrain:
    """Uniform slope: every facet normal is the slope normal."""
    theta = jnp.asarray(theta)
    n = facet_normal(theta, jnp.zeros((2, 4), theta.dtype))
    return SlopeTerrain(theta=theta, psi=jnp.asarray(psi, theta.dtype), normals=n)


def irregular_slope(theta: Array, psi: Array, spread: Array, key: Array) -> SlopeTerrain:
    """Facets with the slope's inclination and gradient directions scattered uniformly
    in [-spread, spread] around the main gradient (the paper's irregular slope)."""
    theta = jnp.asarray(theta)
    az = jax.random.uniform(key, (2, 4), theta.dtype, -1.0, 1.0) * spread
    return SlopeTerrain(theta=theta, psi=jnp.asarray(psi, theta.dtype), normals=facet_normal(theta, az))


# ------------------------------------------------------------------------------ frames
def slope_rotation(theta: Array) -> Array:
    """R_GS: slope frame to world."""
    return geo.rot_y(-theta)


def body_rotation(terrain: SlopeTerrain, walk: WalkParams) -> Array:
    """R_GR: robot frame to world (body parallel to the slope, y_R... along the walk)."""
    return slope_rotation(terrain.theta) @ geo.rot_z(terrain.psi - walk.heading)


def walk_direction(terrain: SlopeTerrain) -> Array:
    """Unit walking direction in the world (3,)."""
    return slope_rotation(terrain.theta) @ jnp.stack(
        [jnp.cos(terrain.psi), jnp.sin(terrain.psi), jnp.zeros_like(terrain.psi)]
    )


def uv_to_world_xy(terrain: SlopeTerrain, uv: Array) -> Array:
    """Horizontal world position (2,) of the slope-plane point with walking-frame
    coordinates uv (2,)."""
    return slope_to_world(terrain, jnp.concatenate([uv, jnp.zeros(1, uv.dtype)]))[:2]


def world_xy_to_uv(terrain: SlopeTerrain, xy: Array) -> Array:
    """Walking-frame coordinates of the slope-plane point vertically below/above the
    horizontal world position xy (inverse of `uv_to_world_xy`)."""
    s = jnp.stack([xy[0] / jnp.cos(terrain.theta), xy[1]])
    return geo.rot_z(-terrain.psi)[:2, :2] @ s


def slope_to_world(terrain: SlopeTerrain, uv_height: Array) -> Array:
    """World position of a point given in walking-frame coordinates (u, v, height)."""
    R_SW = geo.rot_z(terrain.psi)
    return slope_rotation(terrain.theta) @ (R_SW @ uv_height)


# ----------------------------------------------------------------------- the cycle plan
@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class CyclePlan:
    """Footholds and body placements of one cycle (world frame, metres).

    feet[k]: the four footholds before grope k (k = 0..3) and after the cycle (k = 4).
    body[k]: body origin at the start (k = 0) and at the end of phase A of grope k
    (k = 1..4). cog_target[k]: horizontal COG at the start (k = 0: above the centroid
    of the feet) and planned for grope k (k = 1..4). cog_margin, grope_margin: signed
    distances [m, in the slope plane] of the COG (step B) inside pi_g and of the groped foothold inside pi_grp,g
    (negative: not admissible). triangle_margin: signed distance [m, slope plane] of the
    grope's COG target inside the triangle of the other three footholds (positive: the
    robot stands on them if the groped foothold collapses).
    reach_margin: the smallest IK reach margin at any planned placement [m]."""

    feet: Array  # (5, 4, 3)
    body: Array  # (5, 3)
    cog_target: Array  # (5, 2)
    cog_margin: Array  # (4,)
    grope_margin: Array  # (4,)
    triangle_margin: Array  # (4,)
    reach_margin: Array  # ()
    R_GR: Array  # (3, 3)
    h_ref: Array  # (2, 4) normalized grope force per foothold (before/after its step)

    @property
    def margin(self) -> Array:
        """Smallest geometric margin of the plan [m] (negative: not admissible)."""
        return jnp.minimum(jnp.min(self.cog_margin), jnp.min(self.grope_margin))

    def rule_margin(self, rule: str) -> Array:
        """The smallest margin that the COG rule `rule` maximizes (`WalkConfig.cog_rule`):
        "balanced", region margins (`margin`); "collapse_safe", grope-region and triangle
        margins (step B's COG is then the experimental walk's A' position, elsewhere);
        "static_safe", all three."""
        if rule == "collapse_safe":
            return jnp.minimum(jnp.min(self.grope_margin), jnp.min(self.triangle_margin))
        if rule == "static_safe":
            return jnp.minimum(self.margin, jnp.min(self.triangle_margin))
        return self.margin


def _lattice(n: int) -> np.ndarray:
    """Barycentric weights (L, 3) of a triangular lattice, interior points only."""
    pts = [(i, j, n - i - j) for i in range(1, n) for j in range(1, n - i)]
    return np.asarray(pts, float) / n


def _signed_distance_any_orientation(q: Array, vertices: Array, valid: Array) -> Array:
    """Signed distance of q to a compacted convex polygon listed clockwise or
    counter-clockwise (e.g. an affine image of a CCW polygon); positive inside."""
    a, b, ev = geo.polygon_edges(vertices, valid)
    orient = jnp.sign(jnp.sum(jnp.where(ev, geo.cross2(a, b), 0.0)))
    seg = jax.vmap(geo.point_segment_distance, (None, 0, 0))(q, a, b)
    d = jnp.min(jnp.where(ev, seg, jnp.inf))
    inside = jnp.all(jnp.where(ev, orient * geo.cross2(b - a, q - a) >= 0, True)) & (orient != 0)
    return jnp.where(inside, d, -d)


COG_RULES = ("balanced", "collapse_safe", "static_safe")


def _search_cog(stance, h_stance, h_grp, target, lattice, swing_shift, rule="balanced"):
    """COG target c for one grope, on a barycentric lattice over the stance triangle.

    Margins of a candidate c: m_cog, the step-B COG c - swing_shift inside pi_g (during
    step B the groped leg has not swung yet, so the COG sits `swing_shift` behind its
    step-D position); m_grp, the groped foothold `target` inside the step-D region of c
    (`regions.grope_feasible_region`, the union of pi_grp,g over the float legs, an
    affine image of one fixed polygon W, so no hull is needed here); m_tri, c inside the
    stance triangle. `rule` (see `WalkConfig.cog_rule`) picks c. Returns c and its three
    margins."""
    if rule not in COG_RULES:
        raise ValueError(f"unknown cog_rule {rule!r}; expected one of {COG_RULES}")
    w, w_ok = regions._cog_weights_polygon(h_stance[0], h_stance[1], h_stance[2])
    cog_poly = w[:, :1] * stance[0] + w[:, 1:] * stance[1] + (1.0 - w[:, :1] - w[:, 1:]) * stance[2]
    s, s_ok = regions._support_weights_polygon(h_stance[0], h_stance[1], h_stance[2], 1.0 - h_grp)
    W = s[:, :1] * stance[0] + s[:, 1:] * stance[1] + (1.0 - h_grp - s[:, :1] - s[:, 1:]) * stance[2]
    cand = jnp.asarray(lattice, stance.dtype) @ stance  # (L, 2)
    tri_ok = jnp.ones(3, bool)

    def margins(c):
        m_cog = _signed_distance_any_orientation(c - swing_shift, cog_poly, w_ok)
        m_grp = _signed_distance_any_orientation(target, (c - W) / h_grp, s_ok)
        m_tri = _signed_distance_any_orientation(c, stance, tri_ok)
        return m_cog, m_grp, m_tri

    m_cog, m_grp, m_tri = jax.vmap(margins)(cand)
    score = {"balanced": jnp.minimum(m_cog, m_grp), "collapse_safe": jnp.minimum(m_grp, m_tri),
             "static_safe": jnp.minimum(jnp.minimum(m_cog, m_grp), m_tri)}[rule]
    # quantize to 10 nm so that near-ties resolve the same way in every compiled variant
    # (batched or not, any device count): argmax then takes the first of equal scores
    best = jnp.argmax(jnp.round(score * 1e8))
    return cand[best], m_cog[best], m_grp[best], m_tri[best]


def whole_body_cog(params: LegGropeParams, R_GR: Array, body: Array, feet: Array) -> Array:
    """Whole-robot COG (world, (3,)) for the body origin `body` and toe positions `feet`
    (world, (4, 3)); legs placed by inverse kinematics."""
    return jnp.sum(mass_positions(params, R_GR, body, feet) * masses(params)[:, None], 0) / params.total_mass


def masses(params: LegGropeParams) -> Array:
    """Masses of the 13 rigid parts: body, then links i1, i2, i3 of L1..L4."""
    return jnp.concatenate([jnp.atleast_1d(params.body_mass), jnp.tile(jnp.asarray(params.link_masses), 4)])


def leg_angles(params: LegGropeParams, R_GR: Array, body: Array, feet: Array) -> tuple[Array, Array]:
    """Joint angles (4, 3) and IK reach margins (4,) for world toe positions."""
    toes_R = (feet - body) @ R_GR
    return jax.vmap(lambda leg, t: kinematics.inverse_kinematics(params, leg, t))(jnp.arange(4), toes_R)


def mass_positions(params: LegGropeParams, R_GR: Array, body: Array, feet: Array) -> Array:
    """World positions (13, 3) of the body COM and the 12 link midpoints."""
    q, _ = leg_angles(params, R_GR, body, feet)
    links_R = jax.vmap(lambda leg, qq: kinematics.link_com_positions(params, leg, qq))(jnp.arange(4), q)
    links_W = body + links_R.reshape(12, 3) @ R_GR.T
    return jnp.concatenate([body[None], links_W], axis=0)


def place_body(
    params: LegGropeParams, terrain: SlopeTerrain, R_GR: Array, feet: Array, cog_xy: Array, iters: int
) -> Array:
    """Body origin (world) at `body_height` above the slope whose whole-body COG projects
    vertically onto `cog_xy`: Newton iterations on the body's position in the slope
    plane (the legs follow by inverse kinematics)."""
    R_GS = slope_rotation(terrain.theta)
    height = jnp.asarray(params.body_height, cog_xy.dtype)

    def cog_of(uv):
        body = R_GS @ jnp.concatenate([uv, height[None]])
        return whole_body_cog(params, R_GR, body, feet)[:2]

    def step(uv, _):
        J = jax.jacfwd(cog_of)(uv)
        return uv + linalg.solve_2x2(J, cog_xy - cog_of(uv)), None

    uv0 = jnp.stack([cog_xy[0] / jnp.cos(terrain.theta), cog_xy[1]])
    uv, _ = jax.lax.scan(step, uv0, None, length=iters)
    return R_GS @ jnp.concatenate([uv, height[None]])


def plan_cycle(
    params: LegGropeParams,
    walk: WalkParams,
    terrain: SlopeTerrain,
    config: WalkConfig = WalkConfig(),
    steps: Array | None = None,
) -> CyclePlan:
    """Footholds, COG targets and body placements for one leg-grope walk cycle.

    The paper draws its regions on the horizontal plane. Vertical projection between
    the horizontal plane and the slope plane is an affine map, and every region here is
    defined by barycentric (affine) relations, so we plan in slope-plane coordinates
    (u, v), with the COG represented by the slope point vertically below it: the plan
    is then the same on every slope and in every walking direction, and the margins are
    distances in the slope plane. Every groped foot moves `stride` forward and
    `lateral[leg]` sideways (a design input, see `design.py`); the COG target of each
    grope is searched on a lattice (`_search_cog`). `steps` (4, 2) overrides each leg's
    step (u forward, v left) [m] in the walking frame (e.g. a shorter fallback step)."""
    dtype = jnp.asarray(terrain.theta).dtype
    R_GR = body_rotation(terrain, walk)
    to_world = lambda uv: slope_to_world(terrain, jnp.concatenate([uv, jnp.zeros(1, dtype)]))  # noqa: E731
    cos_n = terrain.normals[..., 2]  # cos theta_n of each foothold
    h_ref = params.r_ref_factor * jnp.cos(terrain.theta) / cos_n  # (2, 4)
    lattice = _lattice(config.lattice)
    lateral = jnp.asarray(walk.lateral, dtype)
    if steps is None:
        steps = jnp.stack([jnp.full(4, walk.stride, dtype), lateral], axis=1)
    steps = jnp.asarray(steps, dtype)

    uv = jnp.asarray(walk.stance, dtype)
    feet0 = jax.vmap(to_world)(uv)
    c0 = jnp.mean(uv, axis=0)
    body0 = place_body(params, terrain, R_GR, feet0, uv_to_world_xy(terrain, c0), config.fixed_point_iters)
    feet, uvs = [feet0], [uv]
    moved = np.zeros(4, bool)
    out: dict[str, list] = {k: [] for k in ("c", "mc", "mg", "mt", "body")}
    for g in config.order:
        cur, cur_uv = feet[-1], uvs[-1]
        stance_idx = np.array([n for n in range(4) if n != g])
        h_cur = jnp.where(jnp.asarray(moved), h_ref[1], h_ref[0])
        new_uv = cur_uv.at[g].set(cur_uv[g] + steps[g])
        after = cur.at[g].set(to_world(new_uv[g]))
        # COG shift (slope-plane uv) caused by swinging leg g, body where it was
        b_prev = out["body"][-1] if out["body"] else body0
        uv_cog = lambda f: world_xy_to_uv(terrain, whole_body_cog(params, R_GR, b_prev, f)[:2])  # noqa: E731
        shift = uv_cog(after) - uv_cog(cur)
        c, mc, mg, mt = _search_cog(
            cur_uv[stance_idx], h_cur[stance_idx], h_ref[1, g], new_uv[g], lattice, shift, config.cog_rule
        )
        c_xy = uv_to_world_xy(terrain, c)
        out["body"].append(place_body(params, terrain, R_GR, after, c_xy, config.fixed_point_iters))
        for key, val in zip(("c", "mc", "mg", "mt"), (c_xy, mc, mg, mt)):
            out[key].append(val)
        feet.append(after)
        uvs.append(new_uv)
        moved[g] = True
    body = jnp.stack([body0] + out["body"])
    feet = jnp.stack(feet)
    # reach at every planned placement: body before and after each move, feet before it
    reach = jax.vmap(lambda b, f: leg_angles(params, R_GR, b, f)[1])(
        jnp.concatenate([body[:-1], body[1:], body[1:]]), jnp.concatenate([feet[:-1], feet[:-1], feet[1:]])
    )
    return CyclePlan(
        feet=feet,
        body=body,
        cog_target=jnp.stack([uv_to_world_xy(terrain, c0)] + out["c"]),
        cog_margin=jnp.stack(out["mc"]),
        grope_margin=jnp.stack(out["mg"]),
        triangle_margin=jnp.stack(out["mt"]),
        reach_margin=jnp.min(reach),
        R_GR=R_GR,
        h_ref=h_ref,
    )


# ---------------------------------------------------------------------------- motion
def trapezoid(t: Array, distance: Array, a_max: Array, v_max: Array) -> tuple[Array, Array]:
    """Distance travelled at time t [s] along a rest-to-rest move of `distance` [m] with
    acceleration a_max and speed limit v_max (trapezoidal, or triangular when short),
    and the move's duration."""
    d = jnp.maximum(distance, 0.0)
    t_a = jnp.minimum(v_max / a_max, jnp.sqrt(d / a_max))
    v_p = a_max * t_a
    t_c = jnp.where(v_p > 0, (d - a_max * t_a**2) / jnp.where(v_p > 0, v_p, 1.0), 0.0)
    total = 2.0 * t_a + t_c
    s1 = 0.5 * a_max * t**2
    s2 = 0.5 * a_max * t_a**2 + v_p * (t - t_a)
    s3 = d - 0.5 * a_max * (total - t) ** 2
    s = jnp.where(t < t_a, s1, jnp.where(t < t_a + t_c, s2, jnp.where(t < total, s3, d)))
    return s, total


def min_jerk(s: Array) -> Array:
    """Minimum-jerk blend 10 s^3 - 15 s^4 + 6 s^5 on [0, 1]."""
    s = jnp.clip(s, 0.0, 1.0)
    return s**3 * (10.0 + s * (-15.0 + 6.0 * s))


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class StepInfo:
    """Which grope, phase and local time a global step index stands for."""

    grope: Array  # 0..3
    leg: Array  # groping leg 0..3
    phase: Array  # 0..3 = A, B, C, D
    local: Array  # step index within the phase
    tau: Array  # time since the phase began, at the end of this step [s]
    fraction: Array  # (local + 1) / phase length


def step_info(i: Array, config: WalkConfig, dt: float) -> StepInfo:
    """Decode a global step index (traced int) of the cycle."""
    n = config.steps_per_grope
    grope = i // n
    j = i % n
    lengths = np.array(config.phase_lengths())
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]])
    phase = jnp.sum(j >= jnp.asarray(starts[1:]))
    local = j - jnp.asarray(starts)[phase]
    length = jnp.asarray(lengths)[phase]
    leg = jnp.asarray(np.array(config.order))[grope]
    return StepInfo(grope, leg, phase, local, (local + 1) * dt, (local + 1) / length)


def pose_at(
    params: LegGropeParams,
    walk: WalkParams,
    plan: CyclePlan,
    info: StepInfo,
    tau: Array,
    config: WalkConfig,
) -> tuple[Array, Array]:
    """Body origin (3,) and toe positions (4, 3) in the world at time `tau` into the
    phase `info.phase` of grope `info.grope` (tau is an explicit argument so that
    velocities and accelerations follow by differentiating with respect to it)."""
    k, g = info.grope, info.leg
    b0, b1 = plan.body[k], plan.body[k + 1]
    dist = jnp.linalg.norm(b1 - b0)
    s, _ = trapezoid(tau, dist, params.a_max, params.v_max)
    direction = (b1 - b0) / jnp.where(dist > 0, dist, 1.0)
    body = jnp.where(info.phase == 0, b0 + s * direction, b1)
    before, after = plan.feet[k], plan.feet[k + 1]
    normal = plan.R_GR[:, 2]
    T_swing = config.n_swing * params.dt
    frac = jnp.clip(tau / T_swing, 0.0, 1.0)
    lift = walk.swing_height * 0.5 * (1.0 - jnp.cos(2.0 * jnp.pi * frac))
    swing = before[g] + (after[g] - before[g]) * min_jerk(frac) + lift * normal
    toe_g = jnp.where(info.phase < 2, before[g], jnp.where(info.phase == 2, swing, after[g]))
    feet = before.at[g].set(toe_g)
    return body, feet


def move_durations(params: LegGropeParams, plan: CyclePlan) -> Array:
    """Duration [s] of each phase-A body move of the plan, (4,)."""
    dist = jnp.linalg.norm(plan.body[1:] - plan.body[:-1], axis=1)
    return jax.vmap(lambda d: trapezoid(jnp.zeros_like(d), d, params.a_max, params.v_max)[1])(dist)


__all__ = [
    "G",
    "PHASES",
    "WalkParams",
    "WalkConfig",
    "SlopeTerrain",
    "CyclePlan",
    "simple_slope",
    "place_body",
    "default_stance",
    "irregular_slope",
    "plan_cycle",
    "pose_at",
    "step_info",
    "trapezoid",
    "min_jerk",
    "masses",
    "mass_positions",
    "whole_body_cog",
    "leg_angles",
    "move_durations",
    "walk_direction",
    "body_rotation",
    "GaitDesign",
    "DESIGNS",
    "CYCLE_DESIGNS",
    "gait_design",
]
