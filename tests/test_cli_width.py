"""The command line fits the terminal: describe, summaries, tune tables, progress lines and
--help at 80 (and 60) columns, with no text cut. No JAX compilation."""

from __future__ import annotations

import io
import re

import pytest
import typer
from rich.cells import cell_len
from rich.console import Console
from typer.testing import CliRunner

from jaxloco import analysis as registry
from jaxloco.analysis import Summary
from jaxloco.cli import app
from jaxloco.sweep.display import RowProgress, describe_tables, print_summary, rows_progress_bar
from jaxloco.terminal import FoldedTable
from jaxloco.tune import objective as objectives
from jaxloco.tune.display import describe_table, steps_progress_bar

BOX = re.compile(r"[\u2500-\u257f]")  # box-drawing characters (table borders)


def drawn(renderable: object, width: int) -> list[str]:
    console = Console(file=io.StringIO(), width=width, color_system=None)
    console.print(renderable)
    return console.file.getvalue().splitlines()


def flat(lines: list[str]) -> str:
    """The text without table borders, every run of whitespace one space: a wrapped doc
    (in a block or in a table's last column) reads as one string again."""
    return " ".join(BOX.sub(" ", "\n".join(lines)).split())


def assert_fits(lines: list[str], width: int) -> None:
    too_long = [line for line in lines if cell_len(line) > width]
    assert not too_long, f"{len(too_long)} lines wider than {width}: {too_long[0]!r}"
    assert "…" not in "\n".join(lines)


def invoke(*args: str, columns: int = 80):
    return CliRunner().invoke(app, list(args), env={"COLUMNS": str(columns)})


def test_describe_slope_cycle_at_80_columns_keeps_every_doc():
    result = invoke("describe", "leggrope.slope_cycle")
    assert result.exit_code == 0, result.output
    lines = result.stdout.splitlines()
    assert_fits(lines, 80)
    text = flat(lines)
    analysis = registry.get("leggrope.slope_cycle")
    for item in (*analysis.params, *analysis.metrics):
        assert " ".join(item.doc.split()) in text, item.name
    assert len(lines) < 120  # was 179 with a 6-character doc column


@pytest.mark.parametrize("width", [60, 80, 120, 200])
@pytest.mark.parametrize("name", registry.names())
def test_describe_fits_and_keeps_names_ranges_and_docs(name, width):
    analysis = registry.get(name)
    lines = [line for table in describe_tables(analysis) for line in drawn(table, width)]
    assert_fits(lines, width)
    text = flat(lines)
    for p in analysis.params:
        for part in (p.name, p.range_text(), repr(p.default), " ".join(p.doc.split())):
            assert part in text, (p.name, part)
    for m in analysis.metrics:
        assert " ".join(m.doc.split()) in text, m.name


@pytest.mark.parametrize("width", [60, 80])
@pytest.mark.parametrize("name", objectives.names())
def test_objective_description_fits(name, width):
    objective = objectives.get(name)
    lines = drawn(describe_table(objective), width)
    assert_fits(lines, width)
    text = flat(lines)
    for item in (*objective.tunables, *objective.settings):
        assert item.name in text and " ".join(item.doc.split()) in text, item.name


# The widest summaries the analyses produce (their columns, typical cells).
SUMMARIES = {
    "titan.stride": Summary(
        title="TITAN XI crawl gait: fastest stride with NESM >= S_NE^c per terrain case",
        columns=("frame [m]", "interval [m]", "slope", "dir", "tether", "ok", "L_std", "W_std", "S_NE^c",
                 "dist/cycle", "min NESM", "mods", "deviation", "objective"),
        rows=(("0.2", "1.5", "30", "+0.00", "0.75", "12/40", "0.5", "1", "0.03", "0.998", "0.041", "3", "0.012",
               "0.951"),
              ("flat", "-", "0", "+0.52", "0.5", "0/40", *["-"] * 8)),
        notes=("ok = rows with min NESM >= S_NE^c and no failed cycle; best = the ok row with the largest distance "
               "per cycle (ties within 1 mm: largest min NESM - S_NE^c)",),
    ),
    "leggrope.fragile_walk": Summary(
        title="leg-grope walk over fragile footholds (native MuJoCo)",
        columns=("R_ref/Mg cos", "p_weak", "runs", "success", "max tilt change [deg]", "max N/R_ref outside D'",
                 "collapses met/survived", "min margin [mm]"),
        rows=(("0.50", "0.10", "24", "96%", "2.3", "1.12", "5/4", "31"),
              ("0.70", "0.30", "24", "100%", "1.9", "1.05", "12/12", "28")),
    ),
    "snake.reach": Summary(
        title="T² Snake-3 gripper-tip reach, feedback task-space control (native MuJoCo, box ground, 10 s)",
        columns=("target dx,dy,dz [mm]", "K [1/s]", "k_eta", "final [mm]", "max [mm]", "rms [mm]", "settle [s]",
                 "overshoot %", "loss", "status"),
        rows=(("+50,+0,-20", "1", "0.1", "0.3", "50.2", "12.1", "2.31", "4", "0.123", "ok"),
              ("+50,+0,-20", "4", "0.1", "0.1", "50.2", "7.5", "-", "12", "0.093", "failed: diverged")),
    ),
    "leggrope.slope_cycle": Summary(
        title="leg-grope walk on slopes: critical inclination per walking direction",
        columns=("psi [rad]", "psi [deg]", "crit +theta", "first fail +", "why +", "crit -theta", "first fail -",
                 "why -"),
        rows=(("+0.000", "+0", "0.349", "0.436", "slip", "0.262", "0.349", "normal force beyond R_ref tolerance"),
              ("+0.785", "+45", "none", "-", "-", "0.262", "0.349", "leg out of reach")),
    ),
}


@pytest.mark.parametrize("width", [60, 80])
@pytest.mark.parametrize("name", SUMMARIES)
def test_a_summary_fits_and_keeps_every_cell_whole(name, width):
    summary = SUMMARIES[name]
    out = io.StringIO()
    print_summary(summary, Console(file=out, width=width, color_system=None))
    lines = out.getvalue().splitlines()
    assert_fits(lines, width)
    for row in summary.rows:
        for cell in row:
            assert any(cell in line for line in lines), cell  # on one line, never wrapped or cut
    text = flat(lines)
    for header in summary.columns:
        assert all(word in text for word in header.split()), header
    assert " ".join(summary.title.split()) in text
    assert all(" ".join(note.split()) in text for note in summary.notes)


def test_a_folded_summary_repeats_its_first_column_and_a_wide_one_stays_one_table():
    summary = SUMMARIES["titan.stride"]
    narrow = drawn(FoldedTable(summary.columns, summary.rows), 80)
    headers = [line for line in narrow if line.startswith("┃")]
    assert len(headers) >= 2 and all("frame [m]" in line for line in headers)
    wide = drawn(FoldedTable(summary.columns, summary.rows), 200)
    assert sum(line.startswith("┃") for line in wide) == 1


def progress_line(progress, width: int) -> list[str]:
    console = Console(file=io.StringIO(), width=width, force_terminal=False, color_system=None)
    console.print(progress.get_renderable())
    return console.file.getvalue().splitlines()


@pytest.mark.parametrize("width", [60, 80])
def test_the_progress_lines_fit(width):
    rows = rows_progress_bar(123_456, Console(width=width))
    task = rows.add_task("starting", total=123_456, completed=1_234)
    RowProgress(rows, task).chunk_started(0, 5, first=True)
    lines = progress_line(rows, width)
    assert len(lines) == 1 and cell_len(lines[0]) <= width, lines
    assert "chunk 1/5 +compile" in lines[0] and "1234/123456 rows" in lines[0]

    steps = steps_progress_bar(1000, Console(width=width))
    steps.add_task("references", total=1000, completed=10, loss="-1.234e-05", best="-1.234e-05")
    lines = progress_line(steps, width)
    assert len(lines) == 1 and cell_len(lines[0]) <= width, lines
    assert "references" in lines[0] and "10/1000 steps" in lines[0] and "loss -1.234e-05" in lines[0]
    if width >= 80:
        assert "ETA" in progress_line(rows, width)[0] and "best -1.234e-05" in lines[0]


@pytest.mark.parametrize("command", [[], *([name] for name in typer.main.get_command(app).commands)])
def test_help_shows_flags_without_a_value_type(command):
    result = invoke(*command, "--help")
    assert result.exit_code == 0, result.output
    assert "<bool>" not in result.stdout
    assert "--help" in result.stdout
    assert_fits(result.stdout.splitlines(), 80)
    if command == ["sweep"]:
        assert re.search(r"--resume\s+continue", result.stdout)
        assert re.search(r"--chunk-size\s+<int>", result.stdout)  # options with a value keep their type



def test_the_command_list_wraps_each_summary_as_one_paragraph():
    """`jaxloco --help` lists each command with its docstring's first paragraph wrapped to
    the terminal: a description line breaks only where its next word would not fit (not
    where the docstring's source line ended)."""
    result = invoke("--help")
    assert result.exit_code == 0, result.output
    panel = [BOX.sub(" ", line).rstrip() for line in result.stdout.split("Commands")[1].splitlines()]
    limit = max(len(line) for line in panel)
    pairs = [(a, b) for a, b in zip(panel, panel[1:]) if b.strip() and not b[:12].strip()]  # b continues a
    assert len(pairs) >= 5  # several descriptions wrap at 80 columns
    ragged = [(a, b) for a, b in pairs if len(a) + 1 + len(b.split()[0]) <= limit]
    assert not ragged, ragged
