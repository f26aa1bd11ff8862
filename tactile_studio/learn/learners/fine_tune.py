"""Fine-tuning a trained network's output layers on a few labelled samples of one person:
live "Calibrate to person…" (learn/deploy/personalise.py) and offline
``train --shots K --shots-by fine-tune`` (learn/experiments/experiment.py) share it, so
both measure the same mechanism.

Only the output layers learn (the rest frozen, batch norm and dropout as trained, or,
offline in an adapted run, the batch norm re-estimated on the person's test windows
first: ``adapt_to``, +2.1 points at K = 1 on the simulator, docs/learning/figures.md): a
whole network refit on its training data plus a few windows takes minutes, which a
participant waiting at the sensor does not have, and a few windows would overfit every
layer. Measured on a new virtual person (full cnn1d trained on 4 people, 27 test
performances, 0.41 as trained): output layers K=1 0.52, K=2 0.70; every layer 0.48 /
0.67 and 1.5-3x slower; so the output layers.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Any

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.jobs import CancelToken, ProgressFn, no_progress

FINE_TUNE_STEPS = 150
FINE_TUNE_LR = 3e-3


@dataclass(frozen=True)
class FineTuning:
    """How long and how fast the output layers learn (Adam ``steps`` full-batch steps
    at ``lr``): the measured defaults above unless a test or study asks otherwise."""

    steps: int = FINE_TUNE_STEPS
    lr: float = FINE_TUNE_LR


def fine_tune_head(fitted: Any, x: np.ndarray, y: np.ndarray, n_classes: int,
                   seed: int = 0, tuning: FineTuning = FineTuning(),
                   progress: ProgressFn = no_progress, cancel: CancelToken | None = None,
                   adapt_to: np.ndarray | None = None) -> Any:
    """A copy of a network whose output layers (every linear or convolution layer with
    ``n_classes`` outputs: the network's own, its statistics head's, each ensemble
    member's) are trained further on normalised samples ``x`` labelled ``y``; everything
    else frozen, in eval mode (batch norm and dropout as trained).

    ``adapt_to``: the person's unlabelled normalised samples a run adapted to them
    (``--adapt person``) will be tested on: the batch norm is re-estimated on them first
    (``TorchFitted.adapted``), so the output layers learn on the features the person's
    test sees; re-adapting the result on the same samples leaves it unchanged."""
    import torch

    from tactile_studio.learn.learners.families import TorchFitted

    torch.manual_seed(seed)
    if adapt_to is not None:
        fitted = fitted.adapted(adapt_to)
    net = copy.deepcopy(fitted.model).cpu()
    net.eval()
    kinds = (torch.nn.Linear, torch.nn.Conv1d, torch.nn.Conv2d, torch.nn.Conv3d)
    heads = [m for m in net.modules() if isinstance(m, kinds) and n_classes ==
             getattr(m, "out_features", getattr(m, "out_channels", None))]
    if not heads:
        raise UserError(f"the network has no output layer of {n_classes} classes to "
                        "fine-tune")
    for p in net.parameters():
        p.requires_grad_(False)
    params = [p for m in heads for p in m.parameters()]
    for p in params:
        p.requires_grad_(True)
    steps = tuning.steps
    opt = torch.optim.Adam(params, lr=tuning.lr)
    xt = torch.from_numpy(np.ascontiguousarray(x, dtype=np.float32))
    yt = torch.from_numpy(np.asarray(y, dtype=np.int64))
    for step in range(steps):
        if cancel is not None:
            cancel.check()
        if step % 10 == 0:
            progress(step / steps, f"fine-tuning its output layers: step {step} of {steps}")
        opt.zero_grad()
        loss = torch.nn.functional.cross_entropy(net(xt).float(), yt)
        loss.backward()
        opt.step()
    for p in net.parameters():
        p.requires_grad_(False)
    return TorchFitted(net, "cpu")
