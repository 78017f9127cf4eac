"""Probing paths the user gave (spec files, tables, output directories) without crashing.

`Path.exists()` / `is_file()` / `is_dir()` raise OSError for a path the system cannot
look at (a name too long, a permission denied on a parent, a symlink loop) and ValueError
for a NUL character. The helpers here answer the same questions but turn those into one
`SpecError` line naming the path, so a command exits with a user error (code 2) instead
of a traceback. `where` prefixes the message (e.g. "spec.toml: validate.sweep").
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from jaxloco.errors import SpecError

_LABEL_MAX = 80


def short_label(path: str | os.PathLike[str]) -> str:
    """The path as text, its middle cut out when longer than 80 characters."""
    text = os.fspath(path)
    if len(text) <= _LABEL_MAX:
        return text
    return f"{text[:40]}...{text[-30:]} ({len(text)} characters)"


def unusable(path: str | os.PathLike[str], exc: BaseException, where: str | None = None) -> SpecError:
    """The one-line SpecError for a path the system refused to look at."""
    if isinstance(exc, ValueError):
        reason = "contains a NUL character"
    else:
        reason = (getattr(exc, "strerror", None) or str(exc) or type(exc).__name__).lower()
    prefix = f"{where}: " if where else ""
    return SpecError(f"{prefix}{short_label(path)}: cannot use this path ({reason})")


def mode(path: str | os.PathLike[str], where: str | None = None) -> int | None:
    """The file mode of `path` (following symlinks), None when nothing is there; SpecError
    when the path cannot be looked at (too long, permission denied, NUL character, ...)."""
    try:
        return Path(path).stat().st_mode
    except (FileNotFoundError, NotADirectoryError):
        return None
    except (OSError, ValueError) as exc:
        raise unusable(path, exc, where) from None


def exists(path: str | os.PathLike[str], where: str | None = None) -> bool:
    """`Path.exists()`, or one SpecError line when the path cannot be looked at."""
    return mode(path, where) is not None


def is_file(path: str | os.PathLike[str], where: str | None = None) -> bool:
    """`Path.is_file()`, or one SpecError line when the path cannot be looked at."""
    found = mode(path, where)
    return found is not None and stat.S_ISREG(found)


def is_dir(path: str | os.PathLike[str], where: str | None = None) -> bool:
    """`Path.is_dir()`, or one SpecError line when the path cannot be looked at."""
    found = mode(path, where)
    return found is not None and stat.S_ISDIR(found)
