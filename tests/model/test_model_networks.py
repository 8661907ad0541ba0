import math

import pytest
import torch
from torch import nn

from hybrid_sysid.model import FastCNN, PaperCNN

from helpers.paper_prior import P_MAX, P_MIN, P_SCALE


def test_paper_cnn_layers_match_the_paper():
    # sec. 2.4: conv 100 x k50 on 2 channels, conv 100 x k10, flatten, dense 100, 10, 2 ('valid' convolutions)
    window = 500
    length = window - 50 + 1 - 10 + 1
    expected = [
        (100, 2, 50),
        (100,),
        (100, 100, 10),
        (100,),
        (100, 100 * length),
        (100,),
        (10, 100),
        (10,),
        (2, 10),
        (2,),
    ]
    model = PaperCNN(P_SCALE, window=window)
    assert [tuple(p.shape) for p in model.parameters()] == expected
    n_hand = (2 * 50 + 1) * 100 + (100 * 10 + 1) * 100 + (100 * 442 + 1) * 100 + (100 + 1) * 10 + (10 + 1) * 2
    assert sum(p.numel() for p in model.parameters()) == n_hand == 4_531_332


def test_paper_cnn_output_is_positive_and_scaled():
    torch.manual_seed(0)
    model = PaperCNN(P_SCALE, window=200)
    out = model(torch.randn(5, 2, 200))
    assert out.shape == (5, 2) and (out >= 0).all()
    last = model.net[-1]
    with torch.no_grad():  # a constant last layer shows the abs and the label scale: |(-1, 2)| * p_scale
        last.weight.zero_()
        last.bias.copy_(torch.tensor([-1.0, 2.0]))
    assert torch.allclose(model(torch.randn(3, 2, 200)), torch.tensor([[P_SCALE[0], 2 * P_SCALE[1]]] * 3))


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"window": 40}, "window = 40"),
        ({"p_scale": (1.0, -2.0)}, "p_scale"),
        ({"activation": "gelu"}, "activation = 'gelu'.*tanh"),
    ],
)
def test_paper_cnn_rejects_bad_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        PaperCNN(**({"p_scale": P_SCALE} | kwargs))


def test_fast_cnn_output_stays_inside_the_widened_prior():
    torch.manual_seed(0)
    model = FastCNN(P_MIN, P_MAX, channels=16, n_layers=3, margin=0.1)
    out = model(1e3 * torch.randn(7, 2, 500))
    assert out.shape == (7, 2)
    for j in range(2):
        widen = (P_MAX[j] / P_MIN[j]) ** 0.1  # margin is a fraction of the log range, on each side
        lo, hi = P_MIN[j] / widen, P_MAX[j] * widen
        assert ((out[:, j] > lo) & (out[:, j] < hi)).all()
        with torch.no_grad():  # a saturated head gives the bound itself
            model.head.weight.zero_()
            model.head.bias.fill_(50.0)
        assert torch.allclose(model(torch.randn(2, 2, 500))[:, j], torch.tensor(hi), rtol=1e-5)


def test_fast_cnn_is_blind_to_the_overall_amplitude():
    # the per-window body-RMS scale: a class E road is a scaled class A road as far as p is concerned
    torch.manual_seed(0)
    model = FastCNN(P_MIN, P_MAX, channels=8, n_layers=2).eval()
    x = torch.randn(4, 2, 300)
    assert torch.allclose(model(x), model(16.0 * x), rtol=1e-5)


def test_fast_cnn_layers():
    model = FastCNN(P_MIN, P_MAX, channels=32, n_layers=4, kernel_size=5)
    convs = [m for m in model.modules() if isinstance(m, nn.Conv1d)]
    assert [tuple(c.weight.shape) for c in convs] == [(32, 3, 5)] + [(32, 32, 5)] * 3
    assert model.head.in_features == 32 and model.head.out_features == 2
    assert [c.stride for c in convs] == [(2,)] * 4  # default downsampling: stride-2 convolutions
    assert not any(isinstance(m, nn.MaxPool1d) for m in model.modules())
    pooled = FastCNN(P_MIN, P_MAX, channels=32, n_layers=4, kernel_size=5, downsample="pool")
    assert [c.stride for c in pooled.modules() if isinstance(c, nn.Conv1d)] == [(1,)] * 4
    assert sum(isinstance(m, nn.MaxPool1d) for m in pooled.modules()) == 4


@pytest.mark.parametrize("downsample", ["stride", "pool"])
def test_fast_cnn_halves_the_sequence_per_layer(downsample):
    # each layer halves the length (500 -> 250 -> 125 -> 63|62), so the receptive field is the same either way
    model = FastCNN(P_MIN, P_MAX, n_layers=3, downsample=downsample).eval()
    lengths = []
    hook = lambda m, i, o: lengths.append(o.shape[-1])  # noqa: E731
    for m in model.features:
        if isinstance(m, nn.ReLU):
            m.register_forward_hook(hook)
    model(torch.randn(2, 2, 500))
    expected = [250, 125, 63] if downsample == "stride" else [500, 250, 125]  # pool comes after the ReLU
    assert lengths == expected


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"channels": 0}, "channels = 0"),
        ({"downsample": "avg"}, "downsample = 'avg'"),
        ({"n_layers": 1.5}, "n_layers = 1.5"),
        ({"kernel_size": 4}, "kernel_size = 4.*odd"),
        ({"margin": -0.1}, r"margin = -0.1.*\[0, 1\]"),
        ({"p_min": (20.0, 495.0)}, "p_min"),
        ({"bn_momentum": 0.0}, r"bn_momentum = 0.*\(0, 1\]"),
    ],
)
def test_fast_cnn_rejects_bad_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        FastCNN(**({"p_min": P_MIN, "p_max": P_MAX} | kwargs))


def test_models_are_reproducible_from_the_seed():
    x = torch.randn(3, 2, 500)
    outs = []
    for _ in range(2):
        torch.manual_seed(3)
        outs.append((FastCNN(P_MIN, P_MAX, channels=8)(x), PaperCNN(P_SCALE)(x)))
    assert all(torch.equal(a, b) for a, b in zip(*outs))
    assert math.isfinite(outs[0][1].sum().item())


@pytest.mark.parametrize(
    "make", [lambda: FastCNN(P_MIN, P_MAX, channels=8), lambda: PaperCNN(P_SCALE, window=120)], ids=["fast", "paper"]
)
def test_models_run_under_deterministic_algorithms(make):
    was = torch.are_deterministic_algorithms_enabled()
    torch.use_deterministic_algorithms(True)  # raises on any op without a deterministic implementation
    try:
        torch.manual_seed(0)
        model = make()
        model(torch.randn(4, 2, 120)).sum().backward()
    finally:
        torch.use_deterministic_algorithms(was)
