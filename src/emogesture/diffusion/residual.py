"""Residual noise: the part of a latent that the denoiser's ẑ0 estimate leaves out, added back.

A denoiser trained to predict ẑ0 (the ``tiny`` preset's ``prediction_type="sample"``) regresses to the
conditional mean, so its DDIM samples sit near E[z | c, e, s] and lose what the conditions do not fix —
in motion, the strokes whose exact timing the per-window audio latents do not carry (generated wrists
then move at a third of the real speed). Calibration measures the residuals ``z − ẑ`` between the
latents of real windows held out from training and the samples for their conditions; sampling then adds
``scale · L ε`` with ``L L^T`` their (shrunk) covariance. This is a Gaussian approximation of the
conditional spread around the denoiser's estimate, not part of the paper: see ``DiffusionConfig.residual_scale``.
"""

from __future__ import annotations

import numpy as np
import torch

from emogesture.diffusion.sampling import Generators, draw_noise


def shrunk_covariance(residuals: np.ndarray) -> tuple[np.ndarray, float]:
    """Ledoit–Wolf covariance of ``residuals [N, D]`` (rows = samples): ``(cov [D, D], shrinkage)``.

    scikit-learn's estimator: the sample covariance ``S`` (centred, divided by ``N``) is pulled toward
    ``μ I`` (``μ = tr S / D``) by the weight ``δ = min(b², d²) / d²``, ``d² = ‖S − μ I‖²_F``,
    ``b² = Σ_k ‖x_k x_kᵀ − S‖²_F / N²``; ``δ`` is clipped at 0 against rounding (``N = 2`` gives
    ``b² = 0``), and is 0 where ``S`` already is ``μ I`` (``D = 1``), where any weight gives the same matrix.
    Positive definite even when ``2 < N < D`` (held-out splits are small).
    """
    # imported here: scikit-learn takes about a second to import, and only fitting (not generation) needs it
    from sklearn import covariance

    x = np.asarray(residuals, np.float64)
    if x.ndim != 2 or x.shape[0] < 2:
        raise ValueError(f"residuals must be [N >= 2, D], got shape {x.shape}")
    delta = max(float(covariance.ledoit_wolf_shrinkage(x)), 0.0)
    return covariance.shrunk_covariance(covariance.empirical_covariance(x), delta), delta


def residual_factor(residuals: np.ndarray) -> tuple[np.ndarray, float]:
    """Lower-triangular ``L [D, D]`` with ``L Lᵀ`` = the shrunk covariance of ``residuals [N, D]``, and
    the shrinkage used: ``(L, shrinkage)``."""
    cov, shrinkage = shrunk_covariance(residuals)
    return np.linalg.cholesky(cov).astype(np.float32), shrinkage


def add_residual_noise(z: torch.Tensor, factor: torch.Tensor, generator: Generators,
                       scale: float | torch.Tensor = 1.0) -> torch.Tensor:
    """``z [B, D] + scale · ε Lᵀ`` with ``ε`` standard normal from ``generator`` (one per sample keeps
    samples batch-independent, see :mod:`emogesture.diffusion.sampling`); ``scale`` is a number or one
    per sample ``[B]``. A scale of 0 (a number) returns ``z`` unchanged and draws nothing."""
    if not torch.is_tensor(scale) and scale == 0:
        return z
    if torch.is_tensor(scale):
        scale = scale.to(z).reshape(-1, 1)
    if factor.shape != (z.shape[1], z.shape[1]):
        raise ValueError(f"residual factor must be [{z.shape[1]}, {z.shape[1]}], got {tuple(factor.shape)}")
    eps = draw_noise(generator, z.shape[0], z.shape[1], z.device, z.dtype)
    return z + scale * eps @ factor.to(z).T
