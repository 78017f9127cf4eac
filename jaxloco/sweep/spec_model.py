"""The structure of a sweep spec (pydantic models) and one-line messages for its errors."""

from __future__ import annotations

import difflib
import os
import re
import tomllib
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, ValidationError, field_validator

from jaxloco.errors import SpecError
from jaxloco.paths import short_label

MAX_ROWS = 100_000_000
MAX_SEED = 2**31  # exclusive; keeps jax.random.PRNGKey(seed) identical with and without x64
DEFAULT_CHUNK_SIZE = 256

MAX_NAME_LENGTH = 100
NAME_CHARS = "letters, digits, _, - and ."

NonEmptyStr = Annotated[str, Field(min_length=1)]


def name_problem(name: str) -> str | None:
    """Why `name` cannot name a spec (its default output is results/<name>), or None: a
    name is 1..100 of letters, digits, _, - and ., and not "." or ".."."""
    if not name:
        return "must not be empty"
    if len(name) > MAX_NAME_LENGTH:
        return f"is {len(name)} characters long, more than {MAX_NAME_LENGTH}"
    if "/" in name or "\\" in name:
        return f"{name!r} contains a path separator; a name is {NAME_CHARS} (choose the directory with output or --out)"
    if name in (".", ".."):
        return f"{name!r} is not a name; a name is {NAME_CHARS}"
    bad = re.search(r"[^A-Za-z0-9_.-]", name)
    if bad:
        return f"{name!r} contains {bad.group()!r}; a name is {NAME_CHARS}"
    return None


def _check_name(name: str) -> str:
    problem = name_problem(name)
    if problem:
        raise ValueError(problem)
    return name


PlainName = Annotated[str, AfterValidator(_check_name)]


def name_from_stem(stem: str, source: str, key: str) -> str:
    """The name of a spec without one: its file's stem, each run of characters other than
    letters, digits, _, - and . replaced by "_" ("my sweep.toml" -> "my_sweep"); SpecError
    naming `key` when that is still no name (".", "..", over 100 characters)."""
    name = re.sub(r"[^A-Za-z0-9_.-]+", "_", stem)
    problem = name_problem(name)
    if problem:
        section, field = key.split(".")
        given = f"the file's stem '{short_label(stem)}'"
        raise error(source, key, f"not given, and {given} cannot be the name ({problem}); set {field} in [{section}]")
    return name


def _number(x: float) -> str:
    """A bound as text: whole numbers with thousands separators (1,000,000), others as %g."""
    return f"{int(x):,}" if float(x).is_integer() and abs(x) < 1e15 else f"{x:g}"


def bounded(lo: float, hi: float, *, lo_open: bool = False) -> AfterValidator:
    """A pydantic check that a number is in [lo, hi] ((lo, hi] with lo_open); its message
    names the whole range: "must be > 0 and <= 10, got 1e+308"."""

    def check(v: float) -> float:
        if (v <= lo if lo_open else v < lo) or v > hi:
            raise ValueError(f"must be {'>' if lo_open else '>='} {_number(lo)} and <= {_number(hi)}, got {v!r}")
        return v

    return AfterValidator(check)


class StrictModel(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)


class SweepSection(StrictModel):
    analysis: NonEmptyStr
    name: PlainName | None = None
    output: NonEmptyStr | None = None
    chunk_size: int = Field(DEFAULT_CHUNK_SIZE, ge=1)
    seeds: list[int] = [0]
    combine: Literal["product", "zip"] = "product"
    zip: list[list[str]] | None = None
    formats: list[Literal["parquet", "csv"]] = ["parquet"]

    @field_validator("output", mode="before")
    @classmethod
    def _path_to_str(cls, v: Any) -> Any:
        return os.fspath(v) if isinstance(v, os.PathLike) else v

    @field_validator("seeds", mode="before")
    @classmethod
    def _seed_count(cls, v: Any) -> Any:
        if isinstance(v, int) and not isinstance(v, bool):
            if v < 1:
                raise ValueError(f"a seed count must be >= 1, got {v}")
            return list(range(v))
        return v

    @field_validator("seeds")
    @classmethod
    def _seed_values(cls, v: list[int]) -> list[int]:
        if not v:
            raise ValueError("empty list; give at least one seed")
        for s in v:
            if not 0 <= s < MAX_SEED:
                raise ValueError(f"seed {s} is outside [0, {MAX_SEED})")
        dup = sorted({s for s in v if v.count(s) > 1})
        if dup:
            raise ValueError(f"duplicate seed {dup[0]}")
        return v


class SpecDoc(StrictModel):
    sweep: SweepSection
    fixed: dict[str, Any] = {}
    params: dict[str, Any] = {}


class RangeModel(StrictModel):
    start: float
    stop: float
    num: int | None = Field(None, ge=1)
    step: float | None = Field(None, gt=0)
    scale: Literal["linear", "log"] = "linear"


# ---------------------------------------------------------------------------- errors


def _key(loc: tuple[Any, ...]) -> str:
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def _known_keys(model: type[BaseModel], parent: tuple[Any, ...]) -> list[str]:
    for part in parent:
        field = model.model_fields.get(part) if isinstance(part, str) else None
        sub = getattr(field, "annotation", None) if field else None
        if not (isinstance(sub, type) and issubclass(sub, BaseModel)):
            return []
        model = sub
    return list(model.model_fields)


def _pydantic_problem(err: dict[str, Any], model: type[BaseModel]) -> str:
    kind, value, ctx = err["type"], err.get("input"), err.get("ctx") or {}
    if kind == "extra_forbidden":
        known = _known_keys(model, tuple(err["loc"][:-1]))
        close = difflib.get_close_matches(str(err["loc"][-1]), known, n=1)
        if close:
            return f"unknown key (did you mean '{close[0]}'?)"
        return f"unknown key (known: {', '.join(known)})" if known else "unknown key"
    if kind == "missing":
        return "required key is missing"
    expected = {
        "int_type": "an integer",
        "int_parsing": "an integer",
        "int_from_float": "an integer",
        "float_type": "a number",
        "float_parsing": "a number",
        "string_type": "a string",
        "list_type": "a list",
        "dict_type": "a table",
        "model_type": "a table",
        "model_attributes_type": "a table",
        "bool_type": "true or false",
        "finite_number": "a finite number",
    }.get(kind)
    if expected:
        return f"expected {expected}, got {value!r}"
    if kind == "literal_error":
        return f"expected {ctx.get('expected')}, got {value!r}"
    if kind == "greater_than_equal":
        return f"must be >= {ctx.get('ge')}, got {value!r}"
    if kind == "greater_than":
        return f"must be > {ctx.get('gt')}, got {value!r}"
    if kind == "string_too_short":
        return "must not be empty"
    if kind == "value_error":
        return str(ctx.get("error", err["msg"]))
    return f"{err['msg']}, got {value!r}"


def validate(model: type[BaseModel], data: Any, source: str, prefix: tuple[Any, ...] = ()) -> Any:
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        err = exc.errors(include_url=False)[0]
        loc = prefix + tuple(err["loc"])
        where = f"{_key(loc)}: " if loc else ""
        raise SpecError(f"{source}: {where}{_pydantic_problem(err, model)}") from None


def error(source: str, key: str, problem: str) -> SpecError:
    return SpecError(f"{source}: {key}: {problem}")


def read_toml(path: str | Path) -> dict[str, Any]:
    """A TOML file as a dict; SpecError (one line, naming the file) if it cannot be read."""
    label = os.fspath(path)
    try:
        data = Path(path).read_bytes()
    except FileNotFoundError:
        raise SpecError(f"{label}: no such file") from None
    except IsADirectoryError:
        raise SpecError(f"{label}: is a directory, expected a TOML file") from None
    except OSError as exc:
        raise SpecError(f"{label}: cannot read ({exc.strerror or exc})") from None
    except ValueError:  # a NUL character in the path
        raise SpecError(f"{label}: cannot read (the path contains a NUL character)") from None
    try:
        return tomllib.loads(data.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise SpecError(f"{label}: not UTF-8 text (bad byte at offset {exc.start})") from None
    except tomllib.TOMLDecodeError as exc:
        raise SpecError(f"{label}: invalid TOML: {exc}") from None
