"""How often the front end trained on real speech must hear a long recording: measured on val.

``generate`` lets the front end (Whisper tiny.en and its read-out, :mod:`emogesture.pipeline.voice_features`)
hear a 10-s window at least every ``HEARD_EVERY_S`` seconds where the perception does not trust the speech
model and every ``TRUSTED_HEARD_EVERY_S`` where it does, and interpolates its features for the windows between;
each window heard costs about as much as generating that window's motion. Recordings of one
emotion do not tell intervals apart, so the val recordings here change emotion: the held-out voices of the
synthetic val split, each voice's takes joined in take order, and RAVDESS's val actors, each actor's
recordings of every emotion joined (calm heard as neutral) in an order drawn from a seed. Each window (10 s,
every hop of the bundle's settings) is heard as ``generate`` hears it and scored against the emotion at its
middle; also the windows the front end heard per minute.

Usage: python experiments/perception/hearing_interval.py CACHE RAVDESS_MANIFEST OUT.md [--every 20/20,10/60,...]
(each setting: untrusted/trusted intervals in seconds)
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from tqdm import tqdm

from emogesture.audio import load_audio
from emogesture.checkpoints import write_text_atomic
from emogesture.data.cache import open_cache
from emogesture.data.labelled_speech import labelled_recordings, read_manifest
from emogesture.pipeline import voice_features
from emogesture.pipeline.generate import GesturePipeline
from emogesture.types import EMOTIONS

RATE = 16000


def joined(parts: list[tuple[np.ndarray, str]]) -> tuple[np.ndarray, np.ndarray]:
    """Recordings of one emotion each -> one waveform and the emotion index of each of its samples."""
    wave = np.concatenate([w for w, _ in parts]).astype(np.float32)
    labels = np.concatenate([np.full(len(w), EMOTIONS.index(e)) for w, e in parts])
    return wave, labels


def synthetic_val(cache_dir: str, speakers: list[int]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    cache = open_cache(cache_dir)
    root = Path(cache.manifest["root"])
    emotion_of = cache.split("val").take_emotions(leave_out_speakers=speakers)
    voices: dict[str, list] = {}
    for take in sorted(emotion_of):
        voice = take.split("_")[1]
        voices.setdefault(voice, []).append((load_audio(root / "wave16k" / f"{take}.wav")[0], EMOTIONS[emotion_of[take]]))
    return {f"synthetic {v}": joined(parts) for v, parts in voices.items()}


def ravdess_val(manifest: str, seed: int = 0) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    actors: dict[str, list] = {}
    for name, (wave, emotion) in labelled_recordings(read_manifest(manifest), "val", 10.0).items():
        actors.setdefault(name.split("_")[0], []).append((wave, "neutral" if emotion == "calm" else emotion))
    rng = np.random.default_rng(seed)
    return {f"RAVDESS {a}": joined([parts[i] for i in rng.permutation(len(parts))]) for a, parts in actors.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("cache")
    ap.add_argument("manifest")
    ap.add_argument("out", type=Path)
    ap.add_argument("--every", default="20/20,10/10,40/40,60/60,10/60,20/60",
                    help="the settings to compare: UNTRUSTED/TRUSTED intervals (s), comma-separated")
    args = ap.parse_args()
    settings = [tuple(float(x) for x in item.split("/")) for item in args.every.split(",")]
    pipe = GesturePipeline.from_run()
    sets = {"synthetic val, held-out voices joined": synthetic_val(args.cache, pipe.speech.speakers),
            "RAVDESS val actors, every emotion joined": ravdess_val(args.manifest)}
    rows = []
    for untrusted, trusted in settings:
        voice_features.HEARD_EVERY_S, voice_features.TRUSTED_HEARD_EVERY_S = untrusted, trusted
        row = [f"{untrusted:g} / {trusted:g}"]
        for name, recordings in sets.items():
            right = total = 0
            heard_per_min = []
            for source, (wave, labels) in tqdm(recordings.items(), desc=f"{row[0]} s: {name}", leave=False):
                enc, starts = pipe.encode(wave)
                perceived = pipe.perceive(enc, starts, source)
                middle = np.minimum(((np.asarray(starts) + 5.0) * RATE).astype(int), len(labels) - 1)
                right += int(sum(EMOTIONS.index(lab) == t for lab, t in zip(perceived.labels, labels[middle])))
                total += len(starts)
                hop = starts[1] - starts[0] if len(starts) > 1 else 10.0
                every = np.where(pipe.speech._trusted(enc), trusted, untrusted)
                heard = len(voice_features.hearing_plan(every, hop)[0])
                heard_per_min.append(heard / (len(wave) / RATE / 60))
            row.append(f"{right / total:.3f} ({total}) | {np.mean(heard_per_min):.1f}")
        rows.append("| " + " | ".join(row) + " |")
        print(rows[-1], flush=True)
    text = ("# How often the front end hears a long recording (val)\n\n"
            "`python experiments/perception/hearing_interval.py` (the bundled model, heard as `generate` hears; "
            "recordings that change emotion: each held-out voice's val takes joined, each RAVDESS val actor's "
            "emotions joined). Per set: the share of windows heard as the emotion at their middle (windows), and "
            "the windows the front end hears a minute.\n\n"
            "| front end every (s): untrusted / trusted windows | "
            + " | ".join(f"{name} | heard a minute" for name in sets) + " |\n"
            "|---|" + "---|---|" * len(sets) + "\n" + "\n".join(rows) + "\n")
    write_text_atomic(args.out, text)


if __name__ == "__main__":
    main()
