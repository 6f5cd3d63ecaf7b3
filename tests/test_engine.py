"""Training engine helpers: the weight average."""

from __future__ import annotations

import pytest
import torch
from torch import nn

from emogesture.errors import EmogestureError
from emogesture.train.engine import make_ema, update_ema


def test_weight_average_follows_the_formula_with_warm_up():
    torch.manual_seed(0)
    model = nn.Sequential(nn.Linear(3, 4), nn.BatchNorm1d(4))
    ema = make_ema(model, 0.9)
    assert all(not p.requires_grad for p in ema.parameters())
    assert make_ema(model, 0.0) is None
    with pytest.raises(EmogestureError, match="ema_decay"):
        make_ema(model, 1.0)
    start = [p.clone() for p in ema.parameters()]
    with torch.no_grad():
        for p in model.parameters():
            p.add_(1.0)
        model[1].running_mean.fill_(2.0)
    update_ema(ema, model, 0.9, step=0)  # warm-up: d = min(0.9, 1/10) = 0.1
    for e, s, p in zip(ema.parameters(), start, model.parameters()):
        assert torch.allclose(e, 0.1 * s + 0.9 * p)
    update_ema(ema, model, 0.9, step=1000)  # d = 0.9
    for e, s, p in zip(ema.parameters(), start, model.parameters()):
        assert torch.allclose(e, 0.9 * (0.1 * s + 0.9 * p) + 0.1 * p)
    assert torch.equal(ema[1].running_mean, model[1].running_mean)
    assert any(not torch.equal(e, p) for e, p in zip(ema.parameters(), model.parameters()))
