"""Speech disentanglement model: shapes, sizes, batch independence, losses, pretrained adaptation."""

from __future__ import annotations

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from emogesture.errors import ConfigError, EmogestureError, InputFileError
from emogesture.models import speech_losses as sl
from emogesture.models.pretrained import (
    adapt_ast_checkpoint, adapt_deit_to_audio, init_encoder_from_pretrained, load_deit_state_dict,
)
from emogesture.models.speech import SpeechDisentangler, SpeechEncoding, SpeechModelConfig, flops_per_window
from emogesture.models.speech_losses import SpeechLossConfig, speech_losses
import emogesture.models.vit as vit_module
from emogesture.models.vit import (BLOCKED_ATTENTION_MIN_TOKENS, FLOAT32_TRAINING_ATTENTION, AudioViT, Mlp,
                                  ViTConfig, attention)


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
        monkeypatch.setattr(vit_module, "amx_bf16", lambda: True)
        assert torch.equal(attention(*(x.bfloat16() for x in (q, k, v))),
                           F.scaled_dot_product_attention(*(x.bfloat16() for x in (q, k, v))))
    monkeypatch.setattr(vit_module, "amx_bf16", lambda: False)  # the blocked path, whatever this CPU
    if block_scores:  # blocks smaller than one sample: one sample at a time, 2 of 3 heads, 64 queries
        monkeypatch.setattr(vit_module, "ATTENTION_BLOCK_SCORES", block_scores)
        monkeypatch.setattr(vit_module, "ATTENTION_QUERY_BLOCK", 64)
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
    monkeypatch.setattr(vit_module, "amx_bf16", lambda: amx)  # with or without AMX tiles, whatever this CPU
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
    from emogesture.models.vit import Dropout

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


def test_fused_l1_matches_autograd_reference():
    g = _gen(10)
    pred = torch.randn(2, 3, 4, 5, 6, generator=g, requires_grad=True)
    target = torch.randn(2, 1, 4, 5, 6, generator=g)
    w = torch.tensor([1.0, 2.0, 0.5])
    ref = (pred - target).abs().mean(dim=(0, 2, 3, 4))
    (ref_grad,) = torch.autograd.grad((ref * w).sum(), pred)
    got = sl._MeanAbsError.apply(pred, target)
    (got_grad,) = torch.autograd.grad((got * w).sum(), pred)
    assert torch.allclose(got, ref) and torch.allclose(got_grad, ref_grad)


class StubModel:
    """encode reads rows 0/1/2 of a window as content/emotion/style; decode writes them back.

    Emotion logits are the first 8 entries of the emotion row, speaker logits the first 5 of the style row.
    """

    def __init__(self, noise: float = 0.0):
        self.noise = noise
        self.decoded: list[int] = []

    def encode(self, x):
        e, s = x[:, 1], x[:, 2]
        return SpeechEncoding(x[:, 0], e, s, e[:, :8], s[:, :5])

    def decode(self, c, e, s):
        self.decoded.append(c.shape[0])
        y = torch.stack([c, e, s], dim=1)
        return y * (1 + self.noise) + self.noise  # imperfect, and independent of the batch layout


def _toy_quadruples(b: int = 3):
    """fbank [B, 4, 3, 16] consistent with (c1 s1, c2 s1, c1 s2, c2 s2), one emotion per quadruple."""
    g = _gen(4)
    emotion = torch.randint(0, 8, (b,), generator=g)
    speaker = torch.randint(0, 5, (b, 2), generator=g)
    content = torch.randn(b, 2, 16, generator=g)
    # each speaker voices the shared emotion in its own way (entries 8:), so swapping emotion latents is
    # only harmless between windows of the same speaker: a wrong partner map shows up as a positive loss
    emo_vec = torch.cat([50 * F.one_hot(emotion, 8).float()[:, None].expand(b, 2, 8),
                         torch.randn(b, 2, 8, generator=g)], 2)
    sty_vec = torch.cat([50 * F.one_hot(speaker, 5).float(), torch.randn(b, 2, 11, generator=g)], 2)
    rows = []
    for ci, si in ((0, 0), (1, 0), (0, 1), (1, 1)):
        rows.append(torch.stack([content[:, ci], emo_vec[:, si], sty_vec[:, si]], dim=1))
    fbank = torch.stack(rows, dim=1)
    return fbank, emotion, speaker[:, [0, 0, 1, 1]]


TERMS = ("self_recon", "content", "emotion", "style", "cross_emotion", "cross_style", "cross_content")


def _zero_terms(out):
    return {k for k in TERMS if float(out[k]) < 1e-6}


def test_losses_vanish_for_a_perfect_model():
    fbank, emotion, speaker = _toy_quadruples()
    out = speech_losses(StubModel(), fbank, emotion, speaker)
    assert set(out) == set(TERMS) | {"total"}
    assert _zero_terms(out) == set(TERMS) and float(out["total"]) < 1e-5


@pytest.mark.parametrize(
    "row, window, positive",
    [
        (1, 1, {"cross_emotion"}),  # a2's emotion latent differs from a1's: only the emotion swap notices
        (2, 1, {"cross_style"}),  # a2's style latent differs from a1's (same speaker): only the style swap
        (0, 2, {"content", "cross_content"}),  # a3's content differs from a1's
    ],
)
def test_each_swap_term_uses_its_partner(row, window, positive):
    fbank, emotion, speaker = _toy_quadruples()
    fbank[:, window, row, 8:] += 1.0  # outside the logit entries: labels stay right
    out = speech_losses(StubModel(), fbank, emotion, speaker)
    assert set(TERMS) - _zero_terms(out) == positive


def test_terms_are_positive_for_imperfect_models():
    fbank, emotion, speaker = _toy_quadruples()
    out = speech_losses(StubModel(noise=0.1), fbank, emotion, speaker)
    assert set(TERMS) - _zero_terms(out) == {"self_recon", "cross_emotion", "cross_style", "cross_content"}
    out = speech_losses(StubModel(), fbank, (emotion + 1) % 8, speaker)
    assert set(TERMS) - _zero_terms(out) == {"emotion"}
    out = speech_losses(StubModel(), fbank, emotion, (speaker + 1) % 5)
    assert set(TERMS) - _zero_terms(out) == {"style"}


@pytest.mark.parametrize("term", TERMS)
def test_a_switched_off_term_is_absent_and_not_computed(term, monkeypatch):
    fbank, emotion, speaker = _toy_quadruples()
    fbank[:, 2, 0] += 0.5  # make L_con and L_xcon positive too
    ce_calls = []
    real_ce = F.cross_entropy
    monkeypatch.setattr(F, "cross_entropy", lambda *a, **k: ce_calls.append(1) or real_ce(*a, **k))
    stub = StubModel(noise=0.1)
    full = speech_losses(stub, fbank, (emotion + 1) % 8, (speaker + 1) % 5)
    assert all(float(full[t]) > 1e-3 for t in TERMS)
    ce_calls.clear()
    stub.decoded.clear()
    out = speech_losses(stub, fbank, (emotion + 1) % 8, (speaker + 1) % 5, SpeechLossConfig(**{term: 0.0}))
    assert term not in out
    expected = sum(float(full[t]) for t in TERMS if t != term)
    assert float(out["total"]) == pytest.approx(expected, rel=1e-5)
    n_recon = sum(t in sl.RECONSTRUCTIONS for t in TERMS if t != term)
    assert stub.decoded == [n_recon * 4 * fbank.shape[0]]  # one batched decode of the active swaps
    assert len(ce_calls) == (1 if term in ("emotion", "style") else 2)


def test_configs_round_trip_and_reject_unknown_keys():
    from emogesture.config import from_dict, to_dict
    from emogesture.errors import ConfigError

    for name in ("paper", "tiny"):
        cfg = SpeechModelConfig.preset(name, num_speakers=7)
        assert from_dict(SpeechModelConfig, to_dict(cfg)) == cfg
    with pytest.raises(ConfigError, match="unknown key"):
        from_dict(SpeechModelConfig, {"encoder": {"widht": 3}})
    with pytest.raises(ConfigError, match="divisible"):
        ViTConfig(width=100, heads=3)
    assert from_dict(SpeechLossConfig, {"style": 0}).active() == [t for t in TERMS if t != "style"]


def test_loss_weights_and_presets():
    fbank, emotion, speaker = _toy_quadruples()
    stub = StubModel(noise=0.1)
    ref = speech_losses(stub, fbank, emotion, speaker)
    out = speech_losses(stub, fbank, emotion, speaker, SpeechLossConfig(self_recon=2.0, cross_style=0.5))
    expected = sum(float(ref[t]) for t in TERMS) + float(ref["self_recon"]) - 0.5 * float(ref["cross_style"])
    assert float(out["total"]) == pytest.approx(expected, rel=1e-5)
    assert set(SpeechLossConfig.preset("emotion_only").active()) == set(TERMS) - {"style", "cross_style"}
    assert set(SpeechLossConfig.preset("style_only").active()) == set(TERMS) - {"emotion", "cross_emotion"}
    assert SpeechLossConfig.preset("full").active() == list(TERMS)
    assert SpeechLossConfig.preset("adversarial").active() == list(TERMS) + ["latent_classes", "adversarial"]


def test_latent_classes_read_each_latent_own_factor():
    torch.manual_seed(3)
    model = SpeechDisentangler(SpeechModelConfig.preset("tiny", num_speakers=5))
    fbank = torch.randn(2, 4, 1024, 128, generator=_gen(7)) * 0.5
    emotion, speaker = torch.tensor([3, 5]), torch.tensor([[0, 0, 4, 4], [1, 1, 2, 2]])
    out = speech_losses(model, fbank, emotion, speaker, SpeechLossConfig(**{t: 0.0 for t in TERMS}, latent_classes=1.0))
    assert set(out) == {"latent_classes", "total"}
    enc = model.encode(fbank.reshape(8, 1024, 128))
    expected = (F.cross_entropy(model.emotion_from_latent(sl._standardise(enc.emotion)), emotion.repeat_interleave(4))
                + F.cross_entropy(model.speaker_from_latent(sl._standardise(enc.style)), speaker.reshape(-1)))
    assert float(out["latent_classes"].detach()) == pytest.approx(float(expected.detach()), rel=1e-5)
    out["total"].backward()
    assert model.emotion_encoder.latent_head[1].weight.grad.abs().sum() > 0
    assert model.style_encoder.latent_head[1].weight.grad.abs().sum() > 0
    assert model.content_encoder.latent_head[1].weight.grad is None
    standard = sl._standardise(torch.randn(16, 4) * 3 + 2)
    assert torch.allclose(standard.mean(0), torch.zeros(4), atol=1e-5)
    assert torch.allclose(standard.std(0), torch.ones(4), atol=1e-3)


def test_adversaries_learn_to_read_and_encoders_learn_to_hide():
    """The adversaries' heads get gradient only from their own cross-entropy (on detached latents); the
    encoders only from the confusion term, which is smallest when the adversaries' output is uniform."""
    torch.manual_seed(2)
    model = SpeechDisentangler(SpeechModelConfig.preset("tiny", num_speakers=5))
    fbank = torch.randn(2, 4, 1024, 128, generator=_gen(6)) * 0.5
    emotion, speaker = torch.tensor([3, 5]), torch.tensor([[0, 0, 4, 4], [1, 1, 2, 2]])
    only = SpeechLossConfig(**{t: 0.0 for t in TERMS}, adversarial=1.0)
    out = speech_losses(model, fbank, emotion, speaker, only)
    assert set(out) == {"adversarial", "adversary_ce", "total"}
    # untrained adversaries guess near chance: CE ≈ log 5 + log 8
    assert float(out["adversary_ce"]) == pytest.approx(np.log(5) + np.log(8), rel=0.2)
    model.zero_grad()
    out["total"].backward()
    head = model.speaker_adversary.weight.grad
    enc = model.emotion_encoder.latent_head[1].weight.grad
    assert head is not None and head.abs().sum() > 0 and enc is not None and enc.abs().sum() > 0
    assert model.emotion_encoder.classifier.weight.grad is None or model.emotion_encoder.classifier.weight.grad.abs().sum() == 0
    # the heads' gradient equals that of their cross-entropy alone
    latent = sl._standardise(model.encode(fbank.reshape(8, 1024, 128)).emotion.detach())
    model.speaker_adversary.zero_grad()
    torch.nn.functional.cross_entropy(model.speaker_adversary(latent), speaker.reshape(-1)).backward()
    assert torch.allclose(head, model.speaker_adversary.weight.grad, atol=1e-6)
    # the confusion part is minimal (log K) for uniform predictions
    from emogesture.models.speech_losses import _adversarial_terms

    zero = torch.nn.Linear(256, 8)
    torch.nn.init.zeros_(zero.weight), torch.nn.init.zeros_(zero.bias)
    _, confusion = _adversarial_terms([(zero, torch.randn(4, 256), torch.tensor([0, 1, 2, 3]))])
    assert float(confusion) == pytest.approx(np.log(8), abs=1e-6)


def test_gradients_reach_all_three_encoders():
    torch.manual_seed(1)
    model = SpeechDisentangler(SpeechModelConfig.preset("tiny", num_speakers=5))
    g = _gen(5)
    fbank = torch.randn(1, 4, 1024, 128, generator=g) * 0.5
    out = speech_losses(model, fbank, torch.tensor([3]), torch.tensor([[0, 0, 4, 4]]))
    out["total"].backward()
    for name in ("content_encoder", "emotion_encoder", "style_encoder", "fusion", "decoder"):
        for pname, p in getattr(model, name).named_parameters():
            assert p.grad is not None and p.grad.abs().sum() > 0, f"{name}.{pname} gets no gradient"


# ---------------------------------------------------------------- pretrained weights


def _synthetic_deit(depth: int = 2, width: int = 768) -> dict[str, torch.Tensor]:
    """Random tensors in timm's deit_base_distilled_patch16_384 layout (reduced depth)."""
    g = _gen(6)
    shapes = {"patch_embed.proj.weight": [width, 3, 16, 16], "patch_embed.proj.bias": [width],
              "cls_token": [1, 1, width], "dist_token": [1, 1, width], "pos_embed": [1, 2 + 24 * 24, width],
              "norm.weight": [width], "norm.bias": [width], "head.weight": [1000, width], "head.bias": [1000],
              "head_dist.weight": [1000, width], "head_dist.bias": [1000]}
    sd = {k: torch.randn(*shape, generator=g) for k, shape in shapes.items()}
    shapes = {"norm1": [width], "attn.qkv": [3 * width, width], "attn.proj": [width, width], "norm2": [width],
              "mlp.fc1": [4 * width, width], "mlp.fc2": [width, 4 * width]}
    for i in range(depth):
        for mod, shape in shapes.items():
            sd[f"blocks.{i}.{mod}.weight"] = torch.randn(*shape, generator=g)
            sd[f"blocks.{i}.{mod}.bias"] = torch.randn(shape[0], generator=g)
    return sd


def _time_interp(grid: np.ndarray, size: int) -> np.ndarray:
    """Linear resampling of the last axis with half-pixel centres, written out by hand."""
    n = grid.shape[-1]
    src = np.clip((np.arange(size) + 0.5) * n / size - 0.5, 0, n - 1)
    i0 = np.floor(src).astype(int)
    i1 = np.minimum(i0 + 1, n - 1)
    w = src - i0
    return grid[..., i0] * (1 - w) + grid[..., i1] * w


@pytest.fixture(scope="module")
def deit_and_vit():
    sd = _synthetic_deit()
    vit = AudioViT(ViTConfig(width=768, depth=2, heads=12))
    init_encoder_from_pretrained(vit, adapt_deit_to_audio(sd, vit.config))
    return sd, vit


def test_deit_weights_land_where_they_should(deit_and_vit):
    sd, vit = deit_and_vit
    got = vit.state_dict()
    assert torch.allclose(got["patch_embed.proj.weight"], sd["patch_embed.proj.weight"].mean(1, keepdim=True))
    for key in ("patch_embed.proj.bias", "cls_token", "dist_token", "norm.weight", "blocks.1.attn.qkv.weight",
                "blocks.0.mlp.fc2.bias", "blocks.1.norm2.weight"):
        assert torch.equal(got[key], sd[key]), key
    pos, old = got["pos_embed"], sd["pos_embed"]
    assert pos.shape == (1, 2 + 12 * 101, 768)
    assert torch.equal(pos[:, :2], old[:, :2])
    new_grid = pos[0, 2:].reshape(12, 101, 768)
    old_grid = old[0, 2:].reshape(24, 24, 768)
    # frequency: centre crop rows 6..17; time: the end columns map exactly onto the old ones
    assert torch.allclose(new_grid[0, 0], old_grid[6, 0]) and torch.allclose(new_grid[11, 100], old_grid[17, 23])
    assert torch.allclose(new_grid[0, 100], old_grid[6, 23]) and torch.allclose(new_grid[11, 0], old_grid[17, 0])
    expected = _time_interp(old_grid[6:18].permute(0, 2, 1).numpy().astype(np.float64), 101)
    assert np.allclose(new_grid.permute(0, 2, 1).numpy(), expected, atol=1e-5)


def test_deit_sum_option_and_interpolated_frequency():
    sd = _synthetic_deit(depth=1, width=64)
    cfg = ViTConfig(width=64, depth=1, heads=2)
    out = adapt_deit_to_audio(sd, cfg, channel_reduce="sum", freq_resize="interpolate")
    assert torch.allclose(out["patch_embed.proj.weight"], sd["patch_embed.proj.weight"].sum(1, keepdim=True))
    grid = out["pos_embed"][0, 2:].reshape(12, 101, 64)
    old = sd["pos_embed"][0, 2:].reshape(24, 24, 64)
    assert torch.allclose(grid[0, 0], old[:2, 0].mean(0), atol=1e-5)  # 24 -> 12 averages row pairs
    assert not any(k.startswith("head") for k in out)


def test_pretrained_key_errors_are_clear():
    sd = _synthetic_deit(depth=1, width=64)
    vit = AudioViT(ViTConfig(width=64, depth=1, heads=2))
    adapted = adapt_deit_to_audio(sd, vit.config)
    missing = {k: v for k, v in adapted.items() if k != "blocks.0.mlp.fc2.bias"}
    with pytest.raises(EmogestureError, match=r"lack 'blocks\.0\.mlp\.fc2\.bias' \(expected shape \[64\]\)"):
        init_encoder_from_pretrained(vit, missing)
    wrong = dict(adapted, **{"norm.weight": torch.zeros(70)})
    with pytest.raises(EmogestureError, match=r"'norm\.weight' has shape \[70\], the encoder expects \[64\]"):
        init_encoder_from_pretrained(vit, wrong)
    with pytest.raises(EmogestureError, match=r"12 key\(s\) the encoder does not have, e.g. .blocks\.1\."):
        init_encoder_from_pretrained(vit, adapt_deit_to_audio(_synthetic_deit(depth=2, width=64), vit.config))
    with pytest.raises(EmogestureError, match=r"shape \[64, 3, 16, 16\]; the encoder uses 32x32"):
        adapt_deit_to_audio(sd, ViTConfig(width=64, depth=1, heads=2, patch=32, stride=32))


def test_load_state_dict_files(tmp_path):
    from safetensors.torch import save_file

    sd = _synthetic_deit(depth=1, width=32)
    torch.save({"model": sd, "epoch": 3}, tmp_path / "deit.pth")
    save_file(sd, str(tmp_path / "deit.bin"))  # safetensors content under another name
    for name in ("deit.pth", "deit.bin"):
        loaded = load_deit_state_dict(tmp_path / name)
        assert set(loaded) == set(sd) and all(torch.equal(loaded[k], sd[k]) for k in sd)
    missing = tmp_path / "nope.pth"
    with pytest.raises(InputFileError) as err:
        load_deit_state_dict(missing)
    assert str(err.value) == f"{missing}: pretrained weights file not found"
    (tmp_path / "junk.pth").write_bytes(b"not a checkpoint at all")
    with pytest.raises(InputFileError) as err:
        load_deit_state_dict(tmp_path / "junk.pth")
    assert str(err.value).startswith(f"{tmp_path / 'junk.pth'}: cannot read") and "\n" not in str(err.value)


def test_ast_checkpoint_copies_or_resizes():
    g = _gen(7)
    cfg = ViTConfig(width=32, depth=1, heads=2)
    vit = AudioViT(cfg)
    ast = {f"module.v.{k}": torch.randn(v.shape, generator=g) for k, v in vit.state_dict().items()}
    ast["module.mlp_head.1.weight"] = torch.randn(527, 32, generator=g)
    init_encoder_from_pretrained(vit, adapt_ast_checkpoint(ast, cfg))
    assert all(torch.equal(v, ast[f"module.v.{k}"]) for k, v in vit.state_dict().items())
    short = dict(ast, **{"module.v.pos_embed": torch.randn(1, 2 + 12 * 50, 32, generator=g)})  # 512 frames
    pos = adapt_ast_checkpoint(short, cfg)["pos_embed"]
    old = short["module.v.pos_embed"][0, 2:].reshape(12, 50, 32)
    new = pos[0, 2:].reshape(12, 101, 32)
    assert torch.allclose(new[:, 0], old[:, 0]) and torch.allclose(new[:, 100], old[:, 49])
    expected = _time_interp(old.permute(0, 2, 1).numpy().astype(np.float64), 101)
    assert np.allclose(new.permute(0, 2, 1).numpy(), expected, atol=1e-5)


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
