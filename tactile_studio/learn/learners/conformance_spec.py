"""The ModelSpec half of ``check_model``: the declaration is consistent, the network builds
for every preset and matches what the declaration says about it (conformance.py)."""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from tactile_studio.errors import UserError
from tactile_studio.learn.learners.train import OPTIMIZERS
from tactile_studio.learn.models.registry import NAME_RE, RESERVED
from tactile_studio.learn.models.spec import (
    EXPORT_FORMATS,
    INT8_FORMATS,
    PRESETS,
    VIEW_KINDS,
    ModelSpec,
    TrainDefaults,
    ViewSpec,
    classify_window,
    needs_window,
)

GRID = (6, 6)
N_CLASSES = 3


def check_declaration(spec: ModelSpec, problems: list[str]) -> None:
    """Every declared fact is well-formed and agrees with the others."""
    if not isinstance(spec.name, str) or not NAME_RE.match(spec.name) or spec.name in RESERVED:
        problems.append(f"name {spec.name!r}: give a lowercase name (letters, digits, - or _), "
                        f"not {', '.join(RESERVED)}: the one users type after --model")
    if not isinstance(spec.description, str) or not spec.description.strip() \
            or "\n" in spec.description:
        problems.append("description: give one line saying what the model is")
    if not callable(spec.builder):
        problems.append("builder is not callable")
    for what, table, kind in (("views", spec.views, ViewSpec), ("train", spec.train, TrainDefaults),
                              ("options", spec.options, dict)):
        if set(table) != set(PRESETS):
            problems.append(f"{what}: declare exactly the presets {', '.join(PRESETS)}, "
                            f"not {', '.join(map(str, table)) or 'none'}")
            return
        for preset in PRESETS:
            if not isinstance(table[preset], kind):
                problems.append(f"{what}[{preset!r}] is a {type(table[preset]).__name__}, "
                                f"not a {kind.__name__}")
                return
    kinds = {spec.views[p].kind for p in PRESETS}
    for preset in PRESETS:
        view = spec.views[preset]
        if view.kind not in VIEW_KINDS:
            problems.append(f"views[{preset!r}].kind {view.kind!r} "
                            "is not a view of learn/data/views.py")
        if view.frames < 1 or (view.kind == "windows" and view.stride < 1):
            problems.append(f"views[{preset!r}]: frames (and a windows view's stride) must be >= 1")
        train = spec.train[preset]
        if train.optimizer not in OPTIMIZERS:
            problems.append(f"train[{preset!r}].optimizer {train.optimizer!r} is not one of "
                            f"{', '.join(OPTIMIZERS)}")
        if train.lr <= 0 or min(train.batch_size, train.max_epochs, train.patience) < 1:
            problems.append(f"train[{preset!r}]: lr must be > 0; batch_size, max_epochs and "
                            "patience >= 1")
    if len(kinds) > 1:
        problems.append(f"views: every preset must take the same view kind, not {sorted(kinds)}")
    keys = [set(spec.options[p]) for p in PRESETS]
    if any(k != keys[0] for k in keys):
        problems.append("options: every preset must have the same option keys")
    undocumented = sorted(set().union(*keys) - set(spec.option_help))
    if undocumented:
        problems.append(f"option_help: add one line of help for {', '.join(undocumented)}")
    stray = sorted(set(spec.option_help) - set().union(*keys))
    if stray:
        problems.append("option_help documents options the model does not have: "
                        f"{', '.join(stray)}")
    if not spec.export or any(f not in EXPORT_FORMATS for f in spec.export):
        problems.append(f"export {spec.export!r}: declare one or more of "
                        f"{', '.join(EXPORT_FORMATS)}")
    if spec.quantizable and "onnx" not in spec.export:
        problems.append("quantizable needs export to onnx (int8 is an onnxruntime quantisation)")
    if spec.int8_format not in INT8_FORMATS:
        problems.append(f"int8_format {spec.int8_format!r} is not one of {', '.join(INT8_FORMATS)}")
    if spec.streaming.sliding and kinds != {"windows"}:
        problems.append("streaming.sliding needs the 'windows' view (the model predicts on the "
                        "newest view.frames frames)")
    if spec.streaming.cached and not spec.streaming.sliding:
        problems.append("streaming.cached needs streaming.sliding")
    if not spec.gpus >= 0:
        problems.append(f"gpus {spec.gpus!r} must be >= 0")


def _logits(model: torch.nn.Module, x: torch.Tensor) -> torch.Tensor:
    with torch.inference_mode():
        return model(x)


def check_build(spec: ModelSpec, problems: list[str], observed: dict[str, Any]) -> None:
    """Build every preset on 1- and 3-channel data; forward passes and declared facts."""
    torch.manual_seed(0)
    for preset in PRESETS:
        frames = spec.views[preset].frames
        for channels in (1, 3):
            where = f"preset {preset}, {channels} channel(s), {GRID[0]}x{GRID[1]} grid"
            try:
                model = spec.build(N_CLASSES, channels, GRID, preset).eval()
            except Exception as exc:  # noqa: BLE001 - reported with the others
                problems.append(f"build ({where}): {type(exc).__name__}: {exc}")
                continue
            if not isinstance(model, torch.nn.Module):
                problems.append(f"build ({where}) returned a {type(model).__name__}, "
                                "not a torch.nn.Module")
                continue
            x = torch.randn(2, channels, frames, *GRID)
            try:
                out = _logits(model, x)
            except Exception as exc:  # noqa: BLE001
                problems.append(f"forward ({where}) on {tuple(x.shape)}: "
                                f"{type(exc).__name__}: {exc}")
                continue
            if tuple(out.shape) != (2, N_CLASSES) or not torch.isfinite(out).all():
                problems.append(f"forward ({where}) gave {tuple(out.shape)}, expected finite "
                                f"logits (2, {N_CLASSES})")
                continue
            observed["parameters"][(preset, channels)] = sum(p.numel()
                                                             for p in model.parameters())
            if channels == 3:  # tiny, and full (the recipe: mirrors, members, statistics)
                _check_facts(spec, model, x, out, problems)
    _check_overrides(spec, problems)


def _check_overrides(spec: ModelSpec, problems: list[str]) -> None:
    frames = spec.views["tiny"].frames * 2
    try:
        model = spec.build(N_CLASSES, 3, GRID, "tiny", view_frames=frames).eval()
        out = _logits(model, torch.randn(1, 3, frames, *GRID))
        if tuple(out.shape) != (1, N_CLASSES):
            problems.append(f"view_frames={frames}: forward gave {tuple(out.shape)}")
    except Exception as exc:  # noqa: BLE001
        problems.append(f"view_frames={frames} (the pipeline's view-length override): "
                        f"{type(exc).__name__}: {exc}")
    try:
        spec.build(N_CLASSES, 3, GRID, "tiny", no_such_option=1)
        problems.append("build accepted an unknown option: reject it with a UserError "
                        "(models._common.resolve_options does)")
    except UserError:
        pass
    except Exception as exc:  # noqa: BLE001
        problems.append(f"an unknown option raised {type(exc).__name__}, not a UserError")


def _check_facts(spec: ModelSpec, model: torch.nn.Module, x: torch.Tensor,
                 out: torch.Tensor, problems: list[str]) -> None:
    """The declared streaming and export facts hold for the network."""
    if spec.streaming.cached:
        halves = [m for m in ("frame_features", "classify_embeddings")
                  if not callable(getattr(model, m, None))]
        if halves:
            problems.append(f"streaming.cached is declared but the model has no "
                            f"{', '.join(halves)}")
        else:
            b, c, t, r, s = x.shape
            with torch.inference_mode():
                emb = model.frame_features(x.permute(0, 2, 1, 3, 4).reshape(b * t, c, r, s))
                split = classify_window(model, emb.reshape(b, t, -1),
                                        x if needs_window(model) else None)
            if not torch.allclose(split, out, atol=1e-4):
                problems.append("classify_embeddings(frame_features(frames)) differs from the "
                                "forward pass")
    if "onnx" in spec.export:
        from tactile_studio.learn.learners.onnx_io import cpu_session, onnx_bytes

        try:
            session = cpu_session(onnx_bytes(model, x), 1)
            got = session.run(None, {session.get_inputs()[0].name: x.numpy()})[0]
        except Exception as exc:  # noqa: BLE001
            problems.append(f"export to onnx (declared): {type(exc).__name__}: {exc}")
            return
        if not np.allclose(got, out.numpy(), atol=1e-4):
            problems.append("the ONNX export's logits differ from torch's "
                            f"(max {float(np.abs(got - out.numpy()).max()):.2g})")
