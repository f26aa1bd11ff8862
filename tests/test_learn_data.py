"""Learning data: datasets from sessions, cache, views, splits, metrics, features.

No training here; budget about 10 s.
"""

from __future__ import annotations

import numpy as np
import pytest
from learn_fixtures import (
    make_dataset_folder,
    trial_record,
    write_participant,
    write_pressure_session,
)

from tactile_studio.errors import UserError
from tactile_studio.learn.data import cache, views
from tactile_studio.learn.data.dataset import build_dataset, read_sessions
from tactile_studio.learn.data.features import feature_matrix, gesture_metrics, trial_features
from tactile_studio.learn.data.splits import all_inclusive, group_kfold, lopo
from tactile_studio.learn.data.windowing import vote
from tactile_studio.learn.evaluation.metrics import classification_metrics
from tactile_studio.simulate import GESTURES


@pytest.fixture(scope="module")
def sim_folder(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sim")
    make_dataset_folder(folder, participants=3, blocks=2)
    return folder


@pytest.fixture(scope="module")
def sim_ds(sim_folder, tmp_path_factory):
    return build_dataset([sim_folder], cache_dir=tmp_path_factory.mktemp("cache"))


# ---- datasets --------------------------------------------------------------------------

def test_dataset_groups_labels_and_decodes(sim_ds):
    ds = sim_ds
    assert len(ds) == 3 * 2 * 9
    assert ds.participant_names == ["P01", "P02", "P03"]
    assert ds.label_names == list(GESTURES)  # the protocol's order, from session metadata
    assert np.bincount(ds.labels).tolist() == [6] * 9
    assert ds.channels == "both" and ds.channel_names == ["normal", "shear_x", "shear_y"]
    assert all(t.shape == (3, 86, 6, 6) and t.dtype == np.float32 for t in ds.trials)
    pressed = [t[0].max() for t, lab in zip(ds.trials, ds.labels)
               if ds.label_names[lab] == "Heavy Pat"]
    assert min(pressed) > 5.0  # kPa: decoded stress, not raw counts
    assert np.allclose(ds.rates, 43.0, rtol=1e-3)
    assert len(set(ds.uids)) == len(ds)


def test_channel_sets_and_virtual_grid(sim_ds, sim_folder, tmp_path):
    normal, shear = sim_ds.select("normal"), sim_ds.select("shear")
    assert normal.trials[0].shape[0] == 1 and shear.trials[0].shape[0] == 2
    np.testing.assert_array_equal(shear.trials[5][0], sim_ds.trials[5][1])
    virtual = build_dataset([sim_folder], grid="virtual", cache_dir=tmp_path)
    assert virtual.trials[0].shape == (3, 86, 11, 11)
    with pytest.raises(UserError, match="unknown channel set"):
        sim_ds.select("pressure")


@pytest.mark.damaged_files  # the extra trials overlap the others' rows
def test_ok_trials_only_and_labels_in_protocol_order(tmp_path):
    extra = [trial_record(100, "Poke", 50, 80, status="discarded"),
             trial_record(101, "Tickle", 90, 120, status="redone")]
    write_participant(tmp_path / "a.h5", "P07", 5, gestures=("Tickle", "Poke"), blocks=1,
                      extra_trials=extra)
    ds = read_sessions([tmp_path])
    assert ds.label_names == ["Tickle", "Poke"]
    assert len(ds) == 2 and set(ds.participants) == {"P07"}


def test_pressure_only_layout_any_length(tmp_path):
    write_pressure_session(tmp_path / "c1.h5", "S1", [10, 1700, 40, 12])
    ds = build_dataset([tmp_path], cache_dir=tmp_path / "cache")
    assert ds.channel_names == ["pressure"] and ds.grid_shape == (8, 8)
    assert sorted(ds.lengths().tolist()) == [10, 12, 40, 1700]
    assert ds.label_names == ["pat", "stroke"]
    for bad in ("shear", "both"):
        with pytest.raises(UserError, match="pressure only") as err:
            build_dataset([tmp_path], channels=bad, cache_dir=tmp_path / "cache")
        assert "\n" not in str(err.value)
    x, names = feature_matrix(ds.trials, ds.channel_names, ds.rates)
    assert x.shape == (4, len(names)) and np.isfinite(x).all()


def test_dataset_errors_are_one_line(tmp_path):
    (tmp_path / "mix").mkdir()
    write_participant(tmp_path / "mix" / "a.h5", "P01", 1, gestures=("Poke",), blocks=1)
    write_pressure_session(tmp_path / "mix" / "b.h5", "S1", [20])
    with pytest.raises(UserError, match="mismatched layouts") as err:
        read_sessions([tmp_path / "mix"])
    assert "\n" not in str(err.value)
    (tmp_path / "none").mkdir()
    write_participant(tmp_path / "none" / "a.h5", "P01", 1, gestures=("Poke",), blocks=0,
                      extra_trials=[trial_record(0, "Poke", 0, 20, status="discarded")])
    with pytest.raises(UserError, match="no trials with status ok"):
        read_sessions([tmp_path / "none"])
    with pytest.raises(UserError, match="no such file or folder"):
        read_sessions([tmp_path / "missing"])
    (tmp_path / "empty").mkdir()
    with pytest.raises(UserError, match="no session files"):
        read_sessions([tmp_path / "empty"])


def test_cache_hit_and_invalidation(tmp_path):
    folder = tmp_path / "data"
    files = make_dataset_folder(folder, participants=1, blocks=1, gestures=("Poke", "Twist"))
    messages = []
    first = build_dataset([folder], cache_dir=tmp_path / "c",
                          progress=lambda f, m: messages.append(m))
    assert "dataset from cache" not in messages
    assert len(list((tmp_path / "c" / "datasets").glob("*.npz"))) == 1
    messages.clear()
    second = build_dataset([folder], cache_dir=tmp_path / "c",
                           progress=lambda f, m: messages.append(m))
    assert messages == ["dataset from cache"]
    assert second.uids == first.uids and second.label_names == first.label_names
    for a, b in zip(first.trials, second.trials):
        np.testing.assert_array_equal(a, b)
    key = cache.dataset_key(files, "physical")
    assert cache.dataset_key(files, "virtual") != key
    write_participant(files[0], "P01", 102, gestures=("Poke", "Twist"), blocks=1)  # rewritten
    assert cache.dataset_key(files, "physical") != key


def code_package(tmp_path, monkeypatch, name: str = "stand_in_reader"):
    """A package of real source files on the path, standing in for code a cache keys on
    (an importer or a decoder), and a function that edits it as a new release would."""
    pkg = tmp_path / "code" / name
    pkg.mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "read.py").write_text("SCALE = 1.0\n")
    monkeypatch.syspath_prepend(str(pkg.parent))
    releases = iter(range(2, 100))
    return name, lambda: (pkg / "read.py").write_text(f"SCALE = {next(releases)}.0\n")


def test_code_version_follows_the_code_and_a_new_reader_misses_the_cache(tmp_path,
                                                                         monkeypatch):
    """Issue 45: a dataset decoded by older code is never read back as today's."""
    name, edit = code_package(tmp_path, monkeypatch)
    version = cache.code_version([name])
    assert cache.code_version([name]) == version  # the same code, the same version
    assert cache.code_version([f"{name}.read"]) != version
    edit()
    assert cache.code_version([name]) != version
    # the dataset cache's key holds the reading code's version: with the stand-in as part
    # of it, an edit makes the next build decode again instead of reading the old entry
    assert "tactile_studio.storage.format" in cache.DATASET_CODE
    monkeypatch.setattr(cache, "DATASET_CODE", (*cache.DATASET_CODE, name))
    folder = tmp_path / "data"
    make_dataset_folder(folder, participants=1, blocks=1, gestures=("Poke", "Twist"))
    messages = []
    build_dataset([folder], cache_dir=tmp_path / "c")
    build_dataset([folder], cache_dir=tmp_path / "c", progress=lambda f, m: messages.append(m))
    assert messages == ["dataset from cache"]
    edit()
    messages.clear()
    build_dataset([folder], cache_dir=tmp_path / "c", progress=lambda f, m: messages.append(m))
    assert "dataset from cache" not in messages
    assert len(list((tmp_path / "c" / "datasets").glob("*.npz"))) == 2


# ---- views -----------------------------------------------------------------------------

@pytest.mark.parametrize("n", [1, 5, 10, 27, 86, 1700])
def test_views_handle_any_length(n):
    rng = np.random.default_rng(n)
    x = rng.normal(size=(3, n, 6, 6)).astype(np.float32)
    assert views.resample(x, 86).shape == (3, 86, 6, 6)
    assert views.moving_average_slices(x, 100).shape == (3, 100, 6, 6)
    assert views.gradient_sample(x, 32).shape == (3, 32, 6, 6)
    w = views.sliding_windows(x, 27, 9)
    assert w.shape[1:] == (3, 27, 6, 6)
    if n <= 27:
        assert len(w) == 1
        np.testing.assert_array_equal(w[0, :, :n], x)
        assert not w[0, :, n:].any()  # padded with zero load
    else:
        starts = views.window_starts(n, 27, 9)
        assert starts[0] == 0 and starts[-1] == n - 27  # the tail is covered
        np.testing.assert_array_equal(w[-1], x[:, -27:])
    for kind in views.VIEW_KINDS:
        out = views.trial_view(x, kind, 16, 4)
        assert out.ndim == 5 and np.isfinite(out).all()


def test_resample_and_slices_values():
    ramp = np.arange(11, dtype=np.float32)[None, :, None, None] * np.ones((1, 11, 2, 2), np.float32)
    np.testing.assert_allclose(views.resample(ramp, 21)[0, :, 0, 0], np.linspace(0, 10, 21),
                               atol=1e-6)
    sl = views.moving_average_slices(ramp, 4)[0, :, 0, 0]
    assert np.all(np.diff(sl) > 0) and sl[0] < 3 and sl[-1] > 7  # overlapping span means
    const = np.full((2, 50, 3, 3), 7.0, np.float32)
    np.testing.assert_allclose(views.moving_average_slices(const, 10), 7.0)


def test_gradient_sampling_follows_change():
    x = np.zeros((1, 200, 2, 2), np.float32)
    x[0, 100:120] = np.sin(np.arange(20))[:, None, None]  # all change in frames 100..120
    idx = views.gradient_indices(x, 10)
    assert np.all((idx >= 99) & (idx <= 120))
    still = np.ones((1, 50, 2, 2), np.float32)
    np.testing.assert_array_equal(views.gradient_indices(still, 5), [0, 12, 24, 37, 49])


def test_make_samples_owner_and_normalisation():
    trials = [np.ones((2, n, 3, 3), np.float32) * k for k, n in enumerate([30, 60, 5])]
    x, owner = views.make_samples(trials, "windows", 10, 10)
    assert owner.tolist() == [0, 0, 0, 1, 1, 1, 1, 1, 1, 2]
    mean, std = views.channel_stats(x)
    z = views.normalise(x, mean, std)
    np.testing.assert_allclose(z.mean(axis=(0, 2, 3, 4)), 0, atol=1e-5)


# ---- splits ----------------------------------------------------------------------------

def _toy(n_participants=5, per=18, classes=9):
    parts = np.repeat([f"P{i}" for i in range(n_participants)], per)
    labels = np.tile(np.arange(classes), n_participants * per // classes)
    return labels, parts


def test_lopo_groups_by_participant():
    labels, parts = _toy()
    folds = lopo(labels, parts, seed=3)
    assert [f.test_participants for f in folds] == [[f"P{i}"] for i in range(5)]
    for f in folds:
        assert set(parts[f.test]) == set(f.test_participants)
        assert not set(parts[f.train]) & set(f.test_participants)
        assert not set(parts[f.val]) & set(f.test_participants)
        assert not set(f.train) & set(f.val)
        assert len(f.train) + len(f.val) + len(f.test) == len(labels)
        assert set(labels[f.val]) == set(range(9))  # stratified validation
    assert sorted(np.concatenate([f.test for f in folds]).tolist()) == list(range(len(labels)))
    with pytest.raises(UserError, match="at least 2 participants"):
        lopo(labels[:18], parts[:18], seed=0)


def test_all_inclusive_stratified_70_20_10():
    labels, parts = _toy(4, 27)
    (f,) = all_inclusive(labels, seed=1)
    assert sorted(np.concatenate([f.train, f.val, f.test]).tolist()) == list(range(len(labels)))
    assert set(labels[f.test]) == set(range(9)) and set(labels[f.val]) == set(range(9))
    assert abs(len(f.train) / len(labels) - 0.7) < 0.05
    assert abs(len(f.val) / len(labels) - 0.2) < 0.05
    (g,) = all_inclusive(labels, seed=2)
    assert not np.array_equal(f.test, g.test)  # new seed, new split


def test_all_inclusive_with_one_trial_per_gesture_is_refused_in_one_line():
    """A session cut short after one trial of each gesture (disk full mid-collection) left
    the test part empty and ``train`` ended in a numpy reshape traceback."""
    with pytest.raises(UserError, match="no test trial: 7 trial"):
        all_inclusive(np.arange(7), seed=0)


def test_group_kfold_holds_out_participants():
    labels, parts = _toy(12, 9)
    folds = group_kfold(labels, parts, seed=0, k=5)
    held = set(parts[folds[0].heldout])
    assert len(held) == 1 and len(folds) == 5
    tested = [p for f in folds for p in f.test_participants]
    assert sorted(tested) == sorted(set(parts) - held)  # every other participant tested once
    for f in folds:
        used = set(parts[f.train]) | set(parts[f.val])
        assert not used & held and not used & set(f.test_participants)
    with pytest.raises(UserError, match="at least 3 participants"):
        group_kfold(labels[:18], parts[:18], seed=0)


# ---- metrics ---------------------------------------------------------------------------

def test_metrics_hand_checked():
    y_true = np.array([0, 0, 0, 1, 1, 2])
    y_pred = np.array([0, 0, 1, 1, 2, 2])
    m = classification_metrics(y_true, y_pred, ["a", "b", "c"])
    assert m["confusion_counts"] == [[2, 1, 0], [0, 1, 1], [0, 0, 1]]
    assert m["accuracy"] == pytest.approx(4 / 6)
    assert m["precision_macro"] == pytest.approx((1 + 0.5 + 0.5) / 3)
    assert m["recall_macro"] == pytest.approx((2 / 3 + 0.5 + 1) / 3)
    assert m["f1_macro"] == pytest.approx((0.8 + 0.5 + 2 / 3) / 3)
    assert m["balanced_accuracy"] == pytest.approx(m["recall_macro"])
    assert m["kappa"] == pytest.approx(0.5)  # po 2/3, pe 12/36
    assert m["confusion_matrix"][0] == pytest.approx([2 / 3, 1 / 3, 0])
    assert m["per_class_accuracy"] == pytest.approx({"a": 2 / 3, "b": 0.5, "c": 1.0})


@pytest.mark.filterwarnings("ignore:y_pred contains classes not in y_true")
def test_metrics_match_sklearn_with_absent_classes():
    from sklearn import metrics as skm

    rng = np.random.default_rng(0)
    y_true = rng.integers(0, 6, 200)
    y_pred = np.where(rng.random(200) < 0.6, y_true, rng.integers(0, 7, 200))
    m = classification_metrics(y_true, y_pred, [str(i) for i in range(8)])
    assert m["accuracy"] == pytest.approx(skm.accuracy_score(y_true, y_pred))
    assert m["precision_macro"] == pytest.approx(
        skm.precision_score(y_true, y_pred, average="macro", zero_division=0))
    assert m["recall_macro"] == pytest.approx(
        skm.recall_score(y_true, y_pred, average="macro", zero_division=0))
    assert m["f1_macro"] == pytest.approx(
        skm.f1_score(y_true, y_pred, average="macro", zero_division=0))
    assert m["balanced_accuracy"] == pytest.approx(skm.balanced_accuracy_score(y_true, y_pred))
    assert m["kappa"] == pytest.approx(skm.cohen_kappa_score(y_true, y_pred))
    assert m["per_class_accuracy"]["7"] is None


def test_majority_vote():
    owner = np.array([4, 4, 4, 9, 9])
    probs = np.array([[0.9, 0.1], [0.2, 0.8], [0.6, 0.4], [0.3, 0.7], [0.55, 0.45]])
    trials, pred = vote(owner, probs)
    assert trials.tolist() == [4, 9] and pred.tolist() == [0, 1]  # 9: tie -> more mass


# ---- features --------------------------------------------------------------------------

def test_movement_type_matches_simulated_gestures(sim_ds):
    agree = [gesture_metrics(x, sim_ds.channel_names, r)["movement"]
             == GESTURES[sim_ds.label_names[lab]].movement
             for x, lab, r in zip(sim_ds.trials, sim_ds.labels, sim_ds.rates)]
    assert np.mean(agree) >= 0.8


def test_gesture_metrics_on_known_patterns():
    n, rate = 86, 43.0
    x = np.zeros((3, n, 6, 6), np.float32)
    x[0, :, 2:4, 2:4] = 8.0 + 2 * np.sin(2 * np.pi * 3.0 * np.arange(n) / rate)[:, None, None]
    x[1, :, 2:4, 2:4] = 1.5  # uniform drag along +x
    m = gesture_metrics(x, ["normal", "shear_x", "shear_y"], rate)
    assert m["movement"] == "static" and m["dominant_hz"] == pytest.approx(3.0, abs=0.5)
    assert m["contact_area"] == pytest.approx(4 / 36) and m["mean_abs_shear"] == pytest.approx(1.5)
    assert m["coherence"] == pytest.approx(1.0)
    moving = np.zeros((1, n, 6, 6), np.float32)
    cols = np.abs((np.arange(n) * 12 // n) - 6).clip(0, 5)  # sliding along a row and back
    moving[0, np.arange(n), 2, cols] = 5.0
    assert gesture_metrics(moving, ["normal"], rate)["movement"] == "transversal"
    vec, names = trial_features(x, ["normal", "shear_x", "shear_y"], rate)
    assert len(vec) == len(names) and np.isfinite(vec).all()


# ---- baselines: saved as ONNX (no pickle), predicting like scikit-learn ---------------

def test_baselines_predict_like_sklearn_and_round_trip_as_onnx(tmp_path):
    from sklearn.ensemble import RandomForestClassifier

    from tactile_studio.learn.learners.baselines import BaselineModel, baseline_options

    rng = np.random.default_rng(0)
    x = rng.normal(size=(120, 7))
    y = (x[:, 0] + x[:, 1] > 0).astype(int) + 2 * (x[:, 2] > 1)  # classes 0..3, 4 unused
    opts = baseline_options("rf", "tiny", {"n_estimators": "25"})
    model = BaselineModel("rf", opts, n_classes=5).fit(x, y, seed=3)
    ref = RandomForestClassifier(n_estimators=25, random_state=3, n_jobs=1,
                                 max_features="sqrt").fit(x, y)
    xt = rng.normal(size=(50, 7))
    probs = model.predict_proba(xt)
    np.testing.assert_allclose(probs[:, :4], ref.predict_proba(xt), atol=1e-5)
    assert not probs[:, 4].any()
    model.save(tmp_path / "rf.onnx")
    back = BaselineModel.load(tmp_path / "rf.onnx", "rf", opts, 5)
    np.testing.assert_array_equal(back.predict_proba(xt), probs)
    knn = BaselineModel("knn", baseline_options("knn", "tiny", {}), 5).fit(x, y, seed=0)
    knn.save(tmp_path / "knn.onnx")
    again = BaselineModel.load(tmp_path / "knn.onnx", "knn", knn.options, 5)
    np.testing.assert_allclose(again.predict_proba(xt), knn.predict_proba(xt))
    assert (knn.predict_proba(x).argmax(1) == y).mean() == 1.0  # distance-weighted: memorised
    with pytest.raises(UserError, match="unknown option 'trees'"):
        baseline_options("rf", "tiny", {"trees": 3})
    with pytest.raises(UserError, match="weights"):
        baseline_options("knn", "tiny", {"weights": "heavy"})
