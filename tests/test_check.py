"""`jaxloco check SPEC`: the plan it prints matches what the runner does (rows, chunks,
calls per chunk, one compiled shape), bad specs are one line with exit 2, the output
directory's state (absent, complete, resumable) and the time estimate's sources
(recorded by a run, --probe, the header's `# time:` line); nothing compiled without
--probe, nothing written with it."""

from __future__ import annotations

import dataclasses
import json
import re

import jax
import numpy as np
import pytest
from compile_count import compile_events
from test_cli import invoke, workdir  # noqa: F401  (workdir: a fixture, a temporary working directory)
from test_sweep_run import TASKS, TOY  # noqa: F401  (registers the analyses "test.toy", "test.tasks")
from test_tune import TOY as TOY_TUNE  # noqa: F401  (registers the objective "test.toy_tune")

from jaxloco import check, specs
from jaxloco.analysis import Analysis, Metric, Param, register
from jaxloco.sweep import chunks, executors, load_spec, run, store


def _host_simulate(values, keys, simulator):
    """numpy only, as a simulated analysis (the native MuJoCo engine) is."""
    r = values["scale"] * np.asarray(values["a"], dtype=np.float64) ** 2
    return {"r": r, "status": np.zeros(len(r), dtype=np.int64)}


HOST = register(
    Analysis(
        name="test.check_host",
        doc="A numpy-only host analysis.",
        params=(Param("a", 1.0, "input", unit="m"), Param("scale", 2.0, "factor", sweepable=False)),
        metrics=(Metric("r", "scale a^2", unit="m^2"),),
        simulate=_host_simulate,
    )
)

SWEEP = """# A toy sweep for `jaxloco check`.
#
# time: about 2 s on 2 CPU cores

[sweep]
analysis = "test.toy"
chunk_size = {chunk_size}
seeds = 2

[fixed]
n = 4

[params]
a = {{ start = -1.0, stop = 1.0, num = 5 }}
flag = [true, false]
"""  # 5 a x 2 flag x 2 seeds = 20 rows

TUNE = """[tune]
objective = "test.toy_tune"
params = ["gain", "frac"]
steps = 7

[settings]
scale = 2.0

[validate]
sweep = "toy.toml"
map = { frac = "a" }
"""


def write_sweep(workdir, chunk_size=4, name="toy.toml"):
    path = workdir / "sweeps" / name
    path.write_text(SWEEP.format(chunk_size=chunk_size))
    return path


def field(output: str, label: str) -> str:
    """The value printed after `label:` (continuation lines joined)."""
    lines = output.splitlines()
    for i, line in enumerate(lines):
        if line.startswith(f"{label}:"):
            value = [line[check.LABEL_WIDTH :].strip()]
            for more in lines[i + 1 :]:
                if not more.startswith(" "):
                    break
                value.append(more.strip())
            return " ".join(value)
    raise AssertionError(f"no line '{label}:' in\n{output}")


@pytest.fixture
def batch_calls(monkeypatch):
    """The rows of every call of a sweep's batch function (the local executor's)."""
    calls: list[int] = []
    original = executors.prepare

    def counting_prepare(spec, batch_fn=None):
        prepared = original(spec, batch_fn)

        def fn(swept, keys):
            calls.append(int(keys.shape[0]))
            return prepared.fn(swept, keys)

        return dataclasses.replace(prepared, fn=fn)

    monkeypatch.setattr(executors, "prepare", counting_prepare)
    return calls


# ------------------------------------------------------------------------- the plan


def test_rows_per_call_is_the_runners_call_shape():
    assert chunks.rows_per_call(101, 505, 2, host=False) == 102  # padded to the devices
    assert chunks.rows_per_call(4096, 5000, 2, host=False) == 4096  # the chunk, in one call
    assert chunks.rows_per_call(2000, 5000, 2, host=False) == 2000
    assert chunks.rows_per_call(8, 3, 2, host=False) == 4  # never more than the sweep's rows
    assert chunks.rows_per_call(8, 3, 2, host=True) == 8  # a host analysis: the chunk, unpadded


def test_plan_printed_matches_the_runner(workdir, monkeypatch, batch_calls):
    """The rows, chunks and calls that check prints are those of load_spec and of the
    runner's actual calls: one per chunk, all of one shape (the last chunk padded)."""
    path = write_sweep(workdir, chunk_size=5)
    spec = load_spec(path)
    devices = len(jax.devices())
    plan = check.sweep_plan(spec, devices, jax.devices()[0].platform)

    result = invoke("check", str(path))
    assert result.exit_code == 0, result.output
    out = result.stdout
    assert max(len(line) for line in out.splitlines()) <= 80
    assert field(out, "rows") == f"{spec.n_rows} = 5 a x 2 flag x 2 seeds" and spec.n_rows == 20
    assert field(out, "chunks") == "4 x 5 rows"
    batch = -(-5 // devices) * devices
    assert field(out, "calls").startswith(f"1 per chunk (4 in all), {batch} rows per call")
    assert field(out, "compiled shapes") == f"1 (calls padded to {batch} rows)"
    assert field(out, "output") == "results/toy: absent (the sweep creates it)"
    assert "(from the spec's header)" in field(out, "estimate")
    assert not (workdir / "results").exists()

    run(spec, progress=False)
    assert len(batch_calls) == plan.n_chunks == 4
    assert set(batch_calls) == plan.padded == {plan.batch}


def test_host_analysis_one_call_per_chunk_and_a_linear_probe(workdir, batch_calls):
    path = workdir / "sweeps" / "host.toml"
    path.write_text('[sweep]\nanalysis = "test.check_host"\nchunk_size = 4\n[params]\na = [0, 1, 2, 3, 4, 5]\n')
    result = invoke("check", str(path), "--probe")
    assert result.exit_code == 0, result.output
    out = result.stdout
    assert field(out, "chunks") == "2: 1 x 4 rows and the last of 2"
    assert field(out, "calls").startswith("1 per chunk (2 in all), the chunk's rows in one call: a host analysis")
    assert field(out, "compiled shapes") == "none (not compiled by JAX)"
    rows = min(4, 2 * len(jax.devices()))
    assert re.match(rf"[\d.]+ s for 6 rows: one call on {rows} rows took .*, extrapolated linearly \(from the probe\)",
                    field(out, "estimate"))  # fmt: skip
    assert not (workdir / "results").exists()
    run(load_spec(path), progress=False)
    assert batch_calls == [4, 2]


def test_string_sweep_lists_its_values_and_probes(workdir):
    path = workdir / "sweeps" / "tasks.toml"
    path.write_text('[sweep]\nanalysis = "test.tasks"\nchunk_size = 4\n'
                    '[params]\ntask = ["swim", "climb", "walk"]\nspeed = [1.0, 2.0]\n')
    result = invoke("check", str(path), "--probe")
    assert result.exit_code == 0, result.output
    assert field(result.stdout, "rows") == "6 = 3 task (swim, climb, walk) x 2 speed x 1 seed"
    assert field(result.stdout, "estimate").endswith("extrapolated linearly (from the probe)")
    assert not (workdir / "results").exists()


def test_chunk_size_option_and_a_last_smaller_chunk(workdir):
    path = write_sweep(workdir)
    result = invoke("check", str(path), "--chunk-size", "8", "--out", "elsewhere")
    assert result.exit_code == 0, result.output
    assert field(result.stdout, "chunks") == "3: 2 x 8 rows and the last of 4"
    assert field(result.stdout, "output") == "elsewhere: absent (the sweep creates it)"


@pytest.mark.parametrize(
    "text, args, message",
    [
        ('[sweep]\nanalysis = "test.toy"\nchunk_sise = 3\n', (), "sweeps/bad.toml: sweep.chunk_sise: unknown key"),
        ('[sweep]\nanalysis = "test.toy"\n[params]\na = [2.1, 10.5]\n', (), "sweeps/bad.toml: params.a[1]: 10.5 m"),
        ("[fixed]\nn = 3\n", (), "sweeps/bad.toml: neither a [sweep] nor a [tune] table"),
        ('[sweep]\nanalysis = "test.toy"\n[tune]\n', (), "sweeps/bad.toml: both a [sweep] and a [tune] table"),
        ("[sweep\n", (), "sweeps/bad.toml: invalid TOML"),
        ('[sweep]\nanalysis = "test.toy"\n', ("--chunk-size", "0"), "--chunk-size: must be an integer >= 1"),
        ('[sweep]\nanalysis = "test.toy"\n', ("--steps", "3"), "--steps: only for a tune spec"),
    ],
)  # fmt: skip
def test_bad_spec_is_one_line_and_exit_2(workdir, text, args, message):
    (workdir / "sweeps" / "bad.toml").write_text(text)
    result = invoke("check", "sweeps/bad.toml", *args)
    assert result.exit_code == 2
    assert result.stderr.startswith(f"error: {message}"), result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and result.stdout == ""


def test_missing_spec(workdir):
    result = invoke("check", "sweeps/nope.toml")
    assert result.exit_code == 2 and result.stderr.strip() == "error: sweeps/nope.toml: no such file"


# ----------------------------------------------------------- the time estimate


@pytest.fixture
def compiles():
    """JAX's compile events (tracing, lowering, compiling; a persistent-cache hit included)."""
    with compile_events() as events:
        yield events


def test_no_compilation_without_probe(workdir, compiles):
    result = invoke("check", str(write_sweep(workdir)))
    assert result.exit_code == 0, result.output
    assert compiles == []


def test_probe_prints_an_estimate_and_writes_nothing(workdir, compiles):
    result = invoke("check", str(write_sweep(workdir)), "--probe")
    assert result.exit_code == 0, result.output
    assert compiles  # the probe compiled (the listener sees compilations)
    estimate = field(result.stdout, "estimate")
    assert re.match(r"[\d.]+ (s|min).* for 20 rows = compiling .* \+ 5 calls x .* \(from the probe\)$", estimate)
    assert field(result.stdout, "probe took").endswith(" s")
    assert field(result.stdout, "header") == "about 2 s on 2 CPU cores"  # the other source, still shown
    assert not (workdir / "results").exists()


def test_complete_run_uses_recorded_timings(workdir):
    path = write_sweep(workdir)
    done = run(load_spec(path), progress=False)
    manifest = store.read_manifest(done.path)
    seconds, first = store.chunk_times(manifest)
    assert sorted(seconds) == list(range(5)) and first == {0} and all(s > 0 for s in seconds.values())

    result = invoke("check", str(path))
    assert result.exit_code == 0, result.output
    out = result.stdout
    assert field(out, "output").startswith("results/toy: complete: all 5 chunks and table.parquet")
    assert field(out, "estimate").startswith("nothing left to run; 5 chunks took ")
    assert field(out, "estimate").endswith("(recorded by a run)")


def test_interrupted_run_is_resumable_with_k_of_n_chunks(workdir, monkeypatch):
    original = store.write_chunk
    calls = []

    def interrupt_on_third(out, index, table):
        calls.append(index)
        if len(calls) == 3:
            raise KeyboardInterrupt
        original(out, index, table)

    monkeypatch.setattr(store, "write_chunk", interrupt_on_third)
    path = write_sweep(workdir)
    assert invoke("sweep", str(path), "--quiet").exit_code == 130
    monkeypatch.setattr(store, "write_chunk", original)

    result = invoke("check", str(path))
    assert result.exit_code == 0, result.output
    out = result.stdout
    assert field(out, "output") == "results/toy: resumable: 2 of 5 chunks done (continue with --resume)"
    estimate = field(out, "estimate")
    assert re.match(r"[\d.]+ (s|min).* for the 3 remaining chunks; 2 chunks took .* \(.* per call, compiling", estimate)
    assert field(out, "header") == "about 2 s on 2 CPU cores"

    other = invoke("check", str(path), "--chunk-size", "3")  # another spec hash: not resumable
    assert other.exit_code == 0, other.output
    assert "was made from a different spec" in field(other.stdout, "output")
    assert field(other.stdout, "estimate").endswith("(from the spec's header)")


def test_timing_stays_out_of_the_tables_and_the_hash(workdir):
    """Timings live in the manifest only: a resumed run's table equals a straight run's."""
    path = write_sweep(workdir)
    spec = load_spec(path)
    straight = run(spec, progress=False, output=workdir / "straight")
    manifest = json.loads((straight.path / store.MANIFEST).read_text())
    assert manifest["spec_hash"] == spec.hash and store.TIMING in manifest
    assert b"timing" not in b"".join((straight.table.schema.metadata or {}).values())


# ----------------------------------------------------------------------- tunings


def test_tune_spec_prints_steps_and_validation_rows(workdir):
    write_sweep(workdir)
    (workdir / "sweeps" / "tune.toml").write_text(TUNE)
    result = invoke("check", "sweeps/tune.toml", "--steps", "9")
    assert result.exit_code == 0, result.output
    out = result.stdout
    assert max(len(line) for line in out.splitlines()) <= 80
    assert field(out, "tuning") == "tune (sweeps/tune.toml)"
    assert field(out, "objective") == "test.toy_tune (reverse-mode gradients)"
    assert field(out, "tunables") == "gain = 1, frac = 0.5 (initial values)"
    assert field(out, "held") == "width = 0, offset = 0, k = 2"
    assert field(out, "settings") == "scale = 2, target_gain = 3, quartic = 0"
    assert field(out, "optimizer") == "adam" and field(out, "learning rate") == "0.05"
    assert field(out, "steps") == "9 (11 evaluations: steps 0 to 9 and 1 reference)"
    assert field(out, "output") == "results/tune: absent (the tuning creates it)"
    # toy.toml without its swept a: 2 flag x 2 seeds per set
    assert field(out, "validate") == ("sweep 'toy' (sweeps/toy.toml): 4 rows per compared set, at most 3 sets "
                                      "(initial, tuned, paper; equal sets run once) = 12 rows")  # fmt: skip
    assert field(out, "estimate").startswith("unknown")

    bad = invoke("check", "sweeps/tune.toml", "--chunk-size", "3")
    assert bad.exit_code == 2
    assert bad.stderr.strip() == "error: --chunk-size: only for a sweep spec; this is a tune spec"


def test_tune_probe(workdir):
    write_sweep(workdir)
    (workdir / "sweeps" / "tune.toml").write_text(TUNE)
    result = invoke("check", "sweeps/tune.toml", "--probe")
    assert result.exit_code == 0, result.output
    estimate = field(result.stdout, "estimate")
    assert re.match(r"[\d.]+ (s|min).* = compiling .* \+ 9 evaluations x .* \(from the probe\)$", estimate)
    assert not (workdir / "results").exists()


def test_bundled_sweep_without_probe(tmp_path):
    # an empty output directory: a results/leggrope_slope left by README command 1 in the
    # working directory would make the estimate "nothing left to run"
    result = invoke("check", "leggrope_slope", "--out", str(tmp_path / "out"))
    assert result.exit_code == 0, result.output
    assert field(result.stdout, "rows") == "505 = 101 theta x 5 psi x 1 seed"
    assert field(result.stdout, "estimate") == f"{specs.header('leggrope_slope').time} (from the spec's header)"
