"""``--set`` errors name every option a model run takes: the model's and training's; the
training loop's batches cover every sample once."""

from __future__ import annotations

import numpy as np
import pytest

from tactile_studio.errors import UserError
from tactile_studio.learn.learners.families import DataInfo, make_learner
from tactile_studio.learn.learners.train import TRAIN_KEYS, _batches


@pytest.mark.parametrize("model", ["cnn1d", "cnn3d"])
def test_unknown_option_lists_model_and_training_options(model):
    learner = make_learner(model, "tiny", {"wings": "3"}, device="cpu")
    info = DataInfo(3, 3, (6, 6), ("normal", "shear_x", "shear_y"), 1.0)
    with pytest.raises(UserError) as err:
        learner.check(info)
    msg = str(err.value)
    assert "unknown option 'wings'" in msg and "\n" not in msg
    assert "model options: " in msg and "dropout" in msg
    assert "training options: " + ", ".join(TRAIN_KEYS) in msg


@pytest.mark.parametrize("size", [16, 32])
def test_batches_cover_every_sample_once_and_none_is_alone(size):
    # 33 samples in batches of 32 crashed; 65 lost a batch and trained another twice
    rng = np.random.default_rng(0)
    for n in range(2, 5 * size + 3):
        for order in (None, rng):
            batches = _batches(n, size, order)
            assert sorted(np.concatenate(batches).tolist()) == list(range(n)), n
            assert min(len(b) for b in batches) > 1 or n < 2, n
