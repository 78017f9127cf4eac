"""Tests of jaxloco.geometry against independent oracles: SciPy's Rotation and ConvexHull
(Qhull), MuJoCo's own Euler conversion and forward kinematics, numpy least squares,
closed-form planar kinematics, dense sampling of polygon boundaries and hand-worked
numbers. Every jitted function is compiled once at module level and reused."""

from __future__ import annotations

import itertools

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from jax.test_util import check_grads
from scipy.spatial import ConvexHull
from scipy.spatial.transform import Rotation

from jaxloco import geometry as geo

HYP = settings(max_examples=40, deadline=None, derandomize=True)
N = 12  # fixed polygon size of every polygon test (one compilation per dtype)
Q = 16  # query points per polygon
BATCH = 16  # polygons per batched call (one compilation per dtype)


# ------------------------------------------------------------------ compiled kernels
def _poly_all(points, mask, queries):
    """Everything the polygon tests look at, for one masked point set."""
    E = geo.hull_edges(points, mask)
    verts, valid = geo.convex_hull(points, mask)
    return dict(
        E=E,
        verts=verts,
        valid=valid,
        area=geo.polygon_area(verts, valid),
        hsd=jax.vmap(geo.hull_signed_distance, (0, None, None))(queries, points, mask),
        psd=jax.vmap(geo.polygon_signed_distance, (0, None, None))(queries, verts, valid),
    )


POLY = jax.jit(_poly_all)
POLY_V = jax.jit(jax.vmap(_poly_all))
RPY_V = jax.jit(jax.vmap(geo.rpy_to_matrix))
M2RPY = jax.jit(geo.matrix_to_rpy)
DH_CHAIN = jax.jit(geo.dh_chain)
HALFPLANE = jax.jit(geo.halfplane_polygon)
AREA = jax.jit(geo.polygon_area)
PSD_V = jax.jit(jax.vmap(geo.polygon_signed_distance, (0, None, None)))
SOFT_MIN = jax.jit(geo.soft_min)
SOFT_MIN_GRAD = jax.jit(jax.grad(geo.soft_min))


# ----------------------------------------------------------------------- oracles/helpers
def _scipy_hull(pts: np.ndarray):
    """(CCW vertex coordinates, unit facet equations [n, c] with n.x + c <= 0, area)."""
    h = ConvexHull(pts)
    return pts[h.vertices], h.equations, h.volume


def _sampled_segment_distance(q: np.ndarray, a: np.ndarray, b: np.ndarray, n: int = 41, rounds: int = 6) -> float:
    """Distance from q to [a, b] by sampling: |q - (a + t (b - a))| is convex in t, so the
    best sample brackets the minimum; resample that bracket `rounds` times."""
    lo, hi = 0.0, 1.0
    for _ in range(rounds):
        t = np.linspace(lo, hi, n)
        dist = np.linalg.norm(a + t[:, None] * (b - a) - q, axis=1)
        k = int(np.argmin(dist))
        lo, hi = t[max(k - 1, 0)], t[min(k + 1, n - 1)]
    return float(dist[k])


def _oracle_signed_distance(q: np.ndarray, verts: np.ndarray, eqs: np.ndarray) -> tuple[float, float]:
    """(value, tolerance): exact from the facet equations inside, sampling of the
    boundary outside (with the lower bound of the most violated facet checked too)."""
    viol = eqs[:, :2] @ q + eqs[:, 2]
    if viol.max() <= 0:
        return -viol.max(), 1e-9
    sampled = min(_sampled_segment_distance(q, verts[k], verts[(k + 1) % len(verts)]) for k in range(len(verts)))
    assert sampled >= viol.max() - 1e-12  # the sampled distance respects the lower bound
    return -sampled, 1e-9


def _same_cycle(a: np.ndarray, b: np.ndarray, atol: float = 1e-12) -> bool:
    """True when the rows of a are the rows of b in the same cyclic order."""
    if a.shape != b.shape:
        return False
    return any(np.allclose(np.roll(a, -s, axis=0), b, atol=atol) for s in range(len(a)))


def _random_polygon_case(rng: np.random.Generator, dyadic: bool):
    """N rows: 3..9 real points (plus a duplicate and an exact mid-edge collinear
    point), masked rows filled with garbage, rows shuffled. Returns points, mask,
    the real points, and Q query points (random, hull vertices, mid-edges)."""
    n_real = int(rng.integers(3, 10))
    while True:
        if dyadic:
            real = rng.integers(-16, 17, size=(n_real, 2)) / 8.0
        else:
            real = rng.normal(size=(n_real, 2))
        real = np.unique(real, axis=0)
        if len(real) >= 3 and np.linalg.matrix_rank(real[1:] - real[0]) == 2:
            break
    hv, _, _ = _scipy_hull(real)
    extra = [real[int(rng.integers(len(real)))]]  # duplicate
    if dyadic:  # midpoints of dyadic points are exact: genuinely collinear
        extra.append(0.5 * (hv[0] + hv[1]))
    real = np.concatenate([real, np.array(extra)])
    pts = rng.uniform(-50.0, 50.0, size=(N, 2))  # garbage, far outside
    mask = np.zeros(N, bool)
    rows = rng.permutation(N)[: len(real)]
    pts[rows], mask[rows] = real, True
    qs = np.concatenate(
        [rng.uniform(-3.0, 3.0, size=(Q - 4, 2)), hv[:2], 0.5 * (hv[:2] + hv[1:3])]
    )
    return pts, mask, real, qs


def _batch(seed: int, count: int, dyadic: bool):
    rng = np.random.default_rng(seed)
    cases = [_random_polygon_case(rng, dyadic) for _ in range(count)]
    return [np.stack([c[k] for c in cases]) for k in (0, 1, 3)], [c[2] for c in cases]


def _pad(points, n=N, fill=7.0):
    points = np.asarray(points, float).reshape(-1, 2)
    out = np.full((n, 2), fill)
    out[: len(points)] = points
    mask = np.zeros(n, bool)
    mask[: len(points)] = True
    return out, mask


def _queries(*qs):
    qs = np.asarray(qs, float).reshape(-1, 2)
    return np.concatenate([qs, np.repeat(qs[-1:], Q - len(qs), axis=0)])


# ------------------------------------------------------------------------------ rotations
def test_rotations_orthonormal_and_match_scipy_and_mujoco():
    rng = np.random.default_rng(0)
    rpy = rng.uniform(-np.pi, np.pi, size=(32, 3))
    R = np.asarray(RPY_V(rpy[:, 0], rpy[:, 1], rpy[:, 2]))
    for (roll, pitch, yaw), Rk in zip(rpy, R):
        np.testing.assert_allclose(Rk @ Rk.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(Rk) == pytest.approx(1.0, abs=1e-12)
        # SciPy: intrinsic Z-Y'-X'' with angles (yaw, pitch, roll)
        ref = Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_matrix()
        np.testing.assert_allclose(Rk, ref, atol=1e-12)
        # MuJoCo: upper case = extrinsic (fixed axes) x, then y, then z
        quat, mat = np.zeros(4), np.zeros(9)
        mujoco.mju_euler2Quat(quat, np.array([roll, pitch, yaw]), "XYZ")
        mujoco.mju_quat2Mat(mat, quat)
        np.testing.assert_allclose(Rk, mat.reshape(3, 3), atol=1e-12)
        # MuJoCo: lower case = intrinsic z, y', x'' with (yaw, pitch, roll)
        mujoco.mju_euler2Quat(quat, np.array([yaw, pitch, roll]), "zyx")
        mujoco.mju_quat2Mat(mat, quat)
        np.testing.assert_allclose(Rk, mat.reshape(3, 3), atol=1e-12)
    for a in rng.uniform(-4, 4, size=5):
        for f, ax in ((geo.rot_x, "x"), (geo.rot_y, "y"), (geo.rot_z, "z")):
            Rk = np.asarray(f(jnp.asarray(a)))
            np.testing.assert_allclose(Rk, Rotation.from_euler(ax, a).as_matrix(), atol=1e-12)
            assert np.linalg.det(Rk) == pytest.approx(1.0, abs=1e-12)


def test_rotations_rotate_vectors_actively():
    # a quarter turn about z takes x to y, about x takes y to z, about y takes z to x
    ex, ey, ez = np.eye(3)
    np.testing.assert_allclose(geo.rot_z(jnp.pi / 2) @ ex, ey, atol=1e-15)
    np.testing.assert_allclose(geo.rot_x(jnp.pi / 2) @ ey, ez, atol=1e-15)
    np.testing.assert_allclose(geo.rot_y(jnp.pi / 2) @ ez, ex, atol=1e-15)


def test_octopus_eqs_12_13_are_transposes():
    for a in (-1.2, -0.3, 0.0, 0.4, 1.1):
        c, s = np.cos(a), np.sin(a)
        eq12 = np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]])  # ^C_M R(A_P)
        eq13 = np.array([[1, 0, 0], [0, c, s], [0, -s, c]])  # ^M_R R(A_R)
        np.testing.assert_allclose(geo.rot_y(jnp.asarray(a)).T, eq12, atol=1e-15)
        np.testing.assert_allclose(geo.rot_x(jnp.asarray(a)).T, eq13, atol=1e-15)


angles = st.floats(-np.pi + 1e-3, np.pi - 1e-3)


@HYP
@given(angles, st.floats(-np.pi / 2 + 0.01, np.pi / 2 - 0.01), angles)
def test_matrix_to_rpy_round_trip(roll, pitch, yaw):
    R = Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_matrix()
    np.testing.assert_allclose(M2RPY(R), [roll, pitch, yaw], atol=1e-9)
    np.testing.assert_allclose(
        RPY_V(*[jnp.atleast_1d(v) for v in M2RPY(R)])[0], R, atol=1e-12
    )


def test_skew_is_cross_product():
    rng = np.random.default_rng(1)
    for a, b in rng.normal(size=(5, 2, 3)):
        np.testing.assert_allclose(geo.skew(jnp.asarray(a)) @ b, np.cross(a, b), atol=1e-14)


# ------------------------------------------------------------------ homogeneous transforms
def _random_transform(rng):
    R = Rotation.from_rotvec(rng.normal(size=3)).as_matrix()
    return np.asarray(geo.make_transform(jnp.asarray(R), jnp.asarray(rng.normal(size=3))))


def test_transform_inverse_and_point():
    rng = np.random.default_rng(2)
    for _ in range(5):
        T = _random_transform(rng)
        Ti = np.asarray(geo.invert_transform(jnp.asarray(T)))
        np.testing.assert_allclose(Ti, np.linalg.inv(T), atol=1e-12)
        np.testing.assert_allclose(Ti @ T, np.eye(4), atol=1e-12)
        p = rng.normal(size=3)
        np.testing.assert_allclose(geo.transform_point(T, p), (T @ np.append(p, 1.0))[:3], atol=1e-12)


def _elem(kind: str, v: float) -> np.ndarray:
    M = np.eye(4)
    c, s = np.cos(v), np.sin(v)
    if kind == "Rz":
        M[:2, :2] = [[c, -s], [s, c]]
    elif kind == "Rx":
        M[1:3, 1:3] = [[c, -s], [s, c]]
    elif kind == "Tz":
        M[2, 3] = v
    elif kind == "Tx":
        M[0, 3] = v
    return M


def test_dh_transform_is_product_of_elementary_transforms():
    rng = np.random.default_rng(3)
    for theta, d, a, alpha in rng.uniform(-3, 3, size=(8, 4)):
        ref = _elem("Rz", theta) @ _elem("Tz", d) @ _elem("Tx", a) @ _elem("Rx", alpha)
        np.testing.assert_allclose(geo.dh_transform(theta, d, a, alpha), ref, atol=1e-12)


def test_dh_chain_planar_two_link_closed_form():
    a1, a2 = 0.7, 0.4
    for t1, t2 in [(0.0, 0.0), (0.3, -1.1), (2.0, 0.9), (-np.pi / 2, np.pi / 2)]:
        F = np.asarray(DH_CHAIN(jnp.array([t1, t2]), jnp.zeros(2), jnp.array([a1, a2]), jnp.zeros(2)))
        assert F.shape == (3, 4, 4)
        np.testing.assert_allclose(F[0], np.eye(4), atol=0)
        np.testing.assert_allclose(F[1][:3, 3], [a1 * np.cos(t1), a1 * np.sin(t1), 0.0], atol=1e-14)
        x = a1 * np.cos(t1) + a2 * np.cos(t1 + t2)
        y = a1 * np.sin(t1) + a2 * np.sin(t1 + t2)
        np.testing.assert_allclose(F[2][:3, 3], [x, y, 0.0], atol=1e-14)
        np.testing.assert_allclose(F[2][:3, :3], Rotation.from_euler("z", t1 + t2).as_matrix(), atol=1e-14)


def test_dh_chain_matches_mujoco_forward_kinematics():
    """The same serial chain built as MuJoCo bodies with hinge joints: body k turns
    about its local z by q_k; the next body sits at (a_k, 0, d_k) turned by alpha_k
    about x; a site marks each D-H frame."""
    rng = np.random.default_rng(4)
    n = 3
    d, a, alpha = rng.uniform(-0.5, 0.5, n), rng.uniform(0.1, 0.6, n), rng.uniform(-np.pi, np.pi, n)
    base_pos = np.array([0.2, -0.1, 0.5])
    base_quat = Rotation.from_rotvec([0.3, -0.2, 0.7]).as_quat(scalar_first=True)
    spec = mujoco.MjSpec()
    parent, pos, quat = spec.worldbody, base_pos, base_quat
    for k in range(n):
        body = parent.add_body(name=f"b{k}", pos=pos, quat=quat)
        body.add_joint(name=f"j{k}", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 0, 1])
        body.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.02, 0, 0])
        pos = [a[k], 0.0, d[k]]
        quat = [np.cos(alpha[k] / 2), np.sin(alpha[k] / 2), 0.0, 0.0]
        body.add_site(name=f"s{k}", pos=pos, quat=quat)
        parent = body
    model = spec.compile()
    data = mujoco.MjData(model)
    base = np.eye(4)
    base[:3, :3] = Rotation.from_quat(base_quat, scalar_first=True).as_matrix()
    base[:3, 3] = base_pos
    for q in rng.uniform(-np.pi, np.pi, size=(6, n)):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        F = np.asarray(DH_CHAIN(jnp.asarray(q), jnp.asarray(d), jnp.asarray(a), jnp.asarray(alpha), jnp.asarray(base)))
        np.testing.assert_allclose(F[1:, :3, 3], data.site_xpos, atol=1e-10)
        np.testing.assert_allclose(F[1:, :3, :3], data.site_xmat.reshape(n, 3, 3), atol=1e-10)


# ------------------------------------------------------------------------ planes and lines
def test_project_to_plane():
    rng = np.random.default_rng(5)
    for _ in range(5):
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        c, p = rng.normal(), rng.normal(size=3)
        x = np.asarray(geo.project_to_plane(p, n, c))
        assert n @ x == pytest.approx(c, abs=1e-12)  # on the plane
        assert np.linalg.norm(np.cross(p - x, n)) < 1e-12  # moved along the normal
        y = x + np.cross(n, rng.normal(size=3))  # another point of the plane
        assert np.linalg.norm(p - x) <= np.linalg.norm(p - y) + 1e-12


def test_signed_distance_to_line_left_positive():
    a, b = jnp.array([0.0, 0.0]), jnp.array([2.0, 0.0])
    assert float(geo.signed_distance_to_line(jnp.array([0.5, 2.0]), a, b)) == pytest.approx(2.0)
    assert float(geo.signed_distance_to_line(jnp.array([7.0, -1.5]), a, b)) == pytest.approx(-1.5)
    assert float(geo.signed_distance_to_line(jnp.array([0.5, 2.0]), b, a)) == pytest.approx(-2.0)
    # slanted line y = x; (0, 1) is left of (0,0)->(1,1), at distance 1/sqrt2
    d = geo.signed_distance_to_line(jnp.array([0.0, 1.0]), jnp.array([0.0, 0.0]), jnp.array([1.0, 1.0]))
    assert float(d) == pytest.approx(2**-0.5)


def test_point_segment_distance_against_sampling():
    rng = np.random.default_rng(6)
    for dim in (2, 3):
        for _ in range(4):
            a, b, p = rng.normal(size=(3, dim))
            ref = _sampled_segment_distance(p, a, b)
            assert float(geo.point_segment_distance(p, a, b)) == pytest.approx(ref, abs=1e-9)
    a = jnp.array([1.0, 2.0, 3.0])
    assert float(geo.point_segment_distance(jnp.array([1.0, 2.0, 5.0]), a, a)) == pytest.approx(2.0)
    assert float(geo.point_segment_distance(a, a, a)) == 0.0
    g = jax.grad(geo.point_segment_distance)(a, a, a)
    assert np.all(np.isfinite(g))
    # beyond an endpoint: distance to the endpoint, not to the line
    d = geo.point_segment_distance(jnp.array([3.0, 1.0]), jnp.array([0.0, 0.0]), jnp.array([1.0, 0.0]))
    assert float(d) == pytest.approx(np.hypot(2.0, 1.0))


def test_fit_plane_exact_masked_and_least_squares():
    rng = np.random.default_rng(7)
    n_true = np.array([0.2, -0.3, 1.0])
    n_true /= np.linalg.norm(n_true)
    c_true = 0.4
    xy = rng.uniform(-1, 1, size=(8, 2))
    z = (c_true - n_true[0] * xy[:, 0] - n_true[1] * xy[:, 1]) / n_true[2]
    pts = np.column_stack([xy, z])
    n, c = geo.fit_plane(jnp.asarray(pts))
    np.testing.assert_allclose(n, n_true, atol=1e-12)
    assert float(c) == pytest.approx(c_true, abs=1e-12)
    # garbage rows masked out are ignored
    garbage = rng.uniform(-100, 100, size=(5, 3))
    allpts = np.concatenate([pts, garbage])
    mask = np.r_[np.ones(8, bool), np.zeros(5, bool)]
    n2, c2 = geo.fit_plane(jnp.asarray(allpts), jnp.asarray(mask))
    np.testing.assert_allclose(n2, n_true, atol=1e-10)
    assert float(c2) == pytest.approx(c_true, abs=1e-10)
    # noisy points: numpy least squares on z = c0 + c1 x + c2 y
    noisy = pts + np.column_stack([np.zeros((8, 2)), 0.05 * rng.normal(size=8)])
    coef, *_ = np.linalg.lstsq(np.column_stack([np.ones(8), noisy[:, :2]]), noisy[:, 2], rcond=None)
    n3, c3 = geo.fit_plane(jnp.asarray(np.concatenate([noisy, garbage])), jnp.asarray(mask))
    raw = np.array([-coef[1], -coef[2], 1.0])
    np.testing.assert_allclose(n3, raw / np.linalg.norm(raw), atol=1e-10)
    assert float(c3) == pytest.approx(coef[0] / np.linalg.norm(raw), abs=1e-10)
    assert float(n3[2]) > 0


def test_contact_frame_slope_and_level():
    theta = 0.3  # surface z = x tan(theta): uphill is +x
    n = np.array([-np.sin(theta), 0.0, np.cos(theta)])
    F = np.asarray(geo.contact_frame(jnp.asarray(2.5 * n)))  # not unit on purpose
    np.testing.assert_allclose(F.T @ F, np.eye(3), atol=1e-12)
    assert np.linalg.det(F) == pytest.approx(1.0)
    np.testing.assert_allclose(F[:, 2], n, atol=1e-12)
    np.testing.assert_allclose(F[:, 0], [np.cos(theta), 0.0, np.sin(theta)], atol=1e-12)
    # generic slope: x is the steepest ascent direction within the plane
    rng = np.random.default_rng(8)
    for _ in range(5):
        n = rng.normal(size=3)
        n[2] = abs(n[2]) + 0.2
        n /= np.linalg.norm(n)
        F = np.asarray(geo.contact_frame(jnp.asarray(n)))
        np.testing.assert_allclose(F.T @ F, np.eye(3), atol=1e-12)
        assert np.linalg.det(F) == pytest.approx(1.0)
        np.testing.assert_allclose(F[:, 2], n, atol=1e-12)
        assert F[2, 0] > 0 and F[2, 1] == pytest.approx(0.0, abs=1e-12)  # y is level
        # no unit direction in the plane climbs faster than x
        for phi in np.linspace(0, 2 * np.pi, 73):
            u = np.cos(phi) * F[:, 0] + np.sin(phi) * F[:, 1]
            assert u[2] <= F[2, 0] + 1e-12
    # level ground: fallback (default world x; custom projected into the plane)
    F = np.asarray(geo.contact_frame(jnp.array([0.0, 0.0, 1.0])))
    np.testing.assert_allclose(F, np.eye(3), atol=1e-12)
    F = np.asarray(geo.contact_frame(jnp.array([0.0, 0.0, 1.0]), jnp.array([1.0, 1.0, 0.7])))
    np.testing.assert_allclose(F[:, 0], [2**-0.5, 2**-0.5, 0.0], atol=1e-12)
    np.testing.assert_allclose(F[:, 1], [-(2**-0.5), 2**-0.5, 0.0], atol=1e-12)


# ------------------------------------------------------------------------------ polygons
def _check_case(out, pts, mask, real, qs, exact_vertices: bool, tol_scale: float = 1.0):
    """Compare one `_poly_all` output with SciPy's hull and the distance oracles."""
    hv, eqs, area = _scipy_hull(real)
    E = np.asarray(out["E"])
    # hull_edges: exactly the CCW edges between consecutive Qhull vertices
    got = {(tuple(pts[i]), tuple(pts[j])) for i, j in zip(*np.nonzero(E))}
    want = {(tuple(hv[k]), tuple(hv[(k + 1) % len(hv)])) for k in range(len(hv))}
    assert not np.any(E[~mask]) and not np.any(E[:, ~mask])
    if exact_vertices:
        assert got == want
    else:
        assert len(got) == len(want)
    valid = np.asarray(out["valid"])
    nv = int(valid.sum())
    assert nv == len(hv) and np.all(valid[:nv]) and not np.any(valid[nv:])
    verts = np.asarray(out["verts"])
    assert _same_cycle(verts[:nv], hv, atol=1e-6 * tol_scale)
    np.testing.assert_allclose(verts[nv:], np.broadcast_to(verts[0], verts[nv:].shape))
    assert float(out["area"]) == pytest.approx(area, rel=1e-6 * tol_scale, abs=1e-9 * tol_scale)
    for q, h, p in zip(qs, np.asarray(out["hsd"]), np.asarray(out["psd"])):
        ref, tol = _oracle_signed_distance(q, hv, eqs)
        assert h == pytest.approx(ref, abs=max(tol, 1e-6 * tol_scale))
        assert p == pytest.approx(ref, abs=max(tol, 1e-6 * tol_scale))


@pytest.mark.parametrize("dyadic", [True, False])
def test_polygons_against_scipy_hull(dyadic):
    (pts, mask, qs), reals = _batch(10 + dyadic, BATCH, dyadic)
    out = POLY_V(pts, mask, qs)
    for b in range(len(reals)):
        ob = {k: v[b] for k, v in out.items()}
        _check_case(ob, pts[b], mask[b], reals[b], qs[b], exact_vertices=True)


def test_polygons_permutation_invariant_and_vmap_equals_loop():
    (pts, mask, qs), _ = _batch(20, BATCH, True)
    batched = POLY_V(pts, mask, qs)
    rng = np.random.default_rng(21)
    for b in range(len(pts)):
        single = POLY(pts[b], mask[b], qs[b])
        for k in single:  # bool outputs equal, floats up to rounding (XLA fuses differently)
            np.testing.assert_allclose(np.asarray(single[k]), np.asarray(batched[k][b]), rtol=0, atol=1e-14)
        perm = rng.permutation(N)
        permuted = POLY(pts[b][perm], mask[b][perm], qs[b])
        np.testing.assert_allclose(permuted["hsd"], single["hsd"], atol=1e-14)
        np.testing.assert_allclose(permuted["psd"], single["psd"], atol=1e-14)
        assert float(permuted["area"]) == pytest.approx(float(single["area"]), abs=1e-14)
        nv = int(single["valid"].sum())
        assert _same_cycle(np.asarray(permuted["verts"])[:nv], np.asarray(single["verts"])[:nv])
        # the edge sets agree as coordinate pairs
        def edge_set(E, P):
            return {(tuple(P[i]), tuple(P[j])) for i, j in zip(*np.nonzero(np.asarray(E)))}

        assert edge_set(permuted["E"], pts[b][perm]) == edge_set(single["E"], pts[b])


def test_polygons_float32_agree_with_float64():
    (pts, mask, qs), reals = _batch(30, BATCH, False)
    out64 = POLY_V(pts, mask, qs)
    out32 = POLY_V(pts.astype(np.float32), mask, qs.astype(np.float32))
    assert out32["hsd"].dtype == jnp.float32 and out32["area"].dtype == jnp.float32
    for k in ("hsd", "psd", "area"):
        np.testing.assert_allclose(out32[k], out64[k], atol=1e-5, rtol=1e-5)
    np.testing.assert_array_equal(out32["valid"], out64["valid"])
    for b in range(len(reals)):
        ob = {k: v[b] for k, v in out32.items()}
        _check_case(ob, pts[b].astype(np.float32).astype(float), mask[b], reals[b].astype(np.float32).astype(float),
                    qs[b].astype(np.float32).astype(float), exact_vertices=False, tol_scale=30.0)


def test_masked_garbage_may_be_nan_or_inf():
    square = [[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]]
    pts, mask = _pad(square)
    pts[4:6] = np.nan
    pts[6] = [np.inf, -np.inf]
    out = POLY(pts, mask, _queries([0.5, 0.25], [3.0, 1.0]))
    assert float(out["area"]) == pytest.approx(2.0)
    assert int(out["valid"].sum()) == 4 and np.all(np.isfinite(out["verts"]))
    assert _same_cycle(np.asarray(out["verts"])[:4], np.array(square))
    np.testing.assert_allclose(out["hsd"][:2], [0.25, -1.0], atol=1e-14)
    np.testing.assert_allclose(out["psd"][:2], [0.25, -1.0], atol=1e-14)


def test_polygon_degenerate_cases():
    q = _queries([0.0, 0.0], [3.0, 0.0], [1.0, 2.0], [0.5, 0.0])
    # no points
    out = POLY(*_pad(np.zeros((0, 2))), q)
    assert not np.any(out["E"]) and not np.any(out["valid"]) and float(out["area"]) == 0.0
    assert np.all(np.isneginf(out["hsd"])) and np.all(np.isneginf(out["psd"]))
    # one point (three copies of it): minus the distance to it, one vertex
    out = POLY(*_pad([[1.0, 0.0]] * 3), q)
    assert not np.any(out["E"]) and int(out["valid"].sum()) == 1 and float(out["area"]) == 0.0
    np.testing.assert_allclose(out["verts"][0], [1.0, 0.0])
    np.testing.assert_allclose(out["hsd"][:4], [-1.0, -2.0, -2.0, -0.5], atol=1e-14)
    np.testing.assert_allclose(out["psd"][:4], [-1.0, -2.0, -2.0, -0.5], atol=1e-14)
    # two points: both directions of the segment; distances <= 0, also on the line
    out = POLY(*_pad([[-1.0, 0.0], [1.0, 0.0]]), q)
    E = np.asarray(out["E"])
    assert E[0, 1] and E[1, 0] and E.sum() == 2
    assert int(out["valid"].sum()) == 2 and float(out["area"]) == 0.0
    ref = [0.0, -2.0, -2.0, 0.0]
    np.testing.assert_allclose(out["hsd"][:4], ref, atol=1e-14)
    np.testing.assert_allclose(out["psd"][:4], ref, atol=1e-14)
    # five collinear points (unordered, with a duplicate): only the extreme segment
    line = [[0.5, 0.0], [-1.0, 0.0], [0.0, 0.0], [1.0, 0.0], [0.0, 0.0], [-0.25, 0.0]]
    pts, mask = _pad(line)
    out = POLY(pts, mask, q)
    E = np.asarray(out["E"])
    assert E[1, 3] and E[3, 1] and E.sum() == 2
    assert int(out["valid"].sum()) == 2 and float(out["area"]) == 0.0
    np.testing.assert_allclose(sorted(np.asarray(out["verts"])[:2, 0]), [-1.0, 1.0])
    np.testing.assert_allclose(out["hsd"][:4], ref, atol=1e-14)
    np.testing.assert_allclose(out["psd"][:4], ref, atol=1e-14)
    # a slanted collinear set, query beyond the end on the line
    out = POLY(*_pad([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]]), _queries([3.0, 3.0], [1.0, 1.0]))
    np.testing.assert_allclose(out["hsd"][:2], [-np.sqrt(2.0), 0.0], atol=1e-12)


def test_polygon_gradients():
    """hull_signed_distance, polygon_signed_distance and polygon_area against central
    differences (through the compiled POLY); masked rows get zero gradient."""
    pts, mask = _pad([[0.0, 0.0], [2.0, 0.1], [2.2, 1.3], [0.3, 1.0], [1.0, 0.5]], fill=5.0)
    qs = _queries([1.0, 0.5], [3.0, 0.2], [1.1, -0.6], [0.6, 0.9])
    fn = lambda q, p: {k: POLY(p, mask, q)[k] for k in ("hsd", "psd", "area")}  # noqa: E731
    args = (jnp.asarray(qs), jnp.asarray(pts))
    check_grads(fn, args, order=1, modes=["fwd", "rev"], eps=1e-6)
    out, pullback = jax.vjp(fn, *args)
    for k in out:
        cot = {j: jnp.ones_like(v) * (j == k) for j, v in out.items()}
        g = np.asarray(pullback(cot)[1])
        assert np.all(np.isfinite(g)) and np.all(g[~mask] == 0.0) and np.abs(g[mask]).sum() > 0, k
        assert np.all(g[4] == 0.0), k  # an interior point does not shape the hull


def test_halfplane_polygon_box_and_triangle():
    normals = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0], [1.0, 1.0]])
    offsets = np.array([2.0, 1.0, 0.5, 1.5, 10.0])  # box [-1, 2] x [-1.5, 0.5]; last redundant
    verts, valid = HALFPLANE(normals, offsets, np.ones(5, bool))
    assert verts.shape == (10, 2)
    nv = int(valid.sum())
    box = np.array([[-1.0, -1.5], [2.0, -1.5], [2.0, 0.5], [-1.0, 0.5]])
    assert nv == 4 and _same_cycle(np.asarray(verts)[:nv], box, atol=1e-12)
    assert float(AREA(verts, valid)) == pytest.approx(6.0)
    # masking the right wall out and cutting with x + y <= 0 instead
    offsets2 = offsets.copy()
    offsets2[4] = 0.0
    verts, valid = HALFPLANE(normals, offsets2, np.array([False, True, True, True, True]))
    nv = int(valid.sum())
    pent = np.array([[-1.0, -1.5], [1.5, -1.5], [-0.5, 0.5], [-1.0, 0.5]])
    assert nv == 4 and _same_cycle(np.asarray(verts)[:nv], pent, atol=1e-12)
    # {h_i <= 1/2, h_j <= 1/2, h_i + h_j >= 1/2}: triangle of area 1/8
    tn = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, -1.0]] + [[1.0, 0.0]] * 2)
    to = np.array([0.5, 0.5, -0.5] + [9.0] * 2)
    verts, valid = HALFPLANE(tn, to, np.array([True, True, True, False, False]))
    nv = int(valid.sum())
    tri = np.array([[0.5, 0.0], [0.5, 0.5], [0.0, 0.5]])
    assert nv == 3 and _same_cycle(np.asarray(verts)[:nv], tri, atol=1e-12)
    assert float(AREA(verts, valid)) == pytest.approx(0.125)
    d = PSD_V(jnp.array([[0.4, 0.3], [0.0, 0.0]]), verts, valid)
    np.testing.assert_allclose(d, [0.1, -0.5 / np.sqrt(2.0)], atol=1e-12)
    # the empty set {x <= 0, x >= 1}
    en = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0], [1.0, 0.0]])
    eo = np.array([0.0, -1.0, 1.0, 1.0, 1.0])
    _, valid = HALFPLANE(en, eo, np.ones(5, bool))
    assert not np.any(valid)


# ----------------------------------------------------------------------------- soft-min
@HYP
@given(
    st.lists(st.floats(-5, 5), min_size=8, max_size=8),
    st.lists(st.booleans(), min_size=8, max_size=8).filter(any),
    st.floats(1e-3, 2.0),
)
def test_soft_min_bounds_and_masked_gradient(xs, ms, T):
    x, mask = np.array(xs), np.array(ms)
    x_garbage = np.where(mask, x, np.inf)  # masked entries may be anything
    true_min = x[mask].min()
    s = float(SOFT_MIN(x_garbage, T, mask))
    assert s <= true_min + 1e-12
    assert s >= true_min - T * np.log(mask.sum()) - 1e-12
    g = np.asarray(SOFT_MIN_GRAD(x_garbage, T, mask))
    assert np.all(g[~mask] == 0.0) and np.all(np.isfinite(g))
    assert g.sum() == pytest.approx(1.0)  # soft-min weights


def test_soft_min_tends_to_min():
    x = np.array([0.3, -0.2, 1.5, -0.19, 4.0])
    mask = np.array([True, True, True, True, False])
    gaps = [-0.2 - float(SOFT_MIN(x, T, mask)) for T in (1.0, 0.1, 0.01, 1e-3, 1e-5)]
    assert all(g >= 0 for g in gaps) and all(a > b for a, b in itertools.pairwise(gaps))
    assert gaps[-1] < 1e-6
    check_grads(lambda v: SOFT_MIN(v, 0.2, mask), (jnp.asarray(x),), order=1, modes=["fwd", "rev"])


# ------------------------------------------- small sets: the unrolled hull distance
SMALL = geo.UNROLL_MAX_POINTS  # hull_signed_distance's unrolled form (O(N^2), closed-form gradient)


def _small_case(rng: np.random.Generator, size: int = SMALL):
    """`size` rows: 1..size real points on a dyadic grid (exact duplicates and exact
    collinear triples happen), or in general position; garbage in the masked rows."""
    n_real = int(rng.integers(1, size + 1))
    real = rng.integers(-4, 5, size=(n_real, 2)) / 4.0 if rng.uniform() < 0.5 else rng.normal(size=(n_real, 2))
    pts = rng.uniform(-50.0, 50.0, size=(size, 2))
    mask = np.zeros(size, bool)
    rows = rng.permutation(size)[:n_real]
    pts[rows], mask[rows] = real, True
    qs = np.concatenate([rng.uniform(-2.0, 2.0, size=(Q - 3, 2)), real[:1], 0.5 * (real[:1] + real[-1:]),
                         real[-1:] + 1e-3])
    return pts, mask, qs


def _pad_to(points, mask, n):
    """The same set padded with masked garbage rows to n points (the all-pairs form)."""
    extra = n - len(points)
    return (np.concatenate([points, np.full((extra, 2), 9.0)]), np.concatenate([mask, np.zeros(extra, bool)]))


HSD_SMALL = jax.jit(jax.vmap(jax.vmap(geo.hull_signed_distance, (0, None, None))))


def test_small_hull_distance_equals_the_all_pairs_form_and_qhull():
    """Up to UNROLL_MAX_POINTS points hull_signed_distance runs unrolled; 300 random sets
    (1 to 6 points, duplicates, collinear, garbage in masked rows) give the values of
    the all-pairs form (the same set padded to N rows) to 1e-12, and Qhull's where the
    set spans an area; float32 agrees within its tolerance."""
    rng = np.random.default_rng(7)
    cases = [_small_case(rng) for _ in range(300)]
    pts, mask, qs = (np.stack([c[k] for c in cases]) for k in range(3))
    small = np.asarray(HSD_SMALL(qs, pts, mask))
    padded = [_pad_to(p, m, N) for p, m, _ in cases]
    pts_n, mask_n = np.stack([p for p, _ in padded]), np.stack([m for _, m in padded])
    out = POLY_V(pts_n, mask_n, qs)
    np.testing.assert_allclose(small, np.asarray(out["hsd"]), atol=1e-12, rtol=0)
    assert np.isinf(small).sum() == 0 and (small > 0).any() and (small < 0).any()
    for b in range(0, 300, 10):
        real = np.unique(pts[b][mask[b]], axis=0)
        if len(real) >= 3 and np.linalg.matrix_rank(real[1:] - real[0]) == 2:
            verts, eqs, _ = _scipy_hull(real)
            for q, value in zip(qs[b], small[b]):
                ref, tol = _oracle_signed_distance(q, verts, eqs)
                assert value == pytest.approx(ref, abs=10 * tol), (b, q)  # boundary queries: sampling
    f32 = np.asarray(HSD_SMALL(qs.astype(np.float32), pts.astype(np.float32), mask))
    np.testing.assert_allclose(f32, small, atol=5e-5, rtol=0)


def test_small_hull_distance_gradients():
    """The unrolled form's closed-form derivative against central differences (check_grads,
    forward and reverse) inside and outside a quadrilateral with an interior point;
    masked rows and the interior point get zero gradient; no points gives -inf."""
    pts, mask = _pad([[0.0, 0.0], [2.0, 0.1], [2.2, 1.3], [0.3, 1.0], [1.0, 0.5]], n=SMALL, fill=5.0)
    hsd = jax.jit(geo.hull_signed_distance)
    for q in ([1.1, 0.4], [3.0, 0.2], [1.1, -0.6], [-0.4, 1.3]):
        fn = lambda q_, p_: hsd(q_, p_, jnp.asarray(mask))  # noqa: E731
        args = (jnp.asarray(q), jnp.asarray(pts))
        check_grads(fn, args, order=1, modes=["fwd", "rev"], eps=1e-6)
        g_q, g_p = jax.grad(fn, argnums=(0, 1))(*args)
        g_p = np.asarray(g_p)
        assert np.all(g_p[~mask] == 0.0) and np.all(g_p[4] == 0.0) and np.abs(g_p).sum() > 0
        assert float(jnp.linalg.norm(g_q)) == pytest.approx(1.0)  # a distance: unit slope in q
    assert float(hsd(jnp.zeros(2), jnp.asarray(pts), jnp.zeros(SMALL, bool))) == -np.inf


# ------------------------------------ more points: the vectorised O(N^2) hull distance
LARGE = 16  # beyond UNROLL_MAX_POINTS: every point's gift-wrap step at once, on 16-vectors
HSD_LARGE = jax.jit(jax.vmap(jax.vmap(geo.hull_signed_distance, (0, None, None))))
HSD_ALL_PAIRS = jax.jit(jax.vmap(jax.vmap(geo._hull_signed_distance_all_pairs, (0, None, None))))


def test_vectorized_hull_distance_equals_the_all_pairs_form():
    """Beyond UNROLL_MAX_POINTS, hull_signed_distance runs every point's gift-wrap step on
    N-vectors: 300 random sets of 1 to 16 points (duplicates, collinear, garbage in masked
    rows) give the all-pairs form's values to 1e-12; float32 agrees within its tolerance."""
    assert LARGE > geo.UNROLL_MAX_POINTS
    rng = np.random.default_rng(8)
    cases = [_small_case(rng, LARGE) for _ in range(300)]
    pts, mask, qs = (np.stack([c[k] for c in cases]) for k in range(3))
    got = np.asarray(HSD_LARGE(qs, pts, mask))
    np.testing.assert_allclose(got, np.asarray(HSD_ALL_PAIRS(qs, pts, mask)), atol=1e-12, rtol=0)
    assert np.isinf(got).sum() == 0 and (got > 0).sum() > 500 and (got < 0).sum() > 500
    f32 = np.asarray(HSD_LARGE(qs.astype(np.float32), pts.astype(np.float32), mask))
    np.testing.assert_allclose(f32, got, atol=5e-5, rtol=0)


def test_vectorized_hull_distance_gradients():
    """Its closed-form derivative against central differences (check_grads, forward and
    reverse) and against the all-pairs form's autodiff gradient, inside and outside a
    hexagon with interior points; masked rows and interior points get zero gradient."""
    hexagon = [[np.cos(a) + 0.1 * k, np.sin(a)] for k, a in enumerate(np.linspace(0, 2 * np.pi, 7)[:-1])]
    pts, mask = _pad([*hexagon, [0.2, 0.1], [-0.3, 0.2], [0.5, 0.0]], n=LARGE, fill=5.0)
    hsd = jax.jit(geo.hull_signed_distance)
    reference = jax.jit(jax.grad(geo._hull_signed_distance_all_pairs, argnums=(0, 1)))
    for q in ([0.1, 0.05], [2.0, 0.3], [0.2, -1.4], [-1.5, 0.9]):
        fn = lambda q_, p_: hsd(q_, p_, jnp.asarray(mask))  # noqa: E731
        args = (jnp.asarray(q), jnp.asarray(pts))
        check_grads(fn, args, order=1, modes=["fwd", "rev"], eps=1e-6)
        g_q, g_p = jax.grad(fn, argnums=(0, 1))(*args)
        r_q, r_p = reference(*args, jnp.asarray(mask))
        np.testing.assert_allclose(g_q, r_q, atol=1e-12)
        np.testing.assert_allclose(g_p, r_p, atol=1e-12)
        g_p = np.asarray(g_p)
        assert np.all(g_p[~mask] == 0.0) and np.all(g_p[6:9] == 0.0) and np.abs(g_p).sum() > 0
