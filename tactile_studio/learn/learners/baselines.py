"""Random forest, extra-trees and k-nearest-neighbour models on handcrafted trial features.

Extra-trees (``et``, issue 45) is the forest that held best on new real people: on the
development set's five people (four train, the fifth is tested) it was level with rf on
the same features (+1.0 points, McNemar p 0.79) with smoother probabilities, and capped
at 300 trees and 3 samples a leaf it kept its accuracy at a third of the file (33 MB of
ONNX instead of 94). rf and et read the touch and shear features too
(``features="touch"``, learn/data/touch_features.py) unless told ``features=basic`` (the
115 of runs before issue 45, which a run folder without the option is read with); k-NN
reads the 115 unless told ``features=touch``.

Trained with scikit-learn and saved as ONNX with skl2onnx (no pickle), so every model of
a run folder, deep or not, is a file that onnxruntime loads safely and runs fast; the
tests check that the ONNX graph predicts the labels scikit-learn predicts and the same
probabilities (within 1e-5), and benchmarks/bench_baselines.py times both.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.learn.choices import BASELINES
from tactile_studio.learn.presets import PRESETS

# what ``train`` without --model and the train panel train: extra-trees on the touch
# features, adapted per person and surface (its ``--adapt auto``), chosen on the
# development set's five real people (issue 45; docs/learning/defaults.md)
DEFAULT_MODEL = "et"
FOREST_FEATURES = ("basic", "touch")  # learn/data/features.py without / with touch_features
MODEL_FILE = "model.onnx"
DESCRIPTIONS = {
    "rf": "random forest on handcrafted statistical/spectral features + gesture metrics",
    "et": "extra-trees on handcrafted features + touch and shear features",
    "knn": "k-nearest neighbours on standardised handcrafted features",
}
_OPTIONS: dict[str, dict[str, dict[str, Any]]] = {
    "rf": {"full": {"n_estimators": 300, "max_depth": 0, "min_samples_leaf": 1,
                    "max_features": "sqrt", "features": "touch"},
           "tiny": {"n_estimators": 100, "max_depth": 0, "min_samples_leaf": 1,
                    "max_features": "sqrt", "features": "touch"}},
    "et": {"full": {"n_estimators": 300, "max_depth": 0, "min_samples_leaf": 3,
                    "max_features": "sqrt", "features": "touch"},
           "tiny": {"n_estimators": 60, "max_depth": 0, "min_samples_leaf": 3,
                    "max_features": "sqrt", "features": "touch"}},
    # k-NN keeps the 115 (the touch features were measured for the forests only)
    "knn": {"full": {"n_neighbors": 5, "weights": "distance", "p": 2, "features": "basic"},
            "tiny": {"n_neighbors": 5, "weights": "distance", "p": 2, "features": "basic"}},
}
_CHOICES = {"weights": ("uniform", "distance"), "max_features": ("sqrt", "log2", "all"),
            "features": FOREST_FEATURES}
_FEATURES_HELP = "basic: the 115 handcrafted features; touch: + 122 touch and shear features"
# one line of help per option (the research workspace shows it beside the value)
OPTION_HELP: dict[str, dict[str, str]] = {
    "rf": {"n_estimators": "trees in the forest", "max_depth": "tree depth limit (0 = none)",
           "min_samples_leaf": "fewest samples in a leaf",
           "max_features": "features tried per split", "features": _FEATURES_HELP},
    "et": {"n_estimators": "trees in the forest", "max_depth": "tree depth limit (0 = none)",
           "min_samples_leaf": "fewest samples in a leaf",
           "max_features": "features tried per split", "features": _FEATURES_HELP},
    "knn": {"n_neighbors": "neighbours that vote", "weights": "uniform or distance-weighted votes",
            "p": "Minkowski distance power (2 = Euclidean)", "features": _FEATURES_HELP},
}


def legacy_options(name: str, described: dict[str, Any] | None,
                   overrides: dict[str, Any]) -> dict[str, Any]:
    """A run's model overrides as its models were trained: a forest family run whose
    recorded options (config.json's resolved model description) lack ``features`` was
    trained before the touch features existed, on the 115 basic ones."""
    if name in BASELINES and isinstance(described, dict) \
            and "features" not in (described.get("model_options") or {"features": 0}):
        return {**overrides, "features": "basic"}
    return overrides


def baseline_options(name: str, preset: str, overrides: dict[str, Any]) -> dict[str, Any]:
    """Preset options with ``overrides`` applied (unknown key or bad value -> UserError)."""
    if preset not in PRESETS:
        raise UserError(f"unknown preset '{preset}' (available: {', '.join(PRESETS)})")
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
    """A fitted (or loaded) rf / et / knn: one ONNX file, predicted by onnxruntime.

    ``fit`` trains with scikit-learn and converts the fitted estimator with skl2onnx at
    once, so the predictions recorded at training time, ``evaluate``, ``export-model`` and
    the streaming predictor all come from the same ONNX graph. The graph's input is the
    trial feature vector of :func:`tactile_studio.learn.data.features.trial_features` (the
    feature extraction stays in Python; ``channel_names``, ``cell_pitch`` and the feature
    count are in the file's metadata); k-NN's standardisation is part of the graph.
    """

    kind = "features"
    file_name = MODEL_FILE

    def __init__(self, name: str, options: dict[str, Any], n_classes: int) -> None:
        self.name, self.options, self.n_classes = name, options, n_classes
        self.estimator: Any = None  # the scikit-learn estimator, after fit only
        self.onnx: bytes = b""
        self.metadata: dict[str, str] = {}
        self._session: Any = None
        self._classes = np.arange(n_classes)

    # ---- training --------------------------------------------------------------------
    def fit(self, x: np.ndarray, y: np.ndarray, seed: int,
            metadata: dict[str, str] | None = None) -> BaselineModel:
        """Fit with scikit-learn, then convert to ONNX (``metadata`` goes into the file)."""
        self.estimator = _estimator(self.name, self.options, len(y), seed).fit(x, y)
        self.metadata = {"model": self.name, "options": json.dumps(self.options),
                         "n_classes": str(self.n_classes), "n_features": str(x.shape[1]),
                         "classes": json.dumps(self.estimator.classes_.tolist()),
                         "input": "trial features (tactile_studio.learn.data.features)",
                         **(metadata or {})}
        self.onnx = _to_onnx(self.estimator, x, self.name, self.metadata)
        self._open(self.onnx)
        return self

    def sklearn_predict_proba(self, x: np.ndarray) -> np.ndarray:
        """scikit-learn's own probabilities (n_classes columns); only right after ``fit``."""
        if self.estimator is None:
            raise ValueError("the scikit-learn estimator exists only after fit")
        return self._expand(self.estimator.predict_proba(x))

    # ---- prediction ------------------------------------------------------------------
    def _open(self, model: bytes | str) -> None:
        from tactile_studio.learn.learners.onnx_io import cpu_session

        self._session = cpu_session(model, threads=1)
        meta = dict(self._session.get_modelmeta().custom_metadata_map)
        self.metadata = meta
        self._classes = np.asarray(json.loads(meta.get("classes", "[]")), dtype=np.int64)
        inp = self._session.get_inputs()[0]
        self._input = inp.name
        self._dtype = np.float64 if "double" in inp.type else np.float32

    def _expand(self, probs: np.ndarray) -> np.ndarray:
        """Columns of the classes seen in training -> all ``n_classes`` columns."""
        out = np.zeros((len(probs), self.n_classes))
        out[:, self._classes] = probs
        return out

    def predict_labels_and_proba(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(labels, probabilities (N, n_classes)) from the ONNX graph."""
        if len(x) == 0:
            return np.zeros(0, dtype=np.int64), np.zeros((0, self.n_classes))
        x, want = np.asarray(x), self._session.get_inputs()[0].shape[1]
        if x.ndim != 2 or x.shape[1] != want:
            raise UserError(f"{self.name} model: {x.shape[-1]} features given, its file "
                            f"reads {want} (a model of another run?)")
        labels, probs = self._session.run(None, {self._input: np.asarray(x, self._dtype)})
        return np.asarray(labels, dtype=np.int64), self._expand(np.asarray(probs, np.float64))

    def predict_proba(self, x: np.ndarray) -> np.ndarray:
        return self.predict_labels_and_proba(x)[1]

    def predict_trial(self, trial: np.ndarray, rate: float) -> np.ndarray:
        """Probabilities (n_classes,) of one trial (C, T, R, X) of decoded frames."""
        from tactile_studio.learn.data.features import trial_features

        names = json.loads(self.metadata.get("channel_names", "[]"))
        pitch = float(self.metadata.get("cell_pitch", 1.0))
        # the file says which features it reads (its options; none: the 115 of old files)
        touch = json.loads(self.metadata.get("options") or "{}").get("features") == "touch"
        vec, _ = trial_features(trial, names, rate, pitch, touch)
        return self.predict_proba(vec[None])[0]

    # ---- persistence: the ONNX file itself -------------------------------------------
    def save(self, path) -> None:
        Path(path).write_bytes(self.onnx)

    @classmethod
    def load(cls, path, name: str, options: dict[str, Any], n_classes: int,
             channel_names: list[str] | None = None) -> BaselineModel:
        """The model in ``path``, checked to be this run's kind of model (``name``, its
        classes, its channels when given) before anything runs it."""
        path = Path(path)
        if not path.is_file():
            raise UserError(f"{path}: no such model file")
        model = cls(name, options, n_classes)
        try:
            model._open(str(path))
        except Exception as exc:  # onnxruntime raises its own untyped errors on bad files
            first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
            raise UserError(f"{path}: damaged or unreadable model file ({first[:120]})") from None
        why = model._foreign(channel_names)
        if why:
            raise UserError(f"{path}: not this run's model ({why}); train the run again "
                            "into a new --out")
        model.onnx = path.read_bytes()
        return model

    def _foreign(self, channel_names: list[str] | None) -> str:
        """Why the opened graph is not a ``self.name`` model of this run ("" if it is):
        its metadata, its input (N, features) and its two outputs (labels, probabilities)."""
        meta, session = self.metadata, self._session
        if meta.get("model") != self.name:
            return f"it is a {meta.get('model') or 'foreign'} model, the run's is {self.name}"
        if meta.get("n_classes") != str(self.n_classes) or len(self._classes) == 0 \
                or self._classes.min() < 0 or self._classes.max() >= self.n_classes:
            return f"it has {meta.get('n_classes')} classes, the run has {self.n_classes}"
        if channel_names is not None and meta.get("channel_names") is not None \
                and json.loads(meta["channel_names"]) != list(channel_names):
            return "it reads other channels than the run's"
        inputs, outputs = session.get_inputs(), session.get_outputs()
        shape = inputs[0].shape if len(inputs) == 1 else []
        if len(shape) != 2 or str(shape[1]) != meta.get("n_features"):
            return f"its input is {[i.shape for i in inputs]}, not (N, {meta.get('n_features')})"
        if len(outputs) != 2:
            return f"it has {len(outputs)} outputs, not labels and probabilities"
        return ""


def _estimator(name: str, o: dict[str, Any], n_train: int, seed: int) -> Any:
    if name in ("rf", "et"):
        from sklearn.ensemble import ExtraTreesClassifier, RandomForestClassifier

        forest = RandomForestClassifier if name == "rf" else ExtraTreesClassifier
        return forest(
            n_estimators=o["n_estimators"], max_depth=o["max_depth"] or None,
            min_samples_leaf=o["min_samples_leaf"],
            max_features=None if o["max_features"] == "all" else o["max_features"],
            random_state=seed, n_jobs=1)
    from sklearn.neighbors import KNeighborsClassifier
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    knn = KNeighborsClassifier(n_neighbors=min(o["n_neighbors"], n_train),
                               weights=o["weights"], p=o["p"])
    return make_pipeline(StandardScaler(), knn)


def _to_onnx(estimator: Any, x: np.ndarray, name: str, metadata: dict[str, str]) -> bytes:
    """skl2onnx conversion. The forest takes float32 (scikit-learn itself splits on
    float32 features); k-NN takes float64 so its distances match scikit-learn's."""
    from skl2onnx import to_onnx

    from tactile_studio.learn.learners.onnx_io import OPSET

    dtype = np.float64 if name == "knn" else np.float32
    # a forest's options keyed by the estimator itself: named ones ("zipmap") make skl2onnx
    # walk every attribute of the forest and of each tree twice more, computing every
    # feature_importances_ on the way (a tiny rf run: 2.8 s -> 1.5-2.0 s); the same bytes.
    # (k-NN keeps the name: its pipeline comes out with other node names by id)
    by_id = {id(estimator): {"zipmap": False}}
    proto = to_onnx(estimator, np.asarray(x[:1], dtype=dtype),
                    options={"zipmap": False} if name == "knn" else by_id,
                    target_opset={"": OPSET, "ai.onnx.ml": 3})
    if name == "knn":
        _fix_knn_distances(proto)
    del proto.metadata_props[:]
    for key, value in metadata.items():
        entry = proto.metadata_props.add()
        entry.key, entry.value = key, str(value)
    return proto.SerializeToString()


def _fix_knn_distances(proto: Any) -> None:
    """Work around skl2onnx 1.20's k-NN converter negating the neighbour distances it
    takes from ``TopK(largest=0)``: ``max(-d, 1e-6)`` then turns ``weights="distance"``
    into uniform votes (probabilities off by up to 0.12 in our test). The negation
    becomes an ``Abs``, which is also right once the converter is fixed."""
    topk = {n.output[0] for n in proto.graph.node if n.op_type == "TopK"}
    for node in proto.graph.node:
        if node.op_type == "Mul" and node.input[0] in topk:
            unused = node.input[1]
            node.op_type = "Abs"
            del node.input[1:]
            if not any(unused in n.input for n in proto.graph.node):
                keep = [i for i in proto.graph.initializer if i.name != unused]
                del proto.graph.initializer[:]
                proto.graph.initializer.extend(keep)
