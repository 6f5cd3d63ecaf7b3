"""What a neutral reference of the same speaker does for the emotion perception (``generate --neutral-from``).

:mod:`emogesture.pipeline.neutral_reference` reads a recording's emotion against a second recording of the
same speaker speaking without emotion. On the validation split only, each speech model is read three ways:
the recording alone (``generate``'s default), against the reference alone (the windows moved by the
reference's offset), and both (the mean of the two hearings: what ``--neutral-from`` does):

- the validation set of real voices (:data:`emogesture.data.real_speech.WORD_READERS`, never trained or
  calibrated on): :data:`STRETCHES` 10-s stretches of each reader, as recorded (neutral is right) and given
  each other emotion's corpus prosody (that emotion is right; :func:`~emogesture.data.real_speech.training_voice_emotions`).
  Each stretch as recorded is in turn the reference of the reader's other stretches;
- the held-out voices of the split (never trained on), as recorded and under the seven changes of
  :func:`emogesture.audio.wave_augment.recording_changes` (the levels left out): the reference is each
  speaker's first neutral take (by name) under the same change, and is itself not scored.

Every window is heard as ``generate`` hears it (the voice also moved ``perception_semitones`` up and down);
the held-out voices' takes are cut at an 8-s hop, as ``perception_shift.py`` cuts them.

Usage: python experiments/neutral_reference.py OUT_DIR CACHE NAME=SPEECH_MODEL [NAME=SPEECH_MODEL ...]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
from tqdm import tqdm

from emogesture.audio import load_audio
from emogesture.audio.wave_augment import recording_changes
from emogesture.data.beat import EMOTIONS
from emogesture.data.cache import open_cache
from emogesture.data.real_speech import WORD_READERS, training_voice_emotions
from emogesture.data.synthetic.corpus import CorpusConfig
from emogesture.models.generation import GenerationConfig
from emogesture.pipeline.neutral_reference import NeutralReference
from emogesture.pipeline.perception import heard_probabilities, perception_of
from emogesture.pipeline.speech import SpeechLatentEncoder

STRETCHES = 4
SPLIT = "val"
READINGS = ("alone", "against the reference", "both")
NEUTRAL = EMOTIONS.index("neutral")


def heard(enc, reference: NeutralReference, perception) -> dict[str, np.ndarray]:
    """The emotion index heard in each window ``[W]``, each way of :data:`READINGS`."""
    relative = reference.relative(enc)
    return {"alone": heard_probabilities(enc, perception).argmax(1),
            "against the reference": heard_probabilities(relative, perception).argmax(1),
            "both": heard_probabilities(enc, perception, relative).argmax(1)}


def readers(encoder: SpeechLatentEncoder, semitones: float) -> dict:
    perception = perception_of(encoder)
    names = list(WORD_READERS)
    waves, emotions = training_voice_emotions(names, STRETCHES, CorpusConfig().emotion_prosody_scale, seed=1)
    encs = [encoder.encode(w, 16000, 10.0, perception_semitones=semitones)[0]
            for w in tqdm(waves, desc="word readers", unit="stretch")]
    per = len(EMOTIONS) * STRETCHES
    hits: dict[str, dict[int, list[bool]]] = {r: {k: [] for k in range(len(EMOTIONS))} for r in READINGS}
    for v in range(len(names)):
        for j in range(STRETCHES):
            reference = NeutralReference.of(encs[v * per + j * len(EMOTIONS) + NEUTRAL], perception, names[v])
            for i in (i for i in range(STRETCHES) if i != j):
                for k in range(len(EMOTIONS)):
                    for r, lab in heard(encs[v * per + i * len(EMOTIONS) + k], reference, perception).items():
                        hits[r][k].append(bool(lab[0] == emotions[v * per + i * len(EMOTIONS) + k]))
    return {r: {"neutral_share": float(np.mean(h[NEUTRAL])),
                "emotions_mean": float(np.mean([np.mean(h[k]) for k in h if k != NEUTRAL])),
                "emotions": {EMOTIONS[k]: float(np.mean(h[k])) for k in h}} for r, h in hits.items()}


def held_out_voices(encoder: SpeechLatentEncoder, cache_dir: str, semitones: float) -> dict:
    perception = perception_of(encoder)
    cache = open_cache(cache_dir)
    split = cache.split(SPLIT)
    root = Path(cache.manifest["root"])
    emotion_of = split.take_emotions(leave_out_speakers=encoder.speakers)
    speaker_of = dict(zip(split.takes, split.speaker_id.tolist()))
    first_neutral: dict[int, str] = {}
    for take in sorted(emotion_of):
        if emotion_of[take] == NEUTRAL:
            first_neutral.setdefault(speaker_of[take], take)
    scored = [t for t in emotion_of if t != first_neutral.get(speaker_of[t]) and speaker_of[t] in first_neutral]
    rng = np.random.default_rng(0)
    changes = {"as recorded": lambda w: w,
               **{n: (lambda w, c=c: np.asarray(c(w), np.float32))
                  for n, c in recording_changes(rng).items() if not n.startswith("recording level")}}
    rows = {}
    for name, change in changes.items():
        encs = {}
        for take in tqdm(list(emotion_of), desc=name, unit="take"):
            wave, _ = load_audio(root / "wave16k" / f"{take}.wav")
            encs[take] = encoder.encode(change(wave), 16000, 8.0, perception_semitones=semitones)[0]
        references = {s: NeutralReference.of(encs[t], perception, t) for s, t in first_neutral.items()}
        hits: dict[str, list[bool]] = {r: [] for r in READINGS}
        for take in scored:
            for r, lab in heard(encs[take], references[speaker_of[take]], perception).items():
                hits[r] += (lab == emotion_of[take]).tolist()
        rows[name] = {r: float(np.mean(h)) for r, h in hits.items()} | {"windows": len(hits["both"])}
    return {"speakers": len(first_neutral), "scored_takes": len(scored), "rows": rows}


def markdown(result: dict) -> str:
    lines = ["# A neutral reference of the same speaker (`generate --neutral-from`), val", "",
             "Each way of reading: the recording alone (`generate`'s default), against the reference alone, and "
             "both (the mean of the two hearings: what `--neutral-from` does).", ""]
    for model, r in result.items():
        lines += [f"## {model}", "", f"Word readers (13 real voices, {STRETCHES} stretches of 10 s each, every stretch "
                  "the reference of the reader's other stretches):", "",
                  "| | " + " | ".join(READINGS) + " |", "|---|" + "---|" * len(READINGS),
                  "| as recorded, heard as neutral | " + " | ".join(f"{r['readers'][w]['neutral_share']:.3f}"
                                                                    for w in READINGS) + " |"]
        for e in (e for e in EMOTIONS if e != "neutral"):
            lines.append(f"| given {e}, heard as it | " + " | ".join(f"{r['readers'][w]['emotions'][e]:.3f}"
                                                                    for w in READINGS) + " |")
        lines.append("| given an emotion: mean of the seven | " + " | ".join(
            f"{r['readers'][w]['emotions_mean']:.3f}" for w in READINGS) + " |")
        v = r["held_out_voices"]
        lines += ["", f"Held-out synthetic voices ({v['speakers']} speakers, {v['scored_takes']} takes scored; each "
                  "speaker's first neutral take, under the same change, the reference), heard as their emotion:", "",
                  "| | windows | " + " | ".join(READINGS) + " |", "|---|---|" + "---|" * len(READINGS)]
        for name, row in v["rows"].items():
            lines.append(f"| {name} | {row['windows']} | " + " | ".join(f"{row[w]:.3f}" for w in READINGS) + " |")
        changed = [row for name, row in v["rows"].items() if name != "as recorded"]
        lines.append("| mean of the seven changes | | " + " | ".join(
            f"{np.mean([row[w] for row in changed]):.3f}" for w in READINGS) + " |")
        lines.append("")
    return "\n".join(lines)


def main(out_dir: str, cache_dir: str, *models: str) -> None:
    semitones = GenerationConfig().perception_semitones
    result = {}
    for spec in models:
        name, path = spec.split("=", 1)
        encoder = SpeechLatentEncoder.from_run(path)
        if perception_of(encoder) is None:
            sys.exit(f"{path}: this speech model has no perception calibration")
        result[name] = {"readers": readers(encoder, semitones),
                        "held_out_voices": held_out_voices(encoder, cache_dir, semitones)}
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / "neutral_reference.json").write_text(json.dumps(result, indent=1) + "\n")
    (out / "neutral_reference.md").write_text(markdown(result))
    print(markdown(result))


if __name__ == "__main__":
    if len(sys.argv) < 4:
        sys.exit(__doc__)
    main(*sys.argv[1:])
