"""Reading a `leggrope.slope_cycle` sweep table: status categories and the critical
inclination per walking direction. NumPy only (no JAX, no matplotlib), shared by the
sweep summary (`analysis.summarize`) and the plots.

A table is a `pyarrow.Table` or any mapping of column name to array (dict, DataFrame).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

PAPER_CRITICAL_THETA = 0.40  # rad, Ambe & Matsuno 2016, "Simulation": slip-free for |theta| < ~0.40
DEFAULT_MU = 0.45  # the paper's friction coefficient (used when the table has no mu column)
_ZERO_TOL = 1e-12  # theta = 0 belongs to both sides




def _names(table: Any) -> list[str]:
    return list(table.column_names) if hasattr(table, "column_names") else list(table)


def _column(table: Any, name: str) -> np.ndarray:
    if name not in _names(table):
        raise KeyError(f"the table has no column {name!r}")
    if hasattr(table, "column_names"):  # pyarrow
        return np.asarray(table.column(name).to_numpy(zero_copy_only=False))
    return np.asarray(table[name])


def _floats(table: Any, name: str) -> np.ndarray:
    return np.asarray(_column(table, name), dtype=float)


def _field_meta(table: Any, name: str) -> dict[str, str]:
    """unit / doc of a column from the Parquet field metadata (empty when unavailable)."""
    try:
        meta = table.schema.field(name).metadata or {}
    except (AttributeError, KeyError):
        return {}
    return {k.decode(): v.decode() for k, v in meta.items()}


def status_category(status: Any) -> int:
    """0 = "ok", 1 = slip ("failed: slip ..."), 2 = any other failure (or a missing status)."""
    if status == "ok":
        return 0
    if isinstance(status, str) and status.startswith("failed: slip"):
        return 1
    return 2


def _categories(table: Any) -> np.ndarray:
    return np.asarray([status_category(s) for s in _column(table, "status")], dtype=int)


def _mus(table: Any) -> list[float]:
    if "mu" not in _names(table):
        return [DEFAULT_MU]
    mus = np.unique(_floats(table, "mu"))
    mus = mus[np.isfinite(mus)]
    return [float(m) for m in mus] or [DEFAULT_MU]


class CriticalTheta(NamedTuple):
    """Critical inclinations per walking direction (all in rad, arrays of shape (n_psi,)).

    plus / minus: the largest |theta| on the theta >= 0 / theta <= 0 side such that every
    row of that psi with a smaller or equal |theta| on that side is "ok"; NaN when already
    theta = 0 fails (or the side has no rows). first_fail_plus / first_fail_minus: the
    smallest failing |theta| on that side, NaN when none fails (so the true critical value
    lies between the two, at grid resolution)."""

    psi: np.ndarray
    plus: np.ndarray
    minus: np.ndarray
    first_fail_plus: np.ndarray
    first_fail_minus: np.ndarray


def critical_theta(table: Any, ok: np.ndarray | None = None) -> CriticalTheta:
    """Critical +theta and -theta per psi of a sweep table (see `CriticalTheta`).

    A row counts as ok where `ok` (bool per row) says so; by default where its status is
    "ok". When other swept parameters are pooled, a |theta| counts as ok only if every
    row with it is ok."""
    theta = _floats(table, "theta")
    psi = _floats(table, "psi")
    ok = _categories(table) == 0 if ok is None else np.asarray(ok, bool)
    psis = np.unique(psi)
    out = {k: np.full(len(psis), np.nan) for k in ("plus", "minus", "first_fail_plus", "first_fail_minus")}
    for i, p in enumerate(psis):
        sel = psi == p
        for sign, side in ((1.0, "plus"), (-1.0, "minus")):
            t = sign * theta[sel]
            keep = t >= -_ZERO_TOL
            values = np.unique(np.abs(t[keep]))
            if not len(values):
                continue
            ok_at = np.asarray([np.all(ok[sel][keep][np.abs(t[keep]) == v]) for v in values])
            bad = np.nonzero(~ok_at)[0]
            if not len(bad):
                out[side][i] = values[-1]
            else:
                out["first_fail_" + side][i] = values[bad[0]]
                if bad[0] > 0:
                    out[side][i] = values[bad[0] - 1]
    return CriticalTheta(psis, out["plus"], out["minus"], out["first_fail_plus"], out["first_fail_minus"])
