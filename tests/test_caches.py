"""The size bound of the two on-disk caches (JAX's compilation cache, the program cache):
`runtime.cache_max_bytes` reads `$JAXLOCO_CACHE_MAX_MB`, `runtime.prune_cache` removes the
oldest entries, `runtime.configure` prunes the compilation cache and `sim.programs` the
program cache after each write, touching the files it loads."""

from __future__ import annotations

import importlib.metadata
import os
import subprocess
import sys
import time

import jax.numpy as jnp
import pytest

from jaxloco import runtime
from jaxloco.errors import SpecError

MB = 2**20


def _entry(path, size, age_s, now):
    path.write_bytes(b"x" * size)
    os.utime(path, (now - age_s, now - age_s))
    return path


def test_cache_bound_reads_the_environment(monkeypatch):
    monkeypatch.delenv(runtime.ENV_CACHE_MAX, raising=False)
    assert runtime.cache_max_bytes() == runtime.DEFAULT_CACHE_MAX_MB * MB
    monkeypatch.setenv(runtime.ENV_CACHE_MAX, "2.5")
    assert runtime.cache_max_bytes() == int(2.5 * MB)
    monkeypatch.setenv(runtime.ENV_CACHE_MAX, " -1 ")
    assert runtime.cache_max_bytes() is None
    for bad in ("abc", "0", "-2", "inf", "nan"):
        monkeypatch.setenv(runtime.ENV_CACHE_MAX, bad)
        with pytest.raises(SpecError, match=runtime.ENV_CACHE_MAX):
            runtime.cache_max_bytes()


def test_prune_removes_the_oldest_entries_and_nothing_else(tmp_path):
    now = time.time()
    old, mid, new = (_entry(tmp_path / f"{n}-cache", 400, age, now) for n, age in (("a", 300), ("b", 200), ("c", 100)))
    other = _entry(tmp_path / "notes.txt", 5000, 10_000, now)  # not an entry: never touched
    (tmp_path / "sub-cache").mkdir()  # a directory named like one: skipped
    removed = runtime.prune_cache(tmp_path, 900, suffix="-cache", now=now)
    assert removed == [old]
    assert not old.exists() and mid.exists() and new.exists() and other.exists()
    assert runtime.prune_cache(tmp_path, 800, suffix="-cache", now=now) == []  # already within
    assert runtime.prune_cache(tmp_path, 399, suffix="-cache", now=now) == [mid, new]
    assert runtime.prune_cache(tmp_path, None, suffix="-cache", now=now) == []
    assert runtime.prune_cache(tmp_path / "missing", 0, suffix="-cache", now=now) == []


def test_prune_removes_stale_temporary_files_only(tmp_path):
    now = time.time()
    stale = _entry(tmp_path / "k1.123.tmp", 10, runtime.STALE_TMP_S + 5, now)
    live = _entry(tmp_path / "k2.456.tmp", 10, 5, now)
    kept = _entry(tmp_path / "k3.bin", 10, 10 * runtime.STALE_TMP_S, now)
    removed = runtime.prune_cache(tmp_path, None, suffix=".bin", tmp_suffix=".tmp", now=now)
    assert removed == [stale] and live.exists() and kept.exists()


def test_configure_prunes_the_compilation_cache(tmp_path):
    """In a fresh process (configure points this one's JAX at its cache for good)."""
    now = time.time()
    cache = tmp_path / "jax"
    cache.mkdir()
    old = _entry(cache / "jit_f-1-cache", MB // 2, 100, now)
    new = _entry(cache / "jit_f-2-cache", MB // 2, 10, now)
    env = {**os.environ, runtime.ENV_CACHE_MAX: "0.6"}
    code = f"from jaxloco import runtime; runtime.configure(cache_dir={str(cache)!r})"
    subprocess.run([sys.executable, "-c", code], env=env, check=True, timeout=120)
    assert not old.exists() and new.exists()


def test_a_loaded_program_is_touched_and_a_write_prunes_the_oldest(tmp_path, monkeypatch):
    from jaxloco.sim import programs

    monkeypatch.setenv(programs.ENV_SWITCH, str(tmp_path))
    x = jnp.arange(3.0)
    programs.load_or_export(lambda: lambda v: 2.0 * v, "k1", (x,))
    first = tmp_path / f"k1{runtime.PROGRAM_SUFFIX}"
    size = first.stat().st_size
    os.utime(first, (1.0, 1.0))
    run = programs.load_or_export(lambda: pytest.fail("traced again"), "k1", (x,))
    assert jnp.array_equal(run(x), 2.0 * x)
    assert first.stat().st_mtime > 1e9  # touched: the most recently used
    stale = _entry(tmp_path / f"k0{runtime.PROGRAM_SUFFIX}", size, 1000, time.time())
    monkeypatch.setenv(runtime.ENV_CACHE_MAX, str(2.5 * size / MB))  # room for two programs
    programs.load_or_export(lambda: lambda v: 3.0 * v, "k2", (x,))
    assert not stale.exists() and first.exists() and (tmp_path / f"k2{runtime.PROGRAM_SUFFIX}").exists()


def test_a_cached_program_compiles_once_for_fresh_inputs_and_other_programs_outputs(tmp_path, monkeypatch):
    """`jax.jit` lowers committed and uncommitted arguments to different programs; the
    cached program's runner commits fresh inputs, so a program called with new arrays,
    NumPy arrays and then the committed outputs of another program (a tuning step)
    lowers once. Inside an outer trace it is left to the outer program."""
    import jax
    import numpy as np
    from compile_count import LOWERING_EVENT

    from jaxloco.sim import programs

    monkeypatch.setenv(programs.ENV_SWITCH, str(tmp_path))
    lowered = []

    def listener(event, duration, **kwargs):
        if event == LOWERING_EVENT:
            lowered.append(kwargs.get("fun_name"))

    x = jnp.arange(3.0) + 0.25  # uncommitted
    run = programs.load_or_export(lambda: lambda v, w: v * w, "k_commit", (x, x))
    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        first = run(x, x)
        other = jax.jit(lambda v: v + 1.0)(first)  # the output of a program run on committed inputs
        results = [first, run(np.asarray(x), x), run(other, x), run(other, other)]
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)
    assert other.committed
    assert lowered.count("jit(call)") == 1, lowered  # the cached program (exported.call), once
    np.testing.assert_array_equal(results[0], x * x)
    np.testing.assert_array_equal(results[2], np.asarray(other) * np.asarray(x))
    assert all(r.committed for r in results)
    traced = jax.jit(lambda v: run(v, v))(x)
    np.testing.assert_array_equal(traced, x * x)


def test_a_tune_objectives_evaluate_is_loaded_by_a_later_process(tmp_path, monkeypatch):
    """`runner.jitted_value_and_grad` (what `runner.make_evaluate` jits) keys the loss by
    value: a loss built again (as in a new process) is evaluated from the kept program
    without tracing, with the values and gradients of the plain jit."""
    import jax

    from jaxloco.sim import programs
    from jaxloco.tune import objective as registry
    from jaxloco.tune import runner

    monkeypatch.setenv(programs.ENV_SWITCH, str(tmp_path))
    objective = registry.get("octopus.sigma")
    settings = {p.name: p.default for p in objective.settings} | {"samples": 64}
    values = {t.name: jnp.asarray(t.default, jnp.float32) for t in objective.tunables}
    traced = []

    def make(loss):
        return lambda: traced.append(1) or runner.value_and_grad(loss, "reverse")

    label = "test octopus.sigma"
    first = programs.CachedJit(objective.make_loss(settings), label, make(objective.make_loss(settings)))(values)
    again = objective.make_loss(settings)
    second = programs.CachedJit(again, label, make(again))(values)
    assert len(traced) == 1 and len(list(tmp_path.glob(f"*{runtime.PROGRAM_SUFFIX}"))) == 1
    plain = jax.jit(runner.value_and_grad(again, "reverse"))(values)
    via_runner = runner.jitted_value_and_grad(again, "reverse", None, "octopus.sigma")(values)
    for other in (second, plain, via_runner):
        for a, b in zip(jax.tree_util.tree_leaves(first), jax.tree_util.tree_leaves(other)):
            assert jnp.array_equal(a, b)


def test_a_programs_source_digest_covers_the_core_and_the_robots_its_pickle_names(tmp_path):
    """`programs.source_digest` of a package tree: an edit to the core or to a named
    robot changes it, an edit to another robot does not; a pickle naming a robot counts
    that robot, one naming a module that imports robots (the render package) counts all."""
    from jaxloco.sim import programs

    root = tmp_path / "pkg"
    for rel in ("core.py", "robots/__init__.py", "robots/a/__init__.py", "robots/a/x.py",
                "robots/b/__init__.py", "robots/b/y.py", "robots/notes/readme.py"):
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(f"# {rel}\n")
    robots = programs.robot_packages(root)
    assert robots == ("a", "b")  # a directory without __init__.py is not a robot

    def digest(named):  # uncached: the files change between calls
        return programs.source_digest.__wrapped__(root, frozenset(named))

    a0, b0, none0 = digest({"a"}), digest({"b"}), digest(())
    (root / "robots/b/y.py").write_text("# edited\n")
    assert digest({"a"}) == a0 and digest(()) == none0 and digest({"b"}) != b0
    (root / "robots/a/x.py").write_text("# edited\n")
    assert digest({"a"}) != a0 and digest(()) == none0
    (root / "core.py").write_text("# edited\n")
    assert digest(()) != none0

    assert programs.robots_named(b"...jaxloco.robots.a.x...", robots) == {"a"}
    assert programs.robots_named(b"jaxloco.sim.native", robots) == set()
    assert programs.robots_named(b"jaxloco.render.replay", robots) == {"a", "b"}


def test_the_fast_xla_flags_are_added_unless_already_named():
    """runtime.FAST_XLA_CPU_FLAGS go into $XLA_FLAGS (tests/conftest.py with the fast
    compile, `runtime.configure` before JAX starts); a flag the user set wins, and other
    flags are kept."""
    assert runtime.with_xla_flags("", ("--a=false",)) == "--a=false"
    assert runtime.with_xla_flags(" --b=1 ", ("--a=false",)) == "--b=1 --a=false"
    assert runtime.with_xla_flags("--a=true --b=1", ("--a=false",)) == "--a=true --b=1"
    fast = os.environ.get("JAX_DISABLE_MOST_OPTIMIZATIONS", "").lower() not in ("0", "false", "")
    named = {f.split("=", 1)[0] for f in os.environ.get("XLA_FLAGS", "").split()}
    assert all(f.split("=", 1)[0] in named for f in runtime.FAST_XLA_CPU_FLAGS) or not fast


def test_the_legacy_emitter_flag_is_set_only_where_jaxlib_has_it():
    """jaxlib 0.11's XLA aborts on the legacy-emitter flag (an unknown flag): it is part of
    FAST_XLA_CPU_FLAGS for jaxlib < 0.11 only, read from the package metadata."""
    assert runtime.xla_has_legacy_cpu_emitters("0.10.2") and runtime.xla_has_legacy_cpu_emitters("0.9.0.1")
    assert not runtime.xla_has_legacy_cpu_emitters("0.11.2") and not runtime.xla_has_legacy_cpu_emitters("0.12.0")
    assert not runtime.xla_has_legacy_cpu_emitters("1.0.0") and not runtime.xla_has_legacy_cpu_emitters("dev")
    installed = runtime.xla_has_legacy_cpu_emitters(importlib.metadata.version("jaxlib"))
    assert bool(runtime.FAST_XLA_CPU_FLAGS) == installed


_USER_FLAG = "--xla_cpu_use_fusion_emitters=true"  # the user's own setting of the flag (jaxlib < 0.11 knows it)


@pytest.mark.parametrize("flags, user", [(runtime.FAST_XLA_CPU_FLAGS, ""), ((), ""),
                                         (runtime.FAST_XLA_CPU_FLAGS, _USER_FLAG)])
def test_configure_sets_the_xla_flags_before_jax_starts(flags, user):
    """In a fresh process, `runtime.configure` adds its XLA flags to $XLA_FLAGS before the
    first computation (none with xla_cpu_flags=(); the user's own setting wins); once
    JAX's backend has started it leaves $XLA_FLAGS alone."""
    code = (
        "import os, jax\n"
        "from jaxloco import runtime\n"
        f"runtime.configure(x64=True, cache_dir=False, xla_cpu_flags={tuple(flags)!r})\n"
        "print(os.environ.get('XLA_FLAGS', ''))\n"
        "jax.numpy.ones(1).block_until_ready()\n"
        "os.environ['XLA_FLAGS'] = 'unchanged'\n"
        "runtime.configure(x64=True, cache_dir=False)\n"
        "print(os.environ['XLA_FLAGS'])\n"
    )
    if user and not runtime.FAST_XLA_CPU_FLAGS:
        pytest.skip("this jaxlib's XLA has no legacy-emitter flag to set")
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    if user:
        env["XLA_FLAGS"] = user
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    first, second = out.stdout.split("\n")[:2]
    assert first == runtime.with_xla_flags(user, tuple(flags))
    assert second == "unchanged"
