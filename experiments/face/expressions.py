"""Can the eight emotions be told apart from the face track alone? (the bundled model; held-out corpus voices)

Each take of the val and test splits of the experiments' corpus whose voice the bundled speech model never
heard is given its face as ``generate --face --emotion auto`` gives it: the emotion heard in each window
(blended toward neutral where not trusted), the phones recognised. Each take's face is cut into 10-s windows;
a window's features are the mean and spread of each of the 52 weights. A logistic regression (its
regularisation chosen by 5-fold cross-validation on val) learns the labels on the val windows and is scored
once on the test windows.

Usage: python experiments/face/expressions.py CACHE OUT_DIR [SPEECH_MODEL]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
from sklearn.linear_model import LogisticRegressionCV
from tqdm import tqdm

from emogesture.audio import load_audio
from emogesture.data.cache import open_cache
from emogesture.face.phones import recognise_phones
from emogesture.face.track import face_track
from emogesture.pipeline.face import animated_emotions
from emogesture.pipeline.generate import GesturePipeline
from emogesture.types import EMOTIONS

WINDOW = 300  # frames: 10 s


def windows(pipe: GesturePipeline, cache, split: str) -> tuple[np.ndarray, np.ndarray]:
    """Features ``[W, 104]`` and labels ``[W]`` of the split's held-out voices' 10-s windows."""
    root = Path(cache.manifest["root"])
    takes = cache.split(split).take_emotions(leave_out_speakers=pipe.speech.speakers)
    features, labels = [], []
    for take, emotion in tqdm(takes.items(), desc=split, unit="take"):
        wave, _ = load_audio(root / "wave16k" / f"{take}.wav")
        n = int(round(len(wave) / 16000 * 30))
        heard = pipe.perceive(*pipe.encode(wave), source=take)
        face = face_track(wave, 16000, n, animated_emotions(heard, "auto", n), phones=recognise_phones(wave))
        for a in range(0, n - WINDOW + 1, WINDOW):
            part = face.arkit[a : a + WINDOW]
            features.append(np.concatenate([part.mean(0), part.std(0)]))
            labels.append(emotion)
    return np.array(features), np.array(labels)


def main(cache_dir: str, out_dir: str, speech_model: str | None = None) -> None:
    pipe = GesturePipeline.from_run(None, speech_model)
    cache = open_cache(cache_dir)
    x_val, y_val = windows(pipe, cache, "val")
    x_test, y_test = windows(pipe, cache, "test")
    model = LogisticRegressionCV(Cs=8, cv=5, max_iter=5000).fit(x_val, y_val)
    predicted = model.predict(x_test)
    confusion = np.zeros((len(EMOTIONS), len(EMOTIONS)), int)
    for t, p in zip(y_test, predicted):
        confusion[t, p] += 1
    result = {"val_windows": len(y_val), "test_windows": len(y_test),
              "test_accuracy": float(np.mean(predicted == y_test)),
              "per_emotion": {e: float(confusion[k, k] / max(confusion[k].sum(), 1)) for k, e in enumerate(EMOTIONS)},
              "confusion": confusion.tolist(), "C": float(model.C_[0])}
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / "expressions.json").write_text(json.dumps(result, indent=1) + "\n")
    lines = ["# The eight emotions told apart from the face track alone (trained on val windows, scored once on "
             "test)", "", f"Held-out voices of the experiments' corpus, `--emotion auto`, 10-s windows: "
             f"{len(y_val)} val windows to learn from, {len(y_test)} test windows scored.", "",
             f"**Test accuracy: {result['test_accuracy']:.1%}** (bar 80 %; chance 12.5 %).", "",
             "| emotion | " + " | ".join(EMOTIONS) + " | right |", "|---" * (len(EMOTIONS) + 2) + "|"]
    for k, e in enumerate(EMOTIONS):
        lines.append(f"| {e} | " + " | ".join(map(str, confusion[k])) + f" | {result['per_emotion'][e]:.0%} |")
    (out / "expressions.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    main(*sys.argv[1:4])
