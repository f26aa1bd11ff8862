"""Shared test setup: headless Qt, and no test touches the user's settings or cache."""

from __future__ import annotations

import os
import tempfile

import pytest

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
os.environ.setdefault("TACTILE_STUDIO_TESTING", "1")
# one thread per library (torch, BLAS) in every test process: what float noise a parallel
# reduction leaves depends on the thread count, which would otherwise be the host's cores
# or whatever an earlier test in the same xdist worker set (whole files per worker, so
# which files run before a test depends on the machine's load)
for _lib in ("OMP", "MKL", "OPENBLAS"):
    os.environ.setdefault(f"{_lib}_NUM_THREADS", "1")
# Ray starts its worker processes at nice 15 (its worker_niceness), so on this 2-core
# machine the other xdist worker's tests (nice 0) starved a local Ray instance's tasks:
# the same 12-task sweep took 169 s beside two busy processes, 17 s at nice 0 (152 s in
# a whole run, 16-21 s alone). Tests run Ray's workers at their own priority; what they
# prove (identical metrics, loopback only, nothing left behind) does not depend on it.
os.environ.setdefault("RAY_worker_niceness", "0")
# the app's data, cache and config folders (tactile_studio.paths) live in one temporary
# folder per test run; tests that need their own set them with monkeypatch
_APPDIRS = tempfile.mkdtemp(prefix="tactile-studio-appdirs-")
for _name in ("DATA", "CACHE", "CONFIG"):
    os.environ.setdefault(f"TACTILE_STUDIO_{_name}_DIR", os.path.join(_APPDIRS, _name.lower()))
# Lab Streaming Layer: loopback only, a session ID of its own (read when liblsl loads);
# under pytest-xdist one per worker, so one worker's streams never answer another's resolve
_LSL_CFG = os.path.join(os.path.dirname(__file__), "lsl_api.cfg")
_WORKER = os.environ.get("PYTEST_XDIST_WORKER")
if _WORKER:
    _worker_cfg = os.path.join(_APPDIRS, "lsl_api.cfg")
    with open(_LSL_CFG) as src, open(_worker_cfg, "w") as dst:
        dst.write(src.read().replace("SessionID = tactile-studio-tests",
                                     f"SessionID = tactile-studio-tests-{_WORKER}"))
    _LSL_CFG = _worker_cfg
os.environ.setdefault("LSLAPICFG", _LSL_CFG)
# A worker that dies (a crash in C, an abort) writes its threads' stacks to a file of its
# own here, and the run's summary prints them: the end of a CI log shows why it died
# (a worker's own stderr scrolls away among the progress dots)
if not _WORKER and "TACTILE_STUDIO_TEST_CRASH_DIR" not in os.environ:
    os.environ["TACTILE_STUDIO_TEST_CRASH_DIR"] = tempfile.mkdtemp(
        prefix="tactile-studio-crashes-")
_CRASH_DIR = os.environ["TACTILE_STUDIO_TEST_CRASH_DIR"]
_CRASH_LOG = None  # this worker's open crash file

# test files that start a local Ray instance: one worker runs them all, one after another
_RAY_FILES = {"test_sweep.py", "test_ui_research_sweep.py"}


# The files that take longest, longest first (wall time of a whole `make test` run on a
# loaded 2-core machine; the Ray files are one unit). Whole files go to a worker in this
# order, the rest after them in collection order: a long file handed out last kept one
# worker busy for minutes after the other ran out of work. A stale list costs only balance.
_SLOWEST_FILES = (
    "test_sweep.py", "test_ui_research_sweep.py", "test_personalise.py",
    "test_hostile_sessions.py", "test_learn_windows.py", "test_learn_faults.py",
    "test_population.py", "test_learn_models.py", "test_fused.py", "test_adapt.py",
    "test_shots.py", "test_baselines_onnx.py", "test_terminal_output.py",
    "test_generalise.py", "test_train_job.py", "test_faults_output.py",
    "test_faults_recording.py", "test_characterise_plan_cli.py", "test_export.py",
    "test_resume_clock.py", "test_person_calibration.py", "test_remote_control_faults.py",
    "test_compare.py", "test_characterise.py",
)


def pytest_collection_modifyitems(config, items):
    """The slowest files first (``_SLOWEST_FILES``), each file's tests in their order.
    A Qt test's timeout ends its worker (method ``thread``): the ``signal`` method's
    exception is raised in whatever Qt slot runs and swallowed there, and qtbot's wait
    never returns (seen with ``waitUntil``)."""
    rank = {name: i for i, name in enumerate(_SLOWEST_FILES)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))
    for item in items:
        if {"qtbot", "qapp"} & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.timeout(method="thread"))


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    """The last resort behind pytest-timeout's ``signal`` method: a test stuck where no
    Python signal handler runs (a C call that never returns) dumps every thread's stack
    and ends its worker a minute after its timeout, so a run never hangs."""
    import faulthandler
    import sys
    limit = float(item.config.getoption("timeout", None) or item.config.getini("timeout") or 0)
    if limit > 0:
        faulthandler.dump_traceback_later(limit + 60, exit=True,
                                          file=_CRASH_LOG or sys.__stderr__)
    try:
        yield
    finally:
        if limit > 0:
            faulthandler.cancel_dump_traceback_later()


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    """Whole files per worker (module fixtures are built once), the Ray files together,
    handed out in collection order (slowest first), not by their number of tests."""
    from xdist.scheduler import LoadFileScheduling

    class FilesRayTogether(LoadFileScheduling):
        def _split_scope(self, nodeid: str) -> str:
            path = nodeid.split("::", 1)[0]
            return "ray" if os.path.basename(path) in _RAY_FILES else path

        def remove_node(self, node):
            """A worker that died (a Qt test's timeout ends it, or a crash): the test it
            died in counts as done, its file's other tests go to another worker. xdist's
            own version ran the test again on every new worker until the restarts ran
            out, and a file left with nothing to run was handed to a new worker that then
            waited for tests forever: the run never ended (CI's 90 min)."""
            workload = self.assigned_work.pop(node)
            if not self._pending_of(workload):
                return None
            crashed = next(nodeid for unit in workload.values()
                           for nodeid, done in unit.items() if not done)
            for unit in workload.values():
                if crashed in unit:
                    unit[crashed] = True
            self.workqueue.update((scope, unit) for scope, unit in workload.items()
                                  if not all(unit.values()))
            for other in self.assigned_work:
                self._reschedule(other)
            return crashed

    config.option.loadscopereorder = False
    return FilesRayTogether(config, log)



@pytest.hookimpl(trylast=True)
def pytest_configure(config):
    """The markers; a worker's fatal errors (and the stuck-test dump) go to its crash file
    (trylast: after pytest's own faulthandler set-up, which would send them to stderr)."""
    global _CRASH_LOG
    import faulthandler
    config.addinivalue_line(
        "markers", "damaged_files: the test damages session files on purpose; the "
                   "after-test session check skips the files it wrote")
    if _WORKER and os.path.isdir(_CRASH_DIR):
        _CRASH_LOG = open(os.path.join(_CRASH_DIR, f"{_WORKER}-{os.getpid()}.log"), "w")
        faulthandler.enable(file=_CRASH_LOG, all_threads=True)


def pytest_terminal_summary(terminalreporter):
    """The stacks of workers that died, from their crash files (see _CRASH_DIR)."""
    if _WORKER or not os.path.isdir(_CRASH_DIR):
        return
    for name in sorted(os.listdir(_CRASH_DIR)):
        with open(os.path.join(_CRASH_DIR, name), errors="replace") as f:
            lines = f.read().splitlines()
        if lines:
            terminalreporter.write_sep("-", f"a test worker died: its stacks ({name})")
            for line in lines[-200:]:
                terminalreporter.write_line(line)


def pytest_unconfigure(config):
    if not _WORKER and os.environ.get("TACTILE_STUDIO_TEST_CRASH_DIR") == _CRASH_DIR:
        import shutil
        shutil.rmtree(_CRASH_DIR, ignore_errors=True)


# (path, mtime, size) of session files already checked, and the temporary folders seen
_CHECKED: set[tuple[str, int, int]] = set()
_SEEN_DIRS: set[str] = set()


def _new_session_files(request, tmp_path) -> list:
    """``*.h5`` in the test's ``tmp_path`` and in temporary folders not looked in before
    (a module fixture's ``tmp_path_factory.mktemp``), not checked in this state yet."""
    from pathlib import Path
    roots = [Path(tmp_path)] if tmp_path is not None else []
    factory = request.config._tmp_path_factory if hasattr(request.config, "_tmp_path_factory") \
        else None
    base = getattr(factory, "_basetemp", None)
    if base is not None and Path(base).is_dir():
        for entry in Path(base).iterdir():
            if str(entry) not in _SEEN_DIRS and entry.is_dir() and not entry.is_symlink():
                _SEEN_DIRS.add(str(entry))
                roots.append(entry)
    files = []
    for root in dict.fromkeys(roots):
        for f in root.rglob("*.h5"):
            try:
                st = f.stat()
            except OSError:
                continue
            key = (str(f), st.st_mtime_ns, st.st_size)
            if f.is_file() and key not in _CHECKED:
                _CHECKED.add(key)
                files.append(f)
    return files


@pytest.fixture(autouse=True)
def sessions_written_pass_check(request):
    """Every session file a test writes holds the session invariants (``tactile-studio
    check``): a class of wrong facts is caught wherever a file is written. Files that are
    not sessions or cannot be read are left alone; ``@pytest.mark.damaged_files`` skips
    a test's files. Set up first, so checked after every other fixture closed its files."""
    tmp = request.getfixturevalue("tmp_path") if "tmp_path" in request.fixturenames else None
    yield
    files = _new_session_files(request, tmp)
    if not files or request.node.get_closest_marker("damaged_files"):
        return
    from tactile_studio.errors import SessionFileError
    from tactile_studio.storage.format.session_check import check_file
    from tactile_studio.storage.format.session_compress import wait_for_compression
    failed = []
    for f in files:
        wait_for_compression(f)
        try:
            result = check_file(f)
        except (SessionFileError, OSError):
            continue  # not a session (or damaged on purpose): nothing to hold it to
        if not result.ok:
            failed.append(f"{f}:\n    " + "\n    ".join(result.violations))
    assert not failed, "session files fail `check`:\n" + "\n".join(failed)


@pytest.fixture(scope="session")
def dev_set():
    """The real development set's folder (benchmarks/real_data.py: ``../shared`` beside
    the repository, or ``$TACTILE_STUDIO_DEV_SET``); skips with one line where absent."""
    from benchmarks.real_data import dev_set as find
    from benchmarks.real_data import skip_reason
    folder = find()
    if folder is None:
        pytest.skip(skip_reason())
    return folder


@pytest.fixture(scope="session")
def shared_runs(tmp_path_factory):
    """The tiny runs several learn test files read (tests/shared_runs.py), trained once
    per test run: under xdist in a folder all workers share (``getbasetemp().parent``,
    the run's own), else in this process's temporary folder."""
    from shared_runs import SharedRuns
    base = tmp_path_factory.getbasetemp()
    return SharedRuns((base.parent if _WORKER else base) / "shared-runs")


@pytest.fixture
def wait_until():
    """The shared bounded wait (tests/waiting.py), for tests that prefer a fixture."""
    from waiting import wait_until as wait
    return wait


@pytest.fixture(autouse=True)
def no_recorder_left_running():
    """A test that starts a recorder stops it: one left running would write into its
    file while the interpreter tears down (a crash after the last test)."""
    from tactile_studio.storage.recording.recorder import running_recorders
    before = set(map(id, running_recorders()))
    yield
    left = [r for r in running_recorders() if id(r) not in before]
    for r in left:
        r.stop()
    assert not left, f"recorder left running: {[str(r.path) for r in left]}"


@pytest.fixture(autouse=True)
def widgets_live_until_closed(monkeypatch):
    """Close the widgets a test registered with ``qtbot.addWidget`` at its end.

    pytest-qt holds them weakly: a window the test no longer references was destroyed at
    the test's last line without a closeEvent (a collection console's recording kept
    running). Here they are held until closed; one its parent already deleted is skipped.
    Set up after (so torn down before) the recorder check.
    """
    from pytestqt.qtbot import QtBot
    held = []

    def add_widget(self, widget, *, before_close_func=None):
        held.append((widget, before_close_func))

    monkeypatch.setattr(QtBot, "addWidget", add_widget)
    yield
    if not held:
        return
    import shiboken6
    from PySide6.QtWidgets import QApplication
    for widget, before_close in held:
        if shiboken6.isValid(widget):
            if before_close is not None:
                before_close(widget)
            widget.close()
            widget.deleteLater()
    held.clear()
    QApplication.processEvents()
