"""Evaluation metrics of docs/design.md, 'Metrics', as pure functions of numpy arrays.

FGD (Fréchet distance of feature sets), Div (mean pairwise L2 distance), BA (beat align), SRGR
(semantic-weighted joint recall), jerk and speed. Nothing here reads files or touches the global random
state: randomness comes only from a ``np.random.Generator`` or an integer ``seed``. Every constant is a
keyword parameter whose default is also listed in :data:`METRIC_CONSTANTS`, so a report can print them.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.signal import argrelextrema

from emogesture.motion.skeleton import ARM_JOINTS, UPPER_BODY_JOINTS, WRIST_JOINTS

# Joint groups (docs/design.md, 'Motion representation' and 'Metrics') come from the one skeleton table.
METRIC_CONSTANTS: dict = {
    "fps": 30.0,
    "fgd_eps": 1e-6,
    "div_num_pairs": 300,
    "div_seed": 0,
    "beat_order": 7,
    "beat_threshold": 0.1,
    "beat_rule": "moving_before",
    "beat_sigma_s": 0.3,
    "beat_direction": "motion_to_audio",
    "srgr_delta_m": 0.1,
    "srgr_sem_scale": 0.165,
    "srgr_joints": "47 upper-body joints (all 55 but 1,2,4,5,7,8,10,11) when J == 55, else all",
    "arm_joints": ARM_JOINTS,
    "wrist_joints": WRIST_JOINTS,
}
_C = METRIC_CONSTANTS


# --------------------------------------------------------------------------- FGD
def gaussian_stats(features: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean ``[D]`` and unbiased covariance ``[D, D]`` of ``features`` ``[N, D]`` (N >= 2), in float64."""
    f = np.asarray(features, dtype=np.float64)
    if f.ndim != 2 or f.shape[0] < 2:
        raise ValueError(f"features must be [N, D] with N >= 2, got shape {f.shape}")
    return f.mean(axis=0), np.atleast_2d(np.cov(f, rowvar=False))


def frechet_from_stats(mu1: np.ndarray, sigma1: np.ndarray, mu2: np.ndarray, sigma2: np.ndarray,
                       eps: float = _C["fgd_eps"]) -> float:
    """Fréchet distance ``|mu1-mu2|^2 + tr(S1 + S2 - 2 (S1 S2)^1/2)`` with ``S = sigma + eps*I``.

    ``mu`` are ``[D]``, ``sigma`` are ``[D, D]``. ``eps*I`` is always added to both covariances (it keeps
    the product square root defined for rank-deficient sets). ``tr (S1 S2)^1/2`` is computed as the sum of
    the square roots of the eigenvalues of the symmetric ``S1^1/2 S2 S1^1/2`` (the same eigenvalues as
    ``S1 S2``), which stays real and defined where a general matrix square root of the product can fail
    (``scipy.linalg.sqrtm`` raised an internal error on one set of 128-wide features). The result is
    clipped at 0 from below (tiny negative values are round-off).
    """
    mu1, mu2 = np.atleast_1d(np.asarray(mu1, np.float64)), np.atleast_1d(np.asarray(mu2, np.float64))
    s1, s2 = np.atleast_2d(np.asarray(sigma1, np.float64)), np.atleast_2d(np.asarray(sigma2, np.float64))
    d = mu1.shape[0]
    if mu2.shape != (d,) or s1.shape != (d, d) or s2.shape != (d, d):
        raise ValueError(f"shape mismatch: mu {mu1.shape} {mu2.shape}, sigma {s1.shape} {s2.shape}")
    eye = np.eye(d)
    s1, s2 = s1 + eps * eye, s2 + eps * eye
    w1, v1 = np.linalg.eigh(s1)
    root1 = (v1 * np.sqrt(np.clip(w1, 0.0, None))) @ v1.T
    middle = root1 @ s2 @ root1
    trace_covmean = float(np.sqrt(np.clip(np.linalg.eigvalsh((middle + middle.T) / 2), 0.0, None)).sum())
    diff = mu1 - mu2
    value = diff @ diff + np.trace(s1) + np.trace(s2) - 2.0 * trace_covmean
    return float(max(value, 0.0))


def frechet_distance(feat_a: np.ndarray, feat_b: np.ndarray, eps: float = _C["fgd_eps"]) -> float:
    """FGD between feature sets ``feat_a`` ``[N, D]`` and ``feat_b`` ``[M, D]`` (N, M >= 2)."""
    mu1, s1 = gaussian_stats(feat_a)
    mu2, s2 = gaussian_stats(feat_b)
    return frechet_from_stats(mu1, s1, mu2, s2, eps=eps)


# --------------------------------------------------------------------------- Div
def diversity(features: np.ndarray, num_pairs: int | None = _C["div_num_pairs"],
              rng: np.random.Generator | None = None, seed: int = _C["div_seed"]) -> float:
    """Mean L2 distance between pairs of distinct samples of ``features`` ``[N, D]`` (N >= 2).

    ``num_pairs`` pairs ``(i, j)``, ``i != j``, are drawn independently (with replacement across pairs):
    ``i`` uniform, ``j`` uniform among the other ``N-1`` samples. ``rng`` is used if given, else
    ``np.random.default_rng(seed)``. ``num_pairs=None`` averages over all ``N(N-1)/2`` unordered pairs
    exactly (no randomness).
    """
    f = np.asarray(features, dtype=np.float64)
    if f.ndim != 2 or f.shape[0] < 2:
        raise ValueError(f"features must be [N, D] with N >= 2, got shape {f.shape}")
    n = f.shape[0]
    if num_pairs is None:
        i, j = np.triu_indices(n, k=1)
    else:
        if num_pairs < 1:
            raise ValueError(f"num_pairs must be >= 1, got {num_pairs}")
        gen = rng if rng is not None else np.random.default_rng(seed)
        i = gen.integers(0, n, size=num_pairs)
        j = (i + gen.integers(1, n, size=num_pairs)) % n
    return float(np.linalg.norm(f[i] - f[j], axis=1).mean())


# --------------------------------------------------------------------------- BA
def _select_joints(x: np.ndarray, joints: Sequence[int] | None, default_55: Sequence[int]) -> np.ndarray:
    if x.ndim != 3 or x.shape[-1] != 3:
        raise ValueError(f"expected joint positions [T, J, 3], got shape {x.shape}")
    if joints is None:
        return x[:, list(default_55)] if x.shape[1] == 55 else x
    return x[:, list(joints)]


def motion_beats(joints: np.ndarray, fps: float = _C["fps"], order: int = _C["beat_order"],
                 threshold: float = _C["beat_threshold"], rule: str = _C["beat_rule"],
                 joint_indices: Sequence[int] | None = None, mean_speed: np.ndarray | None = None,
                 per_joint: bool = False) -> np.ndarray | list[np.ndarray]:
    """Kinematic beats (seconds) of joint positions ``joints`` ``[T, J, 3]`` (metres).

    Joints: ``joint_indices`` if given, else the six arm joints (SMPL-X 16..21) when ``J == 55``, else all
    ``J`` (e.g. pass ``[T, 6, 3]`` arm positions directly). Per joint: speed at frame ``k`` (1..T-2) is the
    central difference ``|p[k+1] - p[k-1]| / 2 * fps`` (m/s; the central form puts a symmetric stop exactly
    on its frame), divided by the joint's mean speed (over this sequence, or ``mean_speed`` ``[J]`` if
    given, e.g. ground-truth dataset means). Candidates are strict local minima,
    ``argrelextrema(v, np.less, order=order)``. Which candidates are kept (``rule``):

    - ``"moving_before"`` (default): the joint was moving into the minimum, i.e. the maximum normalised
      speed over the ``order`` frames before it exceeds ``threshold``. Complete stops and reversals are
      kept; jitter minima inside a hold are rejected.
    - ``"value"``: the normalised speed *at* the minimum exceeds ``threshold`` (the rule of the public
      BEAT/EMAGE alignment code). It drops complete stops (speed ~ 0) and keeps only slow-downs.

    Returns the sorted beat times ``(k / fps)`` of all joints concatenated (a frame that is a beat of two
    joints appears twice, so a mean over the result weights every (joint, beat) pair equally), or with
    ``per_joint=True`` a list of ``J`` arrays. Fewer than 3 frames gives no beats.
    """
    if rule not in ("moving_before", "value"):
        raise ValueError(f"rule must be 'moving_before' or 'value', got {rule!r}")
    x = _select_joints(np.asarray(joints, dtype=np.float64), joint_indices, ARM_JOINTS)
    num_j = x.shape[1]
    if x.shape[0] < 3:
        out = [np.zeros(0) for _ in range(num_j)]
        return out if per_joint else np.zeros(0)
    speed = np.linalg.norm(x[2:] - x[:-2], axis=-1) * (0.5 * fps)  # [T-2, J], frame k -> row k-1
    ref = speed.mean(axis=0) if mean_speed is None else np.broadcast_to(np.asarray(mean_speed, float), (num_j,))
    norm = speed / np.maximum(ref, 1e-12)
    out = []
    for j in range(num_j):
        v = norm[:, j]
        cand = argrelextrema(v, np.less, order=order)[0]
        if rule == "value":
            keep = [r for r in cand if v[r] > threshold]
        else:
            keep = [r for r in cand if r > 0 and v[max(0, r - order):r].max() > threshold]
        out.append((np.asarray(keep, dtype=np.int64) + 1) / float(fps))
    return out if per_joint else np.sort(np.concatenate(out))


def beat_align(motion_beats_s: np.ndarray, audio_onsets_s: np.ndarray, sigma: float = _C["beat_sigma_s"],
               direction: str = _C["beat_direction"]) -> float:
    """Beat-align score in [0, 1] between motion beats ``[B]`` and audio onsets ``[O]`` (seconds).

    ``direction="motion_to_audio"`` (default, the BA of docs/design.md, 'Metrics'): mean over motion beats of
    ``exp(-d^2 / (2 sigma^2))``, ``d`` = distance to the nearest audio onset.
    ``"audio_to_motion"`` swaps the roles (mean over onsets, nearest motion beat; EMAGE's "BC").
    Empty inputs: no source events -> ``nan`` (mean over an empty set; aggregate with ``np.nanmean``);
    source events but no target events -> ``0.0``.
    """
    m = np.sort(np.asarray(motion_beats_s, dtype=np.float64).reshape(-1))
    a = np.sort(np.asarray(audio_onsets_s, dtype=np.float64).reshape(-1))
    if direction == "motion_to_audio":
        src, tgt = m, a
    elif direction == "audio_to_motion":
        src, tgt = a, m
    else:
        raise ValueError(f"direction must be 'motion_to_audio' or 'audio_to_motion', got {direction!r}")
    if src.size == 0:
        return float("nan")
    if tgt.size == 0:
        return 0.0
    pos = np.searchsorted(tgt, src)
    left = np.abs(src - tgt[np.clip(pos - 1, 0, tgt.size - 1)])
    right = np.abs(tgt[np.clip(pos, 0, tgt.size - 1)] - src)
    d = np.minimum(left, right)
    return float(np.mean(np.exp(-(d ** 2) / (2.0 * sigma ** 2))))


# --------------------------------------------------------------------------- SRGR
def srgr(pred_joints: np.ndarray, gt_joints: np.ndarray, sem_scores: np.ndarray,
         delta: float = _C["srgr_delta_m"], sem_scale: float = _C["srgr_sem_scale"],
         joints: Sequence[int] | None = None) -> float:
    """Semantic-relevant gesture recall of ``pred_joints`` vs ``gt_joints`` ``[T, J, 3]`` (metres).

    Computes ``mean_{t, j} (sem_scores[t] / sem_scale) * 1[|pred[t, j] - gt[t, j]|_2 < delta]`` over the
    ``T`` frames and the selected joints (``joints`` if given, else the 47 upper-body joints when
    ``J == 55``, else all ``J``). ``sem_scores`` ``[T]`` are the per-frame ground-truth semantic scores
    (0..1). Not bounded by 1: frames with score > ``sem_scale`` weigh more than 1.
    """
    p = _select_joints(np.asarray(pred_joints, dtype=np.float64), joints, UPPER_BODY_JOINTS)
    g = _select_joints(np.asarray(gt_joints, dtype=np.float64), joints, UPPER_BODY_JOINTS)
    s = np.asarray(sem_scores, dtype=np.float64).reshape(-1)
    if p.shape != g.shape or s.shape[0] != p.shape[0]:
        raise ValueError(f"shape mismatch: pred {p.shape}, gt {g.shape}, sem_scores {s.shape}")
    if p.shape[0] == 0:
        raise ValueError("srgr needs at least one frame")
    hit = np.linalg.norm(p - g, axis=-1) < delta  # [T, J']
    return float(np.mean(hit * (s / sem_scale)[:, None]))


# --------------------------------------------------------------------------- jerk and speed
def _derivative_magnitude(positions: np.ndarray, order: int, fps: float) -> float:
    """Mean Euclidean norm of the ``order``-th forward difference along time times ``fps**order``."""
    x = np.asarray(positions, dtype=np.float64)
    if x.ndim < 2 or x.shape[-1] != 3 or x.shape[0] < order + 1:
        raise ValueError(f"positions must be [T, ..., 3] with T >= {order + 1}, got shape {x.shape}")
    d = np.diff(x, n=order, axis=0) * float(fps) ** order
    return float(np.linalg.norm(d, axis=-1).mean())


def jerk(positions: np.ndarray, fps: float = _C["fps"]) -> float:
    """Mean magnitude (m/s^3) of the third time derivative of ``positions`` ``[T, J, 3]`` (or ``[T, 3]``).

    Third forward difference along time times ``fps**3`` (exact for cubic trajectories), Euclidean norm
    over the last axis, mean over the ``T-3`` difference frames and the joints. Needs ``T >= 4``.
    """
    return _derivative_magnitude(positions, 3, fps)


def speed(positions: np.ndarray, fps: float = _C["fps"]) -> float:
    """Mean speed (m/s) of ``positions`` ``[T, J, 3]`` (or ``[T, 3]``): first forward difference times
    ``fps``, Euclidean norm, mean over the ``T-1`` frames and the joints. Needs ``T >= 2``."""
    return _derivative_magnitude(positions, 1, fps)


def _wrists(joints: np.ndarray, wrist_joints: Sequence[int]) -> np.ndarray:
    x = np.asarray(joints)
    if x.ndim != 3:
        raise ValueError(f"joints must be [T, J, 3], got shape {x.shape}")
    return x[:, list(wrist_joints)]


def wrist_jerk(joints: np.ndarray, fps: float = _C["fps"], wrist_joints: Sequence[int] = WRIST_JOINTS) -> float:
    """:func:`jerk` of the wrists (SMPL-X 20, 21) of ``joints`` ``[T, 55, 3]``."""
    return jerk(_wrists(joints, wrist_joints), fps=fps)


def wrist_speed(joints: np.ndarray, fps: float = _C["fps"], wrist_joints: Sequence[int] = WRIST_JOINTS) -> float:
    """:func:`speed` of the wrists (SMPL-X 20, 21) of ``joints`` ``[T, 55, 3]``: how much the hands move."""
    return speed(_wrists(joints, wrist_joints), fps=fps)
