"""Learning pipeline benchmarks: dataset build time (cold decode vs cache), training
throughput through the real pipeline (samples/s, windows/s for the windowed model) and
batch-1 inference latency per prediction on 2 threads, for every model family.

Run: .venv/bin/python benchmarks/bench_learn.py [--quick] [--threads N]
(--quick: tiny presets only). Data: virtual participants made with the simulator.
Prints tables; asserts nothing. The models engineer's bench_models.py adds ONNX / int8 /
streaming-predictor latency.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from learn_fixtures import make_dataset_folder  # noqa: E402

from tactile_studio.learn.data.dataset import build_dataset  # noqa: E402
from tactile_studio.learn.data.features import trial_features  # noqa: E402
from tactile_studio.learn.learners.families import (  # noqa: E402
    DataInfo,
    available_models,
    make_learner,
)
from tactile_studio.learn.learners.train import fit  # noqa: E402


def timed(fn, budget_s: float = 1.0, min_runs: int = 5, max_runs: int = 200) -> list[float]:
    fn()
    out: list[float] = []
    start = time.perf_counter()
    while len(out) < max_runs and (len(out) < min_runs or time.perf_counter() - start < budget_s):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return out


def bench_dataset(folder: Path, cache: Path) -> None:
    print("\n== dataset build (4 participants x 9 gestures x 3 trials of 2 s) ==")
    for grid in ("physical", "virtual"):
        t0 = time.perf_counter()
        ds = build_dataset([folder], grid=grid, cache_dir=cache)
        cold = time.perf_counter() - t0
        t0 = time.perf_counter()
        build_dataset([folder], grid=grid, cache_dir=cache)
        warm = time.perf_counter() - t0
        print(f"{grid:9s} {len(ds)} trials {ds.grid_shape[0]}x{ds.grid_shape[1]}: decode "
              f"{cold * 1e3:7.1f} ms ({cold / len(ds) * 1e3:.2f} ms/trial), from cache "
              f"{warm * 1e3:6.1f} ms")


def bench_model(name: str, preset: str, ds, epochs: int, max_samples: int) -> None:
    learner = make_learner(name, preset, {}, epochs, "cpu")
    info = DataInfo.of(ds)
    t0 = time.perf_counter()
    x, owner = learner.samples(ds)
    t_views = time.perf_counter() - t0
    y = ds.labels[owner]
    stats = learner.norm_stats(x)
    x = learner.apply_norm(x, stats)
    sel = np.random.default_rng(0).permutation(len(x))[:max_samples]
    xt, yt = x[sel], y[sel]
    if learner.kind == "torch":
        torch.manual_seed(0)
        model = learner.build(info)
        n_params = sum(p.numel() for p in model.parameters())
        t0 = time.perf_counter()
        _, history, _ = fit(model, (xt, yt), (xt[:0], yt[:0]), learner.settings, 0,
                            torch.device("cpu"))
        train_s = (time.perf_counter() - t0) / len(history)
        model.eval()
        one = torch.from_numpy(xt[:1])
        with torch.inference_mode():
            lat = timed(lambda: torch.softmax(model(one), 1))
        size = f"{n_params:>10,d} params"
    else:
        t0 = time.perf_counter()
        fitted, _, _ = learner.fit(info, (xt, yt), (xt[:0], yt[:0]), 0, None, None)
        train_s = time.perf_counter() - t0
        trial = ds.trials[0]
        pitch = 0.5 if ds.grid == "virtual" else 1.0

        def predict_one() -> None:  # features of a raw trial + the model
            f, _ = trial_features(trial, ds.channel_names, float(ds.rates[0]), pitch)
            fitted.predict_proba(f[None])

        lat = timed(predict_one)
        size = f"{x.shape[1]:>10d} feats "
    unit = "windows" if learner.windowed else "samples"
    print(f"{name:16s} {preset:5s} {size} views {t_views * 1e3:7.1f} ms | train "
          f"{len(xt) / train_s:8.1f} {unit}/s ({len(xt)} per epoch) | batch-1 latency "
          f"median {statistics.median(lat) * 1e3:7.2f} ms p95 "
          f"{np.percentile(lat, 95) * 1e3:7.2f} ms", flush=True)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="tiny presets only")
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args(argv if argv is not None else [])
    torch.set_num_threads(args.threads)
    print(f"torch {torch.__version__}, {args.threads} threads, load average "
          f"{os.getloadavg()[0]:.1f} (shared machine: compare rows, not absolutes)")
    with tempfile.TemporaryDirectory() as tmp:
        folder, cache = Path(tmp) / "data", Path(tmp) / "cache"
        make_dataset_folder(folder, participants=4, blocks=3)
        bench_dataset(folder, cache)
        ds = build_dataset([folder], cache_dir=cache)
        print("\n== training throughput (2 epochs; full presets on at most 64 samples) "
              "and batch-1 inference latency ==")
        for preset in ["tiny"] if args.quick else ["tiny", "full"]:
            for name in available_models():
                bench_model(name, preset, ds, epochs=2,
                            max_samples=100_000 if preset == "tiny" else 64)


if __name__ == "__main__":
    main(sys.argv[1:])
