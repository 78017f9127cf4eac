"""Tune -> sweep hand-off (`jaxloco.tune.handoff`, `jaxloco tune --validate`,
`jaxloco sweep --from-tune`): the compared sets of a tuning run become one zipped factor
of a sweep, and the per-set comparison equals the analysis evaluated independently."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pyarrow as pa
import pyarrow.csv  # noqa: F401  (pa.csv)
import pytest
from typer.testing import CliRunner

from jaxloco.analysis import Analysis, Metric, Param
from jaxloco.analysis import register as register_analysis
from jaxloco.cli import app
from jaxloco.errors import SpecError
from jaxloco.sweep import spec_from_dict
from jaxloco.tune import Objective, Tunable, handoff
from jaxloco.tune import register as register_objective
from jaxloco.tune import run as tune_run

# a toy objective whose optimum is a = 2, b = -1, and a toy analysis with params a, b, c


def _loss(settings):
    def loss_fn(v):
        return (v["a"] - 2.0) ** 2 + (v["b"] + 1.0) ** 2, {"a_sq": v["a"] ** 2}

    return loss_fn


OBJECTIVE = register_objective(
    Objective(
        name="test.handoff_tune",
        doc="toy",
        tunables=(
            Tunable("a", 0.5, "a", lo=-5.0, hi=5.0),
            Tunable("b", 0.0, "b"),
            Tunable("gain", 1.0, "g", scale="log"),
        ),
        settings=(),
        make_loss=_loss,
        references={"paper": {"a": 0.5, "b": 0.0}, "far": {"a": -1.0}},
    )
)


def y_of(a, b, c):
    return (a - 2.0) ** 2 + b * c


def _row(values, key):
    y = y_of(values["a"], values["b"], values["c"])
    return {"y": y, "good": y < 1.0, "status": jnp.where(y < 4.0, 0, 1)}


ANALYSIS = register_analysis(
    Analysis(
        name="test.handoff",
        doc="toy",
        params=(
            Param("a", 0.0, "a", lo=-3.0, hi=3.0),
            Param("b", 0.0, "b"),
            Param("c", 1.0, "c"),
            Param("d", 1.0, "d", sweepable=False),
        ),
        metrics=(Metric("y", "(a - 2)^2 + b c"), Metric("good", "y < 1", kind="bool")),
        row=_row,
        statuses=("ok", "too far"),
    )
)

SWEEP = {
    "sweep": {"analysis": "test.handoff", "name": "toy_sweep", "chunk_size": 4},
    "fixed": {"a": 1.0},
    "params": {"b": [0.0, 1.0], "c": [1.0, 2.0, 3.0]},
}


@pytest.fixture(scope="module")
def tuned(tmp_path_factory):
    out = tmp_path_factory.mktemp("tuned")
    spec = {"tune": {"objective": "test.handoff_tune", "params": ["a", "b"], "learning_rate": 0.2, "steps": 60}}
    return tune_run(spec, out=out, progress=False)


def test_param_sets_map_equal_names_and_merge_equal_sets(tuned):
    sets, mapping = handoff.param_sets(tuned.comparison, spec_from_dict(SWEEP))
    assert mapping == {"a": "a", "b": "b"}  # gain is no parameter of the analysis
    labels = [s.label for s in sets]
    assert labels == ["initial=paper", "tuned", "far"]  # the paper's values are the initial ones
    tuned_values = tuned.values("tuned")
    assert sets[1].values == {"a": tuned_values["a"], "b": tuned_values["b"]}
    assert abs(tuned_values["a"] - 2.0) < 0.05 and abs(tuned_values["b"] + 1.0) < 0.05
    assert sets[2].values == {"a": -1.0, "b": 0.0}  # "far" names only a; b keeps its initial value


def test_validation_spec_zips_the_sets_first_and_keeps_the_rest(tuned):
    base = spec_from_dict(SWEEP)
    sets, _ = handoff.param_sets(tuned.comparison, base, labels=["initial", "tuned"])
    spec = handoff.validation_spec(base, sets, output="x")
    assert spec.factors[0] == ("a", "b") and spec.factors[1:] == (("c",),)
    assert "a" not in spec.fixed and "b" not in spec.fixed and spec.fixed["d"] == 1.0
    assert spec.n_rows == len(sets) * 3
    assert str(spec.output) == "x" and spec.name == "toy_sweep_validation"


def test_validate_compares_each_set_with_the_analysis_evaluated_independently(tuned):
    done = handoff.validate(tuned.path, spec_from_dict(SWEEP), progress=False)
    assert done.sweep.path == tuned.path / "validation"
    rows = {r["label"]: r for r in done.comparison.to_pylist()}
    assert list(rows) == ["initial=paper", "tuned", "far"]
    for s in done.sets:
        ys = np.array([y_of(s.values["a"], s.values["b"], c) for c in (1.0, 2.0, 3.0)])
        row = rows[s.label]
        assert row["rows"] == 3
        assert row["y_mean"] == pytest.approx(ys.mean(), rel=1e-12)
        assert row["y_max"] == pytest.approx(ys.max(), rel=1e-12)
        assert row["ok_fraction"] == pytest.approx(np.mean(ys < 4.0))
        assert row["good_fraction"] == pytest.approx(np.mean(ys < 1.0))
    # the tuned set is the best one on this sweep too
    assert rows["tuned"]["y_mean"] < rows["initial=paper"]["y_mean"] < rows["far"]["y_mean"]
    assert (tuned.path / "validation" / "validation.csv").is_file()
    again = handoff.validate(tuned.path, spec_from_dict(SWEEP), progress=False)
    assert again.sweep.chunks_computed == 0 and again.sweep.chunks_reused > 0  # resumed, not recomputed
    assert again.comparison.equals(done.comparison)


def test_labels_of_matches_values_not_positions(tuned):
    base = spec_from_dict(SWEEP)
    sets, _ = handoff.param_sets(tuned.comparison, base)
    table = pa.table({"a": [-1.0, sets[1].values["a"]], "b": [0.0, sets[1].values["b"]]})
    assert list(handoff.labels_of(table, sets)) == ["far", "tuned"]
    with pytest.raises(SpecError, match="match no tuned parameter set"):
        handoff.labels_of(pa.table({"a": [9.0], "b": [0.0]}), sets)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"mapping": {"nope": "a"}}, "'nope' is not a column"),
        ({"mapping": {"a": "zz"}}, "unknown parameter 'zz'"),
        ({"labels": ["best"]}, "no row 'best'"),
        ({"mapping": {"a": "d"}}, "'d' cannot be swept"),
    ],
)
def test_bad_hand_offs_are_one_line_errors(tuned, kwargs, message):
    base = spec_from_dict(SWEEP)
    with pytest.raises(SpecError, match=message) as err:
        sets, _ = handoff.param_sets(tuned.comparison, base, **{k: v for k, v in kwargs.items()})
        handoff.validation_spec(base, sets)
    assert "\n" not in str(err.value)


def test_a_value_outside_the_sweep_range_names_the_set(tuned):
    column = tuned.comparison.column_names.index("a")
    field = tuned.comparison.schema.field("a")  # keeps its role metadata
    table = tuned.comparison.set_column(column, field, pa.array([4.5] * tuned.comparison.num_rows))
    with pytest.raises(SpecError, match=r"initial.a -> a: 4.5 is outside \[-3, 3\]"):
        handoff.param_sets(table, spec_from_dict(SWEEP))


def test_missing_tuning_output_is_a_clean_error(tmp_path):
    with pytest.raises(SpecError, match="no tuned.parquet here; run `jaxloco tune` first"):
        handoff.read_tuned(tmp_path)
    (tmp_path / "tuned.parquet").write_text("not parquet")
    with pytest.raises(SpecError, match="not a readable tuning table"):
        handoff.read_tuned(tmp_path)


# ------------------------------------------------------------------------------ CLI

TUNE_TOML = """
[tune]
objective = "test.handoff_tune"
params = ["a", "b"]
learning_rate = 0.2
steps = 40

[validate]
sweep = "toy_sweep.toml"
labels = ["initial", "tuned"]
"""

SWEEP_TOML = """
[sweep]
analysis = "test.handoff"
chunk_size = 4

[fixed]
a = 1.0

[params]
b = [0.0, 1.0]
c = [1.0, 2.0, 3.0]
"""


@pytest.fixture
def specs(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "specs").mkdir()
    (tmp_path / "specs" / "tune.toml").write_text(TUNE_TOML)
    (tmp_path / "specs" / "toy_sweep.toml").write_text(SWEEP_TOML)
    return tmp_path


def invoke(*args):
    return CliRunner().invoke(app, list(args))


def test_cli_tune_validate_runs_the_sweep_relative_to_the_spec(specs):
    result = invoke("tune", "specs/tune.toml", "--quiet", "--out", "t", "--validate")
    assert result.exit_code == 0, result.output
    text = " ".join(result.stdout.split())  # rich wraps the title
    assert "validation by specs/toy_sweep.toml: 3 rows per set (a, b)" in text
    assert "wrote t/validation/validation.csv" in result.stdout
    table = pa.csv.read_csv(specs / "t" / "validation" / "validation.csv")
    assert table.column("label").to_pylist() == ["initial", "tuned"]


def test_cli_validate_without_a_section_or_with_a_bad_path_exits_2(specs):
    (specs / "specs" / "plain.toml").write_text(TUNE_TOML.split("[validate]")[0])
    result = invoke("tune", "specs/plain.toml", "--quiet", "--validate")
    assert result.exit_code == 2 and "--validate needs a [validate] section" in result.output
    (specs / "specs" / "bad.toml").write_text(TUNE_TOML.replace("toy_sweep.toml", "missing.toml"))
    result = invoke("tune", "specs/bad.toml", "--quiet")
    assert result.exit_code == 2
    assert "validate.sweep: no sweep spec at specs/missing.toml" in result.output
    (specs / "specs" / "badlabel.toml").write_text(TUNE_TOML.replace('"tuned"]', '"best"]'))
    result = invoke("tune", "specs/badlabel.toml", "--quiet")
    assert (
        result.exit_code == 2 and "validate.labels[1]: 'best' is not one of initial, tuned, paper, far" in result.output
    )


def test_cli_sweep_from_tune_with_a_map(specs):
    assert invoke("tune", "specs/tune.toml", "--quiet", "--out", "t").exit_code == 0
    result = invoke("sweep", "specs/toy_sweep.toml", "--quiet", "--from-tune", "t", "--map", "a=a", "--out", "v")
    assert result.exit_code == 0, result.output
    text = " ".join(result.stdout.split())
    assert "validation by specs/toy_sweep.toml: 6 rows per set (a)" in text  # only a; b stays swept
    table = pa.csv.read_csv(specs / "v" / "validation.csv")
    assert table.column("label").to_pylist() == ["initial=paper", "tuned", "far"]
    assert "b" not in table.column_names  # b stays swept by the spec
    for args, message in [
        (("--map", "a"), "--map: expected TUNABLE=PARAM"),
        (("--resume",), "--from-tune resumes or replaces"),
    ]:
        bad = invoke("sweep", "specs/toy_sweep.toml", "--quiet", "--from-tune", "t", *args)
        assert bad.exit_code == 2 and message in bad.output, bad.output
    bad = invoke("sweep", "specs/toy_sweep.toml", "--quiet", "--map", "a=a")
    assert bad.exit_code == 2 and "--map needs --from-tune" in bad.output
    bad = invoke("sweep", "specs/toy_sweep.toml", "--quiet", "--from-tune", "nowhere")
    assert bad.exit_code == 2 and "no tuned.parquet here" in bad.output
