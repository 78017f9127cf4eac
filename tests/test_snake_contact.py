"""`snake.contact`: the head's contact forces on a force plate (Tables IV-V) in MuJoCo."""

from __future__ import annotations

import mujoco
import numpy as np
import pyarrow as pa
import pytest

from jaxloco import analysis
from jaxloco.robots.snake import contact, params, scenarios
from jaxloco.sim.rollout import Simulator


def test_push_force_keeps_the_first_contact_and_ignores_impacts():
    f = np.zeros(60)
    f[10:30] = np.linspace(0.0, 20.0, 20)  # the push builds up
    f[30:33] = 0.0  # the gripper slid off
    f[45] = 500.0  # something hits the plate afterwards
    assert contact.push_force(f, window=1) == pytest.approx(20.0)
    assert contact.push_force(f) == pytest.approx(np.mean(f[25:30]))  # 0.1 s average at the peak
    assert contact.push_force(np.zeros(20)) == 0.0
    assert contact.push_force(np.full(20, 7.0)) == pytest.approx(7.0)  # never lost: to the end


def test_postures_put_the_head_where_the_paper_says():
    """The no-skid controller's postures: the head frame at (y_h, z_h), level, facing
    +x; psi_3 at its SCP target; the base part straight or the default L exactly."""
    import jax.numpy as jnp

    from jaxloco.robots.snake import kinematics
    for name in ("iii", "v", "viii"):
        z, y, base = contact.POSTURES[name]
        phi, b = contact.head_posture(z, y, base)
        w = np.asarray(kinematics.base_frame_pose(jnp.asarray(b), jnp.asarray(phi)))
        assert w[2] == pytest.approx(z, abs=0.005) and w[1] - 0.0 == pytest.approx(y, abs=0.005)
        assert np.abs(w[3:]).max() < 0.02
        assert phi[params.SCP_INDEX] == pytest.approx(params.SCP_TARGET, abs=0.02)
        # the base part exactly straight or L-shaped, as the paper's
        np.testing.assert_array_equal(phi[params.N_H:], contact.L_SHAPES[contact.L_BEND] if base == "L" else 0.0)
    with pytest.raises(analysis.SpecError, match="base"):
        contact.head_posture(0.35, 0.0, "U")


def test_plate_sits_beyond_the_gripper_square_to_the_push():
    """In the model: the plate's thin axis along each push and PLATE_GAP between the
    gripper capsule's farthest point along the push (from MuJoCo's geom) and the
    plate's face, for the kinematic head and for a sagging one (lower, nose down)."""
    from jaxloco.robots.snake import model as snake_model
    phi, base = contact.head_posture(*contact.POSTURES["ii"])
    m = scenarios.build_model(contact.PLATE)[0]
    d = mujoco.MjData(m)
    kin = contact.kinematic_head(phi, base)
    qpos, _ = snake_model.pose_qpos_ctrl(m, phi, base)
    for head in (kin, kin + np.array([0.0, 0.0, -0.01, 0.0, 0.05, 0.0])):
        d.qpos[:] = qpos
        d.qpos[:3], d.qpos[3:7] = head[:3], snake_model.rpy_to_quat(head[3:])
        mujoco.mj_kinematics(m, d)
        g = m.geom("gripper").id
        centre, axis, (radius, half) = d.geom_xpos[g], d.geom_xmat[g].reshape(3, 3)[:, 2], m.geom_size[g][:2]
        for direction, push in enumerate(contact.PUSH):
            pos, quat = contact.plate_pose(head, direction)
            d.mocap_pos[m.body_mocapid[m.body("plate").id]] = pos
            d.mocap_quat[m.body_mocapid[m.body("plate").id]] = quat
            mujoco.mj_kinematics(m, d)
            R = d.geom_xmat[m.geom("plate").id].reshape(3, 3)
            assert abs(R[:, 0] @ push) == pytest.approx(1.0, abs=1e-9)  # thin side along the push
            face = pos - push * contact.PLATE_HALF[0]
            reach = centre @ push + half * abs(axis @ push) + radius
            assert face @ push - reach == pytest.approx(contact.PLATE_GAP, abs=1e-9)


def test_log_error_is_zero_on_the_papers_means_and_log_2_at_twice():
    paper = {k: np.array([m for m, _ in contact.PAPER_FORCES[k]]) for k in ("i", "v", "x")}
    assert contact.log_error(paper) == pytest.approx(0.0, abs=1e-12)
    assert contact.log_error({k: 2.0 * v for k, v in paper.items()}) == pytest.approx(np.log(2.0))
    assert contact.log_error({"i": np.array([1.0, 0.0, 1.0])}) == np.inf


def test_height_exponents_recover_a_power_law_and_leave_out_incomplete_series():
    """f = c z_h^n per column is recovered exactly; the paper's Table IV gives f_x, f_y about
    z_h^-2 and f_z rising (two-point closed form on (i), (iii): log(f3 / f1) / log(0.30 / 0.40))."""
    n = np.array([-2.0, 1.5, 0.7])
    means = {k: np.array([3.0, 5.0, 7.0]) * contact.POSTURES[k][0] ** n for k in ("i", "ii", "iii", "iv", "v")}
    out = contact.height_exponents(means)
    assert set(out) == {"straight"}  # (vi) missing: no L series
    np.testing.assert_allclose(out["straight"], n, atol=1e-12)
    paper = contact.PAPER_MEANS
    ex = contact.height_exponents(paper)
    two_point = np.log(paper["iii"] / paper["i"]) / np.log(0.30 / 0.40)
    np.testing.assert_allclose(ex["straight"], two_point, atol=0.15)
    assert np.all(ex["straight"][:2] < -1.5) and np.all(ex["L"][:2] < -1.5) and ex["L"][2] > 1.0
    assert contact.height_exponents({k: np.array([1.0, 0.0, 1.0]) for k in ("i", "ii", "iii")}) == {}


@pytest.fixture(scope="module")
def rows():
    """Posture (iii), two trials, short ramp and hold (one compile for the module)."""
    assert analysis.get("snake.contact") is contact.CONTACT
    fixed = {p.name: p.default for p in contact.PARAMS} | {"ramp": 2.0, "hold": 1.0, "settle": 1.0, "nthread": 2}
    fn = contact.CONTACT.batch_fn(fixed)
    swept = {"posture": np.array(["iii", "iii"])}
    keys = np.array([[0, 0], [0, 1]], np.uint32)
    return fn, swept, keys, fn(swept, keys)


def test_each_row_pushes_the_plate_three_ways(rows):
    _, _, _, out = rows
    assert set(out) == {m.name for m in contact.METRICS} | {"status"}
    assert list(out["status"]) == [0, 0]
    for f in ("fx", "fy", "fz"):
        assert np.all((out[f] > 1.0) & (out[f] < 200.0)), (f, out[f])  # touched, no impact spike
    np.testing.assert_array_equal(out["z_h"], 0.30)


def test_the_plate_is_placed_at_the_sagging_robot(rows):
    """The settled head (from the fixture's settling run, cached) is below the
    kinematic posture's: the head part's servos sag under its weight (Sec. IV-C2)."""
    fixed = {p.name: p.default for p in contact.PARAMS} | {"ramp": 2.0, "hold": 1.0, "settle": 1.0}
    settled = contact.settled_heads(np.array(["iii"]), fixed["ramp"], fixed["hold"], fixed["settle"],
                                    Simulator(nthread=2))[0]
    kin = contact.kinematic_head(*contact.head_posture(*contact.POSTURES["iii"]))
    assert 0.002 < kin[2] - settled[2] < 0.03
    assert np.abs(settled[:2] - kin[:2]).max() < 0.02


def test_the_push_is_a_position_command(rows):
    """The force is the servos' stiffness times the command: a third of the default
    overshoot gives well under half the force along x and -z (a friction or torque
    limit would give about the same)."""
    fn, swept, keys, out = rows
    small = fn({"posture": swept["posture"][:1], "overshoot": np.array([contact.OVERSHOOT / 3])}, keys[:1])
    for f in ("fx", "fz"):
        assert 0.0 < small[f][0] < 0.5 * out[f][0], (f, small[f][0], out[f][0])


def test_a_row_alone_equals_the_row_in_a_batch(rows):
    fn, swept, keys, out = rows
    one = fn({"posture": swept["posture"][1:]}, keys[1:])
    for f in ("fx", "fy", "fz"):
        np.testing.assert_allclose(one[f], out[f][1:], rtol=1e-9, err_msg=f)


def test_summary_has_the_papers_forces_and_checks_the_trends():
    names = list(contact.POSTURE_NAMES)
    paper = np.array([[m for m, _ in contact.PAPER_FORCES[k]] for k in names])
    table = pa.table({"posture": names, "status": ["ok"] * len(names), "fx": paper[:, 0], "fy": paper[:, 1],
                      "fz": paper[:, 2]})
    s = contact.summarize(table)
    assert [r[0] for r in s.rows] == [f"({k})" for k in names]
    assert s.rows[2][5] == "30.4 ± 0.0 / 30.4 ± 1.7" and all(r[-1] == "yes" for r in s.rows)
    # the paper's own means satisfy the paper's trends
    assert all(t.endswith(": holds") for t in s.notes[1:5]) and len(s.notes) == 7
    # the paper's own height exponents beside themselves
    assert s.notes[5].startswith("force ~ z_h^n") and "straight f_x -2.0 / -2.0, f_y -1.8 / -1.8" in s.notes[5]
    # which model made the table: the defaults where the table has no l_bend / wheel_creep columns
    assert s.notes[6] == ("model: the L bent at the middle (theta_6 = theta_7 = 45 deg), hard wheel friction, "
                          "a rigid base")
    flipped = pa.table({"posture": names, "status": ["ok"] * len(names), "fx": paper[::-1, 0], "fy": paper[:, 1],
                        "fz": paper[:, 2], "l_bend": ["tail"] * len(names), "wheel_creep": [0.2] * len(names)})
    s = contact.summarize(flipped)
    assert any(t.endswith("does not hold") for t in s.notes[1:5])
    assert s.notes[6] == ("model: the L bent at the tail (theta_8 = theta_9 = 45 deg), wheels creeping sideways "
                          "(wheel_creep 0.2 s), a rigid base")


def test_contact_force_plot_has_ours_and_the_papers_bars():
    import matplotlib

    matplotlib.use("Agg")
    from jaxloco.robots.snake import plots

    table = pa.table({"posture": ["i", "i", "ii"], "status": ["ok", "ok", "fell"], "fx": [1.0, 3.0, 9.0],
                      "fy": [1.0, 1.0, 1.0], "fz": [2.0, 2.0, 2.0]})
    fig = plots.plot_contact_forces(table)
    ax = fig.axes[0]
    heights = [p.get_height() for p in ax.patches]
    assert heights[0] == 2.0 and np.isnan(heights[1])  # ours: (i) the mean of the ok trials, (ii) none ok
    assert heights[2:] == [contact.PAPER_FORCES["i"][0][0], contact.PAPER_FORCES["ii"][0][0]]


def test_the_tail_reading_of_the_l_bends_theta_8_and_theta_9():
    """`l_bend` "tail": the L of Fig. 12(b) (missing from our copy) turned at the tail,
    theta_8 = theta_9 = 45 deg; the head still where the paper says (posture (x))."""
    import jax.numpy as jnp

    from jaxloco.robots.snake import kinematics
    z, y, base = contact.POSTURES["x"]
    phi, b = contact.head_posture(z, y, base, "tail")
    np.testing.assert_array_equal(phi[params.N_H:], [0.0, 0.0, 0.0, 0.0, np.pi / 4, np.pi / 4])
    w = np.asarray(kinematics.base_frame_pose(jnp.asarray(b), jnp.asarray(phi)))
    assert w[2] == pytest.approx(z, abs=0.005) and w[1] == pytest.approx(y, abs=0.005)
    with pytest.raises(analysis.SpecError, match="l_bend: 'knee' is not one of middle, tail"):
        contact.head_posture(z, y, base, "knee")


def _side_creep_speed(wheel_creep: float, side_force: float = 30.0) -> float:
    """How fast [m/s] the straight robot, standing on its servos, slides sideways under a
    steady side force [N] on link 7 (below mu N of its weight): over the second second
    of the load, after the contacts' elastic give."""
    from jaxloco.robots.snake import model as snake_model
    m = scenarios.build_model(wheel_creep=wheel_creep)[0]
    d = mujoco.MjData(m)
    d.qpos[:], d.ctrl[:] = snake_model.pose_qpos_ctrl(m, np.zeros(params.N_H + params.N_B))
    mujoco.mj_step(m, d, nstep=250)  # settle on the wheels (0.5 s)
    link = m.body("link7").id
    d.xfrc_applied[link, 1] = side_force
    second = round(1.0 / m.opt.timestep)
    mujoco.mj_step(m, d, nstep=second)
    y1 = d.xpos[link, 1]
    mujoco.mj_step(m, d, nstep=second)
    return float(d.xpos[link, 1] - y1)


def test_creeping_wheels_give_under_a_side_load_where_hard_ones_hold():
    """`wheel_creep` (`scenarios.creeping_wheels`): the wheel-floor contacts become
    explicit pairs with solreffriction on an elliptic cone, replacing the dynamic ones;
    under a side load below mu N the robot then creeps sideways several times faster
    than on MuJoCo's default friction (which creeps too, slowly: measured 1.8 against
    6.8 mm/s at 30 N). Native only: MJX is refused in one line."""
    hard = scenarios.build_model()[0]
    soft = scenarios.build_model(wheel_creep=0.2)[0]
    wheels = sum(1 for g in range(soft.ngeom) if soft.geom(g).name.startswith("wheel"))
    assert hard.npair == 0 and hard.opt.cone == mujoco.mjtCone.mjCONE_PYRAMIDAL
    assert soft.npair == soft.nexclude == wheels == 2 * params.N_PAIRS
    assert soft.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC
    np.testing.assert_array_equal(soft.pair_solreffriction, np.tile([0.2, 1.0], (wheels, 1)))
    held, crept = _side_creep_speed(0.0), _side_creep_speed(0.2)
    assert 0.0 < held < 0.003 and crept > 3 * held, (held, crept)
    with pytest.raises(analysis.SpecError, match="wheel_creep: 0.2 s needs .* native MuJoCo"):
        scenarios.build_model(backend="mjx", wheel_creep=0.2)


def test_creeping_wheels_take_each_simulations_floor_friction():
    """The pairs' friction is per simulation, params["mu"] (as the geoms' is): a batch of
    two floors writes 0.6 and 1.2 into every pair's two sliding coefficients."""
    from jaxloco.sim import native
    sc = scenarios.snake_scenario(0.1, wheel_creep=0.2)
    batch = native.make_batch(sc, scenarios.params_batch(2, mu=np.array([0.6, 1.2])), 2)
    for i, mu in enumerate((0.6, 1.2)):
        friction = batch.get_model(i).pair_friction
        np.testing.assert_allclose(friction[:, :2], mu)
        np.testing.assert_allclose(friction[:, 2:], [[0.005, 0.0001, 0.0001]] * sc.model.npair)


def test_contact_height_law_plot_has_ours_and_the_papers_series_with_their_exponents():
    import matplotlib

    matplotlib.use("Agg")
    from jaxloco.robots.snake import plots

    names = ["i", "ii", "iii", "iv", "v", "vi", "vii"]
    z = np.array([contact.POSTURES[k][0] for k in names])
    table = pa.table({"posture": names + ["i"], "status": ["ok"] * len(names) + ["fell"],
                      "fx": list(2.0 / z**2) + [1e3], "fy": list(z) + [1e3], "fz": list(3.0 * z**1.5) + [1e3]})
    means = contact.posture_means(table)
    assert means["i"] == pytest.approx([2.0 / 0.16, 0.4, 3.0 * 0.4**1.5])  # the fallen trial left out
    fig = plots.plot_contact_height_law(table)
    assert len(fig.axes) == 3
    labels = [line.get_label() for line in fig.axes[0].get_lines()]
    assert labels[0] == "ours, straight: n = -2.0" and labels[1].startswith("paper, straight: n = ")
    assert fig.axes[1].get_lines()[0].get_label() == "ours, straight: n = +1.0"
    np.testing.assert_allclose(fig.axes[2].get_lines()[2].get_ydata(), 3.0 * z[3:6] ** 1.5)  # ours, L


def _side_push(twist_compliance: float, side_force: float) -> tuple[float, float]:
    """(link 7's roll, the first twist hinge's angle) [rad] after 2 s of a steady side force
    [N] (+y) at the head of the robot standing in the Sec. V-A posture (head 0.34 m up)."""
    from jaxloco.robots.snake import model as snake_model
    m = scenarios.build_model(twist_compliance=twist_compliance)[0]
    d = mujoco.MjData(m)
    d.qpos[:], d.ctrl[:] = snake_model.pose_qpos_ctrl(m, params.INITIAL_PHI)
    mujoco.mj_step(m, d, nstep=500)  # settle on the servos (1 s)
    head = m.body("link1").id
    d.xfrc_applied[head, :3] = [0.0, side_force, 0.0]  # at the head frame's origin: the force and its moment
    d.xfrc_applied[head, 3:] = np.cross(d.site("head").xpos - d.xipos[head], [0.0, side_force, 0.0])
    mujoco.mj_step(m, d, nstep=1000)
    R7 = d.xmat[m.body("link7").id].reshape(3, 3)
    twist = d.qpos[m.joint(scenarios.TWIST_JOINTS[0]).qposadr[0]] if twist_compliance else 0.0
    return float(np.arctan2(R7[2, 1], R7[2, 2])), float(twist)


def test_a_twisting_base_lets_link_7_roll_over_where_the_rigid_base_holds():
    """`twist_compliance` (`scenarios.twisting_base`): a passive hinge behind each base yaw
    joint. Pushed sideways at the raised head, link 7 and the head part then roll on pair
    3's wheels, mostly about the first hinge (behind theta_4; the base behind stays down):
    at 5 N several times the rigid base's roll, and 20 N, which the rigid base holds
    (the whole robot's weight resists), turns them over; with the contact experiment's
    default 0.05 rad/(N m) as with a softer 0.2 (the front's weight, not the spring,
    sets where)."""
    m = scenarios.build_model(twist_compliance=0.05)[0]
    assert m.nq == scenarios.build_model()[0].nq + params.N_B
    assert [m.jnt_stiffness[m.joint(n).id] for n in scenarios.TWIST_JOINTS] == pytest.approx([20.0] * params.N_B)
    rigid_5, _ = _side_push(0.0, 5.0)
    rigid_20, _ = _side_push(0.0, 20.0)
    assert abs(rigid_20) < 0.01
    for compliance in (0.05, 0.2):
        roll_5, twist_5 = _side_push(compliance, 5.0)
        assert roll_5 < 3 * rigid_5 < 0.0 and 0.7 * -roll_5 < twist_5 < 1.1 * -roll_5  # mostly the first hinge
        assert _side_push(compliance, 20.0)[0] < -1.0
    with pytest.raises(analysis.SpecError, match="twist_compliance: -1 rad/.* needs a value >= 0"):
        scenarios.build_model(twist_compliance=-1.0)


def test_table_3_the_operations_and_the_joint_limit_run_take_the_twist():
    """The other MuJoCo experiments run on the twisting base when asked (their analyses'
    `twist_compliance`, rigid by default): the scenario's model has the hinge."""
    from jaxloco.robots.snake import operations, operations_analysis, table3
    rigid = scenarios.build_model()[0].nq
    for analysis_params in (table3.PARAMS, operations_analysis.PARAMS):
        assert {p.name: p.default for p in analysis_params}["twist_compliance"] == 0.0
    assert table3.table3_scenario(0.5, 0.1, False).model.nq == rigid
    assert table3.table3_scenario(0.5, 0.1, False, "native", 0.05).model.nq == rigid + params.N_B
    door = operations.OPERATIONS["door"]
    twisting = operations.operation_scenario(door.fixture, 0.1, twist_compliance=0.05).model
    assert twisting.nq == operations.operation_scenario(door.fixture, 0.1).model.nq + params.N_B
    assert twisting.jnt_stiffness[twisting.joint(scenarios.TWIST_JOINTS[-1]).id] == pytest.approx(20.0)
