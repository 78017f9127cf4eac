"""Every exception jaxloco raises on purpose, in one place.

User errors (a wrong spec, parameter value, file, name) are `SpecError`: the CLI prints
its one-line message and exits non-zero. Broken contracts (`AnalysisError`,
`ObjectiveError`) are bugs in an analysis or objective, not user errors. Interruptions
(`SweepInterrupted`, `TuneInterrupted`) say what was saved; `TuneDiverged` stops a tuning
whose loss or gradient is not finite."""

from __future__ import annotations

from pathlib import Path


class SpecError(ValueError):
    """A user input (spec, parameter value, file) is wrong; the message is one line."""


class AnalysisError(RuntimeError):
    """An analysis broke its contract (wrong outputs, clashing names): a bug, not a user error."""


class ObjectiveError(RuntimeError):
    """An objective broke its contract (loss not a scalar, clashing aux names): a bug, not a user error."""


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl+C (or a KeyboardInterrupt from `on_chunk`) during a sweep; saved chunks stay on disk."""

    def __init__(self, saved: int, total: int, path: Path) -> None:
        self.saved, self.total, self.path = saved, total, path
        super().__init__(f"interrupted: {saved} of {total} chunks saved in {path}; rerun with --resume")

    def __str__(self) -> str:
        return str(self.args[0])


class TuneInterrupted(KeyboardInterrupt):
    """Ctrl+C (or a KeyboardInterrupt from `on_step`) during a tuning; what was computed is on disk."""

    def __init__(self, done: int, total: int, path: Path | None) -> None:
        self.done, self.total, self.path = done, total, path
        where = f"the loss curve and the best values so far are in {path}" if path else "nothing was written"
        super().__init__(f"interrupted after {done} of {total} steps; {where}")

    def __str__(self) -> str:
        return str(self.args[0])


class TuneDiverged(RuntimeError):
    """The loss or its gradient is not finite at a step; the run stopped (the curve is on disk)."""

    def __init__(self, message: str, step: int, path: Path) -> None:
        self.step, self.path = step, path
        super().__init__(message)
