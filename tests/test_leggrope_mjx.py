"""`leggrope.fragile_walk` on MJX: its MJX variant (`scenarios.make_scenario(mjx_contacts=True)`)
and how far a sweep on `backend = "mjx"` agrees with the same sweep on native MuJoCo.

Oracles: the native MuJoCo sweep of the same rows, within the tolerances that
docs/simulation.md states for the leg-grope walk (the variant's contacts differ: no
no-slip solver, pyramidal cone); the MuJoCo model's own options (the variant changes
nothing but the contact options). One MJX compile: the sweep's rollout (2 rows, 2 s).
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from jaxloco.robots.leggrope import model, scenarios, sim_analysis
from jaxloco.sweep import run as run_sweep

HORIZON = 2.0  # [s]: the first body move (A') and the unloading of L2 (B')
# docs/simulation.md, leg-grope walk: native vs MJX over the first 2 s of a walk
TOLERANCE = {
    "max_attitude_change": 0.005,  # [rad]
    "max_abs_roll": 0.005,  # [rad]
    "max_abs_pitch": 0.005,  # [rad]
    "max_normal_ratio": 0.05,
    "max_foothold_offset": 0.004,  # [m]
}
EQUAL = ("status", "success", "completed_gropes", "collapses_met", "fell", "off_foothold")


def _spec(tmp_path, backend):
    return {
        "sweep": {"analysis": "leggrope.fragile_walk", "name": f"agree-{backend}", "chunk_size": 2,
                  "output": str(tmp_path / backend), "formats": ["parquet"]},
        "fixed": {"horizon": HORIZON, "nthread": 1, "backend": backend, "theta": float(np.pi / 12)},
        "params": {"r_ref_factor": [0.4, 0.5]},
    }


@pytest.fixture(scope="module")
def tables(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("agree")
    return {b: run_sweep(_spec(tmp, b), progress=False).table for b in ("mjx", "native")}


def test_the_mjx_variant_changes_only_the_contact_options():
    native, _ = scenarios.build_model()
    variant, _ = scenarios.build_model(mjx_contacts=True)
    assert native.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC and native.opt.noslip_iterations == model.NOSLIP_ITERATIONS
    assert variant.opt.cone == mujoco.mjtCone.mjCONE_PYRAMIDAL and variant.opt.noslip_iterations == 0
    assert variant.opt.impratio == model.MJX_IMPRATIO and native.opt.impratio == model.IMPRATIO
    assert variant.numeric("max_contact_points").data.tolist() == [model.MJX_MAX_CONTACTS] and native.nnumeric == 0
    for name in ("nq", "nv", "nu", "ngeom", "nmocap", "nsensordata"):
        assert getattr(variant, name) == getattr(native, name), name
    np.testing.assert_array_equal(variant.geom_friction, native.geom_friction)
    np.testing.assert_array_equal(variant.geom_solref, native.geom_solref)
    assert variant.opt.timestep == native.opt.timestep and variant.opt.integrator == native.opt.integrator


def test_the_analysis_picks_the_variant_by_backend():
    plain = {"horizon": 1.0, "numbering": "mirrored"}
    assert sim_analysis.scenario({**plain, "backend": "mjx"}).name == "leggrope.fragile_slope_mjx"
    assert sim_analysis.scenario({**plain, "backend": "native"}).name == "leggrope.fragile_slope"


def test_a_sweep_runs_on_mjx_and_says_so(tables):
    table = tables["mjx"]
    assert table.num_rows == 2
    assert set(table.column("backend").to_pylist()) == {"mjx"}
    assert set(tables["native"].column("backend").to_pylist()) == {"native"}
    assert "MJX" in sim_analysis.summarize(table).title
    assert "native MuJoCo" in sim_analysis.summarize(tables["native"]).title


def test_mjx_agrees_with_native_mujoco_within_the_stated_tolerance(tables):
    """The first 2 s of two walks (R_ref factor 0.4 and 0.5 on the pi/12 slope): the same
    statuses and counts, attitudes within 0.005 rad, the largest normal force / R_ref
    within 0.05, toe offsets from their pads within 4 mm (measured: 0.002 rad, 0.019,
    2.1 mm). min_margin is not compared: it counts a toe as support above 1 N, and L2's
    toe, unloading in B', crosses that threshold at slightly different times."""
    mjx, native = (tables[b].to_pydict() for b in ("mjx", "native"))
    for name in EQUAL:
        assert mjx[name] == native[name], name
    for name, tol in TOLERANCE.items():
        np.testing.assert_allclose(mjx[name], native[name], rtol=0.0, atol=tol, err_msg=name)
    assert max(native["max_attitude_change"]) > 0.005  # the robot moves: a real comparison
