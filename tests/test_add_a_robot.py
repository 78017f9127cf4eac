"""docs/add_a_robot.md runs as written: its Python blocks, executed in order, register a toy
analysis and objective, sweep, tune and validate; the numbers they produce are checked
against the closed forms of the toy."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

DOC = Path(__file__).resolve().parents[1] / "docs" / "add_a_robot.md"


@pytest.fixture(scope="module")
def namespace(tmp_path_factory):
    blocks = re.findall(r"```python\n(.*?)```", DOC.read_text(), flags=re.S)
    assert len(blocks) >= 4, "the page lost its code blocks"
    ns = {"OUT": tmp_path_factory.mktemp("add_a_robot")}
    for i, block in enumerate(blocks):
        exec(compile(block, f"{DOC.name}[block {i}]", "exec"), ns)
    return ns


def test_margins_match_the_closed_form(namespace):
    margins = namespace["margins"]
    sm, ne = margins(0.3, 0.2, 0.25, 0.0)
    assert float(sm) == pytest.approx(0.2) and float(ne) == pytest.approx(math.hypot(0.2, 0.25) - 0.25)
    # walking up a slope moves the projected COG downhill by height * tan(slope); the
    # margin is measured in the horizontal plane, so distances up the slope shrink by cos
    sm, _ = margins(0.3, 0.25, 0.25, 0.4)
    assert float(sm) == pytest.approx(uphill(0.3, 0.4), rel=1e-9)


def uphill(half_length, slope, height=0.25):
    return (half_length - height * math.tan(slope)) * math.cos(slope)


def test_the_sweep_rows_follow_the_model(namespace):
    table = namespace["result"].table
    assert table.num_rows == 21
    for row in table.to_pylist():
        expected = min(0.2, uphill(row["half_length"], row["slope"]))
        assert row["static_margin"] == pytest.approx(expected, abs=1e-9)
        assert row["status"] == ("ok" if expected > 0.05 else "margin below min_margin")


def test_the_tuned_stance_is_near_the_smallest_safe_one(namespace):
    values = namespace["tuned"].values("tuned")
    # smallest stance with a 0.05 m static margin at 0.3 rad: w = 0.05, l = 0.05 / cos 0.3 + 0.25 tan 0.3
    assert values["half_width"] == pytest.approx(0.05, abs=0.01)
    assert values["half_length"] == pytest.approx(0.05 / math.cos(0.3) + 0.25 * math.tan(0.3), abs=0.01)
    rows = {r["label"]: r for r in namespace["check"].comparison.to_pylist()}
    assert rows["hand-set"]["ok_fraction"] == 1.0
    assert rows["tuned"]["static_margin_min"] == pytest.approx(
        min(values["half_width"], uphill(values["half_length"], 0.3)), abs=1e-9)


def test_the_simulated_stance_slides_exactly_when_tan_slope_exceeds_mu(namespace):
    rows = namespace["slides"].table.to_pylist()
    assert [r["mu"] for r in rows] == [0.2, 0.25, 0.35, 0.4]
    for r in rows:
        slides = r["mu"] < math.tan(0.3)
        assert r["status"] == ("slides" if slides else "ok")
        # sliding: about (g sin - mu g cos) t^2 / 2 in 1 s; holding: no more than contact creep
        expected = 0.5 * 9.81 * (math.sin(0.3) - r["mu"] * math.cos(0.3)) if slides else 0.0
        assert r["slide"] == pytest.approx(expected, abs=0.05)


def test_a_simulated_row_replays_through_its_own_simulate(namespace):
    from jaxloco.render.replay import replay_row
    from jaxloco.render.rows import load_row

    row = load_row(namespace["slides"].table_path, 0)
    replay = replay_row(row)
    assert replay.kind == "native MuJoCo simulation" and replay.n_states == 50
    assert replay.metrics["slide"] == row.metrics["slide"] and replay.status == row.status == "slides"
    # the replayed states are those the metric came from: the slide is x's first minus last record
    assert replay.qpos[0, 0] - replay.qpos[-1, 0] == pytest.approx(row.metrics["slide"], rel=1e-12)


def test_states_recorded_on_mjx_match_the_native_ones(namespace):
    """record_state on both backends: the same keys and shapes, the scenario's own records
    untouched, and the states of the two physics engines close (slides of ~0.5 and 0 m)."""
    import numpy as np

    from jaxloco.sim.rollout import rollout

    scenario = namespace["stance_scenario"]({"slope": 0.3})
    params = {"mu": np.array([0.2, 0.4])}
    native = rollout(scenario, params, record_state=True)
    mjx = rollout(scenario, params, backend="mjx", record_state=True)
    assert set(mjx.records) == set(native.records) == {"x"}
    for key in ("qpos", "mocap_pos", "mocap_quat", "time"):
        assert mjx.states[key].shape == native.states[key].shape
    np.testing.assert_allclose(mjx.states["time"], native.states["time"], atol=1e-9)
    np.testing.assert_allclose(mjx.states["qpos"][..., :3], native.states["qpos"][..., :3], atol=0.02)
    assert rollout(scenario, params).states is None
