"""Cheaper dropout masks: the Transformer encoder of cnn_transformer and sefusion, and the
dropout of cnn_transformer's frame embedding and mts3d's feature maps.

Profiled on cnn_transformer's full preset (one LOPO fold, one thread), the attention
dropout alone was a fifth of a training step: ``nn.MultiheadAttention`` draws a
Bernoulli number per attention weight ((B, heads, T, T): 1.9 M per batch of 64 windows
of 86 frames) with ``bernoulli_``, ~8 ns each on this CPU. :class:`EncoderLayer` is
``nn.TransformerEncoderLayer`` (the same parameters and state-dict keys: saved runs
load, export and stream as before) whose self-attention, in training with dropout only,
is computed by hand with a mask of 16-bit random integers (four per 64-bit draw of
torch's generator, ~1 ns per weight): an attention weight is dropped with probability
``round(p * 65536) / 65536`` (0.300003 for p = 0.3) and the kept ones are scaled by the
inverse of the keep probability, so every output has exactly the expectation it has
without dropout, as with ``nn.Dropout``. Evaluation (and an ONNX export, in eval mode)
takes torch's own path unchanged. :class:`Dropout` is ``nn.Dropout`` with the same mask
(its ``bernoulli_`` was another ~5% of a cnn_transformer step).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from tactile_studio.errors import UserError

_LEVELS = 1 << 16  # values of a 16-bit random integer


def keep_mask(shape: torch.Size | tuple[int, ...], p: float,
              device: torch.device | str = "cpu") -> tuple[Tensor, float]:
    """(mask, scale): a bool mask of ``shape`` that is False with probability
    ``round(p * 65536) / 65536`` independently per element, and the factor the kept
    elements are multiplied by (1 / keep probability). Four elements per 64-bit draw
    of torch's default generator (so ``torch.manual_seed`` makes it reproducible)."""
    drop = round(p * _LEVELS)
    n = 1
    for s in shape:
        n *= int(s)
    words = torch.randint(-(1 << 63), (1 << 63) - 1, (-(-n // 4),), dtype=torch.int64,
                          device=device)
    lanes = words.view(torch.int16)[:n].view(shape)  # uniform over -32768..32767
    return lanes >= drop - (_LEVELS // 2), _LEVELS / (_LEVELS - drop)


class Dropout(nn.Dropout):
    """``nn.Dropout`` whose training-time mask is :func:`keep_mask`'s (~3x cheaper on
    the feature maps of cnn_transformer and mts3d); evaluation is the identity as
    before. The mask is drawn over the tensor's logical shape, so the same cells drop
    whatever its memory layout (mts3d trains with channels-last feature maps)."""

    def forward(self, x: Tensor) -> Tensor:
        if not self.training or self.p == 0.0:
            return super().forward(x)
        keep, scale = keep_mask(x.shape, self.p, x.device)
        return x * (keep.to(x.dtype) * scale)


class EncoderLayer(nn.TransformerEncoderLayer):
    """``nn.TransformerEncoderLayer`` (post-norm, batch first) whose training-time
    self-attention dropout uses :func:`keep_mask`, and its other dropouts
    :class:`Dropout` (see the module doc)."""

    def __init__(self, d_model: int, nhead: int, dim_feedforward: int = 2048,
                 dropout: float = 0.1, batch_first: bool = True) -> None:
        super().__init__(d_model, nhead, dim_feedforward=dim_feedforward, dropout=dropout,
                         batch_first=batch_first)
        self.dropout, self.dropout1, self.dropout2 = (Dropout(dropout) for _ in range(3))

    def _sa_block(self, x: Tensor, attn_mask: Tensor | None,
                  key_padding_mask: Tensor | None, is_causal: bool = False) -> Tensor:
        attn = self.self_attn
        p = float(attn.dropout)
        if (not self.training or p == 0.0 or attn_mask is not None
                or key_padding_mask is not None or is_causal or not attn.batch_first
                or attn.in_proj_weight is None):
            return super()._sa_block(x, attn_mask, key_padding_mask, is_causal)
        b, t, e = x.shape
        h = attn.num_heads
        q, k, v = F.linear(x, attn.in_proj_weight, attn.in_proj_bias).chunk(3, dim=-1)
        q, k, v = (z.reshape(b, t, h, e // h).transpose(1, 2) for z in (q, k, v))
        weights = torch.softmax((q @ k.transpose(-2, -1)) * (e // h) ** -0.5, dim=-1)
        keep, scale = keep_mask(weights.shape, p, weights.device)
        weights = weights * (keep.to(weights.dtype) * scale)
        out = (weights @ v).transpose(1, 2).reshape(b, t, e)
        return self.dropout1(attn.out_proj(out))


def transformer_encoder(
    d_model: int, heads: int, layers: int, ff: int, dropout: float
) -> nn.TransformerEncoder:
    """``layers`` post-norm :class:`EncoderLayer` s, batch first."""
    if d_model % heads:
        raise UserError(f"d_model={d_model} must be divisible by heads={heads}")
    layer = EncoderLayer(d_model, heads, dim_feedforward=ff, dropout=dropout, batch_first=True)
    return nn.TransformerEncoder(layer, layers, enable_nested_tensor=False)
