"""DDIM sampling steps without ``diffusers``: the same arithmetic as ``diffusers.DDIMScheduler``.

``emogesture generate`` draws every window with DDIM; importing diffusers costs more than a whole
``tiny`` generation of a 10-s clip (it pulls sympy in), so sampling uses this small scheduler, which
follows diffusers' DDIM step for every setting :class:`DiffusionConfig` allows (beta schedules,
timestep spacings, prediction types, ``set_alpha_to_one``, ``clip_sample``, η) and matches it to
float32 rounding (``tests/test_diffusion.py`` holds the two side by side). Training keeps diffusers'
DDPM scheduler for ``add_noise``.

DDIM (Song et al., 2021, eq. 12), from timestep ``t`` to ``t' = t − T / n``::

    x̂0 = the model's estimate (from ε, x0 or v),  ε̂ = the noise it implies
    σ = η · sqrt((1 − ᾱ_t') / (1 − ᾱ_t) · (1 − ᾱ_t / ᾱ_t'))
    x_t' = sqrt(ᾱ_t') · x̂0 + sqrt(1 − ᾱ_t' − σ²) · ε̂ + σ · z

with ``ᾱ_t'`` of a negative ``t'`` being 1 (``set_alpha_to_one``) or ``ᾱ_0``.
"""

from __future__ import annotations

import math
from dataclasses import asdict
from types import SimpleNamespace
from typing import Any, NamedTuple

import numpy as np
import torch


class DDIMStepOutput(NamedTuple):
    prev_sample: torch.Tensor
    pred_original_sample: torch.Tensor


def make_betas(schedule: str, steps: int, start: float, end: float) -> torch.Tensor:
    """β_1..β_T ``[T]`` float32 of a named schedule (diffusers' definitions)."""
    if schedule == "linear":
        return torch.linspace(start, end, steps, dtype=torch.float32)
    if schedule == "scaled_linear":
        return torch.linspace(start**0.5, end**0.5, steps, dtype=torch.float32) ** 2
    if schedule == "squaredcos_cap_v2":
        def alpha_bar(t: float) -> float:
            return math.cos((t + 0.008) / 1.008 * math.pi / 2) ** 2
        return torch.tensor([min(1 - alpha_bar((i + 1) / steps) / alpha_bar(i / steps), 0.999) for i in range(steps)],
                            dtype=torch.float32)
    raise ValueError(f"unknown beta schedule {schedule!r}")


class DDIMSampler:
    """A DDIM scheduler built from a :class:`~emogesture.diffusion.schedulers.DiffusionConfig`.

    The interface is the part of ``diffusers.DDIMScheduler`` the sampling loop uses: ``config``,
    ``alphas_cumprod [T]``, ``final_alpha_cumprod``, ``timesteps``, ``num_inference_steps``,
    ``set_timesteps(n)``, ``step(model_output, t, sample, eta, variance_noise)`` and ``get_velocity``.
    """

    def __init__(self, cfg: Any) -> None:
        self.config = SimpleNamespace(**asdict(cfg))
        c = self.config
        self.betas = make_betas(c.beta_schedule, c.num_train_timesteps, c.beta_start, c.beta_end)
        self.alphas_cumprod = torch.cumprod(1.0 - self.betas, dim=0)
        self.final_alpha_cumprod = torch.tensor(1.0) if c.set_alpha_to_one else self.alphas_cumprod[0]
        self.num_inference_steps: int | None = None
        self.timesteps = torch.from_numpy(np.arange(0, c.num_train_timesteps)[::-1].copy().astype(np.int64))

    def set_timesteps(self, num_inference_steps: int) -> None:
        c, n = self.config, int(num_inference_steps)
        if not 1 <= n <= c.num_train_timesteps:
            raise ValueError(f"num_inference_steps must be in 1..{c.num_train_timesteps}, got {n}")
        self.num_inference_steps = n
        if c.timestep_spacing == "linspace":
            t = np.linspace(0, c.num_train_timesteps - 1, n).round()[::-1].copy().astype(np.int64)
        elif c.timestep_spacing == "leading":
            ratio = c.num_train_timesteps // n
            t = (np.arange(0, n) * ratio).round()[::-1].copy().astype(np.int64) + c.steps_offset
        elif c.timestep_spacing == "trailing":
            t = np.round(np.arange(c.num_train_timesteps, 0, -c.num_train_timesteps / n)).astype(np.int64) - 1
        else:
            raise ValueError(f"unknown timestep spacing {c.timestep_spacing!r}")
        self.timesteps = torch.from_numpy(t)

    def step(self, model_output: torch.Tensor, timestep: int | torch.Tensor, sample: torch.Tensor, eta: float = 0.0,
             variance_noise: torch.Tensor | None = None, **_: Any) -> DDIMStepOutput:
        """One DDIM step from ``timestep`` for ``sample [B, D]`` given the model's output ``[B, D]``."""
        if self.num_inference_steps is None:
            raise ValueError("set_timesteps first")
        c = self.config
        t = int(timestep)
        prev_t = t - c.num_train_timesteps // self.num_inference_steps
        a_t = self.alphas_cumprod[t]
        a_prev = self.alphas_cumprod[prev_t] if prev_t >= 0 else self.final_alpha_cumprod
        b_t = 1 - a_t
        if c.prediction_type == "epsilon":
            x0 = (sample - b_t**0.5 * model_output) / a_t**0.5
            eps = model_output
        elif c.prediction_type == "sample":
            x0 = model_output
            eps = (sample - a_t**0.5 * x0) / b_t**0.5
        elif c.prediction_type == "v_prediction":
            x0 = a_t**0.5 * sample - b_t**0.5 * model_output
            eps = a_t**0.5 * model_output + b_t**0.5 * sample
        else:
            raise ValueError(f"unknown prediction_type {c.prediction_type!r}")
        if c.clip_sample:
            x0 = x0.clamp(-c.clip_sample_range, c.clip_sample_range)
        variance = (1 - a_prev) / b_t * (1 - a_t / a_prev)
        std = eta * variance**0.5
        prev = a_prev**0.5 * x0 + (1 - a_prev - std**2) ** 0.5 * eps
        if eta > 0:
            if variance_noise is None:
                raise ValueError("eta > 0 needs variance_noise (drawn by the caller from its generators)")
            prev = prev + std * variance_noise
        return DDIMStepOutput(prev, x0)

    def get_velocity(self, sample: torch.Tensor, noise: torch.Tensor, timesteps: torch.Tensor) -> torch.Tensor:
        """``v = sqrt(ᾱ_t)·noise − sqrt(1 − ᾱ_t)·sample`` for ``timesteps [B]``."""
        a = self.alphas_cumprod.to(sample.device, sample.dtype)[timesteps].reshape(-1, *[1] * (sample.dim() - 1))
        return a**0.5 * noise - (1 - a) ** 0.5 * sample

    def add_noise(self, original: torch.Tensor, noise: torch.Tensor, timesteps: torch.Tensor) -> torch.Tensor:
        """``sqrt(ᾱ_t)·x0 + sqrt(1 − ᾱ_t)·noise`` for ``timesteps [B]``."""
        a = self.alphas_cumprod.to(original.device, original.dtype)[timesteps].reshape(-1, *[1] * (original.dim() - 1))
        return a**0.5 * original + (1 - a) ** 0.5 * noise
