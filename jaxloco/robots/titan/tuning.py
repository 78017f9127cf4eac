"""`titan.stride` tuning objective: gradient descent (optax, `jaxloco tune`) on TITAN XI's
standard stride (L_std, W_std) of the grid step over intermittent crawl gait (Hodoshima
et al. 2007, Sec. 4.4-5; `gait.py`), through the gait planner itself.

The question is the `titan.stride` sweep's (`analysis.py`): which stride walks furthest
per cycle while every planned step keeps the normalized energy stability margin (NESM,
Sec. 4.1) at least S_NE^c? One plan is exactly one sweep row (`gait.sweep_plan`: the
standard start 3 m from the map's x = 0 edge, `n_cycles` cycles of six steps along the
map-frame `direction`, frames of `frame_size` every `frame_interval` on a map of slope
`slope`, tethers cancelling `tether` of the slope-parallel gravity); the tunables have
the sweep's names, so a tuned (l_std, w_std) can be handed to a titan.stride sweep.

Loss (one plan; map frame, SI units):

    loss = -d / D_REF + w_margin * softplus((S_NE^c - s) / tau)

  * d: distance per cycle [m] (`GaitPlan.distance_per_cycle`: mean COG progress along
    L_G, 0 for a held cycle); D_REF = 2 L_std = 1.0 m, the default stride's progress per
    cycle, so -1 is "as fast as the default standard gait".
  * s: the analysis' soft-min NESM, -tau log sum_k exp(-nesm_k / tau) over the 6 n_cycles
    planned steps (`analysis.softmin`, tau = `softmin_tau`), a smooth lower bound of the
    hard min (s >= S_NE^c implies min NESM >= S_NE^c), except that the six steps of a
    held cycle (no feasible trial) count as steps at S_NE^c instead of the large margin of
    standing still: holding must not relieve the margin term (the aux `softmin_nesm` is
    the analysis' own, held steps included as they are).
  * the margin term uses the same tau: its slope in s is -(w_margin / tau) (1 - q) with
    q = sigmoid((s - S_NE^c) / tau), the analysis' "objective's sigmoid". Well above
    S_NE^c it vanishes; below, it grows by w_margin per tau of deficit.

The trade-off: one reference distance (1 m per cycle) is worth w_margin tau (5 mm) of
soft-min margin below S_NE^c. Where a longer or narrower stride gains progress dd/dx but
loses margin ds/dx < 0, the loss is stationary at 1 - q = tau (dd/dx) / (D_REF w_margin
|ds/dx|): the soft-min stays about tau log(D_REF w_margin |ds/dx| / (tau dd/dx)) above
S_NE^c. As the soft-min lies up to tau log(number of near-critical steps) below the hard
min, the hard min keeps roughly a centimetre more (the executor loses about 2 cm
of the planned margin to the legs' mass, `walk.py`).

Default case: the Sec. 8.4 test slope (30 deg), walking straight up the fall line for 4
cycles, with the tethers cancelling only 75 % of the slope-parallel gravity (Sec. 8.1
assumes all of it; the remaining downhill pull tilts the effective gravity by ~8 deg)
and no frames. There the default stride keeps min NESM 0.037 m, 7 mm above S_NE^c = 0.03 m,
and the tuning finds a stride that is faster and keeps more margin. With the full tether
(flat-ground margins) the NESM of the standard gait grows with L_std up to the fans' reach
and the tuning just runs to the reach limit (L_std 0.98 m, W_std 0.43 m, next to its
lower bound); with less tether the optimum moves to shorter, wider strides (best of 80
Adam steps, learning rate 0.1, from the default stride: tether 0.8 -> (0.82, 0.81) m, 0.75
-> (0.76, 0.97) m, 0.7 -> (0.66, 1.19) m; at 0.6 the default stride's start is already
below S_NE^c, every cycle is held and the gradient is zero).

Differentiability: the foothold candidates are fixed offsets of the initial search
position I_u (phase-reserved positioning, Sec. 5.3), which moves continuously with L_std
and W_std (the standard strokes), and |L|, |W| of the COG shift are continuous in them
too; the discrete choices (candidate index, trial, roles, failure) are piecewise
constant. So the gradient does flow through the search (it is not killed): within a
piece it is the derivative of the NESMs and progress of the planned footholds with the
discrete decisions held fixed, and it does not see the jumps between pieces. The tests
compare it with central differences whose step stays inside a piece. `gait.plan_cycles`
is built from `lax.while_loop`s, which JAX cannot reverse-differentiate: `loss_fn` is a
`jax.custom_vjp` whose forward pass takes the Jacobian of every output w.r.t. (l_std,
w_std) in forward mode (two tangents, `jax.jacfwd`) and whose backward pass contracts it
with the cotangents. `plan_loss_fn` is the plain (forward-mode only) function.

Frames: without frames the search keeps the standard landing points I_u until a reach or
S_NE^c condition fails, so the pieces are long (a line scan of the default case in L_std
jumps at 0.805 and 0.875 m, nowhere below) and gradient descent works. The runner reports
the best evaluated step, which can sit next to such a jump: in the spec's run step 67
(loss -1.442, min NESM 0.056 m at (0.741, 1.006) m; measured before the planner took the
swing leg's centre of mass: step 69, -1.470 at (0.755, 0.971) m); a sweep row reproduces
it exactly. On
frame maps (frame_size > 0) the search picks the first valid grid candidate, and the
plan jumps every few cm of L_std (a chosen candidate, a modification (a)/(b), a held
cycle); the soft-min NESM there is a sawtooth pinned near S_NE^c whose slope inside a
piece says nothing about the average. `n_offsets` > 1 averages the loss over frame grids
shifted by phases (k / K, frac(k phi)) of the interval in map (x, y) (phi = golden ratio
- 1, k = 0..K-1; k = 0 is the sweep row), the expected loss over where the robot meets
the frames. Even so, on the Sec. 8.4 frame slope (tether 1, 4 phases) 40 Adam steps from
the default stride drifted to (0.91, 1.63) m with held cycles, the loss rising from 0.21 to
1.25 (best step -0.02), while the grid point (0.95, 1.10) m of the same loss is at -0.82
(same with tether 0.75: best 0.15 below the start): the pieces' slopes do not point to
the better strides. Use the titan.stride sweep on frame maps.

Settings: every other titan.stride parameter (S_NE^c, terrain, direction, tether,
softmin_tau, n_cycles, map shape and cell) plus `w_margin` and `n_offsets`. Reference:
the default stride (params.py: L_std = 0.5 m, W_std = 1.0 m) as "default (ours)": the paper
gives no values for L_std, W_std and S_NE^c (its figures are missing).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

import jax
import jax.numpy as jnp

from jaxloco.errors import SpecError
from jaxloco.robots.titan import analysis, gait
from jaxloco.robots.titan import params as titan_params
from jaxloco.tune.objective import Objective

D_REF = 2.0 * titan_params.L_STD  # [m] progress per cycle of the default standard gait on flat ground
PHI = 0.5 * (math.sqrt(5.0) - 1.0)  # y phase step of the frame-grid offsets
L_LO, L_HI = 0.1, 1.0  # [m] bounds of l_std (hi: the sweep's upper bound, ~ the fans' reach)
W_LO, W_HI = 0.4, 1.8  # [m] bounds of w_std (flat ground: at 0.4 the standard gait keeps only
# 4 mm above S_NE^c = 0.03 m, at 0.3 its start fails; above ~1.5 the reach shortens |L|)
# [m] farthest a foot pad reaches from the COG along a body axis: pivot + R_out + pad
FOOT_REACH = max(titan_params.PIVOT_X, titan_params.PIVOT_Y) + titan_params.R_OUT + titan_params.FOOT_RADIUS
MAX_DIRECTION = math.pi / 4  # [rad] beyond it the rear pair changes (`gait.leg_roles`)

# the optimiser's bounds are tighter than the sweep's (L_LO .. W_HI above)
TUNABLES = (
    titan_params.PARAMETERS.tunable("l_std", lo=L_LO, hi=L_HI),
    titan_params.PARAMETERS.tunable("w_std", lo=W_LO, hi=W_HI),
)
DEFAULT_STRIDE = titan_params.PARAMETERS.defaults(("l_std", "w_std"))  # default (ours): not in the paper

# default case (module doc): the Sec. 8.4 slope angle, 75 % tether, no frames (frame_interval:
# the Sec. 8.4 grid, used when frame_size > 0)
_DEFAULTS = {
    "frame_size": 0.0,
    "frame_interval": titan_params.SLOPE_GRID,
    "slope": titan_params.SLOPE_ANGLE,
    "tether": 0.75,
    "n_cycles": 4,
}
_TUNED = {t.name for t in TUNABLES}
SETTINGS = tuple(
    dataclasses.replace(p, default=_DEFAULTS.get(p.name, p.default)) for p in analysis.PARAMS if p.name not in _TUNED
) + titan_params.PARAMETERS.select("w_margin", "n_offsets")
AUX = ("distance_per_cycle", "min_nesm", "softmin_nesm", "margin_penalty", "objective", "n_failures",
       "steps_below", "n_modifications", "path_deviation")


def offsets(n: int) -> list[tuple[float, float]]:
    """Frame-grid phases (x, y) in units of the interval: (k / n, frac(k phi)), k < n."""
    return [(k / n, (k * PHI) % 1.0) for k in range(n)]


def check_settings(settings: Mapping[str, Any]) -> None:
    """SpecError (one line) for settings that cannot give a meaningful tuning."""
    n_off = int(settings["n_offsets"])
    if n_off > 1 and float(settings["frame_size"]) <= 0.0:
        raise SpecError(f"settings: n_offsets = {n_off} averages over frame-grid phases, but frame_size = 0 "
                        "(flat ground) has none: set n_offsets = 1")
    direction = float(settings["direction"])
    if abs(direction) >= MAX_DIRECTION:
        raise SpecError(f"settings: direction = {direction:g} rad: the tuning needs |direction| < pi/4 (its "
                        "map lies ahead of the start along +x)")
    n, cell = int(settings["n_cycles"]), float(settings["cell"])
    box = max(abs(math.cos(direction)), abs(math.sin(direction)))
    # [m] longest walk: n cycles at the upper bound of l_std, lengthened off a body axis
    travel = n * 2.0 * L_HI / box**titan_params.STRIDE_EXPONENT
    need_x = float(settings["start_x"]) + travel * math.cos(direction) + FOOT_REACH
    need_y = 2.0 * (travel * abs(math.sin(direction)) + FOOT_REACH + 0.5 * W_HI)
    if settings["map_nx"] * cell < need_x or settings["map_ny"] * cell < need_y:
        raise SpecError(
            f"settings: the map ({settings['map_nx']} x {settings['map_ny']} cells of {cell:g} m) is too small for "
            f"{n} cycles at l_std up to {L_HI:g} m along direction {direction:g}: it needs "
            f"{need_x:.1f} x {need_y:.1f} m (map_nx >= {math.ceil(need_x / cell)}, "
            f"map_ny >= {math.ceil(need_y / cell)})"
        )


def plan(params: titan_params.TitanParams, s: Mapping[str, Any], phase: jax.Array) -> gait.GaitPlan:
    """`gait.sweep_plan` for the settings `s` with the frame grid shifted by `phase` (2,)
    intervals in map x, y; phase (0, 0) is `sweep_plan` itself (frame centre lines at
    (k + 1/2) interval)."""
    dtype = jnp.asarray(params.l_std).dtype
    shape, cell = (int(s["map_nx"]), int(s["map_ny"])), float(s["cell"])
    v = {n: jnp.asarray(s[n], dtype) for n in ("frame_size", "frame_interval", "slope", "direction", "start_x",
                                               "frame_size_b", "frame_interval_b", "mix_block")}
    gmap, start = gait.sweep_setup(params, v["frame_size"], v["frame_interval"], v["slope"], v["direction"], shape,
                                cell, phase=jnp.asarray(phase, dtype), **analysis.field_values(v))
    return gait.plan_cycles(params, gmap, start, int(s["n_cycles"]), v["direction"])


def plan_loss_fn(settings: Mapping[str, Any]):
    """`f(values) -> (loss, aux)` without the custom VJP: forward-mode differentiable only
    (`jax.jvp`, `jax.jacfwd`). `values` maps l_std, w_std [m] to scalars. aux (AUX, float
    scalars): the titan.stride metrics of the plan (`analysis.plan_metrics`), plus
    margin_penalty (the loss's margin term) and steps_below (steps with NESM below
    S_NE^c - 1e-9 m); over the frame phases the mean of distance_per_cycle,
    softmin_nesm, margin_penalty and objective, the min of min_nesm, the sums of the
    counts and the max of path_deviation."""
    s = dict(settings)
    phases = offsets(int(s["n_offsets"]))

    def f(values):
        dtype = jnp.result_type(values["l_std"], values["w_std"], float)
        v = {n: jnp.asarray(values[n], dtype) for n in ("l_std", "w_std")}
        v.update({n: jnp.asarray(s[n], dtype) for n in ("s_ne_c", "tether")})
        params = analysis.row_params(v, dtype)
        tau = jnp.asarray(s["softmin_tau"], dtype)
        phase = jnp.asarray(phases, dtype)  # (K, 2), one plan per row, vmapped

        def one(ph):
            p = plan(params, s, ph)
            m = analysis.plan_metrics(p, params.s_ne_c, tau)
            # a held cycle (no feasible trial) counts as six steps at S_NE^c, not as the
            # large margin of standing still: failing must not relieve the margin term
            m["loss_margin"] = analysis.softmin(jnp.where(p.failed, jnp.minimum(p.nesm, params.s_ne_c), p.nesm), tau)
            m["margin_penalty"] = s["w_margin"] * jax.nn.softplus((params.s_ne_c - m["loss_margin"]) / tau)
            m["steps_below"] = jnp.sum(p.nesm < params.s_ne_c - analysis.NESM_TOL)
            m["loss"] = -m["distance_per_cycle"] / D_REF + m["margin_penalty"]
            return {k: jnp.asarray(x, dtype) for k, x in m.items()}

        stack = jax.vmap(one)(phase)
        aux = {k: jnp.mean(stack[k]) for k in ("distance_per_cycle", "softmin_nesm", "margin_penalty", "objective")}
        aux.update({k: jnp.sum(stack[k]) for k in ("n_failures", "steps_below", "n_modifications")})
        aux["min_nesm"] = jnp.min(stack["min_nesm"])
        aux["path_deviation"] = jnp.max(stack["path_deviation"])
        return jnp.mean(stack["loss"]), {k: aux[k] for k in AUX}

    return f


def _twice(o):
    return o, o


def make_loss(settings: Mapping[str, Any]):
    """`Objective.make_loss`: loss_fn(values) -> (loss, aux) for the settings (module doc),
    reverse-differentiable through a forward-mode Jacobian (custom VJP)."""
    check_settings(settings)
    f = plan_loss_fn(settings)
    keys = tuple(t.name for t in TUNABLES)

    def g(x):
        return f(dict(zip(keys, x)))

    @jax.custom_vjp
    def loss_x(x):
        return g(x)

    def fwd(x):
        # every output leaf's Jacobian has a trailing axis of len(keys)
        jac, out = jax.jacfwd(lambda y: _twice(g(y)), has_aux=True)(x)
        return out, jac

    def bwd(jac, ct):
        return (sum(jnp.asarray(c)[..., None] * j for c, j in zip(jax.tree.leaves(ct), jax.tree.leaves(jac))),)

    loss_x.defvjp(fwd, bwd)

    def loss_fn(values):
        dtype = jnp.result_type(*(values[k] for k in keys), float)
        return loss_x(jnp.stack([jnp.asarray(values[k], dtype) for k in keys]))

    return loss_fn


STRIDE_TUNE = Objective(
    name="titan.stride",
    doc="TITAN XI crawl gait: stride (L_std, W_std) maximising the distance per cycle against a soft-min NESM "
    "penalty below S_NE^c, through the grid-map gait planner (default: the Sec. 8.4 30 deg slope, 75 % "
    "tether, no frames)",
    tunables=TUNABLES,
    settings=SETTINGS,
    make_loss=make_loss,
    references={"default (ours)": DEFAULT_STRIDE},
    x64=True,
)
