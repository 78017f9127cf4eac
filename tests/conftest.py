"""Test session setup: float64 available (float32 is tested with explicit dtypes) and
JAX's persistent compilation cache outside the repository, so later runs compile less."""

from jaxloco import runtime

runtime.configure(x64=True, cache_dir=True)
