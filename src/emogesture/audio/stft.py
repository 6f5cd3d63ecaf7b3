"""The one short-time power-spectrum helper, shared by the fbank features and the onset envelope."""

from __future__ import annotations

import numpy as np
import torch

__all__ = ["as_float_tensor", "compute_dtype", "frame_signal", "power_spectrum", "stft_power"]


def compute_dtype(device: torch.device) -> torch.dtype:
    """Float64 on the CPU (exact agreement with the C++ references), float32 on accelerators."""
    return torch.float64 if device.type == "cpu" else torch.float32


def as_float_tensor(waveform: np.ndarray | torch.Tensor, dtype: torch.dtype | None = None) -> torch.Tensor:
    """A numpy array or tensor as a floating tensor on its device (float64 on CPU unless ``dtype`` is given)."""
    if isinstance(waveform, torch.Tensor):
        x = waveform.detach()
    else:
        x = torch.from_numpy(np.ascontiguousarray(np.asarray(waveform)))
    if x.is_complex() or x.dtype == torch.bool:
        raise TypeError(f"waveform must be a real-valued array, got dtype {x.dtype}")
    return x.to(dtype or compute_dtype(x.device))


def frame_signal(x: torch.Tensor, frame_length: int, hop_length: int) -> torch.Tensor:
    """``[..., N] -> [..., F, frame_length]`` frames starting every ``hop_length`` samples (a view, no padding).

    ``F = 1 + (N - frame_length) // hop_length``, or 0 when ``N < frame_length``.
    """
    n = x.shape[-1]
    if n < frame_length:
        return x.new_zeros((*x.shape[:-1], 0, frame_length))
    return x.unfold(-1, frame_length, hop_length)


def power_spectrum(frames: torch.Tensor, n_fft: int) -> torch.Tensor:
    """``|rfft(frames, n_fft)|^2`` over the last axis; frames shorter than ``n_fft`` are zero-padded at the end."""
    if frames.numel() == 0:  # MKL refuses empty transforms
        return frames.new_zeros((*frames.shape[:-1], n_fft // 2 + 1))
    spec = torch.fft.rfft(frames, n=n_fft, dim=-1)
    return spec.real.square() + spec.imag.square()


def stft_power(
    x: torch.Tensor,
    n_fft: int,
    hop_length: int,
    win_length: int | None = None,
    center: bool = True,
    pad_mode: str = "constant",
) -> torch.Tensor:
    """Power spectrogram ``[..., frames, n_fft // 2 + 1]`` with a periodic Hann window (librosa's ``stft`` defaults).

    The window of ``win_length`` samples is centred inside ``n_fft``; with ``center`` the signal is padded
    by ``n_fft // 2`` on both sides (``pad_mode`` 'constant' or 'reflect'), giving ``1 + N // hop_length``
    frames whose ``t``-th is centred on sample ``t * hop_length``.
    """
    win_length = n_fft if win_length is None else int(win_length)
    if not 0 < win_length <= n_fft:
        raise ValueError(f"win_length must be in 1..n_fft={n_fft}, got {win_length}")
    window = torch.hann_window(win_length, periodic=True, dtype=x.dtype, device=x.device)
    left = (n_fft - win_length) // 2
    window = torch.nn.functional.pad(window, (left, n_fft - win_length - left))
    if center:
        pad = n_fft // 2
        if pad_mode == "reflect" and x.shape[-1] <= pad:
            pad_mode = "constant"  # reflect needs more samples than the pad; fall back like a zero pad
        shape = x.shape
        x = torch.nn.functional.pad(x.reshape(-1, 1, shape[-1]), (pad, pad), mode=pad_mode)
        x = x.reshape(*shape[:-1], x.shape[-1])
    frames = frame_signal(x, n_fft, hop_length)
    return power_spectrum(frames * window, n_fft)
