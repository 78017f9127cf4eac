"""T² Snake-3 on MJX: the MJX variant of every simulated analysis' model
(`scenarios.mjx_variant`; the operations' gripper a pulling tendon) and a `snake.contact`
sweep on backend "mjx" against the same sweep on native MuJoCo.

Oracles: MJX's own `put_model` (what it can simulate), the native model (indices and
physics the variant keeps), native MuJoCo (the metrics). The MJX sweep is this module's
one MJX compile: its settling runs are padded to the pushes' batch, so one program
serves both. `snake.reach` on MJX is checked in tests/test_snake_mjx_tune.py (its
forward-mode loss against native MuJoCo on both grounds); `snake.table3` runs the
contact experiment's controller on the same variant without the plate. The tolerances
and the measured differences are in docs/simulation.md.
"""

from __future__ import annotations

import contextlib
import io

import mujoco
import numpy as np
import pytest

from jaxloco.robots.snake import contact, operations, params, scenarios, sim_analysis, table3
from jaxloco.sweep import run as run_sweep

with contextlib.redirect_stdout(io.StringIO()):  # mujoco.mjx prints "Failed to import warp" without NVIDIA Warp
    from mujoco import mjx
from mujoco.mjx._src import collision_driver

# ------------------------------------------------------------------ the MJX variants
RAMP, HOLD, SETTLE = 1.5, 0.3, 0.1  # [s] the short contact experiment of the MJX sweep


def _pairs(m) -> set[tuple[str, str]]:
    """The geom pairs MJX collides (by name, wheel cylinders as "wheel")."""
    def name(g):
        n = m.geom(g).name
        return "wheel" if n.startswith("wheel") else n
    return {tuple(sorted((name(a), name(b)))) for a, b, _ in collision_driver.geom_pairs(m)}


def _variants():
    """(analysis, native model, MJX model) of every simulated snake analysis' scenario,
    built by the analyses' own functions (tiny horizons: only the models are used)."""
    plain = {"ramp": 0.5, "settle": 0.1, "feedback": 0, "twist_compliance": 0.0}
    reach = {"ground": "box", "horizon": 0.1, "settle": 0.1}
    out = [("snake.reach", sim_analysis.REACH.simulate.scenario({**reach, "backend": "native"}).model,
            sim_analysis.REACH.simulate.scenario({**reach, "backend": "mjx"}).model),
           ("snake.table3", table3.TABLE3.simulate.scenario({**plain, "backend": "native"}).model,
            table3.TABLE3.simulate.scenario({**plain, "backend": "mjx"}).model),
           ("snake.contact", contact.contact_scenario(0.5, 0.1, 0.1).model,
            contact.contact_scenario(0.5, 0.1, 0.1, "mjx").model)]
    for name, op in operations.OPERATIONS.items():
        out.append((f"snake.operations {name}", operations.operation_scenario(op.fixture, 0.1).model,
                    operations.operation_scenario(op.fixture, 0.1, backend="mjx").model))
    return out


def test_mjx_cannot_simulate_the_native_model():
    """Why the variant: the wheels on the ground box (and the gripper's adhesion)."""
    cylinder_box = r"\(mjtGeom.mjGEOM_CYLINDER, mjtGeom.mjGEOM_BOX\) collisions not implemented"
    with pytest.raises(NotImplementedError, match=cylinder_box):
        mjx.put_model(scenarios.build_model()[0])
    with pytest.raises(NotImplementedError, match="mjTRN_BODY"):
        m = scenarios.build_model(operations.PIPE)[0]
        m.geom_contype[:] = 0  # past the collision check: the adhesion actuator
        mjx.put_model(m)


def test_every_analysis_has_an_mjx_variant_with_the_native_layout():
    wheel_floor = {("terrain/ground", "wheel")}
    objects = {"snake.contact": {("gripper", "plate")},
               "snake.operations pick": {("gripper", "pipe_main"), ("gripper", "pipe_branch"),
                                         ("pipe_main", "terrain/ground"), ("pipe_branch", "terrain/ground")},
               "snake.operations valve": {("gripper", "valve")},
               "snake.operations door": {("door", "gripper"), ("gripper", "knob")}}
    for name, native, m in _variants():
        mjx.put_model(m)  # no NotImplementedError
        assert _pairs(m) == wheel_floor | objects.get(name, set()), name
        for field in ("ngeom", "nbody", "nq", "nv", "nu", "nmocap", "nsensordata"):
            assert getattr(m, field) == getattr(native, field), (name, field)
        assert [m.geom(g).name for g in range(m.ngeom)] == [native.geom(g).name for g in range(native.ngeom)]
        robot = slice(0, m.nu - (1 if "operations" in name else 0))  # the grip actuator differs
        bodies = np.arange(m.nbody) != m.body("terrain/ground").id  # the ground plane has no volume, no mass
        for field in ("body_mass", "body_inertia"):
            np.testing.assert_array_equal(getattr(m, field)[bodies], getattr(native, field)[bodies], err_msg=name)
        for field in ("geom_friction", "dof_damping", "dof_armature", "jnt_range"):
            np.testing.assert_array_equal(getattr(m, field), getattr(native, field), err_msg=f"{name} {field}")
        assert m.opt.timestep == native.opt.timestep and m.opt.integrator == native.opt.integrator
        for field in ("actuator_gainprm", "actuator_biasprm", "actuator_trnid", "actuator_ctrlrange"):
            np.testing.assert_array_equal(getattr(m, field)[robot], getattr(native, field)[robot], err_msg=name)
        assert m.opt.noslip_iterations == 0 and m.opt.cone == native.opt.cone
    # the grip (operations._mjx_grip): a tendon pulled with GRIP_FORCE up to GRIP_REACH beyond touching, 0 from
    # GRIP_RELEASE further on (the actuator's length is minus the tendon's)
    grip = operations.operation_scenario(operations.PIPE, 0.1, backend="mjx").model.actuator("gripper")
    assert grip.trntype[0] == mujoco.mjtTrn.mjTRN_TENDON and grip.gear[0] == -1.0
    assert grip.gaintype[0] == mujoco.mjtGain.mjGAIN_AFFINE and list(grip.forcerange) == [0.0, operations.GRIP_FORCE]
    touch = params.GRIPPER_RADIUS + operations.PIPE_RADIUS
    reach, release = operations.GRIP_REACH, operations.GRIP_RELEASE
    for gap, share in ((0.0, 1.0), (reach, 1.0), (reach + 0.5 * release, 0.5), (reach + release, 0.0), (0.1, 0.0)):
        force = np.clip(grip.gainprm[0] + grip.gainprm[1] * -(touch + gap), *grip.forcerange)
        assert force == pytest.approx(share * operations.GRIP_FORCE, abs=1e-9), gap


# --------------------------------------------------------------- the contact sweep
def _sweep(backend: str, tmp_path):
    spec = {"sweep": {"analysis": "snake.contact", "name": backend, "chunk_size": 1, "formats": ["parquet"],
                      "output": str(tmp_path / backend)},
            "fixed": {"ramp": RAMP, "hold": HOLD, "settle": SETTLE, "nthread": 1, "backend": backend},
            "params": {"posture": ["ii"]}}
    return run_sweep(spec, progress=False)


@pytest.fixture(scope="module")
def sweeps(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("contact")
    return {b: _sweep(b, tmp) for b in ("native", "mjx")}


def test_the_contact_sweep_runs_on_mjx_and_agrees_with_native_mujoco(sweeps):
    """The same spec on both simulators: the table records which ran; the forces agree
    within the tolerance of docs/simulation.md (1 %, at least 0.1 N; measured: 0.02 N), the
    tilt within 0.1 mrad."""
    cols = {b: r.table.to_pydict() for b, r in sweeps.items()}
    assert cols["native"]["backend"] == ["native"] and cols["mjx"]["backend"] == ["mjx"]
    assert cols["mjx"]["status"] == ["ok"] == cols["native"]["status"]
    for f in ("fx", "fy", "fz"):
        native, on_mjx = cols["native"][f][0], cols["mjx"][f][0]
        assert native > 5.0, (f, native)  # a real push
        assert on_mjx == pytest.approx(native, rel=0.01, abs=0.1), f
    assert cols["mjx"]["max_tilt"][0] == pytest.approx(cols["native"]["max_tilt"][0], abs=1e-4)
    key = ("ii", RAMP, HOLD, SETTLE, "mjx", contact.L_BEND, 0.0, contact.TWIST_COMPLIANCE)
    assert key in contact._SETTLED  # the plate placed from an MJX settling (of the twisting base)
