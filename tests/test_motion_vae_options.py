"""The motion VAE's options beside MLD's design: frames per token, latent tokens, the low-frequency and detail paths, the timing stream, the output low-pass and decoder smoothing."""

from __future__ import annotations


import pytest
import torch

from emogesture.errors import ConfigError
from emogesture.models.generation import GenerationConfig
from emogesture.models.motion_vae import MotionVAE, MotionVAEConfig


def _gen(seed: int) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


def _assert_mu_reads(vae: MotionVAE, path: torch.nn.Linear) -> None:
    """The encoder's μ of a random 30-frame window changes when the path's Linear into μ is zeroed."""
    x = torch.randn(1, 30, 282, generator=_gen(1))
    mu = vae.encode(x, sample=False)[1]
    with torch.no_grad():
        path.weight.zero_()
        path.bias.zero_()
    assert not torch.allclose(vae.encode(x, sample=False)[1], mu)


def test_low_frequency_path_adds_dct_analysis_and_synthesis():
    cfg = MotionVAEConfig.preset("tiny", frames=30)
    cfg.low_frequency_path = 4
    vae = MotionVAE(cfg).eval()
    basis = vae.dct_basis
    assert basis.shape == (30, 4) and torch.allclose(basis[:, 0], torch.ones(30))
    # DCT-II columns are orthogonal
    gram = basis.T @ basis
    assert torch.allclose(gram - torch.diag(torch.diagonal(gram)), torch.zeros(4, 4), atol=1e-4)
    z = torch.randn(2, 256, generator=_gen(0))
    with torch.no_grad():
        vae.decoder_output.weight.zero_()
        vae.decoder_output.bias.zero_()
    coefficients = vae.low_frequency_out(z).reshape(2, 4, 282)
    expected = torch.einsum("nf,bfe->bne", basis, coefficients)
    assert torch.allclose(vae.decode(z), expected, atol=1e-5)
    assert torch.allclose(vae.decode(z, frames=17), expected[:, :17], atol=1e-5)
    _assert_mu_reads(vae, vae.low_frequency_mu)  # the encoder's μ moves with the window's slow content
    with pytest.raises(ConfigError, match="low_frequency_path"):
        MotionVAEConfig(frames=30, low_frequency_path=31)


def test_detail_path_writes_and_reads_only_its_columns():
    cfg = MotionVAEConfig.preset("tiny", frames=30)
    cfg.detail_path, cfg.detail_columns = 6, (5, 7, 8)
    vae = MotionVAE(cfg).eval()
    z = torch.randn(2, 256, generator=_gen(0))
    plain, plain17 = vae.decode(z), vae.decode(z, frames=17)
    vae_off = MotionVAE(MotionVAEConfig.preset("tiny", frames=30))
    vae_off.load_state_dict(vae.state_dict(), strict=False)
    assert torch.equal(plain, vae_off.eval().decode(z))  # its output Linear starts at zero: a no-op
    with torch.no_grad():
        vae.detail_out.weight.normal_(generator=_gen(1))
    moved = vae.decode(z) - plain
    coefficients = vae.detail_out(z).reshape(2, 6, 3)
    expected = torch.einsum("tf,bfc->btc", vae.detail_basis, coefficients)
    assert torch.allclose(moved[..., [5, 7, 8]], expected, atol=1e-5)
    others = [c for c in range(282) if c not in (5, 7, 8)]
    assert moved[..., others].abs().max() == 0
    assert torch.allclose((vae.decode(z, frames=17) - plain17)[..., [5, 7, 8]], expected[:, :17], atol=1e-5)
    _assert_mu_reads(vae, vae.detail_mu)  # the encoder's μ moves with the detail columns' content
    for bad in (dict(detail_path=6, detail_columns=()), dict(detail_path=6, detail_columns=(3, 3)),
                dict(detail_path=6, detail_columns=(282,)), dict(detail_path=31, detail_columns=(1,))):
        with pytest.raises(ConfigError, match="detail"):
            MotionVAEConfig(frames=30, **bad)


def test_timing_stream_smoothing_removes_frame_jitter_before_the_decoder():
    from emogesture.motion.filters import gaussian_smooth

    x = torch.zeros(1, 60, 2)
    x[0, 30, 0] = 1.0
    y = gaussian_smooth(x, 2.0)
    assert y.sum().item() == pytest.approx(1.0, abs=1e-5) and y[0, 30, 0] < 0.25 and y[0, :, 1].abs().max() == 0
    torch.testing.assert_close(gaussian_smooth(torch.ones(1, 60, 2), 2.0), torch.ones(1, 60, 2))  # edges held
    outs = {}
    for sigma in (0.0, 2.0):
        torch.manual_seed(0)
        cfg = MotionVAEConfig(frames=60, width=32, layers=3, heads=2, ff_dim=64, dropout=0.0, latent_dim=32,
                              timing_features=2, timing_smoothing=sigma)
        vae = MotionVAE(cfg).eval()
        torch.nn.init.normal_(vae.timing_to_query.weight)  # zero at initialisation
        slow = torch.sin(torch.linspace(0, 6, 60))[None, :, None].expand(1, 60, 2)
        jitter = 0.5 * torch.randn(1, 60, 2, generator=torch.Generator().manual_seed(1))
        z = torch.zeros(1, 32)
        with torch.no_grad():
            outs[sigma] = (vae.decode(z, timing=slow + jitter) - vae.decode(z, timing=slow)).abs().mean().item()
    assert outs[2.0] < 0.75 * outs[0.0]  # (0.61 measured; without smoothing the two are equal)
    with pytest.raises(ConfigError, match="timing_smoothing"):
        MotionVAEConfig(timing_smoothing=-1)


def test_decode_pair_gives_the_decoding_with_and_without_the_stream():
    torch.manual_seed(0)
    cfg = MotionVAEConfig(frames=40, width=32, layers=3, heads=2, ff_dim=64, dropout=0.0, latent_dim=32,
                          timing_features=2)
    vae = MotionVAE(cfg).eval()
    torch.nn.init.normal_(vae.timing_to_query.weight)  # zero at initialisation
    z, stream = torch.randn(3, 32), torch.randn(3, 40, 2)
    with torch.no_grad():
        heard, deaf = vae.decode(z, timing=stream), vae.decode(z, timing=torch.zeros_like(stream))
        pair = vae.decode_pair(z, timing=stream)
        torch.testing.assert_close(pair[0], heard, atol=1e-5, rtol=1e-5)
        torch.testing.assert_close(pair[1], deaf, atol=1e-5, rtol=1e-5)
    assert not torch.allclose(heard, deaf)
    # a deaf decoding that keeps one column hears that column and zeros in the other
    kept = stream.clone()
    kept[..., 1] = 0
    with torch.no_grad():
        pair = vae.decode_pair(z, timing=stream, keep=(0,))
        torch.testing.assert_close(pair[1], vae.decode(z, timing=kept), atol=1e-5, rtol=1e-5)
    assert not torch.allclose(pair[1], deaf)
    with pytest.raises(ValueError, match="keep"):
        vae.decode_pair(z, timing=stream, keep=(2,))
    with pytest.raises(ConfigError, match="timing_guidance_on"):
        GenerationConfig(timing_guidance_on="loudness")
    with pytest.raises(ConfigError, match="timing_guidance"):
        GenerationConfig(timing_guidance=-1)
    with pytest.raises(ConfigError, match="output_smoothing"):
        GenerationConfig(output_smoothing=-0.5)


def test_output_lowpass_keeps_strokes_below_the_cutoff_and_removes_jitter_above_it():
    import math

    from emogesture.motion.filters import gaussian_smooth, lowpass

    t = torch.arange(300, dtype=torch.float32) / 30
    sine = lambda hz: torch.sin(2 * math.pi * hz * t)  # noqa: E731
    x = torch.stack([sine(1.0), sine(2.0), sine(6.0), 3 + 0.5 * t], -1)[None]  # [1, 300, 4]
    y = lowpass(x, 2.75)
    mid = slice(60, 240)
    gain = (y[0, mid].std(0) / x[0, mid].std(0)).tolist()
    assert gain[0] == pytest.approx(1.0, abs=0.01) and gain[1] > 0.95 and gain[2] < 0.01
    torch.testing.assert_close(y[..., 3], x[..., 3], atol=1e-4, rtol=0)  # a ramp passes, edges included
    # where a Gaussian removes as much of the 6-Hz jitter, it also takes a large share of 2-Hz strokes
    g = gaussian_smooth(x, 2.0)
    assert (g[0, mid, 2].std() / x[0, mid, 2].std()) > 0.01 and (g[0, mid, 1].std() / x[0, mid, 1].std()) < 0.8
    assert lowpass(torch.randn(2, 5, 3), 2.75).shape == (2, 5, 3)  # windows shorter than the kernel
    with pytest.raises(ConfigError, match="output_lowpass_hz"):
        GenerationConfig(output_lowpass_hz=15.0)
    with pytest.raises(ConfigError, match="output_lowpass_hz"):
        GenerationConfig(output_lowpass_hz=-1.0)
