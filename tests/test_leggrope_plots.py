"""The leg-grope plots on synthetic data (no cycle simulation): every function draws the
expected axes and lines, and `critical_theta` finds the critical values built into the
table (and agrees with `analysis.summarize`)."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pyarrow as pa
import pytest

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from jaxloco.robots.leggrope import plots  # noqa: E402

SLIP = "failed: slip (no distribution with s >= 0 at some step)"
REACH = "failed: leg out of reach"
THETAS = (-0.3, -0.2, -0.1, 0.0, 0.1, 0.2, 0.3)
PSIS = (-1.0, 0.0, 1.0)
# status per psi, in THETAS order, and the critical (+theta, -theta) it implies
STATUSES = {
    -1.0: ("ok", REACH, "ok", "ok", "ok", "ok", SLIP),  # +: 0.2 (0.3 slips); -: 0.1 (-0.3 ok does not count)
    0.0: ("ok",) * 7,  # every row ok: the largest |theta| on both sides
    1.0: ("ok", "ok", "ok", SLIP, "ok", "ok", "ok"),  # theta = 0 fails: none on both sides
}
EXPECTED = {-1.0: (0.2, 0.1, 0.3, 0.2), 0.0: (0.3, 0.3, np.nan, np.nan), 1.0: (np.nan, np.nan, 0.0, 0.0)}
ORDER = (3, 2, 1, 0)  # a non-default groping order: the plots must read it from `free`


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def synthetic_table() -> pa.Table:
    theta, psi, status = [], [], []
    for p in PSIS:
        for t, s in zip(THETAS, STATUSES[p]):
            theta.append(t)
            psi.append(p)
            status.append(s)
    n = len(theta)
    friction = np.linspace(0.2, 1.1, n)
    friction[3] = np.inf  # non-finite values are left out, not an error
    schema = pa.schema(
        [
            pa.field("row", pa.int64()),
            pa.field("theta", pa.float64(), metadata={"unit": "rad"}),
            pa.field("psi", pa.float64(), metadata={"unit": "rad"}),
            pa.field("mu", pa.float64()),
            pa.field("max_friction_use", pa.float64(), metadata={"unit": "", "doc": "friction use"}),
            pa.field("min_ne_margin", pa.float64(), metadata={"unit": "m"}),
            pa.field("status", pa.string()),
            pa.field("seed", pa.int64()),
        ]
    )
    data = dict(row=list(range(n)), theta=theta, psi=psi, mu=[0.45] * n, max_friction_use=friction,
                min_ne_margin=np.linspace(0.01, 0.02, n), status=status, seed=[0] * n)
    return pa.Table.from_pydict(data, schema=schema)


def synthetic_trace(order=ORDER) -> dict[str, np.ndarray]:
    lengths = (100, 20, 40, 20)
    per_grope = sum(lengths)
    n = 4 * per_grope
    i = np.arange(n)
    grope = i // per_grope
    local = i % per_grope
    phase = np.searchsorted(np.cumsum(lengths), local, side="right")
    leg = np.asarray(order)[grope]
    free = np.ones((n, 4), bool)
    free[i, leg] = phase == 0
    ramp = np.zeros((n, 4), bool)
    ramp[i, leg] = (phase == 1) | (phase == 3)
    rng = np.random.default_rng(0)
    forces = rng.normal(size=(n, 4, 3)) + np.array([5.0, 0.0, 20.0])
    ok = np.ones(n, bool)
    ok[[10, 400]] = False
    return dict(
        time=(i + 1) * 0.015,
        grope=grope,
        phase=phase,
        forces=forces,
        s=np.sin(i / 50.0),
        r=np.zeros(n),
        tau=rng.normal(size=(n, 12)),
        r_ref=np.full(n, 33.4),
        ok=ok,
        cog=np.zeros((n, 3)),
        free=free,
        ramp=ramp,
    )


def _texts(ax) -> list[str]:
    return [t.get_text() for t in ax.texts]


def test_importing_plots_does_not_import_matplotlib():
    code = "import sys, jaxloco.robots.leggrope.plots; print('matplotlib' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_critical_theta_finds_the_built_in_values():
    crit = plots.critical_theta(synthetic_table())
    np.testing.assert_allclose(crit.psi, PSIS)
    for k, p in enumerate(PSIS):
        got = (crit.plus[k], crit.minus[k], crit.first_fail_plus[k], crit.first_fail_minus[k])
        np.testing.assert_allclose(got, EXPECTED[p], err_msg=f"psi = {p}")


def test_critical_theta_agrees_with_the_analysis_summary():
    from jaxloco.robots.leggrope.analysis import summarize

    table = synthetic_table()
    crit = plots.critical_theta(table)
    summary = summarize(table)
    plus_col, minus_col = summary.columns.index("crit +theta"), summary.columns.index("crit -theta")
    for k, row in enumerate(summary.rows):
        for col, values in ((plus_col, crit.plus), (minus_col, crit.minus)):
            expected = float("nan") if row[col] == "none" else float(row[col])
            np.testing.assert_allclose(values[k], expected, atol=5e-4)


def test_critical_theta_accepts_a_plain_mapping():
    table = synthetic_table()
    mapping = {name: table.column(name).to_pylist() for name in table.column_names}
    crit = plots.critical_theta(mapping)
    np.testing.assert_allclose(crit.plus, plots.critical_theta(table).plus)


def test_status_category():
    assert [plots.status_category(s) for s in ("ok", SLIP, REACH, None)] == [0, 1, 2, 2]


def test_feasibility_map():
    table = synthetic_table()
    fig = plots.plot_feasibility_map(table)
    assert len(fig.axes) == 1
    ax = fig.axes[0]
    # +-0.40 (paper) and +-atan(0.45)
    xs = sorted(line.get_xdata()[0] for line in ax.lines)
    np.testing.assert_allclose(xs, [-math.atan(0.45), -0.40, 0.40, math.atan(0.45)])
    mesh = ax.collections[0]
    values = np.asarray(mesh.get_array()).reshape(len(PSIS), len(THETAS))
    np.testing.assert_array_equal(values[0], [0, 2, 0, 0, 0, 0, 1])  # psi = -1: ok, reach, ..., slip
    assert [t.get_text() for t in ax.get_yticklabels()][1].startswith("+0.000")
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "ok (18)" in labels and "slip (2)" in labels and "other failure (1)" in labels


def test_feasibility_map_on_given_axes():
    fig, axes = plt.subplots(1, 2)
    assert plots.plot_feasibility_map(synthetic_table(), ax=axes[1]) is fig
    assert len(axes[1].lines) == 4 and len(axes[0].lines) == 0


def test_critical_theta_plot():
    fig = plots.plot_critical_theta(synthetic_table())
    assert len(fig.axes) == 1
    ax = fig.axes[0]
    assert len(ax.lines) == 4  # +theta, -theta, paper 0.40, atan(mu)
    plus, minus = ax.lines[0], ax.lines[1]
    np.testing.assert_allclose(plus.get_xdata(), PSIS)
    np.testing.assert_allclose(plus.get_ydata(), [EXPECTED[p][0] for p in PSIS])
    np.testing.assert_allclose(minus.get_ydata(), [EXPECTED[p][1] for p in PSIS])
    refs = sorted(line.get_ydata()[0] for line in ax.lines[2:])
    np.testing.assert_allclose(refs, [0.40, math.atan(0.45)])


@pytest.mark.parametrize("metric", ["max_friction_use", "min_ne_margin"])
def test_metric_vs_theta(metric):
    fig = plots.plot_metric_vs_theta(synthetic_table(), metric, hline=1.0 if metric == "max_friction_use" else None)
    ax = fig.axes[0]
    extra = 1 if metric == "max_friction_use" else 0
    assert len(ax.lines) == len(PSIS) + 2 + extra
    for line in ax.lines[: len(PSIS)]:
        np.testing.assert_allclose(line.get_xdata(), THETAS)  # sorted by theta
    assert len(ax.collections) == 2  # failed rows marked for psi = -1 and psi = 1
    assert ax.get_ylabel() == ("min_ne_margin [m]" if metric == "min_ne_margin" else metric)


def test_metric_vs_theta_options():
    fig = plots.plot_metric_vs_theta(synthetic_table(), "min_ne_margin", mark_failed=False, paper=False)
    ax = fig.axes[0]
    assert len(ax.lines) == len(PSIS) and not ax.collections
    with pytest.raises(KeyError):
        plots.plot_metric_vs_theta(synthetic_table(), "no_such_metric")


def test_cycle_forces():
    trace = synthetic_trace()
    fig = plots.plot_cycle_forces(trace)
    assert len(fig.axes) == 4
    for n, ax in enumerate(fig.axes):
        assert len(ax.lines) == 4  # F_x, F_y, F_z, R_ref
        np.testing.assert_allclose(ax.lines[2].get_ydata(), trace["forces"][:, n, 2])
        assert ax.lines[3].get_linestyle() == "--"
        assert _texts(ax) == [f"{plots.LEGS[n]} gropes"]
        # leg n gropes in position ORDER.index(n): its hatched span covers phases B-D of that grope
        hatched = [p for p in ax.patches if p.get_hatch()]
        assert len(hatched) == 1
        patch = hatched[0]
        xs = patch.get_patch_transform().transform(patch.get_path().vertices)[:, 0]  # data x (Rectangle or Polygon)
        start = ORDER.index(n) * 180 + 100
        np.testing.assert_allclose([xs.min(), xs.max()], [start * 0.015, (start + 80) * 0.015])
        assert len([p for p in ax.patches if not p.get_hatch()]) == 16  # 4 gropes x 4 phases shaded


def test_cycle_margin():
    trace = synthetic_trace()
    fig = plots.plot_cycle_margin(trace)
    assert len(fig.axes) == 1
    ax = fig.axes[0]
    assert len(ax.lines) == 2  # s and the zero line
    np.testing.assert_allclose(ax.lines[0].get_ydata(), trace["s"])
    assert len(ax.collections) == 1 and len(ax.collections[0].get_offsets()) == 2  # two failed steps
    assert _texts(ax) == [f"grope {plots.LEGS[leg]}" for leg in ORDER]


def test_cycle_margin_without_free_uses_the_order():
    trace = synthetic_trace(order=plots.GROPE_ORDER)
    del trace["free"]
    ax = plots.plot_cycle_margin(trace).axes[0]
    assert _texts(ax) == ["grope L2", "grope L1", "grope L3", "grope L4"]


def test_cycle_torques():
    trace = synthetic_trace()
    fig = plots.plot_cycle_torques(trace)
    assert len(fig.axes) == 4
    for n, ax in enumerate(fig.axes):
        assert len(ax.lines) == 3
        np.testing.assert_allclose(ax.lines[1].get_ydata(), trace["tau"][:, 3 * n + 1])
    assert _texts(fig.axes[0]) == [f"grope {plots.LEGS[leg]}" for leg in ORDER]


def test_cycle_plots_on_a_given_figure():
    fig = plt.figure()
    assert plots.plot_cycle_torques(synthetic_trace(), fig=fig) is fig
    assert len(fig.axes) == 4
