"""What a recording's bandwidth does to the speech models' perception: held-out voices low-passed or through MP3.

Real recordings often end below 8 kHz: a lossy codec's low-pass (the LibriVox reader of the real-speech
checks is a 64-kbit/s MP3, its level 13 dB lower above 4 kHz than below), an old microphone, a telephone.
The synthetic voices never do. Every fourth take of the val split's held-out voices (the val speakers,
never trained on) is played as recorded, through an 8th-order low-pass at 4, 5 and 6 kHz and through MP3
at 32 and 64 kbit/s (ffmpeg), and heard by each speech model (calibrated): the share of windows heard
as the take's emotion, the median emotion and voice distances over their thresholds, and the share
`--emotion auto` trusts (both distances within their thresholds).

Usage: python experiments/speech_training/band_limits.py CACHE OUT_DIR NAME=SPEECH_MODEL [NAME=SPEECH_MODEL ...]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
from scipy.signal import butter, sosfiltfilt
from tqdm import tqdm

from emogesture.audio import load_audio
from emogesture.audio.wave_augment import codec_roundtrip
from emogesture.data.beat import EMOTIONS
from emogesture.data.cache import open_cache
from emogesture.pipeline.perception import perceive, perception_of
from emogesture.pipeline.speech import SpeechLatentEncoder


def low_pass(cutoff_hz: float):
    sos = butter(8, cutoff_hz, "lowpass", fs=16000, output="sos")
    return lambda w: sosfiltfilt(sos, w)


CHANGES = {"as recorded": lambda w: w, "low-pass 4 kHz": low_pass(4000), "low-pass 5 kHz": low_pass(5000),
           "low-pass 6 kHz": low_pass(6000), "MP3 32 kbit/s": lambda w: codec_roundtrip(w, "mp3", 32),
           "MP3 64 kbit/s": lambda w: codec_roundtrip(w, "mp3", 64)}


def main(cache_dir: str, out_dir: str, *models: str) -> None:
    cache = open_cache(cache_dir)
    val = cache.split("val")
    root = Path(cache.manifest["root"])
    emotion_of = {t: int(e) for t, e in zip(val.takes, val.emotion)}
    result = {}
    for spec in models:
        name, path = spec.split("=", 1)
        encoder = SpeechLatentEncoder.from_run(path)
        perception = perception_of(encoder)
        unheard = {t for t, s in zip(val.takes, val.speaker_id.tolist()) if s not in encoder.speakers}
        takes = [t for t in dict.fromkeys(val.takes) if t in unheard][::4]
        waves = {t: load_audio(root / "wave16k" / f"{t}.wav")[0] for t in takes}
        rows = {}
        for change_name, change in tqdm(CHANGES.items(), desc=name, unit="change"):
            hits, emotion_d, voice_d, trusted = [], [], [], []
            for take, wave in waves.items():
                enc, starts = encoder.encode(np.asarray(change(wave), np.float32), 16000, 8.0)
                p = perceive(enc, starts, perception, take)
                hits += [label == EMOTIONS[emotion_of[take]] for label in p.labels]
                emotion_d += p.distance[:, 0].tolist()
                voice_d += p.distance[:, 1].tolist()
                trusted += (p.trust >= 1.0).tolist()
            rows[change_name] = {"windows": len(hits), "correct": float(np.mean(hits)),
                                 "emotion_distance": float(np.median(emotion_d)),
                                 "voice_distance": float(np.median(voice_d)), "trusted": float(np.mean(trusted))}
        result[name] = {"takes": len(takes), "rows": rows}
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / "band_limits_val.json").write_text(json.dumps(result, indent=1) + "\n")
    lines = ["# Held-out voices through a narrower band (val)", "",
             "Every fourth take of the val split's held-out voices; per window: heard as the take's emotion, the "
             "median emotion / voice distance over its threshold, the share `auto` trusts.", "",
             "| model | audio | windows | correct | emotion distance | voice distance | trusted |",
             "|---|---|---|---|---|---|---|"]
    for name, r in result.items():
        lines += [f"| {name} | {k} | {v['windows']} | {v['correct']:.3f} | {v['emotion_distance']:.2f} | "
                  f"{v['voice_distance']:.2f} | {v['trusted']:.2f} |" for k, v in r["rows"].items()]
    (out / "band_limits_val.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main(*sys.argv[1:])
