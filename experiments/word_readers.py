"""Real voices for validation: what speech models hear in thirteen volunteers reading word lists.

The real-speech checks (``emogesture evaluate real``) read four recordings, and every choice made while
looking at them is made on the checks themselves. KTuberling's sound themes (Debian's ``ktuberling-data``,
GPL-2+) hold the names of its stamps read aloud by a volunteer per language; the thirteen themes of at least
50 s (:data:`emogesture.data.real_speech.WORD_READERS`) are real people, microphones and rooms that no model
or calibration here has heard, so they serve as the validation set of real voices: choices are made on them,
and the check recordings are scored once.

For each calibrated speech model, :data:`STRETCHES` 10-s stretches of each reader (evenly spaced), as
recorded and given each other emotion's corpus prosody
(:func:`emogesture.data.real_speech.training_voice_emotions`): the share of the stretches as recorded heard
as neutral (``--emotion own``; read without acted emotion, neutral is the right answer) and trusted by
``--emotion auto``, and the share given each emotion heard as it (a perception that hears every real voice as
neutral, whatever it does, fails this).

Usage: python experiments/word_readers.py OUT_DIR NAME=SPEECH_MODEL [NAME=SPEECH_MODEL ...]
"""

from __future__ import annotations

import json
import sys
from collections import Counter
from pathlib import Path

import numpy as np

from emogesture.data.beat import EMOTIONS
from emogesture.data.real_speech import WORD_READERS, training_voice_emotions
from emogesture.data.synthetic.corpus import CorpusConfig
from emogesture.pipeline.perception import perceive, perception_of
from emogesture.pipeline.speech import SpeechLatentEncoder

STRETCHES = 4


def hear(encoder: SpeechLatentEncoder, waves: list[np.ndarray], emotions: np.ndarray, readers: list[str]) -> dict:
    perception = perception_of(encoder)
    heard, trusted = [], []
    for wave in waves:
        enc, starts = encoder.encode(wave, 16000, 10.0)
        p = perceive(enc, starts, perception, "reader")
        heard.append(p.labels[0])
        trusted.append(bool(p.trust[0] >= 1.0))
    heard_a, trusted_a = np.asarray(heard), np.asarray(trusted)
    per_stretch = len(EMOTIONS) * STRETCHES
    reader = np.repeat(np.arange(len(readers)), per_stretch)
    neutral = emotions == EMOTIONS.index("neutral")
    rows = {e: {"heard_as_given": float(np.mean(heard_a[emotions == k] == e)),
                "heard": dict(Counter(heard_a[emotions == k].tolist()))} for k, e in enumerate(EMOTIONS)}
    return {"neutral_share": float(np.mean(heard_a[neutral] == "neutral")),
            "trusted_share": float(np.mean(trusted_a[neutral])),
            "emotions_mean": float(np.mean([rows[e]["heard_as_given"] for e in EMOTIONS if e != "neutral"])),
            "emotions": rows,
            "readers": {r: {"heard": heard_a[neutral & (reader == i)].tolist(),
                            "trusted": int(trusted_a[neutral & (reader == i)].sum())}
                        for i, r in enumerate(readers)}}


def main(out_dir: str, *models: str) -> None:
    readers = list(WORD_READERS)
    waves, emotions = training_voice_emotions(readers, STRETCHES, CorpusConfig().emotion_prosody_scale, seed=1)
    result = {}
    for spec in models:
        name, path = spec.split("=", 1)
        result[name] = hear(SpeechLatentEncoder.from_run(path), waves, emotions, readers)
        print(name, {k: round(v, 3) for k, v in result[name].items() if isinstance(v, float)}, flush=True)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / "word_readers.json").write_text(json.dumps(result, indent=1) + "\n")
    names = list(result)
    n = len(readers) * STRETCHES
    lines = ["# Real voices for validation: thirteen volunteers reading word lists (KTuberling)", "",
             f"{len(readers)} readers, {STRETCHES} stretches of 10 s each ({n} as recorded), never trained or "
             "calibrated on. As recorded, neutral is the right answer; given an emotion's corpus prosody, that "
             "emotion.", "",
             "| | " + " | ".join(names) + " |", "|---|" + "---|" * len(names),
             "| heard as neutral, as recorded | " + " | ".join(f"{result[m]['neutral_share']:.2f}" for m in names) + " |",
             "| trusted by `auto`, as recorded | " + " | ".join(f"{result[m]['trusted_share']:.2f}" for m in names)
             + " |"]
    for e in (e for e in EMOTIONS if e != "neutral"):
        cells = []
        for m in names:
            r = result[m]["emotions"][e]
            top, count = Counter(r["heard"]).most_common(1)[0]
            cells.append(f"{r['heard_as_given']:.2f} ({top} {count})")
        lines.append(f"| given {e}: heard as it (most heard) | " + " | ".join(cells) + " |")
    lines.append("| given an emotion: mean of the seven | " + " | ".join(f"{result[m]['emotions_mean']:.2f}"
                                                                          for m in names) + " |")
    lines += ["", "As recorded, each reader's stretches:", "", "| reader | " + " | ".join(names) + " |",
              "|---|" + "---|" * len(names)]
    for r in readers:
        cells = [", ".join(f"{k} {v}" for k, v in Counter(result[m]["readers"][r]["heard"]).most_common())
                 + f"; trusted {result[m]['readers'][r]['trusted']}" for m in names]
        lines.append(f"| {r} | " + " | ".join(cells) + " |")
    (out / "word_readers.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    main(*sys.argv[1:])
