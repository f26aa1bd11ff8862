"""Do the generalisation options beat the 2 s-window random forest on unseen people?

Data: 10 virtual participants x 9 gestures x 4 repetitions of 2 s at the simulator's
default difficulty (``real``, calibrated to the real recordings). Protocol: LOPO. Each
configuration is a sweep on 2 local worker processes (``--jobs``); the table reports
per-trial accuracy, macro F1 and the training time summed over the 10 folds (the cost on
one core). Run: .venv/bin/python benchmarks/bench_generalise.py [--quick] [--jobs N]
(--quick: tiny presets, 15 epochs; default: full presets with their own epochs).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from learn_fixtures import make_dataset_folder  # noqa: E402

from tactile_studio.learn.executors import LocalExecutor  # noqa: E402
from tactile_studio.learn.experiment import ExperimentConfig  # noqa: E402
from tactile_studio.learn.sweep import run_sweep  # noqa: E402

GEN = {"augment": "all", "augment_copies": 2, "participant_norm": True, "balance": True,
       "val_by": "participant"}
CONFIGS = [
    ("rf (baseline)", ["rf"], {}),
    ("rf + participant norm", ["rf"], {"participant_norm": True}),
    ("rf + augment all x2", ["rf"], {"augment": "all", "augment_copies": 2}),
    ("rf + all options", ["rf"], GEN),
    ("torch plain", ["cnn3d", "sefusion", "cnn1d"], {}),
    ("torch + all options", ["cnn3d", "sefusion", "cnn1d"], GEN),
]


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--only", default="", help="run configurations whose name has this")
    ap.add_argument("--models", nargs="+", default=None, help="torch models (default: 3)")
    args = ap.parse_args(argv if argv is not None else [])
    preset, epochs = ("tiny", 15) if args.quick else ("full", None)
    with tempfile.TemporaryDirectory() as tmp:
        data = Path(tmp) / "data"
        make_dataset_folder(data, participants=10, blocks=4, difficulty="real")
        print(f"LOPO, 10 participants x 9 gestures x 4 trials, difficulty real, preset {preset}")
        print(f"{'configuration':26s}{'model':>10s}{'trial acc':>11s}{'f1':>8s}"
              f"{'train s':>9s}{'wall s':>8s}")
        for name, models, options in CONFIGS:
            if args.only and args.only not in name:
                continue
            if args.models and models != ["rf"]:
                models = args.models
            base = ExperimentConfig(data=[str(data)], model=models[0], protocol="lopo",
                                    preset=preset, epochs=None if models == ["rf"] else epochs,
                                    cache_dir=str(Path(tmp) / "cache"),
                                    overrides={} if models == ["rf"] else {"lr": "0.003"},
                                    **options)
            t0 = time.perf_counter()
            with LocalExecutor(args.jobs) as ex:
                res = run_sweep(base, models, [None], ex)
            wall = time.perf_counter() - t0
            for row in res.rows:
                print(f"{name:26s}{row['model']:>10s}{row['trial_accuracy']:>11.3f}"
                      f"{row['f1_macro']:>8.3f}{row['train_seconds']:>9.1f}{wall:>8.1f}",
                      flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
