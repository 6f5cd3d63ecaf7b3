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

from emogesture.config import apply_overrides, to_dict
from emogesture.diffusion.schedulers import DiffusionConfig
from emogesture.errors import ConfigError
from emogesture.models.denoiser import DenoiserConfig, LatentDenoiser
from emogesture.models.motion_vae import MotionVAE, MotionVAEConfig

VARIANTS = ("joint", "disjoint", "no_prior", "no_audio")
#: Settings that change how a trained gesture model generates, not what it learned: they can be changed
#: on a trained model (``emogesture bundle --set``) without retraining.
GENERATION_SETTINGS = ("vae.timing_guidance", "vae.output_smoothing", "vae.output_lowpass_hz",
                       "diffusion.num_inference_steps", "diffusion.residual_scale")


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
                              "(denoiser.timing_tokens and vae.timing_features = 0)")
        if self.variant == "no_prior" and self.vae.timing_features:
            raise ConfigError("the no_prior variant's linear map reads no timing stream (vae.timing_features = 0)")
        if self.vae.timing_features and self.denoiser.timing_tokens \
                and self.vae.timing_features != self.denoiser.timing_features:
            raise ConfigError("vae.timing_features and denoiser.timing_features must agree (one stream)")
        if self.denoiser.timing_tokens and self.denoiser.timing_frames != self.vae.frames:
            raise ConfigError(f"denoiser.timing_frames ({self.denoiser.timing_frames}) must equal vae.frames "
                              f"({self.vae.frames}): the stream covers the window's motion frames")
        if self.vae.latent_dim != self.denoiser.latent_dim:
            raise ConfigError("vae.latent_dim and denoiser.latent_dim must agree")

    def with_generation_settings(self, overrides: list[str]) -> "GestureModelConfig":
        """A copy with ``key=value`` overrides of :data:`GENERATION_SETTINGS` (e.g. ``vae.timing_guidance=3``)."""
        for item in overrides:
            key = item.split("=", 1)[0].strip()
            if "=" not in item or key not in GENERATION_SETTINGS:
                raise ConfigError(f"{item!r}: only generation settings can change on a trained model, as "
                                  f"key=value with key one of {', '.join(GENERATION_SETTINGS)}")
        return apply_overrides(GestureModelConfig, to_dict(self), overrides)

    @property
    def hears_timing(self) -> bool:
        """True when the model reads the speech's timing stream: its denoiser (after its
        condition latents) and/or its motion decoder. The stream then ends the model's conditions."""
        return self.denoiser.timing_tokens > 0 or self.vae.timing_features > 0

    @property
    def timing_features(self) -> int:
        """Numbers per frame of the timing stream (0 when the model reads none)."""
        return self.vae.timing_features or (self.denoiser.timing_features if self.denoiser.timing_tokens else 0)

    @classmethod
    def preset(cls, name: str, variant: str = "joint") -> "GestureModelConfig":
        """``paper``: the paper's design (ε-prediction; docs/design.md, 'Gesture generation model').
        ``tiny``: the small VAE and denoiser, and the denoiser predicts ẑ0
        (``diffusion.prediction_type="sample"``) instead of ε.

        Why ẑ0 for tiny (measured with the 900-step tiny VAE, a denoiser trained alone on its latents
        for 1000 steps, generated emotion accuracy GA on held-out texts, GT 0.935): ε-prediction
        reaches a noise loss of 0.12, yet its samples lie far from the latents (squared error to the
        window's latent 12 per dimension, where the latents' variance is 0.4; GA 0.07), because at
        t ≈ 1000 an ε error is multiplied by sqrt((1 − ᾱ_t) / ᾱ_t) ≈ 15 in the implied ẑ0; clipping
        ẑ0 to [-1, 1] (the authors' released inference) keeps the samples on scale but GA stays at
        chance. v-prediction gives GA 0.62 and ẑ0-prediction 0.73.

        A ẑ0 denoiser regresses to the conditional mean, so ``tiny`` also adds the calibrated residual
        noise, at half its calibrated scale (``diffusion.residual_scale = 0.5``, chosen on val with the
        timing guidance; see :mod:`emogesture.diffusion.residual`).

        ``tiny`` samples with 10 DDIM steps (the paper: 50; sampling is generation's largest stage): a ẑ0
        denoiser's samples hardly change with the step count (val, 4 seeds, the bundled model: GA 0.718 ± 0.033 with 10 steps,
        0.707 ± 0.044 with 25, 0.707 ± 0.038 with 50; FGD 7.41 / 7.44 / 7.47; rhythm gain, speed, jerk and
        the seam checks alike), and its training samples with 10 already (``align_ddim_steps``).

        ``tiny``'s motion decoder also hears the speech's timing stream (not in the paper),
        for the variants that hear speech through a decoder (``joint``, ``disjoint``): see
        :meth:`MotionVAEConfig.preset`. ``paper`` is the paper's design.
        """
        n = 1 if variant == "no_audio" else 3
        diffusion = (DiffusionConfig(prediction_type="sample", residual_scale=0.5, num_inference_steps=10)
                     if name == "tiny" else DiffusionConfig())
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
        model = GestureModel(config).eval()
        motion = torch.zeros(1, config.vae.frames, config.vae.feature_dim)
        z = torch.zeros(1, config.vae.latent_dim)
        conds = [torch.zeros(1, config.denoiser.cond_dim) for _ in range(config.denoiser.num_conditions)]
        timing = torch.zeros(1, config.vae.frames, config.timing_features) if config.hears_timing else None
        if config.denoiser.timing_tokens:
            conds.append(timing)
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
