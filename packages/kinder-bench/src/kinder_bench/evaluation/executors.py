"""Where episodes run: in this process, in a local process pool (the default), or on Ray.

Every executor maps a picklable function over picklable tasks and yields the results as they
finish. Each episode depends only on its task, so the results are the same whichever executor ran
them (only wall-clock timings differ).
"""

from __future__ import annotations

import concurrent.futures
import multiprocessing
import os
import sys
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures.process import BrokenProcessPool
from typing import Any, TypeVar

T = TypeVar("T")
R = TypeVar("R")

EXECUTORS = ("process", "inline", "ray")


def available_cpus() -> int:
    """CPUs this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def run_inline(fn: Callable[[T], R], tasks: Sequence[T]) -> Iterator[R]:
    """One task after another, in this process."""
    for task in tasks:
        yield fn(task)


def _end_with_parent(parent: int) -> None:
    """Pool worker initializer: on Linux, ask for SIGKILL when the parent process dies.

    Without it, killing a run (``kill`` on its process, not on its process group) leaves its
    workers planning on, unseen, taking the CPU that other runs' wall-clock budgets count on.
    """
    if not sys.platform.startswith("linux"):
        return
    import ctypes
    import signal

    pr_set_pdeathsig = 1
    libc = ctypes.CDLL(None, use_errno=True)
    libc.prctl(pr_set_pdeathsig, signal.SIGKILL)
    if os.getppid() != parent:  # the parent died before the request was in place
        os.kill(os.getpid(), signal.SIGKILL)


def run_process_pool(fn: Callable[[T], R], tasks: Sequence[T], workers: int) -> Iterator[R]:
    """A local pool of ``workers`` processes (started with ``spawn``, as on every platform).

    The workers end with this process, however it ends (on Linux)."""
    if not tasks:
        return
    ctx = multiprocessing.get_context("spawn")
    pool = concurrent.futures.ProcessPoolExecutor(
        max_workers=max(1, min(workers, len(tasks))),
        mp_context=ctx,
        initializer=_end_with_parent,
        initargs=(os.getpid(),),
    )
    try:
        futures = [pool.submit(fn, t) for t in tasks]
        for future in concurrent.futures.as_completed(futures):
            try:
                yield future.result()
            except BrokenProcessPool as e:
                raise RuntimeError(
                    "A worker process died (killed or crashed outside Python). The episodes "
                    "finished so far are saved; run the same command again to resume."
                ) from e
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def run_ray(
    fn: Callable[[T], R], tasks: Sequence[T], workers: int, address: str | None = None
) -> Iterator[R]:
    """Ray tasks, one CPU each: on the cluster at ``address``, or on a local instance with
    ``workers`` CPUs (which sees this process's import path). An already initialised Ray session
    is reused."""
    try:
        import ray
    except ImportError as e:
        raise ImportError("The Ray executor needs Ray: `pip install 'kinder-bench[ray]'`") from e
    if not tasks:
        return
    started = False
    if not ray.is_initialized():
        if address is None:
            ray.init(
                num_cpus=workers,
                include_dashboard=False,
                log_to_driver=False,
                runtime_env={"env_vars": {"PYTHONPATH": os.pathsep.join(sys.path)}},
            )
        else:
            ray.init(address=address, log_to_driver=False)
        started = True
    pending: list[Any] = []
    try:
        remote = ray.remote(num_cpus=1, max_retries=0)(fn)
        pending = [remote.remote(t) for t in tasks]
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            for ref in done:
                yield ray.get(ref)
    finally:
        for ref in pending:  # interrupted: do not leave work running on the cluster
            ray.cancel(ref, force=True)
        if started:
            ray.shutdown()


def execute(
    fn: Callable[[T], R],
    tasks: Sequence[T],
    executor: str = "process",
    workers: int | None = None,
    address: str | None = None,
) -> Iterator[Any]:
    """Run ``fn`` over ``tasks`` with the named executor; yields results as they finish."""
    workers = workers or available_cpus()
    if executor == "inline":
        return run_inline(fn, tasks)
    if executor == "process":
        return run_process_pool(fn, tasks, workers)
    if executor == "ray":
        return run_ray(fn, tasks, workers, address)
    raise ValueError(f"Unknown executor {executor!r}; expected one of {list(EXECUTORS)}")
