"""The Transformer encoder of cnn_transformer and sefusion, with a cheaper attention dropout.

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
takes torch's own path unchanged.
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


class EncoderLayer(nn.TransformerEncoderLayer):
    """``nn.TransformerEncoderLayer`` (post-norm, batch first) whose training-time
    self-attention dropout uses :func:`keep_mask` (see the module doc)."""

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
