"""`leggrope.shear_relief`: the leg-grope walk's shear-relief gain tuned through an MJX
rollout of its closed loop, in forward mode.

Oracles: central finite differences of the same MJX loss (the gradient), the friction
cone's definition on synthetic records (the loss). The MJX test shares one compiled
forward-mode loss (a 0.6 s horizon, shorter than the shipped 1.5 s; compiling it is most
of this file's time, JAX's persistent cache keeps it).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from jaxloco import specs
from jaxloco.robots.leggrope import mjx_tuning
from jaxloco.tune import load_spec as load_tune
from jaxloco.tune import objective as registry
from jaxloco.tune import runner

HORIZON = 0.6  # [s] of the test rollout (settings otherwise the objective's defaults)
SETTINGS = {p.name: p.default for p in mjx_tuning.SETTINGS} | {"horizon": HORIZON}


def test_registered_in_forward_mode_with_its_spec():
    objective = registry.get("leggrope.shear_relief")
    assert objective is mjx_tuning.SHEAR_RELIEF_TUNE and objective.grad_mode == "forward"
    spec = load_tune("leggrope_shear_relief_tune")
    assert list(spec.params) == ["shear_relief"]
    assert spec.validation is not None and spec.validation.sweep.name == "leggrope_fragile.toml"
    assert 'backend = "native"' in (specs.DIRECTORY / "leggrope_fragile.toml").read_text()


def test_friction_use_on_synthetic_records():
    """Two records of four toes on a level foothold (normal z): in-plane reaction 3 N on a
    10 N normal load at mu = 0.5 is u = 0.6; a toe with no normal load counts its in-plane
    reaction over MIN_NORMAL; records before t_settle are left out."""
    f = np.zeros((3, 4, 3))
    f[..., 2] = 10.0
    f[..., 0] = 3.0
    f[1:, 3] = [0.2, 0.0, 0.0]  # toe 3 unloaded from t = 0.02 s on
    f[0] = 100.0  # before t_settle: ignored
    toe = np.zeros((3, 4, 3))
    toe[2, 1] = [0.003, 0.004, 0.0]
    records = {"foot_force": jnp.asarray(f), "normal_force": jnp.asarray(f[..., 2]), "toe_pos": jnp.asarray(toe)}
    m = mjx_tuning.friction_use(records, 0.5, jnp.array([0.0, 0.02, 0.04]), 0.02)
    u_light = 0.2 / (0.5 * mjx_tuning.MIN_NORMAL)
    assert float(m["loss"]) == pytest.approx((6 * 0.36 + 2 * u_light**2) / 8, rel=1e-12)
    assert float(m["mean_use"]) == pytest.approx((6 * 0.6 + 2 * u_light) / 8, rel=1e-12)
    assert float(m["max_use"]) == pytest.approx(max(0.6, u_light), rel=1e-12)
    assert float(m["toe_creep"]) == pytest.approx(0.005, rel=1e-12)


@pytest.fixture(scope="module")
def mjx_loss():
    """shear_relief -> (loss, aux, dloss/dshear_relief) of the objective (forward mode, as
    the runner uses it)."""
    f = runner.jitted_value_and_grad(mjx_tuning.make_loss(SETTINGS), "forward", ["shear_relief"],
                                     "leggrope.shear_relief")

    def evaluate(gain: float):
        (loss, aux), g = f({"shear_relief": jnp.float64(gain), "twist_relief": jnp.float64(0.02)})
        return float(loss), {a: float(v) for a, v in aux.items()}, float(g["shear_relief"])

    return evaluate


def test_forward_gradient_matches_central_differences(mjx_loss):
    """Central differences of the same MJX loss at the default gain 0.1 (m/s per M g),
    steps of 1e-5: the four toes stay loaded, so the loss is smooth there (the one-step
    slopes around the gain agree), and forward mode gives its slope."""
    g0, h = 0.1, 1e-5
    loss0, aux, grad = mjx_loss(g0)
    losses = [mjx_loss(g0 + j * h)[0] for j in (-2, -1)] + [loss0] + [mjx_loss(g0 + j * h)[0] for j in (1, 2)]
    slopes = np.diff(losses) / h
    central = (losses[3] - losses[1]) / (2 * h)
    assert 0.1 < loss0 < 1.0 and aux["max_use"] < 1.0  # no toe at the friction limit
    assert grad < -0.01  # a real slope: more relief spreads the friction use (measured -0.16)
    assert np.ptp(slopes) < 1e-3 * abs(grad), slopes  # no jump inside the stencil
    assert central == pytest.approx(grad, rel=1e-5), (central, grad)
