"""`snake.kv` sweep analysis and tuning objective (T² Snake-3 joint-limit avoidance,
Sec. V-B, in the kinematic simulation):

  * the batch function equals `run_one` row by row; statuses agree with the metrics;
  * `limit_loss` against its formula, and larger for a posture kept near the limits;
  * a short sweep through `jaxloco.sweep.run`: the table and `summarize` (ranking, the
    paper's K_V row marked);
  * `jaxloco tune` with `KV_TUNE`: 3 Adam steps lower the loss, the "paper" reference;
    the loss's gradient (reverse mode through the rollout) against finite differences;
  * the committed spec files load and validate.

Short horizons (1-2 s, dt 0.05) keep the compiled programs small."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxloco.sweep
import jaxloco.tune
from jaxloco import specs
from jaxloco.robots.snake import analysis, control, experiments, params, tuning
from jaxloco.sweep import chunks

SWEEPS = specs.DIRECTORY  # the bundled specs
HORIZON, DT = 2.0, 0.05
DEFAULTS = {p.name: p.default for p in analysis.PARAMS}
SWEPT = {  # three rows: paper gains; k_eta 0.5 in the reverse mode order; a low zigzag
    "k_eta": [0.1, 0.5, 0.1],
    "mode_order": [0, 1, 2],
    "amplitude": [1.1, 1.1, 0.5],
}
STATUS = {name: i for i, name in enumerate(analysis.STATUSES)}


def _row_values(i: int) -> dict[str, jax.Array]:
    values = {}
    for p in analysis.PARAMS:
        if not p.sweepable:
            continue
        v = SWEPT[p.name][i] if p.name in SWEPT else DEFAULTS[p.name]
        values[p.name] = jnp.asarray(v, jnp.int32 if p.name == "mode_order" else jnp.float64)
    return values


@pytest.fixture(scope="module")
def rows():
    """(batch metrics, [run_one metrics and records per row])."""
    fixed = {k: v for k, v in DEFAULTS.items() if k not in SWEPT} | {"horizon": HORIZON, "dt": DT}
    batch_fn = chunks.jitted_batch(analysis.KV.name, analysis.KV.batch_fn(fixed))  # as a sweep jits it
    swept = {k: jnp.asarray(v, jnp.int32 if k == "mode_order" else jnp.float64) for k, v in SWEPT.items()}
    keys = jnp.zeros((3, 2), jnp.uint32)
    batch = {k: np.asarray(v) for k, v in batch_fn(swept, keys).items()}
    config = analysis.rollout_config(HORIZON, DT, False)
    one = jax.jit(lambda v: analysis.run_one(v, config))
    singles = [jax.tree_util.tree_map(np.asarray, one(_row_values(i))) for i in range(3)]
    return batch, singles


def test_batch_fn_equals_run_one_row_by_row(rows):
    batch, singles = rows
    assert set(batch) == {m.name for m in analysis.METRICS} | {"status"}
    for i, (m, recs) in enumerate(singles):
        for key in batch:
            np.testing.assert_allclose(batch[key][i], m[key], rtol=1e-9, atol=1e-12, err_msg=f"row {i}: {key}")
        assert recs["t"].shape == (round(HORIZON / DT) + 1,)
        # the rows' own settings reached the rollout: the mode schedule of their order
        order = analysis.MODE_ORDERS[SWEPT["mode_order"][i]]
        switching = recs["t"] >= experiments.SWITCH_AT - 1e-9
        assert np.all(recs["sigma"][~switching] == 1)
        assert np.all(recs["sigma"][switching] == order[0])  # t in [2, 3)
    # the three rows differ where they should
    assert len({round(float(x), 12) for x in batch["loss"]}) == 3


def test_statuses_agree_with_the_metrics(rows):
    batch, singles = rows
    for i, (m, recs) in enumerate(singles):
        pos = np.linalg.norm(recs["error"][:, :3], axis=-1).max()
        att = np.linalg.norm(recs["error"][:, 3:6], axis=-1).max()
        assert m["max_pos_error"] == pytest.approx(pos, rel=1e-12)
        assert m["max_att_error"] == pytest.approx(att, rel=1e-12)
        assert m["max_pos_component_error"] == np.abs(recs["error"][:, :3]).max()
        assert m["max_att_component_error"] == np.abs(recs["error"][:, 3:6]).max()
        assert m["max_pos_component_error"] <= m["max_pos_error"] <= np.sqrt(3) * m["max_pos_component_error"]
        assert bool(m["head_ok"]) == (pos <= 0.03 and att <= 0.1)
        ratio = np.abs(recs["phi"][:, params.N_H :]).max(axis=1) / params.YAW_LIMIT
        below = ratio <= DEFAULTS["recover_ratio"]
        assert bool(m["recovered"]) == below.any()
        expected_t = recs["t"][np.argmax(below)] if below.any() else recs["t"][-1] + DT
        assert m["recovery_time"] == pytest.approx(expected_t)
        expected = "ok" if (below.any() and m["head_ok"]) else (
            "failed: base joints not recovered within the horizon" if not below.any()
            else "failed: head error above 30 mm / 0.1 rad")
        assert int(m["status"]) == STATUS[expected]
    # 2 s from the zigzag at 97 % is too short to recover; the 0.5 rad zigzag (44 %) starts recovered
    assert [int(s) for s in batch["status"]] == [1, 1, 0]
    assert batch["recovery_time"][2] == 0.0
    # the posture kept near the limits costs more
    assert batch["loss"][0] > 1.0 > batch["loss"][2]
    assert batch["time_near_limit"][0] > 1.0 and batch["time_near_limit"][2] == 0.0


def _softplus(x):
    return np.logaddexp(0.0, x)


def test_limit_loss_formula_and_its_limits():
    """mean_t[(|e_p|/30 mm)^2 + (|e_a|/0.1 rad)^2] + w_limit mean_t sum_j T softplus((r_j -
    r0)/T)/(1 - r0): one per base joint at its limit, ~0 far below r0, 1 for a 30 mm or
    0.1 rad head error."""
    n, T, r0 = 5, 0.02, 0.7
    rng = np.random.default_rng(0)
    phi = np.zeros((n, 12))
    error = np.zeros((n, 7))

    def loss(phi, error, w_limit=1.0):
        return float(analysis.limit_loss({"phi": jnp.asarray(phi), "error": jnp.asarray(error)}, r0, w_limit))

    phi[:, params.N_H :] = params.YAW_LIMIT  # every base joint at its limit
    assert loss(phi, error) == pytest.approx(6.0, abs=1e-5)
    phi[:, params.N_H :] = 0.3 * params.YAW_LIMIT
    assert loss(phi, error) < 1e-6
    phi[:, :params.N_H] = 1.5  # head joints (and psi_3) do not count
    assert loss(phi, error) < 1e-6
    error[:, 0] = 0.03
    assert loss(phi, error) == pytest.approx(1.0, rel=1e-5)
    error[:, 0], error[:, 5] = 0.0, 0.1
    assert loss(phi, error) == pytest.approx(1.0, rel=1e-5)
    error[:, 6] = 0.5  # the psi_3 error is not in the head error
    assert loss(phi, error) == pytest.approx(1.0, rel=1e-5)
    # a random case against the formula
    phi = rng.uniform(-1.1, 1.1, (n, 12))
    error = rng.normal(0, 0.02, (n, 7))
    ratio = np.abs(phi[:, params.N_H :]) / params.YAW_LIMIT
    head = np.mean(np.sum(error[:, :3] ** 2, 1) / 0.03**2 + np.sum(error[:, 3:6] ** 2, 1) / 0.1**2)
    joints = np.mean(np.sum(T * _softplus((ratio - r0) / T) / (1 - r0), axis=1))
    assert loss(phi, error, 2.5) == pytest.approx(head + 2.5 * joints, rel=1e-10)


# ------------------------------------------------------------------------------ sweep
@pytest.fixture(scope="module")
def swept(tmp_path_factory):
    out = tmp_path_factory.mktemp("snake_kv") / "out"
    spec = {
        "sweep": {"analysis": "snake.kv", "output": str(out), "combine": "zip"},
        "fixed": {"horizon": HORIZON, "dt": DT},
        "params": SWEPT,
    }
    return jaxloco.sweep.run(spec, progress=False, configure_jax=False)


def test_sweep_table_and_summary(swept, rows):
    t = swept.table.to_pydict()
    assert t["row"] == [0, 1, 2] and t["k_eta"] == SWEPT["k_eta"] and t["amplitude"] == SWEPT["amplitude"]
    batch, _ = rows
    np.testing.assert_allclose(t["loss"], batch["loss"], rtol=1e-9)
    assert t["status"] == [analysis.STATUSES[int(s)] for s in batch["status"]]
    summary = analysis.summarize(swept.table)
    assert summary == swept.summary  # the runner used the analysis' summarize
    assert summary.title.endswith("1/3 rows recovered with the head held")
    assert summary.columns[0] == "row" and all(len(r) == len(summary.columns) for r in summary.rows)
    # ranked: the ok row first, then the others by loss; rows 0 and 2 have the paper's K_V
    # and k_eta = 0.1 and are marked
    failed = sorted([0, 1], key=lambda i: t["loss"][i])
    labels = [r[0] for r in summary.rows]
    assert labels == [("paper " if i in (0, 2) else "") + str(i) for i in [2, *failed]]
    # the varying parameters are shown (k_eta, mode order, amplitude), the fixed ones not
    for r in summary.rows:
        i = int(r[0].split()[-1])
        assert {f"{t['k_eta'][i]:g}", f"{t['mode_order'][i]:g}", f"{t['amplitude'][i]:g}"} <= set(r[1:])
    assert (
        len(summary.columns) == len(analysis.summarize(swept.table.slice(0, 2)).columns) + 1
    )  # amplitude varies in 3 rows only


# ------------------------------------------------------------------------------- tune
@pytest.fixture(scope="module")
def tuned(tmp_path_factory):
    out = tmp_path_factory.mktemp("snake_kv_tune") / "out"
    spec = {
        "tune": {"objective": "snake.kv", "params": [t.name for t in tuning.TUNABLES], "steps": 3,
                 "learning_rate": 0.15, "formats": ["parquet"]},
        "settings": {"horizon": HORIZON, "dt": DT},
    }
    return jaxloco.tune.run(spec, progress=False, out=out, configure_jax=False)


def test_three_adam_steps_lower_the_loss_and_report_the_paper_row(tuned, rows):
    curve = tuned.curve.to_pydict()
    assert curve["step"] == [0, 1, 2, 3]
    initial, best, paper = tuned.row("initial"), tuned.row("tuned"), tuned.row("paper")
    assert best["loss"] < initial["loss"]
    assert best["loss"] == min(curve["loss"])
    assert tuned.values("initial") == pytest.approx(tuning.PAPER)  # the defaults are the paper's
    assert {k: paper[k] for k in tuning.PAPER} == pytest.approx(tuning.PAPER)
    assert paper["loss"] == pytest.approx(initial["loss"], rel=1e-12)
    # the loss is the sweep's: row 0 of the batch has the same settings (2 s, paper K_V)
    batch, _ = rows
    assert initial["loss"] == pytest.approx(float(batch["loss"][0]), rel=1e-9)
    assert initial["recovery_time"] == pytest.approx(float(batch["recovery_time"][0]))
    assert tuned.values("tuned") != tuned.values("initial")


def test_loss_gradient_matches_finite_differences():
    """Reverse mode through the 2 s rollout (joint stops, mode schedule) against central
    differences of the same loss in each tunable (relative step 1e-5). The settings are
    the `tuned` fixture's, so the program is the one the tune runner compiled (JAX's
    persistent cache then skips the compilation when this module runs as a whole)."""
    settings = {p.name: p.default for p in tuning.SETTINGS} | {"horizon": HORIZON, "dt": DT}
    loss_fn = tuning.KV_TUNE.make_loss(settings)
    evaluate = jax.jit(jax.value_and_grad(loss_fn, has_aux=True))
    values = {t.name: jnp.asarray(t.default, jnp.float64) for t in tuning.TUNABLES}
    (loss, aux), grad = evaluate(values)
    assert set(aux) == set(tuning.AUX) and np.isfinite(float(loss))
    assert abs(float(grad["k_eta"])) > 1e-3  # k_eta matters
    for name, value in values.items():
        h = 1e-5 * float(value)
        up = float(evaluate({**values, name: value + h})[0][0])
        down = float(evaluate({**values, name: value - h})[0][0])
        fd = (up - down) / (2 * h)
        assert float(grad[name]) == pytest.approx(fd, rel=1e-4, abs=1e-6 * abs(float(loss))), name


# ------------------------------------------------------------- the order of the joints
def _release_times_loop(t, phi, ratio):
    """Reference: per base joint, the first record time from which |theta| <= ratio *
    limit to the end (inf if never), by a plain loop."""
    out = []
    for j in range(params.N_B):
        inside = np.abs(phi[:, params.N_H + j]) <= ratio * params.YAW_LIMIT
        bad = np.flatnonzero(~inside)
        first = 0 if bad.size == 0 else bad[-1] + 1
        out.append(t[first] if first < t.size else np.inf)
    return np.array(out)


def _order_score_loop(times):
    """Reference: +1 per pair where the joint nearer the tail left first, -1 the other
    way, 0 where neither left; the mean over the 15 pairs."""
    total = 0.0
    for i in range(params.N_B):  # i nearer the head than j
        for j in range(i + 1, params.N_B):
            if not (np.isinf(times[i]) and np.isinf(times[j])):
                total += np.sign(times[i] - times[j])
    return total / 15.0


def test_release_times_and_the_order_score_on_made_up_records():
    t = np.arange(10) * 0.5
    limit = params.YAW_LIMIT
    phi = np.zeros((10, params.N_PHI))
    phi[:, params.N_H:] = limit  # every base joint at its limit ...
    for j in range(params.N_B):  # ... until theta_9 leaves first (t = 0.5), theta_4 last (t = 3.0)
        phi[1 + params.N_B - 1 - j:, params.N_H + j] = 0.5 * limit
    phi[4, params.N_H + 5] = limit  # theta_9 comes back once: it leaves for good at t = 2.5
    times = np.asarray(experiments.release_times(t, phi))
    np.testing.assert_allclose(times, _release_times_loop(t, phi, 0.7))
    np.testing.assert_allclose(times, [3.0, 2.5, 2.0, 1.5, 1.0, 2.5])
    assert float(experiments.release_order_score(jnp.asarray(times))) == pytest.approx(_order_score_loop(times))
    tail_to_head = np.array([3.0, 2.5, 2.0, 1.5, 1.0, 0.5])
    assert float(experiments.release_order_score(jnp.asarray(tail_to_head))) == 1.0
    assert float(experiments.release_order_score(jnp.asarray(tail_to_head[::-1]))) == -1.0
    never = np.full(params.N_B, np.inf)
    assert float(experiments.release_order_score(jnp.asarray(never))) == 0.0
    # a joint that never leaves counts as last
    assert float(experiments.release_order_score(jnp.asarray(np.r_[np.inf, tail_to_head[1:]]))) == 1.0


def test_the_wheels_weight_in_W_sets_the_order_of_the_joints():
    """The paper's K_V from the zigzag, 30 s: with our W (w_wheel 1) and k_eta 0.1 the
    head-end joints leave their limits first (score < 0); with the wheels 10 x dearer
    and k_eta 0.7 the tail leads (theta_9, theta_8 first, as the paper's Fig. 10). The
    score against a plain-loop reference on the rollout's records."""
    horizon, dt = 30.0, 0.05
    values = {k: jnp.full(2, v, jnp.int32 if k == "mode_order" else jnp.float64)
              for k, v in DEFAULTS.items() if analysis.KV.param(k).sweepable}
    values |= {"w_wheel": jnp.asarray([1.0, 10.0]), "k_eta": jnp.asarray([0.1, 0.7])}
    run = jax.jit(jax.vmap(lambda v: analysis.run_one(v, analysis.rollout_config(horizon, dt, False))))
    out, recs = jax.tree_util.tree_map(np.asarray, run(values))
    score = out["order_score"]
    assert np.all(out["recovered"])
    assert score[0] < 0.0 < 0.5 < score[1]
    times = [_release_times_loop(recs["t"][i], recs["phi"][i], DEFAULTS["recover_ratio"]) for i in range(2)]
    for i in range(2):
        assert score[i] == pytest.approx(_order_score_loop(times[i]), abs=1e-12)
    assert list(np.argsort(times[1])[:2]) == [5, 4]  # the dearer wheels: theta_9, then theta_8


def test_w_wheel_scales_only_the_wheels_in_W():
    values = {k: jnp.asarray(v, jnp.int32 if k == "mode_order" else jnp.float64)
              for k, v in DEFAULTS.items() if analysis.KV.param(k).sweepable}
    ours = np.asarray(analysis.control_params(values).weights)
    np.testing.assert_array_equal(ours, np.asarray(control.default_weights()))
    dear = np.asarray(analysis.control_params(values | {"w_wheel": jnp.float64(10.0)}).weights)
    np.testing.assert_array_equal(dear[: params.N_PHI], ours[: params.N_PHI])
    np.testing.assert_allclose(dear[params.N_PHI :], 10.0 * ours[params.N_PHI :], rtol=1e-15)


# ---------------------------------------------------------------------------- specs
def test_committed_spec_files_load_and_validate():
    sweep = jaxloco.sweep.load_spec(SWEEPS / "snake_kv.toml")
    assert sweep.analysis.name == "snake.kv" and sweep.name == "snake_kv"
    assert sweep.n_rows == 288  # 3 x 3 x 2 x 4 x 2 x 2, as its comment says
    assert sweep.fixed["horizon"] == 30.0 and sweep.fixed["dt"] == 0.02
    assert set(sweep.swept) == {"kv_head_yaw", "kv_base", "kv_ratio", "k_eta", "delta_t", "mode_order"}
    assert 15.0 in sweep.swept["kv_head_yaw"] and 9.6 in sweep.swept["kv_base"]  # the paper's K_V is a row
    assert len(jaxloco.sweep.expand(sweep)) == 288
    tune = jaxloco.tune.load_spec(SWEEPS / "snake_kv_tune.toml")
    assert tune.objective is tuning.KV_TUNE and tune.steps == 40 and tune.optimizer == "adam"
    assert set(tune.params) == {t.name for t in tuning.TUNABLES}
    assert tune.settings["horizon"] == 20.0 and tune.settings["dt"] == 0.05
    assert dict(tune.init) == pytest.approx(tuning.PAPER)
    assert control.PAPER_KV_BASE == tuning.PAPER["kv_base"]
    order = jaxloco.sweep.load_spec(SWEEPS / "snake_order.toml")
    assert order.analysis.name == "snake.kv" and order.n_rows == 42  # 6 x 7, as its comment says
    assert 1.0 in order.swept["w_wheel"] and 0.1 in order.swept["k_eta"]  # our defaults are a row
