"""Generalisation tools: augmentation that respects the ShearSense geometry (checked
against the simulated sensor touched at the mirrored / rotated place with the shear
turned accordingly), per-participant normalisation, class balancing, validation on whole
training participants, and the options through the experiment."""

from __future__ import annotations

import numpy as np
import pytest
from learn_fixtures import make_dataset_folder

from tactile_studio.errors import UserError
from tactile_studio.learn.data import augment as A
from tactile_studio.learn.data.dataset import read_sessions
from tactile_studio.learn.data.splits import make_folds
from tactile_studio.learn.data.touch_stats import REAL, trial_stats
from tactile_studio.learn.experiments.experiment import ExperimentConfig, run_experiment
from tactile_studio.learn.learners.generalise import (
    balanced_index,
    participant_normalised,
    participant_val,
)
from tactile_studio.sensor.decode import compute_baseline, decode
from tactile_studio.sensor.layout import SHEARSENSE_6X6
from tactile_studio.simulate import SensorSimulator

NAMES = ["normal", "shear_x", "shear_y"]


def _pressed(x_mm: float, y_mm: float, sx: float, sy: float) -> np.ndarray:
    """The decoded (3, 1, 6, 6) frame of a held press with shear traction (sx, sy), on a
    sensor without the imperfections that break its symmetry (x-y crosstalk, gain spread)."""
    sim = SensorSimulator(gesture="idle", seed=2, noise=0.0, drift=0.0, gain_spread=0.0,
                          creep=0.0, crosstalk=0.0, difficulty="easy")
    base = compute_baseline(sim.step(50))
    sim.press(x_mm, y_mm, 12.0, radius_mm=6.0, shear_x=sx, shear_y=sy, duration_s=2.0)
    d = decode(SHEARSENSE_6X6, sim.step(40)[-1:], base)
    return np.stack([d.normal, d.shear_x, d.shear_y]).astype(np.float32)


def _close(a: np.ndarray, b: np.ndarray) -> None:
    assert np.abs(a[0] - b[0]).max() < 0.02 * np.abs(b[0]).max()   # normal
    assert np.abs(a[1:] - b[1:]).max() < 0.05 * np.abs(b[1:]).max()  # shear


def test_mirrors_and_rotations_match_the_sensor_touched_there():
    here = _pressed(16.0, 32.0, 2.0, 1.0)
    assert here[1].sum() > 0 and here[2].sum() > 0  # +x, +y drag reads positive
    _close(A.mirror(here, NAMES, "x"), _pressed(64.0, 32.0, -2.0, 1.0))
    _close(A.mirror(here, NAMES, "y"), _pressed(16.0, 48.0, 2.0, -1.0))
    _close(A.transpose(here, NAMES), _pressed(32.0, 16.0, 1.0, 2.0))
    # a quarter turn (x towards y) about the centre: (x, y) -> (80 - y, x), (sx, sy) -> (-sy, sx)
    _close(A.rotate90(here, NAMES), _pressed(48.0, 16.0, -1.0, 2.0))
    assert np.array_equal(A.rotate90(here, NAMES, 4), here)
    # without this shear bookkeeping the mirror image is wrong
    plain = np.array(here[..., ::-1])
    assert np.abs(plain[1] - _pressed(64.0, 32.0, -2.0, 1.0)[1]).max() > 0.5


def test_shift_warp_scale_and_bad_kinds():
    x = np.arange(2 * 6 * 6, dtype=np.float32).reshape(1, 2, 6, 6) + 1
    s = A.shift(x, 1, -1)
    assert np.array_equal(s[..., 1:, :5], x[..., :5, 1:]) and s[..., 0, :].sum() == 0
    assert s[..., :, 5].sum() == 0
    rng = np.random.default_rng(0)
    t = np.ones((3, 40, 6, 6), np.float32)
    lengths = {A.augment_one(t, NAMES, ("warp",), rng).shape[1] for _ in range(20)}
    assert min(lengths) < 40 < max(lengths) and 30 <= min(lengths) and max(lengths) <= 52
    scaled = A.augment_one(t, NAMES, ("scale",), rng)
    assert scaled[0].std() < 1e-6 and scaled[0, 0, 0, 0] != scaled[1, 0, 0, 0]
    assert A.parse_kinds("all") == A.KINDS and A.parse_kinds("") == ()
    with pytest.raises(UserError, match="augmentation 'spin'"):
        A.parse_kinds("flip,spin")


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("generalise")
    make_dataset_folder(root / "data", participants=4, blocks=2, difficulty="real",
                        gestures=("Poke", "Circular Stroke", "Heavy Pat"))
    return root


def test_participant_norm_puts_everyone_on_one_scale(data):
    ds = read_sessions([data / "data"]).select(None)
    normed = participant_normalised(ds)
    for p in np.unique(ds.participants):
        idx = np.flatnonzero(ds.participants == p)
        peaks = [trial_stats(normed.trials[i], normed.channel_names) for i in idx]
        assert np.median([s["peak_normal_p90"] for s in peaks]) == pytest.approx(
            REAL["peak_normal_p90"][0], rel=1e-3)
        assert np.median([s["peak_shear_p90"] for s in peaks]) == pytest.approx(
            REAL["peak_shear_p90"][0], rel=1e-3)


def test_balancing_and_participant_validation(data):
    y = np.array([0, 0, 0, 0, 1, 2, 2])
    idx = balanced_index(y, np.random.default_rng(1))
    assert np.bincount(y[idx]).tolist() == [4, 4, 4]
    ds = read_sessions([data / "data"]).select(None)
    fold = make_folds("lopo", ds.labels, ds.participants, 0)[0]
    pv = participant_val(fold, ds.participants, 0.15, 0)
    val_people = set(ds.participants[pv.val])
    assert len(val_people) == 1 and not val_people & set(ds.participants[pv.train])
    assert not val_people & set(fold.test_participants)
    assert sorted(np.concatenate([pv.train, pv.val])) == sorted(np.concatenate([fold.train,
                                                                                fold.val]))


@pytest.mark.parametrize("model", ["rf", "cnn3d"])
def test_options_run_through_the_experiment(data, model):
    torch_model = model != "rf"
    cfg = ExperimentConfig(data=[str(data / "data")], model=model, evaluation="lopo",
                           preset="tiny", epochs=4 if torch_model else None, threads=1,
                           cache_dir=str(data / "cache"), augment="all", augment_copies=2,
                           participant_norm=True, balance=True, val_by="participant",
                           overrides={"lr": "0.01"} if torch_model else {})
    res = run_experiment(cfg)
    assert 0 <= res.metrics["trial_accuracy"] <= 1
    rec = res.folds[0]
    assert len(set(rec["val"]) & set(rec["train"])) == 0
    again = run_experiment(cfg)  # seeded augmentation: the same result twice
    assert again.metrics["confusion_counts"] == res.metrics["confusion_counts"]
    with pytest.raises(UserError, match="validation split"):
        run_experiment(ExperimentConfig(data=[str(data / "data")], model="rf", val_by="x"))
