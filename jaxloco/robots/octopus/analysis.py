"""`octopus.terrain_classification`: how well the terrain-exploration rules (paper,
"Terrain exploration", Cases 1-3 and Eq. 9; `kinematics.explore_terrain`) classify the
terrain in front of the robot for a choice of the thresholds sigma_1, sigma_2, sigma_3.

Model of one Monte-Carlo sample
-------------------------------
The robot stands on its crawlers with the four arm endpoints (EPRAs, roller centres) at the
Table 2 target positions in {R} (front arms at x = 0.618 m, rear arms at x = -0.121 m,
y = +-0.399 m). Its crawlers rest on level ground, {R} is BASE_HEIGHT above it and level,
except on slopes. The terrain type (`terrain`, an int code, `TERRAINS`) and `height` put
the endpoints on the ground:
  0 flat        every roller on the ground (height unused);
  1 step_up     a step of `height` with its edge at x = `edge` in {R}: the front rollers
                sit `height` higher (a roller within one radius of the edge rests on the
                corner instead);
  2 step_down   the same, the front rollers `height` lower;
  3 slope_up    the robot stands on a plane rising ahead; every roller lies on it, the
                endpoints stay at the Table 2 targets in {R} and the IMU reads the plane's
                pitch (A_P > 0). `height` is the rise between the rear and the front
                endpoints: sin(angle) = height / 0.739 m;
  4 slope_down  the same, falling ahead (A_P < 0);
  5 rough       level ground with an independent bump/hollow of uniform height in
                [-height, height] under each roller (drawn per sample).
Each endpoint target goes through the closed-form IK and back through the FK (Eqs. 1-6;
a sample with an endpoint out of reach is left out of the row's fractions and means, and
the row's status says so; e.g. rough bumps of 0.4 m under a rear roller); the sensed
endpoints add Gaussian noise of std `noise` [m] per coordinate, the sensed attitude
Gaussian noise of std `imu_noise` [rad]. `explore_terrain` with (sigma_1, sigma_2,
sigma_3) gives the case (0 undetectable, 1 flat, 2 up, 3 down) and H_EST (Eq. 9).

Ground truth (what the paper's rules *should* answer for that terrain)
----------------------------------------------------------------------
It is defined from the true (noise-free) contact geometry and reference constants of the
robot, never from the sigmas being swept. Let D = (z1 - z4, z2 - z3) be the true
front-minus-rear height differences of the rollers in the level frame {C} (for a step of
height h: D = (h, h); for a slope: the rise; for rough terrain: whatever was drawn). The
paper's meaning of the cases gives the set of correct answers:
  * flat (Case 1, "the height difference between four EPRAs is small"): correct when every
    |D_k| < step_min;
  * up (Case 2, "upward step or slope ... robot has the ability to get over steps lower
    than sigma_2"): correct when every D_k > flat_tol and D_k <= climb_max (the robot's
    real step-climbing capability) and, on a slope, the inclination <= slope_max (Table 3
    "climbing ability 30 deg");
  * down (Case 3, "downward step or pit ... ability to down steps lower than sigma_3"):
    correct when every D_k < -flat_tol and D_k >= -descend_max (and slope <= slope_max);
  * undetectable (the paper's fallback for "other kinds of situations": beyond the
    robot's capability, mixed or twisted contact heights): correct when none of the
    three above is.
So a real difference below flat_tol (2 cm) must be called flat, one of step_min (5 cm) or
more an obstacle; in the grey band between both answers count. Steps higher than the
robot can climb (climb_max 0.45 m, `params.SIGMA`'s reasoning: it climbs 0.40 m steps in
CLM) and slopes steeper than 30 deg should be "undetectable" (left to the operator).
The reference constants are parameters (not meant to be swept with the sigmas).

Per row, `samples` Monte-Carlo samples (vmapped) give the accuracy (fraction classified
into a correct class), the confusion (fraction classified as each class), the fraction for
which each class is correct, and the H_EST error (H_EST - true (z1 + z2 - z3 - z4) / 2).

Note for later (not implemented here): "climb success against sigma" needs the CLM
controller (`jaxloco/robots/octopus/clm.py`, being written). Once it exists, a separate
analysis (e.g. `octopus.clm_climb`: step height -> climbed or not) should give the robot's
real capability, which is what `climb_max` / `descend_max` stand for here; then the
ground truth "up" can be taken from that analysis instead of these constants.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco.analysis import Analysis, Metric, Summary
from jaxloco.robots.octopus import kinematics
from jaxloco.robots.octopus.params import (
    BASE_HEIGHT,
    PARAMETERS,
    ROLLER_RADIUS,
    TABLE2_TARGET,
    TERRAINS,
    default_params,
)

FLAT, STEP_UP, STEP_DOWN, SLOPE_UP, SLOPE_DOWN, ROUGH = range(len(TERRAINS))
# classes in kinematics.CASE_* order (0 undetectable, 1 flat, 2 up, 3 down)
CLASSES = ("undetectable", "flat", "up", "down")
# rear-to-front distance of the Table 2 target endpoints along x_R [m] (0.739)
BASELINE = float(TABLE2_TARGET[:2, 0].mean() - TABLE2_TARGET[2:, 0].mean())
FRONT_X = float(TABLE2_TARGET[0, 0])

_SHORT = ("flat", "up", "down", "slope+", "slope-", "rough")  # summary column headers
_CODES = ", ".join(f"{i} {n}" for i, n in enumerate(TERRAINS))

PARAMS = PARAMETERS.select(
    "sigma1", "sigma2", "sigma3", "terrain", "height", "edge", "noise", "imu_noise", "flat_tol", "step_min",
    "climb_max", "descend_max", "slope_max", "samples",
    # sensed terrain in front of the robot, not octopus.step_climb's MuJoCo step
    height={"default": 0.3, "doc": "step height; slope: rise from the rear to the front endpoints (0.739 m apart); "
            "rough: amplitude of the per-endpoint bumps", "hi": 0.7},
)

METRICS = (
    Metric("accuracy", "fraction of samples classified into a correct class (module docstring)"),
    Metric("frac_undetectable", "fraction of samples classified undetectable (case 0)"),
    Metric("frac_flat", "fraction of samples classified flat (Case 1)"),
    Metric("frac_up", "fraction of samples classified upward step or slope (Case 2)"),
    Metric("frac_down", "fraction of samples classified downward step or pit (Case 3)"),
    Metric("truth_undetectable", "fraction of samples for which undetectable is the correct answer"),
    Metric("truth_flat", "fraction of samples for which flat is a correct answer"),
    Metric("truth_up", "fraction of samples for which up is a correct answer"),
    Metric("truth_down", "fraction of samples for which down is a correct answer"),
    Metric("h_true", "mean true front-minus-rear height (z1 + z2 - z3 - z4) / 2 in {C}", "m"),
    Metric("h_est_bias", "mean of H_EST (Eq. 9, sensed) minus the true height", "m"),
    Metric("h_est_rms", "root mean square of H_EST minus the true height", "m"),
    Metric("slope_angle", "terrain inclination (slopes; 0 otherwise), > 0 rising ahead", "rad"),
    Metric("pitch_rms", "root mean square of T_P (Eq. 7) from the sensed minus T_P from the true endpoints",
           "rad"),
    Metric("reach_margin", "smallest IK reach margin of any arm in any sample (< 0: unreachable)", "m"),
    Metric("reachable", "fraction of samples with every endpoint within reach (the others are left out of "
           "every other fraction and mean)"),
)

STATUSES = (
    "ok",
    "partial: an arm endpoint out of reach in some samples (left out of the fractions)",
    "failed: an arm endpoint out of reach in every sample",
)


def _roller_centre(x: jax.Array, edge: jax.Array, low: jax.Array, high: jax.Array, r: float) -> jax.Array:
    """Height of a roller centre of radius r at x over a step profile: ground `low` for
    x < edge and `high` beyond it; near the edge the roller rests on the upper corner."""
    ground = jnp.where(x < edge, low, high)
    dx2 = (x - edge) ** 2
    corner = jnp.maximum(low, high) + jnp.sqrt(jnp.maximum(r * r - dx2, 0.0))
    return jnp.where(dx2 < r * r, jnp.maximum(ground + r, corner), ground + r)


def ground_truth(diffs: jax.Array, angle: jax.Array, is_slope: jax.Array, v: Mapping[str, jax.Array]) -> jax.Array:
    """The correct classes (bool (4,), `CLASSES` order) for true height differences
    diffs = (z1 - z4, z2 - z3) [m] in {C} and terrain inclination `angle` [rad]."""
    slope_ok = jnp.where(is_slope, jnp.abs(angle) <= v["slope_max"], True)
    flat = jnp.all(jnp.abs(diffs) < v["step_min"])
    up = jnp.all((diffs > v["flat_tol"]) & (diffs <= v["climb_max"])) & slope_ok
    down = jnp.all((diffs < -v["flat_tol"]) & (diffs >= -v["descend_max"])) & slope_ok
    undetectable = ~(flat | up | down)
    return jnp.stack([undetectable, flat, up, down])


def terrain_tips(v: Mapping[str, jax.Array], key: jax.Array) -> tuple[jax.Array, jax.Array]:
    """True endpoint positions in {R} (4, 3) [m] and the robot pitch A_P [rad] for the
    terrain of `v` (module docstring); `key` draws the rough-terrain bumps."""
    dt = v["height"].dtype
    targets = jnp.asarray(TABLE2_TARGET, dt)
    terrain, h = v["terrain"], v["height"]
    r = ROLLER_RADIUS
    x = targets[:, 0]
    zero = jnp.zeros((), dt)
    step_up = _roller_centre(x, v["edge"], zero, h, r)
    step_down = _roller_centre(x, v["edge"], zero, -h, r)
    bumps = r + jax.random.uniform(key, (4,), dt, -1.0, 1.0) * h
    centre = jnp.select(
        [terrain == STEP_UP, terrain == STEP_DOWN, terrain == ROUGH], [step_up, step_down, bumps], jnp.full(4, r, dt)
    )
    tips = targets.at[:, 2].set(centre - BASE_HEIGHT)
    angle = jnp.arcsin(jnp.clip(h / BASELINE, 0.0, 1.0))
    a_p = jnp.where(terrain == SLOPE_UP, angle, jnp.where(terrain == SLOPE_DOWN, -angle, zero))
    return tips, a_p


def run_sample(v: Mapping[str, jax.Array], key: jax.Array) -> dict[str, jax.Array]:
    """One Monte-Carlo sample for scalar parameter values `v`."""
    dt = v["height"].dtype
    k_terrain, k_tips, k_imu = jax.random.split(key, 3)
    params = default_params().astype(dt).with_(sigma=jnp.stack([v["sigma1"], v["sigma2"], v["sigma3"]]))
    tips, a_p = terrain_tips(v, k_terrain)
    zero = jnp.zeros((), dt)
    true_c = kinematics.to_level_frame(tips, a_p, zero)
    z = true_c[:, 2]
    diffs = jnp.stack([z[0] - z[3], z[1] - z[2]])
    h_true = 0.5 * (z[0] + z[1] - z[2] - z[3])
    is_slope = (v["terrain"] == SLOPE_UP) | (v["terrain"] == SLOPE_DOWN)
    truth = ground_truth(diffs, a_p, is_slope, v)

    qs, margins = kinematics.inverse_kinematics_all(params, tips)
    sensed = kinematics.arm_tips(params, qs) + v["noise"] * jax.random.normal(k_tips, (4, 3), dt)
    imu = a_p * jnp.asarray([1.0, 0.0], dt) + v["imu_noise"] * jax.random.normal(k_imu, (2,), dt)
    est = kinematics.explore_terrain(params, sensed, imu[0], imu[1])
    exact = kinematics.explore_terrain(params, tips, a_p, zero)  # T_P of the true contact plane
    return {
        "case": est.case,
        "diffs": est.diffs,  # sensed (z1 - z4, z2 - z3) [m] in {C}: what the thresholds see
        "truth": truth,
        "correct": truth[est.case],
        "h_true": h_true,
        "h_err": est.step_height - h_true,
        "pitch_err": est.pitch - exact.pitch,
        "angle": a_p,
        "margin": jnp.min(margins),
    }


def run_row(v: Mapping[str, jax.Array], key: jax.Array, samples: int) -> dict[str, jax.Array]:
    """Metrics and status of one row: `samples` samples of `run_sample`, vmapped."""
    s = jax.vmap(lambda k: run_sample(v, k))(jax.random.split(key, samples))
    dt = v["height"].dtype
    ok = (s["margin"] >= 0).astype(dt)  # samples whose endpoints are all reachable
    n_ok = jnp.sum(ok)

    def mean(x):  # over the reachable samples (NaN when there is none)
        return jnp.sum(ok.reshape(ok.shape + (1,) * (x.ndim - 1)) * x, axis=0) / n_ok

    frac = mean((s["case"][:, None] == jnp.arange(4)[None, :]).astype(dt))
    truth = mean(s["truth"].astype(dt))
    out = {
        "accuracy": mean(s["correct"].astype(dt)),
        "h_true": mean(s["h_true"]),
        "h_est_bias": mean(s["h_err"]),
        "h_est_rms": jnp.sqrt(mean(s["h_err"] ** 2)),
        "slope_angle": s["angle"][0],
        "pitch_rms": jnp.sqrt(mean(s["pitch_err"] ** 2)),
        "reach_margin": jnp.min(s["margin"]),
        "reachable": n_ok / samples,
        "status": jnp.where(n_ok == 0, 2, jnp.where(n_ok < samples, 1, 0)).astype(jnp.int32),
    }
    for i, name in enumerate(CLASSES):
        out[f"frac_{name}"] = frac[i]
        out[f"truth_{name}"] = truth[i]
    return out


def row(values: Mapping[str, Any], key: jax.Array) -> dict[str, jax.Array]:
    """`Analysis.row`: accuracy and costs of one row over `samples` Monte-Carlo draws."""
    return run_row(values, key, int(values["samples"]))


def summarize(table) -> Summary:
    """Mean accuracy per sigma setting (rows) and terrain type (columns), pooled over the
    other parameters (heights, seeds, ...)."""
    cols = table.to_pydict()
    sig = np.column_stack([np.asarray(cols[n], float) for n in ("sigma1", "sigma2", "sigma3")])
    terr = np.asarray(cols["terrain"], int)
    acc = np.asarray(cols["accuracy"], float)
    finite = np.isfinite(acc)
    present = [t for t in range(len(TERRAINS)) if np.any(terr == t)]
    settings = list(dict.fromkeys(map(tuple, sig)))
    rows, overall = [], []
    for s in settings:
        mine = np.all(sig == np.asarray(s), axis=1) & finite
        cells = [f"{v:g}" for v in s]
        for t in present:
            sel = mine & (terr == t)
            cells.append(f"{acc[sel].mean():.3f}" if np.any(sel) else "-")
        total = float(acc[mine].mean())
        overall.append(total)
        cells.append(f"{total:.3f}")
        rows.append(tuple(cells))
    best = int(np.argmax(overall))
    notes = [
        ("accuracy = fraction of samples whose class is correct for the true terrain "
        "(flat < flat_tol, obstacle >= step_min, up/down within the robot's capability, "
        "slopes <= slope_max; otherwise undetectable); pooled over heights and seeds"),
        "best setting: sigma = (" + ", ".join(f"{v:g}" for v in settings[best]) + f") m, accuracy {overall[best]:.3f}",
    ]
    up = terr == STEP_UP
    if np.any(up):
        rms = np.sqrt(np.mean(np.asarray(cols["h_est_rms"], float)[up] ** 2))
        bias = np.mean(np.asarray(cols["h_est_bias"], float)[up])
        notes.append(f"H_EST on step_up rows: bias {1000 * bias:+.1f} mm, rms {1000 * rms:.1f} mm")
    partial = sum(1 for x in cols.get("status", []) if x != "ok")
    if partial:
        notes.append(f"{partial} rows had samples with an arm endpoint out of reach (those samples left out; "
                     f"{int(np.sum(~finite))} rows with none left)")
    notes.append("s1, s2, s3 = sigma_1..3 [m]; " + ", ".join(f"{_SHORT[t]} = {TERRAINS[t]}" for t in present
                                                             if _SHORT[t] != TERRAINS[t]))
    return Summary(
        title="OCTOPUS terrain exploration: accuracy per sigma setting and terrain",
        columns=("s1", "s2", "s3", *(_SHORT[t] for t in present), "all"),
        rows=tuple(rows),
        notes=tuple(notes),
    )


TERRAIN_CLASSIFICATION = Analysis(
    name="octopus.terrain_classification",
    doc="Terrain exploration from the four arm endpoints (Cases 1-3): classification accuracy "
    "against sigma_1..3, step height and terrain type",
    params=PARAMS,
    metrics=METRICS,
    row=row,
    statuses=STATUSES,
    summarize=summarize,
    x64=True,
)
