"""Noise schedulers for the latent diffusion (docs/design.md, 'Gesture generation model'): DDPM for training,
DDIM for sampling.

Every scheduler field is passed to ``diffusers`` explicitly, because its defaults differ from the
paper's setting (DDIM: ``clip_sample=True``, ``set_alpha_to_one=True``, ``steps_offset=0``; the
authors' inference silently clipped x̂0 to [-1, 1] through that default). ``diffusers`` is imported
only inside the factory functions (it is slow to import and not needed by the rest of the package);
sampling uses :class:`emogesture.diffusion.ddim.DDIMSampler`, the same DDIM arithmetic without it.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

from emogesture.errors import ConfigError

BETA_SCHEDULES = ("linear", "scaled_linear", "squaredcos_cap_v2")
PREDICTION_TYPES = ("epsilon", "sample", "v_prediction")
VARIANCE_TYPES = ("fixed_small", "fixed_small_log", "fixed_large", "fixed_large_log")
TIMESTEP_SPACINGS = ("leading", "trailing", "linspace")


@dataclass
class DiffusionConfig:
    """The diffusion setting; defaults are the paper's (docs/design.md, 'Gesture generation model').

    Training: DDPM, 1000 steps, "scaled_linear" betas 0.00085 -> 0.012 (β_t = (linspace(√β0, √β1))²),
    ε-prediction, fixed-small variance. Sampling: DDIM, 50 steps with "leading" spacing and
    ``steps_offset=1`` (timesteps 981, 961, …, 1), ``set_alpha_to_one=False`` (the last step goes to
    ᾱ_0, not 1), no clipping of x̂0, η = 0 (deterministic given the initial noise).
    ``clip_sample_range`` only matters with ``clip_sample=True``.
    """

    num_train_timesteps: int = 1000
    beta_start: float = 0.00085
    beta_end: float = 0.012
    beta_schedule: str = "scaled_linear"
    prediction_type: str = "epsilon"
    variance_type: str = "fixed_small"
    clip_sample: bool = False
    clip_sample_range: float = 1.0
    set_alpha_to_one: bool = False
    steps_offset: int = 1
    timestep_spacing: str = "leading"
    eta: float = 0.0

    def __post_init__(self) -> None:
        def choice(name: str, allowed: tuple[str, ...]) -> None:
            if getattr(self, name) not in allowed:
                raise ConfigError(f"diffusion: {name} must be one of {list(allowed)}, got {getattr(self, name)!r}")

        choice("beta_schedule", BETA_SCHEDULES)
        choice("prediction_type", PREDICTION_TYPES)
        choice("variance_type", VARIANCE_TYPES)
        choice("timestep_spacing", TIMESTEP_SPACINGS)
        if self.num_train_timesteps < 1:
            raise ConfigError("diffusion: num_train_timesteps must be ≥ 1")
        if not 0.0 < self.beta_start < self.beta_end < 1.0:
            raise ConfigError(f"diffusion: need 0 < beta_start < beta_end < 1, got {self.beta_start}, {self.beta_end}")
        if self.steps_offset < 0 or self.eta < 0 or self.clip_sample_range <= 0:
            raise ConfigError("diffusion: steps_offset and eta must be ≥ 0, clip_sample_range > 0")


def _common(cfg: DiffusionConfig) -> dict[str, Any]:
    """Keyword arguments shared by diffusers' DDPM and DDIM schedulers, all explicit."""
    return dict(
        num_train_timesteps=cfg.num_train_timesteps,
        beta_start=cfg.beta_start,
        beta_end=cfg.beta_end,
        beta_schedule=cfg.beta_schedule,
        trained_betas=None,
        clip_sample=cfg.clip_sample,
        clip_sample_range=cfg.clip_sample_range,
        prediction_type=cfg.prediction_type,
        thresholding=False,
        dynamic_thresholding_ratio=0.995,
        sample_max_value=1.0,
        timestep_spacing=cfg.timestep_spacing,
        steps_offset=cfg.steps_offset,
        rescale_betas_zero_snr=False,
    )


def _import_diffusers() -> Any:
    os.environ.setdefault("HF_HUB_OFFLINE", "1")  # scheduler construction never needs the network
    try:
        import diffusers
    except ImportError as e:  # pragma: no cover - depends on the installation
        raise ConfigError("the diffusion schedulers need the 'diffusers' package (pip install diffusers)") from e
    return diffusers


def make_ddpm_scheduler(cfg: DiffusionConfig | None = None) -> Any:
    """A ``diffusers.DDPMScheduler`` for training (``add_noise``, ``alphas_cumprod``) from ``cfg``."""
    cfg = cfg or DiffusionConfig()
    return _import_diffusers().DDPMScheduler(variance_type=cfg.variance_type, **_common(cfg))


def make_ddim_scheduler(cfg: DiffusionConfig | None = None, num_inference_steps: int = 50,
                        backend: str = "emogesture") -> Any:
    """A DDIM scheduler for sampling from ``cfg``, with its timesteps already set to ``num_inference_steps``
    (call ``set_timesteps`` again to change the count; a count outside ``1..num_train_timesteps`` is a
    ``ConfigError``).

    ``backend``: ``emogesture`` (default) is :class:`emogesture.diffusion.ddim.DDIMSampler`, the same
    arithmetic as diffusers' without its import cost; ``diffusers`` is ``diffusers.DDIMScheduler``."""
    cfg = cfg or DiffusionConfig()
    if backend == "emogesture":
        from emogesture.diffusion.ddim import DDIMSampler

        scheduler = DDIMSampler(cfg)
    elif backend == "diffusers":
        scheduler = _import_diffusers().DDIMScheduler(set_alpha_to_one=cfg.set_alpha_to_one, **_common(cfg))
    else:
        raise ConfigError(f"DDIM backend must be emogesture or diffusers, got {backend!r}")
    if not 1 <= num_inference_steps <= cfg.num_train_timesteps:
        raise ConfigError(f"DDIM: num_inference_steps must be in 1..{cfg.num_train_timesteps}, got {num_inference_steps}")
    scheduler.set_timesteps(num_inference_steps)
    return scheduler
