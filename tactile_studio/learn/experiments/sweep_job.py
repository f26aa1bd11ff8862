"""A sweep for the GUI: :func:`~tactile_studio.learn.experiments.sweep.run_sweep` on the same
executors as ``tactile-studio sweep``, coordinated from a background thread so the window
never freezes, with events the window polls.

The thread only plans the tasks and collects results; the training runs in the
executor's worker processes (local, spawned) or on Ray. Cancelling sets the sweep's
:class:`~tactile_studio.jobs.CancelToken`: the executor drops pending tasks and ends the
running ones within a poll interval, and the finished tasks stay in the sweep folder (a
table of them is written; starting the same sweep into the same folder runs only the rest).

:meth:`SweepJob.poll` returns the events since the last call, the typed
:mod:`~tactile_studio.learn.experiments.job_events`: :class:`~.job_events.Progress`,
:class:`~.job_events.Plan` (the tasks are known; ``done``: kept from before),
:class:`~.job_events.Task` per finished task, then one of :class:`~.job_events.Done`
(``rows``, ``out``) / :class:`~.job_events.Cancelled` (``rows``, ``message``) /
:class:`~.job_events.Failed` — the last event of a job.
"""

from __future__ import annotations

import queue
import sys
import threading
import time
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tactile_studio.errors import Cancelled as Stopped
from tactile_studio.errors import UserError
from tactile_studio.jobs import CancelToken
from tactile_studio.learn.experiments.experiment import ExperimentConfig
from tactile_studio.learn.experiments.job_events import (
    Cancelled,
    Done,
    Failed,
    JobEvent,
    Plan,
    Progress,
    Task,
    is_final,
)
from tactile_studio.learn.experiments.runfolder import read_json
from tactile_studio.output_faults import fault_line


@dataclass
class ExecutorChoice:
    """Where the tasks run: ``local`` worker processes (``jobs``, default the number of
    cores) or ``ray`` (``address`` HOST:PORT of a cluster, empty: a local instance)."""

    name: str = "local"
    jobs: int | None = None
    address: str | None = None


class SweepJob:
    def __init__(self, base: ExperimentConfig, models: list[str], channel_sets: list[str],
                 executor: ExecutorChoice, out: str) -> None:
        self.base, self.models, self.channel_sets = base, list(models), list(channel_sets)
        self.executor, self.out = executor, str(out)
        self.token = CancelToken()
        self._events: queue.Queue[JobEvent] = queue.Queue()
        self._thread = threading.Thread(target=self._run, name="sweep", daemon=True)
        self.started = 0.0
        self.total = 0
        self.done = 0
        self.done_before = 0
        self.finished: Done | Cancelled | Failed | None = None

    def start(self) -> SweepJob:
        self.started = time.monotonic()
        self._thread.start()
        return self

    @property
    def running(self) -> bool:
        return self.finished is None

    def cancel(self) -> None:
        """Stop the sweep: pending tasks are dropped, running ones ended; finished ones kept."""
        self.token.cancel()

    def elapsed(self) -> float:
        return time.monotonic() - self.started if self.started else 0.0

    def eta(self) -> float | None:
        """Seconds left if the remaining tasks take as long as this run's finished ones."""
        from tactile_studio.learn.experiments.train_job import eta_seconds

        todo = self.total - self.done_before
        if todo <= 0 or self.done <= self.done_before:
            return None
        return eta_seconds((self.done - self.done_before) / todo, self.elapsed())

    def poll(self) -> list[JobEvent]:
        out: list[JobEvent] = []
        while self.finished is None:
            try:
                event = self._events.get_nowait()
            except queue.Empty:
                break
            out.append(event)
            if isinstance(event, Plan):
                self.total, self.done = event.total, event.done
                self.done_before = event.done
            elif isinstance(event, Task):
                self.total, self.done = event.total, event.done
            elif is_final(event):
                self.finished = event
        if self.finished is not None:
            self._thread.join(timeout=5)
        return out

    def wait(self, timeout: float) -> bool:
        """Block until the coordinating thread ends (for closing the window); True if it did."""
        self._thread.join(timeout)
        return not self._thread.is_alive()

    # --- the background thread -----------------------------------------------------------
    def _run(self) -> None:
        from tactile_studio.learn.experiments.executors import make_executor
        from tactile_studio.learn.experiments.sweep import run_sweep

        put = self._events.put
        try:
            ex = make_executor(self.executor.name, self.executor.jobs,
                               self.executor.address or None)
            put(Progress(0.0, f"starting {ex.name} workers"))
            with ex:
                result = run_sweep(self.base, self.models, self.channel_sets, ex, self.out,
                                   lambda f, m: put(Progress(float(f), m)),
                                   self.token, put)
            put(Done(out=self.out, rows=result.rows))
        except Stopped as exc:
            put(Cancelled(message=str(exc), rows=self._saved_rows()))
        except UserError as exc:
            put(Failed(str(exc)))
        except Exception as exc:  # noqa: BLE001 - the window shows one line; stderr the rest
            if (line := fault_line(exc)) is not None:  # the sweep folder cannot be written
                put(Failed(line))
                return
            traceback.print_exc(file=sys.stderr)
            first = (str(exc).strip().splitlines() or [""])[0]
            put(Failed(f"the sweep failed: {type(exc).__name__}: {first} (details on stderr)"))

    def _saved_rows(self) -> list[dict[str, Any]]:
        path = Path(self.out) / "results.json"
        try:
            return list(read_json(path).get("rows", [])) if path.is_file() else []
        except UserError:
            return []
