"""Where a sweep's chunks are computed: in this process ("local") or as Ray tasks ("ray").

An executor turns the driver's `SweepWork` and the indices of the chunks still to do
into `(index, chunk table)` pairs, in the order the chunks finish; the driver
(`jaxloco.sweep.runner.run`) writes each chunk file as it arrives, advances the
progress bar and assembles the table, whatever the executor. Both executors compute a
chunk with the same function (`chunks.compute_chunk`), so their tables are equal.

The Ray executor sends a `ChunkJob` (the spec in its TOML layout, plain data) once to
the object store and submits one task per chunk (`num_cpus` / `num_gpus` per task); a
worker process prepares and jits the batch function once per sweep and keeps it for
its next chunks. At most `IN_FLIGHT_PER_SLOT` tasks per parallel slot are submitted at a
time. When the driver is interrupted, chunks that already finished are still handed over
(and saved) and no further task is submitted; the few tasks in flight are left to end
(see `RayExecutor.chunks` on why they are not cancelled). Workers must be able to import
jaxloco (and the module of an analysis registered at run time, unless it is defined in
`__main__` or in a closure, which Ray sends by value): on one machine the driver's
virtualenv does it; on a cluster install jaxloco on every node or use a Ray `runtime_env`.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import re
import socket
import warnings
from collections.abc import Iterator, Sequence
from typing import Any, Protocol

import pyarrow as pa

from jaxloco.errors import SpecError
from jaxloco.sweep.chunks import ChunkJob, SweepWork, compute_chunk, compute_job_chunk, prepare

EXECUTORS = ("local", "ray")
RAY_MISSING = 'the ray executor needs Ray: pip install "jaxloco[ray]"'
CONNECT_TIMEOUT_S = 5.0  # a host:port that does not answer within this is refused
IN_FLIGHT_PER_SLOT = 2  # tasks submitted ahead per task that can run at once


class Executor(Protocol):
    """Computes chunks of a sweep; see the module docstring."""

    name: str
    in_process: bool  # computes in the driver's process (gets the driver's batch function)

    def session(self) -> contextlib.AbstractContextManager[None]:
        """Set up (connect, start) before anything is written; SpecError if it cannot."""
        ...

    def chunks(self, work: SweepWork, todo: Sequence[int]) -> Iterator[tuple[int, pa.Table]]:
        """(index, table) of every chunk in `todo`, as each finishes."""
        ...


class LocalExecutor:
    """Every chunk in this process, in index order, on all of this process' JAX devices."""

    name = "local"
    in_process = True

    def session(self) -> contextlib.AbstractContextManager[None]:
        return contextlib.nullcontext()

    def chunks(self, work: SweepWork, todo: Sequence[int]) -> Iterator[tuple[int, pa.Table]]:
        if not todo:
            return
        prepared = prepare(work.spec, batch_fn=work.batch_fn)
        for index in todo:
            yield index, compute_chunk(prepared, index)


class RayExecutor:
    """One Ray task per chunk.

    address: None starts a local Ray instance with every core of this machine (or uses
    the one this process is already connected to); "auto", "host:6379" or
    "ray://host:10001" connect to an existing cluster. cpus_per_task / gpus_per_task:
    the resources each task asks for (gpus_per_task < 1 shares a GPU between workers).
    cpu_devices: JAX CPU devices per worker. None (default): as many as the driver has,
    so that a worker compiles the same per-device program as a local run and the table is
    identical to the local one to the last bit (with one device per worker, XLA's
    different per-device batch changed a few metrics of titan.stride in the 16th digit).
    A connection this process already has (`ray.init` called before) is used as it is.
    """

    name = "ray"
    in_process = False

    def __init__(
        self,
        address: str | None = None,
        *,
        cpus_per_task: float = 1.0,
        gpus_per_task: float = 0.0,
        cpu_devices: int | None = None,
        num_cpus: int | None = None,
    ) -> None:
        if not (isinstance(cpus_per_task, (int, float)) and math.isfinite(cpus_per_task) and cpus_per_task >= 0):
            raise SpecError(f"--ray-cpus-per-task: must be a number >= 0, got {cpus_per_task!r}")
        if not (isinstance(gpus_per_task, (int, float)) and math.isfinite(gpus_per_task) and gpus_per_task >= 0):
            raise SpecError(f"--ray-gpus-per-task: must be a number >= 0, got {gpus_per_task!r}")
        if gpus_per_task > 1 and gpus_per_task != int(gpus_per_task):
            raise SpecError(f"--ray-gpus-per-task: above 1 it must be a whole number, got {gpus_per_task:g}")
        if cpus_per_task == 0 and gpus_per_task == 0:
            raise SpecError("--ray-cpus-per-task: a task must ask for some CPUs or GPUs, got 0 of each")
        self.address = address or None
        self.cpus_per_task = float(cpus_per_task)
        self.gpus_per_task = float(gpus_per_task)
        self.cpu_devices = cpu_devices
        self.num_cpus = num_cpus

    # ------------------------------------------------------------------ connection

    @contextlib.contextmanager
    def session(self) -> Iterator[None]:
        ray = import_ray()
        if self.address is not None:
            check_reachable(self.address)
        if ray.is_initialized():  # e.g. a notebook or a test that called ray.init itself
            yield
            return
        quiet: dict[str, Any] = {"log_to_driver": False, "logging_level": logging.ERROR}
        where = self.address or "a local Ray instance"
        try:
            with warnings.catch_warnings():
                # JAX warns on any fork; Ray's fork is subprocess' fork+exec of its services
                warnings.filterwarnings("ignore", r"os\.fork\(\) was called", RuntimeWarning)
                if self.address is None:
                    ray.init(num_cpus=self.num_cpus or _cores(), include_dashboard=False, **quiet)
                else:
                    ray.init(address=self.address, **quiet)
        except Exception as exc:  # any failure to start or connect is the user's to fix
            raise SpecError(f"cannot start or connect to Ray at {where}: {_first_line(exc)}") from None
        try:
            yield
        finally:
            ray.shutdown()

    # ------------------------------------------------------------------- the tasks

    def chunks(self, work: SweepWork, todo: Sequence[int]) -> Iterator[tuple[int, pa.Table]]:
        if not todo:
            return
        ray = import_ray()
        devices = self.cpu_devices if self.cpu_devices is not None else work.cpu_devices
        job = ChunkJob.of(work.spec, x64=work.x64, cpu_devices=devices)
        # Read when a worker's JAX backend starts, i.e. once per worker process. Ray keeps
        # separate worker processes per runtime_env, so a worker configured for another
        # device count (or an unshared GPU) is never reused for these tasks.
        env = {"JAXLOCO_CPU_DEVICES": str(devices)} if devices else {}
        if 0 < self.gpus_per_task < 1:  # workers share a GPU: no preallocation of 75% of it each
            env["XLA_PYTHON_CLIENT_PREALLOCATE"] = "false"
        options: dict[str, Any] = {"name": f"jaxloco sweep {work.spec.name}"}
        if env:
            options["runtime_env"] = {"env_vars": env}  # merged with the job's env_vars
        task = ray.remote(
            num_cpus=self.cpus_per_task,
            num_gpus=self.gpus_per_task,
            max_calls=0,  # keep workers (and their compiled functions) between chunks, GPU tasks too
        )(compute_job_chunk).options(**options)
        job_ref = ray.put(job)
        waiting = list(todo)
        running: dict[Any, int] = {}
        window = IN_FLIGHT_PER_SLOT * self._slots(ray)

        def submit() -> None:
            while waiting and len(running) < window:
                index = waiting.pop(0)
                running[task.remote(job_ref, index)] = index

        try:
            submit()
            while running:
                try:
                    ready, _ = ray.wait(list(running), num_returns=1)
                except KeyboardInterrupt:
                    # hand over what already finished, then stop (the driver saves them)
                    ready, _ = ray.wait(list(running), num_returns=len(running), timeout=0)
                    for ref in ready:
                        index = running.pop(ref)
                        with contextlib.suppress(Exception):
                            yield index, ray.get(ref)
                    raise
                for ref in ready:
                    index = running.pop(ref)
                    yield index, _result(ray, ref, index)
                submit()
        finally:
            # Chunks not yet submitted never start. Submitted ones (a few per slot) are not
            # `ray.cancel`led: in Ray 2.60 a cancel racing with the task's completion aborts
            # the driver process ("Check failed: ... Tried to complete task that was not
            # pending"). They finish on their own (a local instance we started is shut down
            # at once) and their results are dropped with the references.
            waiting.clear()
            running.clear()

    def _slots(self, ray: Any) -> int:
        """How many tasks the cluster can run at once (at least 1)."""
        resources = ray.cluster_resources()
        counts = []
        if self.cpus_per_task > 0:
            counts.append(int(resources.get("CPU", 1) // self.cpus_per_task))
        if self.gpus_per_task > 0:
            counts.append(int(resources.get("GPU", 0) // self.gpus_per_task))
        return max(1, min(counts))


def get_executor(executor: str | Executor) -> Executor:
    """An executor object from a name ("local", "ray") or the object itself."""
    if not isinstance(executor, str):
        return executor
    if executor == "local":
        return LocalExecutor()
    if executor == "ray":
        return RayExecutor()
    raise SpecError(f"--executor: unknown executor '{executor}' (known: {', '.join(EXECUTORS)})")


def import_ray() -> Any:
    try:
        import ray
    except ImportError:
        raise SpecError(RAY_MISSING) from None
    return ray


_HOST_PORT = re.compile(r"^(?:ray://)?\[?([^\[\]]+?)\]?:(\d+)$")


def check_reachable(address: str, timeout: float = CONNECT_TIMEOUT_S) -> None:
    """SpecError at once if `address` names a host:port that does not accept a connection
    (Ray itself retries an unreachable address for minutes). "auto" and other forms pass."""
    match = _HOST_PORT.match(address.strip())
    if not match:
        if address.strip() in ("auto", "local") or "://" in address:
            return
        raise SpecError(f"--address: expected auto, host:port or ray://host:port, got '{address}'")
    host, port = match.group(1), int(match.group(2))
    try:
        with socket.create_connection((host, port), timeout=timeout):
            pass
    except OSError as exc:
        reason = exc.strerror or str(exc) or type(exc).__name__
        if isinstance(exc, TimeoutError | socket.timeout):
            reason = f"no answer within {timeout:g} s"
        raise SpecError(f"cannot connect to Ray at {address}: {reason}") from None


def _result(ray: Any, ref: Any, index: int) -> pa.Table:
    """The task's table; the worker's own exception (not Ray's wrapper) if it raised."""
    try:
        return ray.get(ref)
    except ray.exceptions.RayTaskError as exc:
        cause = getattr(exc, "cause", None)
        if isinstance(cause, Exception):
            raise cause from None
        raise RuntimeError(f"chunk {index}: the Ray task failed: {_first_line(exc)}") from None
    except ray.exceptions.RayError as exc:  # worker died, node lost, ...
        raise RuntimeError(f"chunk {index}: the Ray task failed: {_first_line(exc)}") from None


def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return (text.splitlines()[0] if text else "") or type(exc).__name__


__all__ = ["EXECUTORS", "Executor", "LocalExecutor", "RayExecutor", "check_reachable", "get_executor"]
