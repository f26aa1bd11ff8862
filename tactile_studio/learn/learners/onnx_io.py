"""A torch module as ONNX bytes, and an onnxruntime CPU session over ONNX bytes or a file.

Below deploy/ because the learners need them too: the forest and k-NN baselines run as
ONNX, and the conformance checks compare a model's ONNX predictions with torch's.
deploy/export.py builds the exported files on them. Opset 17 and the TorchScript-based
exporter (``dynamo=False``): see deploy/export.py's docstring for why.
"""

from __future__ import annotations

import io
import warnings

import torch
from torch import nn

OPSET = 17


def onnx_bytes(
    module: nn.Module,
    example_input: torch.Tensor | tuple[torch.Tensor, ...],
    input_name: str | tuple[str, ...] = "input",
    output_name: str = "logits",
) -> bytes:
    """``module`` (in eval mode) as an ONNX model in memory, batch axis dynamic; several
    inputs as tuples of example tensors and names."""
    inputs = example_input if isinstance(example_input, tuple) else (example_input,)
    names = list(input_name) if isinstance(input_name, tuple) else [input_name]
    was_training = module.training
    module.eval()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            warnings.simplefilter("ignore", torch.jit.TracerWarning)
            buffer = io.BytesIO()
            torch.onnx.export(
                module,
                inputs,
                buffer,
                dynamo=False,
                opset_version=OPSET,
                input_names=names,
                output_names=[output_name],
                dynamic_axes={**{name: {0: "batch"} for name in names},
                              output_name: {0: "batch"}},
                do_constant_folding=True,
            )
    finally:
        module.train(was_training)
    return buffer.getvalue()


def cpu_session(model: bytes | str, threads: int = 0):
    """An onnxruntime CPU InferenceSession (``threads`` 0 = onnxruntime's default)."""
    import onnxruntime as ort

    options = ort.SessionOptions()
    if threads:
        options.intra_op_num_threads = threads
    return ort.InferenceSession(model, options, providers=["CPUExecutionProvider"])
