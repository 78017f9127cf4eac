"""Running sweeps end to end on a toy analysis: table layout, chunking and padding,
atomic chunk files, resume after an interruption, output-directory rules."""

from __future__ import annotations

import dataclasses
import json

import jax
import jax.numpy as jnp
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from jaxloco.analysis import Analysis, Metric, Param, Summary, register
from jaxloco.analysis import get as get_analysis
from jaxloco.errors import SpecError
from jaxloco.sweep import (
    AnalysisError,
    SweepInterrupted,
    expand,
    run,
    spec_from_dict,
    store,
)

# ------------------------------------------------------------------ the toy analysis

TRACES: list[dict[str, str]] = []  # one entry per trace of a toy batch function: input dtypes


def _toy_row(values, key):
    """One row of the toy: every sweepable value a scalar array, the others plain."""
    TRACES.append({name: str(v.dtype) for name, v in values.items() if hasattr(v, "dtype")})
    n = values["n"]  # not sweepable: a Python int that sets an array shape
    assert isinstance(n, int) and isinstance(values["label"], str)
    y = values["a"] * jnp.sum(jnp.arange(n)) / n + values["b"] + jnp.where(values["flag"], 1.0, 0.0)
    return {"y": y, "u": jax.random.uniform(key), "k": values["m"] + n, "pos": y > 0, "status": jnp.where(y < 0, 1, 0)}


def toy_expected_y(a, b, n, flag):
    return a * sum(range(n)) / n + b + (1.0 if flag else 0.0)


def _toy_summary(table):
    ys = table.column("y").to_pylist()
    return Summary(title="toy", columns=("rows", "max y"), rows=((str(len(ys)), f"{max(ys):.3f}"),), notes=("a note",))


TOY_PARAMS = (
    Param("a", 1.0, "slope", unit="m", lo=-10.0, hi=10.0),
    Param("b", 0.0, "offset", unit="m"),
    Param("m", 0, "an integer knob", kind="int", lo=0, hi=100),
    Param("n", 3, "shape-changing count", kind="int", lo=1, hi=16, sweepable=False),
    Param("flag", False, "adds one", kind="bool"),
    Param("label", "toy", "a label", kind="str"),
)
TOY_METRICS = (
    Metric("y", "a*mean(0..n-1) + b + flag", unit="m"),
    Metric("u", "uniform noise from the row's key"),
    Metric("k", "m + n", kind="int"),
    Metric("pos", "y > 0", kind="bool"),
)
TOY = register(
    Analysis(
        name="test.toy",
        doc="A toy analysis for the sweep tests.\nSecond line.",
        params=TOY_PARAMS,
        metrics=TOY_METRICS,
        row=_toy_row,
        statuses=("ok", "failed: negative"),
    )
)
TOY_SUMMARY = register(dataclasses.replace(TOY, name="test.toy_summary", doc="The toy with a summary.",
                                           summarize=_toy_summary))

COLUMNS = ["row", "a", "b", "m", "n", "flag", "label", "y", "u", "k", "pos", "status", "seed",
           "analysis", "jaxloco_version", "jax_version", "mujoco_version"]  # fmt: skip


def toy_spec(out, *, analysis="test.toy", chunk_size=4, seeds=(0, 1), **params):
    params = params or {"a": {"start": -1.0, "stop": 1.0, "num": 5}, "flag": [True, False]}
    return spec_from_dict(
        {
            "sweep": {"analysis": analysis, "output": str(out), "chunk_size": chunk_size, "seeds": list(seeds)},
            "fixed": {"n": 4, "label": "hi"},
            "params": params,
        }
    )


@pytest.fixture
def chunk_writes(monkeypatch):
    """The chunk indices written to disk, in order."""
    written: list[int] = []
    original = store.write_chunk

    def counting(out, index, table):
        written.append(index)
        original(out, index, table)

    monkeypatch.setattr(store, "write_chunk", counting)
    return written


# ----------------------------------------------------------------------------- tests


def test_run_table_columns_types_order_and_values(tmp_path):
    TRACES.clear()
    spec = toy_spec(tmp_path / "out")  # 5 a x 2 flag x 2 seeds = 20 rows, chunks 4 -> 5 chunks
    result = run(spec, progress=False)
    t = result.table
    assert t.column_names == COLUMNS
    types = {f.name: f.type for f in t.schema}
    assert types["row"] == pa.int64() and types["a"] == pa.float64() and types["m"] == pa.int64()
    assert types["flag"] == pa.bool_() and types["label"] == pa.string() and types["k"] == pa.int64()
    assert types["pos"] == pa.bool_() and types["status"] == pa.string() and types["seed"] == pa.int64()
    rows = t.to_pylist()
    assert [r["row"] for r in rows] == list(range(20))
    grid = expand(spec).columns
    assert [r["a"] for r in rows] == grid["a"].tolist()
    assert [r["seed"] for r in rows] == [0, 1] * 10
    for r in rows:
        assert r["y"] == pytest.approx(toy_expected_y(r["a"], 0.0, 4, r["flag"]))
        assert r["status"] == ("failed: negative" if r["y"] < 0 else "ok")
        assert (r["n"], r["label"], r["b"], r["m"], r["k"]) == (4, "hi", 0.0, 0, 4)
        assert r["analysis"] == "test.toy" and r["jax_version"] == jax.__version__
    # seeds matter; the same seed gives the same key
    u: dict[int, set[float]] = {0: set(), 1: set()}
    for r in rows:
        u[r["seed"]].add(r["u"])
    assert len(u[0]) == 1 and len(u[1]) == 1 and u[0] != u[1]
    assert {r["status"] for r in rows} == {"ok", "failed: negative"}
    # float64 inputs, int32 ints, one compilation for all chunks
    assert TRACES == [{"a": "float64", "b": "float64", "m": "int32", "flag": "bool"}]
    assert (result.path / "table.parquet").is_file() and not (result.path / "table.csv").exists()
    assert pq.read_table(result.path / "table.parquet").equals(t)
    assert result.summary is not None and result.summary.columns == ("status", "rows", "share")


def test_units_and_docs_in_parquet_metadata(tmp_path):
    result = run(toy_spec(tmp_path / "out", seeds=(0,)), progress=False)
    schema = pq.read_schema(result.path / "table.parquet")
    assert schema.field("a").metadata[b"unit"] == b"m"
    assert schema.field("a").metadata[b"role"] == b"swept"
    assert schema.field("b").metadata[b"role"] == b"fixed"
    assert schema.field("u").metadata[b"doc"] == b"uniform noise from the row's key"
    described = json.loads(schema.metadata[b"jaxloco"])
    assert described["analysis"] == "test.toy"
    assert [p["name"] for p in described["params"]] == ["a", "b", "m", "n", "flag", "label"]
    assert described["statuses"] == ["ok", "failed: negative"]
    manifest = json.loads((result.path / "manifest.json").read_text())
    assert manifest["rows"] == 10 and manifest["chunks"] == 3 and manifest["spec_hash"] == described["spec_hash"]


def test_padding_does_not_leak_rows(tmp_path, chunk_writes):
    TRACES.clear()
    spec = toy_spec(tmp_path / "out", chunk_size=4, seeds=(0,), a=[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, -1.0])
    result = run(spec, progress=False)
    assert result.table.num_rows == 10
    assert result.table.column("row").to_pylist() == list(range(10))
    assert result.table.column("a").to_pylist()[-1] == -1.0
    assert result.table.column("status").to_pylist()[-1] == "failed: negative"
    assert chunk_writes == [0, 1, 2]
    assert [pq.read_metadata(store.chunk_path(result.path, i)).num_rows for i in range(3)] == [4, 4, 2]
    assert len(TRACES) == 1  # every call had the same shape


def test_batch_is_never_larger_than_the_sweep(tmp_path):
    TRACES.clear()
    spec = toy_spec(tmp_path / "out", chunk_size=256, seeds=(0,), a=[0.5, 1.5])
    assert run(spec, progress=False).table.num_rows == 2


def test_no_swept_params_gives_one_row_per_seed(tmp_path):
    spec = spec_from_dict({"sweep": {"analysis": "test.toy", "output": str(tmp_path / "o"), "seeds": 3}})
    t = run(spec, progress=False).table
    assert t.column("seed").to_pylist() == [0, 1, 2]
    assert t.column("a").to_pylist() == [1.0, 1.0, 1.0]


def test_resume_after_interruption_matches_uninterrupted_run(tmp_path, chunk_writes):
    spec = toy_spec(tmp_path / "interrupted")  # 5 chunks
    saved_calls = []

    def stop_after_two(index, n_chunks):
        saved_calls.append((index, n_chunks))
        if len(saved_calls) == 2:
            raise KeyboardInterrupt

    with pytest.raises(SweepInterrupted) as info:
        run(spec, progress=False, on_chunk=stop_after_two)
    assert (info.value.saved, info.value.total) == (2, 5)
    assert str(info.value) == f"interrupted: 2 of 5 chunks saved in {spec.output}; rerun with --resume"
    assert isinstance(info.value, KeyboardInterrupt)
    assert not (spec.output / "table.parquet").exists()
    before = {i: store.chunk_path(spec.output, i).stat().st_mtime_ns for i in (0, 1)}

    with pytest.raises(SpecError, match="exists; pass --resume to continue it or --overwrite to start again"):
        run(spec, progress=False)

    resumed_calls = []
    result = run(spec, progress=False, resume=True, on_chunk=lambda i, n: resumed_calls.append(i))
    assert resumed_calls == [2, 3, 4]
    assert chunk_writes == [0, 1, 2, 3, 4]  # nothing recomputed or written twice
    assert (result.chunks_computed, result.chunks_reused) == (3, 2)
    assert {i: store.chunk_path(spec.output, i).stat().st_mtime_ns for i in (0, 1)} == before

    fresh = run(toy_spec(tmp_path / "fresh"), progress=False)
    assert result.table.equals(fresh.table)
    assert pq.read_table(spec.output / "table.parquet").equals(fresh.table)

    # resuming a finished sweep computes nothing and gives the same table
    again = run(spec, progress=False, resume=True)
    assert again.chunks_computed == 0 and again.table.equals(fresh.table)


def test_resume_with_changed_spec_is_refused(tmp_path):
    out = tmp_path / "out"
    run(toy_spec(out, seeds=(0,)), progress=False)
    with pytest.raises(SpecError, match="different spec"):
        run(toy_spec(out, seeds=(0, 1)), progress=False, resume=True)
    with pytest.raises(SpecError, match="different spec"):
        run(toy_spec(out, seeds=(0,), chunk_size=3), progress=False, resume=True)


def test_overwrite_starts_again_but_only_in_a_sweep_directory(tmp_path, chunk_writes):
    out = tmp_path / "out"
    run(toy_spec(out, seeds=(0,)), progress=False)
    (out / "notes.txt").write_text("mine")
    result = run(toy_spec(out, seeds=(0, 1), chunk_size=8), progress=False, overwrite=True)
    assert result.table.num_rows == 20
    assert sorted(p.name for p in (out / "chunks").iterdir()) == [f"chunk-0000{i}.parquet" for i in range(3)]
    assert (out / "notes.txt").read_text() == "mine"
    with pytest.raises(SpecError, match="either --resume or --overwrite"):
        run(toy_spec(out), progress=False, overwrite=True, resume=True)

    other = tmp_path / "not_a_sweep"
    other.mkdir()
    (other / "precious.txt").write_text("keep")
    with pytest.raises(SpecError, match="not a sweep output"):
        run(toy_spec(other), progress=False, overwrite=True)
    with pytest.raises(SpecError, match="no manifest.json"):
        run(toy_spec(other), progress=False, resume=True)
    assert (other / "precious.txt").read_text() == "keep"


def test_csv_on_request_and_output_override(tmp_path):
    spec = toy_spec(tmp_path / "ignored", seeds=(0,)).with_options(csv=True)
    result = run(spec, progress=False, output=tmp_path / "here")
    assert result.path == tmp_path / "here"
    csv = (tmp_path / "here" / "table.csv").read_text().splitlines()
    assert csv[0].replace('"', "").split(",") == COLUMNS
    assert len(csv) == 1 + result.table.num_rows
    assert not (tmp_path / "ignored").exists()


def test_interrupted_then_resumed_with_leftover_temporary_file(tmp_path):
    spec = toy_spec(tmp_path / "out", seeds=(0,))

    def stop(index, n):
        raise KeyboardInterrupt

    with pytest.raises(SweepInterrupted):
        run(spec, progress=False, on_chunk=stop)
    leftover = spec.output / "chunks" / ".tmp-chunk-00001.parquet.abc"
    leftover.write_bytes(b"half a file")
    result = run(spec, progress=False, resume=True)
    assert result.table.num_rows == 10 and not leftover.exists()


def test_custom_summary_and_failing_summary(tmp_path):
    result = run(toy_spec(tmp_path / "a", analysis="test.toy_summary", seeds=(0,)), progress=False)
    assert result.summary == _toy_summary(result.table)

    def broken(table):
        raise ZeroDivisionError("oops")

    bad = Analysis(
        name="test.toy_bad_summary", doc="", params=TOY_PARAMS, metrics=TOY_METRICS,
        row=_toy_row, statuses=("ok", "failed: negative"), summarize=broken,
    )  # fmt: skip
    register(bad)
    result = run(toy_spec(tmp_path / "b", analysis="test.toy_bad_summary", seeds=(0,)), progress=False)
    assert result.summary is None and "oops" in result.summary_error
    assert (tmp_path / "b" / "table.parquet").is_file()


def test_analysis_returning_wrong_keys_is_a_bug_not_a_user_error(tmp_path):
    def bad_row(values, key):
        return {"y": jnp.zeros(()), "status": jnp.zeros((), jnp.int32)}

    register(Analysis(name="test.wrong_keys", doc="", params=TOY_PARAMS, metrics=TOY_METRICS, row=bad_row))
    with pytest.raises(AnalysisError, match="missing: k, pos, u"):
        run(toy_spec(tmp_path / "out", analysis="test.wrong_keys", seeds=(0,)), progress=False)


def test_float32_inputs_when_x64_is_off(tmp_path):
    TRACES.clear()
    previous = jax.config.jax_enable_x64
    jax.config.update("jax_enable_x64", False)
    try:
        result = run(toy_spec(tmp_path / "out", seeds=(0,), a=[0.1, 0.2]), progress=False, configure_jax=False)
    finally:
        jax.config.update("jax_enable_x64", previous)
    assert TRACES == [{"a": "float32", "b": "float32", "m": "int32", "flag": "bool"}]
    assert result.table.column("a").to_pylist() == [0.1, 0.2]  # the spec's values, not float32 ones
    assert result.table.schema.field("y").type == pa.float64()


def test_int_sweep_uses_int32_inputs(tmp_path):
    TRACES.clear()
    result = run(toy_spec(tmp_path / "out", seeds=(0,), m={"start": 0, "stop": 6, "step": 2}), progress=False)
    assert len(TRACES) == 1 and TRACES[0]["m"] == "int32"
    assert result.table.column("k").to_pylist() == [4, 6, 8, 10]
    assert np.array_equal(result.table.column("m").to_numpy(), [0, 2, 4, 6])


def test_a_wide_summary_is_not_cut_in_a_narrow_terminal():
    import io

    from rich.console import Console

    from jaxloco.sweep.display import print_summary

    columns = tuple(f"column number {i}" for i in range(8))
    summary = Summary(title="wide", columns=columns, rows=(tuple(f"{i}.123456789" for i in range(8)),))
    out = io.StringIO()
    print_summary(summary, Console(file=out, width=40, color_system=None))
    text = out.getvalue()
    assert "…" not in text
    for i in range(8):
        assert f"{i}.123456789" in text and f"column number {i}" in text


# ----------------------------------------------- a categorical (string) swept parameter

TASK_OFFSET = {"walk": 0.0, "climb": 10.0, "swim": 100.0}
HOST_CALLS: list[dict[str, np.ndarray]] = []  # the `swept` argument of every call of the task toy


def _task_simulate(values, keys, simulator):
    """numpy only, as a simulated analysis is; `values["task"]` is a numpy array of str."""
    HOST_CALLS.append(dict(values))
    y = np.array([TASK_OFFSET[str(t)] for t in values["task"]]) + values["speed"]
    return {"y": y, "status": (values["task"] == "swim").astype(np.int64)}


TASK_PARAMS = (
    Param("task", "walk", "which experiment", kind="str", choices=tuple(TASK_OFFSET)),
    Param("speed", 1.0, "commanded speed", unit="m/s", lo=0.0, hi=10.0),
    Param("note", "", "a free-form label", kind="str"),
    Param("mode", "a", "a structural choice", kind="str", choices=("a", "b"), sweepable=False),
)
TASKS = register(
    Analysis(
        name="test.tasks",
        doc="A toy host analysis with a categorical task.",
        params=TASK_PARAMS,
        metrics=(Metric("y", "the task's offset + speed", unit="m/s"),),
        simulate=_task_simulate,
        statuses=("ok", "wet"),
    )
)
TASKS_JAX = register(dataclasses.replace(TASKS, name="test.tasks_jax", simulate=None,
                                         row=lambda values, key: {"y": values["speed"], "status": 0}))


def task_spec(out, *, chunk_size=4, formats=("parquet",), **params):
    params = params or {"task": ["climb", "walk", "swim"], "speed": [0.5, 2.0]}
    return spec_from_dict(
        {
            "sweep": {"analysis": "test.tasks", "output": str(out), "chunk_size": chunk_size, "seeds": [0],
                      "formats": list(formats)},
            "params": params,
        }
    )


TASK_ROWS = [("climb", 0.5), ("climb", 2.0), ("walk", 0.5), ("walk", 2.0), ("swim", 0.5), ("swim", 2.0)]


def test_string_param_is_a_string_column_in_grid_order(tmp_path):
    HOST_CALLS.clear()
    spec = task_spec(tmp_path / "out")  # 3 tasks x 2 speeds x 1 seed = 6 rows; chunks of 4 and 2
    assert spec.swept["task"] == ("climb", "walk", "swim")
    grid = expand(spec)
    assert grid.axes["task"].dtype.kind == "U" and grid.columns["task"].tolist() == [t for t, _ in TASK_ROWS]
    result = run(spec, progress=False)
    t = result.table
    assert t.schema.field("task").type == pa.string() and t.schema.field("task").metadata[b"role"] == b"swept"
    assert t.schema.field("note").type == pa.string() and t.schema.field("note").metadata[b"role"] == b"fixed"
    assert list(zip(t.column("task").to_pylist(), t.column("speed").to_pylist(), strict=True)) == TASK_ROWS
    assert t.column("y").to_pylist() == [TASK_OFFSET[task] + speed for task, speed in TASK_ROWS]
    assert t.column("status").to_pylist() == ["ok"] * 4 + ["wet"] * 2
    assert t.column("note").to_pylist() == [""] * 6 and t.column("mode").to_pylist() == ["a"] * 6
    # the host batch function got numpy arrays of str, one call per chunk
    assert [len(call["task"]) for call in HOST_CALLS] == [4, 2]
    assert all(isinstance(c["task"], np.ndarray) and c["task"].dtype.kind == "U" for c in HOST_CALLS)
    assert HOST_CALLS[1]["task"].tolist() == ["swim", "swim"]
    assert json.loads(t.schema.metadata[b"jaxloco"])["swept"] == ["task", "speed"]
    # the default summary counts statuses per task, in the table's order
    assert result.summary.columns == ("task", "status", "rows", "share")
    assert result.summary.rows == (
        ("climb", "ok", "2", "100.0%"), ("walk", "ok", "2", "100.0%"), ("swim", "wet", "2", "100.0%"),
    )  # fmt: skip


def test_string_param_zipped_and_fixed(tmp_path):
    zipped = spec_from_dict(
        {
            "sweep": {"analysis": "test.tasks", "output": str(tmp_path / "z"), "combine": "zip"},
            "params": {"task": ["swim", "walk"], "speed": [1.0, 3.0]},
        }
    )
    t = run(zipped, progress=False).table
    assert t.column("task").to_pylist() == ["swim", "walk"] and t.column("y").to_pylist() == [101.0, 3.0]
    fixed = spec_from_dict(
        {
            "sweep": {"analysis": "test.tasks", "output": str(tmp_path / "f")},
            "fixed": {"task": "climb"},
            "params": {"speed": [1.0, 2.0]},
        }
    )
    t = run(fixed, progress=False).table
    assert t.column("task").to_pylist() == ["climb", "climb"]
    assert t.schema.field("task").metadata[b"role"] == b"fixed"


def test_string_sweep_resumed_after_interruption_gives_the_same_table(tmp_path, chunk_writes):
    spec = task_spec(tmp_path / "interrupted", chunk_size=2)  # 3 chunks

    def stop(index, n_chunks):
        raise KeyboardInterrupt

    with pytest.raises(SweepInterrupted) as info:
        run(spec, progress=False, on_chunk=stop)
    assert (info.value.saved, info.value.total) == (1, 3)
    resumed = run(spec, progress=False, resume=True)
    assert (resumed.chunks_computed, resumed.chunks_reused) == (2, 1)
    assert chunk_writes == [0, 1, 2]
    fresh = run(task_spec(tmp_path / "fresh", chunk_size=2), progress=False)
    assert resumed.table.equals(fresh.table)
    assert resumed.table.schema.field("task").type == pa.string()
    assert pq.read_table(spec.output / "table.parquet").equals(fresh.table)


def test_string_column_csv_round_trip(tmp_path):
    import pyarrow.csv as pa_csv

    result = run(task_spec(tmp_path / "out", formats=("parquet", "csv")), progress=False)
    path = result.path / "table.csv"
    assert pa_csv.read_csv(path).schema.field("task").type == pa.string()  # inferred, too
    types = pa_csv.ConvertOptions(column_types={f.name: f.type for f in result.table.schema})
    back = pa_csv.read_csv(path, convert_options=types)
    assert back.column_names == result.table.column_names
    assert back.to_pylist() == result.table.to_pylist()
    assert back.column("task").to_pylist() == [t for t, _ in TASK_ROWS]


def test_string_spec_survives_the_worker_round_trip():
    from jaxloco.sweep.chunks import ChunkJob

    spec = task_spec("unused")
    rebuilt = ChunkJob.of(spec, x64=True).rebuild()
    assert rebuilt.hash == spec.hash and rebuilt.swept["task"] == ("climb", "walk", "swim")


def test_a_hand_made_string_sweep_under_jax_is_refused_before_computing(tmp_path):
    from jaxloco.sweep.chunks import prepare

    spec = dataclasses.replace(task_spec(tmp_path / "out"), analysis=TASKS_JAX)
    with pytest.raises(SpecError, match=r"params\.task: 'task' is a string parameter and this analysis runs under JAX"):
        prepare(spec)


def test_heatmap_over_a_string_axis(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    from jaxloco.plots import grid_mean, heatmap

    table = run(task_spec(tmp_path / "out"), progress=False).table
    xs, ys, mean, _ = grid_mean(table, "speed", "task", "y")
    assert ys.tolist() == ["climb", "swim", "walk"] and xs.tolist() == [0.5, 2.0]
    assert mean.tolist() == [[10.5, 12.0], [100.5, 102.0], [0.5, 2.0]]
    fig = heatmap(table, "speed", "task", "y", mark=(2.0, "walk"))
    ax = fig.axes[0]
    assert [t.get_text() for t in ax.get_yticklabels()] == ["climb", "swim", "walk"]
    assert len(ax.patches) == 1  # the marked cell


# ------------------------------------------------------------------- the contract itself


def test_an_analysis_gives_exactly_one_of_row_and_simulate():
    with pytest.raises(ValueError, match="exactly one of row"):
        Analysis(name="test.neither", doc="", params=TOY_PARAMS, metrics=TOY_METRICS)
    with pytest.raises(ValueError, match="exactly one of row"):
        Analysis(name="test.both", doc="", params=TOY_PARAMS, metrics=TOY_METRICS, row=_toy_row,
                 simulate=_task_simulate)
    assert TOY.executor == "jax" and TASKS.executor == "host"


def test_simulate_gets_merged_columns_and_the_frameworks_simulator():
    from jaxloco.sim.rollout import Simulator, simulator_for

    seen = {}

    def simulate(values, keys, simulator):
        seen.update(values=dict(values), simulator=simulator)
        return {"y": np.asarray(values["speed"], float), "status": np.zeros(keys.shape[0], int)}

    toy = dataclasses.replace(TASKS, name="test.tasks_seen", simulate=simulate)
    fixed = {**toy.defaults(), "note": "n", "mode": "b"}
    out = toy.batch_fn(fixed)({"speed": np.array([1.0, 2.0, 3.0])}, np.zeros((3, 2), np.uint32))
    assert out["y"].tolist() == [1.0, 2.0, 3.0]
    values = seen["values"]
    assert values["task"].tolist() == ["walk"] * 3  # a fixed column, broadcast to the rows
    assert values["note"] == "n" and values["mode"] == "b"  # free text and non-sweepable: plain
    assert isinstance(seen["simulator"], Simulator) and seen["simulator"].backend == "native"
    mine = Simulator(backend="mjx", nthread=3)
    toy.batch_fn(fixed, mine)({}, np.zeros((1, 2), np.uint32))
    assert seen["simulator"] is mine
    made = simulator_for({"backend": "mjx", "nthread": 2}, record_state=True)
    assert (made.backend, made.nthread, made.record_state, made.runs) == ("mjx", 2, True, [])


def test_a_simulation_builds_its_scenario_once_per_set_of_plain_values():
    from jaxloco.analysis import Simulation

    made, ran = [], []

    def scenario(plain):
        made.append(dict(plain))
        return f"scenario {len(made)}"

    class Recorder:  # a simulator that returns what it was given
        def run(self, scenario, params):
            ran.append((scenario, params))
            return params

    sim = Simulation(scenario, lambda values, keys: {"speed": values["speed"]},
                     lambda values, result: {"y": result["speed"], "status": np.zeros(len(result["speed"]), int)})
    keys = np.zeros((2, 2), np.uint32)
    for horizon in (1.0, 1.0, 2.0, 1.0):
        out = sim({"speed": np.array([1.0, 2.0]), "horizon": horizon, "mode": "a"}, keys, Recorder())
        assert out["y"].tolist() == [1.0, 2.0]
    assert made == [{"horizon": 1.0, "mode": "a"}, {"horizon": 2.0, "mode": "a"}]  # columns never reach it
    assert [s for s, _ in ran] == ["scenario 1", "scenario 1", "scenario 2", "scenario 1"]
    assert all(p["key"] is keys for _, p in ran)  # the rows' keys, added by the framework


def test_a_later_sweep_loads_the_traced_batch_program_and_gets_the_same_table(tmp_path, monkeypatch):
    """A JAX analysis' batch program is kept in the program cache (`chunks.jitted_batch`,
    `jaxloco.sim.programs`): the first sweep traces it and keeps it on disk, the same sweep
    again (as in a new process) loads it without tracing and gives the same table bit for
    bit, as does a run with the cache off (traced as before). The toy analysis, whose code
    is in this test module, is traced every time and leaves nothing on disk."""
    from jaxloco.sim import programs

    cache = tmp_path / "programs"
    monkeypatch.setenv(programs.ENV_SWITCH, str(cache))
    traced: list[str] = []

    def listener(event: str, duration: float, **kwargs) -> None:
        if event == "/jax/core/compile/jaxpr_trace_duration":
            traced.append(kwargs.get("fun_name", ""))

    spec = {"sweep": {"analysis": "octopus.terrain_classification", "name": "cached", "chunk_size": 2,
                      "formats": ["parquet"]},
            "fixed": {"samples": 8}, "params": {"height": [0.2, 0.3, 0.4]}}
    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        tables = [run(spec, output=tmp_path / "first", progress=False).table]
        assert traced.count("batch") == 1 and len(list(cache.glob("*.bin"))) == 1
        tables.append(run(spec, output=tmp_path / "later", progress=False).table)
        assert traced.count("batch") == 1  # loaded, not traced
        monkeypatch.setenv(programs.ENV_SWITCH, "0")
        tables.append(run(spec, output=tmp_path / "plain", progress=False).table)
        assert traced.count("batch") == 2
        monkeypatch.setenv(programs.ENV_SWITCH, str(cache))
        run(toy_spec(tmp_path / "toy"), progress=False)
        run(toy_spec(tmp_path / "toy_again"), progress=False)
        assert traced.count("batch") == 4 and len(list(cache.glob("*.bin"))) == 1
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)
    metrics = [m.name for m in get_analysis("octopus.terrain_classification").metrics] + ["status"]
    for other in tables[1:]:
        for name in metrics:
            assert other.column(name).equals(tables[0].column(name)), name
