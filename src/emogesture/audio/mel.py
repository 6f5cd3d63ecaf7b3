"""Mel scales and triangular mel filterbanks — the one place they are built.

Two constructions are provided, because two references are matched:

* :func:`kaldi_mel_banks` — Kaldi's ``MelBanks`` (``feat/mel-computations.cc``): HTK mel scale
  ``1127 ln(1 + f/700)``, bin edges equally spaced in mel between ``low_freq`` and ``high_freq``, and the
  triangles evaluated *in the mel domain* at each FFT bin's mel value, unnormalised (peak 1). The FFT bin
  at Nyquist never gets weight (Kaldi loops over ``padded_window_size / 2`` bins). Used by the fbank
  features (docs/design.md, 'Audio front end').
* :func:`librosa_mel_banks` — ``librosa.filters.mel`` defaults: Slaney mel scale, triangles in the Hz
  domain, Slaney area normalisation. Used by the onset envelope (BA, docs/design.md, 'Metrics'), whose reference is
  ``librosa.onset.onset_detect``.

Filterbanks are cached and returned as read-only float64 arrays of shape ``[num_bins, n_fft // 2 + 1]``.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from emogesture.errors import ConfigError

__all__ = [
    "hz_to_mel_htk",
    "mel_to_hz_htk",
    "hz_to_mel_slaney",
    "mel_to_hz_slaney",
    "kaldi_mel_banks",
    "librosa_mel_banks",
    "kaldi_mel_edges",
]


def hz_to_mel_htk(freq: np.ndarray | float) -> np.ndarray:
    """HTK / Kaldi mel scale: ``1127 ln(1 + f / 700)``."""
    return 1127.0 * np.log1p(np.asarray(freq, dtype=np.float64) / 700.0)


def mel_to_hz_htk(mel: np.ndarray | float) -> np.ndarray:
    """Inverse of :func:`hz_to_mel_htk`: ``700 (exp(m / 1127) - 1)``."""
    return 700.0 * np.expm1(np.asarray(mel, dtype=np.float64) / 1127.0)


_SLANEY_F_SP = 200.0 / 3.0
_SLANEY_MIN_LOG_HZ = 1000.0
_SLANEY_MIN_LOG_MEL = _SLANEY_MIN_LOG_HZ / _SLANEY_F_SP  # 15
_SLANEY_LOGSTEP = np.log(6.4) / 27.0


def hz_to_mel_slaney(freq: np.ndarray | float) -> np.ndarray:
    """Slaney (Auditory Toolbox) mel scale, librosa's default: linear below 1 kHz, log above."""
    f = np.asarray(freq, dtype=np.float64)
    mel = f / _SLANEY_F_SP
    log_part = _SLANEY_MIN_LOG_MEL + np.log(np.maximum(f, _SLANEY_MIN_LOG_HZ) / _SLANEY_MIN_LOG_HZ) / _SLANEY_LOGSTEP
    return np.where(f >= _SLANEY_MIN_LOG_HZ, log_part, mel)


def mel_to_hz_slaney(mel: np.ndarray | float) -> np.ndarray:
    """Inverse of :func:`hz_to_mel_slaney`."""
    m = np.asarray(mel, dtype=np.float64)
    freq = _SLANEY_F_SP * m
    log_part = _SLANEY_MIN_LOG_HZ * np.exp(_SLANEY_LOGSTEP * (np.maximum(m, _SLANEY_MIN_LOG_MEL) - _SLANEY_MIN_LOG_MEL))
    return np.where(m >= _SLANEY_MIN_LOG_MEL, log_part, freq)


def _kaldi_freq_range(sample_rate: float, low_freq: float, high_freq: float) -> tuple[float, float]:
    nyquist = 0.5 * float(sample_rate)
    high = float(high_freq) if high_freq > 0.0 else nyquist + float(high_freq)
    low = float(low_freq)
    if not (0.0 <= low < nyquist and 0.0 < high <= nyquist and high > low):
        raise ConfigError(
            f"bad mel frequency range: low_freq={low_freq}, high_freq={high_freq} "
            f"(resolved to {low}..{high} Hz) at sample_rate={sample_rate}"
        )
    return low, high


def kaldi_mel_edges(
    num_bins: int, sample_rate: float, low_freq: float = 20.0, high_freq: float = 0.0
) -> np.ndarray:
    """``[num_bins, 3]`` (left, centre, right) edges of each Kaldi filter, in HTK mel.

    ``high_freq <= 0`` is an offset from Nyquist (0 means Nyquist), as in Kaldi.
    """
    if num_bins < 1:
        raise ConfigError(f"num_mel_bins must be >= 1, got {num_bins}")
    low, high = _kaldi_freq_range(sample_rate, low_freq, high_freq)
    mel_low, mel_high = float(hz_to_mel_htk(low)), float(hz_to_mel_htk(high))
    delta = (mel_high - mel_low) / (num_bins + 1)
    b = np.arange(num_bins, dtype=np.float64)[:, None]
    return mel_low + (b + np.arange(3, dtype=np.float64)[None, :]) * delta


@lru_cache(maxsize=32)
def kaldi_mel_banks(
    num_bins: int,
    padded_window_size: int,
    sample_rate: float,
    low_freq: float = 20.0,
    high_freq: float = 0.0,
) -> np.ndarray:
    """Kaldi's triangular mel filterbank as a dense ``[num_bins, padded_window_size // 2 + 1]`` matrix.

    Row ``m`` weights FFT bin ``k`` (frequency ``k * sample_rate / padded_window_size``) by the triangle
    ``(mel - left) / (centre - left)`` rising, ``(right - mel) / (right - centre)`` falling, zero outside
    the open interval ``(left, right)``. A filter narrower than the FFT bin spacing can be all zero (e.g.
    at 128 bins and 16 kHz); Kaldi refuses that, we keep it so its log energy sits at the floor.
    """
    if padded_window_size < 2:
        raise ConfigError(f"padded_window_size must be >= 2, got {padded_window_size}")
    edges = kaldi_mel_edges(num_bins, sample_rate, low_freq, high_freq)
    left, centre, right = edges[:, 0:1], edges[:, 1:2], edges[:, 2:3]
    num_fft_bins = padded_window_size // 2
    fft_bin_width = float(sample_rate) / padded_window_size
    mel = hz_to_mel_htk(fft_bin_width * np.arange(num_fft_bins, dtype=np.float64))[None, :]
    up = (mel - left) / (centre - left)
    down = (right - mel) / (right - centre)
    weights = np.where(mel <= centre, up, down)
    weights = np.where((mel > left) & (mel < right), weights, 0.0)
    out = np.zeros((num_bins, num_fft_bins + 1), dtype=np.float64)
    out[:, :num_fft_bins] = weights
    out.setflags(write=False)
    return out


@lru_cache(maxsize=32)
def librosa_mel_banks(
    sample_rate: float,
    n_fft: int,
    n_mels: int = 128,
    fmin: float = 0.0,
    fmax: float | None = None,
    htk: bool = False,
    norm: str | None = "slaney",
) -> np.ndarray:
    """``librosa.filters.mel`` as a ``[n_mels, n_fft // 2 + 1]`` matrix (Slaney scale and norm by default)."""
    if n_mels < 1 or n_fft < 2:
        raise ConfigError(f"bad mel filterbank size: n_mels={n_mels}, n_fft={n_fft}")
    if fmax is None:
        fmax = float(sample_rate) / 2.0
    if norm not in (None, "slaney"):
        raise ConfigError(f"mel norm must be None or 'slaney', got {norm!r}")
    to_mel, to_hz = (hz_to_mel_htk, mel_to_hz_htk) if htk else (hz_to_mel_slaney, mel_to_hz_slaney)
    fft_freqs = np.linspace(0.0, float(sample_rate) / 2.0, 1 + n_fft // 2)
    mel_pts = np.linspace(float(to_mel(fmin)), float(to_mel(fmax)), n_mels + 2)
    mel_f = to_hz(mel_pts)
    fdiff = np.diff(mel_f)
    ramps = mel_f[:, None] - fft_freqs[None, :]
    lower = -ramps[:-2] / fdiff[:-1, None]
    upper = ramps[2:] / fdiff[1:, None]
    weights = np.maximum(0.0, np.minimum(lower, upper))
    if norm == "slaney":
        weights *= (2.0 / (mel_f[2 : n_mels + 2] - mel_f[:n_mels]))[:, None]
    weights.setflags(write=False)
    return weights
