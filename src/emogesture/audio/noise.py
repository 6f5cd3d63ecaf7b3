"""Steady background noise taken out of a recording's log-mel fbank before the speech model hears it.

A fan, a hiss or a distant road fills every pause of a recording, and a speech model that has heard its
voices in quiet rooms reads that floor as part of the voice (in white noise at 10 dB SNR the held-out
voices' emotion was heard right in 0.71 of the windows, against 0.89 as recorded). Spectral subtraction
in the mel domain takes it out: each mel bin's noise power is estimated as a low quantile of that bin's
power over the whole recording (the pauses), and ``over_subtraction`` times it is subtracted from every
frame, never below ``floor``² of the frame's own power (the spectral floor keeps the residue from
turning into the isolated spikes of "musical noise").

Only a noisy recording is changed. How noisy is read from the recording's *dynamic range*: the distance
in dB between its loud frames (95th percentile of the frames' mean mel power) and its quiet ones (10th
percentile). Speech recorded in a quiet room, reverberant or not, spans 23 dB or more (the corpus's
voices 27–49 dB through every change the robustness reports make but noise; the real recordings of the
checks 41–76 dB), speech in white noise at 10 dB SNR 4–12 dB. The subtraction is full below
``full_below_db``, none above ``off_above_db`` and scaled linearly between, so a recording in range is
returned as it is, bit for bit; no bin is taken below Kaldi's log floor. Recordings shorter than
``min_seconds`` (the first seconds of a live stream) are left alone: their quantiles say little about
the pauses.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from emogesture.audio.windows import FBANK_FRAMES_PER_SECOND, LOG_FLOOR, fbank_float64, fbank_like

__all__ = ["NoiseSuppression", "digital_silence", "dynamic_range_db", "fill_digital_silence", "suppress_noise",
           "suppression_strength"]

Array = np.ndarray | torch.Tensor


@dataclass(frozen=True)
class NoiseSuppression:
    """Settings of :func:`suppress_noise` (chosen on the val split's held-out voices in noise)."""

    #: Times the estimated noise power subtracted from each bin (at full strength).
    over_subtraction: float = 2.0
    #: Amplitude floor: a bin keeps at least ``floor``² of its power.
    floor: float = 0.1
    #: Percentile of a bin's power over the recording taken as its noise power.
    noise_percentile: float = 10.0
    #: Full subtraction for a dynamic range (dB) at or below this ...
    full_below_db: float = 10.0
    #: ... none at or above this, linear between.
    off_above_db: float = 20.0
    #: Recordings shorter than this (seconds) are left alone.
    min_seconds: float = 5.0

    def __post_init__(self) -> None:
        if not (self.over_subtraction >= 0 and 0 < self.floor <= 1 and 0 <= self.noise_percentile <= 100
                and self.full_below_db < self.off_above_db and self.min_seconds >= 0):
            raise ValueError(f"noise suppression settings out of range: {self}")


def column_percentiles(x: np.ndarray, q: float) -> np.ndarray:
    """``np.percentile(x, q, axis=0)`` of a float64 ``[F, B]`` (linear interpolation, the same values) for
    a ``q`` near either end, from the few order statistics it needs (a live stream measures its window at
    every update; a full partition of each column costs seven times as much)."""
    n = len(x)
    position = q / 100.0 * (n - 1)
    low = int(math.floor(position))
    t = position - low
    high = min(low + 1, n - 1)
    smallest = q <= 50.0
    need = high + 1 if smallest else n - low  # order statistics low and high, counted from the nearer end
    if n < 2 or need > n // 2:
        return np.percentile(x, q, axis=0)
    picked = torch.topk(torch.from_numpy(np.ascontiguousarray(x.T)), need, dim=1, largest=not smallest).values
    a, b = (picked[:, low], picked[:, high]) if smallest else (picked[:, n - 1 - low], picked[:, n - 1 - high])
    a, b = a.numpy(), b.numpy()
    diff = b - a  # numpy's lerp: from the nearer end, so that t = 1 gives b exactly
    return np.where(t >= 0.5, b - diff * (1.0 - t), a + diff * t)


def dynamic_range_db(fbank: Array) -> float:
    """dB between the loud (95th percentile) and quiet (10th) frames' mean mel power of a log-mel fbank
    ``[F, n_mels]``."""
    x = torch.from_numpy(fbank_float64(fbank))
    frame_power = (torch.logsumexp(x, 1) - math.log(x.shape[1])).numpy()  # log of the mean mel power
    loud, quiet = np.percentile(frame_power, [95, 10])
    return float(10.0 / math.log(10.0) * (loud - quiet))


def suppression_strength(fbank: Array, settings: NoiseSuppression = NoiseSuppression()) -> float:
    """How much of its noise :func:`suppress_noise` takes out of a recording's log-mel fbank ``[F, n_mels]``:
    1 at a dynamic range of ``full_below_db`` or less, 0 from ``off_above_db`` on (and for a recording
    shorter than ``min_seconds`` or no subtraction at all), linear between."""
    if len(fbank) < settings.min_seconds * FBANK_FRAMES_PER_SECOND or settings.over_subtraction == 0.0:
        return 0.0
    span = settings.off_above_db - settings.full_below_db
    return min(max((settings.off_above_db - dynamic_range_db(fbank)) / span, 0.0), 1.0)


def suppress_noise(fbank: Array, settings: NoiseSuppression = NoiseSuppression(),
                   strength: float | None = None) -> Array:
    """One recording's raw log-mel fbank ``[F, n_mels]`` with its steady noise subtracted, scaled by how
    noisy the recording is (``strength``; None: :func:`suppression_strength`, for a caller that has not
    measured it); a recording in range, or too short, is returned as it is. Returns the same type as
    ``fbank``."""
    strength = suppression_strength(fbank, settings) if strength is None else strength
    if strength == 0.0:
        return fbank
    x = fbank_float64(fbank)
    noise = column_percentiles(x, settings.noise_percentile)  # [n_mels], log power
    # log(max(P − a·N, f²·P)) = x + log(max(1 − a·N/P, f²)), computed in the log domain (no overflow)
    keep = np.maximum(1.0 - strength * settings.over_subtraction * np.exp(noise[None] - x), settings.floor ** 2)
    # nothing goes below Kaldi's log floor (digital silence, the mel filter that covers no FFT bin stay there)
    return fbank_like(np.where(x <= LOG_FLOOR, x, np.maximum(x + np.log(keep), LOG_FLOOR)), fbank)


#: The percentile of each bin over a recording's other frames that its digital silence takes (chosen on the
#: val split's held-out voices with inserted silence and through a noise gate, against the 10th).
SILENCE_FILL_PERCENTILE = 1.0


def digital_silence(fbank: Array) -> np.ndarray:
    """``[F]`` bool: the frames of a log-mel fbank ``[F, n_mels]`` at Kaldi's log floor in every bin, exact
    zeros in the waveform (digital silence: no microphone records it)."""
    return fbank_float64(fbank).max(1) <= LOG_FLOOR + 1e-4


def fill_digital_silence(fbank: Array, percentile: float = SILENCE_FILL_PERCENTILE,
                         min_frames: int = FBANK_FRAMES_PER_SECOND // 2) -> Array:
    """A recording's log-mel fbank ``[F, n_mels]`` with its digital silence heard as the recording's own quiet:
    each frame of :func:`digital_silence` takes, bin by bin, the ``percentile`` of the other frames (the
    quietest the recording is elsewhere). Clips joined with inserted silence, a noise gate or padding give
    a recording pauses that no microphone and no training recording has; the speech model would read them
    as part of the voice. A recording with fewer than ``min_frames`` other frames (all silence, or nearly)
    is returned as it is, and so is one without digital silence. Same type as ``fbank``."""
    silent = digital_silence(fbank)
    if not silent.any() or (~silent).sum() < min_frames:
        return fbank
    x = fbank_float64(fbank)
    x[silent] = column_percentiles(x[~silent], percentile)
    return fbank_like(x, fbank)
