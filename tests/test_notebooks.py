"""The notebooks run top to bottom on small settings (`jaxloco.notebook`), so they never rot;
plus the helpers that shrink their sweeps."""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from jaxloco import notebook
from jaxloco.errors import SpecError
from jaxloco.sweep import load_spec

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))


@pytest.mark.parametrize(("n", "keep", "expected"), [(5, 2, [0, 4]), (5, 3, [0, 2, 4]), (2, 5, [0, 1]), (7, 1, [0])])
def test_evenly_spreads_first_and_last(n, keep, expected):
    assert notebook.evenly(n, keep) == expected


def test_shrink_keeps_zipped_groups_together_and_checks_fixed():
    spec = load_spec("titan_stride")
    small = notebook.shrink(spec, keep=2, fixed={"n_cycles": 1}, keep_by_name={"frame_size": 3})
    assert small.factors == spec.factors
    assert small.swept["l_std"] == (0.3, 0.5)
    # the zipped terrain cases keep matching (size, interval, slope) triples
    triples = list(zip(small.swept["frame_size"], small.swept["frame_interval"], small.swept["slope"]))
    original = list(zip(spec.swept["frame_size"], spec.swept["frame_interval"], spec.swept["slope"]))
    assert len(triples) == 3 and all(t in original for t in triples)
    assert small.fixed["n_cycles"] == 1 and small.n_rows == 2 * 2 * 2 * 3 * 2
    with pytest.raises(SpecError, match="n_cycles: 0 is outside"):
        notebook.shrink(spec, fixed={"n_cycles": 0})
    with pytest.raises(ValueError, match="'l_std' is swept"):
        notebook.shrink(spec, fixed={"l_std": 0.4})


def test_results_dir_follows_the_environment(monkeypatch, tmp_path):
    monkeypatch.delenv(notebook.OUT_ENV, raising=False)
    monkeypatch.delenv(notebook.SMALL_ENV, raising=False)
    monkeypatch.setattr(notebook, "_TMP", {})  # small mode's temporary root: made afresh, in tmp_path
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    assert not notebook.small() and notebook.results_dir("x") == Path("../results/x")
    monkeypatch.setenv(notebook.SMALL_ENV, "1")
    root = notebook.results_dir("x").parent
    assert notebook.small() and root.name.startswith("jaxloco_notebook_") and root.parent == tmp_path
    monkeypatch.setenv(notebook.OUT_ENV, str(tmp_path))
    assert notebook.results_dir("x") == tmp_path / "x"
    monkeypatch.setenv(notebook.SMALL_ENV, "0")
    assert not notebook.small()


def test_small_mode_temporary_results_are_removed_at_exit(tmp_path):
    """A small-mode run without JAXLOCO_NOTEBOOK_OUT leaves no jaxloco_notebook_* behind."""
    env = {k: v for k, v in os.environ.items() if k != notebook.OUT_ENV}
    env.update({notebook.SMALL_ENV: "1", "TMPDIR": str(tmp_path)})
    code = "from jaxloco import notebook; d = notebook.results_dir('x'); d.mkdir(); (d / 'f').write_text('1'); print(d)"
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=60,
                          check=False)
    assert done.returncode == 0, done.stderr
    made = Path(done.stdout.strip())
    assert made.parent.parent == tmp_path and not made.parent.exists()


def test_small_settings_of_a_tuning_are_checked_like_a_spec(monkeypatch, tmp_path):
    monkeypatch.setenv(notebook.SMALL_ENV, "1")
    monkeypatch.setenv(notebook.OUT_ENV, str(tmp_path))
    with pytest.raises(SpecError, match=r"small_settings\.horizn: unknown"):
        notebook.tune_result("snake_kv_tune", small_settings={"horizn": 2.0})
    with pytest.raises(SpecError, match=r"small_settings\.horizon: -1 s is outside"):
        notebook.tune_result("snake_kv_tune", small_settings={"horizon": -1.0})
    assert not os.listdir(tmp_path)  # nothing ran


def test_there_is_a_notebook_per_robot_and_an_overview():
    names = {p.stem for p in NOTEBOOKS}
    for prefix in ("overview", "leggrope", "octopus", "titan", "snake"):
        assert any(n.startswith(prefix) for n in names), f"no notebook for {prefix}: {sorted(names)}"


def _run_on_small_settings(path: Path, out: Path, monkeypatch) -> None:
    """Execute the notebook at `path` top to bottom in a fresh kernel on small settings,
    results under `out`; it must draw a plot and write something."""
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    monkeypatch.setenv(notebook.SMALL_ENV, "1")
    monkeypatch.setenv(notebook.OUT_ENV, str(out))
    monkeypatch.setenv("MPLBACKEND", "agg")
    nb = nbformat.read(path, as_version=4)
    client = nbclient.NotebookClient(
        nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(path.parent)}}
    )
    client.execute()  # raises CellExecutionError naming the cell on any error
    images = [
        o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", []) if "image/png" in o.get("data", {})
    ]
    assert images, f"{path.name}: no plot was drawn"
    assert os.listdir(out), f"{path.name}: wrote nothing under JAXLOCO_NOTEBOOK_OUT"


# One class per notebook: pytest-xdist (--dist loadscope) hands each class to a worker of
# its own, so the five kernels run side by side rather than one after the other. They are
# handed out in the order below (tests/conftest.py): the longest first, and the overview
# last, whose sweeps (one per robot, the robot notebooks' small settings) then load the
# programs the robot notebooks traced and compiled (program and compilation caches).
@pytest.mark.slow
class _RunsTopToBottom:
    stem = ""

    def test_runs_top_to_bottom_on_small_settings(self, tmp_path, monkeypatch):
        _run_on_small_settings(ROOT / "notebooks" / f"{self.stem}.ipynb", tmp_path, monkeypatch)


class TestSnakeNotebook(_RunsTopToBottom):
    stem = "snake"


class TestLeggropeSlopeNotebook(_RunsTopToBottom):
    stem = "leggrope_slope"


class TestTitanNotebook(_RunsTopToBottom):
    stem = "titan"


class TestOctopusNotebook(_RunsTopToBottom):
    stem = "octopus"


class TestOverviewNotebook(_RunsTopToBottom):
    stem = "overview"


def test_every_notebook_has_its_test_class():
    covered = {cls.stem for cls in _RunsTopToBottom.__subclasses__()}
    assert covered == {p.stem for p in NOTEBOOKS}, "add a _RunsTopToBottom class for each notebook"
