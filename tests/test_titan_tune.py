"""`titan.stride` tuning objective (`jaxloco.robots.titan.tuning`): registry and settings
checks, the reverse-mode gradient (custom VJP over forward mode through the planner's
while loops) against central differences, the loss and aux against the titan.stride
sweep analysis' own metrics (its batch function, `gait.sweep_plan`) and the closed form
of a fully held plan, a 3-step `jaxloco.tune.run`, and the committed spec.

One jitted `value_and_grad` (default case, 2 cycles), the tune runner's own for the tune
test's spec (`runner.make_evaluate`), serves the gradient, agreement and tune tests: the
tune run reuses its trace and compiled program."""

from __future__ import annotations

import math
from functools import cache

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxloco.tune
from jaxloco import specs
from jaxloco.errors import SpecError
from jaxloco.robots.titan import analysis as ta
from jaxloco.robots.titan import params as titan_params
from jaxloco.robots.titan import tuning
from jaxloco.sweep import chunks
from jaxloco.tune import runner

SWEEPS = specs.DIRECTORY  # the bundled specs
SETTINGS = {p.name: p.default for p in tuning.SETTINGS} | {"n_cycles": 2, "map_nx": 110}
# generic strides (no foothold exactly on a cell boundary) in the smooth part of the
# default case: no held cycle, no modification, the margin term active
POINTS = [(0.6137, 1.1421), (0.7423, 0.9611)]
HELD = (0.3, 0.8)  # the standard start is below S_NE^c: every cycle held
H = 1e-6  # [m] central-difference step (inside one piece of the plan)


def _tune_spec(**tune) -> dict:
    """The 3-step tune of `test_three_adam_steps_lower_the_loss` at SETTINGS."""
    return {
        "tune": {"objective": "titan.stride", "params": ["l_std", "w_std"], "steps": 3, "learning_rate": 0.1,
                 "formats": ["parquet"], **tune},
        "settings": {k: SETTINGS[k] for k in ("n_cycles", "map_nx")},
    }


@cache
def _evaluate():
    """The runner's jitted reverse-mode `values -> ((loss, aux), grads)` for `_tune_spec()`."""
    spec = jaxloco.tune.spec_from_dict(_tune_spec())
    assert dict(spec.settings) == SETTINGS
    return runner.make_evaluate(spec)


def _values(l_std, w_std):
    return {"l_std": jnp.float64(l_std), "w_std": jnp.float64(w_std)}


def _loss(l_std, w_std) -> float:
    return float(_evaluate()(_values(l_std, w_std))[0][0])


@pytest.fixture(scope="module")
def analysis_rows() -> dict[str, np.ndarray]:
    """The titan.stride batch function (the sweep's path) at POINTS, HELD and the paper stride."""
    fixed = {p.name: SETTINGS[p.name] for p in ta.PARAMS if p.name not in ("l_std", "w_std")}
    pts = [*POINTS, HELD, (titan_params.L_STD, titan_params.W_STD)]
    swept = {"l_std": jnp.asarray([p[0] for p in pts]), "w_std": jnp.asarray([p[1] for p in pts])}
    keys = jax.vmap(jax.random.PRNGKey)(jnp.arange(len(pts)))
    out = chunks.jitted_batch(ta.STRIDE.name, ta.STRIDE.batch_fn(fixed))(swept, keys)  # as a sweep jits it
    return {k: np.asarray(v) for k, v in out.items()}


# ------------------------------------------------------------------------ registry, specs
def test_registry_names_bounds_and_settings():
    obj = jaxloco.tune.get("titan.stride")
    assert obj is tuning.STRIDE_TUNE and obj.x64
    params = {p.name: p for p in ta.PARAMS}
    for t in obj.tunables:  # the sweep's names and ranges: tuned values go back into a sweep
        p = params[t.name]
        assert p.check(t.lo) == t.lo and p.check(t.hi) == t.hi and t.lo < t.default < t.hi
    assert obj.references["default (ours)"] == {"l_std": titan_params.L_STD, "w_std": titan_params.W_STD}
    assert {p.name for p in obj.settings} == (set(params) - {"l_std", "w_std"}) | {"w_margin", "n_offsets"}
    np.testing.assert_allclose(
        tuning.offsets(3), [(0.0, 0.0), (1 / 3, tuning.PHI), (2 / 3, 2 * tuning.PHI - 1)], rtol=1e-15
    )


@pytest.mark.parametrize(
    ("settings", "init", "match"),
    [
        ({"n_offsets": 2}, {}, "n_offsets"),  # flat ground has no frame phase to average
        ({"direction": 0.9}, {}, "direction"),
        ({"map_ny": 80}, {}, "map_ny >= "),
        ({"s_ne_c": 0.5}, {}, "s_ne_c"),
        ({"w_margin": -1.0}, {}, "w_margin"),
        ({"bogus": 1.0}, {}, "bogus"),
        ({}, {"l_std": 1.2}, "l_std"),
    ],
)
def test_bad_settings_are_one_line_spec_errors(settings, init, match, tmp_path):
    spec = {"tune": {"objective": "titan.stride", "params": ["l_std", "w_std"], "steps": 1},
            "settings": settings, "init": init}
    with pytest.raises(SpecError, match=match) as err:
        jaxloco.tune.run(spec, progress=False, out=tmp_path / "out", configure_jax=False)
    assert "\n" not in str(err.value)
    assert not (tmp_path / "out").exists()  # nothing computed or written


def test_committed_spec_loads():
    spec = jaxloco.tune.load_spec(SWEEPS / "titan_stride_tune.toml")
    assert spec.objective is tuning.STRIDE_TUNE and spec.name == "titan_stride_tune"
    assert set(spec.params) == {"l_std", "w_std"} and dict(spec.init) == pytest.approx(tuning.DEFAULT_STRIDE)
    assert spec.settings["slope"] == pytest.approx(math.radians(30.0))  # Sec. 8.4
    assert spec.settings["tether"] == 0.75 and spec.settings["frame_size"] == 0.0
    tuning.check_settings(spec.settings)


# ----------------------------------------------------------------------------- gradient
@pytest.mark.parametrize("point", POINTS)
def test_reverse_gradient_matches_central_differences(point):
    (_, aux), grad = _evaluate()(_values(*point))
    assert float(aux["n_failures"]) == 0 and float(aux["margin_penalty"]) > 1e-3
    for i, name in enumerate(("l_std", "w_std")):
        fd = {}
        for h in (H, 10 * H):
            up, down = list(point), list(point)
            up[i] += h
            down[i] -= h
            fd[h] = (_loss(*up) - _loss(*down)) / (2 * h)
        assert fd[H] == pytest.approx(fd[10 * H], rel=1e-4)  # both steps inside one piece
        assert abs(fd[H]) > 0.1  # the stride matters
        assert float(grad[name]) == pytest.approx(fd[H], rel=1e-5), name


# ------------------------------------------------------------------- agreement, closed form
def test_loss_and_aux_equal_the_analysis_metrics(analysis_rows):
    r = analysis_rows
    tau, s_c, w = SETTINGS["softmin_tau"], SETTINGS["s_ne_c"], SETTINGS["w_margin"]
    for i, point in enumerate([*POINTS, (titan_params.L_STD, titan_params.W_STD)]):
        j = i if i < len(POINTS) else len(POINTS) + 1
        (loss, aux), _ = _evaluate()(_values(*point))
        for k in ("distance_per_cycle", "min_nesm", "softmin_nesm", "objective", "path_deviation"):
            assert float(aux[k]) == pytest.approx(float(r[k][j]), rel=1e-12, abs=1e-14), (point, k)
        for k in ("n_failures", "n_modifications"):
            assert float(aux[k]) == int(r[k][j]), (point, k)
        assert r["n_failures"][j] == 0  # no held step: the loss's soft-min is the analysis'
        expected = -r["distance_per_cycle"][j] / (2 * titan_params.L_STD) + w * np.logaddexp(
            0.0, (s_c - r["softmin_nesm"][j]) / tau
        )
        assert float(loss) == pytest.approx(expected, rel=1e-12)
        assert (float(aux["steps_below"]) == 0) == bool(r["status"][j] != 2)


def test_fully_held_plan_has_the_closed_form_loss(analysis_rows):
    """Every cycle held: d = 0 and the 6 n_cycles steps count at S_NE^c, so the soft-min is
    S_NE^c - tau log(6 n) and the loss w_margin log(1 + 6 n), whatever the standing NESM."""
    r = analysis_rows
    j = len(POINTS)
    assert r["n_failures"][j] == SETTINGS["n_cycles"] and r["status"][j] == 1
    (loss, aux), grad = _evaluate()(_values(*HELD))
    assert float(aux["distance_per_cycle"]) == 0.0 and float(aux["softmin_nesm"]) == pytest.approx(r["softmin_nesm"][j])
    assert float(r["softmin_nesm"][j]) > 0.5  # standing on four legs: a large margin, not rewarded
    assert float(loss) == pytest.approx(SETTINGS["w_margin"] * math.log1p(6 * SETTINGS["n_cycles"]), rel=1e-12)
    assert all(float(g) == 0.0 for g in grad.values())  # held cycles: nothing moves with the stride


# ---------------------------------------------------------------------------------- tune
def test_three_adam_steps_lower_the_loss(tmp_path, analysis_rows):
    res = jaxloco.tune.run(_tune_spec(), progress=False, out=tmp_path / "out", configure_jax=False)
    curve = res.curve.to_pydict()
    assert curve["step"] == [0, 1, 2, 3]
    initial, best, paper = res.row("initial"), res.row("tuned"), res.row("default (ours)")
    assert res.values("initial") == pytest.approx(tuning.DEFAULT_STRIDE) and paper["loss"] == pytest.approx(
        initial["loss"]
    )
    assert initial["loss"] == pytest.approx(_loss(titan_params.L_STD, titan_params.W_STD), rel=1e-12)
    assert initial["min_nesm"] == pytest.approx(float(analysis_rows["min_nesm"][-1]), rel=1e-12)
    assert best["loss"] == min(curve["loss"]) < initial["loss"] - 0.1
    tuned = res.values("tuned")
    assert all(t.lo < tuned[t.name] < t.hi for t in tuning.TUNABLES) and tuned != res.values("initial")
    assert (res.path / "loss_curve.parquet").exists()
