"""Geometry kernels: rotations, homogeneous transforms, Denavit-Hartenberg links, planes,
lines and masked fixed-size convex polygons. Pure JAX; jit, vmap and grad work; the
dtype of the inputs (float32 or float64) is kept.

Conventions: SI units, radians, right-handed frames. Rotation matrices are *active*
(they rotate vectors: v_A = R_AB v_B maps coordinates in frame B to frame A). A frame
transform that the papers write as a passive rotation is the transpose, e.g. OCTOPUS
Eq. 12 is `rot_y(A_P).T` and Eq. 13 is `rot_x(A_R).T`.

Polygons are fixed-size: `points` of shape (N, 2) with a boolean `mask` (N,) saying
which rows are real. Nothing depends on the order of the masked points; functions that
return a polygon return its vertices counter-clockwise, compacted to the front, with a
validity mask.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import jax
import jax.numpy as jnp

from jaxloco import linalg

Array = jax.Array


# --------------------------------------------------------------------------- rotations
def rot_x(angle: Array) -> Array:
    """Active rotation about x by `angle` (rad), shape (3, 3)."""
    c, s = jnp.cos(angle), jnp.sin(angle)
    o, z = jnp.ones_like(c), jnp.zeros_like(c)
    return jnp.stack([jnp.stack([o, z, z]), jnp.stack([z, c, -s]), jnp.stack([z, s, c])])


def rot_y(angle: Array) -> Array:
    """Active rotation about y by `angle` (rad), shape (3, 3)."""
    c, s = jnp.cos(angle), jnp.sin(angle)
    o, z = jnp.ones_like(c), jnp.zeros_like(c)
    return jnp.stack([jnp.stack([c, z, s]), jnp.stack([z, o, z]), jnp.stack([-s, z, c])])


def rot_z(angle: Array) -> Array:
    """Active rotation about z by `angle` (rad), shape (3, 3)."""
    c, s = jnp.cos(angle), jnp.sin(angle)
    o, z = jnp.ones_like(c), jnp.zeros_like(c)
    return jnp.stack([jnp.stack([c, -s, z]), jnp.stack([s, c, z]), jnp.stack([z, z, o])])


def rpy_to_matrix(roll: Array, pitch: Array, yaw: Array) -> Array:
    """R = Rz(yaw) Ry(pitch) Rx(roll): body-to-world rotation of a body with the given
    roll, pitch, yaw (Z-Y-X Tait-Bryan, as an IMU reports them)."""
    return rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)


def matrix_to_rpy(R: Array) -> Array:
    """Inverse of `rpy_to_matrix` for |pitch| < pi/2: returns [roll, pitch, yaw]."""
    roll = jnp.arctan2(R[2, 1], R[2, 2])
    pitch = jnp.arcsin(jnp.clip(-R[2, 0], -1.0, 1.0))
    yaw = jnp.arctan2(R[1, 0], R[0, 0])
    return jnp.stack([roll, pitch, yaw])


def skew(v: Array) -> Array:
    """Cross-product matrix: skew(a) @ b == cross(a, b)."""
    z = jnp.zeros_like(v[0])
    return jnp.stack(
        [jnp.stack([z, -v[2], v[1]]), jnp.stack([v[2], z, -v[0]]), jnp.stack([-v[1], v[0], z])]
    )


# ------------------------------------------------------------ homogeneous transforms
def make_transform(R: Array, p: Array) -> Array:
    """4x4 homogeneous transform from rotation R (3, 3) and translation p (3,)."""
    top = jnp.concatenate([R, p[:, None]], axis=1)
    bottom = jnp.concatenate([jnp.zeros(3, R.dtype), jnp.ones(1, R.dtype)])[None, :]
    return jnp.concatenate([top, bottom], axis=0)


def transform_point(T: Array, p: Array) -> Array:
    """Apply a 4x4 transform to a point (3,)."""
    return T[:3, :3] @ p + T[:3, 3]


def invert_transform(T: Array) -> Array:
    """Inverse of a rigid 4x4 transform."""
    R, p = T[:3, :3], T[:3, 3]
    return make_transform(R.T, -R.T @ p)


def dh_transform(theta: Array, d: Array, a: Array, alpha: Array) -> Array:
    """Standard Denavit-Hartenberg link transform Rz(theta) Tz(d) Tx(a) Rx(alpha)."""
    ct, st = jnp.cos(theta), jnp.sin(theta)
    ca, sa = jnp.cos(alpha), jnp.sin(alpha)
    z, o = jnp.zeros_like(ct), jnp.ones_like(ct)
    d, a = d * o, a * o
    return jnp.stack(
        [
            jnp.stack([ct, -st * ca, st * sa, a * ct]),
            jnp.stack([st, ct * ca, -ct * sa, a * st]),
            jnp.stack([z, sa * o, ca * o, d]),
            jnp.stack([z, z, z, o]),
        ]
    )


def dh_chain(theta: Array, d: Array, a: Array, alpha: Array, base: Array | None = None) -> Array:
    """Frames of a serial D-H chain: (n+1, 4, 4), frame 0 = `base` (identity if None),
    frame k = base @ A_1 ... A_k. All parameter arrays have shape (n,)."""
    theta = jnp.asarray(theta)
    n = theta.shape[0]
    d, a, alpha = (jnp.broadcast_to(jnp.asarray(v, theta.dtype), (n,)) for v in (d, a, alpha))
    T = jnp.eye(4, dtype=theta.dtype) if base is None else base
    frames = [T]
    for k in range(n):  # n is static and small: unrolled
        T = T @ dh_transform(theta[k], d[k], a[k], alpha[k])
        frames.append(T)
    return jnp.stack(frames)


# ------------------------------------------------------------------- planes and lines
def project_to_plane(p: Array, normal: Array, offset: Array) -> Array:
    """Orthogonal projection of point p (3,) onto the plane {x : n.x = offset} (n unit)."""
    return p - (jnp.dot(normal, p) - offset) * normal


def cross2(a: Array, b: Array) -> Array:
    """z-component of the cross product of 2D vectors (..., 2)."""
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def signed_distance_to_line(p: Array, a: Array, b: Array) -> Array:
    """Signed distance from 2D point p to the line through a -> b; positive on the left."""
    e = b - a
    return cross2(e, p - a) / jnp.linalg.norm(e)


def point_segment_distance(p: Array, a: Array, b: Array) -> Array:
    """Euclidean distance from p to the segment [a, b] (any dimension; a == b allowed)."""
    e = b - a
    ee = jnp.dot(e, e)
    t = jnp.clip(jnp.dot(p - a, e) / jnp.where(ee > 0, ee, 1.0), 0.0, 1.0)
    diff = p - (a + t * e)
    return _safe_norm(diff)


def _safe_norm(v: Array) -> Array:
    """|v| with a finite (zero) gradient at v = 0."""
    sq = jnp.sum(v * v, axis=-1)
    ok = sq > 0
    return jnp.where(ok, jnp.sqrt(jnp.where(ok, sq, 1.0)), 0.0)


def fit_plane(points: Array, mask: Array | None = None) -> tuple[Array, Array]:
    """Least-squares plane z = c0 + c1 x + c2 y through masked 3D points (N, 3).

    This is TITAN XI's "virtual contact plane" (least squares on the z positions of the
    feet). Returns (unit normal n with n_z > 0, offset) such that the plane is
    {x : n.x = offset}. Needs at least 3 non-collinear masked points.
    """
    w = jnp.ones(points.shape[0], points.dtype) if mask is None else mask.astype(points.dtype)
    X = jnp.stack([jnp.ones_like(points[:, 0]), points[:, 0], points[:, 1]], axis=1)
    XtW = X.T * w
    c = linalg.spd_solve(XtW @ X, XtW @ points[:, 2])
    raw = jnp.stack([-c[1], -c[2], jnp.ones_like(c[0])])
    scale = jnp.linalg.norm(raw)
    return raw / scale, c[0] / scale


def contact_frame(normal: Array, fallback_x: Array | None = None) -> Array:
    """Rotation (3, 3) whose columns are the axes of a contact frame Sigma_S in the world:
    z = unit surface normal, x = direction of steepest ascent of the contact plane (the
    "gradient" axis of the leg-grope paper), y = z x x. On a level plane the gradient is
    undefined and `fallback_x` (default world x) projected onto the plane is used."""
    n = normal / jnp.linalg.norm(normal)
    up = jnp.array([0.0, 0.0, 1.0], n.dtype)
    g = up - jnp.dot(up, n) * n
    fb = jnp.array([1.0, 0.0, 0.0], n.dtype) if fallback_x is None else fallback_x
    fb = fb - jnp.dot(fb, n) * n
    gn = jnp.dot(g, g)
    level = gn < 1e-12
    x = jnp.where(level, fb, g)
    x = x / _safe_norm(x)
    y = jnp.cross(n, x)
    return jnp.stack([x, y, n], axis=1)


# ---------------------------------------------------------- masked fixed-size polygons
def _tolerance(points: Array, mask: Array) -> Array:
    """Distance tolerance scaled to the extent of the masked points and the dtype."""
    extent = jnp.max(jnp.where(mask[:, None], jnp.abs(points), 0.0))
    return 1e3 * jnp.finfo(points.dtype).eps * (1.0 + extent)


def unique_mask(points: Array, mask: Array) -> Array:
    """`mask` with repeated points (within tolerance) dropped, keeping the first copy."""
    tol = _tolerance(points, mask)
    n = points.shape[0]
    rows = jnp.arange(n)
    dup = jnp.zeros(n, bool)
    coords = [points[:, a] for a in range(points.shape[1])]
    for j in range(n - 1):  # every point against p_j, on N-vectors (an (N, N, D) array was 7x slower)
        d = functools.reduce(jnp.maximum, [jnp.abs(c - c[j]) for c in coords])
        dup = dup | ((rows > j) & (d <= tol) & mask[j])
    return mask & ~dup


def hull_edges(points: Array, mask: Array) -> Array:
    """Edges of the convex hull of the masked 2D points, as an (N, N) boolean matrix:
    E[i, j] is true when the directed segment p_i -> p_j is a maximal edge of the hull
    traversed counter-clockwise (every masked point lies left of or on its line, and the
    collinear ones lie between p_i and p_j). Order of the points does not matter.

    Degenerate sets: all points collinear -> both directions of the extreme segment;
    one point (or none) -> no edges. The selection is piecewise constant (no gradient).
    From the successors of `small_hull_edges` (a gift-wrap step, a support test and the
    farthest point on the line, from every point: O(N^2)); `_hull_edges_all_pairs`
    (O(N^3)) gives the same matrix."""
    n = points.shape[0]
    succ, edge = small_hull_edges(points, mask)
    return edge[:, None] & (succ[:, None] == jnp.arange(n)[None, :])


def _hull_edges_all_pairs(points: Array, mask: Array) -> Array:
    """`hull_edges` by testing every pair (i, j) against every point k (O(N^3)): the
    reference the gift-wrap forms are tested against."""
    mask = unique_mask(points, mask)
    tol = jax.lax.stop_gradient(_tolerance(points, mask))
    p = jax.lax.stop_gradient(points)
    e = p[None, :, :] - p[:, None, :]  # e[i, j] = p_j - p_i
    elen = jnp.linalg.norm(e, axis=-1)
    safe_len = jnp.where(elen > 0, elen, 1.0)
    rel = p[None, :, :] - p[:, None, :]  # rel[i, k] = p_k - p_i
    # dist[i, j, k]: signed distance of p_k from the line i -> j (left positive)
    dist = cross2(e[:, :, None, :], rel[:, None, :, :]) / safe_len[:, :, None]
    t = jnp.sum(e[:, :, None, :] * rel[:, None, :, :], axis=-1) / (safe_len**2)[:, :, None]
    left = dist >= -tol
    on_line = jnp.abs(dist) <= tol
    inside_segment = (t >= -tol / safe_len[:, :, None]) & (t <= 1.0 + tol / safe_len[:, :, None])
    ok_k = ~mask[None, None, :] | (left & (~on_line | inside_segment))
    pair = mask[:, None] & mask[None, :] & (elen > tol)
    return pair & jnp.all(ok_k, axis=-1)


def _most_clockwise(xi: Array, yi: Array, x: list[Array], y: list[Array], tol2: Array,
                    mk: list[Array] | None = None, skip: int | None = None) -> tuple[Array, Array, Array]:
    """A gift-wrap step without tie rules from p_i = (xi, yi) (scalars, or N-vectors of
    every point at once) over the points x, y (per-point scalars; masks mk, None: all
    real; the loop is unrolled at trace time; `skip` leaves out p_i itself in the scalar
    form): the offset e = p_j - p_i of the most clockwise other point (points within
    sqrt(tol2) of p_i are skipped, ties keep the first) and whether one was found.
    Returns (e_x, e_y, found)."""
    ex, ey, found = jnp.zeros_like(xi), jnp.zeros_like(xi), jnp.zeros_like(xi, dtype=bool)
    for k in range(len(x)):
        if k == skip:
            continue
        ax, ay = x[k] - xi, y[k] - yi
        cand = ax * ax + ay * ay > tol2
        if mk is not None:
            cand = mk[k] & cand
        better = cand & (~found | (ex * ay - ey * ax < 0))  # p_k right of the best line so far
        ex, ey, found = jnp.where(better, ax, ex), jnp.where(better, ay, ey), found | cand
    return ex, ey, found


def _maximal_successor(i, xi: Array, yi: Array, mki: Array, x: list[Array], y: list[Array], mk: list[Array],
                       tol: Array) -> Array:
    """From p_i = (xi, yi) (mask mki) over the points given as per-point scalars x, y, mk
    (stop-gradient; the loops are unrolled at trace time): the far end j of the support
    line through p_i, and whether that line supports the points. Three passes, none with
    tie rules:
    1. the most clockwise other point (`_most_clockwise`): its offset e runs along the
       hull edge from p_i when p_i is on the hull's boundary;
    2. the support value h = max_k u . p_k of u = (e_y, -e_x) (|e| times the outward
       normal): the line supports the points when p_i is within `tol` of it, h - u . p_i
       <= tol |e| (every masked point left of the line or within `tol` of it);
    3. among the points within `tol` of that line, the farthest along e (ties keep the
       first): the end of the maximal edge.
    A point in the middle of a hull edge passes too; `small_hull_edges` keeps only the
    lines from hull vertices (the successors of supporting points). Returns j where the
    line supports the points, else -1.

    `i` is a point's index (int; xi, yi, mki its scalars), or `jnp.arange(N)` with xi, yi,
    mki the (N,) arrays of every point: then every point's passes at once, O(N)
    operations on N-vectors instead of O(N^2) on scalars."""
    skip = i if isinstance(i, int) else None
    ex, ey, found = _most_clockwise(xi, yi, x, y, tol * tol, mk, skip)
    low = jnp.asarray(-jnp.finfo(xi.dtype).max, xi.dtype)
    s = [jnp.where(mk[k], ey * x[k] - ex * y[k], low) for k in range(len(x))]
    h = functools.reduce(jnp.maximum, s)
    band = tol * jnp.sqrt(ex * ex + ey * ey)
    supports = mki & found & (h - (ey * xi - ex * yi) <= band)
    on_line = h - band
    j, best = jnp.asarray(i), ex * xi + ey * yi
    for k in (k for k in range(len(x)) if k != skip):
        along = ex * x[k] + ey * y[k]
        better = (s[k] >= on_line) & (along > best)
        j, best = jnp.where(better, k, j), jnp.where(better, along, best)
    return jnp.where(supports, j, -1)


def _support_directions(xi: Array, yi: Array, x: list[Array], y: list[Array], tol2: Array,
                        skip: int | None = None) -> tuple[Array, Array, Array, Array]:
    """For point(s) p_i = (xi, yi) (scalars, or N-vectors of every point at once): the
    most clockwise other point's offset e = p_j - p_i (`_most_clockwise`), whether one
    was found, and the support value h = max_k u . p_k of the outward unit normal u = (e_y,
    -e_x) / |e| over the points x, y (per-point scalars; the loops are unrolled at trace
    time; `skip` leaves out p_i itself in the scalar form). From a hull vertex e runs
    along its counter-clockwise hull edge; from any other point it is a line whose h is
    only larger (see `_support_distance`). Returns (e_x, e_y, found, h)."""
    ex, ey, found = _most_clockwise(xi, yi, x, y, tol2, skip=skip)
    inv = jax.lax.rsqrt(jnp.where(found, ex * ex + ey * ey, 1.0))
    ux, uy = ey * inv, -ex * inv
    h = ux * x[0] + uy * y[0]
    for k in range(1, len(x)):
        h = jnp.maximum(h, ux * x[k] + uy * y[k])
    return ex, ey, found, h


def _support_distance(q: Array, points: Array, mask: Array, unrolled: bool) -> tuple[Array, Array, Array]:
    """`hull_signed_distance` and its gradients (w.r.t. q (2,) and points (N, 2)) as the
    smallest support gap min_u h(u) - u . q over a few unit directions u, with h(u) =
    max_k u . p_k the hull's support function.

    For every unit u, h(u) - u . q is at least the signed distance from q to the hull's
    boundary (inside: the distance to the nearest supporting line; outside: minus the
    distance to the hull, by the separating line), with equality at the outward normal of
    the nearest edge, or outside a vertex at the unit vector from that vertex to q. So
    the candidates are each point's gift-wrap direction (`_support_directions`: from a
    hull vertex, its edge's normal; from an interior point an extra direction that cannot
    win) and the direction from the nearest point to q (outside a vertex, that vertex is
    the nearest point). Unlike `_hull_edges_all_pairs` nothing has to be verified as a
    hull edge, and collinear or repeated points need no tie rules: O(N^2) work in about
    20 operations per pair instead of 45. Masked rows are replaced by copies of the
    nearest point (they change no support value).

    `unrolled`: per-point scalars (O(N^2) operations: fastest up to UNROLL_MAX_POINTS,
    slow to compile beyond); otherwise every point's step on N-vectors at once (O(N)
    operations on N-vectors). A collinear set has both normals of its line: nothing is
    inside it; a single point gives minus the distance to it; no point -inf.
    Gradients: those of the winning line's distance (inside or outside an edge: the line
    through p_i and its direction's end p_j, foot parameter t) or of the distance to the
    nearest point; the choice itself is not differentiated."""
    n = points.shape[0]
    dt = points.dtype
    big = jnp.asarray(jnp.finfo(dt).max, dt)
    tol = jax.lax.stop_gradient(_tolerance(points, mask))
    rel = jax.lax.stop_gradient(points - q[None, :])  # q at the origin; gradients by the closed forms
    rows = jnp.arange(n)

    def pick(index, values):  # values[index] as a masked sum (no gather)
        return jnp.sum(jnp.where(rows == index, values, 0), axis=-1)

    r2 = jnp.where(mask, rel[:, 0] * rel[:, 0] + rel[:, 1] * rel[:, 1], big)
    near = jnp.argmin(r2)
    near_x, near_y = pick(near, rel[:, 0]), pick(near, rel[:, 1])
    px, py = jnp.where(mask, rel[:, 0], near_x), jnp.where(mask, rel[:, 1], near_y)
    x, y = [px[k] for k in range(n)], [py[k] for k in range(n)]
    if unrolled:
        steps = [_support_directions(x[i], y[i], x, y, tol * tol, skip=i) for i in range(n)]
        ex, ey, found, h = (jnp.stack(column) for column in zip(*steps))
    else:
        ex, ey, found, h = _support_directions(px, py, x, y, tol * tol)
    h = jnp.where(mask & found, h, big)
    edge = jnp.argmin(h)
    # the nearest point's direction: u = (q - p) / |q - p|; q on a point: no direction
    # (an edge through it gives 0 when it is on the boundary; alone it is the distance 0)
    d_near = jnp.sqrt(jnp.min(r2))
    on_point = d_near == 0
    wx, wy = -near_x / jnp.where(on_point, 1.0, d_near), -near_y / jnp.where(on_point, 1.0, d_near)
    h_near = jnp.max(wx * px + wy * py)
    h_near = jnp.where(on_point, jnp.where(jnp.any(mask & found), big, 0.0), h_near)
    by_edge = jnp.min(h) <= h_near
    # the winner's unit direction s (outward normal or from the point to q), its line's
    # endpoints i, j and foot parameter t: value = s . (p_i - q) at t = 0 ... 1
    ei_x, ei_y, xi, yi = pick(edge, ex), pick(edge, ey), pick(edge, px), pick(edge, py)
    e2 = jnp.where(by_edge, ei_x * ei_x + ei_y * ei_y, 1.0)
    inv = jax.lax.rsqrt(e2)
    s = jnp.where(by_edge, jnp.stack([ei_y * inv, -ei_x * inv]), jnp.stack([wx, wy]))
    far = jnp.argmin(jnp.where(mask, (px - xi - ei_x) ** 2 + (py - yi - ei_y) ** 2, big))  # p_j = p_i + e
    i, j = jnp.where(by_edge, edge, near), jnp.where(by_edge, far, near)
    t = jnp.where(by_edge, -(xi * ei_x + yi * ei_y) / e2, 0.0)
    live = jnp.any(mask)
    value = jnp.where(live, jnp.minimum(jnp.min(h), h_near), -jnp.inf)
    g_p = ((rows == i).astype(dt)[:, None] * ((1.0 - t) * s)[None, :]
           + (rows == j).astype(dt)[:, None] * (t * s)[None, :])
    return value, jnp.where(live, -s, 0.0), jnp.where(live, g_p, 0.0)


def small_hull_edges(points: Array, mask: Array) -> tuple[Array, Array]:
    """The counter-clockwise hull edges of the masked 2D points as successors: (succ (N,)
    int, edge (N,) bool), edge[i] when p_i -> p_succ[i] is a maximal hull edge (the edges
    of `hull_edges`, one per hull vertex; of repeated points the first copy). O(N^2): the
    passes of `_maximal_successor` from every point, on per-point scalars up to
    UNROLL_MAX_POINTS points, on N-vectors beyond. An edge's start must itself be the
    successor of a supporting point: that drops the lines from points in the middle of an
    edge and from later copies of a vertex, with no duplicate or tie test. The selection
    is piecewise constant (no gradient)."""
    n = points.shape[0]
    if n == 0:
        return jnp.zeros((0,), jnp.int32), jnp.zeros((0,), bool)
    p = jax.lax.stop_gradient(points)
    tol = _tolerance(p, mask)
    mk = [mask[k] for k in range(n)]
    if n > UNROLL_MAX_POINTS:
        # the coordinates as their own (N,) arrays: read from the (N, 2) or (N, 3) rows
        # inside the passes' fused loop they cost 1.6x at 16 points (NESM 1.7e6 -> 2.6e6/s)
        px, py = jax.lax.optimization_barrier((p[:, 0], p[:, 1]))
        x, y = [px[k] for k in range(n)], [py[k] for k in range(n)]
        ends = _maximal_successor(jnp.arange(n), px, py, mask, x, y, mk, tol)
    else:  # scalars read straight from the rows (slices of a barrier's arrays cost here)
        x, y = [p[k, 0] for k in range(n)], [p[k, 1] for k in range(n)]
        ends = jnp.stack([_maximal_successor(i, x[i], y[i], mk[i], x, y, mk, tol) for i in range(n)])
    # One array out of the passes, so that XLA computes them once (with two outputs it
    # fused the passes into each consumer: 2.5x the work at 8 points). The successors
    # marked by a scatter: compares of every row against every end ran 5x slower at 8.
    vertex = jnp.zeros(n, bool).at[jnp.where(ends >= 0, ends, n)].set(True, mode="drop")  # -1 would wrap
    edge = (ends >= 0) & vertex
    rows = jnp.arange(n)
    return jnp.where(edge, ends, rows), edge


def _with_closed_form_jvp(distance: Callable[[Array, Array, Array], tuple[Array, Array, Array]]):
    """`hull_signed_distance` by `distance` (`_support_distance`, unrolled or not),
    with the closed-form derivative of the distance to the nearest edge's line (inside)
    or nearest edge point (outside) that `distance` returns: exact between changes of the
    nearest edge, zero for masked and interior points, O(N) to evaluate; the selection
    itself is never differentiated."""

    @jax.custom_jvp
    def signed_distance(q: Array, points: Array, mask: Array) -> Array:
        return distance(q, points, mask)[0]

    @signed_distance.defjvp
    def signed_distance_jvp(primals, tangents):
        q, points, mask = primals
        dq, dp, _ = tangents
        value, g_q, g_p = distance(q, points, mask)
        return value, jnp.dot(g_q, dq) + jnp.sum(g_p * dp)

    return signed_distance


_hull_signed_distance_unrolled = _with_closed_form_jvp(functools.partial(_support_distance, unrolled=True))
_hull_signed_distance_vectorized = _with_closed_form_jvp(functools.partial(_support_distance, unrolled=False))


# Up to this many points `hull_signed_distance` (and `small_hull_edges`) run on per-point
# scalars (`_support_distance(unrolled=True)`: 3.2e7 margins/s at 4 points, 1.6e7 at 6,
# against 2.1e7 and 6.2e6 on N-vectors; float64, batch 1e5 on 2 cores; the program grows
# with N^2), beyond on N-vectors (3.2e6 at 16; the all-pairs form 3.0e4). Default (ours).
# The maximal edges themselves (`small_hull_edges`, for the NESM and the longitudinal
# margin): 3.8e7 per s at 4 points (unrolled), 0.9e7-1.35e7 at 8 and 3.1e6-3.6e6 at 16
# (N-vectors; the verified gift-wrap until 5 Dec 2026: 1.2e7, 6.4e6 and 1.8e6).
UNROLL_MAX_POINTS = 6


def hull_signed_distance(q: Array, points: Array, mask: Array) -> Array:
    """Signed distance from 2D point q to the boundary of the convex hull of the masked
    points: positive inside, negative outside (minus the distance to the hull). A
    segment or a single point gives <= 0; no points gives -inf. Gradients flow through
    the coordinates of the nearest edge or point; masked and interior points get none.
    O(N^2): the smallest support gap over each point's gift-wrap direction and the
    nearest point's (`_support_distance`), on per-point scalars up to UNROLL_MAX_POINTS
    points, on N-vectors beyond (`_hull_signed_distance_all_pairs`, O(N^3), gives the
    same values)."""
    n = points.shape[0]
    if n == 0:
        return jnp.asarray(-jnp.inf, points.dtype)
    if n <= UNROLL_MAX_POINTS:
        return _hull_signed_distance_unrolled(q, points, mask)
    return _hull_signed_distance_vectorized(q, points, mask)


def _edges_signed_distance(q: Array, points: Array, mask: Array, E: Array) -> Array:
    """Signed distance of q to the boundary of the hull given by edge matrix E."""
    a = points[:, None, :]
    b = points[None, :, :]
    seg = jax.vmap(jax.vmap(point_segment_distance, (None, 0, 0)), (None, 0, 0))(
        q, jnp.broadcast_to(a, E.shape + (2,)), jnp.broadcast_to(b, E.shape + (2,))
    )
    big = jnp.asarray(jnp.finfo(points.dtype).max, points.dtype)
    d = jnp.min(jnp.where(E, seg, big))
    side = cross2(b - a, q[None, None, :] - a)
    # a segment (collinear points: < 3 hull vertices) has no inside, even on its line
    inside = jnp.all(jnp.where(E, side >= 0, True)) & (jnp.sum(jnp.any(E, axis=1)) >= 3)
    has_edges = jnp.any(E)
    # a single point: distance to it, never inside
    m = unique_mask(points, mask)
    single = jnp.sum(m) == 1
    d_point = _safe_norm(q - points[jnp.argmax(m)])
    return jnp.where(
        has_edges, jnp.where(inside, d, -d), jnp.where(single, -d_point, -jnp.inf)
    )


def _hull_signed_distance_all_pairs(q: Array, points: Array, mask: Array) -> Array:
    """`hull_signed_distance` from the all-pairs edge matrix (`_hull_edges_all_pairs`,
    O(N^3)): the reference the O(N^2) forms are tested against (autodiff gradients)."""
    return _edges_signed_distance(q, points, mask, _hull_edges_all_pairs(points, mask))


def convex_hull(points: Array, mask: Array) -> tuple[Array, Array]:
    """Convex hull of masked 2D points (N, 2): (vertices (N, 2), valid (N,)). Valid
    vertices come first, counter-clockwise; the rest repeat the first vertex."""
    E = hull_edges(points, mask)
    m = unique_mask(points, mask)
    is_vertex = jnp.any(E, axis=1) | (m & (jnp.sum(m) == 1))
    n_v = jnp.sum(is_vertex)
    w = is_vertex.astype(points.dtype)
    centre = jnp.sum(jnp.where(is_vertex[:, None], points, 0.0), axis=0) / jnp.maximum(jnp.sum(w), 1.0)
    rel = jax.lax.stop_gradient(points - centre)
    angle = jnp.arctan2(rel[:, 1], rel[:, 0])
    key = jnp.where(is_vertex, angle, jnp.inf)
    order = jnp.argsort(key)
    verts = points[order]
    valid = jnp.arange(points.shape[0]) < n_v
    verts = jnp.where(valid[:, None], verts, verts[0])
    return verts, valid


def polygon_edges(vertices: Array, valid: Array) -> tuple[Array, Array, Array]:
    """Edges (start, end, edge_valid) of a compacted CCW polygon from `convex_hull`."""
    n = jnp.sum(valid)
    idx = jnp.arange(vertices.shape[0])
    nxt = jnp.where(idx + 1 < n, idx + 1, 0)
    return vertices, vertices[nxt], valid


def polygon_signed_distance(q: Array, vertices: Array, valid: Array) -> Array:
    """Signed distance of q to a compacted CCW convex polygon (positive inside)."""
    a, b, ev = polygon_edges(vertices, valid)
    seg = jax.vmap(point_segment_distance, (None, 0, 0))(q, a, b)
    big = jnp.asarray(jnp.finfo(vertices.dtype).max, vertices.dtype)
    d = jnp.min(jnp.where(ev, seg, big))
    inside = jnp.all(jnp.where(ev, cross2(b - a, q - a) >= 0, True)) & (jnp.sum(valid) >= 3)
    return jnp.where(jnp.any(valid), jnp.where(inside, d, -d), -jnp.inf)


def polygon_area(vertices: Array, valid: Array) -> Array:
    """Area of a compacted CCW polygon (shoelace formula)."""
    a, b, ev = polygon_edges(vertices, valid)
    return 0.5 * jnp.sum(jnp.where(ev, cross2(a, b), 0.0))


def halfplane_polygon(normals: Array, offsets: Array, mask: Array | None = None) -> tuple[Array, Array]:
    """The bounded convex polygon {x : n_k . x <= c_k for all masked k} as
    (vertices (K*(K-1)/2, 2), valid), CCW and compacted. Vertices are the pairwise line
    intersections that satisfy every constraint; an empty set has no valid vertices.
    The caller guarantees boundedness (e.g. with box constraints)."""
    K = normals.shape[0]
    mask = jnp.ones(K, bool) if mask is None else mask
    ii, jj = jnp.triu_indices(K, k=1)
    n1, n2 = normals[ii], normals[jj]
    det = cross2(n1, n2)
    scale = 1.0 + jnp.max(jnp.abs(offsets))
    tol = 1e3 * jnp.finfo(normals.dtype).eps * scale
    ok_det = jnp.abs(det) > 1e3 * jnp.finfo(normals.dtype).eps
    sdet = jnp.where(ok_det, det, 1.0)
    # solve [n1; n2] x = [c1; c2] by Cramer's rule
    x = (offsets[ii] * n2[:, 1] - offsets[jj] * n1[:, 1]) / sdet
    y = (n1[:, 0] * offsets[jj] - n2[:, 0] * offsets[ii]) / sdet
    pts = jnp.stack([x, y], axis=1)
    viol = pts @ normals.T - offsets[None, :]
    feasible = jnp.all(jnp.where(mask[None, :], viol <= tol, True), axis=1)
    cand = ok_det & mask[ii] & mask[jj] & feasible
    return convex_hull(pts, cand)


# ------------------------------------------------------------------------ soft minimum
def soft_min(x: Array, temperature: Array, mask: Array | None = None, axis: int = -1) -> Array:
    """Smooth lower bound of min(x): -T log sum exp(-x / T) over masked entries.

    For tuning by gradient: it is differentiable everywhere, <= the true minimum, and
    within T log(n) of it. Gradients of masked-out entries are exactly zero."""
    mask = jnp.ones(x.shape, bool) if mask is None else mask
    m = jax.lax.stop_gradient(jnp.min(jnp.where(mask, x, jnp.inf), axis=axis, keepdims=True))
    m = jnp.where(jnp.isfinite(m), m, 0.0)
    z = jnp.where(mask, (x - m) / temperature, 0.0)
    s = jnp.sum(jnp.where(mask, jnp.exp(-z), 0.0), axis=axis)
    return jnp.squeeze(m, axis) - temperature * jnp.log(s)
