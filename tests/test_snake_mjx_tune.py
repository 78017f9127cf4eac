"""`snake.reach_gain` (T² Snake-3's task gain K tuned through an MJX rollout in forward
mode), the `snake.reach` native sweep analysis, and the tune runner's forward mode.

Oracles: reverse-mode gradients (forward mode of the runner), central finite
differences of the same MJX loss (the gradient), MuJoCo's C code through the native
backend (the MJX loss), one-row runs (the batched analysis), closed forms (the metrics).
The MJX tests share one compiled forward-mode loss (a 1 s horizon, shorter than the
shipped 3 s; compiling it is most of this file's time, JAX's persistent cache keeps it):
the runner's own (`runner.make_evaluate` keeps one per objective and settings), so the
short tune reuses its trace.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxloco import analysis
from jaxloco.analysis import Param
from jaxloco.robots.snake import mjx_tuning, sim_analysis
from jaxloco.sim.rollout import rollout
from jaxloco.tune import objective as registry
from jaxloco.tune import runner
from jaxloco.tune.objective import Objective, Tunable
from jaxloco.tune.spec import spec_from_dict

HORIZON = 1.0  # [s] of the test rollouts (settings otherwise the objective's defaults)
SETTINGS = {p.name: p.default for p in mjx_tuning.SETTINGS} | {"horizon": HORIZON}


# ------------------------------------------------------------------ grad_mode (toy)
def _toy_loss(settings):
    def loss_fn(v):
        a, b, c = v["a"], v["b"], v["c"]
        loss = jnp.sin(a) * b**2 + jnp.exp(0.3 * a * b) + (c - 1.0) ** 2 + settings["w"] * a**4
        return loss, {"ab": a * b}

    return loss_fn


def _toy(mode: str) -> Objective:
    return registry.register(Objective(
        name=f"test.snake_mjx_toy_{mode}",
        doc="a smooth toy loss of three tunables",
        tunables=(Tunable("a", 0.4, "a", scale="log"), Tunable("b", -0.5, "b", lo=-2.0, hi=2.0),
                  Tunable("c", 0.0, "c (never tuned here)")),
        settings=(Param("w", 0.1, "weight of a**4", lo=0.0),),
        make_loss=_toy_loss,
        grad_mode=mode,
    ))


def test_forward_mode_gives_the_reverse_mode_gradient():
    loss_fn = _toy_loss({"w": 0.1})
    values = {"a": jnp.float64(0.7), "b": jnp.float64(-0.3), "c": jnp.float64(2.0)}
    (l_r, aux_r), g_r = jax.jit(runner.value_and_grad(loss_fn, "reverse"))(values)
    (l_f, aux_f), g_f = jax.jit(runner.value_and_grad(loss_fn, "forward"))(values)
    assert float(l_f) == float(l_r) and float(aux_f["ab"]) == float(aux_r["ab"])
    for k in values:
        np.testing.assert_allclose(g_f[k], g_r[k], rtol=1e-13, atol=1e-15)
    # one tuned entry: one jvp instead of jacfwd, the same loss, aux and slope
    (l_a, aux_a), g_a = jax.jit(runner.value_and_grad(loss_fn, "forward", ["a"]))(values)
    assert float(l_a) == float(l_r) and float(aux_a["ab"]) == float(aux_r["ab"])
    assert set(g_a) == {"a"} and np.shape(g_a["a"]) == () and g_a["a"].dtype == g_r["a"].dtype
    assert float(g_a["a"]) == pytest.approx(float(g_r["a"]), rel=1e-13)
    assert float(g_a["a"]) == pytest.approx(float(g_f["a"]), rel=1e-14)
    assert abs(float(g_r["b"])) > 0.1  # the check above compares non-trivial numbers
    with pytest.raises(ValueError, match="grad mode"):
        runner.value_and_grad(loss_fn, "sideways")


def test_a_forward_mode_objective_tunes_as_the_reverse_mode_one(tmp_path):
    curves = {}
    for mode in ("reverse", "forward"):
        spec = {"tune": {"objective": _toy(mode).name, "params": ["a", "b"], "learning_rate": 0.05, "steps": 8,
                         "formats": ["parquet"]}}
        res = runner.run(spec_from_dict(spec), progress=False, out=tmp_path / mode, configure_jax=False)
        curves[mode] = res.curve.to_pydict()
    for key in ("loss", "grad_norm", "a", "b", "c"):
        np.testing.assert_allclose(curves["forward"][key], curves["reverse"][key], rtol=1e-12)
    assert curves["forward"]["loss"][-1] < curves["forward"]["loss"][0]
    assert set(curves["forward"]["c"]) == {0.0}


def test_objective_checks_grad_mode():
    with pytest.raises(ValueError, match="grad_mode"):
        Objective(name="x", doc="", tunables=(Tunable("a", 1.0, "a"),), settings=(),
                  make_loss=_toy_loss, grad_mode="backward")
    assert registry.get("snake.reach_gain").grad_mode == "forward"


# ---------------------------------------------------------------------- metrics
def test_reach_metrics_closed_form():
    """A synthetic tip that follows the target plus an error c exp(-t / tau) along z."""
    dt, n, t0, ramp, dz, c, tau, tol = 0.02, 101, 0.1, 0.8, 0.03, 0.01, 0.3, 0.002
    t = np.arange(n) * dt
    x = np.clip((t - t0) / ramp, 0.0, 1.0)
    s = x - np.sin(2 * np.pi * x) / (2 * np.pi)
    e = np.where(t >= t0, c * np.exp(-(t - t0) / tau), 0.0)
    p0 = np.array([0.4, -0.1, 0.27])
    tip = np.zeros((n, 6))
    tip[:, :3] = p0 + np.outer(s * dz + e, [0.0, 0.0, 1.0])
    rng = np.random.default_rng(0)
    cmd = np.cumsum(rng.normal(0.0, 0.01, (n, 12)), 0)
    m = {k: float(v) for k, v in jax.jit(sim_analysis.reach_metrics)(jnp.asarray(tip), jnp.asarray(cmd),
                                                           jnp.array([0.0, 0.0, dz]), t0, ramp, tol, 0.5).items()}
    effort = np.mean(np.sum((np.diff(cmd, axis=0) / dt) ** 2, -1))
    assert m["final_error"] == pytest.approx(e[-1], rel=1e-9)
    assert m["max_error"] == pytest.approx(c, rel=1e-9)
    assert m["rms_error"] == pytest.approx(np.sqrt(np.mean(e**2)), rel=1e-9)
    assert m["effort"] == pytest.approx(effort, rel=1e-12)
    assert m["loss"] == pytest.approx(np.mean(e**2) / 0.01**2 + 0.5 * effort, rel=1e-9)
    t_in = t[np.argmax((t >= t0) & (e <= tol))]  # e decreases: first record inside the band
    assert t_in > t0 + tau * math.log(c / tol) - 1e-9
    assert m["settle_time"] == pytest.approx(t_in - t0, abs=1e-12)
    assert m["overshoot"] == pytest.approx(max(np.max(s * dz + e) - dz, 0.0) / dz, rel=1e-9)
    assert m["overshoot"] > 0.0
    # never inside the band: nan; no target displacement: no overshoot
    never = sim_analysis.reach_metrics(
        jnp.asarray(tip), jnp.asarray(cmd), jnp.array([0.0, 0.0, dz]), t0, ramp, 1e-9, 0.0
    )
    assert math.isnan(float(never["settle_time"]))
    still = sim_analysis.reach_metrics(jnp.asarray(tip), jnp.asarray(cmd), jnp.zeros(3), t0, ramp, tol, 0.0)
    assert float(still["overshoot"]) == 0.0


# ------------------------------------------------------------------------- MJX
def _tune_spec(**tune):
    """The short tune of K at HORIZON (`test_a_short_tune_lowers_the_loss`)."""
    return spec_from_dict({"tune": {"objective": "snake.reach_gain", "params": ["gain_k"], "learning_rate": 0.15,
                                    "steps": 1, "formats": ["parquet"], **tune},
                           "init": {"gain_k": 1.0}, "settings": {"horizon": HORIZON}})


@pytest.fixture(scope="module")
def mjx_loss():
    """K -> ((loss, aux), dloss/dK) of the objective: the runner's own jitted forward-mode
    function for the short tune's spec (the tune then reuses its trace)."""
    spec = _tune_spec()
    assert dict(spec.settings) == SETTINGS
    f = runner.make_evaluate(spec)

    def evaluate(k: float):
        (loss, aux), g = f({"gain_k": jnp.float64(k), "k_eta": jnp.float64(0.1)})
        return float(loss), {a: float(v) for a, v in aux.items()}, float(g["gain_k"])

    return evaluate


def test_forward_gradient_matches_central_differences(mjx_loss):
    """Central differences of the same MJX loss with steps of 1e-5 in K, inside one
    smooth piece (the loss jumps by ~1e-4 every ~1e-4 of K: contact-point and solver
    changes, see `mjx_tuning`); the four one-step slopes around K must agree."""
    k0, h = 1.0, 1e-5
    loss0, _, grad = mjx_loss(k0)
    losses = [mjx_loss(k0 + j * h)[0] for j in (-2, -1)] + [loss0] + [mjx_loss(k0 + j * h)[0] for j in (1, 2)]
    slopes = np.diff(losses) / h
    central = (losses[3] - losses[1]) / (2 * h)
    assert abs(grad) > 0.01  # a real slope (measured 0.03; loss ~0.3, K ~1)
    assert np.ptp(slopes) < 1e-3 * abs(grad), slopes  # no jump inside the stencil
    assert central == pytest.approx(grad, rel=1e-5), (central, grad)


@pytest.mark.parametrize("ground", ["plane", "box"])
def test_mjx_loss_agrees_with_native_mujoco(mjx_loss, ground):
    """The same scenario (settled state, controller) on MuJoCo's C code: on the plane
    ground (the model MJX runs), and on the box ground (the native model of `snake.reach`,
    whose MJX variant the plane is; docs/simulation.md states this tolerance)."""
    gains = (1.0, 2.5)
    sc = sim_analysis.reach_scenario(ground, HORIZON, SETTINGS["settle"])
    res = rollout(sc, sim_analysis.reach_params(len(gains), gain_k=np.array(gains), d_z=SETTINGS["d_z"],
                                     t_start=SETTINGS["t_start"], ramp=SETTINGS["ramp"]), backend="native")
    assert list(res.status) == ["ok", "ok"]
    native = jax.vmap(lambda tip, cmd: sim_analysis.reach_metrics(tip, cmd, jnp.array([0.0, 0.0, SETTINGS["d_z"]]),
                                                       SETTINGS["t_start"], SETTINGS["ramp"], 1.0,
                                                       SETTINGS["w_effort"]))(
        jnp.asarray(res.records["tip"]), jnp.asarray(res.records["phi_cmd"]))
    losses = []
    for i, k in enumerate(gains):
        loss, aux, _ = mjx_loss(k)
        losses.append(loss)
        assert loss == pytest.approx(float(native["loss"][i]), rel=0.01)
        for name in ("rms_error", "max_error", "final_error"):
            assert aux[name] == pytest.approx(float(native[name][i]), abs=3e-4)  # 0.3 mm
    assert abs(losses[1] - losses[0]) > 0.05 * losses[0]  # the gains differ measurably


def test_a_short_tune_lowers_the_loss(tmp_path, mjx_loss):
    spec = _tune_spec()
    assert runner.make_evaluate(spec) is runner.make_evaluate(_tune_spec(learning_rate=0.3))  # the fixture's
    res = runner.run(spec, progress=False, out=tmp_path / "tune", configure_jax=False)
    curve = res.curve.to_pydict()
    loss0, _, grad0 = mjx_loss(1.0)
    assert curve["loss"][0] == pytest.approx(loss0, rel=1e-12)
    assert grad0 < 0 and curve["gain_k"][1] > 1.0  # downhill: K grows at this horizon
    assert min(curve["loss"][1:]) < curve["loss"][0]
    assert res.row("paper")["loss"] == pytest.approx(loss0, rel=1e-12)
    assert set(curve["k_eta"]) == {0.1}


# ------------------------------------------------------------------- the analysis
def test_reach_analysis_batch_equals_single_rows():
    assert analysis.get("snake.reach") is sim_analysis.REACH
    fixed = {p.name: p.default for p in sim_analysis.PARAMS} | {
        "ground": mjx_tuning.GROUND,
        "horizon": HORIZON,
        "nthread": 2,
    }
    fn = sim_analysis.REACH.batch_fn(fixed)
    swept = {"gain_k": np.array([0.5, 1.0, 3.0]), "d_z": np.array([0.03, -0.02, 0.03])}
    keys = np.zeros((3, 2), np.uint32)
    batch = fn(swept, keys)
    assert set(batch) == {m.name for m in sim_analysis.METRICS} | {"status"}
    for i in range(3):
        row = fn({k: v[i:i + 1] for k, v in swept.items()}, keys[i:i + 1])
        for name, value in row.items():  # the physics is bit-identical; XLA's reductions may round differently
            # (final_error 1.3e-12 relative, 2e-15 m, with XLA's legacy CPU emitters)
            np.testing.assert_allclose(value, batch[name][i:i + 1], rtol=1e-11, atol=0.0, err_msg=name)
    assert list(batch["status"]) == [0, 0, 0]
    assert np.all(batch["max_error"] >= batch["final_error"]) and np.all(batch["max_error"] > 0.002)


def test_reach_analysis_rejects_a_bad_ground():
    with pytest.raises(analysis.SpecError, match="ground"):
        sim_analysis.build_model("sand")
