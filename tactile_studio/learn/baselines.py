"""Random forest and k-nearest-neighbour baselines on handcrafted trial features.

Trained with scikit-learn, but saved without pickling: a fitted forest is stored as
plain arrays (each tree's children, split features, thresholds and leaf class
distributions) in a safetensors file and predicted by walking those arrays with numpy,
which gives the same probabilities as scikit-learn. k-NN stores its standardised
training features and labels (that is all a k-NN model is).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from tactile_studio.errors import UserError

BASELINES = ("rf", "knn")
DESCRIPTIONS = {
    "rf": "random forest on handcrafted statistical/spectral features + gesture metrics",
    "knn": "k-nearest neighbours on standardised handcrafted features",
}
_OPTIONS: dict[str, dict[str, dict[str, Any]]] = {
    "rf": {"full": {"n_estimators": 300, "max_depth": 0, "min_samples_leaf": 1,
                    "max_features": "sqrt"},
           "tiny": {"n_estimators": 100, "max_depth": 0, "min_samples_leaf": 1,
                    "max_features": "sqrt"}},
    "knn": {"full": {"n_neighbors": 5, "weights": "distance", "p": 2},
            "tiny": {"n_neighbors": 5, "weights": "distance", "p": 2}},
}
_CHOICES = {"weights": ("uniform", "distance"), "max_features": ("sqrt", "log2", "all")}


def baseline_options(name: str, preset: str, overrides: dict[str, Any]) -> dict[str, Any]:
    """Preset options with ``overrides`` applied (unknown key or bad value -> UserError)."""
    if preset not in ("full", "tiny"):
        raise UserError(f"unknown preset '{preset}' (available: full, tiny)")
    options = dict(_OPTIONS[name][preset])
    for key, value in overrides.items():
        if key not in options:
            raise UserError(f"unknown option '{key}' for model '{name}' "
                            f"(allowed: {', '.join(options)})")
        default = options[key]
        try:
            value = type(default)(value)
        except (TypeError, ValueError):
            raise UserError(f"model '{name}': option {key}={value!r} is not a valid "
                            f"{type(default).__name__}") from None
        if key in _CHOICES and value not in _CHOICES[key]:
            raise UserError(f"model '{name}': {key}={value!r} is not one of "
                            f"{', '.join(_CHOICES[key])}")
        if isinstance(value, int) and value < (0 if key == "max_depth" else 1):
            raise UserError(f"model '{name}': {key}={value!r} must be positive")
        options[key] = value
    return options


class BaselineModel:
    """A fitted (or loaded) rf / knn over feature vectors, predicting all classes."""

    def __init__(self, name: str, options: dict[str, Any], n_classes: int) -> None:
        self.name, self.options, self.n_classes = name, options, n_classes
        self.tensors: dict[str, np.ndarray] = {}

    # ---- training --------------------------------------------------------------------
    def fit(self, x: np.ndarray, y: np.ndarray, seed: int) -> BaselineModel:
        if self.name == "rf":
            from sklearn.ensemble import RandomForestClassifier

            o = self.options
            rf = RandomForestClassifier(
                n_estimators=o["n_estimators"], max_depth=o["max_depth"] or None,
                min_samples_leaf=o["min_samples_leaf"],
                max_features=None if o["max_features"] == "all" else o["max_features"],
                random_state=seed, n_jobs=1)
            rf.fit(x, y)
            self.tensors = _forest_arrays(rf, self.n_classes)
        else:
            mean = x.mean(axis=0)
            scale = x.std(axis=0)
            scale = np.where(scale < 1e-12, 1.0, scale)
            self.tensors = {"x": ((x - mean) / scale).astype(np.float64),
                            "y": y.astype(np.int64), "mean": mean, "scale": scale}
        return self

    # ---- prediction ------------------------------------------------------------------
    def predict_proba(self, x: np.ndarray) -> np.ndarray:
        if self.name == "rf":
            return _forest_predict(self.tensors, x)
        from sklearn.neighbors import KNeighborsClassifier

        t, o = self.tensors, self.options
        k = min(o["n_neighbors"], len(t["y"]))
        knn = KNeighborsClassifier(n_neighbors=k, weights=o["weights"], p=o["p"])
        knn.fit(t["x"], t["y"])
        probs = np.zeros((len(x), self.n_classes))
        probs[:, knn.classes_] = knn.predict_proba((x - t["mean"]) / t["scale"])
        return probs

    # ---- persistence (safetensors, no pickle) ----------------------------------------
    def save(self, path) -> None:
        from safetensors.numpy import save_file

        save_file({k: np.ascontiguousarray(v) for k, v in self.tensors.items()}, str(path))

    @classmethod
    def load(cls, path, name: str, options: dict[str, Any], n_classes: int) -> BaselineModel:
        from safetensors.numpy import load_file

        model = cls(name, options, n_classes)
        from safetensors import SafetensorError

        try:
            model.tensors = load_file(str(path))
        except (OSError, SafetensorError) as exc:
            raise UserError(f"{path}: damaged or unreadable weights file ({exc})") from None
        return model


def _forest_arrays(rf, n_classes: int) -> dict[str, np.ndarray]:
    """Every tree's nodes, concatenated, with child indices made global."""
    left, right, feat, thr, value, roots = [], [], [], [], [], []
    offset = 0
    for est in rf.estimators_:
        tree = est.tree_
        n = tree.node_count
        cl, cr = tree.children_left.astype(np.int64), tree.children_right.astype(np.int64)
        left.append(np.where(cl >= 0, cl + offset, -1))
        right.append(np.where(cr >= 0, cr + offset, -1))
        feat.append(tree.feature.astype(np.int64))
        thr.append(tree.threshold.astype(np.float64))
        v = tree.value[:, 0, :].astype(np.float64)
        v = v / np.maximum(v.sum(axis=1, keepdims=True), 1e-12)
        full = np.zeros((n, n_classes))
        full[:, rf.classes_.astype(np.int64)] = v  # tree columns follow the forest's classes
        value.append(full)
        roots.append(offset)
        offset += n
    return {"left": np.concatenate(left), "right": np.concatenate(right),
            "feature": np.concatenate(feat), "threshold": np.concatenate(thr),
            "value": np.concatenate(value), "roots": np.array(roots, dtype=np.int64)}


def _forest_predict(t: dict[str, np.ndarray], x: np.ndarray) -> np.ndarray:
    """Mean leaf class distribution over trees (scikit-learn's predict_proba)."""
    x = np.asarray(x, dtype=np.float32).astype(np.float64)  # sklearn splits on float32 X
    rows = np.arange(len(x))[:, None]
    node = np.broadcast_to(t["roots"][None, :], (len(x), len(t["roots"]))).copy()
    while True:
        inner = t["left"][node] >= 0
        if not inner.any():
            break
        f = np.where(inner, t["feature"][node], 0)
        go_left = x[rows, f] <= t["threshold"][node]
        node = np.where(inner, np.where(go_left, t["left"][node], t["right"][node]), node)
    return t["value"][node].mean(axis=1)
