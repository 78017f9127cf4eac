"""The `jaxloco` command line: exit codes, one-line errors, sweep/summary/describe/info."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from test_sweep_run import TASKS, TOY  # noqa: F401  (registers the analyses "test.toy", "test.tasks", ...)
from typer.testing import CliRunner

from jaxloco.cli import app
from jaxloco.errors import SpecError
from jaxloco.sweep import store

REPO = Path(__file__).resolve().parents[1]

GOOD = """
[sweep]
analysis = "test.toy"
chunk_size = 4
seeds = 2

[fixed]
label = "[fixed] stays literal"

[params]
a = { start = -1.0, stop = 1.0, num = 4 }
"""


@pytest.fixture
def workdir(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "sweeps").mkdir()
    (tmp_path / "sweeps" / "good.toml").write_text(GOOD)
    return tmp_path


def invoke(*args):
    return CliRunner().invoke(app, list(args))


def test_sweep_writes_table_and_prints_summary(workdir):
    result = invoke("sweep", "sweeps/good.toml", "--quiet", "--csv")
    assert result.exit_code == 0, result.output
    assert "test.toy: 8 rows by status" in result.stdout
    assert "wrote results/good/table.parquet (8 rows)" in result.stdout
    assert "wrote results/good/table.csv" in result.stdout
    assert (workdir / "results" / "good" / "table.csv").is_file()

    again = invoke("sweep", "sweeps/good.toml", "--quiet")
    assert again.exit_code == 2
    assert again.stderr.strip() == (
        "error: output results/good exists; pass --resume to continue it or --overwrite to start again"
    )

    summary = invoke("summary", "results/good/table.parquet")
    assert summary.exit_code == 0, summary.output
    assert "failed: negative" in summary.stdout and "ok" in summary.stdout


def test_sweep_options_override_the_spec(workdir):
    result = invoke("sweep", "sweeps/good.toml", "--out", "elsewhere", "--chunk-size", "3")
    assert result.exit_code == 0, result.output
    assert len(list((workdir / "elsewhere" / "chunks").iterdir())) == 3
    assert "wrote elsewhere/table.parquet (8 rows)" in result.stdout
    bad = invoke("sweep", "sweeps/good.toml", "--out", "other", "--chunk-size", "0")
    assert bad.exit_code == 2 and bad.stderr.startswith("error: --chunk-size")


@pytest.mark.parametrize(
    "text, message",
    [
        ('[sweep]\nanalysis = "test.toy"\nchunk_sise = 3\n', "error: sweeps/bad.toml: sweep.chunk_sise: unknown key"),
        ('[sweep]\nanalysis = "test.toy"\n[params]\na = [2.1, 10.5]\n',
         "error: sweeps/bad.toml: params.a[1]: 10.5 m is outside"),
        ('[sweep]\nanalysis = "test.toy"\n[params]\na = { start = 0, stop = 1, num = "ten" }\n',
         "error: sweeps/bad.toml: params.a.num: expected an integer, got 'ten'"),
        ("[sweep\n", "error: sweeps/bad.toml: invalid TOML"),
    ],
)  # fmt: skip
def test_bad_spec_is_one_line_and_exit_2(workdir, text, message):
    (workdir / "sweeps" / "bad.toml").write_text(text)
    result = invoke("sweep", "sweeps/bad.toml")
    assert result.exit_code == 2
    assert result.stderr.startswith(message), result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    assert "Traceback" not in result.output
    assert not (workdir / "results").exists()


def test_missing_spec_file(workdir):
    result = invoke("sweep", "sweeps/nope.toml")
    assert result.exit_code == 2
    assert result.stderr.strip() == "error: sweeps/nope.toml: no such file"


def test_interrupted_sweep_exits_130_and_resumes(workdir, monkeypatch):
    original = store.write_chunk
    calls = []

    def interrupt_on_second(out, index, table):
        calls.append(index)
        if len(calls) == 2:
            raise KeyboardInterrupt
        original(out, index, table)

    monkeypatch.setattr(store, "write_chunk", interrupt_on_second)
    result = invoke("sweep", "sweeps/good.toml", "--quiet")
    assert result.exit_code == 130
    assert result.stderr.strip() == "interrupted: 1 of 2 chunks saved in results/good; rerun with --resume"
    monkeypatch.setattr(store, "write_chunk", original)
    resumed = invoke("sweep", "sweeps/good.toml", "--resume", "--quiet")
    assert resumed.exit_code == 0, resumed.output
    assert "(8 rows)" in resumed.stdout
    changed = invoke("sweep", "sweeps/good.toml", "--resume", "--quiet", "--chunk-size", "2")
    assert changed.exit_code == 2 and "different spec" in changed.stderr


def test_describe_and_analyses():
    result = invoke("describe", "test.toy")
    assert result.exit_code == 0, result.output
    for text in ("parameters", "metrics", "statuses", "slope", "[-10, 10]", "failed: negative", "flag", "label"):
        assert text in result.stdout
    unknown = invoke("describe", "no.such")
    assert unknown.exit_code == 2 and unknown.stderr.startswith("error: unknown analysis 'no.such'")
    listed = invoke("analyses")
    assert listed.exit_code == 0 and "test.toy" in listed.stdout and "A toy analysis" in listed.stdout


TASKS_SPEC = """
[sweep]
analysis = "test.tasks"
chunk_size = 4

[params]
task = ["swim", "walk"]
speed = [1.0, 2.0, 3.0]
"""


def test_string_sweep_from_the_command_line(workdir):
    (workdir / "sweeps" / "tasks.toml").write_text(TASKS_SPEC)
    result = invoke("sweep", "sweeps/tasks.toml", "--quiet", "--csv")
    assert result.exit_code == 0, result.output
    assert "test.tasks: 6 rows by task and status" in result.stdout
    summary = invoke("summary", "results/tasks/table.parquet")
    assert summary.exit_code == 0, summary.output
    lines = [" ".join(line.replace("│", " ").split()) for line in summary.stdout.splitlines()]
    assert "swim wet 3 100.0%" in lines and "walk ok 3 100.0%" in lines
    (workdir / "sweeps" / "bad.toml").write_text(TASKS_SPEC.replace('"walk"', '"run"'))
    bad = invoke("sweep", "sweeps/bad.toml", "--quiet")
    assert bad.exit_code == 2
    assert bad.stderr.strip() == "error: sweeps/bad.toml: params.task[1]: 'run' is not one of 'walk', 'climb', 'swim'"


def _sweepable_column(stdout: str) -> dict[str, str]:
    """name -> "yes" / "no" from `jaxloco describe`'s parameter blocks (the test terminal is
    narrow: "task: str, default 'walk', range one of ..., sweepable")."""
    cells = {}
    for line in stdout.splitlines():
        name, _, rest = line.partition(": ")
        if name in ("task", "speed", "note", "mode") and rest.endswith("sweepable"):
            cells[name] = "no" if rest.endswith("not sweepable") else "yes"
    return cells


def test_describe_says_which_string_params_are_sweepable():
    host = invoke("describe", "test.tasks")
    assert host.exit_code == 0, host.output
    assert "one of 'walk', 'climb', 'swim'" in host.stdout
    assert _sweepable_column(host.stdout) == {"task": "yes", "speed": "yes", "note": "no", "mode": "no"}
    under_jax = invoke("describe", "test.tasks_jax")
    assert _sweepable_column(under_jax.stdout)["task"] == "no"


def test_summary_errors(workdir):
    missing = invoke("summary", "nope.parquet")
    assert missing.exit_code == 2 and missing.stderr.strip() == "error: nope.parquet: no such file"
    (workdir / "junk.parquet").write_text("not parquet")
    junk = invoke("summary", "junk.parquet")
    assert junk.exit_code == 2 and junk.stderr.startswith("error: junk.parquet: not a readable Parquet file")


LONG = "a" * 300  # a file name longer than the system allows (255 bytes)


@pytest.mark.parametrize(
    "args",
    [
        ("sweep", f"sweeps/{LONG}.toml"),
        ("sweep", "sweeps/good.toml", "--out", LONG),
        ("sweep", "sweeps/good.toml", "--from-tune", LONG),
        ("summary", f"{LONG}.parquet"),
        ("render", "sweeps/good.toml", "--out", f"{LONG}.gif"),
    ],
    ids=["sweep-spec", "sweep-out", "sweep-from-tune", "summary-table", "render-out"],
)
def test_an_over_long_path_is_one_line_and_exit_2(workdir, args):
    result = invoke(*args)
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    assert "file name too long" in lines[0].lower() and "Traceback" not in result.output


def test_an_over_long_render_source_is_one_spec_error(workdir):
    from jaxloco.render.rows import load_row

    with pytest.raises(SpecError) as info:
        load_row(f"{LONG}.parquet", 0)
    assert str(info.value) == (f"{'a' * 40}...{'a' * 22}.parquet (308 characters): cannot use this path "
                               "(file name too long)")


def test_info_subprocess_is_clean():
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")]))}
    proc = subprocess.run(
        [sys.executable, "-c", "from jaxloco.cli import main; main()", "info"],
        capture_output=True, text=True, env=env, timeout=120, cwd=REPO,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    for name in ("jaxloco", "jax", "jaxlib", "mujoco", "mujoco-mjx", "jax devices", "float64", "compilation cache",
                 "program cache", "qp kernel backend"):
        assert name in proc.stdout
    from importlib.metadata import version

    assert version("jax") in proc.stdout and version("mujoco") in proc.stdout
    assert "warp" not in (proc.stdout + proc.stderr).lower()
    assert proc.stderr.strip() == ""
