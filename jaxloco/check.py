"""`jaxloco check SPEC`: what running a sweep or tune spec would do, without running it.

For a sweep: rows, chunks, batch calls per chunk and rows per call as the runner makes
them on this machine's JAX devices (`chunks.rows_per_call`), the
output directory's state (`store.check_output`) and a time estimate. For a tuning: the
objective, tunables, settings, optimizer, steps, output state and the [validate] sweep.

The time estimate comes from the best source there is, named in the output:
  * "recorded": the wall time per chunk that `jaxloco sweep` records in the output
    directory's manifest (remaining chunks of an interrupted run; a finished run's total),
  * "probe" (--probe): the batch function (or the tuning's value-and-gradient) compiled
    and called twice on the first call's inputs; nothing is written to the output,
  * "header": the spec file's `# time: ...` comment line.
Without --probe nothing is compiled: JAX is asked for its devices only (the analysis'
or objective's module is imported to validate the spec).
"""

from __future__ import annotations

import json
import textwrap
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from jaxloco import paths, specs
from jaxloco.errors import SpecError
from jaxloco.sweep.spec_model import read_toml

if TYPE_CHECKING:
    from jaxloco.sweep.spec import SweepSpec
    from jaxloco.tune.spec import TuneSpec

WIDTH = 80  # columns of the printed report
LABEL_WIDTH = 17  # "compiled shapes: " and the value column after it


# ------------------------------------------------------------------ the spec's kind


def spec_kind(spec: str | Path) -> tuple[str, Path]:
    """("sweep" or "tune", the resolved file) from the TOML's top-level table; SpecError
    (one line) for a file that has neither [sweep] nor [tune], or both."""
    path = specs.resolve(spec)
    doc = read_toml(path)
    kinds = [kind for kind in ("sweep", "tune") if kind in doc]
    if len(kinds) == 1:
        return kinds[0], path
    found = "both a [sweep] and a [tune] table" if kinds else "neither a [sweep] nor a [tune] table"
    raise SpecError(f"{path}: {found}; a sweep spec has [sweep], a tune spec [tune]")


def check(
    spec: str | Path,
    *,
    probe: bool = False,
    output: str | Path | None = None,
    chunk_size: int | None = None,
    steps: int | None = None,
) -> list[tuple[str, str]]:
    """The report on a sweep or tune spec as (label, value) lines; SpecError if invalid.

    output, chunk_size (sweeps), steps (tunings): the command-line overrides of `jaxloco
    sweep` / `jaxloco tune`. probe: also time a short probe (compiles; writes nothing)."""
    kind, path = spec_kind(spec)
    if kind == "sweep":
        if steps is not None:
            raise SpecError("--steps: only for a tune spec; this is a sweep spec")
        return sweep_report(path, probe=probe, output=output, chunk_size=chunk_size)
    if chunk_size is not None:
        raise SpecError("--chunk-size: only for a sweep spec; this is a tune spec")
    return tune_report(path, probe=probe, output=output, steps=steps)


def render(lines: list[tuple[str, str]], width: int = WIDTH) -> str:
    """`label: value` lines, values wrapped within `width` columns under their own column."""
    out: list[str] = []
    for label, value in lines:
        head = f"{label}:".ljust(LABEL_WIDTH)
        wrapped = textwrap.wrap(
            value, width, initial_indent=head, subsequent_indent=" " * LABEL_WIDTH, break_on_hyphens=False
        )
        out.extend(wrapped or [head.rstrip()])
    return "\n".join(out)


def duration(seconds: float) -> str:
    """A wall time for people: "0.25 s", "8.4 s", "42 s", "3 min 5 s", "2 h 10 min"."""
    if seconds < 1:
        return f"{seconds:.2f} s"
    if seconds < 10:
        return f"{seconds:.1f} s"
    if seconds < 59.5:
        return f"{seconds:.0f} s"
    if seconds < 3570:
        minutes, rest = divmod(round(seconds), 60)
        return f"{minutes} min {rest} s" if rest else f"{minutes} min"
    hours, rest = divmod(round(seconds / 60), 60)
    return f"{hours} h {rest} min" if rest else f"{hours} h"


def where(path: str | Path) -> str:
    """A spec file for the report: "bundled" for one of `jaxloco.specs`, else its path."""
    return "bundled" if Path(path).resolve().parent == specs.DIRECTORY else str(path)


def _plural(n: int, word: str) -> str:
    return f"{n:,} {word}" if n == 1 else f"{n:,} {word}s"


SOURCES = {"recorded": "recorded by a run", "probe": "from the probe", "header": "from the spec's header"}


@dataclass(frozen=True)
class Estimate:
    """A time estimate: `text` for the report, from `source` ("recorded", "probe", "header")."""

    source: str
    text: str
    extra: tuple[tuple[str, str], ...] = ()  # further lines, e.g. the probe's own time


def estimate_lines(estimates: list[Estimate]) -> list[tuple[str, str]]:
    """The best estimate (the first) as `estimate`, the other sources under their own name."""
    if not estimates:
        return [("estimate", "unknown: no recorded run, no `# time:` line in the spec's header; try --probe")]
    best, *others = estimates
    lines = [("estimate", f"{best.text} ({SOURCES[best.source]})"), *best.extra]
    for other in others:
        lines.append((other.source, other.text))
        lines.extend(other.extra)
    return lines


def header_estimate(path: Path) -> Estimate | None:
    """The spec file's `# time: ...` header line, if it has one."""
    text = specs.read_header(path).time
    return Estimate("header", text) if text else None


def _timed(call: Callable[[], Any]) -> float:
    """Wall time [s] of `call()`, waiting for JAX's asynchronous results."""
    import jax

    started = time.perf_counter()
    jax.block_until_ready(call())
    return time.perf_counter() - started


# --------------------------------------------------------------------------- sweeps


@dataclass(frozen=True)
class SweepPlan:
    """How the runner computes a sweep on given JAX devices (the runner's own functions)."""

    bounds: list[tuple[int, int]]  # (start, stop) rows of every chunk
    batch: int  # rows per call of the batch function (padded; host: the chunk size)
    padded: set[int]  # the distinct row counts the calls are made with (compiled shapes)
    n_devices: int
    platform: str
    host: bool

    @property
    def n_chunks(self) -> int:
        return len(self.bounds)

    def work(self, index: int) -> int:
        """What chunk `index` costs: one call (JAX: every call has the same shape) or its
        rows (a host analysis batches itself, one call per chunk)."""
        start, stop = self.bounds[index]
        return stop - start if self.host else 1


def sweep_plan(spec: SweepSpec, n_devices: int, platform: str) -> SweepPlan:
    """The chunks and calls of `spec` on `n_devices` JAX devices of `platform` ("cpu", "gpu")."""
    from jaxloco.sweep.chunks import rows_per_call
    from jaxloco.sweep.grid import chunk_bounds

    host = spec.analysis.executor == "host"
    bounds = chunk_bounds(spec.n_rows, spec.chunk_size)
    batch = rows_per_call(spec.chunk_size, spec.n_rows, n_devices, host)
    padded = {stop - start if host else batch for start, stop in bounds}
    return SweepPlan(bounds, batch, padded, n_devices, platform, host)


def jax_devices() -> tuple[int, str]:
    """How many JAX devices the runner would shard over, and their platform (starts JAX's
    backend with the runner's CPU device count; compiles nothing)."""
    import jax

    from jaxloco import runtime

    runtime.use_cpu_cores()
    devices = jax.devices()
    return len(devices), devices[0].platform


def rows_text(spec: SweepSpec) -> str:
    """Rows and how they come about, e.g. "505 = 101 theta x 5 psi x 1 seed"; a swept
    string parameter lists its values: "6 = 3 task (step1, step2_front, block) x 2 speed x 1 seed"."""
    parts = []
    for factor in spec.factors:
        count = len(spec.swept[factor[0]])
        if len(factor) > 1:
            parts.append(f"{count} ({', '.join(factor)} zipped)")
        elif spec.analysis.param(factor[0]).kind == "str":
            parts.append(f"{count} {factor[0]} ({', '.join(spec.swept[factor[0]])})")
        else:
            parts.append(f"{count} {factor[0]}")
    parts.append(_plural(len(spec.seeds), "seed"))
    return f"{spec.n_rows:,} = {' x '.join(parts)}"


def chunks_text(spec: SweepSpec, plan: SweepPlan) -> str:
    """E.g. "5 x 101 rows", "3: 2 x 4 rows and the last of 2"."""
    sizes = [stop - start for start, stop in plan.bounds]
    if len(sizes) == 1:
        note = f" (chunk_size {spec.chunk_size:,})" if sizes[0] != spec.chunk_size else ""
        return f"1 of {_plural(sizes[0], 'row')}{note}"
    if sizes[-1] == spec.chunk_size:
        return f"{len(sizes):,} x {spec.chunk_size:,} rows"
    return f"{len(sizes):,}: {len(sizes) - 1:,} x {spec.chunk_size:,} rows and the last of {sizes[-1]:,}"


def calls_text(plan: SweepPlan) -> str:
    """Calls of the batch function per chunk and rows per call, as the runner makes them."""
    total = plan.n_chunks
    if plan.host:
        return (
            f"1 per chunk ({total:,} in all), the chunk's rows in one call: a host analysis"
            " batches itself (native MuJoCo), JAX does not compile it"
        )
    devices = f"{plan.n_devices} {plan.platform} {'device' if plan.n_devices == 1 else 'devices'}"
    return f"1 per chunk ({total:,} in all), {plan.batch:,} rows per call sharded over {devices}"


def shapes_text(plan: SweepPlan) -> str:
    if plan.host:
        return "none (not compiled by JAX)"
    sizes = ", ".join(f"{n:,}" for n in sorted(plan.padded))
    return f"{len(plan.padded)} (calls padded to {sizes} rows)"


@dataclass(frozen=True)
class OutputState:
    """What `jaxloco sweep` finds in the output directory (read only, nothing written)."""

    text: str
    saved: frozenset[int]  # chunk indices on disk of this spec's run
    manifest: dict[str, Any] | None  # this spec's manifest (None: absent, another spec's, ...)


def sweep_output(out: Path, spec_hash: str, n_chunks: int) -> OutputState:
    """The state of a sweep's output directory: absent, complete, resumable (k of n chunks)
    or refused as it is (another spec's, not a sweep output, ...; the reason says which)."""
    from jaxloco.sweep import store

    try:
        mode = store.check_output(out, spec_hash, resume=True, overwrite=False)
    except SpecError as exc:
        reason = str(exc).removeprefix(f"output {out} ")
        return OutputState(f"not usable as it is: {reason}", frozenset(), None)
    if mode == "new":
        text = "empty (the sweep writes into it)" if paths.exists(out) else "absent (the sweep creates it)"
        return OutputState(text, frozenset(), None)
    manifest = store.read_manifest(out)
    saved = frozenset(i for i in range(n_chunks) if store.chunk_path(out, i).is_file())
    if len(saved) == n_chunks and (out / store.TABLE).is_file():
        text = f"complete: all {n_chunks:,} chunks and {store.TABLE} (run again with --overwrite)"
    else:
        text = f"resumable: {len(saved):,} of {n_chunks:,} chunks done (continue with --resume)"
    return OutputState(text, saved, manifest)


def recorded_estimate(manifest: dict[str, Any], plan: SweepPlan, saved: frozenset[int]) -> Estimate | None:
    """Remaining time from the chunk wall times a run recorded in its manifest: compiling
    (the first chunk of a run, less a steady chunk's time) plus the steady time per call
    (per row for a host analysis) times the remaining chunks' calls (rows)."""
    from jaxloco.sweep import store

    seconds, first = store.chunk_times(manifest)
    seconds = {i: s for i, s in seconds.items() if 0 <= i < plan.n_chunks}
    if not seconds:
        return None
    unit = "row" if plan.host else "call"
    steady = [i for i in seconds if i not in first]
    compiled = [i for i in seconds if i in first]
    if steady:
        per_unit = sum(seconds[i] for i in steady) / sum(plan.work(i) for i in steady)
        overhead = max((seconds[i] - per_unit * plan.work(i) for i in compiled), default=0.0)
        basis = f"{duration(per_unit)} per {unit}"
        if compiled:
            basis += f", compiling {duration(max(overhead, 0.0))}"
    else:  # only first chunks: compiling included in every unit, an upper bound
        per_unit = sum(seconds.values()) / sum(plan.work(i) for i in seconds)
        overhead = 0.0
        basis = f"{duration(per_unit)} per {unit} with compiling, an upper bound"
    recorded = f"{_plural(len(seconds), 'chunk')} took {duration(sum(seconds.values()))}"
    todo = [i for i in range(plan.n_chunks) if i not in saved]
    if not todo:
        return Estimate("recorded", f"nothing left to run; {recorded}, compiling included")
    remaining = max(overhead, 0.0) + per_unit * sum(plan.work(i) for i in todo)
    text = f"{duration(remaining)} for the {_plural(len(todo), 'remaining chunk')}; {recorded} ({basis})"
    return Estimate("recorded", text)


def sweep_probe(spec: SweepSpec, plan: SweepPlan) -> Estimate:
    """Time the batch function on the first call's inputs, writing nothing to the output.

    JAX analysis: called twice (compile + run, then run): compile + calls x run. Host
    analysis: one call on min(first chunk's rows, 2 x devices) rows, extrapolated linearly
    to every row (its own setup counts in full, so this errs on the long side)."""
    from jaxloco import runtime
    from jaxloco.sweep.chunks import call_args, prepare

    started = time.perf_counter()
    runtime.configure(x64=spec.analysis.x64, cache_dir=True)  # as the runner does
    prepared = prepare(spec)
    start, stop = prepared.bounds[0]
    swept, seed_pos = prepared.grid.rows(start, stop)
    if prepared.host:
        rows = min(stop - start, 2 * plan.n_devices)
        args = call_args(prepared, swept, seed_pos, rows)
        once = _timed(lambda: prepared.fn(*args))
        total = once * spec.n_rows / rows
        text = (
            f"{duration(total)} for {_plural(spec.n_rows, 'row')}: one call on {_plural(rows, 'row')} took"
            f" {duration(once)}, extrapolated linearly"
        )
    else:
        args = call_args(prepared, swept, seed_pos, stop - start)
        first = _timed(lambda: prepared.fn(*args))
        run = _timed(lambda: prepared.fn(*args))
        compiling = max(first - run, 0.0)
        calls = plan.n_chunks
        total = compiling + calls * run
        text = (
            f"{duration(total)} for {_plural(spec.n_rows, 'row')} = compiling {duration(compiling)}"
            f" + {_plural(calls, 'call')} x {duration(run)}"
        )
    return Estimate("probe", text, (("probe took", duration(time.perf_counter() - started)),))


def sweep_report(
    path: Path, *, probe: bool = False, output: str | Path | None = None, chunk_size: int | None = None
) -> list[tuple[str, str]]:
    """The report on the sweep spec at `path` (see the module docstring)."""
    from jaxloco.sweep.schema import check_names
    from jaxloco.sweep.spec import load_spec

    spec = load_spec(path).with_options(output=output, chunk_size=chunk_size)
    check_names(spec.analysis)
    plan = sweep_plan(spec, *jax_devices())
    state = sweep_output(spec.output, spec.hash, plan.n_chunks)
    lines = [
        ("sweep", f"{spec.name} ({where(spec.source)})"),
        ("analysis", spec.analysis.name),
        ("rows", rows_text(spec)),
        ("chunks", chunks_text(spec, plan)),
        ("calls", calls_text(plan)),
        ("compiled shapes", shapes_text(plan)),
        ("output", f"{spec.output}: {state.text}"),
    ]
    estimates = []
    if state.manifest is not None and (recorded := recorded_estimate(state.manifest, plan, state.saved)):
        estimates.append(recorded)
    if probe:
        estimates.append(sweep_probe(spec, plan))
    if header := header_estimate(path):
        estimates.append(header)
    return lines + estimate_lines(estimates)


# -------------------------------------------------------------------------- tunings


def tune_output(spec: TuneSpec) -> str:
    """What `jaxloco tune` finds in the output directory: absent, or the files of a run
    (of this spec or not, and how many steps it recorded), which a new run replaces."""
    import pyarrow.parquet as pq

    from jaxloco.sweep.schema import METADATA_KEY
    from jaxloco.tune import output as files

    out = spec.output
    if not paths.exists(out, where="output"):
        return "absent (the tuning creates it)"
    if not paths.is_dir(out):
        return "not usable: exists and is not a directory"
    present = [p.name for p in files.all_files(out) if p.is_file()]
    if not present:
        return "no tuning files yet (the tuning writes into it)"
    whose, steps = "another spec's", ""
    try:
        curve = out / f"{files.CURVE}.parquet"
        meta = json.loads((pq.read_schema(curve).metadata or {})[METADATA_KEY])
        if meta.get("spec") == json.loads(json.dumps(spec.content())):
            whose = "this spec's"
        steps = f", {max(pq.read_metadata(curve).num_rows - 1, 0):,} of {meta['spec']['steps']:,} steps"
    except (OSError, KeyError, TypeError, ValueError):
        whose = "an earlier"
    return f"holds {whose} tuning ({', '.join(present)}{steps}); a new run replaces its files"


def validation_text(spec: TuneSpec) -> str:
    """The [validate] sweep: its name, rows per compared set and how many sets at most."""
    from jaxloco.sweep.spec import load_spec as load_sweep
    from jaxloco.tune.handoff import ParamSet, validation_spec

    plan = spec.validation
    sweep = load_sweep(plan.sweep)
    known = {p.name for p in sweep.analysis.params}
    mapping = plan.mapping or {t.name: t.name for t in spec.objective.tunables if t.name in known}
    one = ParamSet("initial", {param: spec.init[tunable] for tunable, param in mapping.items()})
    per_set = validation_spec(sweep, [one]).n_rows
    labels = list(plan.labels or ("initial", "tuned", *spec.objective.references))
    return (
        f"sweep '{sweep.name}' ({where(plan.sweep)}): {_plural(per_set, 'row')} per compared set, at most"
        f" {len(labels)} sets ({', '.join(labels)}; equal sets run once) = {per_set * len(labels):,} rows"
    )


def tune_probe(spec: TuneSpec) -> Estimate:
    """Time the tuning's value-and-gradient (the runner's own `make_evaluate`) twice at the
    initial values: compiling + evaluations x one evaluation (the optimizer's update, a
    small compiled function of its own, is not counted). Writes nothing."""
    from jaxloco import runtime
    from jaxloco.tune.runner import make_evaluate, tunable_values

    started = time.perf_counter()
    runtime.configure(x64=spec.objective.x64, cache_dir=True)  # as the runner does
    evaluate = make_evaluate(spec)
    values = tunable_values(spec, spec.init)
    first = _timed(lambda: evaluate(values))
    once = _timed(lambda: evaluate(values))
    compiling = max(first - once, 0.0)
    evaluations = spec.steps + 1 + len(spec.objective.references)
    total = compiling + evaluations * once
    text = (
        f"{duration(total)} = compiling {duration(compiling)} + {_plural(evaluations, 'evaluation')}"
        f" x {duration(once)}"
    )
    return Estimate("probe", text, (("probe took", duration(time.perf_counter() - started)),))


def _number(value: Any) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


def tune_report(
    path: Path, *, probe: bool = False, output: str | Path | None = None, steps: int | None = None
) -> list[tuple[str, str]]:
    """The report on the tune spec at `path` (see the module docstring)."""
    from jaxloco.tune.spec import load_spec

    spec = load_spec(path).with_options(output=output, steps=steps)
    objective = spec.objective
    held = [t.name for t in objective.tunables if t.name not in spec.params]
    tuned = ", ".join(f"{name} = {_number(spec.init[name])}" for name in spec.params)
    optimizer = spec.optimizer + (f", gradient norm clipped at {spec.clip_norm:g}" if spec.clip_norm else "")
    evaluations = spec.steps + 1 + len(objective.references)
    lines = [
        ("tuning", f"{spec.name} ({where(spec.source)})"),
        ("objective", f"{objective.name} ({objective.grad_mode}-mode gradients)"),
        ("tunables", f"{tuned} (initial values)"),
    ]
    if held:
        lines.append(("held", ", ".join(f"{name} = {_number(spec.init[name])}" for name in held)))
    lines += [
        ("settings", ", ".join(f"{k} = {_number(v)}" for k, v in spec.settings.items()) or "none"),
        ("optimizer", optimizer),
        ("learning rate", f"{spec.learning_rate:g}"),
        ("steps", f"{spec.steps:,} ({_plural(evaluations, 'evaluation')}: steps 0 to {spec.steps:,}"
                  f" and {_plural(len(objective.references), 'reference')})"),
        ("output", f"{spec.output}: {tune_output(spec)}"),
        ("validate", validation_text(spec) if spec.validation is not None else "none (no [validate] table)"),
    ]
    estimates = []
    if probe:
        estimates.append(tune_probe(spec))
    if header := header_estimate(path):
        estimates.append(header)
    return lines + estimate_lines(estimates)


__all__ = ["check", "render", "spec_kind", "sweep_plan", "sweep_report", "tune_report"]
