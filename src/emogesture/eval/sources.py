"""Motion sources for the gesture evaluation, all cut into the windows of one cache split.

A source gives raw motion features ``[W, 300, D]`` aligned with the split's windows: the ground
truth, the built-in baselines (mean pose, mismatched ground truth, ground truth shifted in time),
or a folder of BEAT2 ``.npz`` files written by any system (float32 or float64, extra keys allowed).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from emogesture.data.cache import SplitWindows, WindowsCache
from emogesture.errors import InputFileError
from emogesture.motion import MotionFeatureSpec, load_smplx_npz, poses_to_features


def take_motion(cache: WindowsCache, take: str) -> np.ndarray:
    """A whole take's raw motion features ``[N, D]`` from the cache."""
    with np.load(cache.root / "takes" / f"{take}.npz") as z:
        return z["motion"]


def _cut(motion: np.ndarray, start_frame: int, frames: int) -> np.ndarray:
    """``frames`` frames from ``start_frame``; past the end the last frame is held."""
    out = motion[max(start_frame, 0) : start_frame + frames]
    if len(out) < frames:
        out = np.concatenate([out, np.repeat(out[-1:], frames - len(out), axis=0)])
    return out


def ground_truth(windows: SplitWindows) -> np.ndarray:
    return np.asarray(windows.motion, np.float32)


def mean_pose(windows: SplitWindows, cache: WindowsCache) -> np.ndarray:
    """Every frame the training set's mean feature vector (a static average pose)."""
    mean = np.asarray(cache.stats["motion_mean"], np.float32)
    return np.broadcast_to(mean, windows.motion.shape).copy()


def mismatched(windows: SplitWindows, seed: int = 0) -> np.ndarray:
    """Each window gets the ground truth of a window of another text (so other audio), seeded."""
    rng = np.random.default_rng(seed)
    n = len(windows)
    out = np.empty(windows.motion.shape, np.float32)
    for i in range(n):
        candidates = np.flatnonzero(windows.text != windows.text[i])
        j = int(rng.choice(candidates)) if len(candidates) else (i + 1) % n
        out[i] = windows.motion[j]
    return out


def time_shifted(windows: SplitWindows, cache: WindowsCache, shift_s: float = 1.0, fps: int = 30) -> np.ndarray:
    """The ground truth of the same take, ``shift_s`` later (earlier when that runs past the end)."""
    frames = windows.motion.shape[1]
    out = np.empty(windows.motion.shape, np.float32)
    current, motion = None, None
    for i, (take, start) in enumerate(zip(windows.takes, windows.start_s)):
        if take != current:
            motion, current = take_motion(cache, take), take
        s = int(round((start + shift_s) * fps))
        if s + frames > len(motion):
            s = int(round((start - shift_s) * fps))
        out[i] = _cut(motion, s, frames)
    return out


def npz_folder(folder: Path, windows: SplitWindows, spec: MotionFeatureSpec, fps: int = 30) -> np.ndarray:
    """Windows cut from ``<folder>/<take>.npz`` (whole takes, BEAT2 format, any float type)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise InputFileError(folder, "motion folder not found")
    frames = windows.motion.shape[1]
    out = np.empty((len(windows), frames, spec.dim), np.float32)
    current, motion = None, None
    for i, (take, start) in enumerate(zip(windows.takes, windows.start_s)):
        if take != current:
            path = folder / f"{take}.npz"
            if not path.is_file():
                raise InputFileError(path, f"missing: the {len(set(windows.takes))} evaluated takes each need a file")
            seq = load_smplx_npz(path)
            if abs(seq.fps - fps) > 1e-3:
                raise InputFileError(path, f"frame rate {seq.fps} is not {fps}")
            with torch.no_grad():
                motion = poses_to_features(torch.from_numpy(seq.poses), spec,
                                           trans=torch.from_numpy(seq.trans)).numpy()
            current = take
        out[i] = _cut(motion, int(round(start * fps)), frames)
    return out
