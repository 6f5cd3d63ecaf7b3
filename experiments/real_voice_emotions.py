"""Does a speech model hear the corpus's emotions in a real voice? The real recordings given each emotion's prosody.

No emotion-labelled real speech can be had here, and a model that has learned to hear every real voice as
neutral would pass the real-speech checks without hearing anything. So each real recording of
:mod:`emogesture.data.real_speech` (read without acted emotion) is given, by signal processing, the speech
prosody the synthetic corpus gives each emotion (its factor table at the corpus's default emotion prosody
scale), as :func:`emogesture.data.synthetic.speech.give_prosody` gives it: the pitch raised or lowered and
its movements widened or narrowed (TD-PSOLA, the formants kept), the tempo (WSOLA), the vocal effort
(spectral tilt), breath and tremolo, and the corpus's loudness for that emotion. For each speech model:
the share of the 10-s windows (5-s hop) heard as the emotion given, per emotion, and which emotion is
heard instead. The neutral row is the recording as it was. (Given without breath and tremolo, as this
check first did, sadness, fear and disgust were heard as none of them by any model.)

These are not real emotional voices (a real speaker's anger is more than a louder, brighter, faster
voice), only the corpus's own cues carried by a real voice: a model that hears them there reads the cues it
was taught, not the voice.

Usage: python experiments/real_voice_emotions.py OUT_DIR NAME=SPEECH_MODEL [NAME=SPEECH_MODEL ...]
"""

from __future__ import annotations

import json
import sys
from collections import Counter
from pathlib import Path

import numpy as np

from emogesture.data.beat import EMOTIONS
from emogesture.data.real_speech import load_real_recording, real_recordings
from emogesture.data.synthetic.corpus import CorpusConfig
from emogesture.data.synthetic.factors import emotion_prosody
from emogesture.data.synthetic.speech import give_prosody
from emogesture.pipeline.perception import perceive, perception_of
from emogesture.pipeline.speech import SpeechLatentEncoder

HOP_SECONDS = 5.0


def with_emotion(wave: np.ndarray, emotion: str, seed: int) -> np.ndarray:
    """``wave`` ``[N]`` (16 kHz) given the corpus's speech prosody of ``emotion`` (breath noise and tremolo
    phase from ``seed``); float32."""
    prosody = emotion_prosody(emotion, CorpusConfig().emotion_prosody_scale)
    return give_prosody(wave, prosody, np.random.default_rng(seed))


def main(out_dir: str, *models: str) -> None:
    recordings = real_recordings()
    waves = {r.name: load_real_recording(r) for r in recordings}
    given = {(name, e): with_emotion(w, e, k) if e != "neutral" else w
             for name, w in waves.items() for k, e in enumerate(EMOTIONS)}
    result = {}
    for spec in models:
        name, path = spec.split("=", 1)
        encoder = SpeechLatentEncoder.from_run(path)
        perception = perception_of(encoder)
        rows = {}
        for emotion in EMOTIONS:
            heard: list[str] = []
            per_recording = {}
            for rec in recordings:
                enc, starts = encoder.encode(given[rec.name, emotion], 16000, HOP_SECONDS)
                labels = perceive(enc, starts, perception, rec.name).labels
                per_recording[rec.name] = labels
                heard += labels
            rows[emotion] = {"windows": len(heard), "heard_as_given": heard.count(emotion) / len(heard),
                             "heard": dict(Counter(heard)), "recordings": per_recording}
        result[name] = rows
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / "real_voice_emotions.json").write_text(json.dumps(result, indent=1) + "\n")
    names = list(result)
    lines = ["# The real recordings given each emotion's corpus prosody: heard as that emotion", "",
             f"Recordings: {', '.join(r.name for r in recordings)}; every 10-s window at a {HOP_SECONDS:g}-s hop. "
             "Neutral: the recordings as they were. Each cell: the share heard as the emotion given, then the "
             "emotion most heard.", "",
             "| emotion given | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
    for emotion in EMOTIONS:
        cells = []
        for n in names:
            r = result[n][emotion]
            top, count = Counter(r["heard"]).most_common(1)[0]
            cells.append(f"{r['heard_as_given']:.2f} ({top} {count}/{r['windows']})")
        lines.append(f"| {emotion} | " + " | ".join(cells) + " |")
    means = [np.mean([result[n][e]["heard_as_given"] for e in EMOTIONS if e != "neutral"]) for n in names]
    lines.append("| mean of the seven emotions | " + " | ".join(f"{m:.2f}" for m in means) + " |")
    (out / "real_voice_emotions.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    main(*sys.argv[1:])
