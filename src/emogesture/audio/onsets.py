"""Onset strength, onset detection and per-frame energy (gesture timing and beat align: docs/design.md,
'Synthetic corpus' and 'Metrics').

The reference is librosa (not a dependency): :func:`onset_strength` follows ``librosa.onset.onset_strength``
with its defaults — power mel spectrogram (n_fft 2048, periodic Hann, centred frames with zero padding,
128 Slaney mel bands up to Nyquist), ``power_to_db`` (``10 log10(max(S, 1e-10))``, clipped 80 dB below the
maximum), first difference along time (lag 1), half-wave rectified, mean over bands, shifted by
``lag + n_fft // (2 hop)`` frames so each value lines up with its frame. :func:`detect_onsets` follows
``librosa.onset.onset_detect``: min-max normalise the envelope, then ``librosa.util.peak_pick`` with the
defaults converted to frames as librosa does (``pre_max = 0.03 s``, ``post_max = 0 s + 1 frame``,
``pre_avg = 0.1 s``, ``post_avg = 0.1 s + 1 frame``, ``delta = 0.07``, ``wait = 0.03 s``).
"""

from __future__ import annotations

import numpy as np
import torch
from numpy.lib.stride_tricks import sliding_window_view

from emogesture.audio.io import TARGET_SAMPLE_RATE
from emogesture.audio.mel import librosa_mel_banks
from emogesture.audio.stft import as_float_tensor, stft_power

__all__ = ["onset_strength", "detect_onsets", "peak_pick", "frame_energy", "window_activity"]


def _mono(waveform: np.ndarray | torch.Tensor, dtype: torch.dtype | None = None) -> torch.Tensor:
    x = as_float_tensor(waveform, dtype)
    if x.ndim != 1:
        raise ValueError(f"waveform must be mono [N], got shape {tuple(x.shape)}")
    return x


def onset_strength(
    waveform: np.ndarray | torch.Tensor,
    sample_rate: int = TARGET_SAMPLE_RATE,
    hop_length: int = 512,
    *,
    n_fft: int = 2048,
    n_mels: int = 128,
    fmin: float = 0.0,
    fmax: float | None = None,
    lag: int = 1,
    top_db: float | None = 80.0,
    center: bool = True,
) -> np.ndarray:
    """Spectral-flux onset envelope ``[1 + N // hop_length]`` (float32), one value per hop (see module doc)."""
    if lag < 1:
        raise ValueError(f"lag must be >= 1, got {lag}")
    x = _mono(waveform)
    power = stft_power(x, n_fft, hop_length, center=center)  # [T, n_fft/2 + 1]
    banks = torch.tensor(np.array(librosa_mel_banks(float(sample_rate), n_fft, n_mels, fmin, fmax)),
                         dtype=power.dtype, device=power.device)
    mel = power @ banks.T  # [T, n_mels]
    db = 10.0 * torch.log10(mel.clamp_min(1e-10))
    if top_db is not None and db.numel():
        db = torch.maximum(db, db.max() - top_db)
    num_frames = db.shape[0]
    flux = (db[lag:] - db[:-lag]).clamp_min(0.0).mean(dim=-1) if num_frames > lag else db.new_zeros(0)
    pad = lag + (n_fft // (2 * hop_length) if center else 0)
    env = torch.cat([flux.new_zeros(pad), flux])
    if center:
        env = env[:num_frames]
    return env.cpu().numpy().astype(np.float32)


def peak_pick(
    x: np.ndarray, pre_max: int, post_max: int, pre_avg: int, post_avg: int, delta: float, wait: int
) -> np.ndarray:
    """``librosa.util.peak_pick``: indices ``n`` with ``x[n] == max(x[n - pre_max : n + post_max])``,
    ``x[n] >= mean(x[n - pre_avg : n + post_avg]) + delta`` (windows truncated at the ends) and more than
    ``wait`` samples after the previous peak."""
    if pre_max < 0 or pre_avg < 0 or wait < 0 or post_max < 1 or post_avg < 1 or delta < 0:
        raise ValueError("peak_pick needs pre_max, pre_avg, wait >= 0; post_max, post_avg >= 1; delta >= 0")
    x = np.asarray(x, dtype=np.float64).reshape(-1)
    n = x.size
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    idx = np.arange(n)
    # Sliding max over x[i - pre_max : i + post_max] and mean over x[i - pre_avg : i + post_avg].
    padded = np.concatenate([np.full(pre_max, -np.inf), x, np.full(post_max, -np.inf)])
    mov_max = sliding_window_view(padded, pre_max + post_max)[: n].max(axis=1)
    csum = np.concatenate([[0.0], np.cumsum(x)])
    lo = np.clip(idx - pre_avg, 0, n)
    hi = np.clip(idx + post_avg, 0, n)
    mov_avg = (csum[hi] - csum[lo]) / (hi - lo)
    candidates = np.flatnonzero((x == mov_max) & (x >= mov_avg + delta))
    peaks: list[int] = []
    last = -np.inf
    for i in candidates:
        if i > last + wait:
            peaks.append(int(i))
            last = i
    return np.asarray(peaks, dtype=np.int64)


def detect_onsets(
    waveform: np.ndarray | torch.Tensor,
    sample_rate: int = TARGET_SAMPLE_RATE,
    hop_length: int = 512,
    *,
    pre_max: float = 0.03,
    post_max: float = 0.0,
    pre_avg: float = 0.10,
    post_avg: float = 0.10,
    delta: float = 0.07,
    wait: float = 0.03,
    envelope: np.ndarray | None = None,
    **strength_params,
) -> np.ndarray:
    """Onset times in seconds (float64, ascending), as ``librosa.onset.onset_detect(units='time')``.

    The peak-picking parameters are in seconds and converted to frames as librosa does
    (``int(p * sample_rate // hop_length)``, plus one frame for ``post_max`` and ``post_avg``); ``delta`` is
    on the [0, 1]-normalised envelope. ``envelope`` reuses a precomputed :func:`onset_strength`;
    ``strength_params`` go to :func:`onset_strength` otherwise. Silence gives no onsets.
    """
    env = envelope if envelope is not None else onset_strength(waveform, sample_rate, hop_length, **strength_params)
    env = np.asarray(env, dtype=np.float64).reshape(-1)
    env = env - env.min() if env.size else env
    if not env.any():
        return np.zeros(0, dtype=np.float64)
    env = env / (env.max() + np.finfo(np.float32).tiny)

    def frames(seconds: float) -> int:
        return int(seconds * sample_rate // hop_length)

    peaks = peak_pick(
        env,
        pre_max=frames(pre_max),
        post_max=frames(post_max) + 1,
        pre_avg=frames(pre_avg),
        post_avg=frames(post_avg) + 1,
        delta=delta,
        wait=frames(wait),
    )
    return peaks.astype(np.float64) * hop_length / float(sample_rate)


def frame_energy(waveform: np.ndarray | torch.Tensor, sample_rate: int, fps: float = 30) -> np.ndarray:
    """RMS of the waveform per motion frame: ``[T]`` float32 with ``T = round(N / sample_rate * fps)``.

    Frame ``t`` covers samples ``[round(t N / T), round((t + 1) N / T))`` — an even partition of the whole
    waveform, each part ``≈ sample_rate / fps`` samples long.
    """
    single = getattr(waveform, "dtype", None) in (np.float32, torch.float32)  # squared in float64 all the same
    x = _mono(waveform, torch.float32 if single else None).cpu().numpy()
    n = x.size
    t = int(round(n / float(sample_rate) * fps))
    if t == 0:
        return np.zeros(0, dtype=np.float32)
    edges = np.round(np.arange(t + 1) * (n / t)).astype(np.int64)
    csum = np.empty(n + 1)  # float64, its running sums written in place (10 min of audio: 77 MB an array)
    csum[0] = 0.0
    np.cumsum(np.square(x, dtype=np.float64), out=csum[1:])
    counts = np.diff(edges)
    sums = csum[edges[1:]] - csum[edges[:-1]]
    rms = np.sqrt(np.maximum(sums, 0.0) / np.maximum(counts, 1))
    return rms.astype(np.float32)


def window_activity(waveform: np.ndarray | torch.Tensor, sample_rate: int, starts_s: list[float],
                    window_seconds: float | list[float] = 10.0, floor_db: float = -50.0,
                    range_db: float = 40.0) -> np.ndarray:
    """Share of each window's 1/30-s frames that hold sound: ``[W]`` in [0, 1] for windows starting at
    ``starts_s``, each ``window_seconds`` long (one length for all, or one per window). A frame counts when
    its RMS (:func:`frame_energy`) is above ``floor_db`` dBFS and within ``range_db`` of the loudest frame of
    the whole waveform; digital silence scores 0. Frames past the end of the waveform count as silent."""
    rms = frame_energy(waveform, sample_rate, fps=30)
    level = 20 * np.log10(np.maximum(rms, 1e-12))
    loudest = float(level.max()) if level.size else floor_db
    active = level > max(floor_db, loudest - range_db)
    lengths = np.broadcast_to(np.asarray(window_seconds, np.float64), (len(starts_s),))
    out = np.zeros(len(starts_s), np.float64)
    for i, (start, seconds) in enumerate(zip(starts_s, lengths)):
        first, frames = int(round(start * 30)), int(round(seconds * 30))
        out[i] = active[first:first + frames].sum() / frames
    return out
