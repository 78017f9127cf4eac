"""Counting JAX compilations during a sweep: a sweep compiles its programs for the first
chunk and reuses them for every later chunk of the same shape.

    with lowerings_per_chunk() as per_chunk:
        run(spec, on_chunk=per_chunk.on_chunk)
    per_chunk.assert_compiled_once()

JAX reports every lowering of a jitted program to MLIR (`/jax/core/compile/
jaxpr_to_mlir_module_duration`, also on a persistent-cache hit, which skips only the XLA
compile); eager operations lower once per shape too. After chunk 0 no lowering should
happen."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import jax

LOWERING_EVENT = "/jax/core/compile/jaxpr_to_mlir_module_duration"


class LoweringsPerChunk:
    """Lowerings counted since the start and recorded at the end of every chunk."""

    def __init__(self) -> None:
        self.total = 0
        self.at_chunk_end: list[int] = []

    def listener(self, event: str, duration: float, **kwargs) -> None:
        if event == LOWERING_EVENT:
            self.total += 1

    def on_chunk(self, index: int, n_chunks: int) -> None:
        self.at_chunk_end.append(self.total)

    def after_first_chunk(self) -> int:
        """Lowerings after the first chunk was saved."""
        return self.at_chunk_end[-1] - self.at_chunk_end[0]

    def assert_compiled_once(self) -> None:
        assert len(self.at_chunk_end) >= 2, f"the sweep ran {len(self.at_chunk_end)} chunk(s); the check needs two"
        assert self.at_chunk_end[0] > 0 or self.total == 0
        assert self.after_first_chunk() == 0, (
            f"{self.after_first_chunk()} lowering(s) after the first chunk (per chunk end: {self.at_chunk_end})"
        )


@contextlib.contextmanager
def lowerings_per_chunk() -> Iterator[LoweringsPerChunk]:
    counter = LoweringsPerChunk()
    jax.monitoring.register_event_duration_secs_listener(counter.listener)
    try:
        yield counter
    finally:
        jax.monitoring.unregister_event_duration_listener(counter.listener)


def run_counting(run, spec, **kwargs):
    """`run(spec, on_chunk=..., **kwargs)` (a sweep) with its lowerings counted per chunk:
    (result, counter)."""
    with lowerings_per_chunk() as counter:
        result = run(spec, on_chunk=counter.on_chunk, **kwargs)
    return result, counter
