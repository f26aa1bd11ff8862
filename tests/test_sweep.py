"""Sweeps: models x channel sets x folds as tasks on local worker processes and on a real
local Ray instance (2 CPUs, no dashboard) give identical metrics, equal to
``run_experiment``'s; finished tasks are kept on cancel and a re-run resumes."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest
from learn_fixtures import make_dataset_folder
from waiting import wait_until

from tactile_studio.cli import main as cli_main
from tactile_studio.errors import Cancelled, UserError
from tactile_studio.jobs import CancelToken
from tactile_studio.learn.experiments.executors import LocalExecutor, RayExecutor, make_executor
from tactile_studio.learn.experiments.experiment import ExperimentConfig, run_experiment
from tactile_studio.learn.experiments.sweep import run_sweep, task_gpus
from tactile_studio.learn.results.rescore import rescore_run

pytestmark = pytest.mark.slow  # real worker processes and a Ray instance


GESTURES = ("Poke", "Circular Stroke", "Heavy Pat")
MODELS = ["rf", "cnn1d"]
CHANNELS = ["normal", "shear"]
EXE = str(Path(sys.executable).parent / "tactile-studio")


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("sweep")
    make_dataset_folder(root / "data", participants=3, blocks=2, gestures=GESTURES)
    return root


def _base(data, **kw) -> ExperimentConfig:
    cfg = dict(data=[str(data / "data")], model="rf", evaluation="lopo", preset="tiny", epochs=3,
               cache_dir=str(data / "cache"), overrides={}, adapt="auto")
    cfg.update(kw)
    return ExperimentConfig(**cfg)


@pytest.fixture(scope="module")
def local_run(data):
    with LocalExecutor(2) as ex:
        return run_sweep(_base(data), MODELS, CHANNELS, ex, data / "local")


def _scores(result) -> dict:
    return {key: {k: m[k] for k in ("accuracy", "trial_accuracy", "f1_macro", "kappa",
                                   "confusion_counts", "trial_confusion_counts")}
            for key, m in result.metrics.items()}


def test_local_sweep_writes_a_table_equal_to_single_runs(data, local_run):
    rows = {(r["model"], r["channels"]): r for r in local_run.rows}
    assert set(rows) == {(m, c) for m in MODELS for c in CHANNELS}
    assert all(r["folds_done"] == r["folds"] == 3 for r in rows.values())
    # auto: a network meets each held-out person on their own terms, a forest as trained
    assert {r["model"]: (r["adapt"], r["name"]) for r in rows.values()} == {
        "rf": ("none", "rf"), "cnn1d": ("person", "cnn1d (adapted)")}
    csv_lines = (data / "local" / "results.csv").read_text().splitlines()
    assert csv_lines[0].startswith("model,name,adapt,channels,folds_done") and len(csv_lines) == 5
    assert len(list((data / "local" / "tasks").glob("*.json"))) == 12
    for model in MODELS:  # a task in a worker = the same fold in one process
        single = run_experiment(_base(data, model=model, channels="shear")).metrics
        swept = local_run.metrics[f"{model}/shear"]
        assert swept["accuracy"] == single["accuracy"]
        assert swept["confusion_counts"] == single["confusion_counts"]
        # each row is a run folder whose saved fold models reproduce its metrics
        run = data / "local" / "runs" / f"{model}-shear"
        assert rescore_run(run)["accuracy"] == pytest.approx(swept["accuracy"])
        assert json.loads((run / "metrics.json").read_text())["complete"] is True


def _descendants(root: int) -> set[int]:
    children: dict[int, list[int]] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            ppid = int(stat.read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, IndexError, ValueError):
            continue
        children.setdefault(ppid, []).append(int(stat.parent.name))
    found, todo = set(), [root]
    while todo:
        for child in children.get(todo.pop(), []):
            if child not in found:
                found.add(child)
                todo.append(child)
    return found


def _listening(pids: set[int]) -> list[str]:
    """The local addresses (hex, as /proc/net/tcp{,6} spell them) of the TCP sockets
    ``pids`` listen on."""
    inodes = set()
    for pid in pids:
        try:
            for fd in Path(f"/proc/{pid}/fd").iterdir():
                target = os.readlink(fd)
                if target.startswith("socket:["):
                    inodes.add(target[8:-1])
        except OSError:
            continue
    found = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        for line in Path(table).read_text().splitlines()[1:]:
            cols = line.split()
            if cols[3] == "0A" and cols[9] in inodes:  # LISTEN
                found.append(cols[1].split(":")[0])
    return found


LOOPBACK_HEX = ("0100007F", "0000000000000000FFFF00000100007F",
                "00000000000000000000000001000000")  # 127.0.0.1, ::ffff:127.0.0.1, ::1


ENV_KEYS = ("RAY_AUTH_TOKEN", "RAY_AUTH_MODE", "TORCHINDUCTOR_CACHE_DIR")


def test_ray_sweep_gives_identical_metrics(data, local_run, tmp_path, monkeypatch):
    # the local instance is private to the run: loopback only, nothing in the home folder
    # (Ray wrote ~/.ray/auth_token), its files under the app's cache folder and removed
    # afterwards (Ray left /tmp/ray/session_* behind)
    for name in ("home", "cache"):
        (tmp_path / name).mkdir()
    tmp = Path(tempfile.mkdtemp(prefix="ts", dir="/tmp"))  # short: Ray's sockets go there
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.setenv("TMPDIR", str(tmp))
    monkeypatch.setattr(tempfile, "tempdir", str(tmp))
    monkeypatch.setenv("TACTILE_STUDIO_CACHE_DIR", str(tmp_path / "cache"))
    env_before = {k: os.environ.get(k) for k in ENV_KEYS}
    with RayExecutor(jobs=2) as ex:  # a real local Ray instance: ray.init(num_cpus=2)
        import ray

        assert ray.cluster_resources().get("CPU") == 2
        listening = _listening(_descendants(os.getpid()) | {os.getpid()})
        result = run_sweep(_base(data), MODELS, CHANNELS, ex, data / "ray")
    assert not ray.is_initialized()
    assert listening and set(listening) <= set(LOOPBACK_HEX), listening
    assert list((tmp_path / "home").iterdir()) == [], list((tmp_path / "home").rglob("*"))[:20]
    left = sorted(p.name for p in tmp.iterdir())
    shutil.rmtree(tmp)
    assert left == []
    assert list((tmp_path / "cache").rglob("*")) == [tmp_path / "cache" / "ray"]
    # the environment as it was (torch itself may have set its inductor folder before)
    assert {k: os.environ.get(k) for k in ENV_KEYS} == env_before
    assert _scores(result) == _scores(local_run)
    saved = json.loads((data / "ray" / "results.json").read_text())
    assert saved["complete"] and len(saved["rows"]) == 4


def test_cancel_keeps_finished_tasks_and_a_rerun_resumes(data, local_run):
    token = CancelToken()
    seen = []

    def progress(fraction: float, message: str) -> None:
        if "done" in message and "before" not in message:
            seen.append(message)
            token.cancel()

    out = data / "cancelled"
    with LocalExecutor(1) as ex, pytest.raises(Cancelled, match="finished"):
        run_sweep(_base(data), MODELS, CHANNELS, ex, out, progress, token)
    kept = list((out / "tasks").glob("*.json"))
    assert 1 <= len(kept) < 12 and len(seen) == len(kept)
    assert json.loads((out / "results.json").read_text())["complete"] is False
    messages = []
    with LocalExecutor(2) as ex:
        again = run_sweep(_base(data), MODELS, CHANNELS, ex, out, lambda f, m: messages.append(m))
    assert f"{12 - len(kept)} tasks to run ({len(kept)} done before)" in messages
    assert _scores(again) == _scores(local_run)
    with LocalExecutor(1) as ex, pytest.raises(UserError, match="other settings"):
        run_sweep(_base(data, seed=5), MODELS, CHANNELS, ex, out)


def test_gpu_requests_and_bad_settings():
    assert task_gpus("rf", "cuda") == 0 and task_gpus("cnn3d", "cpu") == 0
    assert task_gpus("cnn3d", "cuda") == 1
    with pytest.raises(UserError, match="executor"):
        make_executor("slurm")
    with pytest.raises(UserError, match="--address"):
        make_executor("local", address="10.0.0.1:6379")


def test_cli_sweep_prints_the_table(data, capsys):
    code = cli_main(["sweep", "--data", str(data / "data"), "--models", "rf", "knn",
                     "--channels", "both", "--preset", "tiny", "--jobs", "2",
                     "--cache-dir", str(data / "cache"), "--out", str(data / "cli")])
    out = capsys.readouterr().out
    assert code == 0 and "trial_accuracy" in out and "3/3" in out
    assert cli_main(["sweep", "--data", str(data / "data"), "--models", "nope",
                     "--cache-dir", str(data / "cache")]) == 1
    assert "unknown model 'nope'" in capsys.readouterr().err


def _workers(parent: int) -> set[int]:
    """PIDs of the sweep's worker processes (spawned children, not the resource tracker)."""
    found = set()
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            ppid = int(stat.read_text().rsplit(")", 1)[1].split()[1])
            cmdline = (stat.parent / "cmdline").read_bytes()
        except (OSError, IndexError, ValueError):
            continue
        if ppid == parent and b"spawn_main" in cmdline:
            found.add(int(stat.parent.name))
    return found


def _running(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return state != "Z"


def _training(pid: int) -> bool:
    """The worker has imported torch: it is running its task (or about to)."""
    try:
        return "torch" in Path(f"/proc/{pid}/maps").read_text()
    except OSError:
        return False


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL], ids=["sigterm", "sigkill"])
def test_a_sweep_stopped_by_a_signal_leaves_no_worker_running(data, sig):
    # long tasks (cnn1d for 5,000 epochs): a worker left behind would run for minutes
    out, log = data / f"signalled-{sig.name}", data / f"signalled-{sig.name}.err"
    workers: set[int] = set()
    with log.open("w") as err_file:  # a file, not a pipe: orphans would hold a pipe open
        proc = subprocess.Popen([EXE, "sweep", "--data", str(data / "data"), "--models",
                                 "cnn1d", "--channels", "both", "--preset", "tiny",
                                 "--epochs", "5000", "--jobs", "2", "--cache-dir",
                                 str(data / f"cache-{sig.name}"), "--out", str(out)],
                                stdout=subprocess.DEVNULL, stderr=err_file)
    try:
        wait_until(lambda: len(_workers(proc.pid)) == 2, 60.0, what="two sweep workers")
        workers = _workers(proc.pid)
        wait_until(lambda: all(_training(w) for w in workers), 60.0,
                   what="the workers to start their tasks")
        proc.send_signal(sig)
        proc.wait(timeout=60)
        wait_until(lambda: not any(_running(w) for w in workers), 30.0,
                   what="the workers to exit")
    finally:
        proc.kill()
        proc.wait()
        for w in workers:  # only if the test failed: do not leave them running
            if _running(w):
                os.kill(w, signal.SIGKILL)
    err = log.read_text()
    if sig == signal.SIGTERM:  # cancelled as by Ctrl-C: the table of what finished is kept
        assert proc.returncode == 130 and "Traceback" not in err, err
        assert "cancelled" in err
        assert json.loads((out / "results.json").read_text())["complete"] is False
