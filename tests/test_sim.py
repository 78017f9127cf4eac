"""The simulation layer (`jaxloco.sim`): both backends, per-simulation parameters,
divergence, gradients, errors. A small standing-quadruped scenario (the leg-grope
model on a flat box whose height and friction are per-simulation parameters) keeps
these fast."""

from __future__ import annotations

import os

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from jaxloco.errors import SpecError
from jaxloco.robots.leggrope import kinematics as kin
from jaxloco.robots.leggrope import model as robot_model
from jaxloco.robots.leggrope.params import default_params
from jaxloco.robots.leggrope.scenarios import standing_scenario
from jaxloco.sim import terrain as tr
from jaxloco.sim.rollout import rollout, stack_params
from jaxloco.sim.scenario import ModelField, initial_activation, model_field_values


@pytest.fixture(scope="module")
def scenario():
    return standing_scenario(horizon=20, substeps=5)


def _params(n=1, **kw):
    base = {"ground": 0.0, "offset": 0.0, "mu": 1.0, "kick": 0.0}
    rows = [{k: kw.get(k, [base[k]] * n)[i] for k in base} for i in range(n)]
    return stack_params(rows)


def test_native_is_identical_for_one_and_two_threads(scenario):
    p = _params(3, offset=[0.0, 0.05, -0.05], ground=[0.0, 0.1, -0.2])
    a = rollout(scenario, p, nthread=1)
    b = rollout(scenario, p, nthread=2)
    np.testing.assert_array_equal(a.records["qpos"], b.records["qpos"])
    np.testing.assert_array_equal(a.metrics["final_height"], b.metrics["final_height"])


def test_native_init_in_blocks_gives_the_rollout_of_one_vmap(scenario):
    """The controller's init runs over the batch in vmapped blocks of `init_rows` rows
    (memory for one block); 3 rows in blocks of 2 (the last one padded) give the same
    rollout, records and final controller state as one vmap over the 3 rows."""
    from jaxloco.sim import native

    p = _params(3, offset=[0.0, 0.05, -0.05], ground=[0.0, 0.1, -0.2])
    keys = jnp.stack([jax.random.PRNGKey(i) for i in range(3)])
    p["key"] = keys
    one = native.run(scenario, p, keys, init_rows=None)
    blocks = native.run(scenario, p, keys, init_rows=2)
    np.testing.assert_array_equal(blocks["records"]["qpos"], one["records"]["qpos"])
    for a, b in zip(jax.tree_util.tree_leaves(blocks["final"].ctrl_state),
                    jax.tree_util.tree_leaves(one["final"].ctrl_state)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    with pytest.raises(ValueError, match="init_rows must be a positive int"):
        native.run(scenario, p, keys, init_rows=0)


def test_per_simulation_parameters_differ_and_match_single_runs(scenario):
    grounds, offsets, mus = [0.0, 0.1, -0.2], [0.0, 0.05, -0.05], [1.0, 0.3, 0.6]
    batch = rollout(scenario, _params(3, ground=grounds, offset=offsets, mu=mus), seeds=[0, 1, 2])
    # the ground height really moves the robot: heights differ by the ground offsets
    h = batch.metrics["mean_height"]
    assert abs((h[1] - h[0]) - 0.1) < 0.02 and abs((h[2] - h[0]) + 0.2) < 0.02
    for i in range(3):
        single = rollout(scenario, _params(1, ground=[grounds[i]], offset=[offsets[i]], mu=[mus[i]]), seeds=[i])
        np.testing.assert_array_equal(batch.records["qpos"][i], single.records["qpos"][0])


def test_friction_is_per_simulation():
    """Expanded geom_friction reaches each simulation (native) / each vmapped model (mjx)."""
    sc = standing_scenario(horizon=2, substeps=1)
    from jaxloco.sim import native
    p = _params(2, mu=[0.2, 0.9])
    batch = native.make_batch(sc, p, 2, 1)
    gid = sc.model_fields[0].index[0][0]
    np.testing.assert_allclose(batch.expanded("geom_friction")[:, gid, 0], [0.2, 0.9])


def test_diverging_simulation_is_flagged_and_does_not_spoil_neighbours(scenario):
    p = _params(3, kick=[0.0, 1e6, 0.0], offset=[0.0, 0.0, 0.05])
    out = rollout(scenario, p, seeds=[0, 1, 2])
    assert list(out.status) == ["ok", "diverged", "ok"]
    assert np.isfinite(out.t_diverged[1]) and out.t_diverged[1] <= scenario.horizon * scenario.control_dt
    assert np.isnan(out.t_diverged[[0, 2]]).all()
    for i in (0, 2):
        single = rollout(scenario, _params(1, offset=[[0.0, 0.0, 0.05][i]]), seeds=[i])
        np.testing.assert_array_equal(out.records["qpos"][i], single.records["qpos"][0])


@pytest.fixture(scope="module")
def short_scenario():
    return standing_scenario(horizon=10, substeps=2)


def test_backends_agree_on_a_short_rollout(short_scenario):
    """Same model and controller for 40 ms (20 physics steps). MJX and MuJoCo C use the
    same formulation, but their collision routines (MJX: GJK-style convex vs. C's
    analytic box-sphere), solver loops and float summation orders differ: contact forces
    differ at solver-tolerance level, which moves the toes by far less than a millimetre
    over this window. 1 mm / 10 mrad bounds that; a real model mismatch (e.g. one
    backend ignoring the per-simulation ground height, 0.1 m) fails it."""
    p = _params(2, ground=[0.0, 0.1], offset=[0.0, 0.05])
    a = rollout(short_scenario, p, backend="native")
    b = rollout(short_scenario, p, backend="mjx")
    assert list(b.status) == ["ok", "ok"]
    np.testing.assert_allclose(b.records["qpos"][..., :3], a.records["qpos"][..., :3], atol=1e-3)
    np.testing.assert_allclose(b.records["qpos"][..., 7:], a.records["qpos"][..., 7:], atol=1e-2)
    np.testing.assert_allclose(b.times, a.times)


def test_mjx_gradient_matches_finite_differences(short_scenario):
    """d(mean body height)/d(knee offset) through the MJX rollout (forward mode)
    against central differences, in float64, with the robot in the air (ground 1 m
    below): controller, actuators and multibody dynamics, no contact. (Through these
    stiff, nearly hard toe contacts forward-mode and finite differences disagreed, even
    in sign, over 40 ms: contact gradients need softer contacts or smoothing; see the
    note in `jaxloco.sim.mjx`.)"""
    from jaxloco.sim import mjx as mjx_backend

    run = mjx_backend.rollout_fn(short_scenario)
    key = jax.random.PRNGKey(0)

    def height(offset):
        p = {"ground": jnp.float64(-1.0), "offset": offset, "mu": jnp.float64(1.0), "kick": jnp.float64(0.0),
             "key": key}
        return run(p, key)[0]["qpos"][-1, 9]  # L1 knee at the last record

    # one compiled program gives the value (for the differences) and the forward-mode slope
    value_and_slope = jax.jit(lambda x: jax.jvp(height, (x,), (jnp.ones_like(x),)))
    x = jnp.float64(0.02)
    g = value_and_slope(x)[1]
    h = 1e-4
    fd = (value_and_slope(x + h)[0] - value_and_slope(x - h)[0]) / (2 * h)
    assert np.isfinite(g) and abs(g) > 1e-3  # the knee target moves the knee
    np.testing.assert_allclose(g, fd, rtol=0.05, atol=1e-5)


def _with_a_sensing_controller(sc):
    """`sc` with a controller whose state starts from forward-dynamics quantities (the
    subtree COM, the actuator forces, the sensors) and integrates them, so that the
    records show which data each tick saw."""
    from jaxloco.sim.scenario import Controller

    def observe(data):
        return {"time": data.time, "q": data.qpos[7:], "com": data.subtree_com[1], "force": data.actuator_force,
                "sensors": data.sensordata}

    def init(p, obs):
        return {"com0": obs["com"], "effort": jnp.sum(jnp.abs(obs["force"])), "n": jnp.zeros((), jnp.int32)}

    def step(p, c, obs):
        c = {"com0": c["com0"], "effort": c["effort"] + jnp.sum(jnp.abs(obs["force"])), "n": c["n"] + 1}
        action = sc.initial_state(p, jax.random.PRNGKey(0)).ctrl  # the standing pose
        return c, action.at[0].add(0.3 * jnp.sin(20.0 * obs["time"]) + 1e-3 * obs["com"][2])

    def record(p, data, obs, c, e):
        return {"qpos": data.qpos, "height": data.qpos[2], "com": obs["com"], "effort": c["effort"],
                "sensors": obs["sensors"]}

    return sc.with_(controller=Controller(init, step), observe=observe, record=record)


def _plain_mjx_rollout(sc, params, key):
    """The oracle: `mjx.forward`, the controller's init, then per control period one
    tick and `substeps` x `mjx.step`, written as a Python loop of jitted pieces (the
    actuators' filter states start at their controls, as in both backends)."""
    from jaxloco.sim import data as simdata
    from jaxloco.sim.mjx import mjx
    from jaxloco.sim.scenario import tick_fn

    mx = mjx.put_model(sc.model).tree_replace(model_field_values(sc, params))
    s0 = sc.initial_state(params, key)
    d = mjx.make_data(mx).replace(qpos=s0.qpos, qvel=s0.qvel, ctrl=s0.ctrl, mocap_pos=s0.mocap_pos,
                                  mocap_quat=s0.mocap_quat, act=initial_activation(sc.model, s0.ctrl))
    d = jax.jit(mjx.forward)(mx, d)
    cstate, estate = sc.controller.init(params, sc.observe(simdata.from_mjx(d))), jnp.zeros(())
    tick, step = jax.jit(tick_fn(sc)), jax.jit(mjx.step)
    records = []
    for k in range(sc.horizon):
        cstate, estate, ctrl, mocap_pos, mocap_quat, rec, bad = tick(params, cstate, estate, simdata.from_mjx(d))
        assert not bad
        if k % sc.record_every == 0:
            records.append(rec)
        d = d.replace(ctrl=ctrl, mocap_pos=mocap_pos, mocap_quat=mocap_quat)
        for _ in range(sc.substeps):
            d = step(mx, d)
    records = jax.tree_util.tree_map(lambda *r: np.stack(r), *records)
    return records, d, cstate


def test_the_mjx_rollout_computes_forward_init_then_ticks_and_steps():
    """The rollout's single loop (the initial forward dynamics as its first iteration's
    physics, the controller started inside it, the last iteration's control discarded)
    against the plain sequence written out: every record, the final state and the
    controller's final state agree to float64 rounding; three records of two periods
    each, two physics steps per period, the robot dropping onto the box."""
    from jaxloco.sim import mjx as mjx_backend

    sc = _with_a_sensing_controller(standing_scenario(horizon=6, substeps=2, record_every=2))
    key = jax.random.PRNGKey(3)
    params = {"ground": jnp.float64(0.0), "offset": jnp.float64(0.05), "mu": jnp.float64(0.8),
              "kick": jnp.float64(-0.3), "key": key}
    records, _, final = jax.jit(mjx_backend.rollout_fn(sc))(params, key)
    want, d, cstate = _plain_mjx_rollout(sc, params, key)
    assert records["qpos"].shape == (3, sc.model.nq)
    for name in want:
        np.testing.assert_allclose(records[name], want[name], rtol=1e-10, atol=1e-12, err_msg=name)
    np.testing.assert_allclose(final.data.qpos, d.qpos, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(final.data.qvel, d.qvel, rtol=1e-10, atol=1e-9)
    np.testing.assert_allclose(final.data.sensordata, d.sensordata, rtol=1e-10, atol=1e-9)
    np.testing.assert_allclose(final.data.time, d.time, rtol=1e-12)
    assert int(final.ctrl_state["n"]) == sc.horizon == int(cstate["n"])
    np.testing.assert_allclose(final.ctrl_state["effort"], cstate["effort"], rtol=1e-10)
    np.testing.assert_allclose(final.ctrl_state["com0"], cstate["com0"], rtol=1e-12)
    assert bool(final.alive)
    assert np.abs(np.diff(records["com"][:, 2])).max() > 1e-4  # it moved


def test_mjx_refuses_mass_fields():
    from jaxloco.sim import mjx as mjx_backend

    sc = standing_scenario(horizon=2, substeps=1)
    sc = sc.with_(model_fields=(ModelField("body_mass", (np.array([1]),), lambda p: p["mu"][None]),))
    with pytest.raises(ValueError, match="body_mass"):
        mjx_backend.rollout_fn(sc)


def test_native_mass_field_recomputes_derived_constants():
    sc = standing_scenario(horizon=2, substeps=1)
    sc = sc.with_(model_fields=(ModelField("body_mass", (np.array([1]),), lambda p: 4.54 + p["mu"][None]),))
    from jaxloco.sim import native
    batch = native.make_batch(sc, _params(2, mu=[0.0, 1.0]), 2, 1)
    sub = batch.expanded("body_subtreemass")
    assert sub is not None
    np.testing.assert_allclose(sub[1, 1] - sub[0, 1], 1.0)


def test_broken_model_file_gives_one_line_error(tmp_path):
    with pytest.raises(SpecError, match="model file not found"):
        robot_model.load_spec(tmp_path / "missing.xml")
    bad = tmp_path / "bad.xml"
    bad.write_text("<mujoco><worldbody><body><geom type='sphere'/></worldbody></mujoco>")
    with pytest.raises(SpecError, match="broken MJCF") as err:
        robot_model.load_spec(bad)
    assert "\n" not in str(err.value)


def test_invalid_terrain_parameter_is_rejected():
    with pytest.raises(SpecError, match="theta"):
        tr.slope().check({"theta": 2.0})
    with pytest.raises(SpecError, match="unknown"):
        tr.slope().check({"tilt": 0.1})


def test_scenario_validates_its_shape():
    sc = standing_scenario(horizon=4, substeps=1)
    with pytest.raises(ValueError, match="multiple"):
        sc.with_(record_every=3)


def test_filtered_servos_start_at_their_controls():
    """Actuators with a setpoint filter (MJCF timeconst: an activation state) start at their
    controls, the filter's steady state; MuJoCo would start them at 0."""
    xml = """<mujoco><worldbody><body><joint name='a' type='hinge'/><geom size='.1' mass='1'/>
    <body><joint name='b' type='hinge'/><geom size='.1' mass='1'/></body></body></worldbody>
    <actuator><position joint='a' kp='10'/><position joint='b' kp='10' timeconst='0.02'/></actuator></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    act = np.asarray(initial_activation(m, jnp.array([[0.3, -0.7], [0.1, 0.2]])))
    assert act.shape == (2, 1) and np.allclose(act[:, 0], [-0.7, 0.2])
    assert robot_model.build_spec().compile().na == 12  # the leg-grope servos are filtered


def test_model_file_matches_generator_and_table_1():
    assert robot_model.MODEL_PATH.read_text() == robot_model.xml_text()
    m = robot_model.load_spec().compile()
    np.testing.assert_allclose(m.body_subtreemass[m.body("torso").id], float(default_params().total_mass))
    assert m.nu == 12 and mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SENSOR, "L1_force") >= 0


def test_model_toe_sites_match_kinematics():
    """MuJoCo's own toe-site positions equal `kinematics.foot_position` (robot frame)."""
    m = robot_model.load_spec().compile()
    d = mujoco.MjData(m)
    rng = np.random.default_rng(0)
    params = default_params()
    for _ in range(5):
        q = rng.uniform(-0.8, 0.8, 12) + np.tile([0.0, 0.3, -1.2], 4)
        d.qpos[:7] = [0, 0, 0, 1, 0, 0, 0]
        d.qpos[7:] = q
        mujoco.mj_kinematics(m, d)
        for leg in range(4):
            site = d.site_xpos[m.site(f"L{leg + 1}_toe").id]
            ref = np.asarray(kin.foot_position(params, leg, jnp.asarray(q[3 * leg:3 * leg + 3])))
            np.testing.assert_allclose(site, ref, atol=1e-6)  # the MJCF stores 6 significant digits


def test_mjx_batch_is_sharded_over_every_device_and_matches_one_device(short_scenario, monkeypatch):
    """The MJX backend pads the batch to a multiple of the device count and shards it over
    every JAX device (the CPU cores here, the GPUs on an accelerator machine); the rows
    equal an unsharded run's."""
    import jax

    from jaxloco.sim import mjx as mjx_backend

    if len(jax.devices()) < 2:
        pytest.skip("one JAX device: nothing to shard over")
    seen = []
    original = mjx_backend.program

    def spy(scenario, block):
        fn = original(scenario, block)

        def wrapped(params, keys):
            seen.append((keys.shape[0], keys.sharding.device_set))
            return fn(params, keys)

        return wrapped

    monkeypatch.setattr(mjx_backend, "program", spy)
    # one row, padded to one per device, its key among the parameters as `rollout` puts
    # it: with 2 devices the sharded program is the one test_backends_agree_on_a_short_rollout
    # compiled (2 rows, same structure), so only the single-device run compiles anew
    p = _params(1, ground=[0.05], offset=[0.02])
    keys = jnp.stack([jax.random.PRNGKey(0)])
    p["key"] = keys
    sharded = mjx_backend.run(short_scenario, p, keys, shard=True)
    single = mjx_backend.run(short_scenario, p, keys, shard=False)
    n_dev = len(jax.devices())
    assert seen[0] == (n_dev, set(jax.devices()))
    assert len(seen[1][1]) == 1 and seen[1][0] == 1
    for k in sharded["records"]:
        np.testing.assert_allclose(sharded["records"][k], single["records"][k], rtol=1e-12, atol=1e-12)


def test_a_large_mjx_batch_runs_block_by_block_with_the_rows_of_one_vmap(short_scenario):
    """An MJX batch of more rows per device than `rows_per_device` runs as a `lax.map`
    over vmapped blocks (on CPU from 5 rows per device: jaxlib's batched Cholesky can
    hang XLA's CPU thread pool on large batches). Each row is the same simulation as in
    one vmap: here 5 rows in blocks of one row per device against the 2-row run of
    test_backends_agree_on_a_short_rollout (the same compiled program)."""
    from jaxloco.sim import mjx as mjx_backend

    n_dev = len(jax.devices())
    assert mjx_backend.block_size(n_dev, "cpu") == mjx_backend.CPU_ROWS_PER_DEVICE * n_dev
    assert mjx_backend.block_size(n_dev, "gpu") == mjx_backend.ACCELERATOR_ROWS_PER_DEVICE * n_dev
    with pytest.raises(ValueError, match="rows_per_device must be a positive int"):
        mjx_backend.block_size(n_dev, rows_per_device=0)
    ref = rollout(short_scenario, _params(2, ground=[0.0, 0.1], offset=[0.0, 0.05]), backend="mjx")
    p = _params(5, ground=[0.1, 0.0, 0.1, 0.1, 0.0], offset=[0.05, 0.0, 0.05, 0.05, 0.0])
    keys = jnp.stack([jax.random.PRNGKey(i) for i in (1, 0, 1, 1, 0)])
    p["key"] = keys
    blocked = mjx_backend.run(short_scenario, p, keys, rows_per_device=1)
    for row, ref_row in enumerate((1, 0, 1, 1, 0)):
        np.testing.assert_allclose(blocked["records"]["qpos"][row], ref.records["qpos"][ref_row], rtol=1e-9, atol=1e-12)


def _counting_rollout_fn(monkeypatch):
    """Count the MJX backend's calls of `rollout_fn` (each one traces the rollout anew)."""
    from jaxloco.sim import mjx as mjx_backend

    calls = []
    original = mjx_backend.rollout_fn

    def counted(scenario):
        calls.append(scenario.name)
        return original(scenario)

    monkeypatch.setattr(mjx_backend, "rollout_fn", counted)
    return calls


def test_a_later_process_loads_the_traced_mjx_program_and_gets_the_same_rows(tmp_path, monkeypatch):
    """The program cache (`jaxloco.sim.programs`): the first MJX run of a scenario traces
    its rollout and keeps the lowered program on disk; a scenario built the same way (as
    in a new process) loads it without tracing and gets the same rows bit for bit, as
    does a run with the cache off (traced as before). A damaged file is traced again and
    rewritten. (2 rows, 10 periods: the program of test_backends_agree_on_a_short_rollout.)"""
    from jaxloco.sim import programs

    monkeypatch.setenv(programs.ENV_SWITCH, str(tmp_path))
    calls = _counting_rollout_fn(monkeypatch)
    p = _params(2, ground=[0.0, 0.1], offset=[0.0, 0.05])
    first = rollout(standing_scenario(horizon=10, substeps=2), p, backend="mjx")
    files = list(tmp_path.glob("*.bin"))
    assert len(calls) == 1 and len(files) == 1
    later = rollout(standing_scenario(horizon=10, substeps=2), p, backend="mjx")
    assert len(calls) == 1  # loaded, not traced
    monkeypatch.setenv(programs.ENV_SWITCH, "0")
    plain = rollout(standing_scenario(horizon=10, substeps=2), p, backend="mjx")
    assert len(calls) == 2 and len(list(tmp_path.glob("*.bin"))) == 1
    monkeypatch.setenv(programs.ENV_SWITCH, str(tmp_path))
    files[0].write_bytes(b"not a program")
    again = rollout(standing_scenario(horizon=10, substeps=2), p, backend="mjx")
    assert len(calls) == 3 and files[0].stat().st_size > 10_000
    for other in (later, plain, again):
        for k in first.records:
            np.testing.assert_array_equal(other.records[k], first.records[k], err_msg=k)
        assert list(other.status) == list(first.status) == ["ok", "ok"]


def test_a_later_process_loads_the_native_backends_inits_and_metrics(tmp_path, monkeypatch):
    """The native backend keeps its jitted initial states, controller init, per-period
    tick and metrics in the program cache (`programs.CachedJit`, `programs.load_or_export`):
    a scenario built again loads them without tracing the init or the tick, and its rows
    and metrics equal bit for bit those of the first run and of a run with the cache off."""
    from jaxloco.sim import native, programs

    monkeypatch.setenv(programs.ENV_SWITCH, str(tmp_path))
    calls = []
    for name in ("init_fn", "tick_fn"):
        original = getattr(native, name)
        monkeypatch.setattr(native, name, lambda sc, o=original, n=name: calls.append(n) or o(sc))
    p = _params(2, ground=[0.0, 0.1], offset=[0.0, 0.05])
    runs = [rollout(standing_scenario(horizon=10, substeps=2), p, backend="native")]
    assert sorted(calls) == ["init_fn", "tick_fn"]
    assert len(list(tmp_path.glob("*.bin"))) == 4  # initial_state, init, tick, summarize
    runs.append(rollout(standing_scenario(horizon=10, substeps=2), p, backend="native"))
    assert len(calls) == 2  # loaded, not traced
    monkeypatch.setenv(programs.ENV_SWITCH, "0")
    runs.append(rollout(standing_scenario(horizon=10, substeps=2), p, backend="native"))
    assert sorted(calls) == ["init_fn", "init_fn", "tick_fn", "tick_fn"]
    for other in runs[1:]:
        for k in runs[0].records:
            np.testing.assert_array_equal(other.records[k], runs[0].records[k], err_msg=k)
        for k in runs[0].metrics:
            np.testing.assert_array_equal(other.metrics[k], runs[0].metrics[k], err_msg=k)


def test_program_keys_follow_what_the_program_is_traced_from(tmp_path, monkeypatch):
    """Same scenario and inputs, same key; another horizon, batch or dtype, another key;
    a scenario holding code from outside jaxloco (here this test module, whose edits the
    key would not see) or a cache switched off, no key (traced every time)."""
    import dataclasses

    from jaxloco.sim import programs

    monkeypatch.setenv(programs.ENV_SWITCH, str(tmp_path))
    keys2 = jnp.stack([jax.random.PRNGKey(0)] * 2)

    def key(sc, n=2, dtype=jnp.float64):
        p = jax.tree_util.tree_map(lambda x: jnp.asarray(x, dtype), _params(n))
        return programs.program_key(sc, (p, keys2[:1].repeat(n, 0)), "test")

    base = key(standing_scenario(horizon=10, substeps=2))
    assert base is not None and base == key(standing_scenario(horizon=10, substeps=2))
    assert len({base, key(standing_scenario(horizon=12, substeps=2)), key(standing_scenario(horizon=10, substeps=2), 3),
                key(standing_scenario(horizon=10, substeps=2), dtype=jnp.float32)}) == 4

    def summarize_here(params, records, final):
        return {}

    mine = dataclasses.replace(standing_scenario(horizon=10, substeps=2), summarize=summarize_here)
    assert key(mine) is None
    monkeypatch.setenv(programs.ENV_SWITCH, "off")
    assert programs.cache_dir() is None and key(standing_scenario(horizon=10, substeps=2)) is None


def test_mujoco_warnings_stay_out_of_the_working_directory(tmp_path, monkeypatch):
    """An unstable simulation makes MuJoCo log a warning; in the suite (conftest) the log
    goes to a temporary directory, not to MUJOCO_LOG.TXT in the working directory."""
    monkeypatch.chdir(tmp_path)
    m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><body><joint/><geom size=".1"/></body></worldbody></mujoco>')
    d = mujoco.MjData(m)
    d.qvel[:] = 1e300
    mujoco.mj_step(m, d)
    assert d.warning[mujoco.mjtWarning.mjWARN_BADQVEL].number >= 1
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()
    logfile = mujoco.MjLogConfig.get().logfile
    assert os.path.isabs(logfile) and "Nan, Inf or huge value in QVEL" in open(logfile).read()


def test_auto_backend_is_native_on_cpus_and_mjx_on_accelerators():
    from jaxloco.sim import backend

    assert backend.resolve("auto", on="cpu") == "native"
    assert backend.resolve("auto", on="gpu") == "mjx" and backend.resolve("auto", on="tpu") == "mjx"
    assert backend.resolve("mjx", on="cpu") == "mjx" and backend.resolve("native", on="gpu") == "native"
    assert backend.resolve("auto") == ("native" if jax.default_backend() == "cpu" else "mjx")
    with pytest.raises(ValueError, match="backend: expected one of native, mjx, auto, got 'warp'"):
        backend.resolve("warp")
    assert backend.resolved({"x": 1}) == {"x": 1}


def test_a_sweep_records_the_backend_auto_picked(tmp_path):
    """The spec's "auto" is resolved when the spec is read: the table's `backend` column,
    and the simulator the analysis runs on, say which backend ran; a bad name is a one-line
    spec error."""
    from jaxloco.sim import backend
    from jaxloco.sweep.spec import spec_from_dict

    spec = {"sweep": {"analysis": "octopus.step_climb", "name": "auto"}, "fixed": {"backend": "auto"},
            "params": {"mu": [0.8]}}
    assert spec_from_dict(spec).fixed["backend"] == backend.resolve("auto")
    with pytest.raises(SpecError, match=r"fixed\.backend: .*'warp'"):
        spec_from_dict({**spec, "fixed": {"backend": "warp"}})
