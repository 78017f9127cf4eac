"""Tests of jaxloco.stability against independent oracles: hand-worked numbers, closed
forms (flat and sloped NESM, the slip angle tan(theta) = mu), SciPy's ConvexHull with a
brute-force Rodrigues rotation of the COG (NESM) and a bisection along the travel line
(longitudinal margin), the four rows of the friction pyramid, finite differences
(`check_grads`), rotation of the whole scene (up vector), vmap vs loop and float32."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from jax.test_util import check_grads
from scipy.spatial import ConvexHull
from scipy.spatial.transform import Rotation

from jaxloco import geometry as geo
from jaxloco import stability as sm

N = 16  # contacts per scene, masked
MU = 0.6
SQ2 = np.sqrt(2.0)
EXACT = ("static", "nesm", "long", "fric")
SMOOTH = ("static_s", "nesm_s", "long_s", "fric_s")


def _margins(cog, contacts, mask, direction, forces, T):
    return dict(
        static=sm.static_margin(cog, contacts, mask),
        nesm=sm.ne_stability_margin(cog, contacts, mask),
        long=sm.longitudinal_margin(cog, contacts, mask, direction),
        fric=sm.friction_margin(forces, MU, mask),
        static_s=sm.static_margin_smooth(cog, contacts, mask, T),
        nesm_s=sm.ne_stability_margin_smooth(cog, contacts, mask, T),
        long_s=sm.longitudinal_margin_smooth(cog, contacts, mask, direction, T),
        fric_s=sm.friction_margin_smooth(forces, MU, mask, T, abs_eps=1e-3 * T),
    )


def _margins_up(cog, contacts, mask, direction, up):
    return dict(
        static=sm.static_margin(cog, contacts, mask, up=up),
        nesm=sm.ne_stability_margin(cog, contacts, mask, up=up),
        long=sm.longitudinal_margin(cog, contacts, mask, direction, up=up),
    )


MARG = jax.jit(_margins)
MARG_V = jax.jit(jax.vmap(_margins, in_axes=(0, 0, 0, 0, 0, None)))
MARG_UP = jax.jit(_margins_up)
FRIC_MARGINS = jax.jit(sm.friction_margins)


# ---------------------------------------------------------------------------- helpers
def _pad(contacts, fill_seed=0):
    """Active contacts first, then garbage rows (masked out) up to N."""
    contacts = np.asarray(contacts, float).reshape(-1, 3)
    out = np.random.default_rng(fill_seed).uniform(-30.0, 30.0, size=(N, 3))
    out[: len(contacts)] = contacts
    mask = np.zeros(N, bool)
    mask[: len(contacts)] = True
    return out, mask


def _eval(cog, contacts, mask, direction=(1.0, 0.0), forces=None, T=1e-3):
    forces = np.tile([0.0, 0.0, 10.0], (N, 1)) if forces is None else forces
    out = MARG(jnp.asarray(cog, float), jnp.asarray(contacts), jnp.asarray(mask),
               jnp.asarray(direction, float), jnp.asarray(forces, float), T)
    return {k: float(v) for k, v in out.items()}


def _random_scene(rng, inside=True):
    """Irregular, sloped, rough contacts (3..12 active of N) and a COG above them,
    its projection at least 2 cm inside (or outside) the support polygon."""
    while True:
        scene = _try_scene(rng, inside)
        if scene is not None:
            return scene


def _try_scene(rng, inside):
    n = int(rng.integers(3, 13))
    ang = np.sort(rng.uniform(0, 2 * np.pi, n))
    r = rng.uniform(0.3, 0.6, n)
    xy = np.column_stack([r * np.cos(ang), r * np.sin(ang)]) + rng.normal(0, 0.3, 2)
    slope = rng.uniform(-0.4, 0.4, 2)
    z = xy @ slope + rng.uniform(-0.1, 0.1, n)
    contacts = np.random.default_rng(rng.integers(1 << 30)).uniform(-30, 30, size=(N, 3))
    mask = np.zeros(N, bool)
    rows = rng.permutation(N)[:n]
    contacts[rows] = np.column_stack([xy, z])
    mask[rows] = True
    h = ConvexHull(xy)
    centre = xy[h.vertices].mean(axis=0)
    for _ in range(100):
        if inside:  # a random convex combination of the hull vertices
            cxy = rng.dirichlet(np.ones(len(h.vertices))) @ xy[h.vertices]
        else:
            cxy = centre + rng.uniform(-1.2, 1.2, 2)
        viol = np.max(h.equations[:, :2] @ cxy + h.equations[:, 2])
        if (viol < -0.02) if inside else (viol > 0.02):
            break
    else:
        return None
    cog = np.array([cxy[0], cxy[1], centre @ slope + rng.uniform(0.2, 0.6)])
    d = rng.normal(size=2)
    forces = np.column_stack([rng.normal(0, 3, (N, 2)), rng.uniform(1, 20, N)])
    return cog, contacts, mask, d / np.linalg.norm(d), forces


def _scenes(seed, count, inside=True):
    rng = np.random.default_rng(seed)
    cases = [_random_scene(rng, inside) for _ in range(count)]
    return [np.stack([c[k] for c in cases]) for k in range(5)]


B = 16  # every batched call uses this batch size: MARG_V compiles once per dtype


def _mixed_scenes(seed, n_inside):
    """B scenes: the first n_inside with the COG inside, the rest outside."""
    a = _scenes(seed, n_inside, inside=True)
    b = _scenes(seed + 1, B - n_inside, inside=False)
    return [np.concatenate([x, y]) for x, y in zip(a, b)]


def _hull_ccw_edges(contacts, mask):
    """CCW support edges (3D contact pairs) from Qhull on the horizontal projection."""
    act = contacts[mask]
    h = ConvexHull(act[:, :2])
    v = h.vertices
    return [(act[v[k]], act[v[(k + 1) % len(v)]]) for k in range(len(v))], h


def _nesm_brute_force(cog, contacts, mask):
    """Rotate the COG about each support edge's 3D axis over a fine grid of angles
    (Rodrigues), take max height minus present height, refine around the best angle;
    negative for edges whose inner side the projected COG is not on; min over edges."""
    edges, _ = _hull_ccw_edges(contacts, mask)
    vals = []
    for a, b in edges:
        k = (b - a) / np.linalg.norm(b - a)
        v = cog - a

        def heights(phi):
            c, s = np.cos(phi)[:, None], np.sin(phi)[:, None]
            rot = v * c + np.cross(k, v) * s + np.outer(1 - c[:, 0], k) * (k @ v)
            return a[2] + rot[:, 2]

        phi = np.linspace(-np.pi, np.pi, 40001)
        best = phi[np.argmax(heights(phi))]
        fine = np.linspace(best - 2e-4, best + 2e-4, 4001)
        rise = max(heights(fine).max(), heights(phi).max()) - cog[2]
        e, r = b[:2] - a[:2], cog[:2] - a[:2]
        inner = e[0] * r[1] - e[1] * r[0] >= 0
        vals.append(rise if inner else -rise)
    return min(vals)


def _longitudinal_bisection(cog, contacts, mask, d):
    """Distances along +d and -d from the projected COG (inside) to the support
    boundary, each found by bisection on Qhull's inside test; their min."""
    _, h = _hull_ccw_edges(contacts, mask)
    inside = lambda x: np.max(h.equations[:, :2] @ x + h.equations[:, 2]) <= 0  # noqa: E731
    out = []
    for sgn in (1.0, -1.0):
        lo, hi = 0.0, 100.0
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if inside(cog[:2] + sgn * mid * d) else (lo, mid)
        out.append(lo)
    return min(out)


# ------------------------------------------------------------------------ static margin
SQUARE = [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0], [0.2, 0.1, 0], [1, 1, 0]]  # + interior, duplicate
TRIANGLE = [[0, 0, 0], [4, 0, 0], [0, 3, 0], [1, 1, 0]]


@pytest.mark.parametrize(
    "shape, cog_xy, expected",
    [
        (SQUARE, (0.2, 0.3), 0.7),
        (SQUARE, (0.0, 0.0), 1.0),
        (SQUARE, (1.0, 0.5), 0.0),  # on the boundary
        (SQUARE, (2.0, 0.0), -1.0),
        (SQUARE, (2.0, 2.0), -np.sqrt(2.0)),  # nearest point is a corner
        (TRIANGLE, (1.0, 0.5), 0.5),
        (TRIANGLE, (2.0, 1.2), 0.24),  # hypotenuse 3x + 4y = 12: (12 - 10.8) / 5
        (TRIANGLE, (2.0, 0.0), 0.0),
        (TRIANGLE, (5.0, 0.0), -1.0),
        (TRIANGLE, (2.0, -1.0), -1.0),
        (TRIANGLE, (4.0, 3.0), -2.4),  # (24 - 12) / 5
    ],
)
def test_static_margin_hand(shape, cog_xy, expected):
    c = np.asarray(shape, float)
    for slope in ((0.0, 0.0), (0.4, -0.25)):  # only the horizontal projection matters
        c[:, 2] = c[:, :2] @ np.asarray(slope) + np.array([0.0, 0.05, -0.03, 0.02, 0.04, 0.01])[: len(c)]
        contacts, mask = _pad(c)
        got = _eval([cog_xy[0], cog_xy[1], 0.8], contacts, mask)
        assert got["static"] == pytest.approx(expected, abs=1e-12)


def test_static_margin_degenerate():
    contacts, mask = _pad([[0, 0, 0], [2, 0, 0.3], [1, 0, 0.1]])  # collinear
    assert _eval([1.0, 0.0, 1.0], contacts, mask)["static"] == pytest.approx(0.0, abs=1e-12)
    assert _eval([3.0, 0.0, 1.0], contacts, mask)["static"] == pytest.approx(-1.0)  # on the line, beyond
    assert _eval([1.0, 0.5, 1.0], contacts, mask)["static"] == pytest.approx(-0.5)
    contacts, mask = _pad([[0, 0, 0]])
    got = _eval([0.0, 2.0, 1.0], contacts, mask)
    assert got["static"] == pytest.approx(-2.0) and got["nesm"] == -np.inf and got["long"] == -np.inf
    contacts, mask = _pad([])
    got = _eval([0.0, 0.0, 1.0], contacts, mask)
    assert got["static"] == -np.inf and got["nesm"] == -np.inf and got["fric"] == np.inf


def test_masked_rows_may_hold_nan():
    cogs, contacts, masks, dirs, forces = _scenes(45, 3, inside=True)
    for cog, c, m, d, f in zip(cogs, contacts, masks, dirs, forces):
        ref = _eval(cog, c, m, d, f)
        c, f = c.copy(), f.copy()
        c[~m], f[~m] = np.nan, np.nan
        got = _eval(cog, c, m, d, f)
        for k in ref:
            assert got[k] == pytest.approx(ref[k], abs=1e-12), k


def test_up_vector_is_rotation_invariant():
    cogs, contacts, masks, dirs, _ = _scenes(40, 6, inside=True)
    cogs_out, contacts_out, masks_out, dirs_out, _ = _scenes(41, 4, inside=False)
    rng = np.random.default_rng(42)
    for cog, c, m, d in zip(
        np.r_[cogs, cogs_out], np.r_[contacts, contacts_out], np.r_[masks, masks_out], np.r_[dirs, dirs_out]
    ):
        ref = MARG_UP(cog, c, m, jnp.r_[d, 0.0], jnp.array([0.0, 0.0, 1.0]))
        base = _eval(cog, c, m, d)
        for k in ref:
            assert float(ref[k]) == pytest.approx(base[k], abs=1e-12)
        R = Rotation.from_rotvec(rng.normal(size=3)).as_matrix()
        got = MARG_UP(R @ cog, c @ R.T, m, R @ np.r_[d, 0.0], R[:, 2])
        for k in ref:
            assert float(got[k]) == pytest.approx(float(ref[k]), abs=1e-10), k


# ------------------------------------------------------- normalized energy stability margin
@pytest.mark.parametrize("a, h", [(1.0, 0.5), (0.3, 0.6), (0.5, 0.05)])
def test_nesm_flat_square_closed_form(a, h):
    contacts, mask = _pad([[-a, -a, 0], [a, -a, 0], [a, a, 0], [-a, a, 0]])
    assert _eval([0.0, 0.0, h], contacts, mask)["nesm"] == pytest.approx(np.hypot(a, h) - h, abs=1e-12)
    # off centre: the nearest edge is at a - 0.1 * a horizontally
    got = _eval([0.9 * a, 0.3 * a, h], contacts, mask)["nesm"]
    assert got == pytest.approx(np.hypot(0.1 * a, h) - h, abs=1e-12)
    # past the edge x = a by 0.2 a: minus the rise back to the top over that edge
    got = _eval([1.2 * a, 0.0, h], contacts, mask)["nesm"]
    assert got == pytest.approx(-(np.hypot(0.2 * a, h) - h), abs=1e-12)


@pytest.mark.parametrize("t", [0.2, 0.5])
def test_nesm_slope_downhill_edge(t):
    """Square of half-width a on the slope z = t x, COG h above the centre: the downhill
    edge x = -a lies a t lower, so its margin is sqrt(a^2 + (h + a t)^2) - (h + a t),
    smaller than on flat ground."""
    a, h = 0.5, 0.4
    c = np.array([[-a, -a], [a, -a], [a, a], [-a, a]])
    contacts, mask = _pad(np.column_stack([c, t * c[:, 0]]))
    got = _eval([0.0, 0.0, h], contacts, mask)["nesm"]
    H = h + a * t
    assert got == pytest.approx(np.hypot(a, H) - H, abs=1e-12)
    assert got < np.hypot(a, h) - h
    assert got == pytest.approx(_nesm_brute_force(np.array([0.0, 0.0, h]), contacts, mask), abs=1e-9)


def test_nesm_against_brute_force_rotation():
    cogs, contacts, masks, dirs, forces = _mixed_scenes(50, 10)
    out = MARG_V(cogs, contacts, masks, dirs, forces, 1e-3)
    for b in range(B):
        ref = _nesm_brute_force(cogs[b], contacts[b], masks[b])
        assert float(out["nesm"][b]) == pytest.approx(ref, abs=1e-9)
        if b >= 10:  # COG outside
            assert ref < 0 and float(out["static"][b]) < 0
            continue
        assert ref > 0
        # static margin: exact from Qhull's facet equations for an inside COG
        _, h = _hull_ccw_edges(contacts[b], masks[b])
        ref_s = -np.max(h.equations[:, :2] @ cogs[b][:2] + h.equations[:, 2])
        assert float(out["static"][b]) == pytest.approx(ref_s, abs=1e-12)
        ref_l = _longitudinal_bisection(cogs[b], contacts[b], masks[b], dirs[b])
        assert float(out["long"][b]) == pytest.approx(ref_l, abs=1e-10)



@pytest.mark.parametrize("t", [0.0, 0.3])
def test_ne_edge_margins_are_the_nesm_per_edge(t):
    """The per-edge energy margins: the four hull edges of a square on the slope z = t x
    carry the closed-form rises, the smallest is `ne_stability_margin`, and no diagonal
    or masked edge is marked as a hull edge."""
    a, h = 0.5, 0.4
    c = np.array([[-a, -a], [a, -a], [a, a], [-a, a]])
    contacts, mask = _pad(np.column_stack([c, t * c[:, 0]]))
    cog = jnp.array([0.0, 0.0, h])
    S, E = sm.ne_edge_margins(cog, contacts, mask)
    edges = {(int(i), int(j)) for i, j in zip(*np.nonzero(np.asarray(E)))}
    assert edges == {(0, 1), (1, 2), (2, 3), (3, 0)}
    down, up = h + a * t, h - a * t  # COG height over the downhill (x = -a) and uphill edges
    expected = {(3, 0): np.hypot(a, down) - down, (1, 2): np.hypot(a, up) - up}
    if t == 0.0:  # flat: the edges y = -a, y = +a too
        expected.update({(0, 1): np.hypot(a, h) - h, (2, 3): np.hypot(a, h) - h})
    for (i, j), want in expected.items():
        assert float(S[i, j]) == pytest.approx(want, abs=1e-9)
    assert float(jnp.min(jnp.where(E, S, jnp.inf))) == pytest.approx(
        float(sm.ne_stability_margin(cog, contacts, mask)), abs=1e-12)

# ------------------------------------------------------------ longitudinal stability margin
RECT = [[-2, -1, 0], [3, -1, 0.2], [3, 1, 0.1], [-2, 1, 0], [0, 0, 0]]


@pytest.mark.parametrize(
    "cog_xy, direction, expected",
    [
        ((1.0, 0.2), (1.0, 0.0), 2.0),  # front 2, rear 3
        ((1.0, 0.2), (-3.0, 0.0), 2.0),  # travel direction sign and scale do not matter
        ((1.0, 0.2), (1.0, 0.0, 0.7), 2.0),  # 3D direction: horizontal part
        ((-1.0, 0.2), (1.0, 0.0), 1.0),
        ((0.0, 0.5), (1.0, 1.0), 0.5 * np.sqrt(2.0)),  # diagonal: y = 1 hit at t = 0.5 sqrt2
        ((2.5, 0.0), (1.0, 1.0), 0.5 * np.sqrt(2.0)),  # x = 3 hit first, at t = 0.5 sqrt2
        ((0.0, 0.0), (0.0, 1.0), 1.0),
        ((4.0, 0.0), (1.0, 0.0), -1.0),  # outside: back along the travel line to x = 3
        ((4.0, 0.0), (1.0, 1.0), -np.sqrt(2.0)),  # line x = 3 is sqrt2 away along (1,1)
    ],
)
def test_longitudinal_margin_hand(cog_xy, direction, expected):
    contacts, mask = _pad(RECT)
    d3 = np.r_[direction, 0.0][:3]
    got = MARG_UP(jnp.array([*cog_xy, 0.6]), contacts, mask, jnp.asarray(d3), jnp.array([0.0, 0.0, 1.0]))
    assert float(got["long"]) == pytest.approx(expected, abs=1e-12)


def test_longitudinal_margin_beside_polygon_is_large_negative():
    contacts, mask = _pad(RECT)
    got = _eval([0.0, 2.0, 0.6], contacts, mask, direction=(1.0, 0.0))
    assert got["long"] < -1e5


# ------------------------------------------------------------------------------- friction
def test_friction_margins_hand():
    fz = 10.0
    f = np.array(
        [
            [MU * fz, 0.0, fz],  # on the cone (and pyramid) edge along x
            [0.0, -MU * fz, fz],  # along -y
            [0.0, 0.0, fz],  # along the normal
            [MU * fz / 2, -MU * fz / 2, fz],  # on a pyramid face
            [0.0, 0.0, -fz],  # pulling
            [2 * MU * fz, 0.0, fz],  # outside the cone
        ]
    )
    s = np.asarray(FRIC_MARGINS(f, MU))
    np.testing.assert_allclose(s, [0, 0, MU * fz / SQ2, 0, -MU * fz / SQ2, -MU * fz / SQ2], atol=1e-12)
    assert float(sm.friction_margin(jnp.asarray(f), MU, jnp.array([1, 1, 1, 1, 0, 0], bool))) == pytest.approx(
        0.0, abs=1e-12
    )
    assert float(sm.friction_margin(jnp.asarray(f), MU, jnp.array([0, 0, 1, 0, 1, 0], bool))) == pytest.approx(
        -MU * fz / SQ2
    )
    assert float(sm.friction_margin(jnp.asarray(f), MU, jnp.zeros(6, bool))) == np.inf


def test_friction_margin_slip_angle_on_slope():
    """A block of weight W on a slope of angle theta, held by the vertical reaction
    only: in the contact frame f = (W sin theta, 0, W cos theta); the margin vanishes at
    the slip angle tan(theta) = mu and changes sign there."""
    W = 9.81
    for theta in (0.1, np.arctan(MU), 0.7):
        n = np.array([-np.sin(theta), 0.0, np.cos(theta)])
        F = geo.contact_frame(jnp.asarray(n))
        f = sm.forces_in_contact_frames(jnp.array([[0.0, 0.0, W]]), F[None])
        np.testing.assert_allclose(f[0], [W * np.sin(theta), 0.0, W * np.cos(theta)], atol=1e-12)
        s = float(sm.friction_margin(f, MU, jnp.array([True])))
        assert s == pytest.approx(W * (MU * np.cos(theta) - np.sin(theta)) / SQ2, abs=1e-12)
        assert np.sign(round(s, 12)) == np.sign(round(np.arctan(MU) - theta, 12))


@settings(max_examples=30, deadline=None, derandomize=True)
@given(st.integers(0, 2**31 - 1), st.floats(0.1, 1.5))
def test_friction_margins_define_the_pyramid(seed, mu):
    rng = np.random.default_rng(seed)
    f = rng.normal(0, 5, size=(N, 3))
    f[:, 2] += 3.0
    s = np.asarray(FRIC_MARGINS(f, mu))
    rows = np.stack(
        [-mu / SQ2 * f[:, 2] + sx * f[:, 0] / SQ2 + sy * f[:, 1] / SQ2 for sx in (1, -1) for sy in (1, -1)]
    )
    assert np.all(rows <= -s + 1e-12)  # all four rows hold at s
    np.testing.assert_allclose(rows.max(axis=0), -s, atol=1e-12)  # and one is tight
    # s >= 0 exactly when the force lies in the pyramid |f_x| + |f_y| <= mu f_z
    inside = np.abs(f[:, 0]) + np.abs(f[:, 1]) <= mu * f[:, 2]
    np.testing.assert_array_equal(s >= 0, inside)


# ------------------------------------------------------------------ gradients and smoothing
def test_gradients_match_finite_differences():
    """Every margin, exact (at generic points: no ties) and smooth, in float64, against
    central differences along random directions (check_grads, fwd and rev) w.r.t. the
    COG, the contacts and the forces; masked rows get exactly zero gradient. The
    derivatives are taken through the already compiled MARG (one more compilation
    for each mode, shared by all scenes)."""
    cogs, contacts, masks, dirs, forces = _scenes(60, 2, inside=True)
    for cog, c, m, d, f in zip(cogs, contacts, masks, dirs, forces):
        fn = lambda x, p, F: MARG(x, p, m, d, F, 0.05)  # noqa: B023, E731
        args = (jnp.asarray(cog), jnp.asarray(c), jnp.asarray(f))
        check_grads(fn, args, order=1, modes=["fwd", "rev"], eps=1e-6)
        out, pullback = jax.vjp(fn, *args)
        for k in out:
            cot = {j: jnp.asarray(float(j == k)) for j in out}
            g_cog, g_contacts, g_forces = (np.asarray(g) for g in pullback(cot))
            g_rows = g_forces if k.startswith("fric") else g_contacts
            assert np.all(np.isfinite(g_contacts)) and np.all(np.isfinite(g_forces)), k
            assert np.all(g_rows[~m] == 0.0) and np.abs(g_rows[m]).sum() > 0, k


def test_smooth_margins_bound_and_converge():
    cogs, contacts, masks, dirs, forces = _scenes(70, B, inside=True)
    exact = MARG_V(cogs, contacts, masks, dirs, forces, 1.0)
    gaps = []
    for T in (0.1, 1e-2, 1e-3, 1e-5):
        out = MARG_V(cogs, contacts, masks, dirs, forces, T)
        for ke, ks in zip(EXACT, SMOOTH):
            assert np.all(np.asarray(out[ks]) <= np.asarray(exact[ke]) + 1e-12), ks
            assert np.all(np.asarray(out[ks]) >= np.asarray(exact[ke]) - T * np.log(N * N) - 2e-3 * T), ks
        gaps.append(max(float(np.max(exact[ke] - out[ks])) for ke, ks in zip(EXACT, SMOOTH)))
    assert gaps == sorted(gaps, reverse=True) and gaps[-1] < 1e-4


# ----------------------------------------------------------------------- batching, dtypes
def test_vmap_equals_loop_and_float32():
    cogs, contacts, masks, dirs, forces = _mixed_scenes(80, 12)
    batched = MARG_V(cogs, contacts, masks, dirs, forces, 0.01)
    for b in range(len(cogs)):
        single = MARG(cogs[b], contacts[b], masks[b], dirs[b], forces[b], 0.01)
        for k in single:
            assert float(single[k]) == pytest.approx(float(batched[k][b]), rel=1e-12, abs=1e-12), k
    f32 = lambda x: x.astype(np.float32)  # noqa: E731
    out32 = MARG_V(f32(cogs), f32(contacts), masks, f32(dirs), f32(forces), np.float32(0.01))
    for k in batched:
        assert out32[k].dtype == jnp.float32, k
        scale = 1.0 if k not in ("fric", "fric_s") else 10.0  # forces are tens of newtons
        np.testing.assert_allclose(out32[k], batched[k], atol=1e-4 * scale, rtol=1e-4, err_msg=k)


# ------------------------------------ a few contacts: the unrolled hull (geometry.UNROLL_MAX_POINTS)
FEW = geo.UNROLL_MAX_POINTS
SMALL_MARGINS = jax.jit(jax.vmap(lambda c, p, m: (sm.static_margin(c, p, m), sm.ne_stability_margin(c, p, m))))
EDGES_V = jax.jit(jax.vmap(lambda p, m: (geo._hull_edges_all_pairs(p, m), *geo.small_hull_edges(p, m))))
NESM_BOTH = jax.jit(jax.vmap(lambda c, p, m: (sm.ne_stability_margin(c, p, m),
                                              sm._ne_stability_margin_all_pairs(c, p, m))))


def _few_scenes(seed: int, count: int, size: int = FEW):
    """`size` rows: 1..size contacts on a sloped grid (exact duplicates and collinear sets
    happen) or in general position, garbage in the masked rows; a COG above them."""
    rng = np.random.default_rng(seed)
    cogs, contacts, masks = [], [], []
    for _ in range(count):
        n = int(rng.integers(1, size + 1))
        xy = rng.integers(-2, 3, size=(n, 2)) * 0.25 if rng.uniform() < 0.5 else rng.normal(0, 0.4, (n, 2))
        z = xy @ rng.uniform(-0.4, 0.4, 2) + rng.uniform(-0.05, 0.05, n)
        pts = rng.uniform(-30.0, 30.0, size=(size, 3))
        mask = np.zeros(size, bool)
        rows = rng.permutation(size)[:n]
        pts[rows], mask[rows] = np.column_stack([xy, z]), True
        cogs.append(np.r_[xy.mean(axis=0) + rng.normal(0, 0.2, 2), z.mean() + rng.uniform(0.2, 0.6)])
        contacts.append(pts)
        masks.append(mask)
    return np.array(cogs), np.array(contacts), np.array(masks)


def _assert_successors_are_the_all_pairs_edges(contacts, masks):
    """`small_hull_edges`' successor edges of every scene == `_hull_edges_all_pairs`."""
    E, succ, edge = (np.asarray(a) for a in EDGES_V(jnp.asarray(contacts[..., :2]), jnp.asarray(masks)))
    from_succ = np.zeros_like(E)
    scene, i = np.nonzero(edge)
    from_succ[scene, i, succ[scene, i]] = True
    np.testing.assert_array_equal(from_succ, E)


def test_few_contacts_give_the_all_pairs_margins_and_edges():
    """Up to UNROLL_MAX_POINTS contacts the static margin and the NESM run on the unrolled
    O(N^2) hull: on 400 random scenes (1..6 contacts, duplicates, collinear sets) the
    successor edges are the all-pairs test's edges, the NESM is the all-pairs form's, and
    both margins equal those of the same scene padded to N rows (the vectorised forms) to
    1e-12 m in float64 and to 1e-4 m in float32."""
    cogs, contacts, masks = _few_scenes(11, 400)
    _assert_successors_are_the_all_pairs_edges(contacts, masks)
    nesm, ref = (np.asarray(a) for a in NESM_BOTH(jnp.asarray(cogs), jnp.asarray(contacts), jnp.asarray(masks)))
    np.testing.assert_allclose(nesm, ref, atol=1e-12, rtol=0)
    static, nesm = (np.asarray(a) for a in SMALL_MARGINS(jnp.asarray(cogs), jnp.asarray(contacts), jnp.asarray(masks)))
    padded = np.concatenate([contacts, np.full((len(contacts), N - FEW, 3), 9.0)], axis=1)
    pmask = np.concatenate([masks, np.zeros((len(masks), N - FEW), bool)], axis=1)
    ref = MARG_V(cogs, padded, pmask, np.tile([1.0, 0.0], (len(cogs), 1)), np.tile([0.0, 0.0, 10.0], (len(cogs), N, 1)),
                 1e-3)
    np.testing.assert_allclose(static, np.asarray(ref["static"]), atol=1e-12, rtol=0)
    np.testing.assert_allclose(nesm, np.asarray(ref["nesm"]), atol=1e-12, rtol=0)
    assert (nesm > 0).sum() > 50 and (nesm < 0).sum() > 20 and np.isinf(nesm).sum() > 0
    f32 = SMALL_MARGINS(jnp.asarray(cogs, jnp.float32), jnp.asarray(contacts, jnp.float32), jnp.asarray(masks))
    for a, b in zip(f32, (static, nesm)):
        finite = np.isfinite(b)
        np.testing.assert_allclose(np.asarray(a)[finite], b[finite], atol=1e-4, rtol=0)


def test_few_contacts_margin_gradients():
    """The unrolled static margin and NESM against central differences (check_grads, fwd
    and rev) w.r.t. the COG and the contacts, inside and outside; masked rows get zero
    gradient, and so does a contact inside the support polygon."""
    contacts = np.array([[0.0, 0.0, 0.0], [0.6, 0.05, 0.08], [0.65, 0.5, 0.12], [0.05, 0.45, 0.03],
                         [0.3, 0.25, 0.05], [9.0, 9.0, 9.0]])
    mask = np.array([True, True, True, True, True, False])
    fn = jax.jit(lambda c, p: jnp.stack([sm.static_margin(c, p, jnp.asarray(mask)),
                                         sm.ne_stability_margin(c, p, jnp.asarray(mask))]))
    for cog in ([0.35, 0.2, 0.5], [0.9, 0.3, 0.4]):
        args = (jnp.asarray(cog), jnp.asarray(contacts))
        check_grads(fn, args, order=1, modes=["fwd", "rev"], eps=1e-6)
        jac = np.asarray(jax.jacrev(fn, argnums=1)(*args))
        assert np.all(jac[:, 5] == 0.0) and np.all(jac[:, 4] == 0.0) and np.all(np.isfinite(jac))


def test_many_contacts_nesm_uses_the_successor_edges():
    """With N = 16 contacts (beyond UNROLL_MAX_POINTS) the NESM's edges come from the
    vectorised gift-wrap (`small_hull_edges` on 16-vectors) and only the successor axes
    are evaluated: on 300 random scenes the successors are the all-pairs test's edges and the
    NESM equals the all-pairs form (every pair's margin) to 1e-12 m."""
    cogs, contacts, masks = _few_scenes(12, 300, size=N)
    _assert_successors_are_the_all_pairs_edges(contacts, masks)
    nesm, ref = (np.asarray(a) for a in NESM_BOTH(jnp.asarray(cogs), jnp.asarray(contacts), jnp.asarray(masks)))
    np.testing.assert_allclose(nesm, ref, atol=1e-12, rtol=0)
    assert (nesm > 0).sum() > 50 and (nesm < 0).sum() > 20


LONG_BOTH = jax.jit(jax.vmap(lambda c, p, m, d: (sm.longitudinal_margin(c, p, m, d),
                                                 sm._longitudinal_margin_all_pairs(c, p, m, d))))


@pytest.mark.parametrize("size", [FEW, N])
def test_longitudinal_margin_equals_the_all_pairs_form(size):
    """Up to UNROLL_MAX_POINTS contacts the longitudinal margin takes every pair's term
    over the gift-wrap's edges, beyond only the N successor axes' terms: on 300 random
    scenes (duplicates, collinear sets, garbage in masked rows, random travel directions)
    both equal the all-pairs form to 1e-12 m."""
    cogs, contacts, masks = _few_scenes(13 + size, 300, size=size)
    phi = np.random.default_rng(size).uniform(0, 2 * np.pi, len(cogs))
    dirs = np.stack([np.cos(phi), np.sin(phi)], axis=1)
    got, ref = (np.asarray(a) for a in LONG_BOTH(*(jnp.asarray(v) for v in (cogs, contacts, masks, dirs))))
    finite = np.isfinite(ref)
    np.testing.assert_array_equal(np.isfinite(got), finite)
    np.testing.assert_allclose(got[finite], ref[finite], atol=1e-12, rtol=0)
    assert (got > 0).sum() > 50 and (got < 0).sum() > 20


def test_the_minimum_over_edges_reads_only_the_minimisers_tangents():
    """Forward mode: a larger edge whose tangent is not finite (sqrt at 0) does not touch
    the derivative, which `jnp.min`'s 0/1-indicator product would make NaN; ties average."""

    def f(x):
        margins = jnp.stack([x, jnp.sqrt(x - 0.5) + 1.0, -x])  # the third is not an edge
        return sm._min_over_edges(margins, jnp.array([True, True, False]))

    value, tangent = jax.jvp(f, (0.5,), (1.0,))
    assert float(value) == 0.5 and float(tangent) == 1.0
    ties = jax.jvp(lambda x: sm._min_over_edges(jnp.stack([x, 2 * x - 0.5]), jnp.array([True, True])), (0.5,), (1.0,))
    assert float(ties[0]) == 0.5 and float(ties[1]) == 1.5
    assert float(sm._min_over_edges(jnp.array([1.0, jnp.inf]), jnp.array([False, False]))) == -np.inf
