"""The encoder layer with the cheaper attention dropout (learn/models/attention.py) is
torch's TransformerEncoderLayer in everything but how its attention-dropout mask is drawn:
the same weights give the same output without dropout, the same expectation with it,
and the same state-dict keys (saved cnn_transformer and sefusion runs load)."""

from __future__ import annotations

import torch
from torch import nn

from tactile_studio.learn.models import MODELS
from tactile_studio.learn.models.attention import EncoderLayer, keep_mask


def _pair(dropout: float) -> tuple[EncoderLayer, nn.TransformerEncoderLayer]:
    torch.manual_seed(0)
    ours = EncoderLayer(16, 4, dim_feedforward=32, dropout=dropout, batch_first=True)
    theirs = nn.TransformerEncoderLayer(16, 4, dim_feedforward=32, dropout=dropout,
                                        batch_first=True)
    theirs.load_state_dict(ours.state_dict())  # the same keys, the same weights
    return ours, theirs


def test_same_output_as_torch_layer_in_eval_and_in_training_without_dropout():
    x = torch.randn(5, 11, 16)
    for dropout, train in ((0.3, False), (0.0, True)):
        ours, theirs = _pair(dropout)
        ours.train(train)
        theirs.train(train)
        with torch.no_grad():
            torch.testing.assert_close(ours(x), theirs(x), atol=1e-5, rtol=1e-5)


def test_hand_written_attention_is_torchs_when_nothing_is_dropped():
    """The training path itself (taken only with dropout) computes torch's attention:
    with a keep-everything mask its output and gradients are the torch layer's."""
    ours, theirs = _pair(1e-9)  # rounds to no dropped weight, but takes our path
    for layer in (ours, theirs):
        layer.train()
        layer.dropout.p = layer.dropout1.p = layer.dropout2.p = 0.0
    x = torch.randn(4, 9, 16)
    a, b = ours(x), theirs(x)
    torch.testing.assert_close(a, b, atol=1e-5, rtol=1e-5)
    a.square().sum().backward()
    b.square().sum().backward()
    for (name, pa), (_, pb) in zip(ours.named_parameters(), theirs.named_parameters()):
        torch.testing.assert_close(pa.grad, pb.grad, atol=1e-5, rtol=1e-4, msg=name)


def test_attention_dropout_keeps_the_expectation_of_the_output():
    """Averaged over many masks, the training output (attention dropout only) equals the
    output without dropout: the kept weights are scaled by 1 / keep probability."""
    ours, _ = _pair(0.3)
    ours.train()
    ours.dropout.p = ours.dropout1.p = ours.dropout2.p = 0.0  # only the attention's
    torch.manual_seed(1)
    x = torch.randn(2, 7, 16)
    ours.self_attn.dropout = 0.0
    with torch.no_grad():
        plain = ours._sa_block(x, None, None)
        ours.self_attn.dropout = 0.3
        draws = torch.stack([ours._sa_block(x, None, None) for _ in range(4000)])
    assert not torch.allclose(draws[0], plain, atol=1e-3)  # dropout does act
    torch.testing.assert_close(draws.mean(0), plain, atol=0.02, rtol=0.0)


def test_keep_mask_drops_each_element_with_probability_p_in_every_lane():
    torch.manual_seed(2)
    keep, scale = keep_mask((400, 1000), 0.3)
    assert keep.shape == (400, 1000) and keep.dtype == torch.bool
    assert scale == 65536 / (65536 - round(0.3 * 65536))
    # each of the four 16-bit lanes of a 64-bit draw is a fair coin of the same bias
    lanes = keep.reshape(-1, 4).float().mean(0)
    assert torch.allclose(lanes, torch.full((4,), 0.7), atol=0.004), lanes
    assert keep_mask((3, 5), 0.0)[0].all()
    torch.manual_seed(3)
    first = keep_mask((64,), 0.5)[0]
    torch.manual_seed(3)
    assert torch.equal(first, keep_mask((64,), 0.5)[0])  # torch's seed decides


def test_transformer_models_keep_their_state_dict_keys():
    """A cnn_transformer / sefusion run saved before the layer changed still loads."""
    for name in ("cnn_transformer", "sefusion"):
        model = MODELS[name].build(5, 3, (6, 6), "full")
        encoder = next(m for m in model.modules() if isinstance(m, nn.TransformerEncoder))
        assert isinstance(encoder.layers[0], EncoderLayer)
        torch.manual_seed(0)
        plain = nn.TransformerEncoder(
            nn.TransformerEncoderLayer(encoder.layers[0].self_attn.embed_dim,
                                       encoder.layers[0].self_attn.num_heads,
                                       dim_feedforward=encoder.layers[0].linear1.out_features,
                                       batch_first=True),
            len(encoder.layers), enable_nested_tensor=False)
        assert plain.state_dict().keys() == encoder.state_dict().keys()
        encoder.load_state_dict(plain.state_dict())  # an old run's weights load


def test_dropout_is_nn_dropout_in_eval_and_keeps_the_expectation_in_training():
    from tactile_studio.learn.models.attention import Dropout

    layer = Dropout(0.3)
    x = torch.randn(6, 8, 5)
    layer.eval()
    assert torch.equal(layer(x), x)
    layer.train()
    torch.manual_seed(4)
    draws = torch.stack([layer(x) for _ in range(3000)])
    dropped = (draws == 0).float().mean()
    assert abs(float(dropped) - 0.3) < 0.005
    ratio = draws.mean(0) / x  # each ~ 1 +- 0.012 (3000 draws): 5 standard errors
    torch.testing.assert_close(ratio, torch.ones_like(x), atol=0.06, rtol=0.0)


def test_dropout_drops_the_same_cells_whatever_the_memory_layout():
    """mts3d trains with channels-last feature maps: its dropout must not depend on them."""
    from tactile_studio.learn.models.attention import Dropout

    layer = Dropout(0.5).train()
    x = torch.randn(2, 4, 3, 5, 5)
    torch.manual_seed(5)
    a = layer(x)
    torch.manual_seed(5)
    b = layer(x.contiguous(memory_format=torch.channels_last_3d))
    assert torch.equal(a, b)
