"""The style an unfamiliar voice takes: the training speaker whose gestures are the model's typical ones.

Under ``--emotion auto`` the style latent of a voice beyond the training voices is blended toward one
training speaker's mean style latent (:func:`emogesture.pipeline.perception.auto_style`), so that the
gesture model is never asked to extrapolate. *Which* speaker decides how the animation looks: the
training speakers' motion styles differ widely, and on the same real recording (the bundled model of
corpus version 6, neutral emotion) their mean styles put a hand in front of the chest in 5–81 % of the
frames. The speaker whose style latent lies nearest the centre of the voices (the speech model's own
choice, :meth:`~emogesture.models.perception.EmotionPerception.typical_speaker`) says nothing about
their gestures, and there it was one with the arms hanging (8 %).

So the gesture model keeps its own *fallback style*, chosen on held-out windows (``val``) by motion. An
unfamiliar voice's emotion is untrusted too (a window's trust is the smaller of its emotion's and its
voice's), so it is animated with the neutral mean emotion latent and the fallback style. The choice
copies that: the neutral windows of the split are generated with their own latents (the reference: the
model on held-out voices of the same emotion), and again with the neutral mean emotion latent and each
training speaker's mean style in place of their own, everything else alike (timing stream, noise seed).
The speaker chosen is the one whose motion is nearest the reference in the two statistics the
real-speech check reads (:mod:`emogesture.eval.real_speech`): the share of frames with a hand in front of
the chest and the wrists' median distance, each in units of that check's tolerance.
"""

from __future__ import annotations

from os import PathLike
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from emogesture.checkpoints import LoadedModel, check_model_output, load_model, save_model, stored_weights_dtype
from emogesture.provenance import refuse_trained_split
from emogesture.config import from_dict
from emogesture.data.beat import EMOTIONS
from emogesture.data.cache import WindowsCache, open_cache
from emogesture.errors import EmogestureError
from emogesture.eval.motion_stats import hands_in_front, wrist_distance
from emogesture.eval.real_speech import FRONT_SHARE_TOLERANCE, WRIST_DISTANCE_TOLERANCE
from emogesture.motion import MotionFeatureSpec
from emogesture.motion.body import SkeletonBody
from emogesture.eval.split_latents import encode_split, model_conditions
from emogesture.pipeline.sampling import generate_from_conditions, window_seeds
from emogesture.pipeline.speech import SpeechLatentEncoder

#: Held-out windows generated per candidate speaker (evenly spaced through the split): enough for the
#: two shares to settle within a few points, few enough that the whole choice takes minutes on 2 cores.
FALLBACK_WINDOWS = 96


def speaker_style_means(speech: SpeechLatentEncoder, cache: WindowsCache) -> dict[int, np.ndarray]:
    """Each training speaker's mean style latent ``[D]`` over the train split's windows, by speaker id."""
    train = cache.split("train")
    style = encode_split(speech, cache, "train").style
    return {int(k): style[train.speaker_id == k].mean(0).astype(np.float32) for k in np.unique(train.speaker_id)}


def motion_typicality(gesture: LoadedModel, features: np.ndarray) -> dict[str, float]:
    """Generated raw motion features ``[W, T, D]`` -> the share of frames with a hand in front of the chest
    and the wrists' median distance (m), on the licence-free skeleton."""
    spec = from_dict(MotionFeatureSpec, gesture.metadata.require("features", gesture.path))
    with torch.no_grad():
        joints = SkeletonBody().forward_features(torch.from_numpy(np.ascontiguousarray(features, np.float32)), spec)
    joints = joints.reshape(-1, *joints.shape[-2:]).numpy()  # every window's frames in a row: both are per frame
    return {"in_front": float(hands_in_front(joints).mean()),
            "wrist_distance": float(np.median(wrist_distance(joints)))}


def typicality_cost(stats: dict[str, float], reference: dict[str, float]) -> float:
    """How far a speaker's statistics lie from the reference's, in units of the real-speech tolerances."""
    return float(np.hypot((stats["in_front"] - reference["in_front"]) / FRONT_SHARE_TOLERANCE,
                          (stats["wrist_distance"] / reference["wrist_distance"] - 1.0) / WRIST_DISTANCE_TOLERANCE))


def fit_fallback_style(gesture: LoadedModel, speech: SpeechLatentEncoder, cache: WindowsCache, split: str = "val",
                       seed: int = 0, windows: int = FALLBACK_WINDOWS, progress: bool = True) -> dict:
    """Choose the fallback style (module docstring) on at most ``windows`` evenly spaced neutral windows of
    ``split``.

    Returns the record stored in the gesture model's metadata: ``speaker`` (id), ``latent`` ``[D]``, the
    split and windows measured, the reference's statistics and every candidate's (``candidates``, by id,
    with its cost)."""
    if windows < 1:
        raise EmogestureError(f"a fallback style needs at least 1 window to compare on, got {windows}")
    if gesture.config.variant == "no_audio":
        raise EmogestureError(f"{gesture.path}: the no_audio ablation has no style latent to fall back on")
    held_out = cache.split(split)
    neutral = np.flatnonzero(held_out.emotion == EMOTIONS.index("neutral"))
    if len(neutral) == 0:
        raise EmogestureError(f"{cache.root}: the {split} split has no neutral windows to choose a fallback style on")
    pick = neutral[np.unique(np.linspace(0, len(neutral) - 1, min(windows, len(neutral))).round().astype(np.int64))]
    conds = [c[pick] for c in model_conditions(gesture, cache, split, speech)]
    seeds = window_seeds(seed, len(pick))
    neutral_latent = np.asarray((gesture.metadata.require("emotion_latent_means", gesture.path))["neutral"], np.float32)
    means = speaker_style_means(speech, cache)
    reference = motion_typicality(gesture, generate_from_conditions(gesture, conds, seeds))
    candidates = {}
    for speaker, style in tqdm(means.items(), desc="fallback style", unit="speaker", disable=not progress, leave=False):
        swapped = [conds[0], np.broadcast_to(neutral_latent, conds[1].shape).copy(),
                   np.broadcast_to(style, conds[2].shape).copy(), *conds[3:]]
        stats = motion_typicality(gesture, generate_from_conditions(gesture, swapped, seeds))
        candidates[speaker] = {**stats, "cost": typicality_cost(stats, reference)}
    chosen = min(candidates, key=lambda k: candidates[k]["cost"])
    return {"speaker": chosen, "latent": means[chosen].tolist(), "split": split, "windows": int(len(pick)),
            "seed": int(seed), "reference": reference, "candidates": {str(k): v for k, v in candidates.items()}}


def calibrate_fallback_run(run: str | PathLike[str], cache_dir: str | PathLike[str], out: str | PathLike[str],
                           split: str = "val", seed: int = 0, overwrite: bool = False,
                           windows: int = FALLBACK_WINDOWS) -> dict:
    """Write a copy of the gesture model of ``run`` to ``out`` with its fallback style chosen on ``split``
    of the cache (``emogesture calibrate style``); returns the stored record."""
    out = Path(out)
    check_model_output(out, overwrite)
    gesture = load_model(run, "gesture")
    speech = SpeechLatentEncoder.of_gesture_model(gesture)
    refuse_trained_split(split, gesture, speech.loaded, purpose="choose a fallback style")
    record = fit_fallback_style(gesture, speech, open_cache(cache_dir), split, seed, windows)
    save_model(out, "gesture", gesture.model, gesture.config, gesture.metadata.replace(fallback_style=record),
               generation=gesture.generation, weights_dtype=stored_weights_dtype(gesture))
    return record
