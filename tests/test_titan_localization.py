"""TITAN XI self-localisation by surveying (Sec. 8.2.2, `localization.py`): the circle
through three total-station points, the pose from its centre and axis plus a
single-axis attitude sensor (both readings of the mount), exact without noise, errors
proportional to the survey noise, vmap and gradients."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxloco import geometry as geo
from jaxloco.robots.titan import localization

CENTRE_B = jnp.array([-1.0, 0.4, 1.6])  # [m] the mechanism on the trunk's top, ours
RADIUS = 0.5  # [m]
PHASES = jnp.array([0.2, 2.0, 4.1])  # [rad] three arbitrary points, in time order


def _poses(n, seed=0):
    rng = np.random.default_rng(seed)
    euler = np.c_[rng.uniform(-np.pi, np.pi, n), rng.uniform(-0.6, 0.6, n), rng.uniform(-0.6, 0.6, n)]
    pos = rng.uniform(-20.0, 20.0, (n, 3))
    return jnp.asarray(pos), jnp.asarray(euler)


def _measure(pos, euler, mount, noise=0.0, key=None):
    R = geo.rpy_to_matrix(euler[2], euler[1], euler[0])
    pts = localization.cube_points(pos, R, CENTRE_B, RADIUS, PHASES, mount)
    if noise:
        pts = pts + noise * jax.random.normal(key, pts.shape)
    angle = euler[2] if mount == "x" else euler[0]  # the single-axis sensor: roll or heading
    return pts, angle


def test_circle_through_three_points_is_exact():
    rng = np.random.default_rng(3)
    for _ in range(20):
        c, r = rng.normal(size=3), rng.uniform(0.2, 3.0)
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        e1 = np.cross(u, [0.3, -0.5, 0.8])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(u, e1)
        ph = np.sort(rng.uniform(0.0, 2 * np.pi, 3))
        pts = c + r * (np.cos(ph)[:, None] * e1 + np.sin(ph)[:, None] * e2)
        circ = localization.circle_through(*jnp.asarray(pts))
        np.testing.assert_allclose(circ.centre, c, atol=1e-9)
        np.testing.assert_allclose(circ.axis, u, atol=1e-9)  # the sign from the turning sense
        assert float(circ.radius) == pytest.approx(r, rel=1e-9)


@pytest.mark.parametrize("mount", localization.MOUNTS)
def test_pose_is_recovered_exactly_without_noise(mount):
    pos, euler = _poses(50)
    run = jax.jit(jax.vmap(lambda p, e: localization.localize(*_measure(p, e, mount), CENTRE_B, mount)))
    pose = run(pos, euler)
    np.testing.assert_allclose(pose.position, pos, atol=1e-8)
    np.testing.assert_allclose(pose.euler, euler, atol=1e-9)
    R = jax.vmap(lambda e: geo.rpy_to_matrix(e[2], e[1], e[0]))(euler)
    np.testing.assert_allclose(pose.rotation, R, atol=1e-9)


def test_the_two_mount_readings_differ():
    pos, euler = _poses(1, seed=5)
    pts, _ = _measure(pos[0], euler[0], "x")
    wrong = localization.localize(pts, euler[0, 0], CENTRE_B, "z")  # x-mounted data read as z-mounted
    assert float(jnp.abs(wrong.position - pos[0]).max()) > 0.1
    with pytest.raises(ValueError, match="mount"):
        localization.localize(pts, 0.0, CENTRE_B, "y")


def test_survey_noise_gives_proportional_pose_errors():
    """Points measured with N(0, sigma) noise per axis: the pose errors grow linearly with
    sigma (first-order error propagation) and stay at a few sigma / radius in angle; at
    the survey's 5 mm the position is within a few cm (the 1.7 m lever arm of the
    mechanism turns angle errors into position errors)."""
    pos, euler = _poses(400, seed=1)
    keys = jax.random.split(jax.random.PRNGKey(0), 400)

    def errors(sigma):
        def one(p, e, k):
            pose = localization.localize(*_measure(p, e, "x", sigma, k), CENTRE_B, "x")
            d = pose.euler - e
            d = jnp.arctan2(jnp.sin(d), jnp.cos(d))
            return jnp.linalg.norm(pose.position - p), jnp.abs(d[:2]).max()

        dp, da = jax.jit(jax.vmap(one))(pos, euler, keys)
        return float(jnp.sqrt(jnp.mean(dp**2))), float(jnp.sqrt(jnp.mean(da**2)))

    p1, a1 = errors(0.001)
    p5, a5 = errors(0.005)
    assert p5 / p1 == pytest.approx(5.0, rel=0.1) and a5 / a1 == pytest.approx(5.0, rel=0.1)
    assert a5 < 3 * 0.005 / RADIUS
    assert p5 < 0.05


def test_pose_is_differentiable_in_the_measurements():
    pos, euler = _poses(1, seed=2)
    pts, angle = _measure(pos[0], euler[0], "x")
    jac = jax.jacfwd(lambda q: localization.localize(q, angle, CENTRE_B).position)(pts)
    assert jac.shape == (3, 3, 3) and bool(jnp.all(jnp.isfinite(jac)))
    g = jax.grad(lambda q: localization.localize(q, angle, CENTRE_B).euler[0])(pts)
    h = 1e-6
    fd = (localization.localize(pts.at[1, 0].add(h), angle, CENTRE_B).euler[0]
          - localization.localize(pts.at[1, 0].add(-h), angle, CENTRE_B).euler[0]) / (2 * h)
    assert float(g[1, 0]) == pytest.approx(float(fd), rel=1e-5)
