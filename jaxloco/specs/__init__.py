"""The ready sweep and tune specs bundled with jaxloco (package data, `jaxloco/specs/*.toml`).

Every command that takes a spec accepts a path or a bundled spec's name:
`jaxloco sweep leggrope_slope` runs `jaxloco/specs/leggrope_slope.toml` from any
directory. A path that exists always wins over a bundled name. `jaxloco sweeps` lists
them with their header: the question (the header's first paragraph), the rows (or tuning
steps) and the time a line `# time: ...` of the header records.

Nothing here imports JAX: listing the specs is instant.
"""

from __future__ import annotations

import difflib
import os
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path

from jaxloco import paths
from jaxloco.errors import SpecError

DIRECTORY = Path(__file__).resolve().parent
SUFFIX = ".toml"
_TIME_LINE = re.compile(r"^#\s*time:\s*(.+)$", re.IGNORECASE)


def names() -> list[str]:
    """The bundled specs' names (file stems), sorted."""
    return sorted(p.stem for p in DIRECTORY.glob(f"*{SUFFIX}"))


def path(name: str) -> Path:
    """The bundled spec `name` (with or without `.toml`); SpecError (one line) naming the
    bundled specs, closest first, if there is none."""
    stem = name.removesuffix(SUFFIX)
    known = names()
    if stem in known:
        return DIRECTORY / f"{stem}{SUFFIX}"
    close = difflib.get_close_matches(stem, known, n=1, cutoff=0.6)
    hint = f"did you mean '{close[0]}'? " if close else ""
    raise SpecError(f"{name}: no such file or bundled spec ({hint}bundled: {', '.join(known)})")


def is_plain_name(text: str) -> bool:
    """True if `text` could only name a bundled spec, not a path (no directory part)."""
    return bool(text) and os.sep not in text and "/" not in text and text not in (".", "..")


def resolve(spec: str | os.PathLike[str]) -> Path:
    """The file a spec argument means: an existing path as given, else the bundled spec of
    that name. A missing path with a directory part (`x/y.toml`) is returned unchanged so
    that the reader reports "no such file" for it."""
    given = Path(spec)
    text = os.fspath(spec)
    if paths.exists(given) or not is_plain_name(text):
        return given
    return path(text)


@dataclass(frozen=True)
class Header:
    """What a bundled spec's comment header says, plus its size from the TOML itself."""

    name: str
    kind: str  # "sweep" or "tune"
    target: str  # the analysis or objective it runs
    size: str  # "505 rows" or "150 steps"
    time: str  # the header's `# time:` line ("" if it has none)
    question: str  # the header's first paragraph, joined into one line


def header(name: str) -> Header:
    """The header of the bundled spec `name` (no JAX, no validation beyond reading TOML)."""
    return read_header(path(name))


def read_header(file: Path) -> Header:
    """The header of the spec file `file`, bundled or not (no JAX, no validation beyond
    reading TOML; OSError / TOMLDecodeError if it cannot be read)."""
    text = file.read_text(encoding="utf-8")
    doc = tomllib.loads(text)
    comments = _comment_lines(text)
    kind = "tune" if "tune" in doc else "sweep"
    section = doc.get(kind, {})
    target = str(section.get("objective" if kind == "tune" else "analysis", ""))
    size = f"{section.get('steps', '?')} steps" if kind == "tune" else f"{count_rows(doc):,} rows"
    times = [m.group(1).strip() for line in comments if (m := _TIME_LINE.match(line))]
    return Header(file.stem, kind, target, size, times[0] if times else "", _first_paragraph(comments))


def _comment_lines(text: str) -> list[str]:
    """The leading comment block of a TOML file (up to the first non-comment line)."""
    lines = []
    for line in text.splitlines():
        if not line.startswith("#"):
            break
        lines.append(line.rstrip())
    return lines


def _first_paragraph(comments: list[str]) -> str:
    words: list[str] = []
    for line in comments:
        body = line.lstrip("#").strip()
        if not body:
            if words:
                break
            continue
        words.extend(body.split())
    return " ".join(words)


def count_rows(doc: dict) -> int:
    """Rows of a sweep spec's TOML document, counted without validating its values:
    swept values per parameter (zipped groups count once) times seeds."""
    from jaxloco.sweep.ranges import arange_count

    sweep = doc.get("sweep", {})
    lengths: dict[str, int] = {}
    for key, entry in doc.get("params", {}).items():
        if isinstance(entry, list):
            lengths[key] = len(entry)
        elif isinstance(entry, dict) and "num" in entry:
            lengths[key] = int(entry["num"])
        elif isinstance(entry, dict) and "step" in entry:
            lengths[key] = arange_count(entry["start"], entry["stop"], entry["step"])[0]
        else:
            lengths[key] = 1
    if sweep.get("combine") == "zip":
        groups = [list(lengths)] if lengths else []
    else:
        zipped = [list(g) for g in sweep.get("zip", [])]
        in_zip = {k for g in zipped for k in g}
        groups = zipped + [[k] for k in lengths if k not in in_zip]
    rows = 1
    for group in groups:
        rows *= lengths.get(group[0], 1)
    seeds = sweep.get("seeds", [0])
    return rows * (seeds if isinstance(seeds, int) else len(seeds))
