"""Live few-shot personalisation (learn/deploy/personalise.py): a run's fold model retrained with
labelled windows of a new virtual person predicts that person's other performances
better than the run's own model; forgetting it returns to the run's model."""

from __future__ import annotations

import numpy as np
import pytest
from learn_fixtures import make_dataset_folder, write_participant

from tactile_studio.errors import UserError
from tactile_studio.learn.deploy.personalise import personalise
from tactile_studio.learn.deploy.window_model import WindowModel
from tactile_studio.learn.experiments.experiment import ExperimentConfig, run_experiment
from tactile_studio.playback import SessionPlayback

BLOCKS_NEW = 5  # the new person: blocks 0-1 give the shots, 2-4 are tested


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    """4 virtual people of the default (real) difficulty, 9 gestures x 2 blocks; a new
    person P09 who performs each gesture 5 times."""
    root = tmp_path_factory.mktemp("personal")
    make_dataset_folder(root / "data", participants=4, blocks=2, difficulty="real")
    write_participant(root / "new.h5", "P09", 909, blocks=BLOCKS_NEW, difficulty="real")
    return root


def _run(root, model: str, adapt: str = "none"):
    out = root / f"run-{model}-{adapt}"
    if not (out / "metrics.json").is_file():
        run_experiment(ExperimentConfig(data=[str(root / "data")], model=model,
                                        protocol="lopo", preset="tiny", adapt=adapt,
                                        cache_dir=str(root / "cache")), out)
    return out


def _new_person(model: WindowModel, path):
    """(layout, rate, windows, gestures, blocks) of the new person's trials."""
    pb = SessionPlayback(path)
    try:
        frames = model.decode(pb.layout, pb.raw, pb.session.baseline(0))
        rate = (pb.n_frames - 1) / pb.duration
        n = len({t.gesture for t in pb.trials})
        return (pb.layout, rate, [frames[:, t.start:t.end] for t in pb.trials],
                [t.gesture for t in pb.trials], [i // n for i in range(len(pb.trials))])
    finally:
        pb.close()


def _accuracy(model: WindowModel, layout, rate, windows, gestures) -> float:
    probs = model.predict_windows(layout, windows, rate)
    return float(np.mean([model.labels[p] == g for p, g in zip(probs.argmax(1), gestures)]))


@pytest.mark.parametrize("name,adapt", [
    ("rf", "none"), ("knn", "none"),
    ("rf", "person"),  # features standardised per person: theirs by their own touches
    pytest.param("cnn1d", "none", marks=pytest.mark.slow)])
def test_labelled_touches_of_a_new_person_lift_their_accuracy(root, name, adapt):
    model = WindowModel(_run(root, name, adapt))
    layout, rate, windows, gestures, blocks = _new_person(model, root / "new.h5")
    test = [i for i, b in enumerate(blocks) if b >= 2]
    tw, tg = [windows[i] for i in test], [gestures[i] for i in test]
    before = _accuracy(model, layout, rate, tw, tg)
    run_model = model.trained
    gains = []
    for k in (1, 2):
        shots = [i for i, b in enumerate(blocks) if b < k]  # K performances per gesture
        personal = personalise(model, layout, [windows[i] for i in shots],
                               [gestures[i] for i in shots], rate, seed=0)
        assert personal.per_gesture == k and personal.windows == 9 * k
        assert personal.how == ("fine-tuned" if name == "cnn1d" else "refit")
        assert (personal.reference is not None) == (adapt == "person")
        model.personalise(personal)
        gains.append(_accuracy(model, layout, rate, tw, tg) - before)
        model.forget_personalisation()
        assert model.trained is run_model and _accuracy(model, layout, rate, tw, tg) == before
    assert min(gains) > 0, (name, before, gains)


def test_refused_in_one_line(root):
    model = WindowModel(_run(root, "rf"))
    layout, rate, windows, gestures, _ = _new_person(model, root / "new.h5")
    with pytest.raises(UserError, match="no gesture Wave"):
        personalise(model, layout, windows[:2], ["Wave", gestures[1]], rate)
    with pytest.raises(UserError, match="none were recorded"):
        personalise(model, layout, [], [], rate)
    # the run's data gone: the fold's training windows cannot be read again
    model.config.data = [str(root / "gone")]
    model.config.use_cache = False
    with pytest.raises(UserError, match="training data cannot be read"):
        personalise(model, layout, windows[:9], gestures[:9], rate)
