"""`titan.stride`: registration and parameter checks, batching (the vmapped rows equal
`gait.sweep_metrics` one at a time), the standard gait on flat ground in closed form
(2 L_std per cycle, no failures), an impossible margin, the smooth objective's
forward-mode derivative against central differences, and the summary table."""

from functools import cache

import jax
import jax.numpy as jnp
import numpy as np
import pyarrow as pa
import pytest

from jaxloco import analysis
from jaxloco.robots.titan import analysis as ta
from jaxloco.robots.titan import gait, params
from jaxloco.sweep import SpecError, chunks, spec_from_dict

# small maps and two cycles keep the compilations short
FIXED = {**ta.STRIDE.defaults(), "n_cycles": 2, "map_nx": 100, "map_ny": 80}
SHAPE = (FIXED["map_nx"], FIXED["map_ny"])
SWEEPABLE = [p.name for p in ta.PARAMS if p.sweepable]
PAD = 10  # every batch call has this many rows: one compilation
H = 1e-4  # [m] central-difference step in l_std
S_TIGHT = 0.08  # [m] S_NE^c just below the flat-ground standard NESM (0.085 m): the
# objective's sigmoid is then in its sloped part, so its derivative sees the margins

ROWS = [
    {"frame_size": 0.2, "frame_interval": 2.0},
    {"frame_size": 0.3, "frame_interval": 3.0, "direction": 0.3, "l_std": 0.4},
    {"frame_size": 0.2, "frame_interval": 1.5, "slope": 0.5236, "w_std": 0.8},
    {"frame_size": 0.0},  # flat, default stride
    {"frame_size": 0.0, "l_std": 0.35},
    {"frame_size": 0.0, "s_ne_c": 0.3},  # impossible margin
    {"frame_size": 0.0, "s_ne_c": S_TIGHT, "l_std": params.L_STD + H},
    {"frame_size": 0.0, "s_ne_c": S_TIGHT, "l_std": params.L_STD - H},
    # a mixed field (4 m blocks of 0.2 m / 2 m and 0.3 m / 3 m frames), off a body axis
    {"frame_size": 0.2, "frame_interval": 2.0, "mix_block": 4.0, "frame_size_b": 0.3, "frame_interval_b": 3.0,
     "direction": 2.4, "start_x": 5.5},
]


@cache
def _batch():
    return chunks.jitted_batch(ta.STRIDE.name, ta.STRIDE.batch_fn(FIXED))  # as a sweep jits it


@pytest.fixture(scope="module")
def rows() -> dict[str, np.ndarray]:
    full = [{**FIXED, **r} for r in ROWS] + [FIXED] * (PAD - len(ROWS))
    swept = {n: jnp.asarray([r[n] for r in full], jnp.float64) for n in SWEEPABLE}
    keys = jax.vmap(jax.random.PRNGKey)(jnp.arange(PAD))
    out = _batch()(swept, keys)
    return {k: np.asarray(v)[: len(ROWS)] for k, v in out.items()}


def test_registered_and_params_validate():
    a = analysis.get("titan.stride")
    assert a is ta.STRIDE and a.x64
    assert all(p.doc for p in a.params) and all(m.doc for m in a.metrics)
    assert {"min_nesm", "distance_per_cycle", "n_failures", "n_modifications", "path_deviation", "nesm_ok",
            "objective"} <= {m.name for m in a.metrics}
    base = {"sweep": {"analysis": "titan.stride"}}
    spec = spec_from_dict({**base, "params": {"l_std": [0.3, 0.5]}})
    assert spec.n_rows == 2 and spec.fixed["n_cycles"] == 4
    with pytest.raises(SpecError, match="l_std"):
        spec_from_dict({**base, "params": {"l_std": [0.0, 0.5]}})
    with pytest.raises(SpecError, match="s_ne_c"):
        spec_from_dict({**base, "fixed": {"s_ne_c": 0.31}})
    with pytest.raises(SpecError, match="frame_size"):
        spec_from_dict({**base, "params": {"frame_size": [0.2, 0.4]}})
    with pytest.raises(SpecError, match="n_cycles"):
        spec_from_dict({**base, "params": {"n_cycles": [2, 4]}})


def test_batch_equals_sweep_metrics_one_at_a_time(rows):
    one = jax.jit(gait.sweep_metrics, static_argnums=(5, 6, 7))
    for i, r in enumerate(ROWS):
        v = {**FIXED, **r}
        par = params.default_params().astype(jnp.float64).with_(
            **{n: jnp.asarray(v[n], jnp.float64) for n in ta.TITAN_PARAMS}
        )
        field = ta.field_values({n: jnp.float64(v[n]) for n in SWEEPABLE})
        ref = one(par, jnp.float64(v["frame_size"]), jnp.float64(v["frame_interval"]), jnp.float64(v["slope"]),
                  jnp.float64(v["direction"]), FIXED["n_cycles"], SHAPE, FIXED["cell"], **field)
        for k, x in ref.items():
            np.testing.assert_allclose(rows[k][i], np.asarray(x), rtol=1e-9, atol=1e-12, err_msg=f"row {i} {k}")


def test_frame_rows_walk(rows):
    for i in (0, 1, 2, 8):  # the Sec. 7 and 8.4 cases with the default margin: walking, safely
        assert rows["n_failures"][i] == 0 and rows["nesm_ok"][i] and rows["status"][i] == 0
        assert rows["distance_per_cycle"][i] > 0.3
        assert rows["min_nesm"][i] >= params.S_NE_C
        assert rows["softmin_nesm"][i] <= rows["min_nesm"][i] + 1e-12


def test_flat_ground_standard_gait_closed_form(rows):
    for i, l_std in ((3, params.L_STD), (4, 0.35)):
        assert rows["distance_per_cycle"][i] == pytest.approx(2.0 * l_std, abs=1e-9)
        assert rows["n_failures"][i] == 0 and rows["n_modifications"][i] == 0
        assert rows["path_deviation"][i] == pytest.approx(0.0, abs=1e-9)
        assert rows["nesm_ok"][i] and rows["status"][i] == 0
    # params.py: the standard gait has NESM = 0.085 m on flat ground
    assert rows["min_nesm"][3] == pytest.approx(0.085, abs=1e-3)
    # soft-min bounds: min - tau log(S) <= softmin <= min, S = 12 steps
    tau = FIXED["softmin_tau"]
    assert rows["min_nesm"][3] - tau * np.log(12) <= rows["softmin_nesm"][3] <= rows["min_nesm"][3]


def test_impossible_margin_fails(rows):
    i = 5
    assert rows["n_failures"][i] == FIXED["n_cycles"]
    assert not rows["nesm_ok"][i] and rows["status"][i] == 1
    assert rows["distance_per_cycle"][i] == 0.0 and rows["objective"][i] == pytest.approx(0.0, abs=1e-12)


def test_objective_forward_derivative_matches_central_difference(rows):
    f = ta.objective_fn({**FIXED, "frame_size": 0.0, "s_ne_c": S_TIGHT})
    value, slope = jax.jit(lambda l_std: jax.jvp(lambda x: f(x, params.W_STD), (l_std,), (1.0,)))(params.L_STD)
    assert np.isfinite(float(value)) and np.isfinite(float(slope))
    fd = (rows["objective"][6] - rows["objective"][7]) / (2.0 * H)
    assert float(slope) == pytest.approx(fd, rel=1e-4, abs=1e-6)
    # the margin term matters here: the slope differs from the speed term alone (2 per m)
    assert abs(float(slope) - 2.0) > 0.05


def test_summary_picks_the_fastest_safe_stride():
    cols = {n: [] for n in (*ta.GROUP, *ta.STRIDE_COLS, "n_cycles", "distance_per_cycle", "min_nesm", "nesm_ok",
                            "n_modifications", "path_deviation", "objective")}

    def add(case, stride, dist, nesm, ok):
        for n, x in zip((*ta.GROUP, *ta.STRIDE_COLS), (*case, *stride)):
            cols[n].append(x)
        for n, x in (("n_cycles", 4), ("distance_per_cycle", dist), ("min_nesm", nesm), ("nesm_ok", ok),
                     ("n_modifications", 0), ("path_deviation", 0.0), ("objective", dist)):
            cols[n].append(x)

    a, b = (0.2, 2.0, 0.0, 0.0, 1.0), (0.3, 3.0, 0.0, 0.0, 1.0)
    add(a, (0.3, 1.0, 0.03), 0.6, 0.05, True)
    add(a, (0.5, 1.0, 0.03), 0.95, 0.04, True)
    add(a, (0.5, 0.8, 0.03), 0.95, 0.06, True)  # as fast, more margin: the best
    add(a, (0.6, 1.0, 0.03), 1.1, 0.01, False)  # faster but unsafe
    add(b, (0.5, 1.0, 0.3), 0.0, 0.08, False)
    s = ta.summarize(pa.table(cols))
    assert len(s.rows) == 2 and "tether" not in s.columns
    best = dict(zip(s.columns, s.rows[0]))
    assert best["ok"] == "3/4" and (best["L_std"], best["W_std"]) == ("0.5", "0.8")
    assert best["dist/cycle"] == "0.950" and best["min NESM"] == "0.060"
    assert s.rows[1][s.columns.index("ok")] == "0/1" and s.rows[1][-1] == "-"


def test_direction_study_summary_counts_walks_per_field():
    """One stride and many headings: one summary row per field (mixed fields named), the
    ok walks, failed cycles, the worst min NESM with its heading, and the headings that
    failed in a note."""
    heads = np.radians(np.arange(0.0, 360.0, 90.0))
    cols = {n: [] for n in (*ta.GROUP, *ta.STRIDE_COLS, "frame_size_b", "frame_interval_b", "mix_block",
                            "n_cycles", "distance_per_cycle", "min_nesm", "nesm_ok", "n_failures")}
    for size, interval, block in ((0.2, 2.0, 0.0), (0.2, 2.0, 6.0)):
        for k, h in enumerate(heads):
            bad = block > 0 and k == 1
            row = dict(frame_size=size, frame_interval=interval, slope=0.0, direction=h, tether=1.0, l_std=0.5,
                       w_std=1.0, s_ne_c=0.03, frame_size_b=0.3, frame_interval_b=3.0, mix_block=block, n_cycles=6,
                       distance_per_cycle=0.2 if bad else 1.0 - 0.01 * k, min_nesm=0.04 - 0.001 * k,
                       nesm_ok=not bad, n_failures=3 if bad else 0)
            for n, x in row.items():
                cols[n].append(x)
    assert ta.is_direction_study({n: np.asarray(v) for n, v in cols.items()})
    s = ta.summarize(pa.table(cols))
    assert [r[0] for r in s.rows] == ["0.2 m / 2 m", "mixed 0.2 m / 2 m + 0.3 m / 3 m, 6 m blocks"]
    assert s.rows[0][1:5] == ("4", "4/4", "0", "0.037 at 270")
    assert s.rows[1][2:4] == ("3/4", "3")
    assert s.rows[0][5] == f"{np.mean([1.0, 0.99, 0.98, 0.97]):.2f} (0.97)"
    assert any(n.startswith("mixed") and n.endswith("not ok at 90 deg") for n in s.notes)
