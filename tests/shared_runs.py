"""Tiny training runs shared by the test files that read the same ones (test_adapt,
test_fused, test_person_calibration): each run is trained once per test run, by whichever
xdist worker asks first, and every module gets its own copy to write into.

Those three files trained 13 runs on the same 3-people x 3-gestures data, 8 of them
distinct; one cnn1d fold set is ~20 s of CPU and the machine has 2 cores. The store
lives beside the workers' temporary folders (``getbasetemp().parent`` under xdist), a
file lock per run: a second worker that needs a run being trained builds another one it
needs first, then waits. A run folder counts once its result is pickled beside it.
"""

from __future__ import annotations

import pickle
import shutil
from dataclasses import dataclass
from pathlib import Path

from filelock import FileLock, Timeout
from learn_fixtures import make_dataset_folder

from tactile_studio.learn.experiments.experiment import (
    ExperimentConfig,
    RunResult,
    run_experiment,
)

GESTURES = ("Poke", "Heavy Pat", "Twist")


@dataclass(frozen=True)
class RunSpec:
    """One tiny lopo run on the shared data (epochs 2 for a network, threads 1)."""

    model: str
    adapt: str = "none"
    rf_weight: float = 0.0
    features: str = ""

    def config(self, root: Path) -> ExperimentConfig:
        overrides: dict[str, object] = {}
        if self.rf_weight:
            overrides["rf_weight"] = self.rf_weight
        if self.features:
            overrides["features"] = self.features
        return ExperimentConfig(data=[str(root / "data")], model=self.model,
                                evaluation="lopo", preset="tiny",
                                epochs=None if self.model == "rf" else 2, threads=1,
                                device="cpu", cache_dir=str(root / "cache"),
                                adapt=self.adapt, overrides=overrides)


# every run any of the three files reads, by one name each
RUNS = {
    "net": RunSpec("cnn1d"),
    "net_adapted": RunSpec("cnn1d", "person"),
    "rf": RunSpec("rf"),
    "rf_adapted": RunSpec("rf", "person"),
    "rf_basic": RunSpec("rf", features="basic"),
    "fused_adapted": RunSpec("cnn1d", "person", rf_weight=0.5),
    "fused_auto": RunSpec("cnn1d", "auto", rf_weight=0.5),
    "fused_03": RunSpec("cnn1d", rf_weight=0.3),
}


class SharedRuns:
    """The store: the data (3 people, 2 blocks of ``GESTURES``), its cache and the runs."""

    def __init__(self, root: Path) -> None:
        self.root = root
        root.mkdir(parents=True, exist_ok=True)
        with FileLock(root / "data.lock"):
            if not (root / "data.done").is_file():
                make_dataset_folder(root / "data", participants=3, blocks=2,
                                    gestures=GESTURES)
                (root / "data.done").touch()

    def _result(self, name: str) -> Path:
        return self.root / "runs" / f"{name}.pickle"

    def _build(self, name: str) -> None:
        """Train ``name`` unless done (the caller holds its lock)."""
        if self._result(name).is_file():
            return
        out = self.root / "runs" / name
        shutil.rmtree(out, ignore_errors=True)  # a worker that died part way
        result = run_experiment(RUNS[name].config(self.root), out)
        self._result(name).write_bytes(pickle.dumps(result))

    def ensure(self, names: list[str]) -> None:
        """Every run of ``names`` trained: first those no other worker is training."""
        (self.root / "runs").mkdir(exist_ok=True)
        waiting = []
        for name in names:
            lock = FileLock(self.root / "runs" / f"{name}.lock")
            try:
                with lock.acquire(timeout=0):
                    self._build(name)
            except Timeout:
                waiting.append(name)
        for name in waiting:
            with FileLock(self.root / "runs" / f"{name}.lock"):
                self._build(name)

    def copy_to(self, root: Path, names: dict[str, str]) -> dict[str, RunResult]:
        """The data, its cache and the runs ``names`` ({name in ``root``: shared name})
        copied into ``root``; each run's result, as ``run_experiment`` returned it. The
        copied runs' config still names the shared data (read only: nothing writes it)."""
        self.ensure(list(dict.fromkeys(names.values())))
        shutil.copytree(self.root / "data", root / "data")
        shutil.copytree(self.root / "cache", root / "cache")
        results = {}
        for mine, shared in names.items():
            shutil.copytree(self.root / "runs" / shared, root / mine)
            results[mine] = pickle.loads(self._result(shared).read_bytes())
        return results
