"""Admissible regions (paper Eqs. 2-10, Table 2, Figs. 3-4): the h_ref = 1/2 special
case exactly, the Table 2 patterns, exactness of the groping region against Eq. 8
solved pointwise, and the union identities used by the planner."""

from types import SimpleNamespace

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxloco import geometry as geo
from jaxloco.robots.leggrope import regions

PI, PJ, PK = jnp.array([0.0, 0.0]), jnp.array([1.0, 0.0]), jnp.array([0.3, 1.0])
HALF = jnp.asarray(0.5)
# distances of many points at once (one compiled call instead of op-by-op loops)
poly_dist = jax.jit(jax.vmap(geo.polygon_signed_distance, (0, None, None)))
union_dist = jax.jit(jax.vmap(regions.union_signed_distance, (0, None, None)))
# the regions jitted: one program per function and shape (run op by op, these tests
# compiled ~1,300 one-operation programs, ~20 ms each in a new process)
J = SimpleNamespace(**{name: jax.jit(getattr(regions, name)) for name in (
    "cog_region", "cog_region_pattern", "grope_feasible_region", "groping_region", "groping_region_all",
    "groping_region_fixed_cog", "groping_region_pattern", "groping_regions_fixed_cog", "_grope_weights_polygon")},
    convex_hull=jax.jit(geo.convex_hull))


def _same_polygon(vertices, valid, expected):
    got = np.asarray(vertices)[np.asarray(valid)]
    assert len(got) == len(expected)
    for e in expected:
        assert np.min(np.linalg.norm(got - np.asarray(e), axis=1)) < 1e-12, (got, e)


def test_cog_region_half_is_medial_triangle():
    v, ok = J.cog_region(PI, PJ, PK, HALF, HALF, HALF)
    _same_polygon(v, ok, [(PI + PJ) / 2, (PJ + PK) / 2, (PK + PI) / 2])


def test_groping_region_fixed_cog_half_is_congruent_triangle():
    pg = jnp.array([0.45, 0.3])
    v, ok = J.groping_region_fixed_cog(pg, PI, PJ, HALF, HALF, HALF)
    # congruent to triangle (p_g, p_i, p_j): its point reflection through p_g (Fig. 4b)
    _same_polygon(v, ok, [pg, 2 * pg - PI, 2 * pg - PJ])


def test_groping_region_half_is_trapezoid_and_union_is_antimedial_triangle():
    v, ok = J.groping_region(PI, PJ, PK, HALF, HALF, HALF, HALF)
    _same_polygon(v, ok, [PI, PJ, PK + PI - PJ, PK + PJ - PI])  # Fig. 4c
    V, OK = J.groping_region_all(jnp.stack([PI, PJ, PK]), jnp.full(3, 0.5), HALF)
    anti = np.array([PJ + PK - PI, PK + PI - PJ, PI + PJ - PK])  # Fig. 4d
    rng = np.random.default_rng(1)
    pts = rng.uniform(-1.5, 2.5, (400, 2))
    in_union = np.asarray(union_dist(jnp.asarray(pts), V, OK)) > 1e-9
    tri_v, tri_ok = J.convex_hull(jnp.asarray(anti), jnp.ones(3, bool))
    in_anti = np.asarray(poly_dist(jnp.asarray(pts), tri_v, tri_ok)) > 1e-9
    assert in_union.sum() > 20
    np.testing.assert_array_equal(in_union, in_anti)


@pytest.mark.parametrize(
    "h, pattern, n_vertices",
    [
        ((0.4, 0.4, 0.4), 1, 3),
        ((0.7, 0.4, 0.2), 2, 4),
        ((0.2, 0.7, 0.4), 3, 4),
        ((0.4, 0.2, 0.7), 4, 4),
        ((0.45, 0.7, 0.5), 5, 5),
        ((0.7, 0.35, 0.5), 6, 5),
        ((0.5, 0.45, 0.7), 7, 5),
        ((0.7, 0.7, 0.7), 8, 6),
    ],
)
def test_table2a_patterns(h, pattern, n_vertices):
    h = tuple(jnp.asarray(x) for x in h)
    assert int(J.cog_region_pattern(*h)) == pattern
    _, ok = J.cog_region(PI, PJ, PK, *h)
    assert int(jnp.sum(ok)) == n_vertices


@pytest.mark.parametrize(
    "h, pattern, n_vertices",
    [((0.3, 0.3, 0.5), 1, 5), ((0.6, 0.3, 0.5), 2, 4), ((0.3, 0.6, 0.5), 3, 4), ((0.6, 0.6, 0.5), 4, 3)],
)
def test_table2b_patterns(h, pattern, n_vertices):
    h = tuple(jnp.asarray(x) for x in h)
    assert int(J.groping_region_pattern(*h)) == pattern
    _, ok = J.groping_region_fixed_cog(jnp.array([0.45, 0.3]), PI, PJ, *h)
    assert int(jnp.sum(ok)) == n_vertices


def _eq8_weights(p_grp, p_g, p_i, p_j):
    """Solve Eq. 7 for (h^_i, h^_j, h_grp) given the positions (3 unknowns, 3 equations)."""
    M = np.array([[1.0, 1.0, 1.0], [p_i[0], p_j[0], p_grp[0]], [p_i[1], p_j[1], p_grp[1]]])
    return np.linalg.solve(M, np.array([1.0, p_g[0], p_g[1]]))


@pytest.mark.parametrize("h", [(0.3, 0.3, 0.5), (0.6, 0.3, 0.5), (0.45, 0.55, 0.4), (0.5, 0.5, 0.5)])
def test_groping_region_is_exactly_eq8(h):
    """Inside the polygon <=> the weights of Eq. 7 satisfy Eq. 8 (checked pointwise)."""
    hi, hj, hg = h
    pg = jnp.array([0.45, 0.3])
    v, ok = J.groping_region_fixed_cog(pg, PI, PJ, *map(jnp.asarray, h))
    rng = np.random.default_rng(2)
    inside_count = 0
    pts = np.asarray(v)[np.asarray(ok)]
    lo, hi_ = pts.min(axis=0) - 0.3, pts.max(axis=0) + 0.3
    samples = rng.uniform(lo, hi_, (600, 2))
    for p, d in zip(samples, np.asarray(poly_dist(jnp.asarray(samples), v, ok))):
        if abs(d) < 1e-6:
            continue
        wi, wj, wg = _eq8_weights(p, np.asarray(pg), np.asarray(PI), np.asarray(PJ))
        eq8 = (hg <= wg < 1) and (0 < wi <= hi) and (0 < wj <= hj)
        assert eq8 == (d > 0), (p, d, wi, wj, wg)
        inside_count += d > 0
    assert inside_count > 10


def test_printed_eq10_is_only_a_relaxation():
    """A point satisfying the paper's printed Eq. 10 bounds but violating Eq. 8: the
    exact region (ours) excludes it."""
    hi, hj, hg = 0.3, 0.3, 0.5
    pg = np.array([0.45, 0.3])
    a, b = 0.55, 0.05  # a <= h_i / h_grp = 0.6 (printed Eq. 10) ...
    p = (1 + a + b) * pg - a * np.asarray(PI) - b * np.asarray(PJ)
    wi, _, wg = _eq8_weights(p, pg, np.asarray(PI), np.asarray(PJ))
    assert wi > hi  # ... but h^_i = a h_grp exceeds h_ref^i: Eq. 8 is violated
    v, ok = J.groping_region_fixed_cog(jnp.asarray(pg), PI, PJ, *map(jnp.asarray, (hi, hj, hg)))
    assert float(geo.polygon_signed_distance(jnp.asarray(p), v, ok)) < 0


def test_grope_feasible_region_contains_union_and_equals_it_at_half():
    stance = jnp.stack([PI, PJ, PK])
    pg = jnp.array([0.45, 0.35])
    # h_ref = 1/2: reflection of the stance triangle through the COG
    v, ok = J.grope_feasible_region(pg, stance, jnp.full(3, 0.5), HALF)
    _same_polygon(v, ok, [2 * pg - PI, 2 * pg - PJ, 2 * pg - PK])
    # general h_ref: every point of some pi_grp,g is in the step-D region
    h = jnp.array([0.55, 0.45, 0.6])
    hg = jnp.asarray(0.45)
    Vf, OKf = J.groping_regions_fixed_cog(pg, stance, h, hg)
    vd, okd = J.grope_feasible_region(pg, stance, h, hg)
    rng = np.random.default_rng(3)
    pts = jnp.asarray(rng.uniform(-1.0, 2.0, (400, 2)))
    in_union = np.asarray(union_dist(pts, Vf, OKf)) > 1e-9
    assert in_union.sum() > 10
    assert (np.asarray(poly_dist(pts, vd, okd))[in_union] > -1e-9).all()


def test_groping_region_union_is_hull_of_vertex_images():
    """pi_grp (float leg k) equals the union over COGs in pi_g of pi_grp,g: every sampled
    (COG, a, b) image lies inside, and the polygon's vertices are attained."""
    h = tuple(jnp.asarray(x) for x in (0.55, 0.45, 0.6, 0.5))
    v, ok = J.groping_region(PI, PJ, PK, *h)
    cog_v, cog_ok = J.cog_region(PI, PJ, PK, *h[:3])
    ab_v, ab_ok = J._grope_weights_polygon(h[0], h[1], h[3])
    cv, av = np.asarray(cog_v)[np.asarray(cog_ok)], np.asarray(ab_v)[np.asarray(ab_ok)]
    rng = np.random.default_rng(4)
    c = rng.dirichlet(np.ones(len(cv)), 300) @ cv
    ab = rng.dirichlet(np.ones(len(av)), 300) @ av
    p = (1 + ab.sum(1, keepdims=True)) * c - ab[:, :1] * np.asarray(PI) - ab[:, 1:] * np.asarray(PJ)
    assert (np.asarray(poly_dist(jnp.asarray(p), v, ok)) > -1e-9).all()
