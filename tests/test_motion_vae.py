"""Motion VAE and skip transformer: shapes, distribution tokens, cross-attention, skips, determinism, overfit."""

from __future__ import annotations

import math

import pytest
import torch
import torch.nn.functional as F

from emogesture.errors import ConfigError
from emogesture.models.generation import GenerationConfig
from emogesture.models.motion_vae import MotionVAE, MotionVAEConfig, kl_loss
from emogesture.models.skip_transformer import PosSelfAttention, SkipTransformer, SkipTransformerConfig
from emogesture.models.vit import CrossAttention


def _gen(seed: int) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


pytestmark = pytest.mark.usefixtures("one_thread")


@pytest.fixture(scope="module")
def tiny() -> MotionVAE:
    torch.manual_seed(0)
    return MotionVAE(MotionVAEConfig.preset("tiny")).eval()


def test_presets_and_validation():
    paper = MotionVAEConfig.preset("paper")
    assert (paper.feature_dim, paper.frames, paper.latent_dim, paper.width) == (282, 300, 256, 256)
    assert (paper.layers, paper.heads, paper.ff_dim, paper.dropout) == (9, 4, 1024, 0.1)
    with pytest.raises(ConfigError):
        MotionVAEConfig(layers=4)
    with pytest.raises(ConfigError):
        MotionVAEConfig(width=66, heads=4)
    with pytest.raises(ConfigError):
        MotionVAEConfig.preset("huge")
    # the tiny preset that hears timing gives the wrists (and only them) their own 24-cosine path
    from emogesture.motion.features import MotionFeatureSpec
    from emogesture.motion.skeleton import JOINT_NAMES

    hears = MotionVAEConfig.preset("tiny", timing=True)
    spec = MotionFeatureSpec()
    named = {JOINT_NAMES[spec.joints[c // 6]] for c in hears.detail_columns}
    assert (hears.detail_path, len(hears.detail_columns), named) == (24, 12, {"left_wrist", "right_wrist"})
    assert MotionVAEConfig.preset("tiny").detail_path == 0 and MotionVAEConfig.preset("paper").detail_path == 0
    assert MotionVAEConfig.preset("tiny", frames=20, timing=True).detail_path == 20
    assert MotionVAEConfig.preset("tiny", feature_dim=333, timing=True).detail_path == 0  # another layout: off


def test_shapes_and_variable_length(tiny):
    x = torch.randn(2, 300, 282, generator=_gen(1))
    recon, z, mu, logvar = tiny(x, generator=_gen(2))
    assert recon.shape == (2, 300, 282)
    assert z.shape == mu.shape == logvar.shape == (2, 256)
    assert tiny.decode(z, frames=120).shape == (2, 120, 282)
    assert tiny(x[:, :90], sample=False)[0].shape == (2, 90, 282)
    with pytest.raises(ValueError):
        tiny.encode(torch.randn(1, 301, 282))
    with pytest.raises(ValueError):
        tiny.decode(z, frames=301)
    with pytest.raises(ValueError):
        tiny.encode(torch.randn(1, 30, 281))


def test_mu_and_logvar_come_from_the_two_distribution_tokens(tiny):
    x = torch.randn(2, 50, 282, generator=_gen(3))
    seen = {}
    handle = tiny.encoder.register_forward_hook(lambda m, i, o: seen.setdefault("out", o))
    try:
        _, mu, logvar = tiny.encode(x, sample=False)
    finally:
        handle.remove()
    out = seen["out"]
    assert out.shape == (2, 52, tiny.config.width)  # 2 distribution tokens + 50 frames
    # μ: the μ token plus the tiny preset's low-frequency path (DCT coefficients of the frame embeddings)
    coefficients = torch.einsum("nf,bnd->bfd", tiny.dct_basis[:50], tiny.encoder_input(x)) / 50
    torch.testing.assert_close(mu, tiny.to_mu(out[:, 0]) + tiny.low_frequency_mu(coefficients.reshape(2, -1)))
    torch.testing.assert_close(logvar, tiny.to_logvar(out[:, 1]))
    # The token parameters matter: perturbing the μ token changes μ.
    vae = MotionVAE(tiny.config).eval()
    vae.load_state_dict(tiny.state_dict())
    with torch.no_grad():
        vae.dist_tokens[0, 0] += 1.0
    assert (vae.encode(x, sample=False)[1] - mu).abs().max() > 1e-3


def test_decoder_reads_z_only_through_cross_attention_and_the_low_frequency_path(tiny):
    z1, z2 = torch.randn(2, 2, 256, generator=_gen(4))
    assert (tiny.decode(z1, 40) - tiny.decode(z2, 40)).abs().max() > 1e-3
    vae = MotionVAE(tiny.config).eval()
    vae.load_state_dict(tiny.state_dict())
    with torch.no_grad():
        vae.low_frequency_out.weight.zero_()
        vae.low_frequency_out.bias.zero_()
        assert (vae.decode(z1, 40) - vae.decode(z2, 40)).abs().max() > 1e-3
        for block in [*vae.decoder.input_blocks, vae.decoder.middle_block, *vae.decoder.output_blocks]:
            block.cross.proj.weight.zero_()
            block.cross.proj.bias.zero_()
    torch.testing.assert_close(vae.decode(z1, 40), vae.decode(z2, 40))


def test_skip_connections_fuse_mirrored_input_blocks():
    cfg = SkipTransformerConfig(width=32, layers=9, heads=4, ff_dim=64, dropout=0.0)
    net = SkipTransformer(cfg).eval()
    assert len(net.input_blocks) == len(net.output_blocks) == len(net.fuse) == 4
    assert all(f.in_features == 64 and f.out_features == 32 for f in net.fuse)
    outs, fused_inputs = [], []
    hooks = [b.register_forward_hook(lambda m, i, o: outs.append(o)) for b in net.input_blocks]
    hooks += [f.register_forward_hook(lambda m, i, o: fused_inputs.append(i[0])) for f in net.fuse]
    try:
        net(torch.randn(2, 7, 32, generator=_gen(5)), torch.randn(1, 7, 32, generator=_gen(6)))
    finally:
        for h in hooks:
            h.remove()
    # Output block k fuses input block (3 - k): the skip is the second half of the concatenation.
    for k, inp in enumerate(fused_inputs):
        torch.testing.assert_close(inp[..., 32:], outs[3 - k])
    paper = MotionVAE(MotionVAEConfig.preset("paper"))
    assert len(paper.encoder.fuse) == len(paper.decoder.fuse) == 4


def test_positional_embedding_enters_every_attention_layer():
    cfg = SkipTransformerConfig(width=32, layers=5, heads=4, ff_dim=64, dropout=0.0)
    net = SkipTransformer(cfg).eval()
    x = torch.randn(2, 6, 32, generator=_gen(7))
    perm = torch.tensor([3, 0, 5, 1, 4, 2])
    # Without positions the stack is permutation-equivariant ...
    torch.testing.assert_close(net(x[:, perm]), net(x)[:, perm])
    pos = torch.randn(1, 6, 32, generator=_gen(8))
    got = []
    hooks = [m.register_forward_hook(lambda m, i, o: got.append(i[1] if len(i) > 1 else None))
             for m in net.modules() if isinstance(m, PosSelfAttention)]
    try:
        y = net(x, pos)
    finally:
        for h in hooks:
            h.remove()
    # ... every self-attention layer receives the positional embedding, which breaks the symmetry.
    assert len(got) == 5 and all(p is pos for p in got)
    assert (net(x[:, perm], pos) - y[:, perm]).abs().max() > 1e-3


@pytest.mark.parametrize("memory_tokens", [1, 3])
def test_inference_computes_the_trained_function(memory_tokens):
    """Without autograd the positional term joins q and k after one qkv product ((x + pos) W = x W +
    pos W), and one memory token is read without the attention (its softmax is exactly 1): the same
    function as the training path, to float rounding."""
    cfg = SkipTransformerConfig(width=32, layers=3, heads=4, ff_dim=64, dropout=0.0, cross_attention=True)
    net = SkipTransformer(cfg).eval()
    x = torch.randn(3, 7, 32, generator=_gen(9))
    pos = torch.randn(1, 7, 32, generator=_gen(10))
    memory = torch.randn(3, memory_tokens, 32, generator=_gen(11))
    trained = net(x, pos, memory)  # autograd on: the training path
    assert trained.requires_grad
    with torch.no_grad():
        inference = net(x, pos, memory)
    torch.testing.assert_close(inference, trained.detach(), rtol=1e-5, atol=1e-5)
    # the memory still matters, per sample
    with torch.no_grad():
        other = net(x, pos, memory.roll(1, 0))
    assert (other - inference).abs().amax((1, 2)).min() > 1e-3


def test_one_memory_token_trains_as_the_full_attention():
    """With autograd too, one memory token is read without the attention: the output and every gradient
    are those of the attention computed in full, the queries' (zero there to rounding) exactly zero, and
    every input and parameter stays in the graph (``autograd.grad`` raises for one left out, as DDP would)."""
    torch.manual_seed(0)
    cross = CrossAttention(16, 4)
    x = torch.randn(2, 5, 16, requires_grad=True)
    memory = torch.randn(2, 1, 16, requires_grad=True)
    inputs = [x, memory, *cross.parameters()]
    out = cross(x, memory)
    g = torch.randn_like(out)
    got = torch.autograd.grad(out, inputs, g)
    q = cross.q(x).reshape(2, 5, 4, 4).transpose(1, 2)
    k, v = cross.kv(memory).reshape(2, 1, 2, 4, 4).permute(2, 0, 3, 1, 4)
    full = cross.proj(F.scaled_dot_product_attention(q, k, v).transpose(1, 2).reshape(2, 5, 16))
    want = torch.autograd.grad(full, inputs, g)
    torch.testing.assert_close(out, full)
    for a, b in zip(got, want):
        torch.testing.assert_close(a, b, rtol=1e-5, atol=1e-6)
    assert got[2].abs().max() == 0 and got[1].abs().max() > 1e-3  # q's weight; the memory's gradient


def test_paper_parameter_count():
    n = sum(p.numel() for p in MotionVAE(MotionVAEConfig.preset("paper")).parameters())
    tiny = MotionVAE(MotionVAEConfig.preset("tiny"))
    t = sum(p.numel() for p in tiny.parameters())
    path = sum(p.numel() for name, p in tiny.named_parameters() if name.startswith("low_frequency"))
    print(f"motion VAE parameters: paper {n / 1e6:.2f} M, tiny {t / 1e6:.2f} M ({path / 1e6:.2f} M in its path)")
    assert 12e6 < n < 25e6  # 9+9 layers of width 256, ff 1024 (+ cross-attention in the decoder)
    # the tiny path's two Linears: 48 cosines × width 64 -> 256, and 256 -> 48 cosines × 282 features
    assert path == (48 * 64 * 256 + 256) + (256 * 48 * 282 + 48 * 282)
    assert t - path < 0.5e6


def test_gradients_reach_every_parameter():
    torch.manual_seed(0)
    vae = MotionVAE(MotionVAEConfig.preset("tiny", frames=20)).train()
    x = torch.randn(3, 20, 282, generator=_gen(9))
    recon, z, mu, logvar = vae(x, generator=_gen(10))
    (F.smooth_l1_loss(recon, x) + 1e-4 * vae.kl_loss(mu, logvar)).backward()
    # (fused attention kernels leave rounding-level gradients on inert parameters: count those as zero)
    missing = {n for n, p in vae.named_parameters() if p.grad is None or not p.grad.abs().max() > 1e-7}
    # With a single memory token (z) the cross-attention softmax is identically 1, so its query path
    # (norm_cross, cross.q) is inert by construction; everything else must learn.
    inert = {n for n, _ in vae.named_parameters() if ".norm_cross." in n or ".cross.q." in n}
    assert len(inert) == 4 * 3 and missing == inert


def test_sampling_is_reproducible(tiny):
    x = torch.randn(2, 40, 282, generator=_gen(11))
    z_a, mu, logvar = tiny.encode(x, sample=False)
    torch.testing.assert_close(z_a, mu)
    torch.testing.assert_close(tiny.encode(x, sample=False)[0], z_a)
    s1 = tiny.encode(x, generator=_gen(12))[0]
    s2 = tiny.encode(x, generator=_gen(12))[0]
    s3 = tiny.encode(x, generator=_gen(13))[0]
    torch.testing.assert_close(s1, s2)
    assert (s1 - s3).abs().max() > 1e-3
    eps = torch.randn(2, 256, generator=_gen(12))
    torch.testing.assert_close(s1, mu + torch.exp(0.5 * logvar) * eps)


def test_kl_loss_closed_form():
    mu = torch.randn(4, 256, generator=_gen(14))
    logvar = torch.randn(4, 256, generator=_gen(15)) * 0.3
    q = torch.distributions.Normal(mu, torch.exp(0.5 * logvar))
    p = torch.distributions.Normal(torch.zeros_like(mu), torch.ones_like(mu))
    torch.testing.assert_close(kl_loss(mu, logvar), torch.distributions.kl_divergence(q, p).sum(-1).mean())
    assert kl_loss(torch.zeros(2, 8), torch.zeros(2, 8)).item() == 0.0


def test_tiny_vae_overfits_a_small_batch():
    torch.manual_seed(0)
    g = _gen(16)
    frames = 32
    cfg = MotionVAEConfig.preset("tiny", frames=frames)
    # without the linear cosine paths (48 cosines would be a complete basis of 32 frames: a linear map could
    # reconstruct the batch alone), so the transformer itself must learn it
    cfg.low_frequency_path = cfg.detail_path = 0
    vae = MotionVAE(cfg)
    basis = torch.randn(3, 282, generator=g)
    phase = torch.rand(4, 3, generator=g) * 2 * math.pi
    t = torch.arange(frames, dtype=torch.float32)
    waves = torch.sin(2 * math.pi * torch.tensor([1.0, 2.0, 3.0]) * t[None, :, None] / frames + phase[:, None, :])
    x = torch.einsum("btk,kf->btf", waves, basis) / math.sqrt(1.5)  # 4 smooth windows, unit scale

    def error() -> float:
        vae.eval()
        with torch.no_grad():
            e = F.mse_loss(vae(x, sample=False)[0], x).item()
        vae.train()
        return e

    before = error()
    opt = torch.optim.AdamW(vae.parameters(), lr=3e-4)
    for _ in range(300):
        recon, _, mu, logvar = vae(x, generator=g)
        loss = F.smooth_l1_loss(recon, x) + 1e-4 * kl_loss(mu, logvar)
        opt.zero_grad()
        loss.backward()
        opt.step()
    after = error()
    print(f"overfit: reconstruction MSE {before:.3f} -> {after:.3f}")
    assert after < 0.5 * before


def test_tiny_gesture_preset_hears_timing_where_it_hears_speech_and_paper_stays_the_papers():
    from emogesture.models.gesture import GestureModelConfig

    for variant in ("joint", "disjoint"):
        vae, g = GestureModelConfig.preset("tiny", variant).vae, GenerationConfig.preset("tiny", variant)
        assert (vae.low_frequency_path, vae.timing_features) == (16, 2)
        assert (g.timing_guidance, g.timing_guidance_on) == (6.0, "onsets")
        assert (g.output_smoothing, g.output_lowpass_hz, g.num_inference_steps) == (0.0, 4.0, 10)  # paper: 50 steps
    for variant in ("no_prior", "no_audio"):  # the ablations keep the design without the timing stream
        c, g = GestureModelConfig.preset("tiny", variant), GenerationConfig.preset("tiny", variant)
        assert not c.hears_timing and c.vae.low_frequency_path == 48 and g.output_smoothing == 0
        assert g.output_lowpass_hz == 0 and g.timing_guidance == 1.0
    paper, g = GestureModelConfig.preset("paper"), GenerationConfig.preset("paper")
    assert not paper.hears_timing and paper.vae.low_frequency_path == 0 and g.timing_guidance == 1.0
    assert g.num_inference_steps == 50 and g.residual_scale == 0


def test_the_posterior_draw_is_made_on_the_generators_device_and_moved(tiny, monkeypatch):
    """A CPU generator cannot draw on a GPU (torch raises there), so the posterior sample ε is drawn where
    the generator is and moved to the latents; on the CPU it is the generator's plain draw. The GPU's
    rule is emulated with torch's meta device, where a CPU generator would not raise by itself."""
    x = torch.randn(2, 300, 282, generator=_gen(1)) * 0.3
    with torch.no_grad():
        z, mu, logvar = tiny.encode(x, generator=_gen(5))
    eps = torch.randn(mu.shape, generator=_gen(5))
    torch.testing.assert_close(z, mu + torch.exp(0.5 * logvar) * eps)

    real = torch.randn

    def gpu_rule(*args, generator=None, device=None, **kwargs):
        if generator is not None and device is not None and torch.device(device) != generator.device:
            raise RuntimeError(f"Expected a '{torch.device(device).type}' device type for generator but "
                               f"found '{generator.device.type}'")
        return real(*args, generator=generator, device=device, **kwargs)

    monkeypatch.setattr(torch, "randn", gpu_rule)
    on_meta = MotionVAE(MotionVAEConfig.preset("tiny")).to("meta")
    z, mu, _ = on_meta.encode(torch.empty(2, 300, 282, device="meta"), generator=_gen(5))
    assert z.device.type == "meta" and z.shape == mu.shape == (2, 256)
