"""Executors: run independent tasks (one function, many argument dicts) on local worker
processes or a Ray cluster, with progress and cancellation. Qt-free: the CLI's sweep and
the GUI learning panel use the same classes.

An executor is used as a context manager and has one method::

    with make_executor("local", jobs=2) as ex:
        for task_id, result in ex.run(fn, tasks, cancel):   # tasks: {id: (kwargs, gpus)}
            ...   # results arrive as tasks finish, in any order

``fn`` must be importable by name (a module-level function) and its arguments and
result plain picklable data. ``cancel`` (a :class:`~tactile_studio.jobs.CancelToken`)
stops the run: pending tasks are dropped, running ones are ended, and ``run`` raises
``Cancelled`` after yielding everything that had finished. ``gpus`` is what a task asks
of the scheduler (Ray places it on a node with that many free GPUs; local workers ignore
it).

* :class:`LocalExecutor` — ``jobs`` worker processes (spawned: no state leaks from the
  parent, Ctrl-C or SIGTERM reaches only the parent, which cancels; a worker whose parent
  was killed exits within a second).
* :class:`RayExecutor` — ``address`` ``HOST:PORT`` of a running Ray cluster (``ray
  start --head`` on one machine, ``ray start --address HOST:PORT`` on others; every node
  needs this package installed and the data at the same path), or a local Ray instance
  of ``jobs`` CPUs started for the run when no address is given.
"""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import os
import signal
import socket
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

from tactile_studio.errors import Cancelled, UserError
from tactile_studio.jobs import CancelToken

Task = tuple[dict[str, Any], float]  # (keyword arguments, GPUs requested)
EXECUTORS = ("local", "ray")
_POLL_S = 0.2
_PARENT_CHECK_S = 1.0


def _init_worker(parent: int) -> None:
    """Ctrl-C and SIGTERM reach the parent only, even sent to the whole process group
    (it cancels, then kills its workers); and a worker whose parent died without ending
    it (killed: no handler ran) exits instead of finishing its task. ``parent`` is the
    sweep's PID as the sweep saw it: one killed while this worker started is gone."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(_PARENT_CHECK_S)
        os._exit(1)  # the sweep is gone: nobody would read this task's result

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()


def _call(fn: Callable[..., Any], kwargs: dict[str, Any]) -> Any:
    return fn(**kwargs)


class LocalExecutor:
    """Tasks on ``jobs`` local worker processes (default: the number of cores)."""

    name = "local"

    def __init__(self, jobs: int | None = None) -> None:
        self.jobs = max(1, int(jobs or os.cpu_count() or 1))
        self._pool: cf.ProcessPoolExecutor | None = None

    def __enter__(self) -> LocalExecutor:
        ctx = multiprocessing.get_context("spawn")
        self._pool = cf.ProcessPoolExecutor(self.jobs, mp_context=ctx, initializer=_init_worker,
                                          initargs=(os.getpid(),))
        return self

    def __exit__(self, *exc: object) -> None:
        self.close(kill=exc[0] is not None)

    def close(self, kill: bool = False) -> None:
        pool, self._pool = self._pool, None
        if pool is None:
            return
        if kill:
            for proc in list(getattr(pool, "_processes", {}).values()):
                proc.kill()  # running tasks of a cancelled sweep are abandoned
        pool.shutdown(wait=True, cancel_futures=True)

    def run(self, fn: Callable[..., Any], tasks: dict[str, Task],
            cancel: CancelToken | None = None) -> Iterator[tuple[str, Any]]:
        assert self._pool is not None, "use the executor as a context manager"
        cancel = cancel or CancelToken()
        futures = {self._pool.submit(_call, fn, kw): tid for tid, (kw, _gpus) in tasks.items()}
        pending = set(futures)
        while pending:
            done, pending = cf.wait(pending, timeout=_POLL_S, return_when=cf.FIRST_COMPLETED)
            for fut in done:
                yield futures[fut], fut.result()
            if cancel.cancelled and pending:
                for fut in pending:
                    fut.cancel()
                self.close(kill=True)
                raise Cancelled("sweep cancelled")


class RayExecutor:
    """Tasks on a Ray cluster at ``address`` (HOST:PORT), or on a local Ray instance."""

    name = "ray"

    def __init__(self, address: str | None = None, jobs: int | None = None) -> None:
        self.address, self.jobs = address, jobs
        self._started = False

    def __enter__(self) -> RayExecutor:
        try:
            import ray
        except ImportError:
            raise UserError("the ray executor needs Ray: pip install 'ray>=2.9'") from None
        if not ray.is_initialized():
            if self.address:
                check_address(self.address)
            try:
                if self.address:
                    ray.init(address=self.address, include_dashboard=False,
                             log_to_driver=False)
                else:
                    ray.init(num_cpus=max(1, int(self.jobs or os.cpu_count() or 1)),
                             include_dashboard=False, log_to_driver=False)
            except ConnectionError as exc:
                raise UserError(f"ray: cannot connect to {self.address} ({exc})") from None
            self._started = True
        return self

    def __exit__(self, *exc: object) -> None:
        if self._started:
            import ray

            ray.shutdown()
            self._started = False

    def run(self, fn: Callable[..., Any], tasks: dict[str, Task],
            cancel: CancelToken | None = None) -> Iterator[tuple[str, Any]]:
        import ray

        cancel = cancel or CancelToken()
        remote = ray.remote(_call)
        refs = {remote.options(num_cpus=1, num_gpus=gpus, max_retries=0).remote(fn, kw): tid
                for tid, (kw, gpus) in tasks.items()}
        pending = list(refs)
        while pending:
            done, pending = ray.wait(pending, num_returns=1, timeout=_POLL_S)
            for ref in done:
                yield refs[ref], ray.get(ref)
            if cancel.cancelled and pending:
                for ref in pending:
                    ray.cancel(ref, force=True)
                raise Cancelled("sweep cancelled")


def check_address(address: str, timeout: float = 3.0) -> None:
    """A clear one-line error, within ``timeout`` s, for a Ray address that is not
    HOST:PORT or where nothing listens (Ray itself would retry for a minute)."""
    if address == "auto":
        return
    host, _, port = address.split("://", 1)[-1].rpartition(":")
    if not host or not port.isdigit():
        raise UserError(f"ray: address {address!r} is not HOST:PORT (e.g. 10.0.0.5:6379)")
    try:
        socket.create_connection((host, int(port)), timeout=timeout).close()
    except OSError as exc:
        raise UserError(f"ray: cannot reach {address} ({exc.strerror or exc}); is "
                        "`ray start --head` running there?") from None


def make_executor(name: str = "local", jobs: int | None = None, address: str | None = None):
    """The executor called ``name`` (``local`` or ``ray``); see the module doc."""
    if name == "local":
        if address:
            raise UserError("--address is for the ray executor (use --executor ray)")
        return LocalExecutor(jobs)
    if name == "ray":
        return RayExecutor(address, jobs)
    raise UserError(f"unknown executor {name!r} (available: {', '.join(EXECUTORS)})")
