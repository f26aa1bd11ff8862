"""Export trained models: ONNX (every model) and int8 ONNX (the quantisable ones).

ONNX uses torch's TorchScript-based exporter (``dynamo=False``), opset 17: the
torch.export-based default needs the ``onnxscript`` package, which is not a dependency,
and the legacy exporter handles every model here (3D convs, the Transformer encoder)
with a dynamic batch axis. Predictions are checked against torch in the tests.

int8 quantises that ONNX file with onnxruntime's static quantisation, calibrated on
training samples, so the int8 model is a file that loads back like the float one
(torch's own int8 modules do not export to ONNX).
"""

from __future__ import annotations

import io
import logging
import os
import tempfile
import warnings
from collections.abc import Callable
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from tactile_studio.errors import UserError
from tactile_studio.file_claims import written_whole
from tactile_studio.learn.learners.onnx_io import (  # noqa: F401 (their home; re-exported)
    OPSET,
    cpu_session,
    onnx_bytes,
)


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
    onnx.checker.check_model(proto)
    return _save_onnx(proto, metadata or {}, path, "ONNX model")


def _save_onnx(proto: Any, metadata: dict[str, str], path: Path, what: str) -> Path:
    """Replace the file's metadata_props with ``metadata`` and write it (one-line errors)."""
    import onnx

    del proto.metadata_props[:]
    for key, value in metadata.items():
        entry = proto.metadata_props.add()
        entry.key, entry.value = str(key), str(value)
    # written beside it and published under its claim (file_claims): a disk filling up
    # part way leaves no cut model that would pass for one (and an earlier export of it
    # stays as it was); two exports to one name never mix
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        written_whole(path, lambda part: onnx.save_model(proto, str(part)), what=what)
    except OSError as exc:
        raise UserError(f"{path}: cannot write the {what} ({exc.strerror or exc})") from None
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


def load_onnx_predictor(path: str | os.PathLike,
                        threads: int = 0) -> Callable[[np.ndarray], np.ndarray]:
    """A callable numpy (B, C, T, R, X) -> logits (B, K) backed by onnxruntime (CPU)."""
    return OnnxPredictor(path, threads)


# ---------------------------------------------------------------- int8

# "qoperator" (QLinearConv, QGemm, ... operators) keeps small models small; "qdq" (float
# ops between QuantizeLinear/DequantizeLinear pairs) is onnxruntime's recommended form but
# its extra nodes outweigh the int8 weights of a ~2 k parameter model (cnn1d: 10 KiB
# QOperator, 15 KiB QDQ, 17 KiB float). mts3d's 36 chained QLinearConv/QLinearAdd layers
# drift in QOperator form (tiny lopo run: accuracy 0.611 -> 0.315; QDQ: 0.602).
CALIBRATION_SAMPLES = 256


def int8_format(model_name: str) -> str:
    """The onnxruntime quantisation format used for ``model_name``'s int8 export (declared
    by the model: ``ModelSpec.int8_format``)."""
    from tactile_studio.learn.models import get_model_spec

    return get_model_spec(model_name).int8_format


@contextmanager
def _quiet_quantizer():
    """onnxruntime's quantiser logs advice through the root logger (and would install a
    stderr handler on it): silence it for the duration without touching the config."""
    root = logging.getLogger()
    guard = logging.NullHandler()
    root.addHandler(guard)
    previous = logging.root.manager.disable
    logging.disable(logging.WARNING)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield
    finally:
        logging.disable(previous)
        root.removeHandler(guard)


def quantize_onnx_int8(
    float_model: str | os.PathLike,
    path: str | os.PathLike,
    calibration: np.ndarray,
    *,
    quant_format: str = "qoperator",
    batch: int = 32,
) -> Path:
    """Write an int8 copy of the ONNX model ``float_model`` to ``path`` (static
    quantisation with onnxruntime; load it with :func:`load_onnx_predictor`).

    Weights are int8 per output channel with a 7-bit range (``reduce_range``: on AVX2
    CPUs without VNNI the uint8 x int8 products saturate otherwise — measured: 80-93%
    agreement with float without it, 97-100% with it); activations are uint8 with ranges
    from min/max over ``calibration`` (N, ...) — a few hundred training samples,
    normalised like the model's input. The float model's metadata is kept and a
    ``quantization`` entry added.
    """
    import onnx
    from onnxruntime.quantization import (
        CalibrationDataReader,
        QuantFormat,
        QuantType,
        quant_pre_process,
        quantize_static,
    )

    formats = {"qoperator": QuantFormat.QOperator, "qdq": QuantFormat.QDQ}
    if quant_format not in formats:
        raise ValueError(f"unknown int8 format {quant_format!r} (available: {', '.join(formats)})")
    calibration = np.ascontiguousarray(calibration, dtype=np.float32)
    if not len(calibration):
        raise UserError(f"{path}: no calibration samples for the int8 model")
    source = onnx.load_model(str(float_model))
    input_name = source.graph.input[0].name

    class Samples(CalibrationDataReader):
        def __init__(self) -> None:
            self.batches = iter(np.array_split(calibration, -(-len(calibration) // batch)))

        def get_next(self) -> dict[str, np.ndarray] | None:
            chunk = next(self.batches, None)
            return None if chunk is None else {input_name: chunk}

    path = Path(path)
    with tempfile.TemporaryDirectory() as tmp, _quiet_quantizer():
        prepared = Path(tmp) / "prepared.onnx"
        # constant folding and shape inference (ONNX's: the symbolic one fails on the
        # Transformer's reshapes), as onnxruntime recommends before quantising
        quant_pre_process(source, prepared, skip_symbolic_shape=True)
        quantized = Path(tmp) / "int8.onnx"
        quantize_static(prepared, quantized, Samples(), quant_format=formats[quant_format],
                        per_channel=True, reduce_range=True,
                        activation_type=QuantType.QUInt8, weight_type=QuantType.QInt8)
        proto = onnx.load_model(str(quantized))
    del proto.graph.value_info[:]  # shape hints from pre-processing: size, no function
    meta = {p.key: p.value for p in source.metadata_props}
    meta["quantization"] = (f"int8 static {quant_format}, per-channel 7-bit weights, uint8 "
                            f"activations calibrated on {len(calibration)} samples")
    return _save_onnx(proto, meta, path, "int8 model")


def model_size_bytes(model: nn.Module) -> int:
    """Bytes of the serialised state dict (what a saved torch model costs on disk)."""
    buffer = io.BytesIO()
    torch.save(model.state_dict(), buffer)
    return len(buffer.getvalue())
