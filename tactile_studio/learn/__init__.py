"""Learning core, in rooms named for what they hold (docs/learning/ has a page per room):
``data`` (trials, views, windows, splits), ``models`` (the torch networks and their
registry), ``learners`` (the model contract, baselines, training, adaptation),
``experiments`` (runs, jobs, sweeps, run folders, reading and comparing finished runs),
``evaluation`` (metrics, statistics, figures) and
``deploy`` (export, streaming, live inference, personalisation).

The model extension seam (docs/models.md) is importable from here; it loads on first use,
so importing a submodule of this package does not pull in torch.
"""

from __future__ import annotations

from typing import Any

_SEAM = {
    "check_model": "tactile_studio.learn.learners.conformance",
    "ModelCheckError": "tactile_studio.learn.learners.conformance",
    "Learner": "tactile_studio.learn.learners.contract",
    "Fitted": "tactile_studio.learn.learners.contract",
    "ModelFacts": "tactile_studio.learn.learners.contract",
    "DataInfo": "tactile_studio.learn.learners.contract",
    "ModelSpec": "tactile_studio.learn.models",
    "Streaming": "tactile_studio.learn.models",
    "TrainDefaults": "tactile_studio.learn.models",
    "ViewSpec": "tactile_studio.learn.models",
    "register_model": "tactile_studio.learn.models",
}

__all__ = sorted(_SEAM)


def __getattr__(name: str) -> Any:
    if name not in _SEAM:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import importlib

    return getattr(importlib.import_module(_SEAM[name]), name)
