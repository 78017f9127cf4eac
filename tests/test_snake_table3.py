"""`snake.table3`: Table III measured on the head in MuJoCo, one row per (target, trial)."""

from __future__ import annotations

import numpy as np
import pyarrow as pa
import pytest

from jaxloco import analysis
from jaxloco.robots.snake import experiments, table3


def test_target_deltas_change_one_component_by_the_papers_target():
    d = table3.target_deltas(np.array(table3.TARGETS))
    m = np.stack([d[k] for k in ("d_x", "d_y", "d_z", "d_roll", "d_pitch", "d_yaw")], -1)
    np.testing.assert_array_equal(m, np.diag(experiments.ACCURACY_DELTAS))
    assert not d["d_psi3"].any()


@pytest.fixture(scope="module")
def rows():
    """z and beta targets, two seeds each, a short ramp (one compile for the module)."""
    assert analysis.get("snake.table3") is table3.TABLE3
    fixed = {p.name: p.default for p in table3.PARAMS} | {"ramp": 1.0, "nthread": 2}
    fn = table3.TABLE3.batch_fn(fixed)
    swept = {"target": np.array(["z", "z", "beta", "beta"])}
    keys = np.array([[0, 0], [0, 1], [0, 0], [0, 1]], np.uint32)
    return fn, swept, keys, fn(swept, keys)


def test_rows_measure_the_six_components_and_the_changed_ones_error(rows):
    _, _, _, out = rows
    assert set(out) == {m.name for m in table3.METRICS} | {"status"}
    assert list(out["status"]) == [0, 0, 0, 0]
    # the changed component moves by its target within 10 %, the others stay small
    np.testing.assert_allclose(out["dz"][:2], -0.1, rtol=0.1)
    np.testing.assert_allclose(out["dbeta"][2:], -np.pi / 6, rtol=0.1)
    assert np.abs(np.stack([out["dx"], out["dy"]])).max() < 0.01
    np.testing.assert_allclose(out["error"][:2], 100 * np.abs(out["dz"][:2] + 0.1) / 0.1, rtol=1e-12)
    np.testing.assert_allclose(out["error"][2:], 100 * np.abs(out["dbeta"][2:] + np.pi / 6) / (np.pi / 6),
                               rtol=1e-12)
    assert np.all(out["max_slip"] < 0.05)


def test_a_row_alone_equals_the_row_in_a_batch(rows):
    fn, swept, keys, out = rows
    one = fn({"target": swept["target"][3:]}, keys[3:])
    for name in ("dz", "dbeta", "error"):
        np.testing.assert_allclose(one[name], out[name][3:], rtol=1e-9, atol=1e-12, err_msg=name)


def test_summary_prints_ours_beside_the_papers_mean_and_sd(rows):
    _, swept, _, out = rows
    table = pa.table({"target": swept["target"], "status": np.array(["ok"] * 4), "feedback": np.zeros(4, int),
                      "head_kp": np.full(4, 200.0), "mu": np.ones(4), "ramp": np.ones(4),
                      **{k: out[k] for k in (*table3.COMPONENTS, "error")}})
    s = table3.summarize(table)
    assert [r[1] for r in s.rows] == ["ours (2/2)", "paper (5)", "ours (2/2)", "paper (5)"]
    z_paper = s.rows[1]
    assert z_paper[4] == "-0.1000 ± 0.0009" and z_paper[-1] == "1.5"  # Table III, dz row
    assert s.rows[0][-1] == f"{out['error'][:2].mean():.1f}"
