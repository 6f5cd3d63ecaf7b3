"""The CPU speed-ups' off switch and their fallback to plain torch (emogesture.runtime)."""

from __future__ import annotations

from dataclasses import replace

import pytest
import torch
from torch import nn

from emogesture import kernels, runtime
from emogesture.kernels import attention


@pytest.fixture(autouse=True)
def environment_decides(monkeypatch):
    monkeypatch.delenv(runtime.ACCELERATION_ENV, raising=False)
    runtime.set_acceleration(None)
    yield
    runtime.set_acceleration(None)


@pytest.mark.parametrize("value, on", [("1", True), ("0", False), ("off", False), ("False", False), ("no", False),
                                       ("yes", True)])
def test_the_environment_switches_the_speed_ups(monkeypatch, value, on):
    monkeypatch.setenv(runtime.ACCELERATION_ENV, value)
    assert runtime.acceleration_enabled() is on
    runtime.set_acceleration(not on)  # the process's own choice wins
    assert runtime.acceleration_enabled() is (not on)


def test_without_the_private_ops_or_switched_off_nothing_calls_them(monkeypatch):
    """Simulate a torch without oneDNN's private ops, and a CPU where they would otherwise run: packing,
    the fused Linear + GELU and every packed product go to plain torch, with the same result."""
    monkeypatch.setattr(runtime, "_onednn_bf16_native", lambda: True)
    called = []

    def missing(*args, **kwargs):
        called.append(args)
        raise AssertionError("a private op was called")

    monkeypatch.setattr(runtime, "_onednn_linear", missing)
    monkeypatch.setattr(runtime, "PRIVATE_OPS", ("_an_op_this_torch_does_not_have",))
    assert not runtime.private_ops_available() and not runtime.packs_bf16_weights("cpu")
    torch.manual_seed(0)
    layer = nn.Sequential(nn.Linear(8, 16))
    x = torch.randn(4, 8)
    with torch.no_grad():
        want = layer(x.to(torch.bfloat16).float())
        runtime.hold_bf16_weights("bf16", layer, pack=True)
        assert "packed_weight" not in vars(layer[0])
        assert runtime.linear_gelu(layer[0], x) is None
        torch.testing.assert_close(layer(x.to(torch.bfloat16)).float(), want, atol=0.05, rtol=0.02)
    monkeypatch.setattr(runtime, "PRIVATE_OPS", ())  # the ops are there, but switched off
    runtime.set_acceleration(False)
    assert runtime.private_ops_available() and not runtime.packs_bf16_weights("cpu")
    assert runtime.linear_gelu(layer[0], x) is None and not called


def test_a_private_op_that_fails_falls_back_to_the_plain_product(monkeypatch):
    """A packed layer whose private op raises (a torch where it changed) gives the plain bf16 product."""
    monkeypatch.setattr(runtime, "_onednn_bf16_native", lambda: True)
    monkeypatch.setattr(runtime, "PRIVATE_OPS", ())

    def changed(*args, **kwargs):
        raise RuntimeError("mkldnn::_linear_pointwise() expected 7 arguments")

    monkeypatch.setattr(runtime, "_onednn_linear", changed)
    torch.manual_seed(1)
    layer = nn.Linear(8, 16)
    layer.weight = nn.Parameter(layer.weight.detach().to(torch.bfloat16), requires_grad=False)
    layer.bias = nn.Parameter(layer.bias.detach().to(torch.bfloat16), requires_grad=False)
    layer.packed_weight = layer.weight  # what the packing would have left
    x = torch.randn(4, 8)
    with torch.no_grad():
        got = runtime._packed_linear(layer, x)
        torch.testing.assert_close(got, nn.functional.linear(x.to(torch.bfloat16), layer.weight, layer.bias))
        assert runtime.linear_gelu(layer, x) is None


def test_switched_off_the_attention_is_torchs_kernel(monkeypatch):
    torch.manual_seed(2)
    q, k, v = (torch.randn(1, 2, 300, 16).to(torch.bfloat16) for _ in range(3))
    monkeypatch.setattr(kernels, "amx_bf16", lambda: False)  # the blocked kernel is the one off AMX
    with torch.no_grad():
        blocked = attention(q, k, v)
        runtime.set_acceleration(False)
        plain = attention(q, k, v)
        torch.testing.assert_close(plain, torch.nn.functional.scaled_dot_product_attention(q, k, v))
        torch.testing.assert_close(blocked.float(), plain.float(), atol=0.03, rtol=0.05)


def test_the_bundled_model_switched_off_moves_as_switched_on_within_bf16_drift():
    """bf16 generation of a demo clip with the speed-ups and with plain torch: the same animation up to
    bf16 rounding (the tolerance of the fp32 / bf16 comparison in test_bundled_model)."""
    import numpy as np

    from emogesture.assets import DEMO_CLIPS
    from emogesture.motion import SkeletonBody
    from emogesture.pipeline.generate import GesturePipeline

    body = SkeletonBody()

    def joints(seq):
        with torch.no_grad():
            return body(torch.from_numpy(seq.poses), torch.from_numpy(seq.trans)).numpy()

    runs = []
    for enabled in (True, False):
        runtime.set_acceleration(enabled)
        pipe = GesturePipeline.from_run(None, precision="bf16")
        wave = pipe.load_speech(DEMO_CLIPS / "talk.flac")
        runs.append(joints(pipe.generate(wave, seed=0, generation=replace(pipe.generation, seam_candidates=1))[0]))
    mm = np.linalg.norm(runs[0] - runs[1], axis=-1) * 1000
    assert mm.mean() < 2 and mm.max() < 20, (mm.mean(), mm.max())
