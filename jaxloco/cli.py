"""The `jaxloco` command line: sweep, sweeps, summary, analyses, describe, tune, check,
objectives, render, view, info.

User errors print one line, `error: ...`, on stderr and exit with code 2; an interrupted
sweep or tuning exits with 130, a tuning whose loss stops being finite with 1. JAX is
imported only by the commands that need it.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path
from typing import Annotated

import typer

from jaxloco.errors import SpecError

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_show_locals=False,
    help="JAX-differentiable, batched kinematics, stability, control and simulation of field locomotion robots "
    "(legged, crawler and snake).",
)

EXIT_USER_ERROR = 2
EXIT_INTERRUPTED = 130
_SWEEP_SPEC_HELP = "a sweep spec: a TOML file, or a bundled spec's name (see `jaxloco sweeps`)"
_TUNE_SPEC_HELP = "a tune spec: a TOML file, or a bundled spec's name (see `jaxloco sweeps`)"


def _fail(message: str, code: int = EXIT_USER_ERROR) -> typer.Exit:
    typer.echo(f"error: {' '.join(message.split())}", err=True)
    return typer.Exit(code)


@contextlib.contextmanager
def _user_errors() -> Iterator[None]:
    try:
        yield
    except SpecError as exc:
        raise _fail(str(exc)) from None
    except OSError as exc:
        raise _fail(str(exc), code=1) from None


def _stdout():
    from rich.console import Console

    return Console()


@app.command()
def sweep(
    spec: Annotated[Path, typer.Argument(help=_SWEEP_SPEC_HELP, show_default=False)],
    resume: Annotated[
        bool, typer.Option("--resume", help="continue an interrupted sweep in its output directory")
    ] = False,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="delete the output directory's sweep files and start again")
    ] = False,
    out: Annotated[Path | None, typer.Option("--out", help="output directory (overrides the spec)")] = None,
    csv: Annotated[bool, typer.Option("--csv", help="also write table.csv")] = False,
    chunk_size: Annotated[
        int | None, typer.Option("--chunk-size", help="rows per compiled batch (overrides the spec)")
    ] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="no progress bar")] = False,
    executor: Annotated[
        str, typer.Option("--executor", help="where chunks run: local (this process) or ray (one Ray task per chunk)")
    ] = "local",
    address: Annotated[
        str | None,
        typer.Option("--address", help="Ray cluster: auto, host:6379 or ray://host:10001 (default: start a local one)"),
    ] = None,
    ray_cpus: Annotated[float, typer.Option("--ray-cpus-per-task", help="CPUs each Ray task asks for")] = 1.0,
    ray_gpus: Annotated[float, typer.Option("--ray-gpus-per-task", help="GPUs each Ray task asks for")] = 0.0,
    from_tune: Annotated[
        Path | None,
        typer.Option("--from-tune", help="a `jaxloco tune` output directory: run the sweep once per compared set "
                     "(initial, tuned, references), those parameters replaced, and compare the sets"),
    ] = None,
    maps: Annotated[
        list[str] | None,
        typer.Option("--map", help="with --from-tune: TUNABLE=PARAM when the names differ (repeatable)"),
    ] = None,
) -> None:
    """Run a parameter sweep and write its table (Parquet, optionally CSV); with --from-tune,
    validate a tuning run's values with it."""
    from jaxloco.errors import SweepInterrupted
    from jaxloco.sweep import load_spec, run
    from jaxloco.sweep.display import print_summary

    with _user_errors():
        loaded = load_spec(spec).with_options(output=out, chunk_size=chunk_size, csv=True if csv else None)
        chosen = _sweep_executor(executor, address, ray_cpus, ray_gpus)
        if maps and from_tune is None:
            raise SpecError("--map needs --from-tune")
        if from_tune is not None:
            if resume or overwrite:
                raise SpecError(
                    "--from-tune resumes or replaces its validation sweep by itself; drop --resume/--overwrite"
                )
            mapping = None
            if maps:
                pairs = [m.split("=", 1) for m in maps]
                if any(len(p) != 2 or not p[0] or not p[1] for p in pairs):
                    raise SpecError(f"--map: expected TUNABLE=PARAM, got {', '.join(maps)}")
                mapping = dict(pairs)
            _validate(from_tune, loaded, mapping, None, out, quiet, executor=chosen)
            return
        try:
            result = run(loaded, resume=resume, overwrite=overwrite, progress=not quiet, executor=chosen)
        except SweepInterrupted as exc:
            typer.echo(str(exc), err=True)
            raise typer.Exit(EXIT_INTERRUPTED) from None
        except KeyboardInterrupt:
            typer.echo("interrupted", err=True)
            raise typer.Exit(EXIT_INTERRUPTED) from None
    for warning in result.warnings:
        typer.echo(f"warning: {warning}", err=True)
    if result.summary is not None:
        print_summary(result.summary, _stdout())
    else:
        typer.echo(f"warning: the summary failed: {result.summary_error}", err=True)
    typer.echo(f"wrote {result.table_path} ({result.table.num_rows} rows)")
    for path in result.written[1:]:
        typer.echo(f"wrote {path}")


def _sweep_executor(name: str, address: str | None, cpus: float, gpus: float):
    """The executor `jaxloco sweep` asked for (SpecError for a wrong combination)."""
    from jaxloco.sweep.executors import EXECUTORS, RayExecutor

    if name not in EXECUTORS:
        raise SpecError(f"--executor: unknown executor '{name}' (known: {', '.join(EXECUTORS)})")
    if name == "ray":
        return RayExecutor(address, cpus_per_task=cpus, gpus_per_task=gpus)
    if address is not None or cpus != 1.0 or gpus != 0.0:
        raise SpecError("--address, --ray-cpus-per-task and --ray-gpus-per-task need --executor ray")
    return name


@app.command()
def summary(table: Annotated[Path, typer.Argument(help="a sweep's table.parquet", show_default=False)]) -> None:
    """Print the summary of an existing sweep table."""
    from jaxloco.sweep.display import print_summary
    from jaxloco.sweep.summary import read_table, summarize

    with _user_errors():
        data, analysis = read_table(table)
    print_summary(summarize(data, analysis), _stdout())


@app.command()
def analyses() -> None:
    """List the analyses that a sweep can run."""
    from jaxloco import analysis as registry
    from jaxloco import catalog
    from jaxloco.sweep.display import analyses_table, first_line

    built_ins = catalog.load()  # built-ins without importing them (see jaxloco.catalog)
    rows = []
    for name in registry.names():
        try:
            doc = first_line(catalog.analysis(name, built_ins).doc)
        except Exception as exc:  # a broken plugin must not hide the others
            doc = f"(cannot load: {type(exc).__name__}: {exc})"
        rows.append((name, doc))
    _stdout().print(analyses_table(rows))


@app.command()
def describe(
    name: Annotated[str, typer.Argument(help="an analysis name (see `jaxloco analyses`)", show_default=False)],
) -> None:
    """Show an analysis' parameters (defaults, units, ranges), metrics and statuses."""
    from rich.text import Text

    from jaxloco import catalog
    from jaxloco.sweep.display import describe_tables

    with _user_errors():
        analysis = catalog.analysis(name, catalog.load())
    console = _stdout()
    console.print(Text(f"{analysis.name}: {analysis.doc.strip()}"))
    for table in describe_tables(analysis):
        console.print(table)


@app.command()
def tune(
    spec: Annotated[Path, typer.Argument(help=_TUNE_SPEC_HELP, show_default=False)],
    out: Annotated[Path | None, typer.Option("--out", help="output directory (overrides the spec)")] = None,
    steps: Annotated[int | None, typer.Option("--steps", help="optimizer steps (overrides the spec)")] = None,
    validate: Annotated[
        bool,
        typer.Option("--validate", help="then run the spec's [validate] sweep once per compared set "
                     "(initial, tuned, references) and compare them"),
    ] = False,
    validate_sweep: Annotated[
        Path | None, typer.Option("--validate-sweep", help="validate with this sweep spec (implies --validate)")
    ] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="no progress bar")] = False,
) -> None:
    """Tune an objective's parameters by gradient descent (optax) and compare them with the
    initial values and the objective's references; --validate hands them to a sweep."""
    from jaxloco.errors import TuneDiverged
    from jaxloco.tune import load_spec, run
    from jaxloco.tune.display import print_result

    with _user_errors():
        loaded = load_spec(spec).with_options(output=out, steps=steps)
        plan = loaded.validation
        if validate_sweep is not None:
            from jaxloco.tune.spec import Validation

            plan = Validation(validate_sweep, plan.mapping if plan else None, plan.labels if plan else None)
            from jaxloco.sweep import load_spec as load_sweep

            load_sweep(validate_sweep)  # a bad sweep spec fails before the tuning
        elif validate and plan is None:
            raise SpecError(f"{spec}: --validate needs a [validate] section (or --validate-sweep SPEC)")
        try:
            result = run(loaded, progress=not quiet)
        except KeyboardInterrupt as exc:  # TuneInterrupted says what was saved
            typer.echo(str(exc) or "interrupted", err=True)
            raise typer.Exit(EXIT_INTERRUPTED) from None
        except TuneDiverged as exc:
            raise _fail(str(exc), code=1) from None
    for warning in result.warnings:
        typer.echo(f"warning: {warning}", err=True)
    print_result(result, _stdout())
    for path in result.written:
        typer.echo(f"wrote {path}")
    if validate or validate_sweep is not None:
        assert plan is not None
        _validate(result.path, plan.sweep, plan.mapping, plan.labels, None, quiet)


def _validate(tuned: Path, sweep_spec, mapping, labels, out: Path | None, quiet: bool, **run_options) -> None:
    """Run a tuning run's validation sweep and print the comparison (shared by tune and sweep)."""
    from jaxloco.errors import SweepInterrupted
    from jaxloco.tune.display import validation_table
    from jaxloco.tune.handoff import validate as run_validation

    with _user_errors():
        try:
            done = run_validation(tuned, sweep_spec, mapping=mapping, labels=labels, output=out, progress=not quiet,
                                  **run_options)
        except SweepInterrupted as exc:
            typer.echo(str(exc), err=True)
            raise typer.Exit(EXIT_INTERRUPTED) from None
    names = ", ".join(f"{k} -> {v}" if k != v else k for k, v in done.mapping.items())
    per_set = done.sweep.table.num_rows // max(len(done.sets), 1)
    source = getattr(sweep_spec, "source", sweep_spec)
    title = f"validation by {source}: {per_set} rows per set ({names}); metric means over each set's rows"
    _stdout().print(validation_table(done.comparison, title))
    typer.echo(f"wrote {done.sweep.table_path} ({done.sweep.table.num_rows} rows)")
    for path in done.written:
        typer.echo(f"wrote {path}")


@app.command()
def sweeps() -> None:
    """List the ready sweep and tune specs bundled with jaxloco: run one by name
    (`jaxloco sweep leggrope_slope`) from any directory."""
    from jaxloco import specs
    from jaxloco.sweep.display import bundled_specs_table

    _stdout().print(bundled_specs_table([specs.header(name) for name in specs.names()], specs.DIRECTORY))


@app.command()
def check(
    spec: Annotated[
        Path, typer.Argument(help="a sweep or tune spec: a TOML file, or a bundled spec's name", show_default=False)
    ],
    probe: Annotated[
        bool, typer.Option("--probe", help="time a short probe (compiles and calls the batch function or the "
                           "tuning's gradient twice; writes nothing)")
    ] = False,
    out: Annotated[Path | None, typer.Option("--out", help="output directory (overrides the spec)")] = None,
    chunk_size: Annotated[
        int | None, typer.Option("--chunk-size", help="sweeps: rows per compiled batch (overrides the spec)")
    ] = None,
    steps: Annotated[int | None, typer.Option("--steps", help="tunings: optimizer steps (overrides the spec)")] = None,
) -> None:
    """Validate a sweep or tune spec and show what running it would do: rows, chunks,
    compiled calls per chunk, the output directory's state and a time estimate (recorded
    by an earlier run, the spec's `# time:` line, or --probe), without running it."""
    from jaxloco.check import check as check_spec
    from jaxloco.check import render

    with _user_errors():
        lines = check_spec(spec, probe=probe, output=out, chunk_size=chunk_size, steps=steps)
    typer.echo(render(lines))


@app.command()
def objectives(
    name: Annotated[
        str | None, typer.Argument(help="an objective to describe (tunables, settings, references)", show_default=False)
    ] = None,
) -> None:
    """List the objectives that `jaxloco tune` can tune, or describe one."""
    from rich.text import Text

    from jaxloco import catalog
    from jaxloco.sweep.display import first_line
    from jaxloco.tune import objective as registry
    from jaxloco.tune.display import describe_table, objectives_table

    console = _stdout()
    built_ins = catalog.load()  # built-ins without importing them (see jaxloco.catalog)
    if name is not None:
        with _user_errors():
            found = catalog.objective(name, built_ins)
        console.print(Text(f"{found.name}: {found.doc.strip()}"))
        console.print(describe_table(found))
        return
    rows = []
    for known in registry.names():
        try:
            doc = first_line(catalog.objective(known, built_ins).doc)
        except Exception as exc:  # a broken plugin must not hide the others
            cause = exc.__cause__ or exc
            doc = f"(cannot load: {type(cause).__name__}: {cause})"
        rows.append((known, doc))
    console.print(objectives_table(rows))


_SOURCE_HELP = ("a sweep spec (TOML file or bundled name; its output table is used if it exists) or a sweep "
                "table (table.parquet)")


@app.command()
def render(
    source: Annotated[Path, typer.Argument(help=_SOURCE_HELP, show_default=False)],
    row: Annotated[int, typer.Option("--row", help="row index in the sweep's order")] = 0,
    out: Annotated[
        Path, typer.Option("--out", help=".gif, .mp4 (needs imageio-ffmpeg) or .png (the last frame)")
    ] = Path("run.gif"),
    fps: Annotated[int, typer.Option("--fps", help="frames per second of the video")] = 15,
    width: Annotated[int, typer.Option("--width", help="image width [px]")] = 480,
    height: Annotated[int, typer.Option("--height", help="image height [px]")] = 360,
    camera: Annotated[
        str,
        typer.Option(
            "--camera",
            help="track (follows the robot), side, front, top, free "
            "(still, frames the whole run) or a camera of the model",
        ),
    ] = "track",
    every: Annotated[
        int | None,
        typer.Option(
            "--every",
            help="draw every N-th recorded state (default: at most 150 frames spread over the run)",
            show_default=False,
        ),
    ] = None,
    seconds: Annotated[
        float | None, typer.Option("--seconds", help="replay only the first S seconds of motion", show_default=False)
    ] = None,
) -> None:
    """Replay one row of a sweep in MuJoCo and write a video (GIF/MP4) or a still (PNG) with
    the row's parameters, status and key metrics drawn on it.

    Simulated analyses rerun the row on native MuJoCo; kinematic ones pose the robot's
    MJCF model from the robot's own JAX code. Offscreen rendering uses MUJOCO_GL: on Linux
    without a display and MUJOCO_GL unset it is set to egl (GPU / headless), falling back
    to osmesa (CPU) if EGL cannot create a context; glfw needs a display."""
    with _user_errors():
        from jaxloco.render import gl
        from jaxloco.render.video import render_row

        result = render_row(source, row, out, fps=fps, width=width, height=height, camera=camera, every=every,
                            seconds=seconds)
    for note in (*gl.notes, *result.replay.row.notes):
        typer.echo(f"note: {note}", err=True)
    for problem in result.replay.mismatches():
        typer.echo(f"warning: the replay differs from the table: {problem}", err=True)
    replay = result.replay
    what = f"{replay.row.analysis.name} row {replay.row.index} ({replay.kind})"
    if result.n_frames == 1:
        typer.echo(f"{what}: a still at t = {float(replay.times[result.indices[-1]]):.1f} s")
        typer.echo(f"wrote {result.path} ({result.width}x{result.height})")
    else:
        typer.echo(f"{what}: {result.n_frames} frames over {result.span:.1f} s of motion")
        typer.echo(f"wrote {result.path} ({result.width}x{result.height}, {result.n_frames / result.fps:.1f} s at "
                   f"{result.fps} fps)")


@app.command()
def view(
    source: Annotated[Path, typer.Argument(help=_SOURCE_HELP, show_default=False)],
    row: Annotated[int, typer.Option("--row", help="row index in the sweep's order")] = 0,
    speed: Annotated[float, typer.Option("--speed", help="playback speed (1 = real time)")] = 1.0,
    every: Annotated[int | None, typer.Option("--every", help="show every N-th recorded state",
                                              show_default=False)] = None,
    seconds: Annotated[float | None, typer.Option("--seconds", help="replay only the first S seconds of motion",
                                                  show_default=False)] = None,
) -> None:
    """Replay one row of a sweep in MuJoCo's interactive viewer, looping in real time.

    Needs a display; on a headless machine use `jaxloco render` (MUJOCO_GL=egl or osmesa)."""
    with _user_errors():
        from jaxloco.render.video import check_options
        from jaxloco.render.viewer import view_row

        check_options(every=every, seconds=seconds)
        view_row(source, row, speed=speed, every=every, seconds=seconds)


@app.command()
def info() -> None:
    """Versions of jaxloco and its JAX/MuJoCo stack, JAX devices, precision and cache."""
    from jaxloco import info as environment_info

    console = _stdout()
    console.print(_info_table(environment_info.static_environment()))  # at once: no JAX yet
    console.print(_info_table(environment_info.jax_environment()))


def _info_table(rows: list[tuple[str, str]]):
    """`jaxloco info` lines as a two-column table; both parts share the label width."""
    from rich.table import Table
    from rich.text import Text

    from jaxloco.info import LABEL_WIDTH

    table = Table(show_header=False, box=None)
    table.add_column(style="bold", no_wrap=True, min_width=LABEL_WIDTH)
    table.add_column()
    for label, value in rows:
        table.add_row(Text(label), Text(value))
    return table


def _one_line_summaries(application: typer.Typer) -> None:
    """Each command's listing line is its docstring's first paragraph as one line, so the
    terminal wraps it (typer keeps the docstring's line breaks in the command list)."""
    import inspect

    for command in application.registered_commands:
        doc = inspect.cleandoc(command.callback.__doc__ or "") if command.callback else ""
        if command.short_help is None and doc:
            command.short_help = " ".join(doc.split("\n\n")[0].split())


_one_line_summaries(app)


def main() -> None:
    app()


if __name__ == "__main__":
    main()
