"""Real voices that carry emotions: the voice packs of the game Hedgewars, as a labelled-speech manifest.

Every real voice a model here could learn from reads without acted emotion, and a perception taught that
real voices are neutral learns that a real voice is neutral whatever it does. Debian's ``hedgewars-data``
(the sounds GFDL-1.3) holds voice packs recorded by voice actors: about sixty short lines each, shouted,
laughed or sighed in character. The lines' words say what each is acted as, so the lines whose words leave
no doubt are labelled by them (:data:`LINES`; no line is disgust). It is weak labelling (what the line
says, not how a listener rates it), the voices are characters (a mobster, a pirate, a surfer), and each line
lasts about a second; a pack's lines of one emotion are joined into a recording as
:mod:`emogesture.data.labelled_speech` joins any speaker's clips. The packs sung (Singer) or put through a
vocoder (Robot) are left out. Three packs are drawn (seed 0) as val speakers.

``hear`` reads what each speech model hears in the val packs' recordings (each pack's lines of an emotion
joined, repeated past 10.5 s, every 10-s window): the share heard as labelled, per emotion and on average.

Usage: python experiments/game_voices.py MANIFEST
       python experiments/game_voices.py hear MANIFEST OUT_DIR NAME=SPEECH_MODEL [NAME=SPEECH_MODEL ...]
"""

from __future__ import annotations

import json
import sys
from collections import Counter
from pathlib import Path

import numpy as np

from emogesture.checkpoints import write_text_atomic
from emogesture.data.labelled_speech import (LabelledClip, assign_speaker_splits, labelled_recordings,
                                             manifest_text, read_manifest)
from emogesture.errors import InputFileError

VOICES = Path("/usr/share/games/hedgewars/Data/Sounds/voices")
LEFT_OUT = ("Singer", "Robot")
#: Lines whose words say the emotion they are acted with.
LINES = {
    "anger": ("Illgetyou", "Revenge", "Youllregretthat", "Justyouwait", "Gonnagetyou", "Cutitout", "Traitor"),
    "fear": ("Nooo", "Takecover", "Runaway", "Incoming"),
    "happiness": ("Victory", "Laugh", "Excellent", "Brilliant", "Amazing", "Flawless"),
    "sadness": ("Ohdear", "Solong", "Byebye"),
    "contempt": ("Coward", "Stupid", "Boring", "Nutter", "Missed"),
    "surprise": ("Whatthe", "Oops", "Uh-oh"),
    "neutral": ("Hello", "Yessir", "Hmm", "Thisoneismine", "Watchthis", "Sameteam", "Reinforcements"),
}


def game_voice_clips(root: Path = VOICES) -> list[LabelledClip]:
    """The labelled lines of every voice pack under ``root`` (train split)."""
    if not root.is_dir():
        raise InputFileError(root, "no voice packs; install Debian's hedgewars-data")
    clips = []
    for pack in sorted(p for p in root.iterdir() if p.is_dir() and p.name not in LEFT_OUT):
        for emotion, lines in LINES.items():
            for line in lines:
                if (pack / f"{line}.ogg").is_file():
                    clips.append(LabelledClip(pack / f"{line}.ogg", emotion, pack.name))
    return clips


def main(out: str) -> None:
    clips = assign_speaker_splits(game_voice_clips(), 3, 0, seed=0)
    write_text_atomic(out, manifest_text(clips, Path(out).resolve().parent))
    val = sorted({c.speaker for c in clips if c.split == "val"})
    print(f"wrote {out}: {len(clips)} lines of {len({c.speaker for c in clips})} packs (val: {', '.join(val)}); "
          + ", ".join(f"{e} {n}" for e, n in sorted(Counter(c.emotion for c in clips).items())))


def hear(manifest: str, out: str, models: list[str]) -> None:
    from emogesture.pipeline.perception import perceive, perception_of
    from emogesture.pipeline.speech import SpeechLatentEncoder

    recordings = labelled_recordings(read_manifest(manifest), "val", 10.5)
    result = {}
    for item in models:
        name, path = item.split("=", 1)
        encoder = SpeechLatentEncoder.from_run(path)
        perception = perception_of(encoder)
        heard: dict[str, list[str]] = {}
        for recording, (wave, emotion) in recordings.items():
            enc, starts = encoder.encode(wave, 16000, 10.0)
            heard.setdefault(emotion, []).extend(perceive(enc, starts, perception, recording).labels)
        rows = {e: {"heard_as_labelled": float(np.mean([h == e for h in v])), "heard": dict(Counter(v))}
                for e, v in sorted(heard.items())}
        result[name] = {"model": path, "mean": float(np.mean([r["heard_as_labelled"] for r in rows.values()])),
                        "emotions": rows}
    names = list(result)
    lines = ["# Game voices never trained on (val packs), heard as labelled", "",
             f"Recordings: {', '.join(recordings)}.", "", "| emotion | " + " | ".join(names) + " |",
             "|---|" + "---|" * len(names)]
    for e in result[names[0]]["emotions"]:
        cells = []
        for n in names:
            row = result[n]["emotions"][e]
            top = max(row["heard"].items(), key=lambda kv: kv[1])[0]
            cells.append(f"{row['heard_as_labelled']:.2f} (most: {top})")
        lines.append(f"| {e} | " + " | ".join(cells) + " |")
    lines.append("| **mean** | " + " | ".join(f"{result[n]['mean']:.3f}" for n in names) + " |")
    Path(out).mkdir(parents=True, exist_ok=True)
    write_text_atomic(Path(out) / "game_voices.json", json.dumps(result, indent=1))
    write_text_atomic(Path(out) / "game_voices.md", "\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    if len(sys.argv) == 2:
        main(sys.argv[1])
    elif len(sys.argv) >= 5 and sys.argv[1] == "hear":
        hear(sys.argv[2], sys.argv[3], sys.argv[4:])
    else:
        sys.exit(__doc__.rsplit("Usage: ", 1)[1])
