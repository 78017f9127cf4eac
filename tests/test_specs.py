"""Bundled specs (`jaxloco.specs`): lookup by name from any directory, `jaxloco sweeps`,
model regeneration to a path the user gives, and a wheel that runs a bundled simulated
spec outside the repository."""

from __future__ import annotations

import os
import subprocess
import sys
import sysconfig
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from jaxloco import specs
from jaxloco.cli import app
from jaxloco.errors import SpecError
from jaxloco.robots.leggrope import model as leggrope_model
from jaxloco.sweep import load_spec as load_sweep
from jaxloco.tune import load_spec as load_tune

REPO = Path(__file__).resolve().parents[1]


def invoke(*args):
    return CliRunner().invoke(app, list(args))


def test_every_bundled_spec_loads_by_name_from_another_directory(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    names = specs.names()
    assert len(names) >= 12 and "leggrope_slope" in names
    for name in names:
        head = specs.header(name)
        loaded = (load_tune if head.kind == "tune" else load_sweep)(name)
        assert Path(loaded.source) == specs.DIRECTORY / f"{name}.toml"
        if head.kind == "sweep":  # the header's count agrees with the validated grid
            assert head.size == f"{loaded.n_rows:,} rows", name
        else:
            assert head.size == f"{loaded.steps} steps", name
        assert head.question and head.time, f"{name}: the header needs a question and a '# time:' line"


def test_tune_specs_find_their_validation_sweep_in_the_bundle():
    for name in specs.names():
        if specs.header(name).kind == "tune":
            plan = load_tune(name).validation
            assert plan is None or Path(plan.sweep).parent == specs.DIRECTORY


def test_a_path_wins_over_a_bundled_name(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    Path("leggrope_slope").write_text('[sweep]\nanalysis = "leggrope.slope_cycle"\n[params]\ntheta = [0.1]\n')
    assert specs.resolve("leggrope_slope") == Path("leggrope_slope")
    assert load_sweep("leggrope_slope").n_rows == 1
    assert specs.resolve("leggrope_slope.toml") == specs.DIRECTORY / "leggrope_slope.toml"


def test_a_typo_names_the_closest_bundled_spec_in_one_line():
    with pytest.raises(SpecError) as info:
        load_sweep("leggrope_slop")
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith("leggrope_slop: no such file or bundled spec (did you mean 'leggrope_slope'?")
    assert all(name in message for name in specs.names())
    result = invoke("sweep", "leggrope_slop")
    assert result.exit_code == 2
    assert (
        result.stderr.startswith("error: leggrope_slop: no such file or bundled spec")
        and result.stderr.count("\n") == 1
    )


def test_a_missing_path_still_says_no_such_file(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SpecError, match=r"^x/leggrope_slope.toml: no such file$"):
        load_sweep("x/leggrope_slope.toml")


def test_render_finds_a_row_of_a_bundled_spec_by_name(tmp_path, monkeypatch):
    from jaxloco.render.rows import load_row

    monkeypatch.chdir(tmp_path)  # no results here: the row comes from the spec's grid
    row = load_row("titan_stride", 5)
    assert row.analysis.name == "titan.stride" and row.index == 5 and row.n_rows == load_sweep("titan_stride").n_rows
    with pytest.raises(SpecError, match="did you mean 'titan_stride'"):
        load_row("titan_strid", 0)


def test_sweeps_lists_every_bundled_spec_with_rows_and_time():
    result = invoke("sweeps")
    assert result.exit_code == 0, result.output
    for name in specs.names():
        head = specs.header(name)
        assert name in result.stdout and head.size in result.stdout
    assert "505 rows" in result.stdout and "leggrope.slope_cycle" in result.stdout


def test_count_rows_handles_zip_steps_and_seed_counts():
    doc = {
        "sweep": {"zip": [["a", "b"]], "seeds": 3},
        "params": {"a": [1, 2], "b": [3, 4], "c": {"start": 0.0, "stop": 1.0, "step": 0.25}},
    }
    assert specs.count_rows(doc) == 2 * 5 * 3
    assert specs.count_rows({"sweep": {"combine": "zip"}, "params": {"a": [1, 2], "b": [3, 4]}}) == 2


def test_model_regeneration_writes_where_asked(tmp_path, capsys):
    out = tmp_path / "leggrope.xml"
    leggrope_model.main(["--write", str(out)])
    assert out.read_text() == leggrope_model.MODEL_PATH.read_text()
    assert capsys.readouterr().out.strip() == f"wrote {out}"
    with pytest.raises(SystemExit) as info:
        leggrope_model.main(["--write", str(tmp_path / "no" / "dir" / "x.xml")])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("error: cannot write") and err.count("\n") == 1


def _run(cmd: list[str], **kwargs) -> subprocess.CompletedProcess:
    done = subprocess.run(cmd, capture_output=True, text=True, **kwargs)
    assert done.returncode == 0, f"{cmd}: {done.stdout[-2000:]}\n{done.stderr[-2000:]}"
    return done


def _source_copy(dest: Path) -> Path:
    """The files a wheel is built from, copied (the build leaves nothing in the checkout)."""
    import shutil

    dest.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(REPO / name, dest / name)
    shutil.copytree(REPO / "jaxloco", dest / "jaxloco", ignore=shutil.ignore_patterns("__pycache__"))
    return dest


def test_wheel_runs_a_bundled_simulated_spec_from_any_directory(tmp_path):
    """Build the wheel, install it (no dependencies: they come from this environment
    through a .pth line) into a fresh venv, and run `jaxloco sweep snake_reach` (native
    MuJoCo, the robot's MJCF from the package) in an empty directory."""
    source = _source_copy(tmp_path / "src")
    wheels = tmp_path / "wheels"
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(wheels), str(source)])
    (wheel,) = wheels.glob("jaxloco-*.whl")
    venv = tmp_path / "venv"
    _run([sys.executable, "-m", "venv", "--without-pip", str(venv)])
    bin_dir = venv / ("Scripts" if os.name == "nt" else "bin")
    python = bin_dir / "python"
    site = Path(_run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"]).stdout.strip())
    (site / "deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    _run([sys.executable, "-m", "pip", "--python", str(python), "install", "--no-deps", "-q", str(wheel)])

    work = tmp_path / "elsewhere"
    work.mkdir()
    env = {**os.environ, "PYTHONPATH": ""}
    where = _run([str(python), "-c", "import jaxloco; print(jaxloco.__file__)"], cwd=work, env=env).stdout
    assert where.startswith(str(site)), where
    listing = _run([str(bin_dir / "jaxloco"), "sweeps"], cwd=work, env=env).stdout
    assert "snake_reach" in listing
    _run([str(bin_dir / "jaxloco"), "sweep", "snake_reach", "--quiet"], cwd=work, env=env)
    table = pq.read_table(work / "results" / "snake_reach" / "table.parquet")
    assert table.num_rows == 8 and set(table.column("status").to_pylist()) == {"ok"}
