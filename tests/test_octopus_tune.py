"""`octopus.sigma` tuning objective (jaxloco/robots/octopus/tuning.py):
  * it loads from the registry, its tunables are the analysis' sigma parameters and its
    "default (ours)" reference is params.SIGMA (the paper gives no values);
  * the sample bank is the `octopus.terrain_classification` sampling: the analysis'
    `run_sample` with the same key gives the same class (through the hard classifier) and
    the same ground truth;
  * the smooth classifier: a closed form at d = 0, vmap == loop, probabilities sum to one,
    and for a small temperature it agrees with the hard classifier (`terrain_case`) on
    every sample not near a threshold; the loss then tends to the hard cost;
  * the loss gradient against central finite differences;
  * a 3-step `jaxloco.tune.run` lowers the loss without lowering the hard accuracy
    (danger_weight 1) or raising the hard cost and the dangerous-error rate (default);
  * bad settings and starting values are one-line SpecErrors; the committed spec loads.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxloco.sweep
import jaxloco.tune
from jaxloco import specs
from jaxloco.errors import SpecError
from jaxloco.robots.octopus import analysis, tuning
from jaxloco.robots.octopus import kinematics as kin
from jaxloco.robots.octopus.params import SIGMA

SWEEPS = specs.DIRECTORY  # the bundled specs
SIGMA_NAMES = ("sigma1", "sigma2", "sigma3")
DEFAULTS = {p.name: p.default for p in tuning.SETTINGS}
SMALL = DEFAULTS | {"samples": 256, "seed": 3}


def _values(s1, s2, s3):
    return {"sigma1": jnp.asarray(s1), "sigma2": jnp.asarray(s2), "sigma3": jnp.asarray(s3)}


@pytest.fixture(scope="module")
def bank():
    return tuning.sample_bank(SMALL)


# ------------------------------------------------------------------ registry, bank
def test_objective_loads_from_the_registry_with_the_analysis_names():
    objective = jaxloco.tune.get("octopus.sigma")
    assert objective is tuning.SIGMA_TUNE
    assert tuple(t.name for t in objective.tunables) == SIGMA_NAMES
    for t in objective.tunables:  # same name as the sweep parameter, and a valid value of it
        analysis.TERRAIN_CLASSIFICATION.param(t.name).check(t.lo)
        analysis.TERRAIN_CLASSIFICATION.param(t.name).check(t.hi)
    assert dict(objective.references["default (ours)"]) == pytest.approx(dict(zip(SIGMA_NAMES, SIGMA.tolist())))
    analysis_defaults = {p.name: p.default for p in analysis.PARAMS}
    assert {k: analysis_defaults[k] for k in SIGMA_NAMES} == pytest.approx(tuning.DEFAULT_SIGMA)


def test_bank_is_the_analysis_sampling(bank):
    """Every sample through the analysis' own `run_sample` (same key, terrain, height):
    the same hard class for two sigma settings, the same truth and reachability."""
    n = 48
    types = bank["terrain"][:n]
    assert set(types.tolist()) == set(range(len(analysis.TERRAINS)))  # every terrain type drawn
    assert np.all((bank["height"] >= 0.0) & (bank["height"] <= SMALL["height_max"]))
    for sigma in (SIGMA, np.array([0.03, 0.3, 0.5])):
        base = {p.name: jnp.asarray(SMALL.get(p.name, p.default), jnp.float64) for p in analysis.PARAMS if p.sweepable}
        rows = {k: jnp.broadcast_to(v, (n,)) for k, v in base.items()} | {
            "terrain": jnp.asarray(types, jnp.int32),
            "height": jnp.asarray(bank["height"][:n]),
            **{k: jnp.full(n, s) for k, s in zip(SIGMA_NAMES, sigma)},
        }
        out = jax.jit(jax.vmap(analysis.run_sample))(rows, jnp.asarray(bank["key"][:n]))
        mine = jax.vmap(kin.terrain_case, in_axes=(0, None))(jnp.asarray(bank["diffs"][:n]), jnp.asarray(sigma))
        np.testing.assert_array_equal(np.asarray(out["case"]), np.asarray(mine))
        np.testing.assert_array_equal(np.asarray(out["truth"]), bank["truth"][:n])
        np.testing.assert_array_equal(np.asarray(out["margin"]) >= 0, bank["valid"][:n])


# ------------------------------------------------------------------ smooth classifier
def test_soft_classifier_closed_form_at_zero_and_vmap_equals_loop(bank):
    s1, tau = 0.05, 0.01
    p = tuning.soft_terrain_probs(jnp.zeros(2), jnp.asarray([s1, 0.4, 0.4]), tau)
    flat = (1.0 / (1.0 + np.exp(-s1 / tau))) ** 4  # four tests |0| < s1 at margin s1
    assert float(p[1]) == pytest.approx(flat, rel=1e-12)
    assert float(jnp.sum(p)) == pytest.approx(1.0, abs=1e-14)
    sigma = jnp.asarray([0.04, 0.35, 0.42])
    diffs = jnp.asarray(bank["diffs"][:5])
    batched = jax.vmap(lambda d: tuning.soft_terrain_probs(d, sigma, 0.02))(diffs)
    looped = np.stack([np.asarray(tuning.soft_terrain_probs(d, sigma, 0.02)) for d in diffs])
    np.testing.assert_allclose(np.asarray(batched), looped, rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(
        np.asarray(tuning.soft_terrain_probs(diffs, sigma, 0.02)), looped, rtol=1e-13, atol=1e-15
    )


@pytest.mark.parametrize("sigma", [tuple(SIGMA), (0.03, 0.3, 0.5), (0.1, 0.6, 0.2)])
def test_small_temperature_agrees_with_the_hard_classifier(bank, sigma):
    tau = 1e-4
    diffs = jnp.asarray(bank["diffs"])
    probs = np.asarray(tuning.soft_terrain_probs(diffs, jnp.asarray(sigma), tau))
    hard = np.asarray(jax.vmap(lambda d: kin.terrain_case(d, jnp.asarray(sigma)))(diffs))
    np.testing.assert_allclose(probs.sum(axis=1), 1.0, atol=1e-12)
    assert probs.min() >= 0.0
    s1, s2, s3 = sigma
    d = np.asarray(bank["diffs"])
    gap = np.min(np.abs(np.concatenate([d - s1, d + s1, d - s2, d + s3], axis=1)), axis=1)
    far = gap > 20 * tau
    assert far.mean() > 0.8
    np.testing.assert_array_equal(probs[far].argmax(axis=1), hard[far])
    assert probs[far].max(axis=1).min() > 1.0 - 1e-6
    # so the relaxed loss tends to the hard classifier's cost on the same bank
    loss, aux = tuning.make_loss(SMALL | {"tau": 1e-7})(_values(*sigma))
    assert float(loss) == pytest.approx(float(aux["hard_cost"]), abs=2e-3)
    assert float(aux["soft_accuracy"]) == pytest.approx(float(aux["accuracy"]), abs=2e-3)


# ------------------------------------------------------------------ gradient
def test_loss_gradient_matches_central_differences():
    loss_fn = tuning.make_loss(SMALL | {"tau": 0.01})
    evaluate = jax.jit(jax.value_and_grad(loss_fn, has_aux=True))
    values = _values(0.04, 0.4, 0.42)
    (loss, aux), grad = evaluate(values)
    assert set(aux) == set(tuning.AUX)
    assert float(loss) == pytest.approx(float(aux["soft_danger"] + aux["soft_undetectable"]), rel=1e-12)
    h = 1e-6
    for name in SIGMA_NAMES:
        up = float(evaluate({**values, name: values[name] + h})[0][0])
        down = float(evaluate({**values, name: values[name] - h})[0][0])
        fd = (up - down) / (2 * h)
        assert abs(fd) > 1e-3, name  # every threshold matters on this bank
        assert float(grad[name]) == pytest.approx(fd, rel=1e-5), name


# ------------------------------------------------------------------ tune runs
def _tune(tmp_path, **settings):
    spec = {
        "tune": {"objective": "octopus.sigma", "params": list(SIGMA_NAMES), "steps": 3, "learning_rate": 0.05,
                 "formats": ["parquet"]},
        "settings": {"samples": 512, **settings},
    }
    return jaxloco.tune.run(spec, progress=False, out=tmp_path / "out", configure_jax=False)


def test_three_steps_lower_the_error_without_losing_hard_accuracy(tmp_path):
    """danger_weight 1: the loss is the expected error rate of the relaxed classifier."""
    result = _tune(tmp_path, danger_weight=1.0)
    initial, best, paper = result.row("initial"), result.row("tuned"), result.row("default (ours)")
    assert result.curve.to_pydict()["step"] == [0, 1, 2, 3]
    assert best["loss"] < initial["loss"]
    assert best["accuracy"] >= initial["accuracy"]
    assert initial["loss"] == pytest.approx(1.0 - initial["soft_accuracy"], rel=1e-12)
    assert result.values("initial") == pytest.approx(tuning.DEFAULT_SIGMA)
    assert paper["loss"] == pytest.approx(initial["loss"], rel=1e-12)
    assert result.values("tuned") != result.values("initial")


def test_three_steps_lower_the_cost_and_the_dangerous_errors(tmp_path):
    result = _tune(tmp_path)
    initial, best = result.row("initial"), result.row("tuned")
    assert best["loss"] < initial["loss"]
    assert best["hard_cost"] <= initial["hard_cost"]
    assert best["danger_rate"] <= initial["danger_rate"]
    assert best["sigma2"] < initial["sigma2"]  # steep slopes look like climbable steps


# ------------------------------------------------------------------ errors, spec file
@pytest.mark.parametrize(
    ("settings", "init", "message"),
    [
        ({"tau": 0.0}, {}, "settings.tau"),
        ({"samples": 4}, {}, "settings.samples"),
        ({"terrains": "flat,ice"}, {}, "unknown terrain 'ice'"),
        ({"terrains": " , "}, {}, "settings.terrains: empty"),
        ({"height_min": 0.5, "height_max": 0.2}, {}, "height_min"),
        ({"flat_tol": 0.1, "step_min": 0.05}, {}, "flat_tol"),
        ({"sigma_flat": 0.1}, {}, "unknown setting 'sigma_flat'"),
        ({}, {"sigma1": 0.5}, "init.sigma1"),
        ({}, {"sigma2": 0.0}, "init.sigma2"),
    ],
)
def test_bad_settings_are_one_line_spec_errors(tmp_path, settings, init, message):
    spec = {"tune": {"objective": "octopus.sigma", "params": ["sigma1"], "steps": 1}, "settings": settings,
            "init": init}
    with pytest.raises(SpecError) as err:
        jaxloco.tune.run(spec, progress=False, out=tmp_path / "out", configure_jax=False)
    assert message in str(err.value) and "\n" not in str(err.value)
    assert not (tmp_path / "out").exists()


def test_committed_spec_loads():
    spec = jaxloco.tune.load_spec(SWEEPS / "octopus_sigma_tune.toml")
    assert spec.objective is tuning.SIGMA_TUNE and spec.name == "octopus_sigma_tune"
    assert spec.params == SIGMA_NAMES and dict(spec.init) == pytest.approx(tuning.DEFAULT_SIGMA)
    assert spec.settings["samples"] == 4096 and spec.settings["danger_weight"] == 4.0
    validation = jaxloco.sweep.load_spec(SWEEPS / "octopus_sigma.toml")
    assert set(SIGMA_NAMES) <= set(validation.swept)  # where the tuned values go for validation
