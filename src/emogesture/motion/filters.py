"""Filters over time for motion features ``[B, T, F]``: a Gaussian smoothing and a zero-phase low-pass."""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F

from emogesture.types import FPS


def gaussian_smooth(x: torch.Tensor, sigma: float) -> torch.Tensor:
    """``x [B, T, F]`` smoothed along T by a Gaussian of ``sigma`` frames (truncated at 3σ; the edges
    repeat the first and last frame)."""
    r = max(1, int(3 * sigma + 0.5))
    offsets = torch.arange(-r, r + 1, device=x.device, dtype=x.dtype)
    return _filter_over_time(x, torch.exp(-0.5 * (offsets / sigma) ** 2), odd_edges=False)


def lowpass(x: torch.Tensor, cutoff_hz: float, fps: float = FPS) -> torch.Tensor:
    """``x [B, T, F]`` low-passed along T at ``cutoff_hz``: zero phase, by a Hann-windowed sinc kernel
    reaching 3 cutoff periods each side (shortened to ``T - 1`` frames for short windows), unit gain at 0 Hz.

    The edges are extended by odd reflection (``2·x[0] − x[k]``), which keeps both the edge value and
    its slope, so a ramp passes unchanged and a window does not slow down towards its ends.
    """
    t = x.shape[1]
    r = min(math.ceil(3 * fps / cutoff_hz), t - 1)
    if r < 1:
        return x
    n = torch.arange(-r, r + 1, device=x.device, dtype=x.dtype)
    f = cutoff_hz / fps  # cycles per frame
    return _filter_over_time(x, torch.sinc(2 * f * n) * (0.5 + 0.5 * torch.cos(torch.pi * n / (r + 1))),
                             odd_edges=True)


def _filter_over_time(x: torch.Tensor, kernel: torch.Tensor, odd_edges: bool) -> torch.Tensor:
    """``x [B, T, F]`` convolved along T with ``kernel [2r + 1]`` (normalised to unit sum), each feature
    alone; the edges extended by ``r`` frames, repeating the end frames or, with ``odd_edges``, by odd
    reflection (``2·x[0] − x[k]``)."""
    r = (len(kernel) - 1) // 2
    y = x.transpose(1, 2)
    if odd_edges:
        y = torch.cat([2 * y[..., :1] - y[..., 1:r + 1].flip(-1), y, 2 * y[..., -1:] - y[..., -r - 1:-1].flip(-1)], -1)
    else:
        y = F.pad(y, (r, r), mode="replicate")
    kernel = (kernel / kernel.sum()).expand(x.shape[2], 1, -1)
    return F.conv1d(y, kernel, groups=x.shape[2]).transpose(1, 2)
