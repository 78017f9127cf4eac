"""Numeric ranges of a spec's [params] tables, expanded to plain Python floats.

Linear ranges are computed in decimal arithmetic from the numbers as written, so
`{start = 0.02, stop = 0.1, step = 0.02}` gives 0.02, 0.04, 0.06, 0.08, 0.1 and not
0.06000000000000001. The end points are always exactly `start` and `stop`.
"""

from __future__ import annotations

import math
from decimal import ROUND_FLOOR, ROUND_HALF_EVEN, Decimal

# `stop` belongs to a stepped range when it is this close (relative, in steps) to a step.
STEP_TOLERANCE = 1e-9


def _dec(x: float) -> Decimal:
    return Decimal(repr(float(x)))


def linspace(start: float, stop: float, num: int) -> list[float]:
    """`num` evenly spaced values from start to stop, both included."""
    if num == 1:
        return [float(start)]
    a, b = _dec(start), _dec(stop)
    delta = (b - a) / (num - 1)
    values = [float(a + delta * i) for i in range(num)]
    values[-1] = float(stop)
    return values


def geomspace(start: float, stop: float, num: int) -> list[float]:
    """`num` geometrically spaced values from start to stop (both > 0), both included."""
    if num == 1:
        return [float(start)]
    lo, hi = math.log(start), math.log(stop)
    values = [math.exp(lo + (hi - lo) * i / (num - 1)) for i in range(num)]
    values[0], values[-1] = float(start), float(stop)
    return values


def arange_count(start: float, stop: float, step: float) -> tuple[int, bool]:
    """(number of values, whether the last one is `stop`) of start, start+step, ... <= stop."""
    steps = (_dec(stop) - _dec(start)) / _dec(step)
    nearest = steps.to_integral_value(rounding=ROUND_HALF_EVEN)
    if abs(steps - nearest) <= Decimal(STEP_TOLERANCE) * max(Decimal(1), abs(steps)):
        return int(nearest) + 1, True
    return int(steps.to_integral_value(rounding=ROUND_FLOOR)) + 1, False


def arange(start: float, stop: float, step: float) -> list[float]:
    """start, start+step, ... up to stop; stop is included when it lands on a step.

    Requires step > 0 and stop >= start (the caller validates).
    """
    count, hits_stop = arange_count(start, stop, step)
    a, s = _dec(start), _dec(step)
    values = [float(a + s * i) for i in range(count)]
    if hits_stop:
        values[-1] = float(stop)
    return values
