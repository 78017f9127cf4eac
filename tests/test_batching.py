"""`batching.vmap_in_blocks` equals `jax.vmap` (pytree arguments and outputs, a shared
argument, a batch that is not a multiple of the block, one or two groups, a gradient
through it) and refuses bad settings with one-line errors."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxloco.batching import vmap_in_blocks


def _fn(scene, weight):
    """A per-instance function of a pytree: a dict of outputs."""
    p, m = scene["points"], scene["mask"]
    return {"sum": jnp.sum(jnp.where(m[:, None], p, 0.0) * weight), "first": p[0] * weight}


@pytest.mark.parametrize("size, groups", [(5, None), (64, None), (300, None), (300, 1), (298, 2), (300, 4)])
def test_equals_one_vmap(size, groups):
    rng = np.random.default_rng(size)
    scene = {"points": jnp.asarray(rng.normal(size=(size, 6, 2))), "mask": jnp.asarray(rng.random((size, 6)) > 0.3)}
    weight = jnp.asarray(1.5)  # shared: no batch axis
    want = jax.vmap(_fn, in_axes=(0, None))(scene, weight)
    got = jax.jit(vmap_in_blocks(_fn, block=64, in_axes=(0, None), groups=groups))(scene, weight)
    for key in want:
        assert got[key].shape == want[key].shape
        np.testing.assert_allclose(np.asarray(got[key]), np.asarray(want[key]), rtol=1e-14)

    def loss(f, w):
        return jnp.sum(f(scene, w)["sum"] ** 2)

    g_blocked = jax.grad(lambda w: loss(vmap_in_blocks(_fn, block=64, in_axes=(0, None), groups=groups), w))(weight)
    g_vmap = jax.grad(lambda w: loss(jax.vmap(_fn, in_axes=(0, None)), w))(weight)
    np.testing.assert_allclose(float(g_blocked), float(g_vmap), rtol=1e-12)


def test_bad_settings():
    x = jnp.ones((3, 2))
    with pytest.raises(ValueError, match="block"):
        vmap_in_blocks(jnp.sum, block=0)
    with pytest.raises(ValueError, match="in_axes"):
        vmap_in_blocks(jnp.sum, in_axes=(1,))(x)
    with pytest.raises(ValueError, match="no argument"):
        vmap_in_blocks(jnp.sum, in_axes=None)(x)
    with pytest.raises(ValueError, match="groups"):
        vmap_in_blocks(jnp.sum, groups=0)
    with pytest.raises(ValueError, match="groups"):
        vmap_in_blocks(jnp.sum, block=2, groups=2)(jnp.ones((5, 2)))


def test_a_sharded_batch_stays_on_its_devices():
    """With the batch sharded over the devices (as a sweep shards it) the blocked program
    moves no member between devices: its compiled text has no collective, and the
    values are one vmap's."""
    devices = jax.devices()
    if len(devices) < 2:
        pytest.skip("needs two JAX devices")
    mesh = jax.sharding.Mesh(np.array(devices[:2]), ("batch",))
    sharded = jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec("batch"))
    rng = np.random.default_rng(0)
    scene = jax.device_put({"points": jnp.asarray(rng.normal(size=(1000, 6, 2))),
                            "mask": jnp.asarray(rng.random((1000, 6)) > 0.3)}, sharded)
    blocked = jax.jit(vmap_in_blocks(_fn, block=128, in_axes=(0, None), groups=2))
    text = blocked.lower(scene, 1.5).compile().as_text()
    assert not any(op in text for op in ("all-gather", "all-to-all", "collective-permute", "all-reduce"))
    got, want = blocked(scene, 1.5), jax.vmap(_fn, in_axes=(0, None))(scene, 1.5)
    np.testing.assert_allclose(np.asarray(got["sum"]), np.asarray(want["sum"]), rtol=1e-13, atol=1e-15)
