"""`titan.walk` on both simulators: the model's MJX variant (`scenarios.mjx_variant`),
one tiny sweep end to end on `backend = "mjx"` and the same rows on native MuJoCo, metric
by metric within the tolerances of docs/simulation.md (one gait cycle, two rows on the
exact map of the Sec. 7 grid, two starts; the native sweep runs first and compiles the
planner, the MJX sweep compiles its rollout with XLA's optimisations, `xla_optimized`).
Oracle: MuJoCo's C engine running the
same plan with the same controller code; the MJX variant differs in the links' and
trunk's collisions, which these walks never make."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from xla_optimized import optimized

from jaxloco.errors import SpecError
from jaxloco.robots.titan import scenarios, sim_analysis
from jaxloco.sweep import run as run_sweep
from jaxloco.sweep import spec_from_dict

# |native - mjx| allowed per metric (docs/simulation.md, "TITAN XI"): ~5x the largest
# difference measured over one cycle on five rows (benchmarks/titan_mjx_agreement.py)
TOLERANCE = {
    "sim_min_nesm": 2e-4,  # [m]
    "distance": 1e-3,  # [m]
    "max_touchdown_error": 1e-3,  # [m]
    "min_swing_clearance": 1e-3,  # [m]
    "max_cycle_error": 1e-3,  # [m]
    "max_path_deviation": 1e-3,  # [m]
    "foot_slip": 5e-3,  # [m]
    "max_tilt": 1e-3,  # [rad]
}


def _spec(backend: str) -> dict:
    return {"sweep": {"analysis": "titan.walk", "name": f"walk_{backend}", "formats": ["parquet"]},
            "fixed": {"n_cycles": 1, "nthread": 1, "backend": backend, "map": "exact"},
            "params": {"start_jitter": [0.0, 0.3]}}


@pytest.fixture(scope="module")
def tables(tmp_path_factory):
    out = tmp_path_factory.mktemp("titan_mjx")
    native = run_sweep(_spec("native"), output=out / "native", progress=False).table.to_pydict()
    with optimized():
        mjx = run_sweep(_spec("mjx"), output=out / "mjx", progress=False).table.to_pydict()
    return {"native": native, "mjx": mjx}


def test_the_mjx_variant_collides_the_feet_only():
    native, _ = scenarios.build_model()
    mjx_model, _ = scenarios.build_model(backend="mjx")
    assert native.ngeom == mjx_model.ngeom
    for i in range(native.ngeom):
        name = native.geom(i).name
        link = name in scenarios.ROBOT_LINK_GEOMS
        assert (mjx_model.geom_contype[i] == 0) == (link or native.geom_contype[i] == 0), name
    assert native.geom_contype[native.geom("trunk").id] != 0  # native keeps the trunk and links
    assert mjx_model.geom_contype[mjx_model.geom("fl_foot").id] != 0
    i = mujoco.mj_name2id(mjx_model, mujoco.mjtObj.mjOBJ_NUMERIC, "max_contact_points")
    assert mjx_model.numeric_data[mjx_model.numeric_adr[i]] == scenarios.MJX_MAX_CONTACTS
    assert mujoco.mj_name2id(native, mujoco.mjtObj.mjOBJ_NUMERIC, "max_contact_points") == -1
    with pytest.raises(ValueError, match="backend: expected one of native, mjx, got 'warp'"):
        scenarios.build_model(backend="warp")


def test_a_bad_backend_is_a_one_line_spec_error():
    with pytest.raises(SpecError) as info:
        spec_from_dict({**_spec("native"), "fixed": {"backend": "gpu"}})
    assert "fixed.backend: 'gpu' is not one of 'native', 'mjx', 'auto'" in str(info.value)
    assert "\n" not in str(info.value)


def test_the_walk_sweep_runs_on_mjx(tables):
    mjx = tables["mjx"]
    assert set(mjx["backend"]) == {"mjx"} and set(tables["native"]["backend"]) == {"native"}
    assert mjx["status"] == ["ok", "ok"], mjx["status"]
    assert all(mjx["success"]) and not any(mjx["swing_collision"]) and not any(mjx["feet_on_frames"])
    assert min(mjx["distance"]) > 0.9  # [m] one cycle of the standard stride, 2 L_std = 1 m


def test_native_and_mjx_walks_agree(tables):
    native, mjx = tables["native"], tables["mjx"]
    assert native["status"] == mjx["status"] and native["success"] == mjx["success"]
    for name in ("planned", "plan_min_nesm", "plan_failures", "plan_modifications"):
        assert native[name] == mjx[name], name  # the same plans
    for name, tol in TOLERANCE.items():
        diff = np.abs(np.asarray(native[name]) - np.asarray(mjx[name]))
        assert (diff <= tol).all(), (name, native[name], mjx[name])
    # the walks are not trivial: the metrics move well beyond the tolerances
    assert min(native["distance"]) > 100 * TOLERANCE["distance"]
    assert min(native["foot_slip"]) > 5 * TOLERANCE["foot_slip"]


def test_the_backend_selects_the_scenario():
    field = sim_analysis.grid_field(2.0)
    native = sim_analysis.walk_scenario(6, 0.2, field, "native")
    assert native is sim_analysis.walk_scenario(6, 0.2, field, "native")  # kept: one compile per sweep
    mjx = sim_analysis.walk_scenario(6, 0.2, field, "mjx")
    assert mjx is not native and mjx.model.geom_contype[mjx.model.geom("trunk").id] == 0
