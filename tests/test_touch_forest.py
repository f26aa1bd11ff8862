"""The model that held on new real people (issue 45): the touch and shear features, extra-
trees beside rf and knn, the forests fitting on all their training people's trials, and
``train`` without ``--model`` training it adapted per person and surface.
Budget: ~10 s (tiny forests on three virtual people)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from learn_fixtures import make_dataset_folder

from tactile_studio.cli import main as cli_main
from tactile_studio.learn.data.augment import mirror, rotate90
from tactile_studio.learn.data.features import trial_features
from tactile_studio.learn.data.touch_features import NAMES, touch_features
from tactile_studio.learn.experiments.experiment import ExperimentConfig, run_experiment

CHANNELS = ["normal", "shear_x", "shear_y"]
GESTURES4 = ("Poke", "Circular Stroke", "Back & Forth Rub", "Heavy Pat")
RATE = 43.0


def _touch(n: int = 86, seed: int = 0) -> np.ndarray:
    """A press moving off centre with a turning shear field and noise: no symmetry."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / RATE
    x = rng.normal(0, 0.05, (3, n, 6, 6))
    x[0, :, 1:4, 2:5] += 4 + 2 * np.sin(2 * np.pi * 1.5 * t)[:, None, None]
    x[0, :, 3, 4] += 3 * (t > 0.8)
    x[1, :, 1:4, 2:5] += np.cos(2 * np.pi * t)[:, None, None]
    x[2, :, 1:4, 2:5] += 0.5 * np.sin(2 * np.pi * t)[:, None, None] + 0.3
    return x.astype(np.float32)


def test_touch_features_append_122_named_values_to_the_115():
    x = _touch()
    basic, basic_names = trial_features(x, CHANNELS, RATE)
    full, names = trial_features(x, CHANNELS, RATE, touch=True)
    assert len(basic) == len(basic_names) == 115 and len(NAMES) == 122
    assert names == basic_names + list(NAMES) and len(set(names)) == 237
    np.testing.assert_array_equal(full[:115], basic)  # a 115-feature model reads the first
    assert full.shape == (237,) and np.isfinite(full).all()
    # without shear channels the shear values are those of zero shear
    normal_only = touch_features(x[:1], ["normal"], RATE)
    assert normal_only[NAMES.index("smag_mean")] == 0 and normal_only.shape == (122,)


@pytest.mark.parametrize("turn", range(4))
@pytest.mark.parametrize("flip", [False, True])
def test_touch_features_do_not_depend_on_how_the_grid_is_turned(turn, flip):
    x = _touch(seed=turn)
    y = rotate90(mirror(x, CHANNELS, "x") if flip else x, CHANNELS, turn)
    assert not np.allclose(x, y) or (turn, flip) == (0, False)
    np.testing.assert_allclose(touch_features(y, CHANNELS, RATE),
                               touch_features(x, CHANNELS, RATE), rtol=1e-6, atol=1e-9)


def test_a_gesture_of_shear_alone_is_told_apart():
    """The same steady press, its shear either turning round (a circular stroke) or
    going back and forth along one axis (a rub) with the same magnitude: the shear
    direction's rotation and axis ratio tell them apart by far (same normal features)."""
    n = 86
    t = np.arange(n) / RATE
    press = np.zeros((3, n, 6, 6))
    press[0, :, 2:4, 2:4] = 5.0
    circle, rub = press.copy(), press.copy()
    circle[1, :, 2:4, 2:4] = np.cos(2 * np.pi * 2 * t)[:, None, None]
    circle[2, :, 2:4, 2:4] = np.sin(2 * np.pi * 2 * t)[:, None, None]
    rub[1, :, 2:4, 2:4] = np.cos(2 * np.pi * 2 * t)[:, None, None]
    a, b = touch_features(circle, CHANNELS, RATE), touch_features(rub, CHANNELS, RATE)
    f = dict(zip(NAMES, a)), dict(zip(NAMES, b))
    assert f[0]["s_rot_consist"] > 0.9 and f[1]["s_rot_consist"] < 0.1
    assert f[0]["s_axis_ratio"] > 0.9 and f[1]["s_axis_ratio"] < 0.1
    normal = [i for i, name in enumerate(NAMES) if name.startswith(("load_", "area_", "peak_"))]
    np.testing.assert_array_equal(a[normal], b[normal])


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("touchforest")
    make_dataset_folder(root / "data", participants=3, blocks=1, conditions=("FLAT", "PILLOW"))
    return root


@pytest.mark.parametrize("model", ["rf", "knn"])
def test_forests_fit_on_all_their_training_people_trials(data, model):
    """No validation share is kept from a forest (nothing stops it early): before issue
    45 rf and knn trained on 85% of the other people's trials. A fold's forest is the
    one fitted on its training and validation trials together, and live
    personalisation refits it on the same trials."""
    from tactile_studio.learn.data.dataset import build_dataset
    from tactile_studio.learn.deploy.personalise import fold_training_samples
    from tactile_studio.learn.deploy.window_model import WindowModel
    from tactile_studio.learn.experiments.experiment import prepare_inputs
    from tactile_studio.learn.learners.baselines import BaselineModel
    from tactile_studio.learn.learners.families import DataInfo, make_learner

    config = ExperimentConfig(data=[str(data / "data")], model=model, evaluation="lopo",
                              preset="tiny", cache_dir=str(data / "cache"),
                              overrides={} if model == "knn" else {"n_estimators": 20})
    out = data / f"all-{model}"
    result = run_experiment(config, out)
    learner = make_learner(model, "tiny", config.overrides)
    ds = build_dataset(config.data, cache_dir=config.cache_dir)
    ds, x, owner, *_ = prepare_inputs(learner, ds, config)
    info, uid = DataInfo.of(ds), np.array(ds.uids)
    for rec in result.folds:
        assert rec["val"], "the fold still names its validation share"
        test = np.isin(owner, np.flatnonzero(np.isin(uid, rec["test"])))
        parts = [np.isin(owner, np.flatnonzero(np.isin(uid, rec[k]))) for k in ("train", "val")]
        rows = np.concatenate([np.flatnonzero(m) for m in parts])  # train, then val
        fitted = BaselineModel(model, learner.options, info.n_classes).fit(
            x[rows], ds.labels[owner[rows]], rec["seed"])
        np.testing.assert_allclose(fitted.predict_proba(x[test]),
                                   np.array(rec["predictions"]["probs"]), atol=1e-4)
        live = WindowModel(out, rec["test_participants"][0])
        assert len(fold_training_samples(live, ds)[1]) == int(parts[0].sum() + parts[1].sum())
    assert result.metrics["accuracy"] > 1.5 / 9


def test_train_without_model_trains_the_default_adapted_per_person_and_surface(data, capsys):
    out = data / "default"
    assert cli_main(["train", "--data", str(data / "data"), "--preset", "tiny",
                     "--set", "n_estimators=20", "--cache-dir", str(data / "cache"),
                     "--out", str(out)]) == 0
    cfg = json.loads((out / "config.json").read_text())
    assert cfg["config"]["model"] == "et" and cfg["config"]["adapt"] == "person-condition"
    assert cfg["resolved"]["model"]["model_options"]["features"] == "touch"
    assert cfg["resolved"]["model"]["model_options"]["min_samples_leaf"] == 3
    assert "et · lopo" in capsys.readouterr().out


def test_a_run_from_before_the_touch_features_still_predicts(data):
    """A forest run folder whose recorded options lack ``features`` was trained on the
    115 basic features: live use and evaluate read it with those, not the 237."""
    from tactile_studio.learn.deploy.window_model import WindowModel
    from tactile_studio.learn.results.rescore import rescore_run
    from tactile_studio.playback import SessionPlayback

    out = data / "before"
    result = run_experiment(ExperimentConfig(
        data=[str(data / "data")], model="rf", evaluation="lopo", preset="tiny",
        overrides={"n_estimators": 20, "features": "basic"}, cache_dir=str(data / "cache")),
        out)
    cfg = json.loads((out / "config.json").read_text())
    del cfg["config"]["overrides"]["features"]
    del cfg["resolved"]["model"]["model_options"]["features"]
    (out / "config.json").write_text(json.dumps(cfg))
    assert rescore_run(out)["accuracy"] == pytest.approx(result.metrics["accuracy"])
    model = WindowModel(out)
    pb = SessionPlayback(sorted((data / "data").glob("*.h5"))[0])
    try:
        frames = model.decode(pb.layout, pb.raw, pb.session.baseline(0))
        windows = [frames[:, t.start:t.end] for t in pb.trials]
        probs = model.predict_windows(pb.layout, windows, (pb.n_frames - 1) / pb.duration)
    finally:
        pb.close()
    assert probs.shape == (len(windows), 9) and np.allclose(probs.sum(axis=1), 1)


def test_live_personalisation_joins_the_shots_as_train_shots_does(tmp_path):
    """The default model's two few-shot paths are one route: "Calibrate to person…"
    (personalise) refits the K = 0 fold's forest on its training people's windows (each
    person's standardised by their own statistics) joined by the person's labelled
    windows standardised by the person's; ``train --shots 1`` trains the K = 1 fold on
    the same rows. Given the same shots and the person's session as calibration, both
    predict the person's other performances alike."""
    from tactile_studio.learn.data.dataset import build_dataset
    from tactile_studio.learn.deploy.personalise import LabelledTouches, personalise
    from tactile_studio.learn.deploy.window_model import WindowModel
    from tactile_studio.playback import SessionPlayback

    make_dataset_folder(tmp_path / "data", participants=3, blocks=2, gestures=GESTURES4)
    config = ExperimentConfig(data=[str(tmp_path / "data")], model="et", adapt="auto",
                              evaluation="lopo", preset="tiny", shots=(0, 1),
                              overrides={"n_estimators": 20}, cache_dir=str(tmp_path / "c"))
    result = run_experiment(config, tmp_path / "run")
    k1 = next(r for r in result.folds if r["name"] == "P01 k1")
    ds = build_dataset(config.data, cache_dir=config.cache_dir)
    index = {u: i for i, u in enumerate(ds.uids)}
    shots = [index[u] for u in k1["train"] if ds.participants[index[u]] == "P01"]
    session = np.flatnonzero(ds.participants == "P01")
    assert len(shots) == 4 and np.allclose(ds.rates[session], ds.rates[session[0]])
    model = WindowModel(tmp_path / "run", "P01")
    assert model.record["name"] == "P01 k0" and model.config.adapt == "person-condition"
    pb = SessionPlayback(tmp_path / "data" / "P01.h5")
    layout = pb.layout
    pb.close()
    rate = float(ds.rates[session[0]])
    touches = LabelledTouches(layout, [ds.trials[i] for i in shots],
                              [ds.label_names[ds.labels[i]] for i in shots], rate)
    personal = personalise(model, touches, seed=k1["seed"], dataset=ds,
                           calibration=[ds.trials[i] for i in session])
    assert personal.how == "refit" and personal.reference is not None
    model.personalise(personal)
    test = k1["predictions"]["owner"]  # the K = 1 fold's test trials, one window each
    assert sorted(test) == sorted(index[u] for u in k1["test"])
    live = model.predict_windows(layout, [ds.trials[i] for i in test], rate)
    np.testing.assert_allclose(live, np.array(k1["predictions"]["probs"]), atol=1e-4)
