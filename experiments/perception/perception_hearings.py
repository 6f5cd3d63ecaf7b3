"""The emotion heard in a window from one hearing or from several, the voice moved up and down in pitch.

The held-out takes of a split (the voices the speech model never heard) are played through the changes of
the robustness reports (:func:`emogesture.audio.wave_augment.recording_changes`, the two level changes left
out: the perception is level-bound by design), and the real read speech (:mod:`emogesture.data.real_speech`;
a check, never a criterion) as it is. Every 10-s window (8-s hop) is heard as recorded and with the voice
moved ±1.5, ±3, ±4.5 or ±6 semitones (``SpeechLatentEncoder.encode(perception_semitones=...)``), and, beside the ±3
semitones, through a telephone band or 6 dB louder and quieter (each of these an encoding of its own, so its
noise suppression is measured on it); each setting's label is the argmax of the mean of its hearings'
probabilities (:func:`emogesture.pipeline.perception.heard_probabilities`).

Usage: python experiments/perception/perception_hearings.py SPEECH_MODEL CACHE OUT_DIR [SPLIT]   (SPLIT: val)
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
from tqdm import tqdm

from emogesture.audio import load_audio
from emogesture.audio.wave_augment import recording_changes, telephone
from emogesture.data.beat import EMOTIONS
from emogesture.data.cache import open_cache
from emogesture.data.real_speech import load_real_recording, real_recordings
from emogesture.pipeline.perception import heard_probabilities, perception_of
from emogesture.pipeline.speech import EncodedWindows, SpeechLatentEncoder

# each setting: the pitch moves (semitones, heard up and down) and the other hearings beside the recording's own
SETTINGS = {"once": ((), ()), "±1.5 st": ((1.5,), ()), "±3 st": ((3.0,), ()), "±4.5 st": ((4.5,), ()),
            "±6 st": ((6.0,), ()), "±1.5 and ±3 st": ((1.5, 3.0), ()),
            "±3 st and a telephone band": ((3.0,), ("telephone",)),
            "±3 st and ±6 dB": ((3.0,), ("6 dB louder", "6 dB quieter"))}
OTHER_HEARINGS = {"telephone": telephone, "6 dB louder": lambda w: np.clip(w * 10 ** (6 / 20), -1.0, 1.0),
                  "6 dB quieter": lambda w: w * 10 ** (-6 / 20)}


def hearings(encoder: SpeechLatentEncoder, wave: np.ndarray) -> tuple[EncodedWindows, dict]:
    heard: dict = {s: encoder.encode(wave, 16000, 8.0, perception_semitones=s)[0]
                   for s in sorted({s for shifts, _ in SETTINGS.values() for s in shifts})}
    for name, change in OTHER_HEARINGS.items():
        heard[name] = encoder.encode(np.asarray(change(wave), np.float32), 16000, 8.0, parts=("emotion",))[0]
    return heard[3.0], heard


def labels(enc: EncodedWindows, heard: dict, setting: tuple[tuple[float, ...], tuple[str, ...]],
           perception) -> np.ndarray:
    shifts, others = setting
    one = EncodedWindows(*(getattr(enc, k) for k in EncodedWindows.stored))
    if shifts or others:
        one.shifted_emotion = np.concatenate([heard[s].shifted_emotion for s in shifts]
                                             + [heard[o].emotion[None] for o in others])
        one.shifted_logits = np.concatenate([heard[s].shifted_logits for s in shifts]
                                            + [heard[o].emotion_logits[None] for o in others])
    return heard_probabilities(one, perception).argmax(1)


def main(speech_model: str, cache_dir: str, out_dir: str, split: str = "val") -> None:
    encoder = SpeechLatentEncoder.from_run(speech_model)
    perception = perception_of(encoder)
    cache = open_cache(cache_dir)
    windows = cache.split(split)
    root = Path(cache.manifest["root"])
    emotion_of = windows.take_emotions(leave_out_speakers=encoder.speakers)
    takes = list(emotion_of)
    if not takes:
        raise SystemExit(f"{cache_dir}: the {split} split has no voice the speech model never heard")
    rng = np.random.default_rng(0)
    changes = {"as recorded": lambda w: w,
               **{k: v for k, v in recording_changes(rng).items() if "level" not in k}}
    table: dict[str, dict[str, float]] = {name: {} for name in SETTINGS}
    for change_name, change in changes.items():
        hits = {name: [] for name in SETTINGS}
        for take in tqdm(takes, desc=change_name, leave=False):
            wave, _ = load_audio(root / "wave16k" / f"{take}.wav")
            enc, heard = hearings(encoder, np.asarray(change(wave), np.float32))
            for name, setting in SETTINGS.items():
                hits[name] += (labels(enc, heard, setting, perception) == emotion_of[take]).tolist()
        for name in SETTINGS:
            table[name][change_name] = float(np.mean(hits[name]))
    real = {name: {} for name in SETTINGS}
    for recording in real_recordings():
        enc, heard = hearings(encoder, np.asarray(load_real_recording(recording), np.float32))
        for name, setting in SETTINGS.items():
            real[name][recording.name] = [EMOTIONS[k] for k in labels(enc, heard, setting, perception)]
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    result = {"split": split, "takes": len(takes), "model": speech_model, "correct": table, "real": real}
    (out / f"perception_hearings_{split}.json").write_text(json.dumps(result, indent=1) + "\n")
    names = list(changes)
    lines = ["# The emotion heard from one hearing or several", "",
             f"{len(takes)} takes of the {split} split, the voices the speech model never heard; every 10-s window "
             "(8-s hop). Share of the windows heard as the take's emotion; each setting averages the probabilities "
             "of its hearings (as recorded, the voice moved that many semitones up and down, and the others named). "
             "Real read speech: "
             "windows heard as neutral (a check: no part of it chose anything).", "",
             "| hearings | " + " | ".join(names) + " | mean of the changes | real speech heard as neutral |",
             "|---|" + "---|" * (len(names) + 2)]
    for name in SETTINGS:
        row = table[name]
        heard_real = [lab for labs in real[name].values() for lab in labs]
        lines.append(f"| {name} | " + " | ".join(f"{row[c]:.3f}" for c in names)
                     + f" | {np.mean([row[c] for c in names[1:]]):.3f} | "
                     + f"{heard_real.count('neutral')} of {len(heard_real)} |")
    lines += ["", "Real read speech, per window:", ""]
    for name in SETTINGS:
        lines.append(f"- {name}: " + "; ".join(f"{rec} " + ", ".join(labs) for rec, labs in real[name].items()))
    (out / f"perception_hearings_{split}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main(*sys.argv[1:5])
