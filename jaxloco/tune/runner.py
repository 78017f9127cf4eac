"""Running a tuning: one jitted `value_and_grad` of the objective's loss (reverse mode, or
forward mode, `jax.jacfwd`, for an objective with grad_mode "forward"), an optax loop in
unconstrained coordinates (`jaxloco.tune.transform`), and the output files.

Step k evaluates the loss at the values after k optimizer updates, so a run of N steps
records N + 1 evaluations: step 0 is the initial values, step N the last update's result.
The "tuned" values are those of the step with the lowest loss. What has been computed is
written every `FLUSH_SECONDS`, at the end, on Ctrl+C and when the loss or its gradient
stops being finite (Parquet every few seconds; CSV and the plot at the end).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa

from jaxloco import info, paths
from jaxloco.errors import ObjectiveError, SpecError, TuneDiverged, TuneInterrupted
from jaxloco.tune import output
from jaxloco.tune.display import step_progress
from jaxloco.tune.result import TuneResult
from jaxloco.tune.spec import TuneSpec, load_spec, spec_from_dict
from jaxloco.tune.transform import from_free, to_free

FLUSH_SECONDS = 2.0


def run(
    spec: TuneSpec | str | Path | Mapping[str, Any],
    *,
    progress: bool = True,
    out: str | Path | None = None,
    steps: int | None = None,
    configure_jax: bool = True,
    on_step: Callable[[int, float], None] | None = None,
) -> TuneResult:
    """Tune, write the output directory and return the result.

    spec: a TuneSpec, a path to a TOML spec, or a dict in the TOML layout. out, steps:
    override the spec. configure_jax: call `jaxloco.runtime.configure(x64=objective.x64)`
    first. on_step(step, loss): called after each evaluation is recorded.
    Raises SpecError for user errors (before computing anything), TuneInterrupted (a
    KeyboardInterrupt) when interrupted and TuneDiverged on a non-finite loss or gradient.
    """
    if isinstance(spec, Mapping):
        spec = spec_from_dict(spec)
    elif not isinstance(spec, TuneSpec):
        spec = load_spec(spec)
    spec = spec.with_options(output=out, steps=steps)
    objective = spec.objective
    if paths.exists(spec.output, where="output") and not paths.is_dir(spec.output):
        raise SpecError(f"output {spec.output} exists and is not a directory")

    import jax
    import jax.numpy as jnp
    import optax

    from jaxloco import runtime

    if configure_jax:
        runtime.configure(x64=objective.x64, cache_dir=True)
    evaluate = make_evaluate(spec)

    dtype = value_dtype(spec)
    tuned = [objective.tunable(name) for name in spec.params]
    optimizer = _optimizer(spec)

    def transform(u: dict[str, Any]) -> dict[str, Any]:
        return {t.name: from_free(t, u[t.name]) for t in tuned}

    def apply(u, state, grads, values):
        _, pullback = jax.vjp(transform, u)
        (g,) = pullback({t.name: grads[t.name].astype(dtype) for t in tuned})
        norm = optax.tree.norm(g)
        updates, state = optimizer.update(g, state, u)
        u = optax.apply_updates(u, updates)
        return u, state, {**values, **transform(u)}, norm

    apply = jax.jit(apply)

    values = tunable_values(spec, spec.init)
    u = {t.name: jnp.asarray(to_free(t, spec.init[t.name]), dtype=dtype) for t in tuned}
    state = optimizer.init(u)
    record = _Record(spec, info.versions())

    try:
        with step_progress(spec.steps, enabled=progress) as bar:
            for step in range(spec.steps + 1):
                (loss, aux), grads = evaluate(values)
                if step == 0:
                    record.set_aux(_checked_aux(objective.name, loss, aux, record.columns))
                    bar.describe("references")
                    for label, given in objective.references.items():
                        (ref_loss, ref_aux), _ = evaluate(tunable_values(spec, {**spec.init, **given}))
                        record.add_reference(label, {**spec.init, **given}, ref_loss, ref_aux)
                    bar.describe("tuning")
                u_next, state_next, values_next, grad_norm = apply(u, state, grads, values)
                host = jax.device_get((loss, aux, grad_norm, values))
                record.add(step, *host)
                if not (math.isfinite(record.last("loss")) and math.isfinite(record.last("grad_norm"))):
                    record.flush(plot=True)
                    raise TuneDiverged(_diverged(record, step, spec), step, spec.output)
                u, state, values = u_next, state_next, values_next
                bar.update(step, record.last("loss"), record.best_loss())
                if on_step is not None:
                    on_step(step, record.last("loss"))
                if record.due():
                    record.flush(final=False)
            bar.describe("done")
        curve, comparison, written = record.flush(plot=True)
    except KeyboardInterrupt:
        saved = record.n_steps > 0
        if saved:
            record.flush()
        raise TuneInterrupted(max(record.n_steps - 1, 0), spec.steps, spec.output if saved else None) from None
    best = record.best_index()
    assert best is not None  # every recorded loss is finite here
    return TuneResult(
        spec=spec,
        path=spec.output,
        curve=curve,
        comparison=comparison,
        best_step=best,
        written=tuple(written),
        warnings=tuple(record.warnings),
    )


_EVALUATE: dict[tuple[Any, ...], tuple[Any, Callable]] = {}  # (objective id, settings, params) -> (objective, fn)
_EVALUATE_KEPT = 8


def make_evaluate(spec: TuneSpec) -> Callable:
    """The jitted `values -> ((loss, aux), grads)` that `run` evaluates at every step (and
    for every reference), gradients of the tuned tunables; JAX must be configured already.
    One per objective, settings and tuned tunables (the 8 most recent are kept), so that
    another run of the same objective and settings in this process (another learning
    rate, init or step count, a probe) reuses its trace and compiled program. SpecError
    (naming the spec) for a combination of settings the objective refuses."""
    import jax

    objective = spec.objective
    key = (id(objective), tuple((k, repr(v)) for k, v in spec.settings.items()), tuple(spec.params),
           jax.config.jax_enable_x64)
    hit = _EVALUATE.get(key)
    if hit is not None and hit[0] is objective:
        return hit[1]
    try:
        loss_fn = objective.make_loss(dict(spec.settings))
    except SpecError as exc:
        message = str(exc)
        raise (exc if message.startswith(f"{spec.source}: ") else SpecError(f"{spec.source}: {message}")) from None
    evaluate = jitted_value_and_grad(loss_fn, objective.grad_mode, list(spec.params), objective.name)
    _EVALUATE[key] = (objective, evaluate)
    while len(_EVALUATE) > _EVALUATE_KEPT:
        _EVALUATE.pop(next(iter(_EVALUATE)))
    return evaluate


def value_dtype(spec: TuneSpec) -> Any:
    """The dtype the tunables' values are evaluated in: float64 when the objective asks for
    it and JAX has float64 enabled, else float32."""
    import jax
    import jax.numpy as jnp

    return jnp.float64 if spec.objective.x64 and jax.config.jax_enable_x64 else jnp.float32


def tunable_values(spec: TuneSpec, given: Mapping[str, float]) -> dict[str, Any]:
    """Every tunable's value from `given` (e.g. `spec.init`) as a scalar array, the input of
    `make_evaluate(spec)`."""
    import jax.numpy as jnp

    dtype = value_dtype(spec)
    return {t.name: jnp.asarray(given[t.name], dtype=dtype) for t in spec.objective.tunables}


def value_and_grad(loss_fn: Callable, mode: str = "reverse", names: list[str] | None = None) -> Callable:
    """`values -> ((loss, aux), grads)` for a `loss_fn(values) -> (loss, aux)`.

    mode "reverse": `jax.value_and_grad` (grads of every entry of `values`). mode
    "forward": `jax.jacfwd`, one tangent per entry of `names` (default: every entry);
    the other entries are held fixed and get no gradient (forward mode costs one
    tangent per differentiated input). With one entry, one `jax.jvp` with a unit
    tangent: the same numbers, without `jacfwd`'s vmap over the tangents, which costs
    an MJX rollout's trace a batching pass over every `cond` of its scan body (the
    snake's reach loss, one process with an empty cache: traced in 6.7 s instead of
    14.6, compiled in 23.1 s instead of 25.6)."""
    import jax
    import jax.numpy as jnp

    if mode == "reverse":
        return jax.value_and_grad(loss_fn, has_aux=True)
    if mode != "forward":
        raise ValueError(f"grad mode: expected 'reverse' or 'forward', got {mode!r}")

    def evaluate(values):
        keys = list(values) if names is None else list(names)
        fixed = {k: v for k, v in values.items() if k not in keys}
        if len(keys) == 1:
            (key,) = keys
            primal = jnp.asarray(values[key])
            loss, slope, aux = jax.jvp(lambda v: loss_fn({**fixed, key: v}), (primal,), (jnp.ones_like(primal),),
                                       has_aux=True)
            return (loss, aux), {key: slope}

        def loss_of(sub):
            loss, aux = loss_fn({**fixed, **sub})
            return loss, (loss, aux)

        grads, (loss, aux) = jax.jacfwd(loss_of, has_aux=True)({k: values[k] for k in keys})
        return (loss, aux), grads

    return evaluate


def jitted_value_and_grad(loss_fn: Callable, mode: str, names: list[str] | None, label: str) -> Callable:
    """`jax.jit(value_and_grad(loss_fn, mode, names))` whose programs come from the program
    cache (`jaxloco.sim.programs.CachedJit`, keyed by `loss_fn` by value, `label` and the
    call signature): a later process evaluates an MJX objective without tracing its
    differentiated rollout again. A loss that cannot be keyed (code from outside jaxloco)
    gets the plain jit."""
    from jaxloco.sim import programs

    return programs.CachedJit(loss_fn, f"tune {label} {mode} {names}", lambda: value_and_grad(loss_fn, mode, names))


def _optimizer(spec: TuneSpec):
    import optax

    base = {"adam": optax.adam, "sgd": optax.sgd, "adamw": optax.adamw}[spec.optimizer](spec.learning_rate)
    if spec.clip_norm is None:
        return base
    return optax.chain(optax.clip_by_global_norm(spec.clip_norm), base)


def _checked_aux(name: str, loss: Any, aux: Any, taken: Mapping[str, Any]) -> list[str]:
    """The aux metric names, after checking the loss function's outputs against the contract."""
    if np.shape(loss) != ():
        raise ObjectiveError(f"objective '{name}': the loss has shape {np.shape(loss)}, expected a scalar")
    if not isinstance(aux, Mapping):
        raise ObjectiveError(f"objective '{name}': aux is a {type(aux).__name__}, expected a dict of scalars")
    for key, value in aux.items():
        if not isinstance(key, str) or key in taken or key == "label":
            raise ObjectiveError(f"objective '{name}': aux metric name {key!r} is taken (or not a string)")
        if np.shape(value) != ():
            raise ObjectiveError(
                f"objective '{name}': aux metric '{key}' has shape {np.shape(value)}, expected a scalar"
            )
    return list(aux)


def _diverged(record: _Record, step: int, spec: TuneSpec) -> str:
    what = f"the loss is {record.last('loss'):g} and the gradient norm {record.last('grad_norm'):g}"
    if step == 0:
        return f"step 0 (the initial values): {what}; check [init] and [settings] (written to {spec.output})"
    return (
        f"step {step}: {what}; stopped, the curve up to this step and the best values are in {spec.output}"
        " (try a smaller learning_rate or set clip_norm)"
    )


class _Record:
    """The curve and reference rows so far, and writing them."""

    def __init__(self, spec: TuneSpec, versions: Mapping[str, str]) -> None:
        self.spec, self.versions = spec, versions
        names = ["step", "loss", "grad_norm", *(t.name for t in spec.objective.tunables)]
        self.columns: dict[str, list[float]] = {name: [] for name in names}
        self.aux: list[str] = []
        self.references: list[dict[str, Any]] = []
        self.warnings: list[str] = []
        self.best: int | None = None
        self.cleared = False
        self.flushed_at = time.monotonic()
        self.interval = FLUSH_SECONDS

    @property
    def n_steps(self) -> int:
        return len(self.columns["step"])

    def set_aux(self, names: list[str]) -> None:
        self.aux = names
        self.columns.update({name: [] for name in names})

    def add(self, step: int, loss: Any, aux: Mapping[str, Any], grad_norm: Any, values: Mapping[str, Any]) -> None:
        row = {"step": step, "loss": float(loss), "grad_norm": float(grad_norm)}
        row |= {name: float(v) for name, v in values.items()}
        row |= {name: float(aux[name]) for name in self.aux}
        for name, column in self.columns.items():
            column.append(row[name])
        if math.isfinite(row["loss"]) and (self.best is None or row["loss"] < self.best_loss()):
            self.best = self.n_steps - 1

    def add_reference(self, label: str, values: Mapping[str, float], loss: Any, aux: Mapping[str, Any]) -> None:
        row = {"label": label, "step": None, "loss": float(loss), **values}
        row |= {name: float(aux[name]) for name in self.aux}
        if not math.isfinite(row["loss"]):
            self.warnings.append(f"reference '{label}': the loss is {row['loss']:g}")
        self.references.append(row)

    def last(self, name: str) -> float:
        return self.columns[name][-1]

    def best_index(self) -> int | None:
        """The first step with the lowest finite loss (None while there is none)."""
        return self.best

    def best_loss(self) -> float:
        return math.nan if self.best is None else self.columns["loss"][self.best]

    def row(self, index: int, label: str) -> dict[str, Any]:
        return {"label": label, **{name: column[index] for name, column in self.columns.items()}}

    def due(self) -> bool:
        return time.monotonic() - self.flushed_at >= self.interval

    def flush(self, *, final: bool = True, plot: bool = False) -> tuple[pa.Table, pa.Table, list[Path]]:
        """Write the curve and the comparison (and the plot); returns them and the paths.

        A periodic flush (final=False) writes Parquet only, and the next one waits at least
        ten times as long as this one took, so that long curves cost little time."""
        started = time.monotonic()
        out = self.spec.output
        if not self.cleared:  # files of an earlier run must not mix with this one's
            for path in output.all_files(out):
                path.unlink(missing_ok=True)
            self.cleared = True
        best = self.best_index()
        meta = output.metadata(self.spec, self.versions, best)
        curve = output.curve_table(self.spec, self.columns, self.aux, meta)
        rows = [self.row(0, "initial")]
        if best is not None:
            rows.append(self.row(best, "tuned"))
        comparison = output.comparison_table(self.spec, rows + self.references, self.aux, meta)
        formats = self.spec.formats if final else ("parquet",)
        written = output.write_tables(out, {output.CURVE: curve, output.TUNED: comparison}, formats)
        if plot and best is not None:
            path = output.plot_curve(
                out, self.columns["step"], self.columns["loss"], best, f"{self.spec.name} ({self.spec.objective.name})"
            )
            if path is not None:
                written.append(path)
        self.flushed_at = time.monotonic()
        self.interval = max(FLUSH_SECONDS, 10 * (self.flushed_at - started))
        return curve, comparison, written


__all__ = [
    "TuneResult",
    "make_evaluate",
    "run",
    "tunable_values",
    "value_and_grad",
]
