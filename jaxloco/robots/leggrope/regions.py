"""Admissible regions of the leg-grope walk (paper Eqs. 2-10, Table 2, Figs. 3-4), on the
horizontal plane O_G-x_G y_G, as masked fixed-size convex polygons (see `geometry`).

All inputs are 2D projected points p (2,) [m] and normalized grope forces
h_ref^n = f_ref^n / (M g) = R_ref / (M g cos theta_n) (dimensionless).

Derivation used here (the paper's static equilibrium with vertical leg forces):
  * pi_g(Li, Lj, Lk) (Eqs. 4-6): p_g = h_i p_i + h_j p_j + h_k p_k with
    0 <= h_n <= h_ref^n and h_i + h_j + h_k = 1. A convex polygon, the image of a
    polygon in the (h_i, h_j) plane; its 8 shapes are Table 2a's patterns.
  * pi_grp,g(Li, Lj, Lgrp) for a fixed COG, L_k floating (Eqs. 7-10): with
    a = h^_i / h_grp and b = h^_j / h_grp,  p_grp = p_g + a (p_g - p_i) + b (p_g - p_j).
    The conditions of Eq. 8 are, exactly,
        a >= 0, b >= 0,
        a + b <= 1 / h_ref^grp - 1                 (h_grp >= h_ref^grp),
        a (1 - h_ref^i) - h_ref^i b <= h_ref^i      (h^_i <= h_ref^i),
        b (1 - h_ref^j) - h_ref^j a <= h_ref^j      (h^_j <= h_ref^j).
    The paper's printed Eq. 10 (a <= h_ref^i / h_ref^grp, b <= h_ref^j / h_ref^grp)
    drops the first of these and replaces the others by a weaker bound: it is
    necessary, not sufficient, for Eq. 8. We use the exact set. Both give the same
    pattern classification (Table 2b: h_ref^i + h_ref^grp vs 1) and coincide in the
    paper's special case h_ref = 1/2 (a triangle congruent to p_g p_i p_j).
  * pi_grp(Li, Lj, Lgrp), float leg L_k: the union over p_g in pi_g of the above.
    For fixed (a, b) the map p_g -> (1 + a + b) p_g - a p_i - b p_j is affine, and
    the union is the convex hull of the images of all vertex pairs (a proof by
    convex combination is in tests/test_leggrope_regions.py).
  * pi_grp,all: the union of pi_grp over the three choices of float leg (three convex
    polygons; in the h_ref = 1/2 case the union is the triangle whose medial triangle
    is p_i p_j p_k).
  * `grope_feasible_region` (ours, used by the planner): for a fixed COG, the set of
    groping-leg positions where the leg presses with exactly h_ref^grp while the three
    other legs stay within [0, h_ref^n] -- what step D needs. It is one convex polygon,
    (p_g - W) / h_ref^grp with W = {sum h_n p_n : 0 <= h_n <= h_ref^n, sum h_n =
    1 - h_ref^grp}. It contains the union of pi_grp,g over the float legs whenever p_g
    is in pi_g (interpolate with the three-leg solution), and for h_ref = 1/2 equals it:
    the reflection 2 p_g - triangle(p_i, p_j, p_k).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxloco import geometry as geo

Array = jax.Array


# ----------------------------------------------------------------------- pattern labels
def cog_region_pattern(h_i: Array, h_j: Array, h_k: Array) -> Array:
    """Table 2a pattern number 1..8 of pi_g for the given h_ref values."""
    a = (h_i + h_j > 1).astype(jnp.int32)
    b = (h_j + h_k > 1).astype(jnp.int32)
    c = (h_k + h_i > 1).astype(jnp.int32)
    table = jnp.array([1, 4, 3, 7, 2, 6, 5, 8])  # index = 4a + 2b + c
    return table[4 * a + 2 * b + c]


def groping_region_pattern(h_i: Array, h_j: Array, h_grp: Array) -> Array:
    """Table 2b pattern number 1..4 of pi_grp,g for the given h_ref values."""
    a = (h_i + h_grp >= 1).astype(jnp.int32)
    b = (h_j + h_grp >= 1).astype(jnp.int32)
    return jnp.array([1, 3, 2, 4])[2 * a + b]


# ------------------------------------------------------------------- parameter polygons
def _cog_weights_polygon(h_i: Array, h_j: Array, h_k: Array) -> tuple[Array, Array]:
    """Polygon of admissible (h_i, h_j) (Eq. 5) in the weight plane."""
    return _support_weights_polygon(h_i, h_j, h_k, jnp.ones_like(h_i))


def _grope_weights_polygon(h_i: Array, h_j: Array, h_grp: Array) -> tuple[Array, Array]:
    """Polygon of admissible (a, b) = (h^_i, h^_j) / h_grp (exact form of Eqs. 8-10)."""
    zero = jnp.zeros_like(h_i)
    normals = jnp.stack(
        [
            jnp.stack([-jnp.ones_like(h_i), zero]),
            jnp.stack([zero, -jnp.ones_like(h_i)]),
            jnp.stack([jnp.ones_like(h_i), jnp.ones_like(h_i)]),
            jnp.stack([1.0 - h_i, -h_i]),
            jnp.stack([-h_j, 1.0 - h_j]),
        ]
    )
    offsets = jnp.stack([zero, zero, 1.0 / h_grp - 1.0, h_i, h_j])
    return geo.halfplane_polygon(normals, offsets)


# ----------------------------------------------------------------------------- regions
def cog_region(p_i, p_j, p_k, h_i, h_j, h_k) -> tuple[Array, Array]:
    """pi_g(Li, Lj, Lk): admissible projected COG positions on three legs (Eqs. 2-6).
    Returns (vertices (15, 2), valid) CCW."""
    w, valid = _cog_weights_polygon(h_i, h_j, h_k)
    pts = w[:, :1] * p_i + w[:, 1:] * p_j + (1.0 - w[:, :1] - w[:, 1:]) * p_k
    return geo.convex_hull(pts, valid)


def groping_region_fixed_cog(p_g, p_i, p_j, h_i, h_j, h_grp) -> tuple[Array, Array]:
    """pi_grp,g(Li, Lj, Lgrp): where the groping leg can press with h >= h_ref^grp while
    L_i, L_j stay within their h_ref and the third stance leg floats (Eqs. 7-10)."""
    ab, valid = _grope_weights_polygon(h_i, h_j, h_grp)
    pts = (1.0 + ab[:, :1] + ab[:, 1:]) * p_g - ab[:, :1] * p_i - ab[:, 1:] * p_j
    return geo.convex_hull(pts, valid)


def groping_region(p_i, p_j, p_k, h_i, h_j, h_k, h_grp) -> tuple[Array, Array]:
    """pi_grp(Li, Lj, Lgrp) with float leg L_k: union over every admissible COG."""
    cog_v, cog_ok = cog_region(p_i, p_j, p_k, h_i, h_j, h_k)
    ab, ab_ok = _grope_weights_polygon(h_i, h_j, h_grp)
    # both polygons come compacted (valid vertices first): pi_g has at most 6 vertices
    # (Table 2a, pattern 8) and the (a, b) polygon at most 5 (Table 2b, pattern 1)
    cog_v, cog_ok, ab, ab_ok = cog_v[:6], cog_ok[:6], ab[:5], ab_ok[:5]
    scale = 1.0 + ab[:, 0] + ab[:, 1]  # (A,)
    pts = scale[:, None, None] * cog_v[None, :, :] - ab[:, None, :1] * p_i - ab[:, None, 1:] * p_j
    ok = ab_ok[:, None] & cog_ok[None, :]
    return geo.convex_hull(pts.reshape(-1, 2), ok.reshape(-1))


def _rotations(p: Array, h: Array) -> tuple[Array, Array]:
    """The three (i, j, float k) assignments of three stance legs, as stacked arrays."""
    idx = jnp.array([[0, 1, 2], [1, 2, 0], [2, 0, 1]])  # float leg = last column
    return p[idx], h[idx]


def groping_region_all(stance: Array, h_stance: Array, h_grp: Array) -> tuple[Array, Array]:
    """pi_grp,all for the three stance legs `stance` (3, 2) with h_ref `h_stance` (3,):
    the three pi_grp polygons (float leg = stance[2], stance[0], stance[1]) stacked as
    (3, V, 2) vertices and (3, V) validity. Their union is the region."""
    P, H = _rotations(stance, h_stance)
    f = lambda p, h: groping_region(p[0], p[1], p[2], h[0], h[1], h[2], h_grp)  # noqa: E731
    return jax.vmap(f)(P, H)


def groping_regions_fixed_cog(p_g: Array, stance: Array, h_stance: Array, h_grp: Array) -> tuple[Array, Array]:
    """pi_grp,g for the three choices of float leg (stance[2], stance[0], stance[1]),
    stacked (3, V, 2) and (3, V)."""
    P, H = _rotations(stance, h_stance)
    f = lambda p, h: groping_region_fixed_cog(p_g, p[0], p[1], h[0], h[1], h_grp)  # noqa: E731
    return jax.vmap(f)(P, H)


def _support_weights_polygon(h_i: Array, h_j: Array, h_k: Array, total: Array) -> tuple[Array, Array]:
    """Polygon of (h_i, h_j) with 0 <= h_n <= h_ref^n and h_i + h_j + h_k = total."""
    zero = jnp.zeros_like(h_i)
    normals = jnp.array([[-1.0, 0.0], [1.0, 0.0], [0.0, -1.0], [0.0, 1.0], [1.0, 1.0], [-1.0, -1.0]], h_i.dtype)
    offsets = jnp.stack([zero, h_i, zero, h_j, total, h_k - total])
    return geo.halfplane_polygon(normals, offsets)


def grope_feasible_region(p_g: Array, stance: Array, h_stance: Array, h_grp: Array) -> tuple[Array, Array]:
    """Where the groping leg can press with exactly h_grp (normalized) while the COG is at
    p_g and the three stance legs `stance` (3, 2) stay within [0, h_stance]: the convex
    polygon (p_g - W) / h_grp (see module docstring). Vertices (15, 2), CCW."""
    w, ok = _support_weights_polygon(h_stance[0], h_stance[1], h_stance[2], 1.0 - h_grp)
    W = w[:, :1] * stance[0] + w[:, 1:] * stance[1] + (1.0 - h_grp - w[:, :1] - w[:, 1:]) * stance[2]
    return geo.convex_hull((p_g - W) / h_grp, ok)


def union_signed_distance(q: Array, vertices: Array, valid: Array) -> Array:
    """Signed distance of q into a union of convex polygons (K, V, 2): the largest of the
    per-polygon signed distances (exact inside; outside, minus the distance to the
    nearest polygon)."""
    d = jax.vmap(geo.polygon_signed_distance, (None, 0, 0))(q, vertices, valid)
    return jnp.max(d)
