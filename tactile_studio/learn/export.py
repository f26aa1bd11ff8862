"""Export trained models: ONNX (every model) and int8 quantisation (the small ones).

ONNX uses torch's TorchScript-based exporter (``dynamo=False``), opset 17: the
torch.export-based default needs the ``onnxscript`` package, which is not a dependency,
and the legacy exporter handles every model here (3D convs, the Transformer encoder)
with a dynamic batch axis. Predictions are checked against torch in the tests.

int8 uses torch.ao eager-mode quantisation (deprecated upstream in favour of torchao,
but present and working in torch 2.13): a model may name ``quant_stacks`` — Sequential
conv stacks (Conv, BN, ReLU, pooling) that get static quantisation with Conv+BN+ReLU
fused, calibrated on sample inputs — and every ``nn.Linear`` outside Transformer layers
gets dynamic quantisation (the Transformer fast path cannot run quantised Linear).
"""

from __future__ import annotations

import copy
import io
import os
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch
from torch import nn

from tactile_studio.errors import UserError

OPSET = 17


def onnx_bytes(
    module: nn.Module,
    example_input: torch.Tensor,
    input_name: str = "input",
    output_name: str = "logits",
) -> bytes:
    """``module`` (in eval mode) as an ONNX model in memory, batch axis dynamic."""
    was_training = module.training
    module.eval()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            warnings.simplefilter("ignore", torch.jit.TracerWarning)
            buffer = io.BytesIO()
            torch.onnx.export(
                module,
                (example_input,),
                buffer,
                dynamo=False,
                opset_version=OPSET,
                input_names=[input_name],
                output_names=[output_name],
                dynamic_axes={input_name: {0: "batch"}, output_name: {0: "batch"}},
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


def export_onnx(
    model: nn.Module,
    example_input: torch.Tensor,
    path: str | os.PathLike,
    *,
    metadata: dict[str, str] | None = None,
) -> Path:
    """Write ``model`` (evaluated in eval mode) as ONNX with input ``input`` (dynamic
    batch) and output ``logits``; ``metadata`` goes into the file's metadata_props
    (e.g. labels, view, normalisation). Returns the path."""
    import onnx

    path = Path(path)
    proto = onnx.load_model_from_string(onnx_bytes(model, example_input))
    for key, value in (metadata or {}).items():
        entry = proto.metadata_props.add()
        entry.key, entry.value = str(key), str(value)
    onnx.checker.check_model(proto)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        onnx.save_model(proto, str(path))
    except OSError as exc:
        raise UserError(f"{path}: cannot write the ONNX model ({exc.strerror or exc})") from None
    return path


class OnnxPredictor:
    """Calls an ONNX model with onnxruntime on the CPU: (B, C, T, R, X) -> logits (B, K).
    A single sample (C, T, R, X) gets a batch axis added."""

    def __init__(self, path: str | os.PathLike, threads: int = 0) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise UserError(f"{self.path}: no such ONNX model file")
        try:
            self.session = cpu_session(str(self.path), threads)
        except Exception as exc:  # onnxruntime raises its own untyped errors on bad files
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            raise UserError(f"{self.path}: not a loadable ONNX model ({first[:120]})") from None
        inp = self.session.get_inputs()[0]
        self.input_name = inp.name
        self.input_shape = tuple(inp.shape)
        self.metadata = dict(self.session.get_modelmeta().custom_metadata_map)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        x = np.ascontiguousarray(x, dtype=np.float32)
        if x.ndim == len(self.input_shape) - 1:
            x = x[None]
        return self.session.run(None, {self.input_name: x})[0]


def load_onnx_predictor(path: str | os.PathLike, threads: int = 0) -> Callable[[np.ndarray], np.ndarray]:
    """A callable numpy (B, C, T, R, X) -> logits (B, K) backed by onnxruntime (CPU)."""
    return OnnxPredictor(path, threads)


# ---------------------------------------------------------------- int8

def _fuse_groups(stack: nn.Sequential, prefix: str = "") -> list[list[str]]:
    """Names of Conv+BN(+ReLU) and Conv+ReLU runs in a (nested) Sequential."""
    convs = (nn.Conv1d, nn.Conv2d, nn.Conv3d)
    bns = (nn.BatchNorm1d, nn.BatchNorm2d, nn.BatchNorm3d)
    mods = list(stack)
    groups, i = [], 0
    while i < len(mods):
        if isinstance(mods[i], nn.Sequential):
            groups += _fuse_groups(mods[i], f"{prefix}{i}.")
            i += 1
        elif isinstance(mods[i], convs):
            n = 1
            if i + n < len(mods) and isinstance(mods[i + n], bns):
                n += 1
            if i + n < len(mods) and isinstance(mods[i + n], nn.ReLU):
                n += 1
            if n > 1:
                groups.append([f"{prefix}{j}" for j in range(i, i + n)])
            i += n
        else:
            i += 1
    return groups


def _get(model: nn.Module, dotted: str) -> nn.Module:
    return model.get_submodule(dotted)


def _set(model: nn.Module, dotted: str, module: nn.Module) -> None:
    parent, _, name = dotted.rpartition(".")
    setattr(model.get_submodule(parent) if parent else model, name, module)


def _dynamic_linear_names(model: nn.Module) -> set[str]:
    layers = [n for n, m in model.named_modules() if isinstance(m, nn.TransformerEncoderLayer)]
    return {
        n for n, m in model.named_modules()
        if type(m) is nn.Linear and not any(n.startswith(prefix + ".") for prefix in layers)
    }


def quantize_int8(
    model: nn.Module, calibration: torch.Tensor | None = None, *, engine: str = "x86"
) -> nn.Module:
    """An int8 copy of ``model`` for CPU inference (the original is untouched).

    Conv stacks the model lists in ``quant_stacks`` are statically quantised, calibrated
    on ``calibration`` (B, C, T, R, X) — pass real training samples; without them random
    z-scored-like inputs N(0, 1) of ``model.input_shape`` are used. Linear layers outside
    Transformer layers are dynamically quantised.
    """
    import torch.ao.quantization as tq

    torch.backends.quantized.engine = engine
    q = copy.deepcopy(model).eval()
    stacks = tuple(getattr(q, "quant_stacks", ()))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        warnings.simplefilter("ignore", UserWarning)
        if stacks:
            if calibration is None:
                gen = torch.Generator().manual_seed(0)
                calibration = torch.randn(64, *q.input_shape, generator=gen)
            for name in stacks:
                stack = _get(q, name)
                groups = _fuse_groups(stack)
                if groups:
                    tq.fuse_modules(stack, groups, inplace=True)
                wrapped = nn.Sequential(tq.QuantStub(), stack, tq.DeQuantStub())
                wrapped.qconfig = tq.get_default_qconfig(engine)
                _set(q, name, wrapped)
            tq.prepare(q, inplace=True)
            with torch.inference_mode():
                for batch in torch.split(calibration, 64):
                    q(batch)
            tq.convert(q, inplace=True)
        names = _dynamic_linear_names(q)
        if names:
            q = tq.quantize_dynamic(q, names, dtype=torch.qint8)
    return q


def model_size_bytes(model: nn.Module) -> int:
    """Bytes of the serialised state dict (what a saved model costs on disk)."""
    buffer = io.BytesIO()
    torch.save(model.state_dict(), buffer)
    return len(buffer.getvalue())
