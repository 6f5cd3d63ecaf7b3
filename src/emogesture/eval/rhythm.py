"""Rhythm: how well arm motion follows the speech's timing, as a gain over mismatched audio
(docs/design.md, 'Metrics').

The measure, in pure functions of numpy arrays:

1. the audio's onset-strength envelope (:func:`emogesture.audio.onset_strength`, one value per 512-sample
   hop) read at every 1/30-s motion frame, and the mean speed of the arm joints (shoulders, elbows,
   wrists) per frame, each smoothed by a Gaussian of ``smooth_s``. The joint positions are first
   low-passed by a Gaussian of ``position_smooth_s`` (two frames): frame-to-frame jitter whose size
   follows the speech's loudness is not a gesture, yet its speed would follow the onsets (a model that
   read the raw onset strength frame by frame scored above the ground truth that way, with six times
   its jerk); strokes, which last a few tenths of a second, pass;
2. their Pearson correlation inside each window, with the motion lagging the audio by ``-max_lag_s`` to
   ``+max_lag_s``, averaged over the windows: a correlation curve over lags (:func:`lagged_correlation`);
3. the **rhythm score**: the curve's maximum (and its lag);
4. the **rhythm gain**: the score against the window's own audio minus the mean score of the same motion
   against mismatched audio — another window's audio (another text; several seeded draws) and the same
   take's audio shifted by 1 s or more (several shifts). Its **spread** is the standard deviation of the
   mismatched scores over those draws. Motion that follows the speech has a gain far above its spread;
   motion that ignores it (a still pose, a model without audio) has a gain within noise of zero.

A window in which either signal does not vary (a still pose) correlates 0. Every constant is a keyword
parameter whose default is listed in :data:`RHYTHM_CONSTANTS`, so reports print them. Randomness comes
only from an integer ``seed``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.ndimage import gaussian_filter1d

from emogesture.motion.skeleton import ARM_JOINTS

RHYTHM_CONSTANTS: dict = {
    "fps": 30.0,
    "onset_hop_length": 512,
    "smooth_s": 0.1,
    "position_smooth_s": 2 / 30,
    "max_lag_s": 0.5,
    "arm_joints": ARM_JOINTS,
    "other_window_draws": 4,
    "shifts_s": (1.0, 1.5, 2.0, 2.5),
    "discrimination_factor": 5.0,
    "noise_factor": 3.0,
    "seed": 0,
}
_C = RHYTHM_CONSTANTS


def envelope_at_frames(envelope: np.ndarray, sample_rate: int, num_frames: int, fps: float = _C["fps"],
                       hop_length: int = _C["onset_hop_length"]) -> np.ndarray:
    """An onset envelope with one value per ``hop_length`` samples, read (linearly interpolated) at the
    times ``t / fps`` of ``num_frames`` motion frames: ``[N] -> [num_frames]`` float64. Past the
    envelope's end it holds its last value."""
    env = np.asarray(envelope, np.float64).reshape(-1)
    if env.size == 0:
        return np.zeros(num_frames)
    times = np.arange(env.size) * hop_length / float(sample_rate)
    return np.interp(np.arange(num_frames) / float(fps), times, env)


def arm_speed(joints: np.ndarray, fps: float = _C["fps"], arm_joints: Sequence[int] = _C["arm_joints"],
              position_smooth_s: float = _C["position_smooth_s"]) -> np.ndarray:
    """Mean speed (m/s) of the arm joints per frame: ``joints [..., T, J, 3] -> [..., T]``.

    The positions are low-passed first (Gaussian, σ ``position_smooth_s`` seconds; 0 = raw); central
    differences inside, one-sided at the two ends; needs ``T >= 2``."""
    x = np.asarray(joints, np.float64)[..., list(arm_joints), :]
    if x.shape[-3] < 2:
        raise ValueError(f"arm_speed needs at least 2 frames, got joints of shape {np.shape(joints)}")
    if position_smooth_s > 0:
        x = gaussian_filter1d(x, position_smooth_s * fps, axis=-3, mode="nearest")
    velocity = np.gradient(x, axis=-3) * float(fps)
    return np.linalg.norm(velocity, axis=-1).mean(axis=-1)


def smooth(x: np.ndarray, sigma_s: float = _C["smooth_s"], fps: float = _C["fps"]) -> np.ndarray:
    """Gaussian smoothing along the last axis (σ in seconds; edges held)."""
    x = np.asarray(x, np.float64)
    return gaussian_filter1d(x, sigma_s * fps, axis=-1, mode="nearest") if sigma_s > 0 else x


def lagged_correlation(audio: np.ndarray, motion: np.ndarray, max_lag: int) -> np.ndarray:
    """Mean over windows of the Pearson correlation of ``audio[t]`` with ``motion[t + lag]``:
    ``audio, motion [W, T] -> [2 max_lag + 1]`` for lags ``-max_lag .. max_lag`` frames (positive: the
    motion follows the audio). Each correlation uses the frames where both are defined; a window in which
    either signal is constant there contributes 0."""
    a, m = np.atleast_2d(np.asarray(audio, np.float64)), np.atleast_2d(np.asarray(motion, np.float64))
    if a.shape != m.shape:
        raise ValueError(f"audio {a.shape} and motion {m.shape} must have the same shape [W, T]")
    t = a.shape[1]
    if not 0 <= max_lag < t - 1:
        raise ValueError(f"max_lag must be in 0..{t - 2} for {t} frames, got {max_lag}")
    curve = np.empty(2 * max_lag + 1)
    for k, lag in enumerate(range(-max_lag, max_lag + 1)):
        x = a[:, max(0, -lag): t - max(0, lag)]
        y = m[:, max(0, lag): t - max(0, -lag)]
        x = x - x.mean(axis=1, keepdims=True)
        y = y - y.mean(axis=1, keepdims=True)
        den = np.sqrt((x * x).sum(axis=1) * (y * y).sum(axis=1))
        ok = den > 1e-12 * max(1.0, float(np.abs(x).max(initial=0) * np.abs(y).max(initial=0)))
        r = np.zeros(len(x))
        r[ok] = (x[ok] * y[ok]).sum(axis=1) / den[ok]
        curve[k] = r.mean()
    return curve


def rhythm_score(audio: np.ndarray, motion: np.ndarray, max_lag: int) -> tuple[float, int]:
    """The maximum of :func:`lagged_correlation` and its lag (frames)."""
    curve = lagged_correlation(audio, motion, max_lag)
    k = int(np.argmax(curve))
    return float(curve[k]), k - max_lag


def other_window_pairs(texts: Sequence, seed: int, draws: int) -> list[np.ndarray]:
    """``draws`` seeded assignments of another window to every window: ``[W]`` indices, each window
    paired with a window of another text (any other window when every window has the same text)."""
    texts = np.asarray(texts)
    n = len(texts)
    out = []
    for d in range(draws):
        rng = np.random.default_rng([seed, 18, d])
        idx = np.empty(n, np.int64)
        for i in range(n):
            candidates = np.flatnonzero(texts != texts[i])
            if not len(candidates):
                candidates = np.delete(np.arange(n), i) if n > 1 else np.arange(n)
            idx[i] = rng.choice(candidates)
        out.append(idx)
    return out


def cut_windows(takes: dict[str, np.ndarray], window_takes: Sequence[str], start_frames: Sequence[int],
                frames: int, shift_frames: int = 0) -> np.ndarray:
    """Per-frame signals of whole takes (take -> ``[N]``) cut into windows: ``[W, frames]``. With
    ``shift_frames`` each window is read that much later in its take, or as much earlier when that runs
    past the end; what still lies outside the take holds the edge value."""
    out = np.empty((len(window_takes), frames))
    for i, (take, start) in enumerate(zip(window_takes, start_frames)):
        signal = np.asarray(takes[take], np.float64)
        s = start + shift_frames
        if s + frames > len(signal) or s < 0:
            s = start - shift_frames
        idx = np.clip(np.arange(s, s + frames), 0, len(signal) - 1)
        out[i] = signal[idx]
    return out


def rhythm_gain(motion_speed: np.ndarray, audio: np.ndarray, mismatched: dict[str, np.ndarray],
                fps: float = _C["fps"], smooth_s: float = _C["smooth_s"], max_lag_s: float = _C["max_lag_s"]) -> dict:
    """The rhythm of one motion source: ``motion_speed [W, T]`` (:func:`arm_speed`) against its own audio
    envelope ``audio [W, T]`` and against each mismatched envelope (name -> ``[W, T]``).

    Returns ``score`` and ``lag_s`` (own audio), ``mismatched`` (name -> score), ``gain`` (score minus the
    mean mismatched score), ``spread`` (standard deviation of the mismatched scores, ddof 1) and
    ``gain_over_spread``."""
    if len(mismatched) < 2:
        raise ValueError("rhythm_gain needs at least two mismatched draws for a spread")
    max_lag = int(round(max_lag_s * fps))
    m = smooth(motion_speed, smooth_s, fps)
    score, lag = rhythm_score(smooth(audio, smooth_s, fps), m, max_lag)
    others = {name: rhythm_score(smooth(a, smooth_s, fps), m, max_lag)[0] for name, a in mismatched.items()}
    values = np.array(list(others.values()))
    gain, spread = score - float(values.mean()), float(values.std(ddof=1))
    return {"score": score, "lag_s": lag / fps, "mismatched": others, "gain": gain, "spread": spread,
            "gain_over_spread": gain / spread if spread > 0 else (0.0 if gain == 0 else float("inf"))}


def discriminates(result: dict, factor: float = _C["discrimination_factor"]) -> bool:
    """The gain is at least ``factor`` times its spread (and positive)."""
    return result["gain"] > 0 and result["gain"] >= factor * result["spread"]


def within_noise(result: dict, factor: float = _C["noise_factor"]) -> bool:
    """The gain lies within ``factor`` spreads of zero."""
    return abs(result["gain"]) <= factor * result["spread"]


def mismatched_envelopes(envelopes: dict[str, np.ndarray], window_takes: Sequence[str], start_frames: Sequence[int],
                         texts: Sequence, frames: int, seed: int = 0, draws: int = _C["other_window_draws"],
                         shifts_s: Sequence[float] = _C["shifts_s"], fps: float = _C["fps"]
                         ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Per-frame audio envelopes of whole takes (take -> ``[N]``) -> the windows' own envelopes
    ``[W, frames]`` and the mismatched ones (name -> ``[W, frames]``): ``draws`` seeded draws of another
    window's audio (:func:`other_window_pairs`) and the same take shifted by each of ``shifts_s``."""
    own = cut_windows(envelopes, window_takes, start_frames, frames)
    out = {f"other window, draw {d}": own[idx] for d, idx in enumerate(other_window_pairs(texts, seed, draws))}
    for s in shifts_s:
        out[f"shifted {s:g} s"] = cut_windows(envelopes, window_takes, start_frames, frames, int(round(s * fps)))
    return own, out


def consecutive_windows(lengths: dict[str, int], frames: int) -> tuple[list[str], list[int]]:
    """Whole takes (take -> frame count) cut into consecutive windows of ``frames`` (a shorter tail is
    dropped): the windows' takes and start frames."""
    takes, starts = [], []
    for take, n in lengths.items():
        for s in range(0, n - frames + 1, frames):
            takes.append(take)
            starts.append(s)
    return takes, starts
