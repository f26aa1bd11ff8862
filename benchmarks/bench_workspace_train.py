"""Does training from the research workspace slow the live view? The main window runs
offscreen on the simulated sensor at 43 Hz; display fps (frames actually painted per
second) is measured idle, then while the workspace's worker process trains a tiny cnn1d
(lopo on virtual participants). The brief asks for at least 90% of the idle rate.

    QT_QPA_PLATFORM=offscreen .venv/bin/python benchmarks/bench_workspace_train.py [--seconds 8]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from learn_fixtures import make_dataset_folder  # noqa: E402


def painted_fps(window, seconds: float) -> float:
    from tactile_studio.ui.main_window import wait_for

    window.latency.clear()
    wait_for(seconds)
    return window.latency.values.size / seconds


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=8.0)
    args = ap.parse_args(argv or [])
    from tactile_studio.learn.experiments.experiment import ExperimentConfig
    from tactile_studio.learn.experiments.train_job import TrainJob
    from tactile_studio.ui.app import ensure_app
    from tactile_studio.ui.main_window import MainWindow, wait_for

    ensure_app()
    with tempfile.TemporaryDirectory() as tmp:
        make_dataset_folder(Path(tmp) / "data", participants=4, blocks=3)
        w = MainWindow(device="simulated", settings={"rate": "43", "gesture": "Twist"},
                       connect=True, persist=False)
        w.latency = type(w.latency)(keep=100_000)
        try:
            w.show()
            wait_for(2.5)
            idle = painted_fps(w, args.seconds)
            cfg = ExperimentConfig(data=[str(Path(tmp) / "data")], model="cnn1d",
                                   evaluation="lopo", preset="tiny", epochs=400,
                                   overrides={"patience": 1000}, threads=1, device="cpu",
                                   cache_dir=str(Path(tmp) / "cache"))
            job = TrainJob(cfg, Path(tmp) / "run").start()
            epochs = 0
            while not epochs and job.running:  # measure once the worker is really training
                epochs += sum(e.type == "epoch" for e in job.poll())
                wait_for(0.1)
            busy = painted_fps(w, args.seconds)
            epochs += sum(e.type == "epoch" for e in job.poll())
            job.cancel()
            while job.running:
                job.poll()
                wait_for(0.1)
        finally:
            w.shutdown()
            w.close()
    print(f"display fps idle          {idle:6.1f}")
    print(f"display fps while training {busy:6.1f}  ({100 * busy / idle:.0f}% of idle; "
          f"{epochs} epochs trained meanwhile in the worker process)")


if __name__ == "__main__":
    main(sys.argv[1:])
