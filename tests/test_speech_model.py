"""Speech disentanglement model: shapes, sizes, batch independence, losses, pretrained adaptation."""

from __future__ import annotations

import pytest
import torch
import torch.nn.functional as F

from emogesture.errors import ConfigError
from emogesture.models import speech_losses as sl
from emogesture.models.speech import SpeechDisentangler, SpeechEncoding, SpeechModelConfig, flops_per_window
import emogesture.kernels as kernels
from emogesture.kernels import BLOCKED_ATTENTION_MIN_TOKENS, FLOAT32_TRAINING_ATTENTION, attention
from emogesture.models.vit import AudioViT, Mlp, ViTConfig


def _gen(seed: int) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


@pytest.fixture(scope="module")
def tiny() -> SpeechDisentangler:
    torch.manual_seed(0)
    return SpeechDisentangler(SpeechModelConfig.preset("tiny", num_speakers=5)).eval()


def test_tiny_output_shapes(tiny):
    x = torch.randn(2, 1024, 128, generator=_gen(1))
    out = tiny(x)
    for name in ("content", "emotion", "style"):
        assert getattr(out, name).shape == (2, 256)
    assert out.emotion_logits.shape == (2, 8)
    assert out.speaker_logits.shape == (2, 5)
    assert out.reconstruction.shape == (2, 1024, 128)
    enc = tiny.encode(x)
    assert isinstance(enc, SpeechEncoding) and enc.latents.content.shape == (2, 256)
    assert tiny.decode(enc.content, enc.emotion, enc.style).shape == (2, 1024, 128)
    with pytest.raises(ValueError, match=r"\[B, 1024, 128\]"):
        tiny.encode(torch.zeros(2, 128, 1024))
    # a separate emotion-encoder input changes the emotion outputs only
    other = tiny.encode(x, emotion_fbank=torch.randn(2, 1024, 128, generator=_gen(2)))
    assert torch.equal(other.content, enc.content) and torch.equal(other.style, enc.style)
    assert not torch.allclose(other.emotion, enc.emotion) and not torch.allclose(other.emotion_logits, enc.emotion_logits)


def test_emotion_speaker_context_starts_neutral_and_reads_the_style_detached(tiny):
    cfg = SpeechModelConfig.preset("tiny", num_speakers=5)
    cfg.emotion_speaker_context = True
    torch.manual_seed(0)
    model = SpeechDisentangler(cfg).eval()
    missing = model.load_state_dict(tiny.state_dict(), strict=False).missing_keys
    assert missing and all(k.startswith("emotion_context.") for k in missing)
    x = torch.randn(2, 1024, 128, generator=_gen(3))
    # zero at initialisation: the same outputs as the model without it
    assert torch.allclose(model.encode(x).emotion, tiny.encode(x).emotion, atol=1e-6)
    torch.nn.init.normal_(model.emotion_context[1].weight, std=0.1)
    enc = model.encode(x)
    assert not torch.allclose(enc.emotion, tiny.encode(x).emotion, atol=1e-4)
    # the style changes the emotion latent through the context, but emotion losses never train the style encoder
    enc.emotion_logits.sum().backward()
    assert model.emotion_context[1].weight.grad.abs().sum() > 0
    assert all(p.grad is None for p in model.style_encoder.parameters())


def test_vit_patch_grid_reads_the_fbank_as_a_frequency_by_time_image():
    cfg = ViTConfig(width=8, depth=1, heads=2)  # paper patching (16, stride 10), narrow for speed
    assert cfg.grid == (12, 101) and cfg.num_patches == 1212
    vit = AudioViT(cfg)
    x = torch.randn(2, 1024, 128, generator=_gen(8))
    assert vit.patch_embed.proj.weight.shape == (8, 1, 16, 16) and vit(x).shape == (2, 2 + 1212, 8)
    assert AudioViT(ViTConfig(width=8, depth=1, heads=2, distilled=False))(x).shape == (2, 1 + 1212, 8)
    image = x.transpose(1, 2).unsqueeze(1)  # [B, 1, 128 (freq), 1024 (time)]
    ref = vit.patch_embed.proj(image).flatten(2).transpose(1, 2)  # frequency-major 12 x 101
    assert torch.allclose(vit.patch_embed(x), ref, atol=1e-5)
    # patch (f=1, t=2) sees bins 10..25 of frames 20..35
    manual = (vit.patch_embed.proj.weight[:, 0] * image[0, 0, 10:26, 20:36]).sum((1, 2)) + vit.patch_embed.proj.bias
    assert torch.allclose(vit.patch_embed(x)[0, 1 * 101 + 2], manual, atol=1e-4)


@pytest.mark.parametrize("block_scores", [None, 2 * 64 * 300])
def test_blocked_bf16_attention_agrees_with_torch_and_is_taken_only_where_it_is_meant_to(block_scores, monkeypatch):
    g = torch.Generator().manual_seed(0)
    n = BLOCKED_ATTENTION_MIN_TOKENS + 37  # not a whole number of query blocks
    q, k, v = (torch.randn(2, 3, n, 16, generator=g) for _ in range(3))
    with torch.inference_mode():  # a CPU with AMX tiles takes torch's fused kernel
        monkeypatch.setattr(kernels, "amx_bf16", lambda: True)
        assert torch.equal(attention(*(x.bfloat16() for x in (q, k, v))),
                           F.scaled_dot_product_attention(*(x.bfloat16() for x in (q, k, v))))
    monkeypatch.setattr(kernels, "amx_bf16", lambda: False)  # the blocked path, whatever this CPU
    if block_scores:  # blocks smaller than one sample: one sample at a time, 2 of 3 heads, 64 queries
        monkeypatch.setattr(kernels, "ATTENTION_BLOCK_SCORES", block_scores)
        monkeypatch.setattr(kernels, "ATTENTION_QUERY_BLOCK", 64)
    exact = F.scaled_dot_product_attention(q, k, v)
    with torch.inference_mode():
        blocked = attention(q.bfloat16(), k.bfloat16(), v.bfloat16()).float()
        fused = F.scaled_dot_product_attention(q.bfloat16(), k.bfloat16(), v.bfloat16()).float()
    # as close to float32 as torch's own bf16 kernel, and not the same computation
    assert (blocked - exact).norm() / exact.norm() < 2 * max((fused - exact).norm() / exact.norm(), 1e-3)
    assert not torch.equal(blocked, fused)
    with torch.inference_mode():
        # strided views of one qkv projection, as the encoders pass them, and other leading shapes
        qkv = torch.randn(2, n, 3, 3, 16, generator=g).bfloat16().permute(2, 0, 3, 1, 4)
        strided = attention(qkv[0], qkv[1], qkv[2])
        assert torch.equal(strided, attention(*(x.contiguous() for x in qkv)))
        assert strided.transpose(1, 2).is_contiguous()  # the output projection reads it without a copy
        assert torch.equal(attention(qkv[0][0], qkv[1][0], qkv[2][0]), strided[0])
    # float32, short sequences and anything that needs gradients (at widths that stay bf16) go to
    # torch's kernel unchanged
    assert torch.equal(attention(q, k, v), exact)
    with torch.inference_mode():
        short = [x[:, :, :100].bfloat16() for x in (q, k, v)]
        assert torch.equal(attention(*short), F.scaled_dot_product_attention(*short))
    wide = [torch.randn(2, 3, n, 64, generator=g).bfloat16() for _ in range(3)]
    qg = wide[0].requires_grad_()
    out = attention(qg, wide[1], wide[2])
    assert torch.equal(out, F.scaled_dot_product_attention(qg, wide[1], wide[2]))
    out.float().sum().backward()
    assert qg.grad is not None and qg.grad.abs().sum() > 0


@pytest.mark.parametrize("amx", [False, True])
def test_bf16_training_attends_in_float32_below_the_threshold_and_in_bf16_above(amx, monkeypatch):
    monkeypatch.setattr(kernels, "amx_bf16", lambda: amx)  # with or without AMX tiles, whatever this CPU
    g = torch.Generator().manual_seed(1)
    tokens, width = FLOAT32_TRAINING_ATTENTION

    def inputs(n, e):
        return [torch.randn(2, 2, n, e, generator=g).bfloat16().requires_grad_() for _ in range(3)]

    for n, e in ((tokens - 1, width), (tokens, width // 2)):  # short, or narrow heads: float32
        q, k, v = inputs(n, e)
        out = attention(q, k, v)
        assert out.dtype == torch.bfloat16
        assert torch.equal(out, F.scaled_dot_product_attention(q.float(), k.float(), v.float()).bfloat16())
        assert not torch.equal(out, F.scaled_dot_product_attention(q, k, v))  # not the bf16 kernel
        out.float().square().sum().backward()
        assert all(x.grad is not None and x.grad.dtype == torch.bfloat16 and x.grad.abs().sum() > 0 for x in (q, k, v))
    q, k, v = inputs(tokens, width)  # the paper encoders' shapes keep torch's bf16 kernel (never the blocked path)
    out = attention(q, k, v)
    assert torch.equal(out, F.scaled_dot_product_attention(q, k, v))
    out.float().square().sum().backward()
    assert q.grad is not None and q.grad.abs().sum() > 0
    with torch.inference_mode():  # and without autograd nothing changes
        q, k, v = (x.detach() for x in inputs(tokens - 1, width))
        assert torch.equal(attention(q, k, v), F.scaled_dot_product_attention(q, k, v))


def test_patch_embedding_trains_in_float32_under_cpu_autocast():
    torch.manual_seed(0)
    vit = AudioViT(ViTConfig.preset("tiny"))
    x = torch.randn(2, vit.config.input_frames, vit.config.input_bins)
    exact = vit.patch_embed(x)
    with torch.autocast("cpu", dtype=torch.bfloat16):
        trained = vit.patch_embed(x)
        with torch.no_grad():
            inferred = vit.patch_embed(x)
    assert trained.dtype == torch.float32 and torch.equal(trained, exact)
    assert inferred.dtype == torch.bfloat16  # without gradients the bf16 convolution runs
    trained.square().sum().backward()
    assert vit.patch_embed.proj.weight.grad.dtype == torch.float32 and vit.patch_embed.proj.weight.grad.abs().sum() > 0


def test_mlp_gelu_in_place_without_autograd_gives_the_same_numbers():
    torch.manual_seed(0)
    mlp = Mlp(16, 64)
    x = torch.randn(2, 5, 16)
    reference = mlp.fc2(F.gelu(mlp.fc1(x)))
    with torch.inference_mode():
        assert torch.equal(mlp(x), reference)
    with torch.no_grad():
        assert torch.equal(mlp(x), reference)
        with torch.autocast("cpu", dtype=torch.bfloat16):  # bf16 hidden activations, as the encoders run
            assert torch.equal(mlp(x), mlp.fc2(F.gelu(mlp.fc1(x))))
    out = mlp(x)  # with autograd: the out-of-place GELU, and gradients reach fc1
    assert torch.equal(out, reference)
    out.sum().backward()
    assert mlp.fc1.weight.grad is not None and mlp.fc1.weight.grad.abs().sum() > 0


@pytest.mark.parametrize("pack", [False, True])
def test_mlp_with_bf16_weights_applies_the_gelu_inside_the_product(pack):
    from emogesture.runtime import _onednn_bf16, bf16_weights, linear_gelu

    torch.manual_seed(0)
    mlp = Mlp(16, 64)
    x = torch.randn(2, 5, 16)
    with torch.inference_mode(), bf16_weights("bf16", mlp, pack=pack), torch.autocast("cpu", dtype=torch.bfloat16):
        two_steps = mlp.fc2(F.gelu(mlp.fc1(x)))
        fused = linear_gelu(mlp.fc1, x)
        assert (fused is not None) == _onednn_bf16()  # a CPU with native bf16 (oneDNN)
        out = mlp(x)
    # the GELU of the float32 sums, rounded once: autocast's numbers to bf16 rounding
    assert out.dtype == torch.bfloat16 and torch.allclose(out.float(), two_steps.float(), rtol=2 ** -6, atol=2e-3)
    with torch.no_grad():  # float32 weights: no fused product
        assert linear_gelu(mlp.fc1, x) is None


def test_dropout_masks_keep_the_rate_and_the_expectation():
    from emogesture.kernels import Dropout

    drop = Dropout(0.1)
    x = torch.ones(400, 999, requires_grad=True)
    torch.manual_seed(3)
    y = drop(x)
    kept = y > 0
    # kept with probability 1 - 6554/65536; 399 600 draws: the rate's standard error is 0.0005
    assert abs(kept.float().mean().item() - (1 - 6554 / 65536)) < 0.002
    assert torch.allclose(y[kept], torch.tensor(65536 / (65536 - 6554)))
    assert abs(y.mean().item() - 1.0) < 0.003
    # the 16-bit draws cover their whole range evenly (none of the words' sign bits is used)
    rows = kept.reshape(-1, 3)  # three draws per 64-bit word
    assert all(abs(rows[:, i].float().mean().item() - 0.9) < 0.004 for i in range(3))
    y.sum().backward()
    assert torch.equal(x.grad, y.detach())  # the gradient is the scaled mask
    torch.manual_seed(3)
    assert torch.equal(drop(x), y)  # draws from the default generator: seeded runs repeat
    assert not torch.equal(drop(x), y)
    drop.eval()
    assert drop(x) is x
    with pytest.raises(ValueError):
        Dropout(1.5)


def test_tiny_patches_are_whole_spectrum_slices():
    cfg = ViTConfig.preset("tiny")
    assert cfg.kernel == (128, 8) and cfg.strides == (128, 8) and cfg.grid == (1, 128)
    vit = AudioViT(cfg)
    x = torch.randn(2, 1024, 128, generator=_gen(9))
    assert vit.patch_embed.proj.weight.shape == (cfg.width, 1, 128, 8)
    # token t sees every bin of frames 8t .. 8t + 7
    image = x.transpose(1, 2)  # [B, 128 (freq), 1024 (time)]
    manual = (vit.patch_embed.proj.weight[:, 0] * image[1, :, 40:48]).sum((1, 2)) + vit.patch_embed.proj.bias
    assert torch.allclose(vit.patch_embed(x)[1, 5], manual, atol=1e-4)
    with pytest.raises(ConfigError, match="smaller than a patch"):
        ViTConfig(patch=8, stride=8, patch_freq=256)


def _vit_flops(c: ViTConfig) -> int:
    """Matmul/conv/attention FLOPs of one window through one ViT, by hand."""
    n, w, h = c.num_prefix + c.num_patches, c.width, int(c.width * c.mlp_ratio)
    conv = 2 * c.num_patches * c.kernel[0] * c.kernel[1] * w
    block = 2 * n * (3 * w * w + w * w + 2 * w * h) + 2 * 2 * n * n * w
    return conv + c.depth * block


def test_paper_sizes_and_flops(capsys):
    cfg = SpeechModelConfig.preset("paper", num_speakers=30)
    with torch.device("meta"):
        model = SpeechDisentangler(cfg)
    counts = model.count_parameters()
    with capsys.disabled():
        print("\npaper parameters:", {k: f"{v / 1e6:.2f} M" for k, v in counts.items()})
    for name in ("content_encoder", "emotion_encoder", "style_encoder"):
        assert 85e6 <= counts[name] <= 88e6, (name, counts[name])
    assert counts["total"] == sum(v for k, v in counts.items() if k != "total")
    assert counts["emotion_encoder"] - counts["content_encoder"] == 768 * 8 + 8
    assert counts["style_encoder"] - counts["content_encoder"] == 768 * 30 + 30
    flops = flops_per_window(cfg)
    with capsys.disabled():
        print("paper GFLOPs/window:", {k: round(v / 1e9, 1) for k, v in flops.items()})
    head = 2 * 768 * 256
    assert flops["content_encoder"] == _vit_flops(cfg.encoder) + head
    assert 250e9 < flops["content_encoder"] < 275e9


def test_tiny_flops_match_hand_count(tiny):
    flops = tiny.flops_per_window()
    c = tiny.config
    assert flops["content_encoder"] == _vit_flops(c.encoder) + 2 * c.encoder.width * 256
    assert flops["emotion_encoder"] == flops["content_encoder"] + 2 * c.encoder.width * 8
    assert flops["total"] == sum(v for k, v in flops.items() if k != "total")
    assert flops["fusion"] > 0 and flops["decoder"] > 0


def test_fusion_and_decoder_keep_samples_apart(tiny):
    g = _gen(3)
    c, e, s = (torch.randn(4, 256, generator=g) for _ in range(3))
    fused = tiny.fusion(c, e, s)
    recon = tiny.decode(c, e, s)
    c2, e2, s2 = (v.clone() for v in (c, e, s))
    for v in (c2, e2, s2):
        v[1:] = torch.randn(3, 256, generator=g) * 5
    assert torch.allclose(tiny.fusion(c2, e2, s2)[0], fused[0], atol=1e-6)
    assert torch.allclose(tiny.decode(c2, e2, s2)[0], recon[0], atol=1e-5)
    assert not torch.allclose(tiny.fusion(c2, e2, s2)[1], fused[1], atol=1e-3)  # the others did change
    assert torch.allclose(tiny.fusion(c[:1], e[:1], s[:1]), fused[:1], atol=1e-6)  # batch of one agrees


def test_swap_index_maps_match_the_paper():
    assert sl.EMOTION_STYLE_PARTNER == (1, 0, 3, 2)
    assert sl.CONTENT_PARTNER == (2, 3, 0, 1)
    # supp. B.4, 1-based: j(k) = [(6 - k) mod 4] + 1 for emotion/style, [(1 + k) mod 4] + 1 for content
    assert tuple((6 - k) % 4 for k in range(1, 5)) == sl.EMOTION_STYLE_PARTNER
    assert tuple((1 + k) % 4 for k in range(1, 5)) == sl.CONTENT_PARTNER


# ---------------------------------------------------------------- pretrained weights


def test_encode_runs_only_the_encoders_of_the_latents_asked_for():
    from emogesture.models.speech import SpeechDisentangler

    torch.manual_seed(0)
    x = torch.randn(2, 1024, 128)
    for context in (False, True):
        cfg = SpeechModelConfig.preset("tiny", num_speakers=5)
        cfg.emotion_speaker_context = context
        model = SpeechDisentangler(cfg).eval()
        if context:
            torch.nn.init.normal_(model.emotion_context[1].weight)  # zero at initialisation
        with torch.no_grad():
            full = model.encode(x)
            emotion = model.encode(x, parts=("emotion",))
            style = model.encode(x, parts=("style",))
        torch.testing.assert_close(emotion.emotion, full.emotion)
        torch.testing.assert_close(emotion.emotion_logits, full.emotion_logits)
        torch.testing.assert_close(style.style, full.style)
        assert emotion.content.shape == (2, 0) and style.content.shape == (2, 0) and style.emotion.shape == (2, 0)
        assert (emotion.style.shape == (2, 256)) is context  # the emotion encoder reads the speaker context
    with pytest.raises(ValueError, match="unknown latent parts"):
        model.encode(x, parts=("prosody",))


def test_heard_bins_hide_the_top_of_the_spectrum():
    """``heard_bins``: the encoders hear the lowest bins only; what lies above them changes no latent."""
    torch.manual_seed(0)
    cfg = SpeechModelConfig.preset("tiny", num_speakers=3)
    full = SpeechDisentangler(cfg).eval()
    limited = SpeechDisentangler(SpeechModelConfig.preset("tiny", num_speakers=3)).eval()
    limited.load_state_dict(full.state_dict())
    limited.config.heard_bins = 96
    x = torch.randn(2, 1024, 128, generator=_gen(3))
    y = x.clone()
    y[..., 96:] = torch.randn(2, 1024, 32, generator=_gen(4))
    with torch.no_grad():
        a, b = limited.encode(x), limited.encode(y)
        c, d = full.encode(x), full.encode(y)
    for name in ("content", "emotion", "style"):
        assert torch.equal(getattr(a, name), getattr(b, name)), name
        assert not torch.allclose(getattr(c, name), getattr(d, name)), name
    with pytest.raises(ConfigError, match="heard_bins 129"):
        SpeechModelConfig(heard_bins=129)
