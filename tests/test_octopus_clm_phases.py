"""The CLM controller's phases one at a time (`clm`'s module-level functions on hand-built
states and observations, no rollouts): the support arms (Eqs. 22-27), the crawl gait's
sequencing, the PREPARE approach, the CLIMB release condition, RELEASE, the DONE carry
and the phase transitions, against closed-form expectations."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from jaxloco.robots.octopus import clm, params
from jaxloco.robots.octopus import clm_rules as cr
from jaxloco.robots.octopus import kinematics as kin

KP = params.default_params()
DT = clm.CONTROL_DT


@pytest.fixture(scope="module")
def p():
    return {k: jnp.asarray(v) for k, v in clm.PARAM_DEFAULTS.items()}


def _obs(flipper_q=(0.5, 0.5, 0.0, 0.0), flipper_tau=(0.0, 0.0, 0.0, 0.0), track_speed=(0.0, 0.0)):
    """Level robot, arms in the start pose (rollers on the ground)."""
    return {"time": jnp.asarray(1.0), "quat": jnp.array([1.0, 0.0, 0.0, 0.0]),
            "flipper_q": jnp.asarray(flipper_q, float), "flipper_tau": jnp.asarray(flipper_tau, float),
            "arm_q": jnp.asarray(clm.start_pose()[0].reshape(-1)), "arm_tau": jnp.zeros(12),
            "track_speed": jnp.asarray(track_speed, float)}


def _no_transfer(arms: clm.ArmState, just_placed=(False,) * 4) -> clm.Transfer:
    """A transfer period in which nothing moves (optionally some arm just placed)."""
    return clm.Transfer(cmd=arms.q_cmd, arm_phase=arms.arm_phase, transferring=jnp.zeros(4, bool),
                        just_placed=jnp.asarray(just_placed), contacts=arms.contacts, stop_case=arms.stop_case,
                        on_step=arms.on_step, lift=arms.lift_to, lift_from=arms.lift_from, hit_n=arms.hit_n,
                        deep=jnp.zeros(4, bool), backoff=arms.backoff)


def test_init_state_is_typed_and_walking(p):
    s = clm.clm_init(p, _obs())
    assert isinstance(s, clm.ClmState) and isinstance(s.arms, clm.ArmState)
    assert int(s.phase) == clm.WALK and (np.asarray(s.arms.arm_phase) == cr.PLACED).all()
    np.testing.assert_allclose(s.arms.contacts, params.TABLE2_INIT, atol=1e-5)
    np.testing.assert_allclose(s.flip, [p["front_start"], p["front_start"], 0.0, 0.0])


def test_support_arms_hold_ground_contacts(p):
    """A support arm's ground-fixed contact moves by -L (cos a, 0, sin a) in {R} (a = T_P -
    R_P) and the hold command puts its EPRA there; an arm not in support keeps its contact."""
    s = clm.clm_init(p, _obs())
    arms = s.arms._replace(arm_phase=s.arms.arm_phase.at[2].set(clm.IDLE))
    L, t_p, pitch = 0.01, 0.1, 0.3
    contacts, q_hold = clm.support_arms(p, arms, jnp.asarray(L), jnp.asarray(t_p), jnp.asarray(pitch))
    a = t_p - pitch
    expect = np.asarray(arms.contacts) - L * np.array([np.cos(a), 0.0, np.sin(a)])
    support = np.array([True, True, False, True])
    np.testing.assert_allclose(np.asarray(contacts)[support], expect[support], atol=1e-12)
    np.testing.assert_allclose(contacts[2], arms.contacts[2])
    np.testing.assert_allclose(np.asarray(kin.arm_tips(KP, q_hold))[support], expect[support], atol=1e-9)
    # the start pose's contacts read flat: T_P = 0 on level ground
    assert float(clm.terrain_pitch(arms.contacts, jnp.asarray(0.0), jnp.asarray(0.0))) == pytest.approx(0.0, abs=1e-5)


def test_a_support_arm_that_would_leave_its_joint_range_holds_its_last_command(p):
    """A support arm whose ground-fixed contact needs joint angles beyond the arm's range
    (beyond ARM_LO / ARM_HI by more than HOLD_RANGE_TOL) to be held holds its last command
    instead of a clipped solution: clipped, the boom stops at its limit and the elbow alone
    chases the contact, pressing the roller into the ground (on the block task's 500 mm top
    the right front roller pressed 430 N and lifted the right crawler off the floor). Within
    the tolerance (an encoder a few mrad past a limit under load) it still holds."""
    s = clm.clm_init(p, _obs())
    arm = 1  # RF
    # the RF arm on a 0.5 m top (z = 0.026 in {R}) with its boom raised to its limit
    q = s.arms.q_cmd.at[arm].set(jnp.array([-0.19, float(clm.ARM_LO[1]) + 0.005, 2.40]))
    tips = kin.arm_tips(KP, q)
    last = q.at[arm, 2].add(0.03)
    arms = s.arms._replace(contacts=tips, q_cmd=last)
    pitch = jnp.asarray(0.0)
    # a short drive keeps the solution within the range: held at the contact
    _, q_near = clm.support_arms(p, arms, jnp.asarray(0.002), pitch, pitch)
    assert float(q_near[arm, 1]) >= float(clm.ARM_LO[1]) - clm.HOLD_RANGE_TOL
    np.testing.assert_allclose(np.asarray(kin.arm_tips(KP, q_near))[arm], np.asarray(tips)[arm]
                               - [0.002, 0.0, 0.0], atol=1e-6)
    # driving on 0.1 m needs the boom beyond its limit: the last command, not a clipped one
    _, q_far = clm.support_arms(p, arms, jnp.asarray(0.1), pitch, pitch)
    q_ik, _ = kin.inverse_kinematics_all(KP, np.asarray(tips) - [0.1, 0.0, 0.0])
    assert float(q_ik[arm, 1]) < float(clm.ARM_LO[1]) - clm.HOLD_RANGE_TOL
    np.testing.assert_allclose(q_far[arm], last[arm])
    # the other support arms are unaffected
    np.testing.assert_allclose(np.asarray(kin.arm_tips(KP, q_far))[[0, 2, 3]],
                               np.asarray(tips)[[0, 2, 3]] - [0.1, 0.0, 0.0], atol=1e-6)


def test_a_support_arm_keeps_its_command_where_the_hold_would_flip_the_ik_branch(p):
    """A roller pushed under its arm's swing axis (a block run's left rear arm, boom 1.11,
    elbow 2.29 rad) is reached by the closed-form inverse kinematics with the swing turned
    by about pi: a hold that jumps more than HOLD_JUMP from the last command is another
    branch, and the arm keeps its last command (on 7 Dec 2026 the arm whipped round and
    threw the robot off the floor). The other support arms hold their contacts."""
    s = clm.clm_init(p, _obs())
    arm = 2  # LR
    q = s.arms.q_cmd.at[arm].set(jnp.array([1.196, 1.113, 2.292]))
    tips = kin.arm_tips(KP, q)
    arms = s.arms._replace(contacts=tips, q_cmd=q)
    zero = jnp.asarray(0.0)
    q_ik, reach = kin.inverse_kinematics_all(KP, tips)
    assert float(reach[arm]) > 0.005 and float(jnp.max(jnp.abs(q_ik[arm] - q[arm]))) > 2.0  # the other branch
    np.testing.assert_allclose(np.asarray(kin.arm_tips(KP, q_ik))[arm], np.asarray(tips)[arm], atol=1e-9)
    _, q_hold = clm.support_arms(p, arms, zero, zero, zero)
    np.testing.assert_allclose(q_hold[arm], q[arm])
    others = [0, 1, 3]
    np.testing.assert_allclose(np.asarray(kin.arm_tips(KP, q_hold))[others], np.asarray(tips)[others], atol=1e-9)
    np.testing.assert_allclose(np.asarray(q_hold)[others], np.asarray(q)[others], atol=1e-6)


@pytest.mark.parametrize("torque_factor", [0.8, 1.5])
def test_lower_ends_on_a_sustained_torque_without_a_rise_or_a_lag(p, torque_factor):
    """A lowering arm whose roller meets the ground at a slant rolls on: its joints follow
    the command (no lag) and the torque climbs by a few N m per period (no rise beyond
    collision_threshold), yet it presses the robot up. The torque rule of the other
    phases ends LOWER too: a boom or elbow torque beyond collision_torque for
    collision_periods periods is a contact (PLACED); below it the arm lowers on."""
    arm = 2  # LR
    s = clm.clm_init(p, _obs())
    obs = _obs()
    q = obs["arm_q"].reshape(4, 3)
    lifted = q.at[arm, 1].add(-0.3)  # the boom on its way down, well above its target
    level = torque_factor * float(p["collision_torque"])
    arms = s.arms._replace(arm_phase=s.arms.arm_phase.at[arm].set(cr.LOWER), active=jnp.asarray(arm, jnp.int32),
                           q_cmd=lifted, q_cmd2=lifted, q_prev=lifted,
                           tau_prev=jnp.zeros((4, 3)).at[arm, 2].set(-(level - 5.0)))
    no = jnp.asarray(False)
    n = int(p["collision_periods"])
    for k in range(n + 1):
        tau = jnp.zeros((4, 3)).at[arm, 2].set(-(level + 5.0 * k))  # 5 N m more every period
        sense = clm.measure({**obs, "arm_q": arms.q_cmd.reshape(-1), "arm_tau": tau.reshape(-1)})
        tr = clm.arm_transfer(p, arms, arms.contacts, sense, no, jnp.asarray(0.0))
        placed = int(tr.arm_phase[arm]) == cr.PLACED
        assert placed == (torque_factor > 1.0 and k == n - 1), (k, int(tr.arm_phase[arm]))
        if placed:
            break
        assert int(tr.arm_phase[arm]) == cr.LOWER
        arms = arms._replace(hit_n=tr.hit_n, q_prev=sense.q, q_cmd2=arms.q_cmd, q_cmd=tr.cmd, tau_prev=tau)


def test_gait_starts_the_next_arm_in_crawl_order_after_the_pause(p):
    s = clm.clm_init(p, _obs())
    ph = clm.phase_masks(s.phase)
    no = jnp.asarray(False)
    pause = float(p["gait_pause"])
    for ptr in range(4):
        arms = s.arms._replace(ptr=jnp.asarray(ptr, jnp.int32), pause=jnp.asarray(pause - 2.5 * DT))
        waiting = clm.gait_sequence(p, arms, _no_transfer(arms), ph, no, no, DT)
        assert int(waiting.active) == -1 and float(waiting.pause) == pytest.approx(pause - 1.5 * DT)
        arms = arms._replace(pause=jnp.asarray(pause - 0.5 * DT))
        g = clm.gait_sequence(p, arms, _no_transfer(arms), ph, no, no, DT)
        arm = int(clm.CRAWL_ORDER[ptr])
        assert int(g.active) == arm and int(g.arm_phase[arm]) == cr.LIFT
        assert (np.delete(np.asarray(g.arm_phase), arm) == cr.PLACED).all()
        assert float(g.lift_to[arm]) == pytest.approx(float(arms.q_cmd[arm, 1] - p["lift_min"]))
    # a confirmed step stops the gait in WALK
    g = clm.gait_sequence(p, arms, _no_transfer(arms), ph, jnp.asarray(True), no, DT)
    assert int(g.active) == -1


def test_gait_sends_the_other_front_arm_after_one_lands_on_the_step(p):
    """A transfer ends: the pointer moves on in CRAWL_ORDER, the pause restarts; if it was
    a front arm that stopped on the step, the other front arm is next (Fig. 14 C)."""
    s = clm.clm_init(p, _obs())
    ph = clm.phase_masks(s.phase)
    no = jnp.asarray(False)
    lf = int(np.flatnonzero(clm.CRAWL_ORDER == 0)[0])
    arms = s.arms._replace(ptr=jnp.asarray(lf, jnp.int32), active=jnp.asarray(0, jnp.int32),
                           pause=jnp.asarray(1.0))
    plain = clm.gait_sequence(p, arms, _no_transfer(arms, (True, False, False, False)), ph, no, no, DT)
    assert int(plain.ptr) == (lf + 1) % 4 and int(plain.active) == -1 and float(plain.pause) == 0.0
    on_step = _no_transfer(arms, (True, False, False, False))._replace(on_step=jnp.array([True, False, False, False]))
    g = clm.gait_sequence(p, arms, on_step, ph, no, no, DT)
    assert int(clm.CRAWL_ORDER[int(g.ptr)]) == 1 and int(g.active) == -1  # RF next


def test_prepare_approach_blocks_a_pressed_side(p):
    """PREPARE on a high step, front flippers at A0: a side whose flipper is pressed beyond
    approach_tau for more than approach_touch_s is blocked and stops; the other drives on;
    both blocked -> squared. A low step skips the approach (squared at once)."""
    a0 = float(p["A0"])
    flip = jnp.array([a0, a0, 0.0, 0.0])
    v = float(p["clm_speed"])
    tau = -2.0 * float(p["approach_tau"])
    sense = clm.measure(_obs(flipper_q=(a0, a0, 0.0, 0.0), flipper_tau=(0.0, tau, 0.0, 0.0), track_speed=(v, v)))
    s = clm.clm_init(p, _obs())
    st = s.approach
    prepare, h_est = jnp.asarray(True), jnp.asarray(0.4)
    s = s._replace(phase=jnp.asarray(clm.PREPARE, jnp.int32), h_est=h_est)
    ph = clm.phase_masks(s.phase)
    need = float(p["approach_touch_s"])
    n = int(np.ceil(need / DT)) + 2
    for k in range(1, n + 1):
        st, approaching = clm.approach_step(p, st, flip, h_est, sense, prepare, DT)
        assert bool(approaching)
        assert float(st.side_touch[1]) == pytest.approx(k * DT)
        assert bool(st.blocked[1]) == (float(st.side_touch[1]) > need)
        assert not bool(st.blocked[0]) and not bool(st.squared)
    assert bool(st.blocked[1])
    t = n * DT
    np.testing.assert_allclose(st.side_touch, [0.0, t], atol=1e-12)
    np.testing.assert_allclose(st.approached, t * v, atol=1e-12)
    _, _, v_side = clm.crawler_drive(p, s._replace(approach=st), ph, jnp.asarray(True), st)
    np.testing.assert_allclose(v_side, [v, 0.0])
    # both pressed: squared once the left one has been pressed long enough too
    both = clm.measure(_obs(flipper_q=(a0, a0, 0.0, 0.0), flipper_tau=(tau, tau, 0.0, 0.0), track_speed=(v, v)))
    for _ in range(n):
        st, _ = clm.approach_step(p, st, flip, h_est, both, prepare, DT)
        if bool(st.squared):
            break
    assert bool(st.squared) and bool(st.blocked.all())  # (the approach is over: blocked resets next period)
    # a low step: no approach
    low, approaching = clm.approach_step(p, s.approach, flip, jnp.asarray(0.2), sense, prepare, DT)
    assert bool(low.squared) and not bool(approaching)


def test_crawlers_wait_while_an_arm_is_idle(p):
    s = clm.clm_init(p, _obs())
    ph = clm.phase_masks(s.phase)
    drive, v_cmd, _ = clm.crawler_drive(p, s, ph, jnp.asarray(False), s.approach)
    assert bool(drive) and float(v_cmd) == pytest.approx(float(p["clm_speed"]))
    idle = s._replace(arms=s.arms._replace(arm_phase=s.arms.arm_phase.at[1].set(clm.IDLE)))
    drive, v_cmd, _ = clm.crawler_drive(p, idle, ph, jnp.asarray(False), s.approach)
    assert not bool(drive) and float(v_cmd) == 0.0


def test_phase_transitions(p):
    s = clm.clm_init(p, _obs())
    no, yes = jnp.asarray(False), jnp.asarray(True)

    def nxt(phase, h_est=0.4, at_riser=no, climb_over=no, release_over=no, crawl_over=no, s=s, p=p):
        s = s._replace(phase=jnp.asarray(phase, jnp.int32))
        tr = clm.phase_transition(p, s, clm.phase_masks(s.phase), s.arms, yes, jnp.asarray(h_est), at_riser,
                                  jnp.asarray(0.0), climb_over, release_over, crawl_over)
        return int(tr.phase), tr

    assert nxt(clm.CLIMB)[0] == clm.CLIMB
    phase, tr = nxt(clm.CLIMB, climb_over=yes)
    assert phase == clm.RELEASE and bool(tr.changed) and not bool(tr.finished)
    assert nxt(clm.WALK)[0] == clm.WALK
    assert nxt(clm.WALK, at_riser=yes)[0] == clm.PREPARE
    assert nxt(clm.WALK, h_est=0.2, at_riser=yes)[0] == clm.PREPARE  # CRAWL off: the paper's default
    crawl = p | {"crawl_max_h": jnp.asarray(0.25, jnp.asarray(p["crawl_max_h"]).dtype)}  # the named option
    assert nxt(clm.WALK, h_est=0.2, at_riser=yes, p=crawl)[0] == clm.CRAWL  # H_EST <= crawl_max_h
    phase, tr = nxt(clm.RELEASE, release_over=yes)
    assert phase == clm.DONE and bool(tr.finished) and not bool(tr.crawled)
    phase, tr = nxt(clm.CRAWL, crawl_over=yes)
    assert phase == clm.DONE and bool(tr.crawled)
    assert nxt(clm.PREPARE)[0] == clm.PREPARE
    placed = s._replace(arms=s.arms._replace(placed_n=jnp.asarray(clm.N_PREPARE, jnp.int32)))
    assert nxt(clm.PREPARE, s=placed)[0] == clm.CLIMB
    assert nxt(clm.DONE, s=s._replace(travel=jnp.asarray(float(p["done_distance"]) + 0.01)))[0] == clm.WALK
    # a finished climb: every arm idle, the step detection cleared
    arms, confirmed, crawl = clm.enter_phase(tr, jnp.asarray(5.0), s.arms, yes, s.crawl)
    assert (np.asarray(arms.arm_phase) == clm.IDLE).all() and not bool(confirmed) and bool(crawl.crawled_last)


def test_paper_climb_release_condition(p):
    """climb_paper = 1, both sides as one (climb_per_side = 0): CLIMB is over when H > H_EST
    and S > L (S the stored travel)."""
    pp = {**p, "climb_paper": jnp.asarray(1.0), "climb_per_side": jnp.asarray(0.0)}
    s = clm.clm_init(pp, _obs())
    s = s._replace(phase=jnp.asarray(clm.CLIMB, jnp.int32), h_est=jnp.asarray(0.3))
    sense = clm.measure(_obs())
    L = float(p["settle_distance"])
    for h, travel, over in ((0.4, L + 0.05, True), (0.2, L + 0.05, False), (0.4, L - 0.05, False)):
        c = clm.climb_step(pp, s._replace(travel=jnp.asarray(travel)), sense, jnp.asarray(h), jnp.asarray(travel))
        assert bool(c.over) == over
        q, f = clm.paper_climb_step(pp, s.arms.q_cmd, s.flip, sense.flip_q, sense.flip_tau, jnp.asarray(over))
        np.testing.assert_array_equal(c.q, q)
        np.testing.assert_array_equal(c.flip, f)


def test_paper_climb_adapts_each_side_to_its_own_step(p):
    """climb_per_side = 1 (the default, Fig. 17): the step detection keeps the step height
    under each side, and in CLIMB each side compares its own H (the COG above its rear
    EPRA) with it. On the two terraces from the side (0.4 m under the left side, 0.2 m
    under the right) the level robot's H (0.27 m) is above the right step and below the
    left one: once S > L the left booms and the left front flipper go on (+Delta_E,
    -Delta_F) while the right ones hold (Eq. 28 as a whole robot, with H_EST = 0.3 m,
    would turn all of them); CLIMB is over only with both sides up, and neither side is
    up before S > L."""
    pp = {**p, "climb_paper": jnp.asarray(1.0), "flip_encoder": jnp.asarray(0.0), "climb_yield": jnp.asarray(0.0)}
    assert float(p["climb_per_side"]) == 1.0
    sense = clm.measure(_obs())
    s = clm.clm_init(pp, _obs())
    contacts = jnp.asarray(params.TABLE2_INIT).at[:2, 2].add(jnp.array([0.4, 0.2]))
    on_step = jnp.array([True, True, False, False])  # both front arms stopped on the terraces
    confirmed, h_est, h_est_side = clm.detect_step(pp, s.confirmed, s.h_est, s.h_est_side, on_step, contacts,
                                                   sense.pitch, sense.roll, jnp.asarray(True))
    assert bool(confirmed)
    np.testing.assert_allclose(h_est_side, [0.4, 0.2], atol=1e-9)
    assert float(h_est) == pytest.approx(0.3, abs=1e-9)
    h_side = np.asarray(kin.cog_height_sides(KP, sense.tips, sense.pitch, sense.roll))
    assert 0.2 < h_side.min() <= h_side.max() < 0.3
    L = float(p["settle_distance"])
    s = s._replace(phase=jnp.asarray(clm.CLIMB, jnp.int32), travel=jnp.asarray(L + 0.05), confirmed=confirmed,
                   h_est=h_est, h_est_side=h_est_side)
    h = jnp.asarray(float(h_side.mean()))
    c = clm.climb_step(pp, s, sense, h, s.travel)
    assert not bool(c.over)
    boom_step = np.asarray(c.q[:, 1] - s.arms.q_cmd[:, 1])
    np.testing.assert_allclose(boom_step, float(p["delta_e"]) * np.array([1.0, 0.0, 1.0, 0.0]), atol=1e-7)
    np.testing.assert_allclose(np.asarray(c.flip - s.flip), -float(p["delta_f"]) * np.array([1.0, 0.0, 0.0, 0.0]),
                               atol=1e-7)
    # both sides up -> over; S short of L -> neither side is up
    both = s._replace(h_est_side=jnp.asarray(h_side - 0.05))
    assert bool(clm.climb_step(pp, both, sense, h, s.travel).over)
    short = both._replace(travel=jnp.asarray(L - 0.05))
    c = clm.climb_step(pp, short, sense, h, short.travel)
    assert not bool(c.over)
    np.testing.assert_allclose(np.asarray(c.q[:, 1] - s.arms.q_cmd[:, 1]), float(p["delta_e"]), atol=1e-7)


def test_release_and_carry(p):
    """RELEASE (level lift): arms at the Table 2 height and flippers >= 0 -> back, commands
    held; a flipper below 0 turns up by delta_f. DONE: booms up by delta_b first, elbows
    held until the booms are up."""
    s = clm.clm_init(p, _obs())
    q = s.arms.q_cmd
    zero = jnp.asarray(0.0)
    q_r, f_r, back = clm.release_step(p, q, jnp.zeros(4), zero, zero)
    assert bool(back)
    np.testing.assert_allclose(q_r, q)
    _, f_r, back = clm.release_step(p, q, jnp.array([-0.1, 0.0, -0.005, 0.2]), zero, zero)
    assert not bool(back)
    np.testing.assert_allclose(f_r, [-0.1 + float(p["delta_f"]), 0.0, 0.0, 0.2])
    db = float(p["delta_b"])
    q_d = clm.carry_step(p, q)
    np.testing.assert_allclose(q_d[:, 1], q[:, 1] - db)
    np.testing.assert_allclose(q_d[:, [0, 2]], q[:, [0, 2]])
    up = q.at[:, 1].set(float(p["lift_boom_front"]))
    q_d = clm.carry_step(p, up)
    np.testing.assert_allclose(q_d[:, 2], up[:, 2] + np.clip(float(p["carry_elbow"]) - up[:, 2], -db, db))


@pytest.mark.parametrize(("phase", "moving"), [(cr.LIFT, False), (cr.SWING, False), (cr.OVER, False),
                                               (cr.SWING, True), (cr.OVER, True)])
def test_collision_stops_a_transfer_in_lift_swing_and_over(p, phase, moving):
    """Figs. 19-20: a boom torque beyond collision_torque for collision_periods periods in a
    row stops the transferring arm where it is (PLACED, its command the *measured* angles:
    "all of the joints in that arm stopped in this sample period", not the last command,
    which the blocked servo lags behind; its contact at its EPRA) in LIFT, SWING and OVER
    alike; in SWING and OVER also while the pressed joint still moves (an arm pressing an
    obstacle top lifts the body and keeps turning). In LIFT the boom must stand still, and
    the signal counts only once it has risen collision_lift from where the lift began: an
    arm that starts on the ground presses it first (no obstacle)."""
    arm = 3  # RR
    s = clm.clm_init(p, _obs())
    obs = _obs()
    q = obs["arm_q"].reshape(4, 3)
    risen = q.at[arm, 1].add(-2.0 * float(p["collision_lift"]))  # boom turned up past collision_lift
    ahead = risen.at[arm, 1:].add(0.05)  # the commands the blocked servos lag behind
    tau = jnp.zeros((4, 3)).at[arm, 1].set(2.0 * float(p["collision_torque"]))
    step = 4.0 * float(p["collision_still"]) if moving else 0.0  # the boom turned this much in the last period
    arms = s.arms._replace(arm_phase=s.arms.arm_phase.at[arm].set(phase), active=jnp.asarray(arm, jnp.int32),
                           q_cmd=ahead, q_cmd2=ahead, q_prev=risen.at[arm, 1].add(step), lift_from=q[:, 1])
    sense = clm.measure({**obs, "arm_q": risen.reshape(-1), "arm_tau": tau.reshape(-1)})
    no = jnp.asarray(False)
    n = int(p["collision_periods"])
    for k in range(n):
        tr = clm.arm_transfer(p, arms, arms.contacts, sense, no, jnp.asarray(0.0))
        stopped = int(tr.arm_phase[arm]) == cr.PLACED
        assert stopped == (k == n - 1), (k, int(tr.arm_phase[arm]))
        arms = arms._replace(hit_n=tr.hit_n)
    np.testing.assert_allclose(tr.cmd[arm], risen[arm])  # stopped where it is, not at the command
    np.testing.assert_allclose(tr.contacts[arm], sense.tips[arm], atol=1e-12)
    if phase == cr.LIFT:  # the same torque while the boom still turns: no collision in LIFT
        turning = arms._replace(hit_n=jnp.zeros(4, jnp.int32), q_prev=risen.at[arm, 1].add(
            4.0 * float(p["collision_still"])))
        for _ in range(n + 2):
            tr = clm.arm_transfer(p, turning, turning.contacts, sense, no, jnp.asarray(0.0))
            assert int(tr.arm_phase[arm]) != cr.PLACED and int(tr.hit_n[arm]) == 0
            turning = turning._replace(hit_n=tr.hit_n)
        # the same torque before the boom has risen: no collision
        arms = arms._replace(hit_n=jnp.zeros(4, jnp.int32), q_cmd=q, q_cmd2=q, q_prev=q)
        grounded = clm.measure({**obs, "arm_tau": tau.reshape(-1)})
        for _ in range(n + 2):
            tr = clm.arm_transfer(p, arms, arms.contacts, grounded, no, jnp.asarray(0.0))
            assert int(tr.arm_phase[arm]) != cr.PLACED and int(tr.hit_n[arm]) == 0
            arms = arms._replace(hit_n=tr.hit_n)


def test_a_front_arm_stopped_high_but_short_of_its_target_is_on_the_step(p):
    """A front arm whose transfer ends 0.2 m above its target and 0.17 m short of it along x
    (it met a 200 mm step top near the edge: stop case BLOCKED, |dx| > delta_c) marks the
    step (dz > delta_d), as one that reaches its target height does not."""
    arm = 1  # RF
    s = clm.clm_init(p, _obs())
    obs = _obs()
    target = jnp.asarray(params.TABLE2_TARGET[arm])
    for dz, on_step in ((0.2, True), (0.0, False)):
        tip = target + jnp.array([-0.17, 0.0, dz])
        q_all, _ = kin.inverse_kinematics_all(KP, jnp.asarray(params.TABLE2_TARGET).at[arm].set(tip))
        q = jnp.asarray(obs["arm_q"]).reshape(4, 3).at[arm].set(q_all[arm])
        tau = jnp.zeros((4, 3)).at[arm, 1].set(2.0 * float(p["collision_torque"]))
        arms = s.arms._replace(arm_phase=s.arms.arm_phase.at[arm].set(cr.OVER), active=jnp.asarray(arm, jnp.int32),
                               q_cmd=q, q_cmd2=q, q_prev=q, hit_n=s.arms.hit_n.at[arm].set(
                                   int(p["collision_periods"]) - 1))
        sense = clm.measure({**obs, "arm_q": q.reshape(-1), "arm_tau": tau.reshape(-1)})
        tr = clm.arm_transfer(p, arms, arms.contacts, sense, jnp.asarray(False), jnp.asarray(0.0))
        assert bool(tr.just_placed[arm])
        np.testing.assert_allclose(sense.tips[arm], tip, atol=1e-6)
        assert int(tr.stop_case[arm]) == cr.STOP_BLOCKED
        assert bool(tr.on_step[arm]) == on_step
