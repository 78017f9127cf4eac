"""The catalog (`jaxloco/catalog.json`) behind `jaxloco analyses`, `describe` and
`objectives`: it is current, reading it imports no JAX, and the commands print the same
from it as from the live registries."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from typer.testing import CliRunner

from jaxloco import analysis as analysis_registry
from jaxloco import catalog
from jaxloco.analysis import Analysis, Metric, Param
from jaxloco.cli import app
from jaxloco.tune import objective as objective_registry
from jaxloco.tune.objective import Objective, Tunable

REPO = Path(__file__).resolve().parents[1]


def invoke(*args):
    return CliRunner().invoke(app, list(args))


def _stale_entries(packaged: dict, built: dict) -> list[str]:
    """'analyses/NAME' and 'objectives/NAME' entries that differ (or exist on one side only)."""
    stale = []
    for section in ("analyses", "objectives"):
        old, new = packaged.get(section, {}), built[section]
        stale += [f"{section}/{name}" for name in sorted(set(old) | set(new)) if old.get(name) != new.get(name)]
    return stale


def test_packaged_catalog_is_current():
    packaged = json.loads(catalog.DEFAULT_PATH.read_text(encoding="utf-8"))
    built = json.loads(catalog.dumps(catalog.build()))
    stale = _stale_entries(packaged, built)
    assert packaged == built, (
        f"jaxloco/catalog.json is out of date ({', '.join(stale) or 'header'}): "
        f"regenerate it with `{catalog.WRITE_COMMAND}`"
    )


def test_write_then_load_round_trips(tmp_path):
    target = tmp_path / "catalog.json"
    assert catalog.main(["--write", str(target)]) == 0
    loaded = catalog.load(target)
    assert loaded is not None and set(loaded.analyses) == set(analysis_registry.ANALYSES.builtin)
    assert set(loaded.objectives) == set(objective_registry.OBJECTIVES.builtin)
    for name in analysis_registry.ANALYSES.builtin:
        live, info = analysis_registry.get(name), loaded.analyses[name]
        assert (info.params, info.metrics, info.statuses) == (live.params, live.metrics, live.statuses)
        assert (info.doc, info.x64, info.executor) == (live.doc, live.x64, live.executor)
    for name in objective_registry.OBJECTIVES.builtin:
        live, info = objective_registry.get(name), loaded.objectives[name]
        assert (info.tunables, info.settings, info.doc) == (live.tunables, live.settings, live.doc)
        assert {k: dict(v) for k, v in info.references.items()} == {k: dict(v) for k, v in live.references.items()}
    assert catalog.main([]) == 2


def test_values_round_trip_through_json():
    param = Param("p", math.inf, "d", unit="m", lo=-math.inf, hi=2.5, lo_open=True, choices=(1, 2.5, "a", None))
    data = json.loads(json.dumps(catalog._record_to_data(param), allow_nan=False))
    assert catalog._record_from_data(Param, data) == param
    nested = {"t": (1, (2.0, -math.inf)), "l": [None, True, 0.1], "x": -0.0}
    back = catalog.decode_value(json.loads(json.dumps(catalog.encode_value(nested), allow_nan=False)))
    assert back == nested and isinstance(back["t"][1], tuple)
    assert math.isnan(catalog.decode_value(json.loads(json.dumps(catalog.encode_value(math.nan)))))


def test_missing_or_unreadable_catalog_is_none(tmp_path):
    assert catalog.load(tmp_path / "nope.json") is None
    (tmp_path / "junk.json").write_text("{not json")
    assert catalog.load(tmp_path / "junk.json") is None
    (tmp_path / "other.json").write_text(json.dumps({"format": 999, "analyses": {}, "objectives": {}}))
    assert catalog.load(tmp_path / "other.json") is None
    (tmp_path / "broken.json").write_text(json.dumps({"format": catalog.FORMAT, "analyses": {"a": {}}}))
    assert catalog.load(tmp_path / "broken.json") is None


def test_an_objective_entry_that_no_longer_fits_falls_back_to_the_registry(tmp_path, monkeypatch):
    data = json.loads(catalog.DEFAULT_PATH.read_text(encoding="utf-8"))
    data["objectives"]["titan.stride"]["tunables"][0]["renamed_field"] = 1.0
    (tmp_path / "old.json").write_text(json.dumps(data))
    loaded = catalog.load(tmp_path / "old.json")
    for name in ("titan.stride", "snake.kv"):  # as if not loaded yet
        monkeypatch.delitem(objective_registry.OBJECTIVES._loaded, name, raising=False)
    assert isinstance(catalog.objective("titan.stride", loaded), Objective)
    assert isinstance(catalog.objective("snake.kv", loaded), catalog.ObjectiveInfo)


def test_reading_the_catalog_imports_no_jax():
    script = textwrap.dedent(
        """
        import sys
        from jaxloco import catalog
        from jaxloco.cli import main

        built_ins = catalog.load()
        assert built_ins is not None
        assert all(type(catalog.analysis(n, built_ins)) is catalog.AnalysisInfo for n in built_ins.analyses)
        assert all(type(catalog.objective(n, built_ins)) is catalog.ObjectiveInfo for n in built_ins.objectives)
        for args in (["analyses"], ["describe", "snake.reach"], ["objectives"], ["objectives", "snake.reach_gain"]):
            sys.argv = ["jaxloco", *args]
            try:
                main()
            except SystemExit as exc:
                assert not exc.code, (args, exc.code)
        from jaxloco.info import static_environment

        static_environment()
        loaded = sorted(m for m in sys.modules if m.split(".")[0] in ("jax", "jaxlib", "mujoco"))
        assert not loaded, loaded
        # the robots' entries modules (strings only) and their packages, no robot code
        robot_code = [m for m in sys.modules if m.startswith("jaxloco.robots.")
                      and not m.endswith(".entries") and m.count(".") > 2]
        assert not robot_code, robot_code
        """
    )
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")]))}
    proc = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=120, cwd=REPO
    )
    assert proc.returncode == 0, proc.stderr
    assert "snake.reach" in proc.stdout


@pytest.fixture
def catalog_vs_live(monkeypatch):
    """`outputs(*args)`: the command's stdout from the catalog, then from the live registries
    (built-ins already loaded by other tests are hidden for the catalog run)."""

    def outputs(*args):
        with monkeypatch.context() as patch:
            for registry in (analysis_registry.ANALYSES, objective_registry.OBJECTIVES):
                patch.setattr(registry, "_loaded", {})
            from_catalog = invoke(*args)
        with monkeypatch.context() as patch:
            patch.setattr(catalog, "load", lambda path=None: None)
            live = invoke(*args)
        assert from_catalog.exit_code == 0, from_catalog.output
        assert live.exit_code == 0, live.output
        return from_catalog.stdout, live.stdout

    return outputs


@pytest.mark.parametrize(
    "args",
    [("analyses",), ("objectives",)]
    + [("describe", name) for name in sorted(analysis_registry.ANALYSES.builtin)]
    + [("objectives", name) for name in sorted(objective_registry.OBJECTIVES.builtin)],
)
def test_catalog_output_equals_live_output(catalog_vs_live, args):
    from_catalog, live = catalog_vs_live(*args)
    assert from_catalog == live


def _toy_analysis(name: str, doc: str) -> Analysis:
    return Analysis(name, doc, (Param("gain", 1.0, "a gain", lo=0.0),), (Metric("m", "a metric"),), lambda fixed: None)


def _toy_objective(name: str, doc: str) -> Objective:
    return Objective(name, doc, (Tunable("k", 2.0, "a tunable", lo=0.0, hi=5.0),), (), lambda settings: None)


def test_names_registered_at_run_time_still_show(monkeypatch):
    extra, tune = "test.catalog_extra", "test.catalog_tune"
    monkeypatch.setitem(analysis_registry.ANALYSES._registered, extra, _toy_analysis(extra, "Extra."))
    monkeypatch.setitem(analysis_registry.ANALYSES._registered, "snake.kv", _toy_analysis("snake.kv", "Overridden kv."))
    monkeypatch.setitem(objective_registry.OBJECTIVES._registered, tune, _toy_objective(tune, "Tune."))
    listed = invoke("analyses")
    assert listed.exit_code == 0 and "test.catalog_extra" in listed.stdout and "Overridden kv." in listed.stdout
    assert "leggrope.slope_cycle" in listed.stdout
    described = invoke("describe", "test.catalog_extra")
    assert described.exit_code == 0 and "Extra." in described.stdout and "gain" in described.stdout
    assert "Overridden kv." in invoke("describe", "snake.kv").stdout
    objectives = invoke("objectives")
    assert objectives.exit_code == 0 and tune in objectives.stdout and "titan.stride" in objectives.stdout
    one = invoke("objectives", "test.catalog_tune")
    assert one.exit_code == 0 and "a tunable" in one.stdout


def test_unknown_names_list_the_known_ones():
    unknown = invoke("describe", "no.such")
    assert unknown.exit_code == 2
    assert unknown.stderr.startswith("error: unknown analysis 'no.such' (known: ") and "snake.kv" in unknown.stderr
    missing = invoke("objectives", "no.such")
    assert missing.exit_code == 2
    assert missing.stderr.startswith("error: unknown objective 'no.such' (known: ") and "titan.stride" in missing.stderr
