"""What speech models hear in real recorded speech, and whether the recording's level changes it.

For each speech model (calibrated: ``emogesture calibrate speech``), every 10-s window (8-s hop) of the
real read speech of :mod:`emogesture.data.real_speech` (Debian's pocketsphinx-testdata and the Asterisk
telephone prompts), played as
recorded and 10 dB quieter and louder: the emotion the classifier hears (``--emotion own``), whether
``--emotion auto`` trusts the window, and the emotion / voice distances over their thresholds. Real read
speech carries no acted emotion, so neutral is the right answer; a microphone's gain should not change it.

Usage: python experiments/real_perception.py OUT_DIR NAME=SPEECH_MODEL [NAME=SPEECH_MODEL ...]
"""

from __future__ import annotations

import json
import sys
from collections import Counter
from pathlib import Path

import numpy as np

from emogesture.data.real_speech import RECORDINGS, load_real_recording
from emogesture.pipeline.perception import perceive, perception_of
from emogesture.pipeline.speech import SpeechLatentEncoder

GAINS_DB = (0, -10, 10)


def hear(encoder: SpeechLatentEncoder, gain_db: float) -> dict:
    perception = perception_of(encoder)
    rows = {}
    for recording in RECORDINGS:
        wave = load_real_recording(recording) * np.float32(10 ** (gain_db / 20))
        enc, starts = encoder.encode(wave, 16000, 8.0)
        p = perceive(enc, starts, perception, recording.name)
        rows[recording.name] = {"heard": p.labels, "trusted": [bool(t >= 1.0) for t in p.trust],
                                "distance": np.round(p.distance, 3).tolist()}
    heard = [h for r in rows.values() for h in r["heard"]]
    trusted = [t for r in rows.values() for t in r["trusted"]]
    return {"recordings": rows, "windows": len(heard), "neutral": heard.count("neutral"), "trusted": sum(trusted),
            "heard_counts": dict(Counter(heard))}


def main(out_dir: str, *models: str) -> None:
    result = {}
    for spec in models:
        name, path = spec.split("=", 1)
        encoder = SpeechLatentEncoder.from_run(path)
        result[name] = {f"{g:+d} dB": hear(encoder, g) for g in GAINS_DB}
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / "real_perception.json").write_text(json.dumps(result, indent=1) + "\n")
    lines = ["# Real read speech: what the speech models hear", "",
             "Debian's pocketsphinx-testdata (LibriVox reader, card names, CMU utterances) and the Asterisk "
             "telephone prompts (a professional voice), every 10-s window "
             "(8-s hop); neutral is the right answer. Gain: the recordings played that much louder.", "",
             "| model | gain | windows heard as neutral | windows trusted by `auto` | heard |", "|---|---|---|---|---|"]
    for name, by_gain in result.items():
        for gain, r in by_gain.items():
            heard = ", ".join(f"{k} {v}" for k, v in sorted(r["heard_counts"].items(), key=lambda kv: -kv[1]))
            lines.append(f"| {name} | {gain} | {r['neutral']} of {r['windows']} | {r['trusted']} of {r['windows']} "
                         f"| {heard} |")
    (out / "real_perception.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    main(*sys.argv[1:])
