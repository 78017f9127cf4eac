"""The output directory of a sweep, written so that an interrupted run can be resumed.

Layout::

    <output>/manifest.json             what the sweep is (spec hash, rows, chunks) and
                                       each saved chunk's wall time ("timing")
    <output>/chunks/chunk-00012.parquet one file per finished chunk
    <output>/table.parquet              all chunks in row order, once every chunk exists
    <output>/table.csv                  the same, when csv was requested

Every file is written to a temporary name in the same directory, flushed to disk and
then renamed over its final name (`os.replace`), so a file that exists is complete.
A chunk file on disk is a finished chunk: resuming never recomputes or duplicates it.
One process at a time per output directory (there is no lock).
"""

from __future__ import annotations

import functools
import json
import os
import re
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any, Literal

import pyarrow as pa
import pyarrow.csv as pa_csv
import pyarrow.parquet as pq

from jaxloco import paths
from jaxloco.errors import SpecError
from jaxloco.sweep.schema import METADATA_KEY

MANIFEST = "manifest.json"
CHUNKS = "chunks"
TABLE = "table.parquet"
CSV = "table.csv"
TMP_PREFIX = ".tmp-"
TIMING = "timing"  # manifest key: per-chunk wall times (see record_chunk_time)
_CHUNK_NAME = re.compile(r"^chunk-(\d+)\.parquet$")

Mode = Literal["new", "resume", "overwrite"]


def chunk_path(out: Path, index: int) -> Path:
    return out / CHUNKS / f"chunk-{index:05d}.parquet"


@functools.cache
def _file_mode() -> int:
    """The permissions a plain `open()` would give a new file (mkstemp's are owner-only)."""
    umask = os.umask(0o022)
    os.umask(umask)
    return 0o666 & ~umask


def atomic_write(path: Path, write: Callable[[Path], None]) -> None:
    """Call `write(tmp)` for a temporary file next to `path`, then move it onto `path`."""
    fd, name = tempfile.mkstemp(prefix=TMP_PREFIX + path.name + ".", dir=path.parent)
    os.close(fd)
    tmp = Path(name)
    try:
        write(tmp)
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())
        os.chmod(tmp, _file_mode())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_json(path: Path, obj: Any) -> None:
    atomic_write(path, lambda tmp: tmp.write_text(json.dumps(obj, indent=2) + "\n"))


def check_output(out: Path, spec_hash: str, *, resume: bool, overwrite: bool) -> Mode:
    """Decide what to do with the output directory (nothing is written; SpecError if refused)."""
    if resume and overwrite:
        raise SpecError("pass either --resume or --overwrite, not both")
    if paths.exists(out, where="output") and not paths.is_dir(out):
        raise SpecError(f"output {out} exists and is not a directory")
    if not paths.exists(out) or not any(out.iterdir()):
        return "new"
    has_manifest = (out / MANIFEST).is_file()
    if overwrite:
        if not has_manifest:
            raise SpecError(f"output {out} exists but is not a sweep output (no {MANIFEST}); refusing to delete it")
        return "overwrite"
    if not resume:
        raise SpecError(f"output {out} exists; pass --resume to continue it or --overwrite to start again")
    if not has_manifest:
        raise SpecError(f"output {out} exists but has no {MANIFEST}, so there is no sweep to resume")
    old = read_manifest(out).get("spec_hash")
    if old != spec_hash:
        raise SpecError(
            f"output {out} was made from a different spec (hash {str(old)[:12]}, now {spec_hash[:12]});"
            " pass --overwrite to start again or choose another --out"
        )
    return "resume"


def read_manifest(out: Path) -> dict[str, Any]:
    path = out / MANIFEST
    try:
        manifest = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise SpecError(f"{path}: unreadable ({exc}); pass --overwrite to start again") from None
    if not isinstance(manifest, dict):
        raise SpecError(f"{path}: not a sweep manifest; pass --overwrite to start again")
    return manifest


def record_chunk_time(out: Path, index: int, seconds: float, *, first: bool) -> None:
    """Add chunk `index`'s wall time [s] to the manifest's "timing" (`chunk_times` reads it).

    seconds: since the previous chunk of the run was saved (or, for the run's first chunk,
    since computing started: that one includes compiling; first=True marks it). Timing
    is not part of the spec hash nor of any table: resuming and the tables are unchanged.
    """
    manifest = read_manifest(out)
    timing = manifest.setdefault(TIMING, {"seconds": {}, "first": []})
    timing["seconds"][str(index)] = round(float(seconds), 4)
    if first and index not in timing["first"]:
        timing["first"].append(index)
    write_json(out / MANIFEST, manifest)


def chunk_times(manifest: dict[str, Any]) -> tuple[dict[int, float], set[int]]:
    """The recorded wall time [s] per chunk index and the indices that include compiling
    (empty for a manifest written before timing was recorded, or a malformed one)."""
    timing = manifest.get(TIMING)
    try:
        seconds = {int(k): float(v) for k, v in timing["seconds"].items()}
        first = {int(i) for i in timing["first"]}
    except (AttributeError, KeyError, TypeError, ValueError):
        return {}, set()
    return seconds, first


def open_output(out: Path, manifest: dict[str, Any], mode: Mode) -> None:
    """Create (or clear, for "overwrite") the directory and write the manifest."""
    if mode == "overwrite":
        clear(out)
    (out / CHUNKS).mkdir(parents=True, exist_ok=True)
    _remove_temporaries(out)
    if mode != "resume":
        write_json(out / MANIFEST, manifest)


def clear(out: Path) -> None:
    """Remove what a sweep writes (other files in the directory are left alone)."""
    shutil.rmtree(out / CHUNKS, ignore_errors=True)
    for name in (MANIFEST, TABLE, CSV):
        (out / name).unlink(missing_ok=True)
    _remove_temporaries(out)


def _remove_temporaries(out: Path) -> None:
    for folder in (out, out / CHUNKS):
        if folder.is_dir():
            for path in folder.glob(TMP_PREFIX + "*"):
                path.unlink(missing_ok=True)


def saved_chunks(out: Path, bounds: list[tuple[int, int]], spec_hash: str) -> tuple[set[int], list[str]]:
    """Indices of the chunk files that are complete, and warnings about unreadable ones.

    An unreadable chunk file (e.g. cut short by a crash of the machine) is deleted so the
    chunk is computed again. A readable one of another sweep is an error.
    """
    done: set[int] = set()
    warnings: list[str] = []
    folder = out / CHUNKS
    if not folder.is_dir():
        return done, warnings
    for path in sorted(folder.iterdir()):
        match = _CHUNK_NAME.match(path.name)
        if not match or int(match.group(1)) >= len(bounds):
            continue
        index = int(match.group(1))
        try:
            meta = pq.read_metadata(path)
        except (OSError, pa.ArrowException) as exc:
            path.unlink(missing_ok=True)
            warnings.append(f"{path}: unreadable ({exc}); computing it again")
            continue
        start, stop = bounds[index]
        described = json.loads((meta.metadata or {}).get(METADATA_KEY, b"{}"))
        if meta.num_rows != stop - start or described.get("spec_hash") != spec_hash:
            raise SpecError(f"{path}: does not belong to this sweep; pass --overwrite to start again")
        done.add(index)
    return done, warnings


def count_saved(out: Path, n_chunks: int) -> int:
    return sum(chunk_path(out, i).is_file() for i in range(n_chunks))


def write_chunk(out: Path, index: int, table: pa.Table) -> None:
    atomic_write(chunk_path(out, index), lambda tmp: pq.write_table(table, tmp))


def assemble(out: Path, n_chunks: int) -> pa.Table:
    """All chunks in row order, as one table."""
    tables = [pq.read_table(chunk_path(out, i)) for i in range(n_chunks)]
    table = pa.concat_tables(tables)
    return table.combine_chunks() if table.num_rows else table


def write_table(out: Path, table: pa.Table, *, csv: bool) -> list[Path]:
    """table.parquet (and table.csv when asked); returns the paths written."""
    written = [out / TABLE]
    atomic_write(out / TABLE, lambda tmp: pq.write_table(table, tmp))
    if csv:
        atomic_write(out / CSV, lambda tmp: pa_csv.write_csv(table, tmp))
        written.append(out / CSV)
    return written
