"""The Ray executor: chunks computed as Ray tasks in worker processes give exactly the
table of the local executor (jitted and host analyses, a builtin one), resume works
across executors in both directions, an interruption keeps every finished chunk, worker
errors arrive as themselves, and the CLI's Ray options fail with one line."""

from __future__ import annotations

import dataclasses
import os
import shutil
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

ray = pytest.importorskip("ray", reason='Ray is not installed (pip install "jaxloco[ray]")')

import jax
import jax.numpy as jnp
import test_sweep_run
from test_sweep_run import TRACES, toy_expected_y, toy_spec
from typer.testing import CliRunner

from jaxloco.analysis import Analysis, Metric, Param, register
from jaxloco.cli import app
from jaxloco.errors import SpecError
from jaxloco.sweep import AnalysisError, SweepInterrupted, expand, run, spec_from_dict, store
from jaxloco.sweep.chunks import ChunkJob, spec_document
from jaxloco.sweep.executors import RAY_MISSING, RayExecutor, check_reachable

TESTS = Path(__file__).resolve().parent


# ------------------------------------------------------- a toy "host" analysis


def _host_simulate(values, keys, simulator):
    """numpy only, as a simulated analysis (e.g. on the native MuJoCo engine) would be."""
    a = np.asarray(values["a"], dtype=np.float64)
    r = values["scale"] * a**2 + keys[:, 1].astype(np.float64) % 7
    return {"r": r, "status": (r > 5.0).astype(np.int64)}


HOST_TOY = register(
    Analysis(
        name="test.host_toy",
        doc="A numpy-only host analysis for the Ray tests.",
        params=(Param("a", 1.0, "input", unit="m"), Param("scale", 2.0, "factor", sweepable=False)),
        metrics=(Metric("r", "scale a^2 + (second word of the row's key mod 7)", unit="m^2"),),
        simulate=_host_simulate,
        statuses=("ok", "failed: large"),
    )
)


def _devices_row(values, key):
    return {"devices": jnp.asarray(jax.device_count()), "twice": 2.0 * values["x"], "status": jnp.asarray(0, jnp.int32)}


DEVICES = register(
    Analysis(
        name="test.devices",
        doc="How many JAX devices the process computing a row has.",
        params=(Param("x", 0.0, "input"),),
        metrics=(Metric("devices", "jax.device_count() where the row ran", kind="int"), Metric("twice", "2 x")),
        row=_devices_row,
    )
)


def host_spec(out, chunk_size=3):
    return spec_from_dict(
        {
            "sweep": {"analysis": "test.host_toy", "output": str(out), "chunk_size": chunk_size, "seeds": [0, 5]},
            "fixed": {"scale": 1.5},
            "params": {"a": [0.0, 0.5, 1.0, 1.5, 2.0]},
        }
    )


# --------------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def ray_cluster():
    """A local Ray instance with 2 CPUs; workers find the test modules via PYTHONPATH.
    Its session directory is in a temporary directory of its own, removed after the
    shutdown (a short path: Ray's Unix sockets live there, pytest's tmp_path is too long)."""
    path = os.pathsep.join([str(TESTS), *filter(None, [os.environ.get("PYTHONPATH")])])
    temp_dir = tempfile.mkdtemp(prefix="jaxloco_ray_")
    try:
        with warnings.catch_warnings():  # JAX warns about the fork+exec of Ray's services
            warnings.filterwarnings("ignore", r"os\.fork\(\) was called", RuntimeWarning)
            ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, _temp_dir=temp_dir,
                     runtime_env={"env_vars": {"PYTHONPATH": path}})  # fmt: skip
        yield
    finally:
        ray.shutdown()
        _remove_when_released(Path(temp_dir))


def _remove_when_released(folder: Path, tries: int = 10) -> None:
    """Delete `folder`, retrying briefly while Ray's exiting processes still write logs."""
    for _ in range(tries):
        shutil.rmtree(folder, ignore_errors=True)
        if not folder.exists():
            return
        time.sleep(0.5)


def ray_executor():
    return RayExecutor(cpus_per_task=1)


def chunk_mtimes(out, n):
    return {i: store.chunk_path(out, i).stat().st_mtime_ns for i in range(n) if store.chunk_path(out, i).is_file()}


# ------------------------------------------------------------ without a cluster


def test_spec_document_rebuilds_the_same_sweep():
    """What a worker receives: rebuilt, it has the same hash, rows and zip groups."""
    specs = [
        toy_spec("o"),
        spec_from_dict(
            {
                "sweep": {"analysis": "test.toy", "zip": [["a", "b"]], "seeds": 3, "chunk_size": 5},
                "fixed": {"n": 7},
                "params": {"m": [1, 2], "a": [0.1, 0.2, 0.3], "b": [1.0, 2.0, 3.0], "flag": [True]},
            }
        ),
        spec_from_dict(
            {
                "sweep": {"analysis": "test.toy", "combine": "zip"},
                "params": {"a": {"start": 0.0, "stop": 1.0, "num": 4}, "m": [3, 1, 4, 1]},
            }
        ),
    ]
    for spec in specs:
        job = ChunkJob.of(spec, x64=True)
        rebuilt = job.rebuild()
        assert rebuilt.hash == spec.hash and rebuilt.factors == spec.factors
        assert dict(rebuilt.fixed) == dict(spec.fixed)
        got, want = expand(rebuilt).columns, expand(spec).columns
        assert got.keys() == want.keys() and all(np.array_equal(got[k], want[k]) for k in want)
        assert job.analysis is spec.analysis  # registered at run time: sent along
        assert spec_document(rebuilt) == spec_document(spec)
    tampered = dataclasses.replace(ChunkJob.of(specs[0], x64=True), spec_hash="0" * 64)
    with pytest.raises(RuntimeError, match="rebuilt a different sweep"):
        tampered.rebuild()


def test_builtin_analysis_is_sent_by_name():
    spec = spec_from_dict({"sweep": {"analysis": "titan.stride"}})
    assert ChunkJob.of(spec, x64=True).analysis is None


def test_unreachable_address_is_refused_at_once():
    t0 = time.perf_counter()
    with pytest.raises(SpecError, match=r"^cannot connect to Ray at 127\.0\.0\.1:1: "):
        check_reachable("127.0.0.1:1")
    with pytest.raises(SpecError, match=r"^cannot connect to Ray at ray://127\.0\.0\.1:1: "):
        check_reachable("ray://127.0.0.1:1")
    with pytest.raises(SpecError, match="expected auto, host:port or ray://host:port"):
        check_reachable("no port here")
    check_reachable("auto")  # left to Ray
    assert time.perf_counter() - t0 < 5


def test_missing_ray_is_one_line_error(monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` now raises ImportError
    with pytest.raises(SpecError) as info:
        run(toy_spec(tmp_path / "out"), progress=False, executor="ray")
    assert str(info.value) == RAY_MISSING == 'the ray executor needs Ray: pip install "jaxloco[ray]"'
    assert not (tmp_path / "out").exists()


# ------------------------------------------------------------- with a cluster


def test_ray_table_equals_local_table(ray_cluster, tmp_path):
    local = run(toy_spec(tmp_path / "local"), progress=False)
    TRACES.clear()
    on_chunk = []
    remote = run(toy_spec(tmp_path / "ray"), progress=False, executor=ray_executor(),
                 on_chunk=lambda i, n: on_chunk.append((i, n)))  # fmt: skip
    assert TRACES == []  # nothing was traced in this process: the workers computed it
    assert sorted(on_chunk) == [(i, 5) for i in range(5)]
    assert (remote.chunks_computed, remote.chunks_reused) == (5, 0)
    assert remote.table.equals(local.table, check_metadata=True)
    assert pq.read_table(remote.table_path).equals(local.table, check_metadata=True)
    for row in remote.table.to_pylist():  # and the values are right, not just equal
        assert row["y"] == pytest.approx(toy_expected_y(row["a"], 0.0, 4, row["flag"]))
    assert remote.summary == local.summary


def test_workers_mirror_the_drivers_cpu_devices(ray_cluster, tmp_path):
    """By default a worker exposes as many JAX CPU devices as this process, so it compiles
    the same per-device program as a local run; cpu_devices overrides it."""

    def spec(name):
        return {"sweep": {"analysis": "test.devices", "output": str(tmp_path / name), "chunk_size": 3},
                "params": {"x": [0.5, 1.0, 1.5, 2.0, 2.5]}}  # fmt: skip

    local = run(spec("local"), progress=False).table
    mirrored = run(spec("ray"), progress=False, executor=ray_executor()).table
    single = run(spec("ray1"), progress=False, executor=RayExecutor(cpu_devices=1)).table
    assert local.column("devices").to_pylist() == [jax.device_count()] * 5
    assert mirrored.equals(local, check_metadata=True)
    assert single.column("devices").to_pylist() == [1] * 5  # computed in a worker, configured there
    assert single.column("twice").to_pylist() == [1.0, 2.0, 3.0, 4.0, 5.0]


def test_host_analysis_on_ray_equals_local(ray_cluster, tmp_path):
    local = run(host_spec(tmp_path / "local"), progress=False)
    remote = run(host_spec(tmp_path / "ray"), progress=False, executor=ray_executor())
    assert remote.table.equals(local.table, check_metadata=True)
    keys = {s: np.asarray(jax.random.PRNGKey(s), dtype=np.uint32) for s in (0, 5)}
    for row in remote.table.to_pylist():
        assert row["r"] == 1.5 * row["a"] ** 2 + float(keys[row["seed"]][1] % 7)


def test_builtin_analysis_on_ray_equals_local(ray_cluster, tmp_path):
    """A real analysis, looked up by name in the workers (which compile the same program
    as this process, so the persistent compilation cache serves both)."""
    doc = {
        "sweep": {"analysis": "octopus.terrain_classification", "chunk_size": 4, "seeds": [0, 1]},
        "fixed": {"samples": 8},
        "params": {"terrain": [0, 2, 4], "height": [0.1, 0.3]},
    }
    local = run({**doc, "sweep": {**doc["sweep"], "output": str(tmp_path / "local")}}, progress=False)
    remote = run({**doc, "sweep": {**doc["sweep"], "output": str(tmp_path / "ray")}}, progress=False,
                 executor=ray_executor())  # fmt: skip
    assert local.table.num_rows == 12
    assert remote.table.equals(local.table, check_metadata=True)


def test_resume_across_executors_both_ways(ray_cluster, tmp_path, monkeypatch):
    full = run(toy_spec(tmp_path / "full"), progress=False).table

    def stop_after(k):
        calls = []

        def on_chunk(index, n):
            calls.append(index)
            if len(calls) == k:
                raise KeyboardInterrupt

        return on_chunk

    # local, interrupted after 2 chunks, resumed on Ray
    spec = toy_spec(tmp_path / "local_then_ray")
    with pytest.raises(SweepInterrupted) as info:
        run(spec, progress=False, on_chunk=stop_after(2))
    assert (info.value.saved, info.value.total) == (2, 5)
    before = chunk_mtimes(spec.output, 5)
    resumed = run(spec, progress=False, resume=True, executor=ray_executor())
    assert (resumed.chunks_computed, resumed.chunks_reused) == (3, 2)
    assert chunk_mtimes(spec.output, 5).items() >= before.items()  # chunks 0, 1 untouched
    assert resumed.table.equals(full, check_metadata=True)

    # Ray, interrupted after its first chunk arrives (nothing more is submitted), resumed locally
    spec = toy_spec(tmp_path / "ray_then_local")
    with pytest.raises(SweepInterrupted) as info:
        run(spec, progress=False, executor=ray_executor(), on_chunk=stop_after(1))
    assert info.value.saved == 1 and len(chunk_mtimes(spec.output, 5)) == 1
    resumed = run(spec, progress=False, resume=True)
    assert (resumed.chunks_computed, resumed.chunks_reused) == (4, 1)
    assert resumed.table.equals(full, check_metadata=True)


def test_ctrl_c_while_waiting_keeps_every_finished_chunk(ray_cluster, tmp_path, monkeypatch):
    """Ctrl+C while the driver waits for Ray: the chunks already finished are saved."""
    original = ray.wait
    blocking_calls = []

    def wait(refs, *, num_returns=1, timeout=None, **kw):
        if timeout is None:
            blocking_calls.append(len(refs))
            if len(blocking_calls) == 2:  # let every running task finish, then "Ctrl+C"
                original(refs, num_returns=len(refs), timeout=None, **kw)
                raise KeyboardInterrupt
        return original(refs, num_returns=num_returns, timeout=timeout, **kw)

    monkeypatch.setattr(ray, "wait", wait)
    spec = toy_spec(tmp_path / "out")  # 5 chunks; 2 slots x 2 = 4 in flight
    with pytest.raises(SweepInterrupted) as info:
        run(spec, progress=False, executor=ray_executor())
    assert blocking_calls == [4, 4]
    assert info.value.saved == 5 and not (spec.output / "table.parquet").exists()
    monkeypatch.setattr(ray, "wait", original)
    resumed = run(spec, progress=False, resume=True, executor=ray_executor())
    assert resumed.chunks_computed == 0
    assert resumed.table.equals(run(toy_spec(tmp_path / "full"), progress=False).table)


def test_worker_errors_arrive_as_themselves(ray_cluster, tmp_path):
    def bad_row(values, key):  # a closure: Ray sends it by value, as from a notebook
        return {"y": jnp.zeros(()), "status": jnp.zeros((), jnp.int32)}

    register(dataclasses.replace(test_sweep_run.TOY, name="test.ray_wrong_keys", row=bad_row))
    spec = toy_spec(tmp_path / "out", analysis="test.ray_wrong_keys")
    with pytest.raises(AnalysisError, match="missing: k, pos, u") as info:
        run(spec, progress=False, executor=ray_executor())
    assert type(info.value) is AnalysisError  # not Ray's wrapper
    assert store.count_saved(spec.output, 5) == 0


# ------------------------------------------------------------------------ CLI

SPEC = """
[sweep]
analysis = "test.toy"
chunk_size = 3
seeds = 2

[params]
a = { start = -1.0, stop = 1.0, num = 4 }
"""


def invoke(*args):
    return CliRunner().invoke(app, list(args))


def test_cli_ray_sweep_and_its_errors(ray_cluster, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    Path("s.toml").write_text(SPEC)
    local = invoke("sweep", "s.toml", "--out", "local", "--quiet")
    assert local.exit_code == 0, local.output
    remote = invoke("sweep", "s.toml", "--out", "ray", "--executor", "ray", "--ray-cpus-per-task", "1")
    assert remote.exit_code == 0, remote.output
    assert "wrote ray/table.parquet (8 rows)" in remote.stdout
    assert pq.read_table("ray/table.parquet").equals(pq.read_table("local/table.parquet"), check_metadata=True)

    bad = invoke("sweep", "s.toml", "--out", "bad", "--executor", "ray", "--address", "127.0.0.1:1")
    assert bad.exit_code == 2
    assert bad.stderr.startswith("error: cannot connect to Ray at 127.0.0.1:1: ")
    assert bad.stderr.count("\n") == 1 and not Path("bad").exists()

    for args, message in [
        (("--address", "auto"), "error: --address, --ray-cpus-per-task and --ray-gpus-per-task need --executor ray"),
        (("--executor", "dask"), "error: --executor: unknown executor 'dask' (known: local, ray)"),
        (("--executor", "ray", "--ray-cpus-per-task", "-1"), "error: --ray-cpus-per-task: must be a number >= 0"),
    ]:
        result = invoke("sweep", "s.toml", "--out", "x", *args)
        assert result.exit_code == 2 and result.stderr.startswith(message), (args, result.output)

    monkeypatch.setitem(sys.modules, "ray", None)
    missing = invoke("sweep", "s.toml", "--out", "y", "--executor", "ray")
    assert missing.exit_code == 2 and missing.stderr == f"error: {RAY_MISSING}\n"
