"""Intonation: a speech recording's pitch (F0) track, and the same recording with its pitch moved.

- :func:`f0_track` — the pitch every 10 ms (normalised autocorrelation; NaN where unvoiced or quiet).
- :func:`intonation_span` — the span between the 10th and 90th percentile of a recording's pitch, in
  semitones: how far its intonation moves.
- :func:`reshape_pitch` — every voiced frame's pitch moved ``span`` times as far (in semitones) from the
  recording's median pitch, and the whole of it raised or lowered by some semitones, by pitch-synchronous
  overlap-add (TD-PSOLA): grains two pitch periods long, cut at the analysis pitch marks, are laid down
  again at the spacing of the new pitch, so the duration and the formants stay where they were
  (:func:`emogesture.audio.wave_augment.voice_shift` moves the formants with the pitch).

Used to measure and to change real recordings for the checks of the emotion perception
(`experiments/real_voice_emotions.py` gives a real voice each emotion's corpus prosody). Real read speech
moves its pitch further than the corpus's synthetic voices do: a span of 6.3-9.1 semitones for three of the
real recordings of :mod:`emogesture.data.real_speech` (2.8 for a man reading out card names), against a
median of 3.3 over the corpus's neutral takes (4.4 happy, 4.5 surprised; `experiments/perception/README.md`).
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import median_filter

from emogesture.audio import TARGET_SAMPLE_RATE as SAMPLE_RATE

HOP = 160  # 10 ms at 16 kHz
FRAME = 640  # 40 ms: two periods of the lowest pitch tracked
F0_MIN, F0_MAX = 70.0, 400.0
VOICING = 0.6  # the normalised autocorrelation's peak above which a frame is voiced
LOUD_DB = 20.0  # frames this far below the loud ones (the 70th percentile of energy) are not voiced
GAP_FRAMES = 5  # unvoiced gaps up to 50 ms inside voiced speech are bridged when the pitch is moved


def f0_track(x: np.ndarray, sample_rate: int = SAMPLE_RATE, voicing: float = VOICING) -> np.ndarray:
    """The pitch (Hz) of a waveform ``[N]`` every 10 ms, ``[(N - 640) // 160 + 1]``: the lag of the
    normalised autocorrelation's highest peak in 70-400 Hz (refined between lags by a parabola), where
    that peak exceeds ``voicing`` and the frame is within 20 dB of the loud frames; NaN elsewhere; a
    5-frame median filter removes single octave slips."""
    if sample_rate != SAMPLE_RATE:
        raise ValueError(f"expected {SAMPLE_RATE} Hz audio, got {sample_rate}")
    x = np.asarray(x, np.float64)
    n = (len(x) - FRAME) // HOP + 1
    if n <= 0:
        return np.zeros(0)
    idx = np.arange(FRAME)[None] + HOP * np.arange(n)[:, None]
    frames = x[idx]
    frames = frames - frames.mean(1, keepdims=True)
    spec = np.fft.rfft(frames, 2 * FRAME, axis=1)
    ac = np.fft.irfft(np.abs(spec) ** 2, axis=1)[:, :FRAME]
    lo, hi = int(sample_rate // F0_MAX), int(sample_rate // F0_MIN)
    r = ac[:, lo:hi + 1] / (ac[:, :1] + 1e-12)
    best = r.argmax(1)
    rows = np.arange(n)
    left, mid, right = r[rows, np.maximum(best - 1, 0)], r[rows, best], r[rows, np.minimum(best + 1, r.shape[1] - 1)]
    bend = left - 2 * mid + right
    offset = np.where(bend < 0, 0.5 * (left - right) / np.where(bend < 0, bend, -1.0), 0.0)  # parabolic peak
    f0 = sample_rate / (lo + best + np.clip(offset, -0.5, 0.5))
    energy = ac[:, 0]
    loud = energy > np.percentile(energy, 70) * 10 ** (-LOUD_DB / 10)
    peak = (best > 0) & (best < r.shape[1] - 1)  # a lag at the search's edge is a slope, not a period
    voiced = (mid > voicing) & loud & peak
    log_f0 = np.where(voiced, np.log(f0), np.nan)
    filled = np.where(voiced, log_f0, np.nanmedian(log_f0) if voiced.any() else 0.0)
    smooth = median_filter(filled, size=5, mode="nearest")
    return np.where(voiced, np.exp(smooth), np.nan)


def intonation_span(x: np.ndarray, sample_rate: int = SAMPLE_RATE) -> float:
    """The span (semitones) between the 10th and 90th percentile of a waveform's pitch over its voiced
    frames; NaN with fewer than 10 voiced frames."""
    f0 = f0_track(x, sample_rate)
    f0 = f0[np.isfinite(f0)]
    if len(f0) < 10:
        return float("nan")
    st = 12 * np.log2(f0)
    return float(np.percentile(st, 90) - np.percentile(st, 10))


def _bridge(f0: np.ndarray) -> np.ndarray:
    """``f0`` with unvoiced gaps of at most :data:`GAP_FRAMES` between voiced frames filled by
    interpolating the log pitch."""
    voiced = np.flatnonzero(np.isfinite(f0))
    out = f0.copy()
    for a, b in zip(voiced[:-1], voiced[1:]):
        if 1 < b - a <= GAP_FRAMES + 1:
            out[a + 1:b] = np.exp(np.interp(np.arange(a + 1, b), [a, b], np.log([f0[a], f0[b]])))
    return out


def _pitch_marks(x: np.ndarray, period: np.ndarray) -> np.ndarray:
    """Analysis marks: in voiced stretches one per period, each at the largest sample within a quarter
    period of where the previous period predicts it; every 10 ms elsewhere. ``period`` ``[N]`` in samples
    (0 where unvoiced)."""
    marks, t, n = [], 0, len(x)
    while t < n:
        p = period[t]
        if p <= 0:
            marks.append(t)
            t += HOP
            continue
        p = int(p)
        q = max(p // 4, 1)
        lo, hi = max(t - q, 0), min(t + q + 1, n)
        m = lo + int(np.argmax(x[lo:hi])) if not marks or marks[-1] < lo else t
        if marks and m <= marks[-1]:
            m = marks[-1] + p
        if m >= n:
            break
        marks.append(m)
        t = m + p
    return np.asarray(marks, np.int64)


def reshape_pitch(x: np.ndarray, span: float = 1.0, semitones: float = 0.0,
                  sample_rate: int = SAMPLE_RATE) -> np.ndarray:
    """A waveform ``[N]`` with each voiced frame's pitch moved ``span`` times as far (in semitones) from its
    median pitch over the voiced frames (1: unchanged; 2: a pitch range twice as wide; 0.5: flatter), then
    raised by ``semitones``, its duration and formants kept (TD-PSOLA); ``[N]``, float64. Unvoiced
    stretches are copied as they were; a recording with fewer than 10 voiced frames is returned as it was."""
    x = np.asarray(x, np.float64)
    f0 = _bridge(f0_track(x, sample_rate, voicing=0.45))
    voiced = np.isfinite(f0)
    if (span == 1.0 and semitones == 0.0) or voiced.sum() < 10:
        return x.copy()
    centre = np.exp(np.median(np.log(f0[voiced])))
    target = centre * 2.0 ** (semitones / 12.0) * (f0 / centre) ** span
    target = np.clip(target, F0_MIN / 1.5, F0_MAX * 1.5)
    # per-sample analysis and synthesis periods (frames are centred at HOP * i + FRAME / 2)
    frame_of = np.clip((np.arange(len(x)) - FRAME // 2) // HOP, 0, len(f0) - 1)
    period = np.where(voiced[frame_of], sample_rate / np.nan_to_num(f0[frame_of], nan=1.0), 0.0)
    new_period = np.where(voiced[frame_of], sample_rate / np.nan_to_num(target[frame_of], nan=1.0), 0.0)
    marks = _pitch_marks(x, period)
    out = np.zeros(len(x) + 2 * FRAME)
    t = 0
    while t < len(x):
        i = int(np.searchsorted(marks, t))
        if i == len(marks) or (i > 0 and t - marks[i - 1] < marks[i] - t):
            i -= 1
        a = int(marks[i])
        half = int(period[a]) or HOP  # a grain two periods long, or two hops where unvoiced
        lo, hi = max(a - half, 0), min(a + half, len(x))
        grain = x[lo:hi] * np.hanning(2 * half)[lo - (a - half): hi - (a - half)]
        start = t - (a - lo)
        if start >= 0:
            out[start: start + len(grain)] += grain
        else:
            out[: len(grain) + start] += grain[-start:]
        step = new_period[min(t, len(x) - 1)]
        t += int(round(step)) if step > 0 else HOP
    return out[: len(x)]
