"""What happens to a gesture model's samples after the DDIM loop, as named steps in the order they run
(docs/design.md, 'Generation and editing'); their settings are a :class:`~emogesture.models.generation.GenerationConfig`.

1. :func:`add_residual`: the calibrated residual noise (the strokes the per-window audio latents leave
   open; :mod:`emogesture.diffusion.residual`) at ``residual_scale``, weighted per window by how much of
   it holds sound (:func:`residual_weights`: silence gets none);
2. :func:`guide_timing`: for a decoder that reads the speech's timing stream, the stream's part of the
   decoded motion scaled by ``timing_guidance``;
3. :func:`filter_output`: a Gaussian smoothing (``output_smoothing``) and a zero-phase low-pass
   (``output_lowpass_hz``) over time;
4. :func:`settle_quiet_windows`: a window with little sound is blended toward itself smoothed over time,
   so a silent stretch gives a calm animation;
5. the seams: every window of a long audio is drawn ``seam_candidates`` times and one candidate per
   window is kept, chosen together over the whole audio (:func:`choose_seam_candidates`: the sequence
   whose worst seam moves least, a seam's cost being the largest frame-to-frame joint displacement of its
   cross-fade); then the windows are cross-faded in the 6D rotation features (:func:`stitch`, a
   raised-cosine ramp over each overlap).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import torch
from torch import Generator

from emogesture.diffusion.residual import add_residual_noise
from emogesture.motion import MotionFeatureSpec, guide_features
from emogesture.motion.filters import gaussian_smooth, lowpass

#: Seams whose cross-fades are costed in one forward kinematics (:func:`choose_seam_candidates`): with 4
#: candidates a window, 16 seams are 256 cross-fades of ~90 frames, about 150 MB of work space.
SEAMS_PER_BATCH = 16
#: Share of a window's frames with sound (:func:`emogesture.audio.window_activity`) from which its
#: residual noise is added in full; below it the noise shrinks linearly to none for silence.
FULL_RESIDUAL_ACTIVITY = 0.5
#: Standard deviation (s) of the Gaussian over time toward which a quiet window's motion settles.
SETTLE_SIGMA_SECONDS = 1.0


def residual_weights(activity: np.ndarray) -> np.ndarray:
    """Windows' share of frames with sound ``[W]`` (:func:`emogesture.audio.window_activity`) -> their
    residual-noise weights ``[W]`` in [0, 1]: none for silence, in full from :data:`FULL_RESIDUAL_ACTIVITY`
    (every window of the corpus's speech has at least 0.6)."""
    return np.clip(np.asarray(activity) / FULL_RESIDUAL_ACTIVITY, 0.0, 1.0)


def add_residual(z: torch.Tensor, model: torch.nn.Module, generators: list[Generator], scale: float,
                 weights: np.ndarray | None = None) -> torch.Tensor:
    """Step 1. Sampled latents ``[B, 256]`` plus the model's calibrated residual noise at ``scale``
    (times ``weights [B]`` when given), drawn from the windows' own generators after their DDIM noise;
    ``z`` unchanged for a model without a calibration."""
    if not model.calibrated:
        return z
    if weights is not None:
        scale = scale * torch.as_tensor(np.asarray(weights, np.float32))
    return add_residual_noise(z, model.latent_residual_tril, generators, scale)


def guide_timing(heard: torch.Tensor, deaf: torch.Tensor, mean: torch.Tensor, std: torch.Tensor,
                 guidance: float, spec: MotionFeatureSpec) -> torch.Tensor:
    """Step 2. The decoder's normalised output with and without the timing stream ``[B, T, D]`` -> raw
    features ``[B, T, D]``: ``deaf + w · (heard − deaf)`` in raw units, where the 6D columns live, with
    ``w`` lowered where a joint's column would turn round (:func:`emogesture.motion.guide_features`)."""
    return guide_features(torch.addcmul(mean, deaf.float(), std), torch.addcmul(mean, heard.float(), std),
                          guidance, spec)


def filter_output(features: torch.Tensor, smoothing: float, cutoff_hz: float) -> torch.Tensor:
    """Step 3. Raw features ``[B, T, D]`` smoothed by a Gaussian of ``smoothing`` frames, then low-passed at
    ``cutoff_hz`` (each step skipped at 0). Both filters have unit gain, so they commute with the features'
    normalisation."""
    if smoothing > 0:
        features = gaussian_smooth(features, smoothing)
    if cutoff_hz > 0:
        features = lowpass(features, cutoff_hz)
    return features

def settle_quiet_windows(features: np.ndarray, weights: np.ndarray, fps: float) -> np.ndarray:
    """Step 4. Drawn windows' motion features ``[W, T, D]`` with their sound weights ``[W]`` in [0, 1] (1: at
    least :data:`FULL_RESIDUAL_ACTIVITY` of the window holds sound) -> the same, each window blended by
    ``1 − weight`` toward itself smoothed over time (a Gaussian of :data:`SETTLE_SIGMA_SECONDS`): a
    silent window keeps its slow posture changes and loses its strokes; a window with speech is unchanged."""
    quiet = np.asarray(weights, np.float64) < 1.0
    if not quiet.any():
        return features
    out = features.copy()
    smooth = gaussian_smooth(torch.from_numpy(features[quiet].astype(np.float64)), SETTLE_SIGMA_SECONDS * fps).numpy()
    w = np.asarray(weights, np.float64)[quiet][:, None, None]
    out[quiet] = (w * features[quiet] + (1.0 - w) * smooth).astype(features.dtype)
    return out


def crossfade_ramp(overlap: int) -> np.ndarray:
    """The incoming window's weights ``[overlap]`` over an overlap (raised cosine from 0 to 1)."""
    return 0.5 - 0.5 * np.cos(np.pi * (np.arange(overlap) + 0.5) / overlap)


def crossfade_weights(num_frames: int, starts: list[int], window: int) -> np.ndarray:
    """Per-window frame weights ``[W, window]`` that sum to 1 over overlapping windows.

    Each window ramps up (raised cosine) over its overlap with the previous window and down over its
    overlap with the next one.
    """
    w = np.ones((len(starts), window), np.float64)
    for i in range(1, len(starts)):
        overlap = starts[i - 1] + window - starts[i]
        if overlap > 0:
            ramp = crossfade_ramp(overlap)
            w[i, :overlap] *= ramp
            w[i - 1, window - overlap :] *= 1.0 - ramp
    return w


def largest_joint_jumps(joints: np.ndarray | torch.Tensor) -> np.ndarray:
    """Joint positions ``[..., T, J, 3]`` -> the largest joint displacement between frames ``[..., T - 1]``.

    The square root is taken of the largest squared displacement (the same number), with the three
    coordinates summed apart: an order of magnitude faster than a norm over a last axis of three."""
    joints = torch.as_tensor(joints)
    step = (joints[..., 1:, :, :] - joints[..., :-1, :, :]).square_()
    return (step[..., 0] + step[..., 1] + step[..., 2]).amax(-1).sqrt_().numpy()


def feature_jumps(frames: np.ndarray) -> np.ndarray:
    """Frame-to-frame change ``[K, L, D] -> [K, L - 1]`` (Euclidean norm over the features)."""
    return np.linalg.norm(np.diff(frames, axis=1), axis=-1)


def _crossfade_frames(previous: np.ndarray, incoming: np.ndarray, overlap: int) -> np.ndarray:
    """Every cross-fade of candidates ``previous [Ka, T, D]`` into ``incoming [Kb, T, D]`` over ``overlap``
    frames, with the frame on either side: ``[Ka · Kb, L, D]`` (``L = overlap + 2``, or ``overlap`` when the
    windows overlap whole)."""
    ka, kb, t, d = len(previous), len(incoming), previous.shape[1], previous.shape[2]
    frames = np.empty((ka, kb, overlap + 2 * (overlap < t), d), np.result_type(previous, incoming))
    faded = frames[:, :, 1: overlap + 1] if overlap < t else frames
    if overlap < t:  # the frame before the overlap (previous window) and after it (the incoming one)
        frames[:, :, 0] = previous[:, None, t - overlap - 1]
        frames[:, :, -1] = incoming[None, :, overlap]
    ramp = crossfade_ramp(overlap).astype(frames.dtype)[None, None, :, None]
    np.multiply(1 - ramp, previous[:, None, t - overlap:], out=faded)
    faded += ramp * incoming[None, :, :overlap]
    return frames.reshape(ka * kb, *frames.shape[2:])


def seam_costs(previous: np.ndarray, incoming: np.ndarray, overlap: int,
               jumps: Callable[[np.ndarray], np.ndarray] = feature_jumps) -> np.ndarray:
    """The cost of each seam between candidates ``previous [Ka, T, D]`` and ``incoming [Kb, T, D]``
    overlapping by ``overlap`` frames -> ``[Ka, Kb]``: the largest jump of their cross-fade, taken over
    the overlap plus the frame on either side (``jumps`` maps frames ``[K, L, D]`` to jumps ``[K, L - 1]``).
    """
    return jumps(_crossfade_frames(previous, incoming, overlap)).max(axis=1).reshape(len(previous), len(incoming))


def _all_seam_costs(candidates: Sequence[np.ndarray], starts: list[int],
                    jumps: Callable[[np.ndarray], np.ndarray]) -> list[np.ndarray]:
    """:func:`seam_costs` of every seam (window ``i - 1`` into ``i``, ``i >= 1``; zeros where windows do not
    overlap). The cross-fades of up to :data:`SEAMS_PER_BATCH` seams of one overlap go through ``jumps``
    together: one forward kinematics for a minute of audio instead of one per seam (a 60-s clip's 8
    seams took about a quarter of the time), with memory bounded for long audio."""
    costs = {i: np.zeros((len(candidates[i - 1]), len(candidates[i]))) for i in range(1, len(candidates))}
    by_overlap: dict[int, list[int]] = {}
    for i in range(1, len(candidates)):
        overlap = starts[i - 1] + candidates[i].shape[1] - starts[i]
        if overlap > 0:
            by_overlap.setdefault(overlap, []).append(i)
    for overlap, seams in by_overlap.items():
        for first in range(0, len(seams), SEAMS_PER_BATCH):
            chunk = seams[first: first + SEAMS_PER_BATCH]
            frames = [_crossfade_frames(candidates[i - 1], candidates[i], overlap) for i in chunk]
            worst = jumps(np.concatenate(frames)).max(axis=1)
            for i, part in zip(chunk, np.split(worst, np.cumsum([len(f) for f in frames])[:-1])):
                costs[i] = part.reshape(costs[i].shape)
    return list(costs.values())


def choose_seam_candidates(candidates: Sequence[np.ndarray], starts: list[int],
                           jumps: Callable[[np.ndarray], np.ndarray] = feature_jumps) -> np.ndarray:
    """Per window, its candidates ``[K_i, T, D]`` (a ``[W, K, T, D]`` array works) -> windows ``[W, T, D]``.

    One candidate per window, chosen together (a bottleneck Viterbi path): the sequence whose largest
    seam cost (:func:`seam_costs`, the largest jump of a cross-fade) is smallest, and among those the
    one with the smallest sum of seam costs. Unlike choosing window by window, this can also pick the
    earlier window of a seam, e.g. one that does not stroke where the next one fades in. Ties go to the
    lower candidate index; with one candidate per window, or no overlaps, candidate 0 everywhere.
    """
    # per candidate of the current window, the best path ending there: its worst seam and its cost sum
    worst, total = np.zeros(len(candidates[0])), np.zeros(len(candidates[0]))
    back = []
    for cost in _all_seam_costs(candidates, starts, jumps):
        path_worst, path_total = np.maximum(worst[:, None], cost), total[:, None] + cost
        best = np.array([np.lexsort((path_total[:, b], path_worst[:, b]))[0] for b in range(cost.shape[1])])
        back.append(best)
        cols = np.arange(cost.shape[1])
        worst, total = path_worst[best, cols], path_total[best, cols]
    pick = [int(np.lexsort((total, worst))[0])]
    for b in reversed(back):
        pick.append(int(b[pick[-1]]))
    pick.reverse()
    return np.stack([candidates[i][k] for i, k in enumerate(pick)])


def stitch(windows: np.ndarray, starts: list[int], num_frames: int) -> np.ndarray:
    """Cross-fade generated windows ``[W, T, D]`` placed at frame ``starts`` into ``[num_frames, D]``."""
    n, t, d = windows.shape
    weights = crossfade_weights(num_frames, starts, t)
    out = np.zeros((max(num_frames, max(starts) + t), d), np.float64)
    norm = np.zeros(len(out), np.float64)
    for win, s, w in zip(windows, starts, weights):
        out[s : s + t] += w[:, None] * win
        norm[s : s + t] += w
    out = out[:num_frames] / np.maximum(norm[:num_frames, None], 1e-8)
    return out.astype(np.float32)


def candidates_drawn(windows: int, seam_candidates: int) -> int:
    """Candidates drawn per window: ``seam_candidates``, or 1 when a single window has no seam to
    choose for (candidate 0 would be kept: the same output, a quarter of the sampling)."""
    return seam_candidates if windows > 1 else 1
