"""Watching JAX compile: its compile events (`/jax/core/compile/...`: tracing, lowering to
MLIR, compiling; a persistent-cache hit lowers too and skips only the XLA compile), and
lowerings counted per sweep chunk. A sweep compiles its programs for the first chunk and
reuses them for every later chunk of the same shape:

    result, per_chunk = run_counting(run, spec)
    per_chunk.assert_compiled_once()
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import jax
from tables import check_table

LOWERING_EVENT = "/jax/core/compile/jaxpr_to_mlir_module_duration"


@contextlib.contextmanager
def compile_events() -> Iterator[list[str]]:
    """The names of JAX's compile events while the block runs (the list grows live)."""
    events: list[str] = []

    def listener(event: str, duration: float, **kwargs) -> None:
        if event.startswith("/jax/core/compile/"):
            events.append(event)

    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        yield events
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)


class LoweringsPerChunk:
    """Lowerings recorded at the end of every chunk (`on_chunk`), from a live event list."""

    def __init__(self, events: list[str]) -> None:
        self.events = events
        self.at_chunk_end: list[int] = []

    def on_chunk(self, index: int, n_chunks: int) -> None:
        self.at_chunk_end.append(self.events.count(LOWERING_EVENT))

    def assert_compiled_once(self) -> None:
        """At least two chunks ran, and nothing was lowered after the first."""
        assert len(self.at_chunk_end) >= 2, f"the sweep ran {len(self.at_chunk_end)} chunk(s); the check needs two"
        after = self.at_chunk_end[-1] - self.at_chunk_end[0]
        assert after == 0, f"{after} lowering(s) after the first chunk (per chunk end: {self.at_chunk_end})"


def run_counting(run, spec, **kwargs):
    """`run(spec, on_chunk=..., **kwargs)` (a sweep) with its lowerings counted per chunk:
    (result, counter). Its table must also match the pinned one (`tables.check_table`):
    these small sweeps are the suite's check that a change keeps every analysis' results."""
    with compile_events() as events:
        counter = LoweringsPerChunk(events)
        result = run(spec, on_chunk=counter.on_chunk, **kwargs)
    check_table(result.table)
    return result, counter
