"""Training in a spawned worker process: events, cancel keeps folds, resume, errors and
a worker that dies are reported (tiny cnn1d and knn on virtual participants)."""

from __future__ import annotations

import json
import os
import signal
import time

import pytest
from learn_fixtures import make_dataset_folder, trial_record, write_participant

from tactile_studio.learn.experiments.experiment import ExperimentConfig
from tactile_studio.learn.experiments.train_job import TrainJob, eta_seconds, model_settings

GESTURES = ("Poke", "Heavy Pat", "Back & Forth Rub")


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("job")
    make_dataset_folder(root / "data", participants=3, blocks=3, gestures=GESTURES)
    return root


def wait_until_finished(job: TrainJob, seconds: float = 240, stop_on=None) -> list[dict]:
    events: list[dict] = []
    deadline = time.monotonic() + seconds
    while job.running and time.monotonic() < deadline:
        events += job.poll()
        if stop_on is not None and stop_on(events):
            return events
        time.sleep(0.05)
    assert not job.running, "the job did not finish in time"
    return events


def cnn_config(data) -> ExperimentConfig:
    return ExperimentConfig(data=[str(data / "data")], model="cnn1d", evaluation="lopo",
                            preset="tiny", epochs=6, cache_dir=str(data / "cache"), threads=1,
                            device="cpu")


@pytest.mark.slow
def test_worker_events_cancel_and_resume(data, tmp_path):
    out = tmp_path / "run"
    job = TrainJob(cnn_config(data), out).start()
    events = wait_until_finished(
        job, stop_on=lambda ev: any(e.type == "fold" for e in ev))
    job.cancel()
    events += wait_until_finished(job)
    kinds = [e.type for e in events]
    assert "epoch" in kinds and "progress" in kinds
    first = next(e for e in events if e.type == "epoch")
    assert first.epoch == 1 and first.val_acc is not None and first.n_folds == 3
    assert job.finished.type in ("cancelled", "done")
    kept = sorted(p.parent.name for p in (out / "folds").glob("*/fold.json"))
    assert len(kept) >= 1
    if job.finished.type == "cancelled":
        assert not json.loads((out / "metrics.json").read_text())["complete"]
    # resume: the finished folds are not trained again
    job2 = TrainJob(cnn_config(data), out).start()
    events2 = wait_until_finished(job2)
    assert job2.finished.type == "done", job2.finished
    folds = [e for e in events2 if e.type == "fold"]
    assert len(folds) == 3 and sum(e.resumed for e in folds) == len(kept)
    assert json.loads((out / "metrics.json").read_text())["complete"]


def test_worker_errors_are_messages(data, tmp_path):
    # every trial discarded: a clear message, not a traceback
    bad = tmp_path / "bad"
    bad.mkdir()
    write_participant(bad / "P01.h5", "P01", 3, gestures=("Poke",), blocks=0,
                      extra_trials=[trial_record(0, "Poke", 5, 40, status="discarded")])
    cfg = ExperimentConfig(data=[str(bad)], model="knn", evaluation="lopo", preset="tiny",
                           use_cache=False)
    job = TrainJob(cfg, tmp_path / "r1").start()
    wait_until_finished(job)
    assert job.finished.type == "error"
    assert "no trials with status ok" in job.finished.message
    # a worker that dies (killed) is reported, and the caller lives on
    job = TrainJob(cnn_config(data), tmp_path / "r2").start()
    wait_until_finished(job, stop_on=lambda ev: any(e.type == "progress" for e in ev))
    os.kill(job.pid, signal.SIGKILL)
    wait_until_finished(job, 30)
    assert job.finished.type == "error"
    assert "ended unexpectedly (exit code -9)" in job.finished.message


def test_model_settings_and_eta():
    knn = dict((k, v) for k, v, _ in model_settings("knn", "tiny"))
    assert knn["n_neighbors"] == 5
    cnn = {k: (v, h) for k, v, h in model_settings("cnn1d", "tiny")}
    assert cnn["lr"] == (0.01, "learning rate") and "filters" in cnn
    assert eta_seconds(0.25, 10.0) == pytest.approx(30.0)
    assert eta_seconds(0.0, 10.0) is None


@pytest.mark.parametrize("name", ["cnn3d", "cnn1d", "cnn_transformer", "mts3d", "sefusion",
                                  "rf", "et", "knn"])
def test_every_option_of_every_model_has_its_own_line_of_help(name):
    rows = model_settings(name, "tiny")
    assert rows and all(help_ and help_ != "model option" for _, _, help_ in rows), \
        [k for k, _, h in rows if h == "model option"]


THREAD_VARS = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "OMP_WAIT_POLICY")


@pytest.mark.slow
def test_training_uses_one_thread_that_sleeps_by_default(data, tmp_path, monkeypatch):
    """As a user starts it (no thread settings in the environment, no --threads), the
    train panel's worker and ``tactile-studio train`` train with one torch thread and
    OpenMP's passive wait: torch's default (one thread per core, spinning at barriers)
    cost 22x the CPU per step on a loaded 2-core machine (issue 45, docs/learning).
    Before: resolved.threads read torch 2 (the cores here) and no wait policy."""
    import subprocess
    import sys

    for name in THREAD_VARS:  # the suite's one-thread settings (conftest) removed
        monkeypatch.delenv(name, raising=False)
    config = ExperimentConfig(data=[str(data / "data")], model="cnn1d", evaluation="lopo",
                              preset="tiny", epochs=1, cache_dir=str(data / "cache"),
                              device="cpu")
    job = TrainJob(config, tmp_path / "panel").start()
    wait_until_finished(job)
    assert job.finished.type == "done", job.finished
    cli = tmp_path / "cli"
    proc = subprocess.run(
        [sys.executable, "-m", "tactile_studio", "train", "--data", str(data / "data"),
         "--model", "cnn1d", "--preset", "tiny", "--epochs", "1", "--device", "cpu",
         "--cache-dir", str(data / "cache"), "--out", str(cli)],
        capture_output=True, text=True, timeout=240, env=dict(os.environ))
    assert proc.returncode == 0, proc.stderr
    for run in (tmp_path / "panel", cli):
        threads = json.loads((run / "config.json").read_text())["resolved"]["threads"]
        assert threads == {"torch": 1, "omp_wait_policy": "PASSIVE"}, (run, threads)
