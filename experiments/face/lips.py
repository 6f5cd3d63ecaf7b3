"""The face track's checks on real read speech with a transcript (nothing here is trained).

Recordings: Debian's ``pocketsphinx-testdata`` LibriVox clips (five, one reader) and two Asterisk prompts of
``asterisk-core-sounds-en-g722`` (Allison Smith; their texts from ``core-sounds-en.txt``; the third prompt the
real-speech report uses is left out: four of its words are not in the pronouncing dictionary, so its
alignment would be wrong). The face is made as ``generate --face`` makes it: the phones *recognised* from the
audio alone (no transcript). It is scored against the transcript's forced alignment (pocketsphinx, the words'
dictionary phones), with openness = max(0, jawOpen - mouthClose):

- bilabials (P, B, M): the lowest openness within the phone (+-1 frame) below half the median openness of the
  recording's open vowels (AA, AE, AH, AO, AW, AY), share of them; open vowels' mean openness over the
  bilabials';
- pauses of 0.4 s or more (silences of the alignment): the share of their frames (after their first and before
  their last 100 ms) with openness < 0.1;
- audio-visual offset: the lag (frames) at which the cross-correlation of openness with the voice's RMS peaks;
- blinks a minute; every weight within [0, 1];
- the emotion by label on the same recordings: mouthSmile under happiness against sadness, browInnerUp under
  sadness against happiness, browDown under anger against happiness (means over all frames).

Usage: python experiments/face/lips.py OUT_DIR [--librivox-only]
"""

from __future__ import annotations

import gzip
import json
import sys
from pathlib import Path

import numpy as np

from emogesture.audio import load_audio
from emogesture.audio.onsets import frame_energy
from emogesture.face.arkit import CLOSURES, INDEX, OPEN_VOWELS
from emogesture.face.phones import recognise_phones
from emogesture.face.track import face_track
from emogesture.types import EMOTIONS

LIBRIVOX = Path("/usr/share/pocketsphinx/test/data/librivox")
ASTERISK = Path("/usr/share/asterisk/sounds/en_US_f_Allison")
ASTERISK_TEXTS = Path("/usr/share/doc/asterisk-core-sounds-en/core-sounds-en.txt.gz")
PROMPTS = ("demo-congrats", "demo-echotest")
FPS = 30


def recordings(librivox_only: bool = False) -> list[tuple[str, np.ndarray, str]]:
    """``(name, 16-kHz waveform, transcript)`` of the installed recordings."""
    out = []
    for line in (LIBRIVOX / "transcription").read_text().splitlines():
        text, name = line.rsplit("(", 1)
        wave, _ = load_audio(LIBRIVOX / f"{name.strip(' )')}.wav")
        out.append((name.strip(" )"), wave, text.replace("<s>", "").replace("</s>", "").strip()))
    if not librivox_only and ASTERISK_TEXTS.exists():
        texts = dict(line.split(": ", 1) for line in gzip.open(ASTERISK_TEXTS, "rt") if ": " in line)
        for name in PROMPTS:
            out.append((name, load_audio(ASTERISK / f"{name}.g722")[0], texts[name].strip()))
    return out


def openness(arkit: np.ndarray) -> np.ndarray:
    return np.maximum(arkit[:, INDEX["jawOpen"]] - arkit[:, INDEX["mouthClose"]], 0.0)


def frames_of(phone, n: int, pad: int = 0) -> slice:
    return slice(max(int(np.floor(phone.start * FPS)) - pad, 0), min(int(np.ceil(phone.end * FPS)) + pad, n))


def lag(op: np.ndarray, loud: np.ndarray, most: int = 10) -> int:
    """The lag (frames; positive: the mouth after the voice) at which their correlation peaks."""
    z, e = (op - op.mean()) / (op.std() + 1e-9), (loud - loud.mean()) / (loud.std() + 1e-9)
    n = len(z)
    scores = [np.mean(z[max(k, 0) : n + min(k, 0)] * e[max(-k, 0) : n - max(k, 0)]) for k in range(-most, most + 1)]
    return int(np.argmax(scores)) - most


def under(wave: np.ndarray, n: int, label: str, phones) -> np.ndarray:
    weights = np.zeros((n, len(EMOTIONS)), np.float32)
    weights[:, EMOTIONS.index(label)] = 1.0
    return face_track(wave, 16000, n, weights, phones=phones).arkit


def checks(recs: list[tuple[str, np.ndarray, str]]) -> dict:
    """The checks of the module docstring over ``recs``, with per-recording rows."""
    rows, lowest, medians, vowels, closures, pauses, lags = [], [], [], [], [], [], []
    blinks, seconds, bounds = 0, 0.0, True
    emotion = {k: [] for k in ("smile_happy", "smile_sad", "brow_inner_sad", "brow_inner_happy", "brow_down_angry",
                               "brow_down_happy")}
    for name, wave, text in recs:
        n = int(round(len(wave) / 16000 * FPS))
        heard = recognise_phones(wave, 16000)
        aligned = recognise_phones(wave, 16000, transcript=text)
        arkit = face_track(wave, 16000, n, phones=heard).arkit
        bounds &= bool(arkit.min() >= 0 and arkit.max() <= 1)
        op = openness(arkit)
        open_v = [op[frames_of(p, n)].mean() for p in aligned if p.name in OPEN_VOWELS]
        med = float(np.median(open_v))
        bil = [op[frames_of(p, n, 1)] for p in aligned if p.name in CLOSURES]
        lowest += [float(b.min()) for b in bil]
        medians += [med] * len(bil)
        closures += [float(b.mean()) for b in bil]
        vowels += open_v
        pause = [op[int(np.ceil((p.start + 0.1) * FPS)) : int(np.floor((p.end - 0.1) * FPS))]
                 for p in aligned if p.name == "SIL" and p.end - p.start >= 0.4]
        pauses += [float(v) for p in pause for v in p]
        lags.append(lag(op, frame_energy(wave, 16000, fps=FPS)[:n]))
        blink = arkit[:, INDEX["eyeBlinkLeft"]] > 0.5
        blinks += int(np.sum(np.diff(blink.astype(int)) == 1))
        seconds += n / FPS
        happy, sad, angry = (under(wave, n, e, heard) for e in ("happiness", "sadness", "anger"))
        emotion["smile_happy"].append(happy[:, INDEX["mouthSmileLeft"]].mean())
        emotion["smile_sad"].append(sad[:, INDEX["mouthSmileLeft"]].mean())
        emotion["brow_inner_sad"].append(sad[:, INDEX["browInnerUp"]].mean())
        emotion["brow_inner_happy"].append(happy[:, INDEX["browInnerUp"]].mean())
        emotion["brow_down_angry"].append(angry[:, INDEX["browDownLeft"]].mean())
        emotion["brow_down_happy"].append(happy[:, INDEX["browDownLeft"]].mean())
        rows.append({"recording": name, "seconds": round(n / FPS, 1), "phones_heard": len(heard),
                     "bilabials": len(bil), "bilabials_closed": float(np.mean([b.min() < 0.5 * med for b in bil]))
                     if bil else None, "pause_frames": sum(len(p) for p in pause), "lag_frames": lags[-1]})
    closed = np.array(lowest) < 0.5 * np.array(medians)
    return {"recordings": rows, "bilabials": len(lowest), "bilabials_closed": float(closed.mean()),
            "open_over_bilabial": float(np.mean(vowels) / max(np.mean(closures), 1e-9)),
            "pause_frames": len(pauses), "pause_closed": float(np.mean(np.array(pauses) < 0.1)) if pauses else None,
            "lags": lags, "blinks_per_minute": blinks / seconds * 60, "weights_within_0_1": bounds,
            **{k: float(np.mean(v)) for k, v in emotion.items()}}


def report(result: dict) -> str:
    r = result
    yes = lambda ok: "holds" if ok else "**fails**"  # noqa: E731
    pause = ("no pause of 0.4 s or more" if r["pause_closed"] is None else
             f"{r['pause_closed']:.1%} of {r['pause_frames']} frames")
    lines = ["# The face on real read speech (nothing trained; phones recognised, scored on forced alignment)", "",
             "| check | measured | bar | |", "|---|---|---|---|",
             f"| bilabials closed (lowest openness < half the open vowels' median) | {r['bilabials_closed']:.1%} of "
             f"{r['bilabials']} | ≥ 80 % | {yes(r['bilabials_closed'] >= 0.8)} |",
             f"| open vowels' openness over the bilabials' | {r['open_over_bilabial']:.2f} | ≥ 2 | "
             f"{yes(r['open_over_bilabial'] >= 2)} |",
             f"| pauses ≥ 0.4 s: openness < 0.1 | {pause} | ≥ 85 % | "
             f"{'—' if r['pause_closed'] is None else yes(r['pause_closed'] >= 0.85)} |",
             f"| openness against loudness: lag of the peak (frames) | {', '.join(map(str, r['lags']))} | within ±1 | "
             f"{yes(all(abs(x) <= 1 for x in r['lags']))} |",
             f"| blinks a minute | {r['blinks_per_minute']:.1f} | 8–30 | {yes(8 <= r['blinks_per_minute'] <= 30)} |",
             f"| every weight in [0, 1] | {r['weights_within_0_1']} | true | {yes(r['weights_within_0_1'])} |",
             f"| mouthSmile, happiness − sadness | {r['smile_happy'] - r['smile_sad']:.3f} | ≥ 0.1 | "
             f"{yes(r['smile_happy'] - r['smile_sad'] >= 0.1)} |",
             f"| browInnerUp, sadness − happiness | {r['brow_inner_sad'] - r['brow_inner_happy']:.3f} | > 0 | "
             f"{yes(r['brow_inner_sad'] > r['brow_inner_happy'])} |",
             f"| browDown, anger − happiness | {r['brow_down_angry'] - r['brow_down_happy']:.3f} | > 0 | "
             f"{yes(r['brow_down_angry'] > r['brow_down_happy'])} |", "",
             "| recording | s | phones heard | bilabials | closed | pause frames | lag |", "|---|---|---|---|---|---|---|"]
    for row in r["recordings"]:
        closed = "—" if row["bilabials_closed"] is None else f"{row['bilabials_closed']:.0%}"
        lines.append(f"| {row['recording']} | {row['seconds']} | {row['phones_heard']} | {row['bilabials']} | "
                     f"{closed} | {row['pause_frames']} | {row['lag_frames']} |")
    return "\n".join(lines) + "\n"


def main(out_dir: str, *flags: str) -> None:
    result = checks(recordings("--librivox-only" in flags))
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / "lips.json").write_text(json.dumps(result, indent=1) + "\n")
    (out / "lips.md").write_text(report(result))
    print(report(result))


if __name__ == "__main__":
    main(*sys.argv[1:])
