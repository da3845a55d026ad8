"""Where the jobs of the reproduction run: local worker processes, or a Ray cluster.

Both executors take a list of :class:`Task` s and call ``on_done(task, output)`` in the driver as
each finishes, in completion order; the driver writes the output to disk, so what a finished job
produced is kept even if the run is interrupted a moment later. ``on_done`` may return new tasks
(the training jobs of a data set that just finished), which join the queue at once. A job that
raises does not stop the others: its error is collected and raised, as one
:class:`~fhnn.errors.FhnnError` naming every failed job, after the rest have finished.

- :func:`run_local`: ``workers`` spawned processes (JAX is not fork-safe), each reused for many
  jobs, so imports and JAX's in-process caches are paid once per worker; ``workers = 1`` runs the
  jobs in the calling process (in one worker process when there are ``xla_flags``).
- :func:`run_ray`: the same job functions as Ray tasks (one CPU each); connects to ``address``
  (``"auto"``: the running cluster; ``"local"``: start one on this machine), or uses the Ray
  session the caller has already initialised.

Workers share JAX's persistent compilation cache (``cache_dir``) where they share a file system,
so a model compiled once is loaded, not compiled again, by every later job and run. ``xla_flags``
(e.g. :data:`FAST_COMPILE_FLAGS`) are added to the workers' ``XLA_FLAGS`` before they compile
anything (a local worker sets them as it starts; Ray starts its workers with them).
"""

from __future__ import annotations

import multiprocessing
import os
import threading
import time
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass, field
from typing import Any

from fhnn.errors import ConfigError, FhnnError
from fhnn.runtime import use_compilation_cache

#: ``XLA_FLAGS`` that trade run speed for compilation speed (LLVM optimisation level 0).
FAST_COMPILE_FLAGS = "--xla_backend_optimization_level=0"


def _xla_flags_with(xla_flags: str) -> str:
    """This process's ``XLA_FLAGS`` with ``xla_flags`` added."""
    return f"{os.environ.get('XLA_FLAGS', '')} {xla_flags}".strip()


def _start_worker(cache_dir: str | None, xla_flags: str) -> None:
    """A local worker's setup, before its first job: a watch that ends the worker when its driver
    is gone (a killed driver would otherwise leave it running, holding the driver's output pipes
    open), ``xla_flags`` (read by XLA when the process first compiles) and the compilation cache."""
    driver = os.getppid()

    def watch() -> None:
        while os.getppid() == driver:
            time.sleep(0.5)
        os._exit(1)

    threading.Thread(target=watch, name="fhnn-driver-watch", daemon=True).start()
    if xla_flags:
        os.environ["XLA_FLAGS"] = _xla_flags_with(xla_flags)
    use_compilation_cache(cache_dir)


@dataclass(frozen=True)
class Task:
    """One job: ``function`` (a name in :data:`FUNCTIONS`) applied to ``args``."""

    name: str
    function: str
    args: tuple[Any, ...] = field(hash=False)


def _functions() -> dict[str, Callable[..., Any]]:
    from fhnn.experiments.jobs import run_data_job, run_model_job, run_model_jobs

    return {"data": run_data_job, "model": run_model_job, "models": run_model_jobs}


def execute(function: str, cache_dir: str | None, *args: Any) -> Any:
    """Run one task (in a worker process, a Ray worker or the driver); ``args`` are top-level
    arguments so that Ray resolves object references among them."""
    use_compilation_cache(cache_dir)
    return _functions()[function](*args)


OnDone = Callable[[Task, Any], "list[Task] | None"]


def _raise_failures(failures: list[tuple[Task, BaseException]]) -> None:
    if failures:
        names = "; ".join(f"{t.name}: {type(e).__name__}: {e}" for t, e in failures)
        raise FhnnError(
            f"{len(failures)} job(s) failed ({names}); finished jobs are kept, run again to retry"
        )


def run_local(
    tasks: list[Task], on_done: OnDone, *, workers: int, cache_dir: str | None = None, xla_flags: str = ""
) -> None:
    """Run ``tasks`` on ``workers`` local processes; in this process when ``workers == 1`` and
    there are no ``xla_flags`` (XLA reads its flags once, when a process first compiles: with flags
    even one worker is a process of its own, so a job's bits do not depend on ``workers``)."""
    check_workers(workers)
    failures: list[tuple[Task, BaseException]] = []
    if workers == 1 and not xla_flags:
        queue = list(tasks)
        while queue:
            task = queue.pop(0)
            try:
                output = execute(task.function, cache_dir, *task.args)
            except Exception as exc:  # reported with the others at the end
                failures.append((task, exc))
                continue
            queue += on_done(task, output) or []
        _raise_failures(failures)
        return
    if not tasks:
        return
    pool = ProcessPoolExecutor(
        max_workers=workers,
        mp_context=multiprocessing.get_context("spawn"),
        initializer=_start_worker,
        initargs=(cache_dir, xla_flags),
    )
    try:
        pending: dict[Future, Task] = {pool.submit(execute, t.function, None, *t.args): t for t in tasks}
        while pending:
            done, _ = wait(pending, return_when=FIRST_COMPLETED)
            for future in done:
                task = pending.pop(future)
                try:
                    output = future.result()
                except Exception as exc:  # a job's failure is reported with the others at the end
                    failures.append((task, exc))
                    continue
                for new in on_done(task, output) or []:
                    pending[pool.submit(execute, new.function, None, *new.args)] = new
    except BaseException:  # interrupted: stop the workers now, keep what has been written
        for process in list(getattr(pool, "_processes", {}).values()):
            process.terminate()
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown()
    _raise_failures(failures)


def run_ray(
    tasks: list[Task], on_done: OnDone, *, address: str, cache_dir: str | None = None, xla_flags: str = ""
) -> None:
    """Run ``tasks`` as Ray tasks on the cluster at ``address`` (or the session already open);
    ``xla_flags`` are added to the ``XLA_FLAGS`` of the workers Ray starts for them."""
    try:
        import ray
    except ImportError:
        raise ConfigError("--ray needs Ray: pip install 'fhnn[ray]'") from None
    if not ray.is_initialized():
        try:
            ray.init(address=None if address == "local" else address, log_to_driver=False)
        except (ConnectionError, ValueError, RuntimeError) as exc:
            raise ConfigError(f"cannot connect to the Ray cluster at {address!r}: {exc}") from None
    remote = ray.remote(num_cpus=1, max_retries=0)(execute)
    if xla_flags:
        remote = remote.options(runtime_env={"env_vars": {"XLA_FLAGS": _xla_flags_with(xla_flags)}})
    shared: dict[int, Any] = {}  # large arguments (data sets) are put in the object store once

    def put(arg: Any) -> Any:
        if isinstance(arg, bytes) and len(arg) > 100_000:
            return shared.setdefault(id(arg), ray.put(arg))
        return arg

    def submit(t: Task) -> Any:
        return remote.remote(t.function, cache_dir, *(put(a) for a in t.args))

    pending = {submit(t): t for t in tasks}
    failures: list[tuple[Task, BaseException]] = []
    try:
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            task = pending.pop(done[0])
            try:
                output = ray.get(done[0])
            except Exception as exc:
                failures.append((task, exc))
                continue
            for new in on_done(task, output) or []:
                pending[submit(new)] = new
    except BaseException:
        for ref in pending:
            ray.cancel(ref, force=True)
        raise
    _raise_failures(failures)


def check_workers(workers: int) -> None:
    """Raise :class:`ConfigError` unless ``workers`` is at least 1."""
    if workers < 1:
        raise ConfigError(f"--workers must be >= 1, got {workers}")


def default_workers() -> int:
    """One worker per CPU core available to this process."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)
