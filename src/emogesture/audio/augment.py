"""Training-only fbank augmentation (docs/design.md, 'Audio front end'): SpecAugment masks, Gaussian noise,
circular time shift.

Applied to normalised fbank windows in the order of AST's data loader: one frequency mask and one time
mask (set to ``mask_value``, 0 = the mean in the normalised domain), then additive Gaussian noise, then a
random circular shift along time. Every random draw comes from the caller's ``torch.Generator`` (on the
CPU), so the result is a function of the generator state; the same seed gives the same augmentation on
any device. Never used at evaluation or inference.
"""

from __future__ import annotations

import torch

__all__ = ["augment_fbank", "scramble_segments"]


def _randint(low: int, high_inclusive: int, n: int, generator: torch.Generator) -> torch.Tensor:
    """``n`` integers uniform in ``[low, high_inclusive]`` (CPU)."""
    return torch.randint(low, high_inclusive + 1, (n,), generator=generator)


def augment_fbank(
    x: torch.Tensor,
    generator: torch.Generator,
    freq_mask: int = 24,
    time_mask: int = 96,
    noise_std: float = 0.05,
    max_shift: int = 10,
    mask_value: float = 0.0,
) -> torch.Tensor:
    """Augment normalised fbank ``[B, T, F]`` or ``[T, F]``; returns a new tensor of the same shape.

    Per example: a frequency mask of width uniform in ``0..freq_mask`` bins and a time mask of width
    uniform in ``0..time_mask`` frames, each at a uniform position fully inside the window; i.i.d.
    ``N(0, noise_std²)`` noise on every element; a circular shift by an integer uniform in
    ``-max_shift..max_shift`` frames. Set any of ``freq_mask``, ``time_mask``, ``noise_std``, ``max_shift``
    to 0 to switch that part off.
    """
    if x.ndim not in (2, 3):
        raise ValueError(f"fbank must be [T, F] or [B, T, F], got shape {tuple(x.shape)}")
    if min(freq_mask, time_mask, max_shift) < 0 or noise_std < 0:
        raise ValueError("freq_mask, time_mask, noise_std and max_shift must be >= 0")
    single = x.ndim == 2
    y = (x.unsqueeze(0) if single else x).clone()
    b, t, f = y.shape
    device = y.device

    def mask_bounds(limit: int, size: int) -> tuple[torch.Tensor, torch.Tensor]:
        width = _randint(0, min(limit, size), b, generator)
        # start uniform in 0..size - width, drawn as floor(u * (size - width + 1)) for per-row ranges
        u = torch.rand(b, generator=generator, dtype=torch.float64)
        start = torch.floor(u * (size - width + 1).to(torch.float64)).to(torch.int64)
        start = torch.minimum(start, size - width)
        return start.to(device), (start + width).to(device)

    if freq_mask > 0:
        lo, hi = mask_bounds(freq_mask, f)
        idx = torch.arange(f, device=device)
        m = (idx[None, :] >= lo[:, None]) & (idx[None, :] < hi[:, None])  # [B, F]
        y = y.masked_fill(m[:, None, :], mask_value)
    if time_mask > 0:
        lo, hi = mask_bounds(time_mask, t)
        idx = torch.arange(t, device=device)
        m = (idx[None, :] >= lo[:, None]) & (idx[None, :] < hi[:, None])  # [B, T]
        y = y.masked_fill(m[:, :, None], mask_value)
    if noise_std > 0:
        noise = torch.randn((b, t, f), generator=generator, dtype=torch.float32)
        y = y + (noise_std * noise).to(device=device, dtype=y.dtype)
    if max_shift > 0 and t > 0:
        shifts = _randint(-max_shift, max_shift, b, generator).tolist()
        y = torch.stack([torch.roll(y[i], shifts=s, dims=0) for i, s in enumerate(shifts)])
    return y[0] if single else y


def scramble_segments(x: torch.Tensor, generator: torch.Generator, segment: int) -> torch.Tensor:
    """Cut every window of ``x [B, T, F]`` into segments of ``segment`` frames and put them in a random
    order, drawn per window from ``generator``; a trailing partial segment stays last.

    Every frame is kept, so the window's spectral and prosodic statistics (loudness, pitch level and
    range, spectral tilt, syllable rate) stay while the word order is destroyed: an emotion encoder
    trained on it cannot key on which text is spoken.
    """
    if x.ndim != 3:
        raise ValueError(f"fbank must be [B, T, F], got shape {tuple(x.shape)}")
    if segment < 1:
        raise ValueError(f"segment must be at least 1 frame, got {segment}")
    b, t, _ = x.shape
    n = t // segment
    if n < 2:
        return x.clone()
    order = torch.stack([torch.randperm(n, generator=generator) for _ in range(b)])  # [B, n]
    frames = (order[:, :, None] * segment + torch.arange(segment)).reshape(b, n * segment)
    frames = torch.cat([frames, torch.arange(n * segment, t).expand(b, -1)], dim=1).to(x.device)
    return torch.gather(x, 1, frames[:, :, None].expand(-1, -1, x.shape[2]))
