"""Diffusion in the motion latent space (docs/design.md, 'Gesture generation model'): noise schedulers and the
sampling loop.

Kept apart from the networks (diffusers' separation of model, scheduler and loop): the loop takes any
callable ``denoiser(z_t [B, D], t [B], conditions) -> [B, D]`` whose output is what the
scheduler's ``prediction_type`` says (ε, ẑ0 or v). ``diffusers`` is imported lazily,
only when a scheduler is built.
"""

from emogesture.diffusion.sampling import (
    add_noise, ddim_sample, draw_noise, make_generators, sample_timesteps, training_target,
)
from emogesture.diffusion.schedulers import DiffusionConfig, make_ddim_scheduler, make_ddpm_scheduler

__all__ = [
    "DiffusionConfig",
    "add_noise",
    "ddim_sample",
    "draw_noise",
    "make_ddim_scheduler",
    "make_ddpm_scheduler",
    "make_generators",
    "sample_timesteps",
    "training_target",
]
