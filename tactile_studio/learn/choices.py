"""The learning pipeline's lists of choices, each declared once, below every room.

The CLI's ``choices=`` and help, the research panels' combo boxes and the checks of
:class:`~tactile_studio.learn.experiments.config.ExperimentConfig` read these (a test holds
them to it: tests/test_choices_declared.py). This module imports nothing, so the CLI and the
model registry read it without loading the data stack or torch.
"""

from __future__ import annotations

EVALUATIONS = ("lopo", "group-kfold", "all-inclusive")  # evaluation splits; the default first
GRIDS = ("physical", "virtual")  # the sensor's taxels, or the (2R-1)x(2C-1) virtual grid
CHANNEL_SETS = ("normal", "shear", "both")  # "both": every channel of a shear sensor
AGGREGATES = ("mean", "vote")  # a trial's class from its windows' probabilities
# the scikit-learn baselines (learn/learners/baselines.py); no network may take their names
BASELINES = ("rf", "et", "knn")
SHOTS_BY = ("auto", "join", "fine-tune")  # how a held-out person's shots reach the model
EXECUTORS = ("local", "ray")  # where a sweep's tasks run: worker processes or Ray
EXPORT_FORMATS = ("onnx", "int8")  # export-model --format: ONNX, or int8-quantised ONNX
