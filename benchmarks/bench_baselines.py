"""rf / extra-trees / k-NN prediction time per trial, and the default model's time per live
window (features + ONNX; issue 45's budget is 5 ms): scikit-learn (and the old k-NN path
that refitted at every prediction) against the ONNX graph in onnxruntime that run folders
now hold.

Two cases: one trial at a time (the streaming predictor / live inference) and a whole
test set at once (``evaluate``), both per trial, preset "full" (300 trees, k = 5
distance-weighted; et 300 trees), on handcrafted features of simulated participants' 2 s
trials (rf and et with the touch and shear features, k-NN without). Feature extraction
(the same for every path) is timed separately.
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
from tactile_studio.learn.learners.baselines import (  # noqa: E402
    BASELINES,
    DEFAULT_MODEL,
    BaselineModel,
    baseline_options,
)


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
    ds_args = (ds.trials, ds.channel_names, ds.rates)
    feature_matrix(ds.trials[:1], ds.channel_names, ds.rates[:1], touch=True)  # imports
    # CPU time: on the shared 2-core machine wall time measures the other jobs' load
    t0 = time.process_time()
    basic, _ = feature_matrix(*ds_args)
    t_basic = (time.process_time() - t0) / len(ds)
    t0 = time.process_time()
    touch, _ = feature_matrix(*ds_args, touch=True)
    t_touch = (time.process_time() - t0) / len(ds)
    people = np.array(ds.participants)
    test = people == sorted(set(people))[0]
    print(f"{len(ds)} trials of {ds.trials[0].shape[1]} frames; train {int((~test).sum())}, "
          f"test {int(test.sum())}; feature extraction {t_basic * 1e3:.2f} ms CPU/trial "
          f"({basic.shape[1]} features), {t_touch * 1e3:.2f} ms/trial with the touch and "
          f"shear features ({touch.shape[1]})")
    print(f"{'model':6s} {'path':28s} {'1 trial':>12s} {'test set, per trial':>22s}")
    onnx_one = {}
    for name in BASELINES:
        model = BaselineModel(name, baseline_options(name, "full", {}), ds.n_classes)
        x = touch if model.options["features"] == "touch" else basic
        xtr, ytr, xte = x[~test], ds.labels[~test], x[test]
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
        onnx_one[name] = single
        print(f"{'':6s} ONNX file {len(model.onnx) / 1024:.0f} KiB")
    total = t_touch + onnx_one[DEFAULT_MODEL]
    print(f"default model ({DEFAULT_MODEL}) per live window: features {t_touch * 1e3:.2f} ms + "
          f"ONNX {onnx_one[DEFAULT_MODEL] * 1e3:.2f} ms = {total * 1e3:.2f} ms "
          f"(budget 5 ms: {'met' if total <= 0.005 else 'NOT met'})")

if __name__ == "__main__":
    main()
