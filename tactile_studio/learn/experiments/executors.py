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
  of ``jobs`` CPUs started for the run when no address is given. The local instance is
  private to the run (:class:`LocalRay`): it listens on the loopback address only, keeps
  its session files under the app's cache folder and removes them afterwards, and its
  token authentication uses a token held in the environment, never ``~/.ray``.
"""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import os
import secrets
import shutil
import signal
import socket
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any

from tactile_studio.errors import Cancelled, UserError
from tactile_studio.jobs import CancelToken
from tactile_studio.learn.choices import EXECUTORS

Task = tuple[dict[str, Any], float]  # (keyword arguments, GPUs requested)
_POLL_S = 0.2
_PARENT_CHECK_S = 1.0


class WorkerLost(Exception):
    """A worker process ended abruptly (killed, out of memory) while tasks ran; a local
    pool cannot go on after that. ``running`` are the tasks that had started in a worker
    and not finished (as the workers reported them): lost, like every task not started."""

    def __init__(self, running: list[str]) -> None:
        super().__init__("a worker process ended abruptly")
        self.running = running


_STARTED: Any = None  # in a worker: the queue on which it says which task it starts


def _init_worker(parent: int, started: Any = None) -> None:
    """Ctrl-C and SIGTERM reach the parent only, even sent to the whole process group
    (it cancels, then kills its workers); and a worker whose parent died without ending
    it (killed: no handler ran) exits instead of finishing its task. ``parent`` is the
    sweep's PID as the sweep saw it: one killed while this worker started is gone."""
    global _STARTED
    _STARTED = started
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(_PARENT_CHECK_S)
        os._exit(1)  # the sweep is gone: nobody would read this task's result

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()


def _call(fn: Callable[..., Any], kwargs: dict[str, Any], task_id: str = "") -> Any:
    if _STARTED is not None:
        _STARTED.put(task_id)  # so a worker killed mid-task is told by its task
    return fn(**kwargs)


class LocalExecutor:
    """Tasks on ``jobs`` local worker processes (default: the number of cores)."""

    name = "local"

    def __init__(self, jobs: int | None = None) -> None:
        self.jobs = max(1, int(jobs or os.cpu_count() or 1))
        self._pool: cf.ProcessPoolExecutor | None = None

    def __enter__(self) -> LocalExecutor:
        ctx = multiprocessing.get_context("spawn")
        self._task_starts = ctx.SimpleQueue()
        self._pool = cf.ProcessPoolExecutor(self.jobs, mp_context=ctx, initializer=_init_worker,
                                          initargs=(os.getpid(), self._task_starts))
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
        futures = {self._pool.submit(_call, fn, kw, tid): tid
                   for tid, (kw, _gpus) in tasks.items()}
        pending, finished = set(futures), set()
        while pending:
            done, pending = cf.wait(pending, timeout=_POLL_S, return_when=cf.FIRST_COMPLETED)
            broken = [f for f in done if isinstance(f.exception(), BrokenProcessPool)]
            for fut in done:
                if fut not in broken:
                    finished.add(futures[fut])
                    yield futures[fut], fut.result()
            if broken:
                started = set()
                while not self._task_starts.empty():
                    started.add(self._task_starts.get())
                raise WorkerLost(sorted(started - finished))
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
        self._local: LocalRay | None = None

    def __enter__(self) -> RayExecutor:
        local = None if self.address else LocalRay()
        try:
            if local is not None:
                local.__enter__()  # before Ray is imported: it reads the environment then
            import ray
        except ImportError:
            if local is not None:
                local.__exit__()
            raise UserError("the ray executor needs Ray: pip install 'ray>=2.9'") from None
        if ray.is_initialized():
            if local is not None:
                local.__exit__()
            return self
        try:
            if self.address:
                check_address(self.address)
                ray.init(address=self.address, include_dashboard=False, log_to_driver=False)
            else:
                ray.init(num_cpus=max(1, int(self.jobs or os.cpu_count() or 1)),
                         include_dashboard=False, log_to_driver=False,
                         _temp_dir=str(local.temp_dir), _node_ip_address=LOOPBACK)
        except ConnectionError as exc:
            raise UserError(f"ray: cannot connect to {self.address} ({exc})") from None
        finally:
            if local is not None and not ray.is_initialized():
                local.__exit__()
        self._started, self._local = True, local
        return self

    def __exit__(self, *exc: object) -> None:
        if self._started:
            import ray

            ray.shutdown()
            self._started = False
        local, self._local = self._local, None
        if local is not None:
            local.__exit__()

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


LOOPBACK = "127.0.0.1"
# Ray's AF_UNIX sockets live under its temp folder: the whole path must fit in 107 bytes,
# after Ray adds "/session_<date>_<time>_<us>_<pid>/sockets/plasma_store" (~64 bytes)
_MAX_RAY_TEMP = 40


class LocalRay:
    """What a local Ray instance started for one run needs, set up and undone around it.

    * loopback only: Ray turns a ``127.0.0.1`` node address into the machine's routable
      one (and its servers then listen on every interface) unless
      ``RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0``;
    * token authentication with a token in ``RAY_AUTH_TOKEN`` (Ray would write one to
      ``~/.ray/auth_token`` and keep it there);
    * its temporary and session files (and torch's inductor cache, which its workers
      would leave in the system temp folder) in ``<cache>/ray/run-XXXX`` (``paths.cache_dir``),
      reached through a short link in the system temp folder when that path is too long
      for Ray's sockets; both are removed afterwards.

    The environment variables are restored on exit.
    """

    def __init__(self) -> None:
        self.temp_dir: Path | None = None
        self._real: Path | None = None
        self._saved: dict[str, str | None] = {}

    def __enter__(self) -> LocalRay:
        from tactile_studio.paths import cache_dir

        env = {"RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "0"}
        if not (os.environ.get("RAY_AUTH_TOKEN") or os.environ.get("RAY_AUTH_TOKEN_PATH")):
            env["RAY_AUTH_TOKEN"] = _process_token()
        for key in (*env, "RAY_AUTH_MODE"):  # Ray sets RAY_AUTH_MODE itself
            self._saved[key] = os.environ.get(key)
        os.environ.update(env)
        constants = sys.modules.get("ray._private.ray_constants")
        if constants is not None:  # Ray imported before: it read the environment then
            constants.ENABLE_RAY_CLUSTER = False
        base = cache_dir() / "ray"
        try:
            base.mkdir(parents=True, exist_ok=True)
            self._real = Path(tempfile.mkdtemp(prefix="run-", dir=base))
        except OSError as exc:
            self.__exit__()
            raise UserError(f"{base}: cannot create Ray's session folder "
                            f"({exc.strerror or exc})") from None
        self.temp_dir = self._real
        if not os.environ.get("TORCHINDUCTOR_CACHE_DIR"):  # torch's workers: not in /tmp
            self._saved["TORCHINDUCTOR_CACHE_DIR"] = None
            os.environ["TORCHINDUCTOR_CACHE_DIR"] = str(self._real / "torchinductor")
        if len(str(self._real)) > _MAX_RAY_TEMP and sys.platform != "win32":  # no AF_UNIX
            short = tempfile.gettempdir()
            if len(short) > _MAX_RAY_TEMP - 16 and os.path.isdir("/tmp"):
                short = "/tmp"
            link = Path(short) / f"ts-ray-{secrets.token_hex(4)}"
            try:
                os.symlink(self._real, link)
            except OSError as exc:
                self.__exit__()
                raise UserError(f"{link}: cannot link Ray's session folder there "
                                f"({exc.strerror or exc})") from None
            self.temp_dir = link
        return self

    def __exit__(self, *exc: object) -> None:
        if self.temp_dir is not None and self.temp_dir != self._real:
            self.temp_dir.unlink(missing_ok=True)
        if self._real is not None:
            shutil.rmtree(self._real, ignore_errors=True)
        self.temp_dir = self._real = None
        for key, value in self._saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value
        self._saved = {}
        constants = sys.modules.get("ray._private.ray_constants")
        if constants is not None:  # as the restored environment says (a cluster run next)
            constants.ENABLE_RAY_CLUSTER = constants.env_bool(
                constants.ENABLE_RAY_CLUSTERS_ENV_VAR, not constants.IS_WINDOWS_OR_OSX)


_TOKEN: list[str] = []


def _process_token() -> str:
    """One token for every local Ray instance this process starts: Ray's driver keeps the
    token it first read, so a second instance with a new one failed to start ("Failed to
    start GCS": its health check was refused)."""
    if not _TOKEN:
        _TOKEN.append(secrets.token_hex(32))
    return _TOKEN[0]


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
