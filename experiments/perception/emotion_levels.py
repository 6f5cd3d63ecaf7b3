"""How loud each emotion is in the synthetic corpus, against real recordings: why a recording played 10 dB quieter
is heard as another emotion.

The speech level of each recording (:func:`emogesture.audio.speech_level`: the log of its active frames' mean mel
power, in dB) for every train and val take of the corpus, by emotion; the packaged real read
speech; and, given a labelled-speech manifest, its val recordings (each speaker's clips of one emotion joined, as
the perception checks hear them). Levels are in dB against the median train take. A gain moves a level by as many
dB; a level the corpus ties to one emotion is then heard as that emotion by a speech model trained on it.

Usage: python experiments/perception/emotion_levels.py CACHE OUT.md [MANIFEST]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
from tqdm import tqdm

from emogesture.audio import kaldi_fbank, load_audio, speech_level
from emogesture.checkpoints import write_text_atomic
from emogesture.data.cache import open_cache
from emogesture.data.labelled_speech import labelled_recordings, read_manifest
from emogesture.data.real_speech import RECORDINGS, load_real_recording
from emogesture.types import EMOTIONS

DB = 10.0 / math.log(10.0)


def level_db(wave: np.ndarray) -> float:
    return DB * speech_level(kaldi_fbank(np.asarray(wave, np.float32)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("cache")
    ap.add_argument("out", type=Path)
    ap.add_argument("manifest", nargs="?")
    args = ap.parse_args()
    cache = open_cache(args.cache)
    root = Path(cache.manifest["root"])
    levels: dict[str, dict[str, list[float]]] = {}
    for split in ("train", "val"):
        takes = cache.split(split).take_emotions()
        for take in tqdm(list(takes), desc=split):
            wave = load_audio(root / "wave16k" / f"{take}.wav")[0]
            levels.setdefault(split, {}).setdefault(EMOTIONS[takes[take]], []).append(level_db(wave))
    reference = float(np.median([v for vs in levels["train"].values() for v in vs]))
    real = [level_db(load_real_recording(r)) - reference for r in RECORDINGS]
    labelled = {}
    if args.manifest:
        for name, (wave, emotion) in labelled_recordings(read_manifest(args.manifest), "val", 10.0).items():
            labelled.setdefault(emotion, []).append(level_db(wave) - reference)

    def row(name: str, values: list[float]) -> str:
        v = np.asarray(values)
        return f"| {name} | {len(v)} | {np.median(v):+.1f} | {np.percentile(v, 10):+.1f} | {np.percentile(v, 90):+.1f} |"

    lines = ["# Speech level by emotion: the synthetic corpus against real recordings", "",
             f"`python experiments/perception/emotion_levels.py` (cache `{Path(args.cache).name}`: every train "
             "and val take; the labelled speech: each val speaker's clips of one emotion joined). Speech level in dB against the median train take "
             "(the log of the active frames' mean mel power); median and 10th-90th percentiles over recordings.",
             "", "| recordings | n | median | p10 | p90 |", "|---|---|---|---|---|"]
    for split in ("train", "val"):
        by = levels[split]
        order = sorted(by, key=lambda e: -float(np.median(by[e])))
        lines += [row(f"corpus {split}: {e}", by[e]) for e in order]
    lines.append(row("real read speech (the packaged recordings)", real))
    for emotion in sorted(labelled, key=lambda e: -float(np.median(labelled[e]))):
        lines.append(row(f"labelled speech, val speakers: {emotion}", labelled[emotion]))
    train = levels["train"]
    spread = max(np.median(v) for v in train.values()) - min(np.median(v) for v in train.values())
    lines += ["", f"The train takes' emotions span {spread:.1f} dB between the loudest and the quietest emotion's "
              "median: a recording 10 dB quieter moves a take more than half of that way, to a quieter emotion's "
              "level.", ""]
    write_text_atomic(args.out, "\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
