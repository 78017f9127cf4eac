"""Stability margins of a robot standing on a masked, fixed-size, unordered set of contact
points. Pure JAX (jit, vmap, grad; float32 and float64).

Inputs, unless said otherwise: `cog` (3,) and `contacts` (N, 3) in a world frame whose
z axis points up (against gravity); `mask` (N,) marks the active contacts (N is fixed,
e.g. 16 for a crawler with many contacts). `up` optionally replaces world z by another
unit "up" vector (e.g. the negative of an effective gravity that includes a tether
force). Distances in metres, forces in newtons.

The support polygon is the convex hull of the active contacts projected along `up`;
its edges come from geometry's gift-wrap (`hull_edges`, `small_hull_edges`, O(N^2)), so
no ordering of contacts is needed.

Every margin is signed: positive when stable, negative when the robot would tip (or
slip, for the friction margin). Each has a `*_smooth` variant for gradient-based
tuning: the min over edges/contacts is replaced by `geometry.soft_min` with a
temperature T (metres or newtons); it is smooth, never above the exact margin when the
robot is stable, and within T log(n) of the min over the same terms. The smooth
variants are for objectives, not for safety checks.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxloco import geometry as geo

Array = jax.Array


def vertical_frame(up: Array | None, dtype) -> Array:
    """Rows (u1, u2, up): an orthonormal basis whose third axis is `up` (identity for
    None: z is up). `B @ x` expresses a world point in it."""
    if up is None:
        return jnp.eye(3, dtype=dtype)
    R = geo.contact_frame(up)  # columns: x, y, z=up
    return R.T


def _vertical_coordinates(cog: Array, contacts: Array, up: Array | None) -> tuple[Array, Array]:
    """The COG (3,) and the contacts (N, 3) in `vertical_frame(up)` (z along up); as
    given for None (no product with the identity: it halved the static margin's rate
    at 4 contacts)."""
    if up is None:
        return cog, contacts
    B = vertical_frame(up, contacts.dtype)
    return B @ cog, contacts @ B.T


def _split(cog: Array, contacts: Array, up: Array | None) -> tuple[Array, Array, Array, Array]:
    """Horizontal (2D) and vertical coordinates of the COG and the contacts."""
    c, p = _vertical_coordinates(cog, contacts, up)
    return c[:2], c[2], p[:, :2], p[:, 2]


def _edge_line_distances(q: Array, p2: Array) -> Array:
    """d[i, j]: signed distance of q from the line p_i -> p_j (left positive)."""
    e = p2[None, :, :] - p2[:, None, :]
    elen = geo._safe_norm(e)  # not jnp.linalg.norm: its gradient is NaN on the i == j diagonal
    safe = jnp.where(elen > 0, elen, 1.0)
    return geo.cross2(e, q[None, None, :] - p2[:, None, :]) / safe


# ----------------------------------------------------------------- static (support) margin
def static_margin(cog: Array, contacts: Array, mask: Array, up: Array | None = None) -> Array:
    """Static stability margin: signed horizontal distance from the COG's vertical
    projection to the boundary of the support polygon (positive inside, negative
    outside; <= 0 for fewer than three non-collinear contacts; -inf with none)."""
    q, _, p2, _ = _split(cog, contacts, up)
    return geo.hull_signed_distance(q, p2, mask)


def static_margin_smooth(
    cog: Array, contacts: Array, mask: Array, temperature: Array, up: Array | None = None
) -> Array:
    """Soft-min over the support edges of the signed distance from the projected COG to
    each edge's line. Equals a smooth lower bound of `static_margin` inside the polygon;
    outside it is negative but smaller in magnitude (distance to a line, not a segment)."""
    q, _, p2, _ = _split(cog, contacts, up)
    E = geo.hull_edges(p2, mask)
    return geo.soft_min(_edge_line_distances(q, p2).ravel(), temperature, E.ravel())


def support_edge_distances(cog: Array, contacts: Array, mask: Array, up: Array | None = None) -> tuple[Array, Array]:
    """Signed distances of the projected COG from the lines of the support polygon's
    edges: (d (N, N), E (N, N) bool). d[i, j] is the distance (positive inside, m) from
    the edge p_i -> p_j when E[i, j] marks it as a counter-clockwise hull edge
    (`geometry.hull_edges`); entries off the hull are meaningless. For costs that use
    every side, e.g. T² Snake-3's Eq. 20 ||d||_2 = sqrt(sum over E of d^2)."""
    q, _, p2, _ = _split(cog, contacts, up)
    return _edge_line_distances(q, p2), geo.hull_edges(p2, mask)


# ------------------------------------------------------ normalized energy stability margin
def axis_energy_rise(c: Array, a: Array, b: Array) -> Array:
    """How high (m, >= 0) the COG `c` rises when the body tips about the 3D axis through
    the contacts a and b until the COG is above the axis: the highest point of its circle
    about the axis minus its present height (points in a frame whose z is up, see
    `vertical_frame`). The unsigned energy margin of one tipping axis (the NE stability
    margin of that edge, Hirose et al.); finite gradients also for a == b. Points (..., 3),
    broadcast against each other."""
    return _energy_rise(*(jnp.moveaxis(v, -1, 0) for v in (c, a, b)))


def _energy_rise(c: tuple, a: tuple, b: tuple) -> Array:
    """`axis_energy_rise` on coordinates: c, a, b are (x, y, z) triples of arrays that
    broadcast (N-vectors, N x N pairs: no reductions over a 3-axis, which XLA vectorises
    badly)."""
    e = [bk - ak for ak, bk in zip(a, b)]
    e2 = e[0] * e[0] + e[1] * e[1] + e[2] * e[2]
    ok = e2 > 0
    inv2 = jnp.where(ok, 1.0 / jnp.where(ok, e2, 1.0), 0.0)  # 1 / |e|^2; a == b: no axis direction
    r = [ck - ak for ak, ck in zip(a, c)]
    along = (r[0] * e[0] + r[1] * e[1] + r[2] * e[2]) * inv2
    R = [rk - along * ek for rk, ek in zip(r, e)]  # from the axis to the COG, normal to it
    # |R| sqrt(1 - e_z^2 / |e|^2) in one square root: |R|^2 (e_x^2 + e_y^2) / |e|^2
    level = jnp.where(ok, (e[0] * e[0] + e[1] * e[1]) * inv2, 1.0)
    rho2 = (R[0] * R[0] + R[1] * R[1] + R[2] * R[2]) * level
    return jnp.sqrt(rho2 + jnp.finfo(rho2.dtype).tiny) - R[2]


def _ne_edge_margins(cog: Array, contacts: Array, up: Array | None) -> tuple[Array, Array]:
    """Per-edge energy margin h_max - h_0 (m), signed by the side of the COG."""
    c, p = _vertical_coordinates(cog, contacts, up)
    # axis i -> j for every pair (finite gradient on the i == j diagonal)
    rise = _energy_rise(tuple(c), tuple(p[:, k, None] for k in range(3)), tuple(p[None, :, k] for k in range(3)))
    side = geo.cross2(p[None, :, :2] - p[:, None, :2], c[None, None, :2] - p[:, None, :2])  # sign only
    return jnp.where(side >= 0, rise, -rise), p[:, :2]


def ne_edge_margins(cog: Array, contacts: Array, mask: Array, up: Array | None = None) -> tuple[Array, Array]:
    """The signed energy margins (N, N) [m] of every tipping axis i -> j (as in
    `ne_stability_margin`) and the support polygon's counter-clockwise hull edges (N, N)
    bool: `ne_stability_margin` is the smallest margin over the edges."""
    S, p2 = _ne_edge_margins(cog, contacts, up)
    return S, geo.hull_edges(p2, mask)


def ne_stability_margin(cog: Array, contacts: Array, mask: Array, up: Array | None = None) -> Array:
    """Normalized energy stability margin (Hirose, Tsukagoshi & Yoneda, ICRA 2001), in m.

    For each edge of the support polygon the tipping axis is the 3D line through its two
    contacts (edges need not be horizontal: slopes, rough terrain). Rotating about that
    axis, the COG moves on a circle; the edge's margin is the height of the circle's
    highest point above the COG's present height, i.e. the tip-over energy divided by
    the weight. It is signed: negative when the COG's projection is outside the edge
    (already past the top). NESM = min over edges; -inf with fewer than two contacts.
    The edges come from geometry's gift-wrap (O(N^2)); up to UNROLL_MAX_POINTS contacts
    every pair's margin is evaluated and the edges' minimum taken, beyond only the N
    successor axes' (`_ne_successor_margins`).
    """
    if contacts.shape[0] > geo.UNROLL_MAX_POINTS:
        return _min_over_edges(*_ne_successor_margins(cog, contacts, mask, up))
    # Up to 6 contacts every pair: the successor axes alone made TITAN's stride gradient
    # NaN in programs compiled at XLA's optimisation level 0, as the suite compiles them
    # (tests/test_titan_tune.py; finite and right at the default level; docs/sweeps.md).
    S, p2 = _ne_edge_margins(cog, contacts, up)
    return _min_over_edges(S, geo.hull_edges(p2, mask))


@jax.custom_jvp
def _min_over_edges(margins: Array, edges: Array) -> Array:
    """The smallest margin over the support edges (any shape, same for both); -inf with
    no edge. Its derivative (`_min_over_edges_jvp`) is the mean tangent of the
    minimisers, as `jnp.min`'s, but read by a select: min's own forward-mode rule
    multiplies every entry's tangent by a 0/1 indicator, so a non-finite tangent of an
    edge that is not the smallest would make the derivative NaN. It did in TITAN's stride
    gradient, in programs compiled at XLA's optimisation level 0 with its legacy emitters
    (`tests/test_titan_tune.py`, 6 Dec 2026). A custom rule leaves the value's program as
    it was (the selects in the value itself ran the NESM at 4 contacts 30 % slower)."""
    return jnp.where(jnp.any(edges), jnp.min(jnp.where(edges, margins, jnp.inf), initial=jnp.inf), -jnp.inf)


@_min_over_edges.defjvp
def _min_over_edges_jvp(primals, tangents):
    margins, edges = primals
    out = _min_over_edges(margins, edges)
    at_min = edges & (margins == out)
    tangent = jnp.sum(jnp.where(at_min, tangents[0], 0.0)) / jnp.maximum(jnp.sum(at_min), 1)
    return out, jnp.where(jnp.any(edges), tangent, 0.0)


def _at_successors(succ: Array, coords: tuple) -> tuple:
    """Each coordinate array (N,) read at the successors `succ` (N,) (a gather: 1.4x the
    NESM's rate at 16 contacts against masked sums over every row)."""
    return tuple(c[succ] for c in coords)


def _ne_successor_margins(cog: Array, contacts: Array, mask: Array, up: Array | None) -> tuple[Array, Array]:
    """The signed energy margins (N,) [m] of the axes p_i -> p_succ[i] and whether each is
    a support edge (`geometry.small_hull_edges`): N axes instead of every pair's N^2. The
    successor's coordinates are gathered (`_at_successors`); a non-edge row's axis is
    degenerate (succ[i] = i), which `axis_energy_rise` keeps finite."""
    c, p = _vertical_coordinates(cog, contacts, up)
    succ, edge = geo.small_hull_edges(p[:, :2], mask)
    a = tuple(p[:, k] for k in range(3))
    b = _at_successors(succ, a)
    rise = _energy_rise(tuple(c), a, b)
    side = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])  # the COG's side, times |edge|
    return jnp.where(side >= 0, rise, -rise), edge


def _ne_stability_margin_all_pairs(cog: Array, contacts: Array, mask: Array, up: Array | None = None) -> Array:
    """`ne_stability_margin` with the support edges from the all-pairs `_hull_edges_all_pairs`
    (O(N^3)) instead of the gift-wrap: the reference the tests hold it to."""
    S, p2 = _ne_edge_margins(cog, contacts, up)
    return _min_over_edges(S, geo._hull_edges_all_pairs(p2, mask))


def ne_stability_margin_smooth(
    cog: Array, contacts: Array, mask: Array, temperature: Array, up: Array | None = None
) -> Array:
    """Soft-min over the support edges of the signed energy margins (see module doc)."""
    S, p2 = _ne_edge_margins(cog, contacts, up)
    E = geo.hull_edges(p2, mask)
    return geo.soft_min(S.ravel(), temperature, E.ravel())


# ------------------------------------------------------------ longitudinal stability margin
def _travel_direction(direction: Array, up: Array | None, dtype) -> tuple[Array, Array]:
    """The unit horizontal travel direction (d_x, d_y) in `vertical_frame(up)`."""
    d3 = jnp.concatenate([direction, jnp.zeros(3 - direction.shape[0], direction.dtype)]).astype(dtype)
    d = d3[:2] if up is None else (vertical_frame(up, dtype) @ d3)[:2]
    d = d / jnp.linalg.norm(d)
    return d[0], d[1]


def _longitudinal_term(q: tuple, a: tuple, b: tuple, d: tuple, eps: float) -> Array:
    """The signed distance from q along the travel line d to the line a -> b (2D (x, y)
    pairs of broadcasting arrays): the distance from q to the line (left positive)
    divided by |n . d|, n the line's unit normal, floored at `eps`; finite gradients also
    for a == b (the term is then 0)."""
    ex, ey = b[0] - a[0], b[1] - a[1]
    e2 = ex * ex + ey * ey
    ok = e2 > 0
    inv = jnp.where(ok, jax.lax.rsqrt(jnp.where(ok, e2, 1.0)), 1.0)
    along = jnp.abs(ey * d[0] - ex * d[1]) * inv
    dist = (ex * (q[1] - a[1]) - ey * (q[0] - a[0])) * inv
    return dist / jnp.maximum(along, eps)


def _longitudinal_terms(cog, contacts, direction, up, eps):
    """Every pair's `_longitudinal_term` (N, N) of the axis i -> j, and the 2D contacts."""
    q, _, p2, _ = _split(cog, contacts, up)
    d = _travel_direction(direction, up, p2.dtype)
    a, b = (p2[:, None, 0], p2[:, None, 1]), (p2[None, :, 0], p2[None, :, 1])
    return _longitudinal_term((q[0], q[1]), a, b, d, eps), p2


def _longitudinal_successor_terms(cog, contacts, mask, direction, up, eps) -> tuple[Array, Array]:
    """`_longitudinal_term` (N,) of the axes p_i -> p_succ[i] and whether each is a
    support edge (`geometry.small_hull_edges`): N terms instead of every pair's N^2."""
    q, _, p2, _ = _split(cog, contacts, up)
    succ, edge = geo.small_hull_edges(p2, mask)
    a = (p2[:, 0], p2[:, 1])
    b = _at_successors(succ, a)
    return _longitudinal_term((q[0], q[1]), a, b, _travel_direction(direction, up, p2.dtype), eps), edge


def longitudinal_margin(
    cog: Array, contacts: Array, mask: Array, direction: Array, up: Array | None = None, eps: float = 1e-6
) -> Array:
    """Longitudinal stability margin (McGhee & Frank 1968), in m: the shorter of the
    distances from the projected COG, along the line of travel `direction` (2D or 3D,
    horizontal part used), to the front and rear boundaries of the support polygon.

    Signed: for a COG outside the polygon it is minus the distance along the travel line
    to the line of the violated edge (edges parallel to the travel line count with
    |n.d| floored at `eps`, so a COG beside the polygon gives a large negative value)."""
    if contacts.shape[0] > geo.UNROLL_MAX_POINTS:
        return _min_over_edges(*_longitudinal_successor_terms(cog, contacts, mask, direction, up, eps))
    terms, p2 = _longitudinal_terms(cog, contacts, direction, up, eps)
    return _min_over_edges(terms, geo.hull_edges(p2, mask))


def _longitudinal_margin_all_pairs(cog: Array, contacts: Array, mask: Array, direction: Array,
                                   up: Array | None = None, eps: float = 1e-6) -> Array:
    """`longitudinal_margin` over the all-pairs edges (`_hull_edges_all_pairs`, O(N^3)):
    the reference the tests hold it to."""
    terms, p2 = _longitudinal_terms(cog, contacts, direction, up, eps)
    return _min_over_edges(terms, geo._hull_edges_all_pairs(p2, mask))


def longitudinal_margin_smooth(
    cog: Array,
    contacts: Array,
    mask: Array,
    direction: Array,
    temperature: Array,
    up: Array | None = None,
    eps: float = 1e-6,
) -> Array:
    """Soft-min version of `longitudinal_margin`."""
    terms, p2 = _longitudinal_terms(cog, contacts, direction, up, eps)
    E = geo.hull_edges(p2, mask)
    return geo.soft_min(terms.ravel(), temperature, E.ravel())


# ----------------------------------------------------------------- friction safety margin
SQRT2 = 2.0**0.5


def forces_in_contact_frames(forces: Array, frames: Array) -> Array:
    """Express world-frame forces (N, 3) in contact frames (N, 3, 3) whose columns are
    the frames' axes in the world (as `geometry.contact_frame` returns)."""
    return jnp.einsum("nij,ni->nj", frames, forces)


def friction_margins(forces: Array, mu: Array) -> Array:
    """Per-contact safety margin of the linearized friction pyramid, leg-grope Eqs. 17-18.

    `forces` (N, 3) are the ground reaction forces on the robot in each contact frame
    Sigma_iS (z along the normal, x along the gradient of the contact plane). The four
    rows -mu/sqrt2 f_z +- f_x/sqrt2 +- f_y/sqrt2 <= -s hold for every s up to
        s_i = (mu f_z - |f_x| - |f_y|) / sqrt(2)      [N].
    s_i >= 0 means the force is inside the pyramid (which is inscribed in the friction
    cone and touches it along +-x and +-y); a negative normal force gives s_i < 0."""
    return (mu * forces[:, 2] - jnp.abs(forces[:, 0]) - jnp.abs(forces[:, 1])) / SQRT2


def friction_margin(forces: Array, mu: Array, mask: Array) -> Array:
    """Friction safety margin s of a contact force set: min of `friction_margins` over
    the active contacts (+inf if none is active)."""
    return jnp.min(jnp.where(mask, friction_margins(forces, mu), jnp.inf))


def friction_margin_smooth(
    forces: Array, mu: Array, mask: Array, temperature: Array, abs_eps: float = 1e-3
) -> Array:
    """Smooth friction margin: |.| replaced by sqrt(x^2 + abs_eps^2) and the min by a
    soft-min with `temperature` (N). A lower bound of `friction_margin`."""
    sabs = lambda x: jnp.sqrt(x * x + abs_eps * abs_eps)  # noqa: E731
    s = (mu * forces[:, 2] - sabs(forces[:, 0]) - sabs(forces[:, 1])) / SQRT2
    return geo.soft_min(s, temperature, mask)
