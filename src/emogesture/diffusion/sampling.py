"""The sampling loop and noise helpers, independent of any particular network or scheduler.

Randomness never comes from global state: every draw takes a ``torch.Generator``. A *generator
argument* is either one generator for the whole batch or a sequence of ``B`` generators, one per sample.
With one generator per sample (``make_generators(seeds)``) sample ``i`` depends only on its own
generator: the same seed gives the same result whether the sample is drawn alone or inside any batch.
With a single generator the batch is drawn as one tensor, so a sample's noise depends on its position.
"""

from __future__ import annotations

from contextlib import nullcontext
from typing import Any, Callable, Sequence, Union

import torch

Generators = Union[torch.Generator, Sequence[torch.Generator]]
Denoiser = Callable[[torch.Tensor, torch.Tensor, Sequence[torch.Tensor]], torch.Tensor]


def make_generators(seeds: Sequence[int], device: str | torch.device = "cpu") -> list[torch.Generator]:
    """One seeded ``torch.Generator`` per sample."""
    return [torch.Generator(device=device).manual_seed(int(s)) for s in seeds]


def draw_noise(
    generator: Generators, batch: int, dim: int, device: str | torch.device = "cpu",
    dtype: torch.dtype = torch.float32,
) -> torch.Tensor:
    """Standard normal noise ``[batch, dim]``; per-sample rows when ``generator`` is a sequence.

    The draw happens on the generator's device and is then moved to ``device``, so results do not
    depend on where the network runs.
    """
    if isinstance(generator, torch.Generator):
        return torch.randn(batch, dim, generator=generator, device=generator.device, dtype=dtype).to(device)
    gens = list(generator)
    if len(gens) != batch:
        raise ValueError(f"got {len(gens)} generators for a batch of {batch}")
    if not gens:
        return torch.empty(0, dim, device=device, dtype=dtype)
    rows = [torch.randn(dim, generator=g, device=g.device, dtype=dtype) for g in gens]
    return torch.stack([r.to(rows[0].device) for r in rows]).to(device)  # one copy to a GPU, not one a row


def sample_timesteps(
    generator: Generators, batch: int, num_train_timesteps: int = 1000, device: str | torch.device = "cpu"
) -> torch.Tensor:
    """Uniform training timesteps ``[batch]`` (int64) in ``0 .. num_train_timesteps - 1``."""
    if isinstance(generator, torch.Generator):
        t = torch.randint(0, num_train_timesteps, (batch,), generator=generator, device=generator.device)
        return t.to(device)
    gens = list(generator)
    if len(gens) != batch:
        raise ValueError(f"got {len(gens)} generators for a batch of {batch}")
    return torch.cat([torch.randint(0, num_train_timesteps, (1,), generator=g, device=g.device) for g in gens]).to(device)


def _timesteps(t: Any, batch: int, device: torch.device) -> torch.Tensor:
    t = torch.as_tensor(t, device=device).long()
    return t.expand(batch) if t.dim() == 0 else t


def add_noise(scheduler: Any, z0: torch.Tensor, noise: torch.Tensor, t: Any) -> torch.Tensor:
    """Forward diffusion ``q(z_t | z_0)``: ``sqrt(ᾱ_t)·z0 + sqrt(1 − ᾱ_t)·noise``.

    Args: a diffusers scheduler (DDPM/DDIM), ``z0 [B, D]``, ``noise [B, D]``, ``t`` an int or ``[B]``.
    Returns: ``z_t [B, D]``.
    """
    if z0.shape != noise.shape:
        raise ValueError(f"z0 {tuple(z0.shape)} and noise {tuple(noise.shape)} differ in shape")
    return scheduler.add_noise(z0, noise, _timesteps(t, z0.shape[0], z0.device))


def training_target(scheduler: Any, z0: torch.Tensor, noise: torch.Tensor, t: Any) -> torch.Tensor:
    """What the denoiser learns to output for ``z_t = add_noise(z0, noise, t)``, by the scheduler's
    ``prediction_type``: ``"epsilon"`` -> the noise; ``"sample"`` -> ``z0``; ``"v_prediction"`` ->
    ``v = sqrt(ᾱ_t)·noise − sqrt(1 − ᾱ_t)·z0``. All ``[B, D]``.
    """
    kind = scheduler.config.prediction_type
    if kind == "epsilon":
        return noise
    if kind == "sample":
        return z0
    if kind == "v_prediction":
        return scheduler.get_velocity(z0, noise, _timesteps(t, z0.shape[0], z0.device))
    raise ValueError(f"unknown prediction_type {kind!r}")


def ddim_sample(
    denoiser: Denoiser,
    scheduler: Any,
    conditions: Sequence[torch.Tensor],
    generator: Generators,
    num_inference_steps: int | None = None,
    batch_size: int | None = None,
    latent_dim: int | None = None,
    eta: float = 0.0,
    return_trajectory: bool = False,
    enable_grad: bool = False,
) -> torch.Tensor | tuple[torch.Tensor, torch.Tensor]:
    """Run the reverse diffusion from pure noise to a clean latent ``z0``.

    Args:
        denoiser: ``denoiser(z_t [B, D], t [B], conditions) -> [B, D]``, the scheduler's prediction
            (ε for the paper's ``prediction_type="epsilon"``; e.g. a ``LatentDenoiser``;
            its train/eval mode is the caller's business — use eval mode for reproducible samples).
        scheduler: a DDIM scheduler (:func:`make_ddim_scheduler`: ours or diffusers'); its ``timesteps``
            are used as set, unless ``num_inference_steps`` is given (then ``set_timesteps`` is called).
        conditions: the condition latents, each ``[B, C]`` (``(c, e, s)`` or ``(m,)``).
        generator: one generator or ``B`` generators (batch-independent results; see the module doc).
            Draws the initial noise and, when ``eta > 0``, the per-step variance noise.
        batch_size: needed only when ``conditions`` is empty.
        latent_dim: ``D``; defaults to ``denoiser.config.latent_dim``, else 256.
        eta: DDIM η (0 = deterministic DDIM).
        return_trajectory: also return every latent ``[S + 1, B, D]`` from the noise to ``z0``.
        enable_grad: keep autograd on (default: the loop runs under ``torch.no_grad``, as the paper's
            stop-gradient sg[z̃]).

    Returns: ``z0 [B, D]``, the last ``prev_sample`` (and the trajectory when asked). With the paper's
    ``set_alpha_to_one=False`` the last step lands on the noise level of t = 0 (ᾱ_0 = 1 − β_0), not on
    a clean sample: even a perfect predictor (of any ``prediction_type``) returns
    ``sqrt(ᾱ_0)·x0 + sqrt(1 − ᾱ_0)·ε`` (≈ 3 % noise).
    """
    if conditions:
        b, device, dtype = conditions[0].shape[0], conditions[0].device, conditions[0].dtype
    elif batch_size is not None:
        b, device, dtype = batch_size, torch.device("cpu"), torch.float32
    else:
        raise ValueError("ddim_sample needs conditions or a batch_size")
    if latent_dim is None:
        latent_dim = getattr(getattr(denoiser, "config", None), "latent_dim", 256)
    if num_inference_steps is not None:
        scheduler.set_timesteps(num_inference_steps)
    if scheduler.num_inference_steps is None:
        raise ValueError("the scheduler has no timesteps: pass num_inference_steps")
    z = draw_noise(generator, b, latent_dim, device, dtype)
    trajectory = [z]
    with nullcontext() if enable_grad else torch.no_grad():
        for t in scheduler.timesteps:
            out = denoiser(z, _timesteps(t, b, device), conditions)
            variance_noise = draw_noise(generator, b, latent_dim, device, dtype) if eta > 0 else None
            z = scheduler.step(out, t, z, eta=eta, variance_noise=variance_noise).prev_sample
            if return_trajectory:
                trajectory.append(z)
    if return_trajectory:
        return z, torch.stack(trajectory)
    return z
