"""The unconstrained coordinate `u` that the optimizer moves for each tuned tunable.

z = log(value) on a log scale, else value; bounds (lo, hi) apply to z (log-scale bounds
as log(lo), log(hi); a lower bound <= 0 on a log scale is no bound). Then:

    both bounds:  z = zlo + (zhi - zlo) * sigmoid(u)
    lower only:   z = zlo + softplus(u)
    upper only:   z = zhi - softplus(u)
    none:         z = u

`to_free` is the inverse, on the host in float64 (the value must be strictly inside).
A saturated map can round onto a bound, so the value is in the closed [lo, hi].
"""

from __future__ import annotations

import math

from jaxloco.tune.objective import Tunable


def z_bounds(t: Tunable) -> tuple[float | None, float | None]:
    if t.scale == "log":
        lo = math.log(t.lo) if t.lo is not None and t.lo > 0 else None
        hi = math.log(t.hi) if t.hi is not None else None
        return lo, hi
    return t.lo, t.hi


def _softplus_inv(x: float) -> float:
    return x + math.log(-math.expm1(-x))


def to_free(t: Tunable, value: float) -> float:
    """The `u` whose value is `value` (which `Tunable.check` has accepted)."""
    z = math.log(value) if t.scale == "log" else float(value)
    lo, hi = z_bounds(t)
    if lo is not None and hi is not None:
        p = (z - lo) / (hi - lo)
        return math.log(p) - math.log1p(-p)
    if lo is not None:
        return _softplus_inv(z - lo)
    if hi is not None:
        return _softplus_inv(hi - z)
    return z


def from_free(t: Tunable, u):
    """The value of `u` (traceable)."""
    import jax
    import jax.numpy as jnp

    lo, hi = z_bounds(t)
    if lo is not None and hi is not None:
        z = lo + (hi - lo) * jax.nn.sigmoid(u)
    elif lo is not None:
        z = lo + jax.nn.softplus(u)
    elif hi is not None:
        z = hi - jax.nn.softplus(u)
    else:
        z = u
    value = jnp.exp(z) if t.scale == "log" else z
    if t.lo is None and t.hi is None:
        return value
    return jnp.clip(value, t.lo, t.hi)  # rounding at a saturated end must not step outside
