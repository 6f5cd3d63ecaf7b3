"""The gesture generation model (docs/design.md, 'Gesture generation model'): motion prior + latent denoiser,
and the ablation variants.

Variants (paper Table 3 / supp. C):
- ``joint``: MLD-style VAE motion prior and latent denoiser trained together (the paper's model);
- ``disjoint``: the same networks, VAE first, then the denoiser on the frozen VAE;
- ``no_prior``: no learned motion prior — a single linear map between a flattened motion window
  and the 256-d latent stands in for the VAE (no KL, no transformer); the denoiser is unchanged;
- ``no_audio``: no speech disentanglement — an 8-layer linear autoencoder over the window's MFCCs
  gives one latent ``m`` that replaces ``(c, e, s)`` as the denoiser's only condition.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import torch
from torch import nn

from emogesture.diffusion.schedulers import DiffusionConfig
from emogesture.errors import ConfigError
from emogesture.models.denoiser import DenoiserConfig, LatentDenoiser
from emogesture.models.motion_vae import MotionVAE, MotionVAEConfig

VARIANTS = ("joint", "disjoint", "no_prior", "no_audio")


@dataclass
class GestureModelConfig:
    variant: str = "joint"
    vae: MotionVAEConfig = field(default_factory=MotionVAEConfig)
    denoiser: DenoiserConfig = field(default_factory=DenoiserConfig)
    diffusion: DiffusionConfig = field(default_factory=DiffusionConfig)
    mfcc_dim: int = 13 * 128  # no_audio: MFCC window (13 coefficients x 1024 frames averaged in 8s)
    audio_ae_width: int = 256  # no_audio: hidden width of the linear autoencoder

    def __post_init__(self) -> None:
        if self.variant not in VARIANTS:
            raise ConfigError(f"unknown gesture model variant {self.variant!r}; known: {', '.join(VARIANTS)}")
        want = 1 if self.variant == "no_audio" else 3
        if self.denoiser.num_conditions != want:
            raise ConfigError(f"variant {self.variant} needs denoiser.num_conditions = {want}")
        if self.variant == "no_audio" and self.hears_timing:
            raise ConfigError("the no_audio variant hears no speech, so it takes no timing stream "
                              "(vae.timing_features = 0)")
        if self.variant == "no_prior" and self.vae.timing_features:
            raise ConfigError("the no_prior variant's linear map reads no timing stream (vae.timing_features = 0)")
        if self.vae.latent_dim != self.denoiser.latent_dim:
            raise ConfigError("vae.latent_dim and denoiser.latent_dim must agree")

    @property
    def hears_timing(self) -> bool:
        """True when the model's motion decoder reads the speech's timing stream. The stream then ends the
        model's conditions."""
        return self.vae.timing_features > 0

    @property
    def timing_features(self) -> int:
        """Numbers per frame of the timing stream (0 when the model reads none)."""
        return self.vae.timing_features

    @classmethod
    def preset(cls, name: str, variant: str = "joint") -> "GestureModelConfig":
        """``paper``: the paper's design (ε-prediction; docs/design.md, 'Gesture generation model').
        ``tiny``: the small VAE and denoiser; the denoiser predicts ẑ0 (``diffusion.prediction_type =
        "sample"``) instead of ε, and the motion decoder of the variants that hear speech through one
        (``joint``, ``disjoint``) also reads the speech's timing stream (:meth:`MotionVAEConfig.preset`).
        How either generates is :meth:`emogesture.models.generation.GenerationConfig.preset`'s; the
        reasons and measurements: ``experiments/motion_prior/README.md``.
        """
        n = 1 if variant == "no_audio" else 3
        diffusion = DiffusionConfig(prediction_type="sample") if name == "tiny" else DiffusionConfig()
        timing = name == "tiny" and variant in ("joint", "disjoint")
        return cls(variant=variant, vae=MotionVAEConfig.preset(name, timing=timing),
                   denoiser=DenoiserConfig.preset(name, n), diffusion=diffusion)


class LinearMotionMap(nn.Module):
    """``no_prior``: motion window ``[B, T, D]`` <-> latent ``[B, 256]`` by one linear map each way."""

    def __init__(self, config: MotionVAEConfig) -> None:
        super().__init__()
        self.config = config
        self.down = nn.Linear(config.frames * config.feature_dim, config.latent_dim)
        self.up = nn.Linear(config.latent_dim, config.frames * config.feature_dim)

    def encode(self, motion: torch.Tensor, generator=None, sample: bool = True):
        z = self.down(motion.reshape(motion.shape[0], -1))
        return z, z, torch.zeros_like(z)

    def decode(self, z: torch.Tensor, frames: int | None = None, timing: torch.Tensor | None = None) -> torch.Tensor:
        return self.up(z).reshape(z.shape[0], self.config.frames, self.config.feature_dim)

    def forward(self, motion: torch.Tensor, generator=None, sample: bool = True, timing=None):
        z, mu, logvar = self.encode(motion)
        return self.decode(z), z, mu, logvar


class MFCCAutoencoder(nn.Module):
    """``no_audio``: 8 linear layers (4 down, 4 up) over a flattened MFCC window -> one latent ``m``."""

    def __init__(self, in_dim: int, width: int, latent_dim: int) -> None:
        super().__init__()
        dims = [in_dim, width * 2, width, width, latent_dim]
        enc, dec = [], []
        for a, b in zip(dims[:-1], dims[1:]):
            enc += [nn.Linear(a, b), nn.GELU()]
        for a, b in zip(dims[::-1][:-1], dims[::-1][1:]):
            dec += [nn.Linear(a, b), nn.GELU()]
        self.encoder = nn.Sequential(*enc[:-1])
        self.decoder = nn.Sequential(*dec[:-1])

    def forward(self, mfcc: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``mfcc [B, in_dim]`` -> ``(m [B, latent], reconstruction [B, in_dim])``."""
        m = self.encoder(mfcc)
        return m, self.decoder(m)


class GestureModel(nn.Module):
    """Motion prior (``prior``) + latent denoiser (``denoiser``) [+ ``audio_ae`` for ``no_audio``].

    ``latent_residual_tril [256, 256]``: the residual-noise calibration (lower Cholesky factor of the
    covariance of ``z − ẑ`` on held-out windows; all zeros = not calibrated, no residual noise).
    """

    #: State-dict entries a model file may lack (files from before they existed load with the default).
    optional_state_keys = ("latent_residual_tril",)

    def __init__(self, config: GestureModelConfig) -> None:
        super().__init__()
        self.config = config
        self.prior = LinearMotionMap(config.vae) if config.variant == "no_prior" else MotionVAE(config.vae)
        self.denoiser = LatentDenoiser(config.denoiser)
        self.audio_ae = (MFCCAutoencoder(config.mfcc_dim, config.audio_ae_width, config.denoiser.cond_dim)
                         if config.variant == "no_audio" else None)
        self.register_buffer("latent_residual_tril", torch.zeros(config.vae.latent_dim, config.vae.latent_dim))

    @property
    def calibrated(self) -> bool:
        """True once a residual-noise calibration is stored."""
        return bool(self.latent_residual_tril.abs().sum() > 0)

    def count_parameters(self) -> dict[str, int]:
        out = {"prior": sum(p.numel() for p in self.prior.parameters()),
               "denoiser": sum(p.numel() for p in self.denoiser.parameters())}
        if self.audio_ae is not None:
            out["audio_ae"] = sum(p.numel() for p in self.audio_ae.parameters())
        out["total"] = sum(out.values())
        return out


def gesture_flops(config: GestureModelConfig) -> dict[str, int]:
    """FLOPs (multiply-add = 2) per component on the meta device: ``prior`` encodes and decodes one
    window (``decode``: decoding only), ``denoiser`` is one denoising step of one sample, ``audio_ae`` one MFCC window."""
    from torch.utils.flop_counter import FlopCounterMode

    with torch.device("meta"):
        model = GestureModel(config).eval().to("meta")  # (its computed buffers are built on the CPU)
        motion = torch.zeros(1, config.vae.frames, config.vae.feature_dim)
        z = torch.zeros(1, config.vae.latent_dim)
        conds = [torch.zeros(1, config.denoiser.cond_dim) for _ in range(config.denoiser.num_conditions)]
        timing = torch.zeros(1, config.vae.frames, config.timing_features) if config.hears_timing else None
        t = torch.zeros(1, dtype=torch.long)
        mfcc = torch.zeros(1, config.mfcc_dim)
    out = {}
    with FlopCounterMode(display=False) as counter:
        model.prior(motion, sample=False, timing=timing)
    out["prior"] = int(counter.get_total_flops())
    with FlopCounterMode(display=False) as counter:
        model.prior.decode(z, timing=timing)
    out["decode"] = int(counter.get_total_flops())
    with FlopCounterMode(display=False) as counter:
        model.denoiser(z, t, conds)
    out["denoiser"] = int(counter.get_total_flops())
    if model.audio_ae is not None:
        with FlopCounterMode(display=False) as counter:
            model.audio_ae(mfcc)
        out["audio_ae"] = int(counter.get_total_flops())
    return out
