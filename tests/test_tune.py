"""Gradient tuning on a toy objective: spec errors are one SpecError line (CLI exit 2), a
short run finds the known optimum inside the bounds, the output files hold the curve and
the comparison (initial, tuned = best step, references), Ctrl+C and divergence keep what
was computed, and the `tune` / `objectives` commands."""

from __future__ import annotations

import copy
import functools
import json
import math

import jax.numpy as jnp
import numpy as np
import pyarrow.csv as pa_csv
import pyarrow.parquet as pq
import pytest
from test_cli import invoke, workdir  # noqa: F401  (workdir: a fixture, a temporary working directory)
from test_sweep_spec import _both
from typer.testing import CliRunner

import jaxloco.tune
from jaxloco.analysis import Param
from jaxloco.cli import app
from jaxloco.errors import SpecError
from jaxloco.tune import (
    Objective,
    ObjectiveError,
    Tunable,
    TuneDiverged,
    TuneInterrupted,
    get,
    load_spec,
    register,
    run,
    spec_from_dict,
)
from jaxloco.tune import objective as registry
from jaxloco.tune.transform import from_free, to_free

# ------------------------------------------------------------------ the toy objective

WIDTH_TARGET = 2.0  # outside width's bounds (-1, 1): the tuned width must stop at 1


def _toy_loss(settings):
    scale, target = settings["scale"], settings["target_gain"]

    def loss_fn(v):
        gain_err = jnp.log(v["gain"]) - math.log(target)
        loss = scale * (
            gain_err**2 + (v["frac"] - 0.8) ** 2 + 0.1 * (v["width"] - WIDTH_TARGET) ** 2
        ) + settings["quartic"] * v["offset"] ** 4 + 0.0 * v["k"]
        return loss, {"gain_error": v["gain"] - target, "frac_sq": v["frac"] ** 2}

    return loss_fn


def toy_loss(values, scale=1.0, target=3.0):
    """The same loss in plain Python (quartic = 0)."""
    v = values
    return scale * (
        (math.log(v["gain"]) - math.log(target)) ** 2 + (v["frac"] - 0.8) ** 2 + 0.1 * (v["width"] - 2.0) ** 2
    )


TUNABLES = (
    Tunable("gain", 1.0, "a positive gain", unit="1/s", scale="log"),
    Tunable("frac", 0.5, "a fraction", lo=0.0, hi=1.0),
    Tunable("width", 0.0, "a width whose optimum is outside its bounds", unit="m", lo=-1.0, hi=1.0),
    Tunable("offset", 0.0, "unbounded; quartic loss"),
    Tunable("k", 2.0, "never tuned here"),
)
PAPER = {"gain": 2.5, "frac": 0.75, "width": 1.0}
TOY = register(
    Objective(
        name="test.toy_tune",
        doc="A toy quadratic.\n\nMore text.",
        tunables=TUNABLES,
        settings=(
            Param("scale", 1.0, "loss scale", lo=0.0, lo_open=True),
            Param("target_gain", 3.0, "optimal gain", lo=0.0, lo_open=True),
            Param("quartic", 0.0, "weight of offset**4", lo=0.0),
        ),
        make_loss=_toy_loss,
        references={"paper": PAPER},
    )
)

BASE = {
    "tune": {"objective": "test.toy_tune", "params": ["gain", "frac", "width"], "learning_rate": 0.1, "steps": 150},
}


def _with(change):
    d = copy.deepcopy(BASE)
    change(d)
    return d


def _table(name, **kw):
    return lambda d: d.setdefault(name, {}).update(kw)


_tune = functools.partial(_table, "tune")


# ------------------------------------------------------------------------ spec errors

ERRORS = [
    (_tune(objective="no.such"), "tune.objective: unknown objective 'no.such' (known: "),
    (_tune(params=["gain", "gian"]), "tune.params[1]: unknown tunable 'gian' for objective 'test.toy_tune'"),
    (_tune(params=[]), "tune.params: empty list"),
    (_tune(params=["gain", "frac", "gain"]), "tune.params[2]: 'gain' is listed twice"),
    (lambda d: d["tune"].pop("params"), "tune.params: required key is missing"),
    (_tune(optimizer="rmsprop"), "tune.optimizer: expected 'adam', 'sgd' or 'adamw', got 'rmsprop'"),
    (_tune(steps=0), "tune.steps: must be >= 1 and <= 1,000,000, got 0"),
    (_tune(steps=1_000_001), "tune.steps: must be >= 1 and <= 1,000,000, got 1000001"),
    (_tune(learning_rate=0), "tune.learning_rate: must be > 0 and <= 10, got 0"),
    (_tune(learning_rate=1e308), "tune.learning_rate: must be > 0 and <= 10, got 1e+308"),
    (_tune(learning_rate=10.5), "tune.learning_rate: must be > 0 and <= 10, got 10.5"),
    (_tune(clip_norm=-1.0), "tune.clip_norm: must be > 0 and <= 1,000,000, got -1.0"),
    (_tune(clip_norm=1e300), "tune.clip_norm: must be > 0 and <= 1,000,000, got 1e+300"),
    (lambda d: d["tune"].update(name="../../../tmp/x"), "tune.name: '../../../tmp/x' contains a path separator"),
    (lambda d: d["tune"].update(name=".."), "tune.name: '..' is not a name; a name is letters, digits, _, - and ."),
    (_tune(stpes=3), "tune.stpes: unknown key (did you mean 'steps'?)"),
    (lambda d: d.update(inits={}), "inits: unknown key"),
    (_tune(formats=["xlsx"]), "tune.formats[0]: expected 'parquet' or 'csv'"),
    (_table("init", frac=1.5), "init.frac: 1.5 is outside (0, 1)"),
    (_table("init", frac=1.0), "init.frac: 1 is outside (0, 1)"),
    (_table("init", gain=0.0), "init.gain: 0 1/s is outside (0, inf)"),
    (_table("init", gain=-2), "init.gain: -2 1/s is outside (0, inf)"),
    (_table("init", frac="half"), "init.frac: expected a number, got 'half'"),
    (_table("init", nope=1.0), "init.nope: unknown tunable 'nope'"),
    (_table("settings", scale=-1.0), "settings.scale: -1 is outside (0, inf]"),
    (_table("settings", gain=1.0), "settings.gain: unknown setting 'gain' for objective 'test.toy_tune'"),
]


@pytest.mark.parametrize("change, message", ERRORS)
def test_spec_errors_are_one_line(change, message):
    with pytest.raises(SpecError) as info:
        spec_from_dict(_with(change))
    text = str(info.value)
    assert "\n" not in text
    assert text.startswith(f"<dict>: {message}"), text


def test_spec_resolves_defaults_and_overrides():
    spec = spec_from_dict(_with(_table("init", k=5.0, gain=2.0)))
    assert spec.name == "tune" and str(spec.output) == "results/tune"
    assert spec.init == {"gain": 2.0, "frac": 0.5, "width": 0.0, "offset": 0.0, "k": 5.0}
    assert spec.settings == {"scale": 1.0, "target_gain": 3.0, "quartic": 0.0}
    assert spec.formats == ("parquet", "csv") and spec.optimizer == "adam"
    assert spec.with_options(steps=7, output="x").steps == 7
    with pytest.raises(SpecError, match=r"^--steps: must be an integer"):
        spec.with_options(steps=0)
    with pytest.raises(SpecError, match=r"^--steps: must be an integer >= 1 and <= 1,000,000, got 1000001$"):
        spec.with_options(steps=1_000_001)


def test_load_spec_names_the_file(tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text('[tune]\nobjective = "test.toy_tune"\nparams = ["gain"]\n')
    spec = load_spec(path)
    assert spec.name == "mine" and spec.source == str(path)
    path.write_text('[tune]\nobjective = "test.toy_tune"\nparams = ["gain"]\noptimizer = "lbfgs"\n')
    with pytest.raises(SpecError, match=rf"^{path}: tune.optimizer: expected"):
        load_spec(path)
    path.write_text("[tune\n")
    with pytest.raises(SpecError, match=rf"^{path}: invalid TOML"):
        load_spec(path)
    with pytest.raises(SpecError, match=r"no such file"):
        load_spec(tmp_path / "missing.toml")


# ------------------------------------------------------------------------- registry


def test_objective_contract_is_checked():
    with pytest.raises(ValueError, match="outside"):
        Objective("x", "", (Tunable("a", 2.0, "", lo=0.0, hi=1.0),), (), _toy_loss)
    with pytest.raises(ValueError, match="outside"):
        Objective("x", "", (Tunable("a", 0.0, "", scale="log"),), (), _toy_loss)
    with pytest.raises(ValueError, match="unknown tunable 'b'"):
        Objective("x", "", (Tunable("a", 1.0, ""),), (), _toy_loss, references={"p": {"b": 1.0}})
    with pytest.raises(ValueError, match="duplicate"):
        Objective("x", "", (Tunable("a", 1.0, ""),), (Param("a", 1.0, ""),), _toy_loss)


def test_builtin_that_cannot_load_is_a_clean_error(monkeypatch):
    monkeypatch.setitem(registry.OBJECTIVES.builtin, "test.broken", "jaxloco.no_such_module:X")
    with pytest.raises(SpecError, match=r"^objective 'test.broken' cannot be loaded \(ModuleNotFoundError"):
        get("test.broken")
    result = CliRunner().invoke(app, ["objectives"])
    assert result.exit_code == 0, result.output
    assert "test.toy_tune" in result.stdout and "A toy quadratic." in result.stdout
    assert "(cannot load: ModuleNotFoundError" in result.stdout and "snake.kv" in result.stdout


@pytest.mark.parametrize(
    "tunable",
    [
        Tunable("a", 0.3, "", lo=0.0, hi=1.0),
        Tunable("a", 3.0, "", scale="log"),
        Tunable("a", 3.0, "", scale="log", lo=0.5, hi=20.0),
        Tunable("a", 3.0, "", scale="log", lo=1.0),
        Tunable("a", -3.0, "", hi=-1.0),
        Tunable("a", 3.0, "", lo=1.0),
        Tunable("a", -3.0, ""),
    ],
)
def test_free_coordinates_round_trip(tunable):
    value = tunable.default
    assert float(from_free(tunable, jnp.asarray(to_free(tunable, value)))) == pytest.approx(value, rel=1e-12)
    for u in (-40.0, 40.0):  # far out the value saturates at, never beyond, a bound
        v = float(from_free(tunable, jnp.asarray(u)))
        assert (tunable.lo is None or v >= tunable.lo) and (tunable.hi is None or v <= tunable.hi)


# ------------------------------------------------------------------------------ runs


@pytest.fixture(scope="module")
def tuned(tmp_path_factory):
    out = tmp_path_factory.mktemp("tune") / "out"
    return run(spec_from_dict(BASE), progress=False, out=out, configure_jax=False)


def test_run_reaches_the_optimum_within_bounds(tuned):
    curve = tuned.curve.to_pydict()
    assert curve["step"] == list(range(151))
    assert curve["loss"][-1] < 0.2 * curve["loss"][0]
    values = tuned.values("tuned")
    assert values["gain"] == pytest.approx(3.0, rel=1e-3)
    assert values["frac"] == pytest.approx(0.8, abs=1e-3)
    assert 0.95 < values["width"] <= 1.0
    assert all(-1.0 <= w <= 1.0 for w in curve["width"]) and all(0.0 < f < 1.0 for f in curve["frac"])
    assert set(curve["k"]) == {2.0} and set(curve["offset"]) == {0.0}  # not tuned
    assert tuned.row("tuned")["loss"] == pytest.approx(0.1, abs=0.02)  # 0.1 * (1 - 2)**2 at the bound


def test_tuned_row_is_the_best_step_and_initial_is_step_0(tuned):
    curve = tuned.curve.to_pylist()
    best = min(range(len(curve)), key=lambda i: curve[i]["loss"])
    assert tuned.best_step == best
    for label, step in (("tuned", best), ("initial", 0)):
        row = tuned.row(label)
        assert row["step"] == step
        for key in ("loss", "gain", "frac", "width", "offset", "k", "gain_error", "frac_sq"):
            assert row[key] == curve[step][key]
    assert tuned.values("initial") == {"gain": 1.0, "frac": 0.5, "width": 0.0, "offset": 0.0, "k": 2.0}
    assert curve[0]["loss"] == pytest.approx(toy_loss(tuned.values("initial")), rel=1e-12)


def test_reference_rows_are_evaluated(tuned):
    paper = tuned.row("paper")
    assert paper["step"] is None
    assert {k: paper[k] for k in PAPER} == PAPER and paper["k"] == 2.0
    assert paper["loss"] == pytest.approx(toy_loss({**tuned.values("initial"), **PAPER}), rel=1e-12)
    assert paper["gain_error"] == pytest.approx(2.5 - 3.0)
    assert tuned.comparison.column("label").to_pylist() == ["initial", "tuned", "paper"]


def test_output_files(tuned):
    out = tuned.path
    names = {p.name for p in out.iterdir()}
    assert {"loss_curve.parquet", "loss_curve.csv", "tuned.parquet", "tuned.csv", "loss_curve.png"} <= names
    assert {p.name for p in tuned.written} == names
    curve = pq.read_table(out / "loss_curve.parquet")
    assert curve.equals(tuned.curve)
    meta = json.loads(curve.schema.metadata[b"jaxloco"])
    assert meta["objective"] == "test.toy_tune" and meta["best_step"] == tuned.best_step
    assert set(meta["versions"]) >= {"jaxloco", "jax"} and meta["spec"]["params"] == ["gain", "frac", "width"]
    assert curve.schema.field("gain").metadata[b"role"] == b"tuned"
    assert curve.schema.field("k").metadata[b"role"] == b"fixed"
    assert pa_csv.read_csv(out / "tuned.csv").column("label").to_pylist() == ["initial", "tuned", "paper"]
    assert pq.read_table(out / "tuned.parquet").equals(tuned.comparison)


def test_clipping_and_other_optimizers_run(tmp_path):
    spec = _with(_tune(optimizer="sgd", clip_norm=0.5, steps=5, formats=["parquet"]))
    result = run(spec, progress=False, out=tmp_path, configure_jax=False)
    assert max(result.curve.column("grad_norm").to_pylist()) > 0.5  # recorded before clipping
    assert not (tmp_path / "tuned.csv").exists()
    assert result.row("tuned")["loss"] < result.row("initial")["loss"]


def test_a_rerun_replaces_the_earlier_files(tmp_path):
    (tmp_path / "notes.txt").write_text("mine")
    run(_with(_tune(steps=2)), progress=False, out=tmp_path, configure_jax=False)
    assert (tmp_path / "loss_curve.csv").exists()
    run(_with(_tune(steps=3, formats=["parquet"])), progress=False, out=tmp_path, configure_jax=False)
    assert not (tmp_path / "loss_curve.csv").exists() and (tmp_path / "notes.txt").read_text() == "mine"
    assert pq.read_table(tmp_path / "loss_curve.parquet").num_rows == 4


def test_interrupt_keeps_what_was_computed(tmp_path):
    def stop(step, loss):
        if step == 4:
            raise KeyboardInterrupt

    with pytest.raises(TuneInterrupted) as info:
        run(spec_from_dict(BASE), progress=False, out=tmp_path, configure_jax=False, on_step=stop)
    assert (
        str(info.value)
        == f"interrupted after 4 of 150 steps; the loss curve and the best values so far are in {tmp_path}"
    )
    curve = pq.read_table(tmp_path / "loss_curve.parquet").to_pydict()
    assert curve["step"] == [0, 1, 2, 3, 4]
    labels = pq.read_table(tmp_path / "tuned.parquet").column("label").to_pylist()
    assert labels == ["initial", "tuned", "paper"]


def test_a_non_finite_loss_stops_the_run(tmp_path):
    spec = _with(_both(_tune(optimizer="sgd", learning_rate=10.0, params=["offset"]),
                       _table("init", offset=1.0), _table("settings", quartic=1.0)))
    with pytest.raises(TuneDiverged) as info:
        run(spec, progress=False, out=tmp_path, configure_jax=False)
    step = info.value.step
    assert 1 <= step < 150 and str(info.value).startswith(f"step {step}: the loss is ")
    assert "\n" not in str(info.value)
    curve = pq.read_table(tmp_path / "loss_curve.parquet").to_pydict()
    assert curve["step"] == list(range(step + 1))
    assert not math.isfinite(curve["loss"][-1]) or not math.isfinite(curve["grad_norm"][-1])
    assert np.isfinite(pq.read_table(tmp_path / "tuned.parquet").column("loss").to_numpy()[:2]).all()


def test_a_loss_that_breaks_the_contract_is_an_objective_error(tmp_path):
    bad = register(
        Objective(
            "test.bad_tune",
            "vector aux",
            (Tunable("a", 1.0, ""),),
            (),
            lambda s: lambda v: (v["a"] ** 2, {"pair": jnp.stack([v["a"], v["a"]])}),
        )
    )
    with pytest.raises(ObjectiveError, match=r"aux metric 'pair' has shape \(2,\), expected a scalar"):
        run({"tune": {"objective": bad.name, "params": ["a"], "steps": 1}}, progress=False, out=tmp_path,
            configure_jax=False)


# ------------------------------------------------------------------------------- CLI

GOOD = """
[tune]
objective = "test.toy_tune"
params = ["gain", "frac"]
learning_rate = 0.1
steps = 40

[init]
gain = 2.0
"""


@pytest.fixture
def tunes(workdir):
    (workdir / "tunes").mkdir()
    (workdir / "tunes" / "good.toml").write_text(GOOD)
    return workdir


def test_cli_tune_prints_the_comparison_and_the_files(tunes):
    result = invoke("tune", "tunes/good.toml", "--quiet", "--steps", "20", "--out", "here")
    assert result.exit_code == 0, result.output
    out = result.stdout
    assert "good: test.toy_tune, 20 adam steps, best at step" in out
    for word in ("initial", "tuned", "paper", "gain *", "frac *", "width", "gain_error", "1/s"):
        assert word in out
    assert "wrote here/loss_curve.parquet" in out and "wrote here/tuned.csv" in out
    assert pq.read_table(tunes / "here" / "loss_curve.parquet").num_rows == 21


@pytest.mark.parametrize(
    "text, message",
    [
        ('[tune]\nobjective = "no.such"\nparams = ["a"]\n', "error: tunes/bad.toml: tune.objective: unknown objective"),
        ('[tune]\nobjective = "test.toy_tune"\nparams = ["gain"]\noptimizer = "lbfgs"\n',
         "error: tunes/bad.toml: tune.optimizer: expected 'adam', 'sgd' or 'adamw', got 'lbfgs'"),
        ('[tune]\nobjective = "test.toy_tune"\nparams = ["gian"]\n',
         "error: tunes/bad.toml: tune.params[0]: unknown tunable 'gian'"),
        ('[tune]\nobjective = "test.toy_tune"\nparams = ["gain"]\n[init]\nfrac = 2.0\n',
         "error: tunes/bad.toml: init.frac: 2 is outside (0, 1)"),
    ],
)
def test_cli_spec_errors_exit_2(tunes, text, message):
    (tunes / "tunes" / "bad.toml").write_text(text)
    result = invoke("tune", "tunes/bad.toml", "--quiet")
    assert result.exit_code == 2
    assert result.stderr.startswith(message) and result.stderr.count("\n") == 1, result.stderr


def test_cli_over_long_paths_are_one_line(tunes):
    """A [validate] sweep or an --out the system refuses to look at: exit 2, one line."""
    long = "a" * 300
    (tunes / "tunes" / "v.toml").write_text(GOOD + f'\n[validate]\nsweep = "{long}.toml"\n')
    result = invoke("tune", "tunes/v.toml")
    assert result.exit_code == 2, result.output
    assert result.stderr == (f"error: tunes/v.toml: validate.sweep: tunes/{'a' * 34}...{'a' * 25}.toml "
                             "(311 characters): cannot use this path (file name too long)\n")
    result = invoke("tune", "tunes/good.toml", "--out", long)
    assert result.exit_code == 2, result.output
    assert result.stderr == (f"error: output: {'a' * 40}...{'a' * 30} (300 characters): cannot use this path "
                             "(file name too long)\n")


def test_cli_steps_option_is_checked(tunes):
    result = invoke("tune", "tunes/good.toml", "--steps", "0")
    assert result.exit_code == 2 and result.stderr.startswith("error: --steps: must be an integer")


def test_cli_interrupt_and_divergence_exit_codes(tunes, monkeypatch):
    def interrupted(spec, **kw):
        raise TuneInterrupted(3, 40, tunes / "results" / "good")

    monkeypatch.setattr(jaxloco.tune, "run", interrupted)
    result = invoke("tune", "tunes/good.toml", "--quiet")
    assert result.exit_code == 130 and "interrupted after 3 of 40 steps" in result.stderr

    def diverged(spec, **kw):
        raise TuneDiverged("step 7: the loss is nan\nand more", 7, tunes)

    monkeypatch.setattr(jaxloco.tune, "run", diverged)
    result = invoke("tune", "tunes/good.toml", "--quiet")
    assert result.exit_code == 1 and result.stderr == "error: step 7: the loss is nan and more\n"


def test_cli_objectives_describes_one(tunes):
    result = invoke("objectives", "test.toy_tune")
    assert result.exit_code == 0, result.output
    for word in ("parameters", "tunable, log scale", "setting (float)", "paper", "(0, 1)", "target_gain", "2.5"):
        assert word in result.stdout
    missing = invoke("objectives", "no.such")
    assert missing.exit_code == 2 and missing.stderr.startswith("error: unknown objective 'no.such'")
