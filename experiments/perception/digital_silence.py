"""Digital silence in a recording, heard as it is or as the recording's own quiet.

No microphone records exact zeros, and no training recording holds them; a user's file can: clips joined
with inserted silence, a recorder's noise gate, padding. The held-out takes of a split (the voices the
speech model never heard) are heard as recorded, with 0.3 s of digital silence inserted every 3 s (clips
joined), and through a noise gate (every 20-ms frame more than 35 dB below the take's loud frames set to
zero); each with the encoder's ``fill_digital_silence`` off and on (:func:`emogesture.audio.fill_digital_silence`,
its frames filled with each bin's 10th percentile or its 1st, the library's), heard as ``generate`` hears it
otherwise. The real read speech (:mod:`emogesture.data.real_speech`, whose
clips are joined with 0.3 s of digital silence) is a check: windows heard as neutral and trusted by ``auto``.

Usage: python experiments/perception/digital_silence.py SPEECH_MODEL CACHE OUT_DIR [SPLIT]   (SPLIT: val)
"""

from __future__ import annotations

import json
import sys
from functools import partial
from pathlib import Path

import numpy as np
from tqdm import tqdm

import emogesture.pipeline.speech as speech_module
from emogesture.audio import fill_digital_silence, load_audio
from emogesture.data.beat import EMOTIONS
from emogesture.data.cache import open_cache
from emogesture.data.real_speech import load_real_recording, real_recordings
from emogesture.models.generation import GenerationConfig
from emogesture.pipeline.perception import perceive, perception_of
from emogesture.pipeline.speech import SpeechLatentEncoder

RATE = 16000
FILLS = {"as it is": None, "filled (10th percentile)": 10.0, "filled (1st percentile)": 1.0}


def joined(w: np.ndarray, every_s: float = 3.0, gap_s: float = 0.3) -> np.ndarray:
    step = int(every_s * RATE)
    parts = []
    for i in range(0, len(w), step):
        parts += [w[i: i + step], np.zeros(int(gap_s * RATE), np.float32)]
    return np.concatenate(parts[:-1])


def gated(w: np.ndarray, below_db: float = 35.0, frame_s: float = 0.02) -> np.ndarray:
    n = int(frame_s * RATE)
    k = len(w) // n
    rms = np.sqrt((w[: k * n].reshape(k, n).astype(np.float64) ** 2).mean(1) + 1e-20)
    quiet = 20 * np.log10(rms / np.percentile(rms, 95)) < -below_db
    out = w.copy()
    out[: k * n].reshape(k, n)[quiet] = 0.0
    return out


def main(speech_model: str, cache_dir: str, out_dir: str, split: str = "val") -> None:
    encoder = SpeechLatentEncoder.from_run(speech_model)
    perception = perception_of(encoder)
    semitones = GenerationConfig().perception_semitones
    cache = open_cache(cache_dir)
    windows = cache.split(split)
    root = Path(cache.manifest["root"])
    emotion_of = {t: EMOTIONS[e] for t, e in windows.take_emotions(leave_out_speakers=encoder.speakers).items()}
    takes = list(emotion_of)
    if not takes:
        raise SystemExit(f"{cache_dir}: the {split} split has no voice the speech model never heard")
    changes = {"as recorded": lambda w: w, "0.3 s of digital silence every 3 s": joined,
               "noise gate, 35 dB": gated}

    def heard(wave: np.ndarray, fill: float | None, source: str):
        encoder.fill_digital_silence = fill is not None
        speech_module.fill_digital_silence = partial(fill_digital_silence, percentile=fill or 10.0)
        enc, starts = encoder.encode(wave, RATE, 8.0, perception_semitones=semitones)
        return perceive(enc, starts, perception, source)

    table: dict[str, dict[str, dict[str, float]]] = {}
    for name, change in changes.items():
        table[name] = {}
        for fill_name, fill in FILLS.items():
            hits, trust, silence = [], [], []
            for take in tqdm(takes, desc=f"{name}, {fill_name}", leave=False):
                wave, _ = load_audio(root / "wave16k" / f"{take}.wav")
                p = heard(np.asarray(change(wave), np.float32), fill, take)
                hits += [lab == emotion_of[take] for lab in p.labels]
                trust += list(p.trust >= 1.0)
                silence.append(p.digital_silence_s)
            table[name][fill_name] = {"correct": float(np.mean(hits)), "trusted": float(np.mean(trust)),
                                      "windows": len(hits), "silence_s": float(np.mean(silence))}
    real: dict[str, dict[str, list]] = {fill_name: {} for fill_name in FILLS}
    for recording in real_recordings():
        wave = load_real_recording(recording)
        for fill_name, fill in FILLS.items():
            p = heard(wave, fill, recording.name)
            real[fill_name][recording.name] = [p.labels, [bool(t >= 1.0) for t in p.trust]]
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / f"digital_silence_{split}.json").write_text(json.dumps(
        {"split": split, "takes": len(takes), "model": speech_model, "perception_semitones": semitones,
         "fills": FILLS,
         "rows": table, "real": real}, indent=1) + "\n")
    lines = ["# Digital silence heard as it is, or as the recording's own quiet", "",
             f"{len(takes)} takes of the {split} split, the voices the speech model never heard; every 10-s window "
             "(8-s hop). Correct: heard as the take's emotion; trusted: within the range `auto` trusts.", "",
             "| recording | digital silence per take (s) | " + " | ".join(f"correct, {f}" for f in FILLS) + " | "
             + " | ".join(f"trusted, {f}" for f in FILLS) + " |", "|---|---|" + "---|" * (2 * len(FILLS))]
    for name, r in table.items():
        last = list(FILLS)[-1]
        lines.append(f"| {name} | {r[last]['silence_s']:.1f} | " + " | ".join(f"{r[f]['correct']:.3f}" for f in FILLS)
                     + " | " + " | ".join(f"{r[f]['trusted']:.3f}" for f in FILLS) + " |")
    lines += ["", "Real read speech (a check; its clips joined with 0.3 s of digital silence):", "",
              "| recording | " + " | ".join(f"heard, {f}" for f in FILLS) + " | "
              + " | ".join(f"trusted, {f}" for f in FILLS) + " |", "|---|" + "---|" * (2 * len(FILLS))]
    for rec in real[list(FILLS)[0]]:
        lines.append(f"| {rec} | " + " | ".join(", ".join(real[f][rec][0]) for f in FILLS) + " | "
                     + " | ".join(f"{sum(real[f][rec][1])} of {len(real[f][rec][1])}" for f in FILLS) + " |")
    cells, trusted_cells = [], []
    for f in FILLS:
        labels = [lab for labs, _ in real[f].values() for lab in labs]
        trusted = [t for _, ts in real[f].values() for t in ts]
        cells.append(f"neutral {labels.count('neutral')} of {len(labels)}")
        trusted_cells.append(f"{sum(trusted)} of {len(trusted)}")
    lines.append("| **all** | " + " | ".join(cells) + " | " + " | ".join(trusted_cells) + " |")
    (out / f"digital_silence_{split}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main(*sys.argv[1:5])
