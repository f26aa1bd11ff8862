"""rf / k-NN prediction time per trial: scikit-learn (and the old k-NN path that refitted
at every prediction) against the ONNX graph in onnxruntime that run folders now hold.

Two cases: one trial at a time (the streaming predictor / live inference) and a whole
test set at once (``evaluate``), both per trial, preset "full" (300 trees, k = 5
distance-weighted), on handcrafted features of simulated participants' trials.
Feature extraction (the same for every path) is timed separately.
Run: python -m benchmarks baselines
"""

from __future__ import annotations

import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from learn_fixtures import make_dataset_folder  # noqa: E402

from tactile_studio.learn.data.dataset import build_dataset  # noqa: E402
from tactile_studio.learn.data.features import feature_matrix  # noqa: E402
from tactile_studio.learn.learners.baselines import BaselineModel, baseline_options  # noqa: E402


def _per_call(fn, runs: int) -> float:
    """Median seconds of ``fn()`` over ``runs`` calls (after one warm-up)."""
    fn()
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def _old_knn(model: BaselineModel, x_train: np.ndarray, y_train: np.ndarray, x: np.ndarray):
    """What the k-NN baseline did before: standardise, refit, predict, on every call."""
    from sklearn.neighbors import KNeighborsClassifier

    mean, scale = x_train.mean(axis=0), x_train.std(axis=0)
    scale = np.where(scale < 1e-12, 1.0, scale)
    o = model.options
    knn = KNeighborsClassifier(n_neighbors=o["n_neighbors"], weights=o["weights"], p=o["p"])
    knn.fit((x_train - mean) / scale, y_train)
    return knn.predict_proba((x - mean) / scale)


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        make_dataset_folder(Path(tmp) / "data", participants=4, blocks=3)
        ds = build_dataset([str(Path(tmp) / "data")], "physical", None, str(Path(tmp) / "c"))
    t0 = time.perf_counter()
    x, _ = feature_matrix(ds.trials, ds.channel_names, ds.rates)
    features = (time.perf_counter() - t0) / len(ds)
    people = np.array(ds.participants)
    test = people == sorted(set(people))[0]
    xtr, ytr, xte = x[~test], ds.labels[~test], x[test]
    print(f"{len(ds)} trials, {x.shape[1]} features; train {len(xtr)}, test {len(xte)}; "
          f"feature extraction {features * 1e3:.2f} ms/trial (every path)")
    print(f"{'model':6s} {'path':28s} {'1 trial':>12s} {'test set, per trial':>22s}")
    for name in ("rf", "knn"):
        model = BaselineModel(name, baseline_options(name, "full", {}), ds.n_classes)
        model.fit(xtr, ytr, seed=0)
        one = xte[:1]
        rows = [("scikit-learn predict_proba", lambda a: model.estimator.predict_proba(a))]
        if name == "knn":
            rows.append(("old: refit at every predict", lambda a: _old_knn(model, xtr, ytr, a)))
        rows.append(("onnxruntime (ONNX file)", model.predict_proba))
        for label, fn in rows:
            single = _per_call(lambda fn=fn: fn(one), 50)
            batch = _per_call(lambda fn=fn: fn(xte), 10) / len(xte)
            print(f"{name:6s} {label:28s} {single * 1e3:9.3f} ms {batch * 1e3:19.4f} ms")
        print(f"{'':6s} ONNX file {len(model.onnx) / 1024:.0f} KiB")


if __name__ == "__main__":
    main()
