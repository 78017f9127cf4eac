"""`octopus.terrain_classification`: the terrain-exploration rules (Cases 1-3) at their
sigma boundaries, the ground truth, H_EST errors, reachability, batching (vmap == loop)
and a small sweep through the sweep engine with its summary."""

from functools import cache

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from compile_count import run_counting

from jaxloco import analysis
from jaxloco.robots.octopus import analysis as oa
from jaxloco.robots.octopus.params import ROLLER_RADIUS
from jaxloco.sweep import SpecError, chunks, run, spec_from_dict

DEFAULTS = {p.name: p.default for p in oa.PARAMS}
SWEEPABLE = [p.name for p in oa.PARAMS if p.sweepable]
PAD = 16  # every call is padded to this many rows and uses SAMPLES: one compilation
SAMPLES = 64


@cache
def _batch(samples: int):
    fn = oa.TERRAIN_CLASSIFICATION.batch_fn({**DEFAULTS, "samples": samples})
    return chunks.jitted_batch(oa.TERRAIN_CLASSIFICATION.name, fn)  # as a sweep jits it


def _swept(rows: list[dict]) -> dict[str, jax.Array]:
    full = [{**DEFAULTS, **r} for r in rows] + [DEFAULTS] * (PAD - len(rows))
    return {n: jnp.asarray([r[n] for r in full], jnp.int32 if n == "terrain" else jnp.float64) for n in SWEEPABLE}


def _rows(rows: list[dict], samples: int = SAMPLES, seed: int = 0) -> dict[str, np.ndarray]:
    """Metrics of `rows` (dicts of parameter overrides; the rest at the defaults)."""
    assert len(rows) <= PAD
    swept = _swept(rows)
    keys = jax.vmap(jax.random.PRNGKey)(jnp.arange(seed, seed + PAD))
    out = _batch(samples)(swept, keys)
    return {k: np.asarray(v)[: len(rows)] for k, v in out.items()}


def _case(out, i):
    """The class every sample of row i got (asserting they agree)."""
    fracs = np.array([out[f"frac_{c}"][i] for c in oa.CLASSES])
    assert np.isclose(fracs.max(), 1.0), fracs
    return oa.CLASSES[int(np.argmax(fracs))]


# ------------------------------------------------------------------ the sigma boundaries
@pytest.mark.parametrize(
    "terrain, height, sigma, expect, accurate",
    [
        # sigma_1 separates flat from a step, up and down (inside the 2-5 cm grey band of
        # the ground truth both answers are right)
        (oa.STEP_UP, 0.049, (0.05, 0.45, 0.45), "flat", True),
        (oa.STEP_UP, 0.051, (0.05, 0.45, 0.45), "up", True),
        (oa.STEP_DOWN, 0.049, (0.05, 0.45, 0.45), "flat", True),
        (oa.STEP_DOWN, 0.051, (0.05, 0.45, 0.45), "down", True),
        # a 1 cm step must be flat and a 10 cm one a step: too large a sigma_1 is wrong
        (oa.STEP_UP, 0.01, (0.02, 0.45, 0.45), "flat", True),
        (oa.STEP_UP, 0.10, (0.12, 0.45, 0.45), "flat", False),
        # sigma_2 / sigma_3 bound what is reported climbable / descendable
        (oa.STEP_UP, 0.449, (0.05, 0.45, 0.45), "up", True),
        (oa.STEP_UP, 0.451, (0.05, 0.45, 0.45), "undetectable", True),
        (oa.STEP_DOWN, 0.449, (0.05, 0.45, 0.45), "down", True),
        (oa.STEP_DOWN, 0.451, (0.05, 0.45, 0.45), "undetectable", True),
        # a sigma below the robot's capability (0.45 m) rejects steps it could take ...
        (oa.STEP_UP, 0.299, (0.05, 0.3, 0.45), "up", True),
        (oa.STEP_UP, 0.301, (0.05, 0.3, 0.45), "undetectable", False),
        (oa.STEP_DOWN, 0.299, (0.05, 0.45, 0.3), "down", True),
        (oa.STEP_DOWN, 0.301, (0.05, 0.45, 0.3), "undetectable", False),
        # ... and one above it reports steps it cannot take as climbable
        (oa.STEP_UP, 0.5, (0.05, 0.6, 0.45), "up", False),
        (oa.STEP_DOWN, 0.5, (0.05, 0.45, 0.6), "down", False),
        # slopes: the rise in the level frame is compared; a 0.3 m rise (24 deg) is
        # climbable, a 0.4 m rise (33 deg > 30 deg) is not, though below sigma_2
        (oa.SLOPE_UP, 0.3, (0.05, 0.45, 0.45), "up", True),
        (oa.SLOPE_UP, 0.4, (0.05, 0.45, 0.45), "up", False),
        (oa.SLOPE_DOWN, 0.3, (0.05, 0.45, 0.45), "down", True),
        (oa.SLOPE_UP, 0.449, (0.05, 0.3, 0.45), "undetectable", True),
    ],
)
def test_case_at_sigma_boundaries(terrain, height, sigma, expect, accurate):
    row = {"terrain": terrain, "height": height, "noise": 0.0}
    row.update(zip(("sigma1", "sigma2", "sigma3"), sigma))
    out = _rows([row])
    assert _case(out, 0) == expect
    assert out["accuracy"][0] == (1.0 if accurate else 0.0)
    assert out["status"][0] == 0


def test_noise_free_well_separated_terrain_is_always_right():
    rows = [{"terrain": oa.FLAT}]
    rows += [{"terrain": t, "height": h} for t in (oa.STEP_UP, oa.STEP_DOWN) for h in (0.1, 0.2, 0.3, 0.4)]
    rows += [{"terrain": t, "height": h} for t in (oa.SLOPE_UP, oa.SLOPE_DOWN) for h in (0.1, 0.3)]
    rows += [{"terrain": oa.ROUGH, "height": 0.005}, {"terrain": oa.STEP_UP, "height": 0.6},
             {"terrain": oa.SLOPE_UP, "height": 0.6}]
    expect = ["flat"] + ["up"] * 4 + ["down"] * 4 + ["up", "up", "down", "down", "flat"] + ["undetectable"] * 2
    out = _rows([{**r, "noise": 0.0} for r in rows])
    np.testing.assert_array_equal(out["accuracy"], 1.0)
    assert [_case(out, i) for i in range(len(rows))] == expect
    # 5 mm of sensing noise is far below the 50 mm separation from every threshold
    noisy = _rows(rows)
    assert noisy["accuracy"].min() >= 0.98


def test_ground_truth_definition():
    v = {k: jnp.asarray(DEFAULTS[k], jnp.float64) for k in ("flat_tol", "step_min", "climb_max", "descend_max",
                                                          "slope_max")}

    def truth(d, angle=0.0, slope=False):
        ok = np.asarray(oa.ground_truth(jnp.asarray(d), jnp.asarray(angle), jnp.asarray(slope), v))
        return {c for c, o in zip(oa.CLASSES, ok) if o}

    assert truth([0.01, -0.01]) == {"flat"}
    assert truth([0.03, 0.04]) == {"flat", "up"}  # grey band
    assert truth([0.10, 0.45]) == {"up"}
    assert truth([-0.3, -0.2]) == {"down"}
    assert truth([0.46, 0.2]) == {"undetectable"}  # beyond the climbing capability
    assert truth([0.10, -0.10]) == {"undetectable"}  # twisted
    assert truth([0.10, 0.01]) == {"undetectable"}  # one side level, the other a step
    assert truth([0.3, 0.3], angle=0.55, slope=True) == {"undetectable"}  # 31.5 deg
    assert truth([0.3, 0.3], angle=0.55, slope=False) == {"up"}


def test_h_est_error_and_step_edge():
    rows = [{"terrain": oa.STEP_UP, "height": 0.3, "noise": 0.0},
            {"terrain": oa.STEP_UP, "height": 0.3, "noise": 0.005},
            {"terrain": oa.SLOPE_UP, "height": 0.2, "noise": 0.0},
            {"terrain": oa.STEP_UP, "height": 0.3, "edge": 0.64, "noise": 0.0}]
    out = _rows(rows)
    assert out["h_true"][0] == pytest.approx(0.3, abs=1e-12)
    assert abs(out["h_est_bias"][0]) < 1e-12 and out["h_est_rms"][0] < 1e-12
    # H_EST = (z1 + z2 - z3 - z4) / 2 of four independent readings has std = noise
    assert out["h_est_rms"][1] == pytest.approx(0.005, rel=0.25)
    assert abs(out["h_est_bias"][1]) < 0.001
    # on a slope the level-frame rise is the height; T_P is exact without noise
    assert out["h_true"][2] == pytest.approx(0.2, abs=1e-12)
    assert out["slope_angle"][2] == pytest.approx(np.arcsin(0.2 / oa.BASELINE))
    assert out["pitch_rms"][2] < 1e-9
    # front rollers 22 mm short of the edge rest on its corner, lower than on top
    dx = 0.64 - oa.FRONT_X
    assert out["h_true"][3] == pytest.approx(0.3 + np.sqrt(ROLLER_RADIUS**2 - dx**2) - ROLLER_RADIUS)


def test_rough_terrain_and_reach():
    out = _rows([{"terrain": oa.ROUGH, "height": 0.2}, {"terrain": oa.ROUGH, "height": 0.5},
                 {"terrain": oa.STEP_DOWN, "height": 0.7}])
    fr = np.array([out[f"frac_{c}"] for c in oa.CLASSES])
    tr = np.array([out[f"truth_{c}"] for c in oa.CLASSES])
    np.testing.assert_allclose(fr[:, :2].sum(axis=0), 1.0)
    # rough terrain is mostly twisted (undetectable) and sometimes a step either way
    assert tr[0, 0] > 0.5 and tr[2, 0] > 0 and tr[3, 0] > 0
    assert 0.6 < out["accuracy"][0] < 1.0 and out["status"][0] == 0
    # 0.5 m bumps under a rear roller fold the arm beyond reach in some samples
    assert 0 < out["reachable"][1] < 1 and out["status"][1] == 1 and np.isfinite(out["accuracy"][1])
    # a 0.7 m deep step is out of reach of the front arms
    assert out["reachable"][2] == 0 and out["status"][2] == 2 and np.isnan(out["accuracy"][2])
    assert out["reach_margin"][2] < 0


def test_vmap_equals_loop():
    rows = [{"terrain": 0}, {"terrain": 1, "height": 0.2}, {"terrain": 2, "height": 0.3, "sigma1": 0.1},
            {"terrain": 3, "height": 0.1, "sigma2": 0.3}, {"terrain": 5, "height": 0.05, "noise": 0.01}]
    batched = _rows(rows, seed=11)
    swept = _swept(rows)
    keys = jax.vmap(jax.random.PRNGKey)(jnp.arange(11, 11 + PAD))
    row_fn = jax.jit(oa.run_row, static_argnums=2)
    for i in range(len(rows)):
        v = {k: x[i] for k, x in swept.items()}
        one = row_fn(v, keys[i], SAMPLES)
        for name, value in one.items():
            np.testing.assert_allclose(np.asarray(value), batched[name][i], rtol=1e-12, atol=1e-15, err_msg=name)
    # the samples of a row: run_row's vmap equals a loop over run_sample
    v = {k: x[4] for k, x in swept.items()}
    sample = jax.jit(oa.run_sample)
    loop = [sample(v, k) for k in jax.random.split(keys[4], SAMPLES)]
    assert batched["accuracy"][4] == pytest.approx(np.mean([float(s["correct"]) for s in loop]), abs=1e-12)
    assert batched["h_est_rms"][4] == pytest.approx(np.sqrt(np.mean([float(s["h_err"]) ** 2 for s in loop])))
    frac_up = np.mean([int(s["case"]) == 2 for s in loop])
    assert batched["frac_up"][4] == pytest.approx(frac_up, abs=1e-12)


# ------------------------------------------------------------------ through the sweep engine
def test_small_sweep_and_summary(tmp_path):
    spec = {
        "sweep": {"analysis": "octopus.terrain_classification", "name": "t", "chunk_size": 2},
        "fixed": {"samples": 16, "terrain": oa.STEP_UP, "noise": 0.0},
        "params": {"sigma2": [0.3, 0.45], "height": [0.2, 0.4]},
    }
    res, compiles = run_counting(run, spec_from_dict(spec), output=tmp_path / "octo", progress=False)
    compiles.assert_compiled_once()  # two chunks, one compiled program
    t = res.table.to_pydict()
    assert t["sigma2"] == [0.3, 0.3, 0.45, 0.45] and t["height"] == [0.2, 0.4, 0.2, 0.4]
    assert t["status"] == ["ok"] * 4
    assert t["accuracy"] == [1.0, 0.0, 1.0, 1.0]  # sigma_2 = 0.3 rejects the climbable 0.4 m step
    assert t["frac_undetectable"][1] == 1.0 and t["frac_up"][3] == 1.0
    s = res.summary
    assert s is not None and res.summary_error is None
    assert s.columns == ("s1", "s2", "s3", "up", "all")
    assert [r[:4] for r in s.rows] == [("0.05", "0.3", "0.45", "0.500"), ("0.05", "0.45", "0.45", "1.000")]
    assert any("best setting: sigma = (0.05, 0.45, 0.45)" in n for n in s.notes)


def test_registered_and_spec_errors():
    a = analysis.get("octopus.terrain_classification")
    assert a is oa.TERRAIN_CLASSIFICATION and a.x64 and a.executor == "jax"
    assert all(p.doc for p in a.params) and all(m.doc for m in a.metrics)
    assert {"sigma1", "sigma2", "sigma3", "terrain", "height", "noise", "samples"} <= {p.name for p in a.params}
    base = {"sweep": {"analysis": "octopus.terrain_classification"}}
    with pytest.raises(SpecError, match="terrain"):
        spec_from_dict({**base, "params": {"terrain": [1, 6]}})
    with pytest.raises(SpecError, match="samples"):
        spec_from_dict({**base, "params": {"samples": [8, 16]}})
    with pytest.raises(SpecError, match="height"):
        spec_from_dict({**base, "params": {"height": [0.1, 0.8]}})


def test_sweep_file_is_valid():

    from jaxloco.sweep import load_spec

    spec = load_spec("octopus_sigma")
    assert spec.analysis is oa.TERRAIN_CLASSIFICATION and spec.n_rows == 972
