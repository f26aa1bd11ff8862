"""``--set`` errors name every option a model run takes: the model's and training's."""

from __future__ import annotations

import pytest

from tactile_studio.errors import UserError
from tactile_studio.learn.learners import DataInfo, make_learner
from tactile_studio.learn.train import TRAIN_KEYS


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
