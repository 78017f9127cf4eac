"""XLA's backend optimisations back on for a block of a test (the suite turns them off,
`tests/conftest.py`): for MJX rollouts, whose programs compile no faster without them
but run 2-3x slower (measured on TITAN XI's walk: 76 s to compile either way, 20 s vs
8.7 s to run one gait cycle). Programs compiled inside the block keep their setting;
the persistent cache keys them apart.

    with optimized():
        result = rollout(scenario, params, backend="mjx")
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import jax

FLAG = "jax_disable_most_optimizations"


@contextlib.contextmanager
def optimized() -> Iterator[None]:
    """Compile with XLA's optimisations inside the block; the previous setting after it."""
    before = jax.config.read(FLAG)
    jax.config.update(FLAG, False)
    try:
        yield
    finally:
        jax.config.update(FLAG, before)
