"""Seams of long audio: the frame-to-frame joint jumps inside the cross-faded overlaps of a generated
recording (its seams) against those inside its windows, for a stretch of the split's cached windows take
after take and for whole takes, next to the ground truth of the same frames; and the rhythm gain of
whole takes. Used by :mod:`emogesture.eval.gesture_models`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import torch

from emogesture.audio import TARGET_SAMPLE_RATE, load_audio, onset_strength, window_starts
from emogesture.data.cache import WindowsCache
from emogesture.errors import EmogestureError
from emogesture.eval.rhythm import (
    RHYTHM_CONSTANTS, arm_speed, consecutive_windows, cut_windows, envelope_at_frames,
    mismatched_envelopes, rhythm_gain,
)
from emogesture.eval import sources as src
from emogesture.config import from_dict
from emogesture.motion import MotionFeatureSpec, SkeletonBody
from emogesture.pipeline.generate import HOP_SECONDS, WINDOW_SECONDS, GesturePipeline
from emogesture.pipeline.postprocess import largest_joint_jumps, stitch
from emogesture.types import FPS, SMPLXSequence


@dataclass
class LongAudio:
    """A long recording made of the split's cached windows, take after take: ``wave [N]`` at 16 kHz, the
    ground truth of the same frames ``motion [T, D]`` (motion features), the takes used and the times (s)
    where the speech and motion do not run on (another take begins, or a gap between cached windows)."""

    wave: np.ndarray
    motion: np.ndarray
    takes: list[str]
    boundaries_s: list[float]


def long_audio(cache: WindowsCache, split: str, seconds: float, first_take: int = 0) -> LongAudio:
    """The split's takes back to back from its ``first_take``-th take (wrapping round), each as its cached
    windows (consecutive in the take, so audio and motion run on inside a take), cut to ``seconds``: the
    same stretch of speech and of real motion."""
    root = Path(cache.manifest["root"])
    windows = cache.split(split)
    window_takes = np.asarray(windows.takes)
    order = list(dict.fromkeys(windows.takes))
    first_take %= len(order)
    waves, motions, takes, boundaries, total, follows = [], [], [], [], 0.0, None
    for take in order[first_take:] + order[:first_take]:
        wave, sr = load_audio(root / "wave16k" / f"{take}.wav")
        for i in sorted(np.flatnonzero(window_takes == take), key=lambda i: windows.start_s[i]):
            if follows is not None and follows != (take, float(windows.start_s[i])):
                boundaries.append(total)  # another take, or a gap inside this one
            start = int(round(windows.start_s[i] * sr))
            waves.append(wave[start: start + int(round(WINDOW_SECONDS * sr))])
            motions.append(np.asarray(windows.motion[i], np.float32))
            total += WINDOW_SECONDS
            follows = (take, float(windows.start_s[i]) + WINDOW_SECONDS)
        takes.append(take)
        if total >= seconds:
            return LongAudio(np.concatenate(waves)[: int(round(seconds * sr))],
                             np.concatenate(motions)[: int(round(seconds * FPS))], takes,
                             [b for b in boundaries if b < seconds])
    raise EmogestureError(f"{cache.root}: the {split} split holds less than {seconds} s of cached windows")


def seam_mask(num_jumps: int, starts_s: list[float], fps: int = FPS) -> np.ndarray:
    """Which of ``num_jumps`` frame-to-frame jumps touch a cross-faded overlap of two neighbouring
    10-s windows starting at ``starts_s`` (from the frame before the overlap to its last frame)."""
    window = int(round(WINDOW_SECONDS * fps))
    starts = [int(round(s * fps)) for s in starts_s]
    seam = np.zeros(num_jumps, bool)
    for prev, cur in zip(starts[:-1], starts[1:]):
        seam[max(cur - 1, 0): min(prev + window, num_jumps)] = True
    return seam


#: Jumps this close (s) to a take boundary of the long audio are left out of the seam statistics: the
#: speech changes there (another take), and real motion has no such change to compare with.
BOUNDARY_MARGIN_S = 1.0


def near_boundaries(num_jumps: int, boundaries_s: list[float], fps: int = FPS,
                    margin_s: float = BOUNDARY_MARGIN_S) -> np.ndarray:
    """Which of ``num_jumps`` jumps lie within ``margin_s`` of a take boundary."""
    near = np.zeros(num_jumps, bool)
    margin = int(round(margin_s * fps))
    for b in boundaries_s:
        f = int(round(b * fps))
        near[max(f - margin, 0): f + margin] = True
    return near


def seam_statistics(seam: np.ndarray, inside: np.ndarray) -> dict:
    """Jumps ``[S]`` touching overlaps and ``[I]`` inside windows -> the check's numbers: the largest seam
    jump and the seam jumps' 99th percentile, each against the inside 99th percentile, and the share of
    seam jumps above it (about 0.01 when seams move like the rest); and the largest jump of all, seam or
    inside (a joint that flips inside a window shows only there)."""
    p99 = float(np.percentile(inside, 99))
    return {"max_jump_m": float(max(seam.max(), inside.max())), "max_seam_jump_m": float(seam.max()),
            "p99_seam_jump_m": float(np.percentile(seam, 99)),
            "p99_inside_jump_m": p99, "seam_jumps": int(len(seam)), "inside_jumps": int(len(inside)),
            "seam_share_above_p99": float((seam > p99).mean())}


def split_jumps(jump: np.ndarray, starts_s: list[float], boundaries_s: list[float] = (),
                fps: int = FPS) -> tuple[np.ndarray, np.ndarray]:
    """Frame-to-frame jumps ``[T - 1]`` -> (seam jumps, inside jumps), leaving out those near a take
    boundary (:func:`near_boundaries`)."""
    seam = seam_mask(len(jump), starts_s, fps)
    keep = ~near_boundaries(len(jump), list(boundaries_s), fps)
    if not (seam & keep).any() or not (~seam & keep).any():
        raise EmogestureError("the audio is too short for window seams (needs more than one window)")
    return jump[seam & keep], jump[~seam & keep]


def pooled_seam_statistics(parts: list[tuple[np.ndarray, np.ndarray]]) -> dict:
    """(seam jumps, inside jumps) of several sequences -> :func:`seam_statistics` of them all pooled."""
    return seam_statistics(np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]))


def seam_jumps(joints: np.ndarray, starts_s: list[float], boundaries_s: list[float] = (), fps: int = FPS) -> dict:
    """Frame-to-frame jumps of a stitched sequence ``joints [T, 55, 3]``: seams vs inside windows (see
    :func:`split_jumps` and :func:`seam_statistics`)."""
    return seam_statistics(*split_jumps(largest_joint_jumps(joints), starts_s, boundaries_s, fps)) | {
        "windows": len(starts_s)}


def ground_truth_jumps(motion: np.ndarray, cache: WindowsCache) -> np.ndarray:
    """Frame-to-frame jumps ``[T - 1]`` of ground-truth motion features ``[T, D]`` of the cache."""
    spec = from_dict(MotionFeatureSpec, cache.manifest["config"]["features"])
    with torch.no_grad():
        return largest_joint_jumps(SkeletonBody().forward_features(torch.from_numpy(motion), spec).numpy())


def ground_truth_seam_reference(cache: WindowsCache, split: str, takes: list[str], hop_seconds: float = HOP_SECONDS,
                                fps: int = FPS) -> dict:
    """The seam check applied to motion without seams: each take's ground truth (its consecutive windows
    of the split), cut into the generator's 10-s windows every ``hop_seconds``; jumps pooled over ``takes``.

    Motion without any seam has seam and inside jumps alike only up to chance; this gives the values
    real motion reaches.
    """
    windows = cache.split(split)
    parts = []
    window_takes = np.asarray(windows.takes)
    for take in takes:
        idx = sorted(np.flatnonzero(window_takes == take), key=lambda i: windows.start_s[i])
        motion = np.concatenate([np.asarray(windows.motion[i], np.float32) for i in idx])
        starts = window_starts(len(motion) / fps, WINDOW_SECONDS, hop_seconds).tolist()
        if len(starts) >= 2:
            parts.append(split_jumps(ground_truth_jumps(motion, cache), starts, fps=fps))
    if not parts:
        raise EmogestureError(f"no take of the {split} split is long enough for window seams")
    return pooled_seam_statistics(parts) | {"takes": len(parts)}


SEAM_CANDIDATES = (4, 1)  # the generator's default (chosen on the seam statistic) and unselected windows


def sequence_joints(pipe: GesturePipeline, seq: SMPLXSequence) -> np.ndarray:
    """A generated sequence -> the joint positions ``[T, 55, 3]`` of the pipeline's skeleton."""
    with torch.no_grad():
        return pipe.body(torch.from_numpy(seq.poses), torch.from_numpy(seq.trans)).numpy()


def generated_joints(pipe: GesturePipeline, wave: np.ndarray, seed: int, hop_seconds: float = HOP_SECONDS,
                     seam_candidates: int = 4) -> tuple[np.ndarray, list[float]]:
    """Generate for a waveform -> joint positions ``[T, 55, 3]`` and its windows' start times (s)."""
    seq = pipe.generate(wave, seed=seed, generation=replace(pipe.generation, hop_seconds=hop_seconds,
                                                            seam_candidates=seam_candidates))[0]
    starts = window_starts(len(wave) / TARGET_SAMPLE_RATE, WINDOW_SECONDS, hop_seconds)
    return sequence_joints(pipe, seq), starts.tolist()


#: Sampling seeds pooled for the long-audio seams of unselected windows: one draw's largest jumps are a
#: handful of frames, so the check reads the 99th percentile of several draws' seam jumps.
SEAM_SEEDS = 4
#: Long stretches whose seams are pooled, starting at takes spread evenly over the split
#: (:func:`long_audio_stretches`). One 65-s stretch is too little motion to read a 99th percentile: on four
#: stretches of the val texts the ground truth's own ratio read 0.79, 1.06, 1.05 and 0.94 (commit 8f8c629).
LONG_AUDIO_STRETCHES = 4


def long_audio_stretches(cache: WindowsCache, split: str, seconds: float,
                         count: int = LONG_AUDIO_STRETCHES) -> list[LongAudio]:
    """``count`` long recordings (:func:`long_audio`) of ``seconds`` each, starting at takes spread evenly
    over the split (fewer when the split has fewer takes); the first starts at its first take."""
    takes = len(dict.fromkeys(cache.split(split).takes))
    firsts = dict.fromkeys(i * takes // count for i in range(count))
    return [long_audio(cache, split, seconds, first) for first in firsts]


def long_audio_check(pipe: GesturePipeline, stretches: list[LongAudio], seed: int,
                     hop_seconds: float = HOP_SECONDS) -> dict:
    """Generate for long recordings (:func:`long_audio_stretches`, all of one length): the first with the
    default seam chooser (seed ``seed``), and every one with 1 candidate per window, no selection (seeds
    ``seed`` to ``seed + SEAM_SEEDS - 1``, jumps of all stretches and seeds pooled): frame count and seam
    statistics of each (see :func:`seam_jumps`), keyed by candidates, and the unselected ratio of each
    stretch. Jumps near a take boundary are left out (:data:`BOUNDARY_MARGIN_S`)."""
    long = stretches[0]
    duration = len(long.wave) / TARGET_SAMPLE_RATE
    out: dict = {"seconds": duration, "hop_seconds": hop_seconds, "expected_frames": int(round(duration * FPS)),
                 "boundaries_s": long.boundaries_s}
    chosen, unselected = SEAM_CANDIDATES
    joints, starts = generated_joints(pipe, long.wave, seed, hop_seconds, chosen)
    out[f"candidates_{chosen}"] = {"frames": len(joints), "seeds": 1, **seam_jumps(joints, starts, long.boundaries_s)}
    parts, own_parts, per_stretch = [], [], []
    num_frames = out["expected_frames"]
    for stretch in stretches:
        mine = []
        for s in range(seed, seed + SEAM_SEEDS):
            drawn, starts = pipe.draw_windows(stretch.wave, seed=s, generation=replace(
                pipe.generation, hop_seconds=hop_seconds, seam_candidates=unselected))
            windows = drawn[0, :, 0]
            joints = sequence_joints(pipe, pipe.to_sequence(stitch(windows, starts, num_frames)))
            starts_s = [st / FPS for st in starts]
            mine.append(split_jumps(largest_joint_jumps(joints), starts_s, stretch.boundaries_s))
            own_parts.append(split_jumps(windows_own_jumps(pipe.joint_jumps(windows), starts, num_frames),
                                         starts_s, stretch.boundaries_s)[0])
        parts += mine
        per_stretch.append({"takes": stretch.takes, **pooled_seam_statistics(mine)})
    out[f"candidates_{unselected}"] = {"frames": len(joints), "seeds": SEAM_SEEDS, "windows": len(starts),
                                       "stretches": len(stretches), **pooled_seam_statistics(parts),
                                       "p99_windows_own_seam_jump_m": float(np.percentile(np.concatenate(own_parts), 99))}
    out["stretches"] = per_stretch
    return out


def windows_own_jumps(jumps: np.ndarray, starts: list[int], num_frames: int) -> np.ndarray:
    """Each window's own frame-to-frame jumps ``[W, T - 1]``, placed at its start frame -> the largest
    of the windows covering each jump of the timeline ``[num_frames - 1]``: what the motion would
    jump there without the cross-fade, had the faster of the two windows been kept."""
    out = np.zeros(num_frames - 1)
    for j, s in zip(jumps, starts):
        m = min(len(j), num_frames - 1 - s)
        out[s: s + m] = np.maximum(out[s: s + m], j[:m])
    return out


def long_audio_ground_truth(stretches: list[LongAudio], cache: WindowsCache, hop_seconds: float = HOP_SECONDS
                            ) -> dict:
    """The same statistics on the ground truth of the long recordings' frames, cut into the same windows
    (real motion, no seams), take boundaries left out alike: pooled, and ``per_stretch``."""
    parts = []
    for long in stretches:
        starts = window_starts(len(long.motion) / FPS, WINDOW_SECONDS, hop_seconds).tolist()
        parts.append(split_jumps(ground_truth_jumps(long.motion, cache), starts, long.boundaries_s))
    return pooled_seam_statistics(parts) | {"takes": len({t for long in stretches for t in long.takes}),
                                            "stretches": len(stretches),
                                            "per_stretch": [seam_statistics(*p) for p in parts]}


def whole_take_seams(pipe: GesturePipeline, cache: WindowsCache, split: str, seed: int,
                     hop_seconds: float = HOP_SECONDS, seam_candidates: int = 1) -> dict:
    """Every take of a split generated whole (its own audio, one emotion and speaker), seam and inside
    jumps pooled over the takes (see :func:`seam_statistics`): seams where the speech runs on, in
    thousands of jumps, next to :func:`ground_truth_seam_reference` over the same takes."""
    root = Path(cache.manifest["root"])
    parts = []
    windows = cache.split(split)
    takes = list(dict.fromkeys(windows.takes))
    speeds, envelopes = {}, {}
    for take in takes:
        wave, sr = load_audio(root / "wave16k" / f"{take}.wav")
        joints, starts = generated_joints(pipe, wave, seed, hop_seconds, seam_candidates)
        speeds[take] = arm_speed(joints, fps=FPS)
        envelopes[take] = envelope_at_frames(onset_strength(wave, sr), sr, len(joints), FPS)
        if len(starts) < 2:
            continue
        parts.append(split_jumps(largest_joint_jumps(joints), starts))
    if not parts:
        raise EmogestureError(f"no take of the {split} split is long enough for window seams")
    text = dict(zip(windows.takes, windows.text.tolist()))
    return pooled_seam_statistics(parts) | {
        "takes": len(parts), "seam_candidates": seam_candidates,
        "ground_truth": ground_truth_seam_reference(cache, split, takes, hop_seconds),
        "rhythm": whole_take_rhythm(speeds, envelopes, text, cache)}


def whole_take_rhythm(speeds: dict[str, np.ndarray], envelopes: dict[str, np.ndarray], text: dict[str, int],
                      cache: WindowsCache) -> dict:
    """The rhythm gain (:mod:`emogesture.eval.rhythm`) of takes generated whole (take -> arm speed ``[N]``)
    and of their ground truth, each cut into consecutive 10-s windows; mismatched audio as in the report."""
    frames = int(round(WINDOW_SECONDS * FPS))
    spec = from_dict(MotionFeatureSpec, cache.manifest["config"]["features"])
    body = SkeletonBody()
    gt = {}
    for take in speeds:
        with torch.no_grad():
            joints = body.forward_features(torch.from_numpy(np.asarray(src.take_motion(cache, take), np.float32)), spec)
        gt[take] = arm_speed(joints.numpy(), fps=FPS)
    out = {}
    for name, speed in (("ours", speeds), ("ground truth", gt)):
        takes, starts = consecutive_windows({k: min(len(v), len(envelopes[k])) for k, v in speed.items()}, frames)
        own, mismatched = mismatched_envelopes(envelopes, takes, starts, [text[t] for t in takes], frames,
                                               seed=RHYTHM_CONSTANTS["seed"], fps=FPS)
        out[name] = rhythm_gain(cut_windows(speed, takes, starts, frames), own, mismatched, fps=FPS) | {
            "windows": len(takes)}
    return out
