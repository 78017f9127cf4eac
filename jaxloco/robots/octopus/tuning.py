"""`octopus.sigma` tuning objective: gradient descent (optax, `jaxloco tune`) on the
terrain-exploration thresholds sigma_1 (flat), sigma_2 (highest upward step) and sigma_3
(deepest downward step) of OCTOPUS (Chen et al. 2018, "Terrain exploration", Cases 1-3;
`kinematics.terrain_case`).

The hard classifier is piecewise constant in the sigmas (zero gradient), so the loss uses a
smooth relaxation of it (`soft_terrain_probs`, temperature `tau` [m]): every comparison
`a < b` becomes sigmoid((b - a) / tau), and the class probabilities follow the hard rule's
order of tests (flat, else up, else down, else undetectable), so they sum to one and tend
to the hard classifier's one-hot answer as tau -> 0.

Sample bank (drawn once per run from `seed`, fixed shape `samples`)
-------------------------------------------------------------------
Each sample draws a terrain type uniformly from `terrains` and a `height` uniformly in
[height_min, height_max], then goes through the sampling code of the
`octopus.terrain_classification` analysis (`analysis.terrain_tips`, the closed-form IK and
FK, endpoint noise `noise` [m], IMU noise `imu_noise` [rad], the level frame {C} and
`analysis.ground_truth` with the same ground-truth constants and their names). The bank
holds the sensed differences (z1 - z4, z2 - z3) [m] in {C}, the correct classes and
whether every endpoint was within reach; unreachable samples get weight zero (as the
analysis leaves them out). `sample_bank(settings, i)`'s sample i is the analysis'
`run_sample` for terrain_i and height_i with the same key (tests/test_octopus_tune.py).

Loss: the expected misclassification cost
------------------------------------------
cost(predicted class c) = 0 when c is a correct class for the true terrain (the grey band
flat_tol..step_min accepts both flat and an obstacle), otherwise
  * `danger_weight` (default 4) when c is an autonomous class (flat, up or down): the
    robot would act on a wrong terrain by itself, e.g. climb a step higher than it can
    (truth "undetectable"), drive into a step it took for flat ground, or descend where
    the ground rises;
  * 1 when c is "undetectable" although the robot could have handled the terrain: only
    the operator's time is lost (the paper's semi-autonomous fallback).
loss = mean over the reachable samples of sum_c p_c cost(c), in units of one false
"undetectable". Its two parts are in aux (`soft_danger`, `soft_undetectable`), next to
the HARD classifier's scores on the same bank (`accuracy`, `danger_rate`,
`undetectable_rate`, `hard_cost`: the same cost with the hard answer).

Reference "default (ours)": the paper gives no values (the sigmas are "set according to
actual condition"); the row is our default `params.SIGMA` = (0.05, 0.45, 0.45) m, the analysis'
defaults. The tuned values have the analysis' parameter names, so they can be put into
jaxloco/specs/octopus_sigma.toml for validation with `octopus.terrain_classification`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco.errors import SpecError
from jaxloco.robots.octopus import analysis, kinematics
from jaxloco.robots.octopus.params import PARAMETERS, SIGMA
from jaxloco.tune.objective import Objective

CLASSES = analysis.CLASSES  # 0 undetectable, 1 flat, 2 up, 3 down (kinematics.CASE_* order)
DEFAULT_SIGMA = {"sigma1": float(SIGMA[0]), "sigma2": float(SIGMA[1]), "sigma3": float(SIGMA[2])}

# the optimiser's bounds: narrower than the sweep's (0, 2] m, around plausible thresholds
TUNABLES = (
    PARAMETERS.tunable("sigma1", lo=0.005, hi=0.2),
    PARAMETERS.tunable("sigma2", lo=0.1, hi=0.8),
    PARAMETERS.tunable("sigma3", lo=0.1, hi=0.8),
)

# the sample bank's settings, then those shared with the analysis (same names, defaults and ranges)
_SHARED = ("edge", "noise", "imu_noise", "flat_tol", "step_min", "climb_max", "descend_max", "slope_max")
SETTINGS = PARAMETERS.select(
    "tau", "danger_weight", "samples", "seed", "terrains", "height_min", "height_max",
    *_SHARED,
    # one fixed bank for the whole run (the analysis' samples are per row)
    samples={"default": 4096, "doc": "size of the fixed sample bank", "lo": 16, "hi": 1 << 17, "sweepable": True},
)
AUX = ("accuracy", "danger_rate", "undetectable_rate", "hard_cost", "soft_danger", "soft_undetectable",
       "soft_accuracy", "reachable")


# ------------------------------------------------------------------ smooth classifier
def soft_terrain_probs(diffs: jax.Array, sigma: jax.Array, tau: jax.Array | float) -> jax.Array:
    """Smooth relaxation of `kinematics.terrain_case`: class probabilities (4,) in `CLASSES`
    order (undetectable, flat, up, down) for the differences diffs = (z1 - z4, z2 - z3) [m]
    in the level frame {C}, thresholds sigma = (sigma_1, sigma_2, sigma_3) [m] and
    temperature tau [m] (> 0).

    Each test a < b is P = sigmoid((b - a) / tau); a conjunction is the product:
      F = prod_k P(|d_k| < s1) = prod_k sigmoid((s1 - d_k)/tau) sigmoid((s1 + d_k)/tau)
      U = prod_k sigmoid((d_k - s1)/tau) sigmoid((s2 - d_k)/tau)
      D = prod_k sigmoid((-d_k - s1)/tau) sigmoid((s3 + d_k)/tau)
    and, in the hard rule's order, p_flat = F, p_up = (1 - F) U, p_down = (1 - F)(1 - U) D,
    p_undetectable = (1 - F)(1 - U)(1 - D). Pure; vmap over leading sample axes."""
    d = jnp.asarray(diffs)
    s = jnp.asarray(sigma, d.dtype)
    s1, s2, s3 = s[0], s[1], s[2]

    def p(x):  # P(x > 0)
        return jax.nn.sigmoid(x / tau)

    flat = jnp.prod(p(s1 - d) * p(s1 + d), axis=-1)
    up = jnp.prod(p(d - s1) * p(s2 - d), axis=-1)
    down = jnp.prod(p(-d - s1) * p(s3 + d), axis=-1)
    p_up = (1.0 - flat) * up
    p_down = (1.0 - flat) * (1.0 - up) * down
    p_undetectable = (1.0 - flat) * (1.0 - up) * (1.0 - down)
    return jnp.stack([p_undetectable, flat, p_up, p_down], axis=-1)


def class_costs(truth: jax.Array, danger_weight: jax.Array | float) -> jax.Array:
    """Cost (..., 4) of answering each class given the correct classes `truth` (..., 4)
    bool: 0 if correct, 1 for a wrong 'undetectable', `danger_weight` for a wrong
    autonomous class (module docstring)."""
    dt = jnp.result_type(float)
    wrong = jnp.asarray(~truth, dt)
    weight = jnp.asarray([1.0, danger_weight, danger_weight, danger_weight], dt)
    return wrong * weight


# ------------------------------------------------------------------ sample bank
def _terrain_codes(text: str) -> tuple[int, ...]:
    names = [t.strip() for t in text.split(",") if t.strip()]
    if not names:
        raise SpecError("settings.terrains: empty; give terrain types, e.g. 'step_up,step_down'")
    for name in names:
        if name not in analysis.TERRAINS:
            raise SpecError(f"settings.terrains: unknown terrain '{name}' (known: {', '.join(analysis.TERRAINS)})")
    return tuple(dict.fromkeys(analysis.TERRAINS.index(n) for n in names))


def check_settings(settings: Mapping[str, Any]) -> dict[str, Any]:
    """Every setting checked (`Param.check`) and the combinations that make no sense
    rejected; SpecError (one line) otherwise."""
    out = {}
    for p in SETTINGS:
        if p.name not in settings:
            raise SpecError(f"settings.{p.name}: missing")
        out[p.name] = p.check(settings[p.name], where=f"settings.{p.name}")
    if out["height_min"] > out["height_max"]:
        raise SpecError(f"settings.height_min: {out['height_min']:g} m is above height_max {out['height_max']:g} m")
    if out["flat_tol"] > out["step_min"]:
        raise SpecError(f"settings.flat_tol: {out['flat_tol']:g} m is above step_min {out['step_min']:g} m")
    _terrain_codes(out["terrains"])
    return out


def _sample_keys(seed: int, samples: int) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Per-sample keys: (terrain type, height, the analysis' `run_sample` key)."""
    keys = jax.random.split(jax.random.PRNGKey(seed), samples)
    three = jax.vmap(lambda k: jax.random.split(k, 3))(keys)
    return three[:, 0], three[:, 1], three[:, 2]


def _sense(v: Mapping[str, jax.Array], key: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Sensed differences (2,) [m] in {C}, the correct classes (4,) and the smallest IK
    reach margin [m] of one sample: `analysis.run_sample` itself (the thresholds it is
    given do not change these three)."""
    out = analysis.run_sample(
        {**v, **{k: jnp.asarray(SIGMA[i], v["height"].dtype) for i, k in enumerate(_SIGMAS)}}, key
    )
    return out["diffs"], out["truth"], out["margin"]


_SIGMAS = ("sigma1", "sigma2", "sigma3")


def sample_bank(settings: Mapping[str, Any]) -> dict[str, np.ndarray]:
    """The fixed bank of `samples` samples (module docstring) as host arrays: `diffs`
    (n, 2) [m] sensed in {C}, `truth` (n, 4) bool, `valid` (n,) bool (every endpoint in
    reach), `terrain` (n,) int codes, `height` (n,) [m] and `key` (n, 2) (the key each
    sample gave `analysis.run_sample`'s chain)."""
    s = check_settings(settings)
    codes = jnp.asarray(_terrain_codes(s["terrains"]), jnp.int32)
    dt = jnp.result_type(float)
    n = s["samples"]
    k_type, k_height, k_run = _sample_keys(s["seed"], n)

    @jax.jit
    def draw(k_type, k_height, k_run):
        def one(kt, kh, kr):
            terrain = codes[jax.random.randint(kt, (), 0, codes.shape[0])]
            height = jax.random.uniform(kh, (), dt, s["height_min"], s["height_max"])
            v = {name: jnp.asarray(s[name], dt) for name in _SHARED} | {"terrain": terrain, "height": height}
            diffs, truth, margin = _sense(v, kr)
            return diffs, truth, margin, terrain, height

        return jax.vmap(one)(k_type, k_height, k_run)

    diffs, truth, margin, terrain, height = jax.device_get(draw(k_type, k_height, k_run))
    return {
        "diffs": np.asarray(diffs),
        "truth": np.asarray(truth, bool),
        "valid": np.asarray(margin) >= 0.0,
        "terrain": np.asarray(terrain),
        "height": np.asarray(height),
        "key": np.asarray(jax.device_get(k_run)),
    }


# ------------------------------------------------------------------ the loss
def make_loss(settings: Mapping[str, Any]):
    """`Objective.make_loss`: draws the bank once; loss_fn(values) -> (expected cost, aux)."""
    s = check_settings(settings)
    bank = sample_bank(s)
    if not bank["valid"].any():
        raise SpecError("settings: no sample of the bank has every arm endpoint within reach; lower height_max")
    tau, danger = s["tau"], s["danger_weight"]

    def loss_fn(values):
        dt = jnp.result_type(*values.values())
        sigma = jnp.stack([jnp.asarray(values[k], dt) for k in ("sigma1", "sigma2", "sigma3")])
        diffs = jnp.asarray(bank["diffs"], dt)
        truth = jnp.asarray(bank["truth"])
        w = jnp.asarray(bank["valid"], dt)
        w = w / jnp.sum(w)
        cost = class_costs(truth, danger).astype(dt)  # (n, 4)
        probs = soft_terrain_probs(diffs, sigma, tau)  # (n, 4)
        expected = probs * cost
        soft_undetectable = jnp.sum(w * expected[:, 0])
        soft_danger = jnp.sum(w * jnp.sum(expected[:, 1:], axis=1))
        case = jax.vmap(lambda d: kinematics.terrain_case(d, sigma))(diffs)
        hot = jax.nn.one_hot(case, 4, dtype=dt)
        right = jnp.sum(hot * truth, axis=1)
        aux = {
            "accuracy": jnp.sum(w * right),
            "danger_rate": jnp.sum(w * (case != kinematics.CASE_UNDETECTABLE) * (1.0 - right)),
            "undetectable_rate": jnp.sum(w * (case == kinematics.CASE_UNDETECTABLE) * (1.0 - right)),
            "hard_cost": jnp.sum(w * jnp.sum(hot * cost, axis=1)),
            "soft_danger": soft_danger,
            "soft_undetectable": soft_undetectable,
            "soft_accuracy": jnp.sum(w * jnp.sum(probs * truth, axis=1)),
            "reachable": jnp.asarray(bank["valid"].mean(), dt),
        }
        return soft_danger + soft_undetectable, aux

    return loss_fn


SIGMA_TUNE = Objective(
    name="octopus.sigma",
    doc="OCTOPUS terrain exploration: thresholds sigma_1..3 minimising the expected misclassification cost "
    "(smooth Cases 1-3, wrong autonomous classes cost danger_weight) over a fixed bank of terrain and "
    "sensing-noise samples",
    tunables=TUNABLES,
    settings=SETTINGS,
    make_loss=make_loss,
    references={"default (ours)": DEFAULT_SIGMA},
    x64=True,
)
