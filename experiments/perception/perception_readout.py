"""Is the emotion perception limited by its read-out or by the speech model's latents?

The perception used to hear a window's emotion through the speech model's classifier head alone. The
same model's emotion latent can be read another way, with nothing retrained: by the nearest emotion mean
in the calibration's own distance (a linear discriminant, ``LatentRange.log_posteriors`` of
:mod:`emogesture.pipeline.perception`, its posterior ``softmax(-D d² / 2)``); by the head and that
posterior together (their log-probabilities summed) everywhere, weighted by the window's emotion trust,
or only where the emotion latent lies within the calibrated range (what the perception now does:
``EmotionPerception.read``); or by the nearest mean of a range fitted on the training windows both as
recorded and heard once more through the training augmentation (:mod:`emogesture.audio.wave_augment`).
Each is scored on the held-out voices of a split (val by default: the choice is made there) under the
recording changes of ``perception_shift.py``, and on the real read speech (a check, not a criterion).

Usage: python experiments/perception/perception_readout.py SPEECH_MODEL CACHE OUT_DIR [SPLIT]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
from tqdm import tqdm

from emogesture.audio import load_audio
from emogesture.audio.wave_augment import WaveAugmentConfig, recording_changes
from emogesture.data.beat import EMOTIONS
from emogesture.data.cache import open_cache
from emogesture.data.datasets import WaveWindowAugmenter
from emogesture.data.real_speech import load_real_recording, real_recordings
from emogesture.models.perception import LatentRange, log_softmax
from emogesture.pipeline.perception import perception_of
from emogesture.eval.split_latents import encode_split
from emogesture.pipeline.speech import SpeechLatentEncoder

HOP_SECONDS = 8.0  # as perception_shift.py


def readouts(perception, augmented: LatentRange) -> dict:
    """Name -> function of (emotion latents ``[W, D]``, head logits ``[W, 8]``) -> log-scores ``[W, 8]``."""
    means = perception.emotion.log_posteriors
    return {"classifier head": lambda e, logits: log_softmax(logits),
            "nearest emotion mean": lambda e, logits: means(e),
            "head and nearest mean": lambda e, logits: log_softmax(logits) + means(e),
            "head, and nearest mean weighted by the emotion trust":
                lambda e, logits: log_softmax(logits) + perception.emotion.trust(e)[:, None] * means(e),
            "head, and nearest mean within the range (shipped)": lambda e, logits: perception.read(e, logits),
            "nearest mean, augmented range": lambda e, logits: augmented.log_posteriors(e)}


def augmented_range(encoder: SpeechLatentEncoder, cache, seed: int = 0) -> LatentRange:
    """Emotion means and spread of the train windows as recorded and once through the training augmentation."""
    train = cache.split("train")
    clean = encode_split(encoder, cache, "train").emotion
    augment = WaveWindowAugmenter(cache, train, WaveAugmentConfig())
    heard = np.stack([augment(j, np.random.default_rng([seed, j]))
                      for j in tqdm(range(len(train)), desc="augmented train windows", leave=False)])
    return LatentRange.fit(np.concatenate([clean, encoder.encode_windows(heard).emotion]),
                           np.concatenate([train.emotion, train.emotion]))


def main(speech_model: str, cache_dir: str, out_dir: str, split: str = "val") -> None:
    encoder = SpeechLatentEncoder.from_run(speech_model)
    perception = perception_of(encoder)
    if perception is None or perception.labels != list(EMOTIONS):
        raise SystemExit(f"{speech_model}: needs an emotion perception calibration over all eight emotions")
    cache = open_cache(cache_dir)
    held = cache.split(split)
    root = Path(cache.manifest["root"])
    unheard = {t for t, s in zip(held.takes, held.speaker_id.tolist()) if s not in encoder.speakers}
    takes = [t for t in dict.fromkeys(held.takes) if t in unheard]
    if not takes:
        raise SystemExit(f"{cache_dir}: the {split} split has no voice the speech model did not train on")
    emotion_of = {t: int(e) for t, e in zip(held.takes, held.emotion)}
    fns = readouts(perception, augmented_range(encoder, cache))
    rng = np.random.default_rng(0)
    changes = {"as recorded": lambda w: w, **recording_changes(rng)}
    waves = {t: load_audio(root / "wave16k" / f"{t}.wav")[0] for t in takes}
    rows = {}
    for name, change in tqdm(changes.items(), desc="recording changes", leave=False):
        hits = {k: [] for k in fns}
        for take in takes:
            enc, _ = encoder.encode(np.asarray(change(waves[take]), np.float32), 16000, HOP_SECONDS)
            for k, f in fns.items():
                hits[k] += list(f(enc.emotion, enc.emotion_logits).argmax(1) == emotion_of[take])
        rows[name] = {k: float(np.mean(v)) for k, v in hits.items()} | {"windows": len(hits[next(iter(fns))])}
    real = {}
    for rec in real_recordings():
        enc, _ = encoder.encode(load_real_recording(rec), 16000, HOP_SECONDS)
        real[rec.name] = {k: [EMOTIONS[i] for i in f(enc.emotion, enc.emotion_logits).argmax(1)]
                          for k, f in fns.items()}
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / f"perception_readout_{split}.json").write_text(json.dumps({"split": split, "takes": len(takes),
                                                                        "rows": rows, "real": real}, indent=1) + "\n")
    names = list(fns)
    lines = [f"# Reading the emotion off the speech model's latents ({split}, held-out voices)", "",
             f"{len(takes)} takes of the {split} split whose voices the speech model never heard, every 10-s window "
             f"({HOP_SECONDS:g}-s hop), played through the changes of `perception_shift.py`: the share heard as "
             "the take's emotion by each read-out of the same model. Real read speech: windows heard as neutral "
             "(a check, not a criterion).", "",
             "| audio | windows | " + " | ".join(names) + " |", "|---|---|" + "---|" * len(names)]
    for name, r in rows.items():
        lines.append(f"| {name} | {r['windows']} | " + " | ".join(f"{r[k]:.3f}" for k in names) + " |")
    heard = {k: [h for rec in real.values() for h in rec[k]] for k in names}
    lines.append("| real read speech, heard as neutral | " + str(len(heard[names[0]])) + " | "
                 + " | ".join(f"{v.count('neutral')} of {len(v)}" for v in heard.values()) + " |")
    (out / f"perception_readout_{split}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main(*sys.argv[1:5])
