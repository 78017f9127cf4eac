"""The leg-grope walk in simulation: force sensing, a collapsing foothold, and the
`leggrope.fragile_walk` sweep (resume after an interruption)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from compile_count import run_counting

from jaxloco.errors import SweepInterrupted
from jaxloco.robots.leggrope import control, gait, model, scenarios
from jaxloco.robots.leggrope.params import G, default_params
from jaxloco.sim.rollout import rollout
from jaxloco.sweep import run as run_sweep

THETA = float(np.pi / 12)


@pytest.fixture(scope="module")
def walk():
    """Three 9 s walks (the default forward crawl) on the pi/12 slope: sound footholds;
    L2's first target weak (L2 gropes first, so its foothold collapses during the first
    grope); L2's first target just under R_ref (0.482-0.483 M g against R_ref = 0.4830
    M g), with the walk set to stop at a collapse as in the paper's experiment."""
    sc = scenarios.make_scenario(horizon_s=9.0, record_every=5)
    p = scenarios.params_batch(3, theta=THETA, weak_leg=np.array([-1, 1, 1]), regrope=np.array([1, 1, 0]),
                               r_break_lo=np.array([0.35, 0.35, 0.482]), r_break_hi=np.array([0.45, 0.45, 0.483]))
    return sc, rollout(sc, p, seeds=[0, 0, 0])


def test_toe_force_sensors_carry_the_weight(walk):
    _, r = walk
    mg = float(default_params().total_mass) * G
    # at 0.5 s the robot stands on four legs: normal forces sum to M g cos(theta)
    i = int(np.searchsorted(r.times, 0.5))
    total = r.records["normal_force"][0, i].sum()
    assert abs(total - mg * np.cos(THETA)) < 0.05 * mg
    assert (r.records["normal_force"][0, i] > 0).all()


def test_first_grope_probes_the_foothold(walk):
    _, r = walk
    assert r.status[0] != "diverged"
    assert r.metrics["completed_gropes"][0] >= 1
    assert r.metrics["collapses_met"][0] == 0


def test_normal_forces_stay_below_r_ref_outside_the_grope(walk):
    """Paper, Figs. 11-12: every normal force is below R_ref except in step D'. With the
    earlier stiff contacts the toe forces chattered to 15 R_ref (model.py)."""
    _, r = walk
    assert r.metrics["max_normal_ratio"][0] < 1.05
    # and the forces are smooth: between records (0.1 s; the first record is the robot
    # placed, unloaded) a toe's normal force changes by 0.05 R_ref on average, mostly in
    # the planned loading and unloading; the chattering contacts gave 0.24
    fn = r.records["normal_force"][0, 1:] / r.records["r_ref"][0, 1:, None]
    assert np.abs(np.diff(fn, axis=0)).mean() < 0.1


def test_first_collapse_names_the_groping_leg_and_the_tilt_after_it(walk):
    """collapsed_leg / collapse_tilt (the paper's Fig. 13 figure): in the walk whose L2
    target is weak the collapse comes in L2's grope, and the tilt over the 0.2 s after it
    equals the change between the records around it; the sound walk has neither."""
    sc, r = walk
    assert r.metrics["collapsed_leg"][0] == -1 and np.isnan(r.metrics["collapse_tilt"][0])
    assert r.metrics["collapsed_leg"][1] == 1
    k = int(np.argmax(np.asarray(r.records["collapsed"][1]) >= 1))
    window = round(scenarios.COLLAPSE_WINDOW / (sc.record_every * control.GropeSettings().control_dt))
    quat = np.asarray(r.records["quat"][1])

    def z_axis(q):  # MuJoCo's own quaternion -> rotation matrix, third column
        mat = np.zeros(9)
        mujoco.mju_quat2Mat(mat, np.asarray(q, float))
        return mat.reshape(3, 3)[:, 2]

    expected = np.arccos(np.clip(z_axis(quat[k - 1]) @ z_axis(quat[k + window]), -1, 1))
    assert r.metrics["collapse_tilt"][1] == pytest.approx(expected, abs=1e-9)
    assert 0.0 < r.metrics["collapse_tilt"][1] < 0.35


def test_grope_breaks_a_foothold_just_under_r_ref_and_the_walk_stops(walk):
    """The method's premise: the grope ends over R_ref (1.01 R_ref, the design's
    overshoot), so a foothold only 0.1-0.3 % weaker than R_ref breaks in its grope, not
    later under an unprobed load; no walk accepts a weak foothold; with regrope = 0 the
    walk stops there (paper: "the robot stops walking after the detection of the foothold
    collapse") without falling."""
    _, r = walk
    assert r.metrics["weak_accepted"][0] == 0 and r.metrics["late_collapses"][0] == 0
    assert r.metrics["collapses_met"][1] >= 1 and r.metrics["late_collapses"][1] == 0
    assert r.metrics["weak_accepted"][1] == 0 and r.metrics["late_weak_collapses"][1] == 0
    assert r.metrics["collapses_met"][2] == 1 and r.metrics["completed_gropes"][2] == 0
    assert r.metrics["late_collapses"][2] == 0 and r.metrics["weak_accepted"][2] == 0
    assert r.status[2] == "stopped_on_collapse" and not r.metrics["fell"][2]
    assert r.metrics["collapsed_leg"][2] == 1  # L2, the paper's label


def test_load_over_probe_compares_later_loads_with_the_probed_force(walk):
    """max_load_over_probe, recomputed record by record: a leg whose grope is done (its
    place in the order L2, L1, L3, L4 before the grope counter) takes later normal
    forces against the force its grope probed it with: the larger of the controller's
    (the filtered peak, grope_force) and the raw load recorded while it groped (C* to
    D'-2)."""
    _, r = walk
    grope, fn, phase = r.records["grope"][0], r.records["normal_force"][0], r.records["phase"][0]
    order = gait.DESIGNS["mirrored"].order
    probed_with = np.asarray(r.final.ctrl_state.grope_force)[0].copy()
    for i in range(len(grope)):
        if control.TOUCH <= phase[i] <= control.D2:
            leg = order[grope[i]]
            probed_with[leg] = max(probed_with[leg], fn[i, leg])
    ratios = [fn[i, leg] / probed_with[leg] for i in range(len(grope))
              for rank, leg in enumerate(gait.DESIGNS["mirrored"].order) if rank < grope[i]]
    assert len(ratios) > 10  # at least one grope finished well before the end
    assert r.metrics["max_load_over_probe"][0] == pytest.approx(max(ratios), rel=1e-12)
    # no collapse in this walk: the steady version is the same figure
    assert r.metrics["max_load_over_probe_steady"][0] == r.metrics["max_load_over_probe"][0]
    # a probed foothold carries no more than it was probed with: the grope
    # ends at 1.01 R_ref and the walk's other steps stay below R_ref
    assert 0.5 < r.metrics["max_load_over_probe"][0] <= 1.0


def test_foothold_offset_is_the_toes_distance_from_its_pad_in_the_slope_plane(walk):
    """The recorded foothold offset, recomputed from the toe sites and the planned
    footholds while all four legs still stand on their starting pads; the sound walk and
    the walk that regropes after L2's collapse stay on their footholds (the toe resting
    in the collapsed pad's hole during the retry is not counted)."""
    _, r = walk
    p = {k: jnp.asarray(v[0]) for k, v in scenarios.params_batch(1, theta=THETA).items()}
    t = jax.jit(lambda p, key: control.walk_targets(p, key, gait.DESIGNS["mirrored"]))(p, jax.random.PRNGKey(0))
    feet0, n0 = np.asarray(t.feet0), np.asarray(t.normals0)
    first = np.nonzero((r.records["grope"][0] == 0) & (r.records["phase"][0] == control.A))[0]
    assert len(first) > 3
    for i in first:
        d = r.records["toe_pos"][0, i] - model.TOE_RADIUS * n0 - feet0
        in_plane = d - np.sum(d * n0, axis=1, keepdims=True) * n0
        np.testing.assert_allclose(r.records["foothold_offset"][0, i], np.linalg.norm(in_plane, axis=1), atol=1e-9)
    assert 0.0 < r.metrics["max_foothold_offset"][0] < scenarios.PAD_HALF
    assert not r.metrics["off_foothold"][0] and r.metrics["completed_gropes"][0] >= 1
    assert r.metrics["collapses_met"][1] == 1 and not r.metrics["off_foothold"][1]


def test_the_scene_is_built_on_the_controllers_footholds(walk):
    """`control.walk_footholds` (the pads and the start pose, without the 16 COG plans)
    gives the footholds, start body pose and attitude of the controller's plan
    (`walk_targets`, in the final controller state): the same operations (bit-identical
    in the batched program; 1e-12 m here, another program may round differently)."""
    _, r = walk
    fh = jax.jit(control.walk_footholds)(jax.tree.map(lambda x: x[0], scenarios.params_batch(1, theta=THETA)),
                                         jax.random.PRNGKey(0))
    targets = r.final.ctrl_state.targets
    for name in ("feet0", "normals0", "cand", "cand_normals", "body0", "R_GR"):
        np.testing.assert_allclose(np.asarray(getattr(targets, name))[0], np.asarray(getattr(fh, name)), rtol=0,
                                   atol=1e-12, err_msg=name)


def test_after_collapse_marks_the_window_after_each_rise_of_the_collapse_count():
    """`max_load_over_probe_steady` leaves out the records within COLLAPSE_WINDOW (here 2
    records) after a foothold collapsed: the record where the count rose and the 2 after."""
    counts = np.array([0, 0, 1, 1, 1, 1, 2, 2, 2, 2, 2])
    marked = np.asarray(scenarios._after_collapse(counts, 2))
    assert marked.tolist() == [False, False, True, True, True, False, True, True, True, False, False]


def test_standing_toes_do_not_creep_on_the_slope():
    """No-slip solver: a robot standing on the pi/12 slope (gravity tilted instead) keeps
    its toes; plain soft contacts let them creep about 50 mm/s (model.py)."""
    spec = model.load_spec()
    ground = spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[2, 2, 0.1], contype=2, conaffinity=1,
                                     friction=[0.45, 0.005, 0.0001])
    ground.solref, ground.solimp = list(model.CONTACT_SOLREF), list(model.CONTACT_SOLIMP)
    m = spec.compile()
    m.opt.gravity[:] = [-9.81 * np.sin(THETA), 0.0, -9.81 * np.cos(THETA)]
    d = mujoco.MjData(m)
    q0 = scenarios._standing_q()
    d.qpos[:3], d.qpos[3], d.qpos[7:], d.ctrl[:] = [0, 0, scenarios.STAND_HEIGHT + 0.001], 1.0, q0, q0
    toe = m.site("L1_toe").id
    for _ in range(250):  # settle 0.5 s
        mujoco.mj_step(m, d)
    start = d.site_xpos[toe].copy()
    for _ in range(500):  # then 1 s
        mujoco.mj_step(m, d)
    assert np.linalg.norm(d.site_xpos[toe] - start) < 1e-4  # [m] over 1 s


def test_collapsing_foothold_is_survived_on_three_legs(walk):
    _, r = walk
    assert r.metrics["collapses_met"][1] >= 1
    assert r.records["collapsed"][1].max() >= 1
    assert not r.metrics["fell"][1]
    assert r.metrics["max_attitude_change"][1] < np.radians(10)
    # after the collapse the robot gropes its fallback foothold
    phases = r.records["phase"][1]
    first = int(np.argmax(r.records["collapsed"][1] >= 1))
    assert (phases[first:] == control.A).any()


def _spec(tmp_path):
    return {
        "sweep": {"analysis": "leggrope.fragile_walk", "name": "t", "chunk_size": 2, "output": str(tmp_path / "out"),
                  "formats": ["parquet"]},
        "fixed": {"horizon": 1.0, "nthread": 1},
        "params": {"mu": [0.45, 0.8], "theta": [0.0, 0.1]},
    }


def test_interrupted_simulation_sweep_resumes(tmp_path):
    full, compiles = run_counting(run_sweep, _spec(tmp_path), progress=False, output=tmp_path / "full")
    compiles.assert_compiled_once()  # two chunks of two simulations, the controller compiled once

    def stop(index, n):
        raise KeyboardInterrupt

    with pytest.raises(SweepInterrupted):
        run_sweep(_spec(tmp_path), progress=False, on_chunk=stop)
    resumed = run_sweep(_spec(tmp_path), progress=False, resume=True)
    assert resumed.chunks_reused == 1 and resumed.chunks_computed == 1
    for name in ("max_abs_roll", "max_attitude_change", "status", "mu", "theta"):
        np.testing.assert_array_equal(resumed.table.column(name).to_numpy(zero_copy_only=False),
                                      full.table.column(name).to_numpy(zero_copy_only=False))


def test_params_batch_rejects_unknown_parameters():
    p = scenarios.params_batch(3, theta=np.array([0.0, 0.1, 0.2]), weak_leg=1)
    assert p["theta"].shape == (3,) and p["weak_leg"].dtype == np.int32
    with pytest.raises(KeyError, match="thetta"):
        scenarios.params_batch(2, thetta=0.1)


def test_summary_reports_load_over_probe_of_the_successful_runs():
    """The fragile summary's last column: mean (worst) of max_load_over_probe over the
    successful runs of each (R_ref factor, p_weak) group; '-' where none succeeded."""
    import pyarrow as pa

    from jaxloco.robots.leggrope import sim_analysis

    n = 6
    table = pa.table({
        "r_ref_factor": [0.5] * 4 + [0.6] * 2, "p_weak": [0.0] * n,
        "success": [True, True, False, True, False, False],
        "max_load_over_probe": [1.05, 1.20, 3.0, 1.10, 0.9, float("nan")],  # row 2 failed: not counted
        "max_attitude_change": [0.01] * n, "max_normal_ratio": [0.9] * n, "collapses_met": [0] * n,
        "collapses_survived": [0] * n, "min_margin": [0.005] * n,
        "late_collapses": [1, 0, 2, 0, 0, 0], "weak_accepted": [0, 1, 0, 1, 0, 0],
    })
    s = sim_analysis.summarize(table)
    col = s.columns.index("load / probe")
    assert s.rows[0][col] == "1.12 (1.20)" and s.rows[1][col] == "-"
    assert s.rows[0][col + 1] == "-"  # an older table without max_load_over_probe_steady
    steady = sim_analysis.summarize(table.append_column("max_load_over_probe_steady", pa.array([0.9, 1.0, 2.0, 0.95,
                                                                                               0.8, 0.7])))
    assert steady.rows[0][col + 1] == "0.95 (1.00)" and steady.rows[1][col + 1] == "-"
    assert s.columns[-1] == "late (weak) / weak accepted"
    assert s.rows[0][-1] == "3 / 2" and s.rows[1][-1] == "0 / 0"  # every row of the group, failed ones too
    split = sim_analysis.summarize(table.append_column("late_weak_collapses", pa.array([1, 0, 0, 0, 0, 0])))
    assert split.rows[0][-1] == "3 (1) / 2"


def test_summary_groups_the_collapse_experiments_by_weak_leg():
    """Rows with weak_leg L1 and L2 are summarized apart; the collapse tilt column is the
    mean (worst) over the runs that met a collapse, in degrees."""
    import pyarrow as pa

    from jaxloco.robots.leggrope import sim_analysis

    n = 4
    table = pa.table({
        "r_ref_factor": [0.5] * n, "p_weak": [0.0] * n, "weak_leg": [0, 0, 1, 1],
        "success": [False, False, True, True], "max_load_over_probe": [1.0] * n,
        "collapse_tilt": [np.radians(2.0), np.radians(4.0), np.radians(1.0), float("nan")],
        "max_attitude_change": [0.05, 0.5, 0.02, 0.01], "max_normal_ratio": [0.9] * n,
        "collapses_met": [1, 1, 1, 0], "collapses_survived": [1, 0, 1, 0], "min_margin": [0.005] * n,
    })
    s = sim_analysis.summarize(table)
    col = s.columns.index("collapse tilt [deg]")
    assert [row[2] for row in s.rows] == ["L1", "L2"]
    assert s.rows[0][col] == "3.0 (4.0)" and s.rows[1][col] == "1.0 (1.0)"
    assert s.rows[0][4] == "0%" and s.rows[1][4] == "100%"

