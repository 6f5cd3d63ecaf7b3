"""Fbank normalisation and the fixed 10 s / 1024-frame model windows (docs/design.md, 'Audio front end').

The audio encoders see ``[1024, bins]`` windows of *normalised* fbank, ``(x - mean) / (2 std)``, so zero
padding in the normalised domain is padding with the dataset mean. At the 10 ms shift, 10 s of audio give
998 Kaldi frames (:data:`WINDOW_CONTENT_FRAMES`); AST and the AMUSE release compute the fbank of the 10 s
clip and zero-pad it to 1024 frames. :func:`fbank_window` does the same when ``content_frames=998`` is passed
(the rest of the window is zeros even when the file goes on); by default it takes up to 1024 real frames.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import torch

from emogesture.audio.fbank import FLOAT32_EPS, FbankConfig, num_fbank_frames
from emogesture.audio.io import TARGET_SAMPLE_RATE

__all__ = [
    "FBANK_MEAN",
    "FBANK_STD",
    "WINDOW_FRAMES",
    "WINDOW_SECONDS",
    "FBANK_FRAMES_PER_SECOND",
    "WINDOW_CONTENT_FRAMES",
    "normalise_fbank",
    "normalise_recording",
    "speech_level",
    "RECORDING_NORMS",
    "denormalise_fbank",
    "fbank_window",
    "fbank_windows",
    "window_starts",
    "seconds_to_fbank_frame",
]

FBANK_MEAN: float = -9.173025
FBANK_STD: float = 5.062332
WINDOW_FRAMES: int = 1024
WINDOW_SECONDS: float = 10.0
FBANK_FRAMES_PER_SECOND: int = 100  # 10 ms shift
WINDOW_CONTENT_FRAMES: int = num_fbank_frames(int(WINDOW_SECONDS * TARGET_SAMPLE_RATE), FbankConfig())  # 998

Array = np.ndarray | torch.Tensor


def normalise_fbank(x: Array, mean: float = FBANK_MEAN, std: float = FBANK_STD) -> Array:
    """``(x - mean) / (2 * std)`` (AST's convention); same type as ``x``."""
    return (x - mean) / (2.0 * std)


RECORDING_NORMS = ("none", "level", "spectrum")
LOG_FLOOR = math.log(FLOAT32_EPS)  # Kaldi's floor of the mel energies (FbankConfig.log_floor)
ACTIVE_GATE_DB = 30.0  # frames this far below the recording's loud frames (95th percentile) are pauses


def fbank_float64(fbank: Array) -> np.ndarray:
    """A fbank (tensor or array) as a float64 numpy array, for per-recording statistics."""
    x = fbank.detach().cpu().numpy() if isinstance(fbank, torch.Tensor) else np.asarray(fbank)
    return x.astype(np.float64)


def fbank_like(out: np.ndarray, fbank: Array) -> Array:
    """``out`` in ``fbank``'s type, dtype and device."""
    if isinstance(fbank, torch.Tensor):
        return torch.as_tensor(out, dtype=fbank.dtype, device=fbank.device)
    return out.astype(np.asarray(fbank).dtype)


def normalise_recording(fbank: Array, mode: str, gate_db: float = ACTIVE_GATE_DB,
                        log_floor: float = LOG_FLOOR) -> Array:
    """One recording's raw log-mel fbank ``[F, n_mels]`` measured against the recording itself.

    A microphone's gain, distance and colouring say nothing about the speaker's emotion, but they move
    every log-mel bin. ``mode``:

    - ``"none"``: unchanged;
    - ``"level"``: the log of the active frames' mean mel power is subtracted (one number: the
      recording's speech level, as a gain would move it; bins at the log floor hardly count);
    - ``"spectrum"``: each bin's mean over the active frames is subtracted (the recording's long-term
      spectrum: level, channel and the voice's average colour; cepstral mean normalisation in the mel domain).

    Active frames: mean log-mel within ``gate_db`` of the 95th percentile over the recording, so pauses
    and silence do not count. Values at Kaldi's log floor (``log_floor``: a mel filter with no energy,
    digital silence), which no gain moves, stay where they are. Returns the same type as ``fbank``.
    """
    if mode not in RECORDING_NORMS:
        raise ValueError(f"recording normalisation {mode!r}: use one of {', '.join(RECORDING_NORMS)}")
    if mode == "none" or len(fbank) == 0:
        return fbank
    x = fbank_float64(fbank)
    active = _active_frames(x, gate_db)
    offset = _mean_power_log(active) if mode == "level" else active.mean(0)
    floor = x <= log_floor + 1e-4
    return fbank_like(np.where(floor, x, x - offset), fbank)


def _active_frames(x: np.ndarray, gate_db: float) -> np.ndarray:
    """The frames of a float64 log-mel fbank ``[F, n_mels]`` whose mean log-mel lies within ``gate_db`` of its
    95th percentile over the recording."""
    loudness = x.mean(1)
    gate = np.percentile(loudness, 95) - gate_db * math.log(10.0) / 10.0  # dB of power -> natural-log units
    return x[loudness >= gate]


def speech_level(fbank: Array, gate_db: float = ACTIVE_GATE_DB) -> float:
    """A recording's speech level from its raw log-mel fbank ``[F, n_mels]`` (non-empty): the log of its active
    frames' mean mel power (:func:`normalise_recording`), in natural-log units of power (× 10 / ln 10 for dB).
    A gain of g dB moves it by g dB."""
    return _mean_power_log(_active_frames(fbank_float64(fbank), gate_db))


def _mean_power_log(active: np.ndarray) -> float:
    """The log of the mean mel power of log-mel frames ``[F, n_mels]`` (computed from their largest value on)."""
    top = active.max()
    return float(top + math.log(float(np.exp(active - top).mean())))


def denormalise_fbank(x: Array, mean: float = FBANK_MEAN, std: float = FBANK_STD) -> Array:
    """Inverse of :func:`normalise_fbank`: ``x * 2 * std + mean``."""
    return x * (2.0 * std) + mean


def seconds_to_fbank_frame(seconds: float) -> int:
    """Index of the fbank frame starting at ``seconds`` (10 ms shift, rounded)."""
    return int(round(seconds * FBANK_FRAMES_PER_SECOND))


def fbank_window(
    normalised_fbank: Array,
    start_frame: int,
    num_frames: int = WINDOW_FRAMES,
    content_frames: int | None = None,
) -> Array:
    """Frames ``start_frame : start_frame + num_frames`` of a normalised ``[F, B]`` fbank as ``[num_frames, B]``.

    Frames outside ``[0, F)`` (past the end, or before the start for a negative ``start_frame``) are zeros,
    i.e. the mean in the normalised domain. With ``content_frames`` only the first ``content_frames`` rows
    of the window take real frames and the rest are zeros (the per-clip fbank + pad convention, see the
    module docstring). Returns the input's type (numpy or torch), dtype and device.
    """
    if num_frames < 0:
        raise ValueError(f"num_frames must be >= 0, got {num_frames}")
    is_numpy = not isinstance(normalised_fbank, torch.Tensor)
    x = torch.from_numpy(np.asarray(normalised_fbank)) if is_numpy else normalised_fbank
    if x.ndim != 2:
        raise ValueError(f"fbank must be [frames, bins], got shape {tuple(x.shape)}")
    total, bins = x.shape
    start = int(start_frame)
    keep = num_frames if content_frames is None else max(0, min(int(content_frames), num_frames))
    out = x.new_zeros((num_frames, bins))
    lo, hi = max(start, 0), min(start + keep, total)
    if hi > lo:
        out[lo - start : hi - start] = x[lo:hi]
    return out.numpy() if is_numpy else out


def fbank_windows(
    normalised_fbank: Array,
    starts: Sequence[int] | np.ndarray | torch.Tensor,
    num_frames: int = WINDOW_FRAMES,
    content_frames: int | None = None,
) -> Array:
    """Stack :func:`fbank_window` at each start frame: ``[W, num_frames, B]``."""
    starts = [int(s) for s in (starts.tolist() if hasattr(starts, "tolist") else starts)]
    wins = [fbank_window(normalised_fbank, s, num_frames, content_frames) for s in starts]
    if isinstance(normalised_fbank, torch.Tensor):
        if not wins:
            return normalised_fbank.new_zeros((0, num_frames, normalised_fbank.shape[-1]))
        return torch.stack(wins)
    if not wins:
        return np.zeros((0, num_frames, np.asarray(normalised_fbank).shape[-1]), np.asarray(normalised_fbank).dtype)
    return np.stack(wins)


def window_starts(
    num_seconds: float,
    window_seconds: float = WINDOW_SECONDS,
    hop_seconds: float | None = None,
    snap_seconds: float | None = None,
) -> np.ndarray:
    """Start times (s) of windows covering ``[0, num_seconds]``.

    Windows start every ``hop_seconds`` (default half a window, so neighbours overlap by 50 %); when the
    duration exceeds one window the last window is aligned to end exactly at ``num_seconds`` (unless a
    regular start already does). A duration of at most one window gives the single start 0 (the window is
    then padded). With ``snap_seconds`` (e.g. 0.1, a common multiple of the 10 ms fbank shift and the
    1/30 s motion frame) regular starts are rounded to that grid and the end-aligned start rounded *up*,
    so the window may extend by less than ``snap_seconds`` past the end.
    """
    if window_seconds <= 0:
        raise ValueError(f"window_seconds must be > 0, got {window_seconds}")
    hop = window_seconds / 2.0 if hop_seconds is None else float(hop_seconds)
    if not 0 < hop <= window_seconds:
        raise ValueError(f"hop_seconds must be in (0, window_seconds], got {hop_seconds}")
    duration = max(float(num_seconds), 0.0)
    eps = 1e-9
    if duration <= window_seconds + eps:
        return np.zeros(1, dtype=np.float64)
    last = duration - window_seconds
    count = int(math.floor(last / hop + eps)) + 1
    starts = [k * hop for k in range(count)]
    if snap_seconds:
        q = float(snap_seconds)
        starts = [round(s / q) * q for s in starts]
        last = math.ceil(last / q - eps) * q
    if last - starts[-1] > eps:
        starts.append(last)
    return np.asarray(sorted(set(round(s, 9) for s in starts)), dtype=np.float64)
