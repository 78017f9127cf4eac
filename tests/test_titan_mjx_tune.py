"""`titan.body_gain`: the footstep executor's body-correction gain tuned through an MJX
rollout in forward mode. Oracles: central finite differences of the same MJX loss (the
gradient), closed forms (the loss on synthetic records), the bundled spec. (The loss on
native MuJoCo: `benchmarks/titan_mjx_agreement.py`; the backends' agreement on the walks:
`tests/test_titan_mjx.py`.) The MJX tests
share one compiled forward-mode loss (a 4 s horizon, shorter than the default 10 s;
compiled with XLA's optimisations, `xla_optimized`: compiling it is most of this file's
time, JAX's persistent cache keeps it)."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest
from xla_optimized import optimized

from jaxloco.robots.titan import mjx_tuning
from jaxloco.robots.titan import params as titan_params
from jaxloco.tune import load_spec, runner
from jaxloco.tune import objective as registry

HORIZON = 4.0  # [s]: the settling and the first swing
SETTINGS = {p.name: p.default for p in mjx_tuning.SETTINGS} | {"horizon": HORIZON}


def test_registered_forward_mode_with_the_table_s_tunable():
    obj = registry.get("titan.body_gain")
    assert obj is mjx_tuning.BODY_GAIN_TUNE and obj.grad_mode == "forward"
    (gain,) = obj.tunables
    assert gain.name == "body_gain" and gain.default == titan_params.PARAMETERS.default("body_gain")
    assert gain.scale == "log" and gain.hi == titan_params.PARAMETERS["body_gain"].hi
    assert {p.name for p in obj.settings} == {"slope", "tether", "mu", "horizon"}
    assert obj.setting("slope").default == pytest.approx(float(titan_params.SLOPE_ANGLE))


def test_committed_spec_validates_on_native_mujoco():
    spec = load_spec("titan_body_gain_tune")
    assert spec.objective.name == "titan.body_gain" and spec.params == ("body_gain",)
    from jaxloco.sweep import load_spec as load_sweep

    sweep = load_sweep(spec.validation.sweep)
    assert sweep.analysis.name == "titan.walk" and sweep.fixed.get("backend", "native") == "native"
    assert "body_gain" in {p.name for p in sweep.analysis.params}


def test_cog_error_closed_form():
    """Records with a constant in-plane error c and an error along the normal that the
    loss ignores, the settling records excluded."""
    p = mjx_tuning.loss_params(SETTINGS)
    p = {k: jnp.asarray(v[0]) for k, v in p.items()}
    theta = SETTINGS["slope"]
    n = np.array([-np.sin(theta), 0.0, np.cos(theta)])
    up = np.array([np.cos(theta), 0.0, np.sin(theta)])  # in the plane, up the fall line
    t, c = 50, 0.004
    step = np.where(np.arange(t) < 10, -1, 0)
    target = np.zeros((t, 3))
    cog = target + c * up + 0.02 * n
    cog[:10] += 0.5 * up  # settling: not counted
    cog[30] += 0.01 * np.array([0.0, 1.0, 0.0])
    m = mjx_tuning.cog_error(p, {"cog": jnp.asarray(cog), "cog_target": jnp.asarray(target),
                                 "step": jnp.asarray(step)})
    e2 = np.full(t - 10, c**2)
    e2[20] += 0.01**2
    assert float(m["loss"]) == pytest.approx(1e6 * e2.mean(), rel=1e-12)
    assert float(m["rms_cog_error"]) == pytest.approx(np.sqrt(e2.mean()), rel=1e-12)
    assert float(m["max_cog_error"]) == pytest.approx(np.sqrt(c**2 + 0.01**2), rel=1e-12)


@pytest.fixture(scope="module")
def mjx_loss():
    """gain -> ((loss, aux), dloss/dgain) of the objective (forward mode, as the runner uses it)."""
    f = runner.jitted_value_and_grad(mjx_tuning.make_loss(SETTINGS), "forward", ["body_gain"], "titan.body_gain")

    def evaluate(gain: float):
        with optimized():  # compiled once, on the first call
            (loss, aux), g = f({"body_gain": jnp.float64(gain)})
        return float(loss), {a: float(v) for a, v in aux.items()}, float(g["body_gain"])

    return evaluate


def test_forward_gradient_matches_central_differences(mjx_loss):
    """Central differences of the same MJX loss with steps of 1e-3 /s in the gain; the four
    one-step slopes around it agree (no contact or latch jump inside the stencil)."""
    g0, h = 3.0, 1e-3
    loss0, aux, grad = mjx_loss(g0)
    losses = [mjx_loss(g0 + j * h)[0] for j in (-2, -1)] + [loss0] + [mjx_loss(g0 + j * h)[0] for j in (1, 2)]
    slopes = np.diff(losses) / h
    central = (losses[3] - losses[1]) / (2 * h)
    assert abs(grad) * g0 > 1e-3 * loss0  # a real slope
    assert np.ptp(slopes) < 0.05 * abs(grad), slopes
    assert central == pytest.approx(grad, rel=1e-4), (central, grad)
    # the walk is sane: standing on three legs with the plan's margin, little slip
    assert aux["min_nesm"] > 0.08 and aux["foot_slip"] < 0.02 and aux["max_cog_error"] < 0.02
    assert loss0 == pytest.approx(1e6 * aux["rms_cog_error"] ** 2, rel=1e-12)

