"""Exceptions of the sweep layer (user errors are `jaxloco.analysis.SpecError`)."""

from __future__ import annotations

from pathlib import Path


class AnalysisError(RuntimeError):
    """An analysis broke its contract (wrong outputs, clashing names): a bug, not a user error."""


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl+C (or a KeyboardInterrupt from `on_chunk`) during a sweep; saved chunks stay on disk."""

    def __init__(self, saved: int, total: int, path: Path) -> None:
        self.saved, self.total, self.path = saved, total, path
        super().__init__(f"interrupted: {saved} of {total} chunks saved in {path}; rerun with --resume")

    def __str__(self) -> str:
        return str(self.args[0])
