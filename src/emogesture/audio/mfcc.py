"""MFCCs from a log-mel filterbank (for the paper's "no audio disentanglement" ablation)."""

from __future__ import annotations

import math

import torch


def dct_matrix(n_in: int, n_out: int, dtype: torch.dtype = torch.float32) -> torch.Tensor:
    """Orthonormal DCT-II basis ``[n_in, n_out]`` (as Kaldi's / HTK's cepstra, without liftering)."""
    n = torch.arange(n_in, dtype=torch.float64)
    k = torch.arange(n_out, dtype=torch.float64)
    basis = torch.cos(math.pi / n_in * (n[:, None] + 0.5) * k[None, :]) * math.sqrt(2.0 / n_in)
    basis[:, 0] /= math.sqrt(2.0)
    return basis.to(dtype)


def mfcc_from_log_mel(log_mel: torch.Tensor, n_mfcc: int = 13, time_pool: int = 1) -> torch.Tensor:
    """``log_mel [..., T, n_mels]`` -> MFCC ``[..., T // time_pool, n_mfcc]`` (frames averaged in groups)."""
    c = log_mel @ dct_matrix(log_mel.shape[-1], n_mfcc, log_mel.dtype).to(log_mel.device)
    if time_pool > 1:
        t = c.shape[-2] // time_pool * time_pool
        c = c[..., :t, :].reshape(*c.shape[:-2], t // time_pool, time_pool, n_mfcc).mean(-2)
    return c
