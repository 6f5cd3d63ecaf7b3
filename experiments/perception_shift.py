"""What the speech model's emotion perception does on voices unlike its training voices.

The held-out takes of the synthetic corpus — those of the voices the speech model never heard when the
cache splits by speaker (``prepare --set split_source=csv+actor``), else every take of the split — are
played through changes that move a voice away from the training voices
(:func:`emogesture.audio.wave_augment.recording_changes`: pitch ±4 semitones, tempo ±15 %, white noise at
10 dB SNR, a telephone band, a reverberant room, a recording 10 dB quieter and one 6 dB louder), and pink
noise alone (no speech at all). For each, over every 10-s window: how often the
perceived emotion is the take's emotion, the median distance to the nearest emotion mean (in units of
the trust threshold), the same for the voice (style latent to the nearest training speaker), and the
share of windows that `generate --emotion auto` blends toward neutral. Each window is heard as `generate`
hears it (the default generation settings: noise suppression; the recording heard by the front end trained on
real speech as well, both read-outs multiplied, where the bundle has its read-out and its packages are
installed, else the voice heard also moved ``perception_semitones`` up and down).

Usage: python experiments/perception_shift.py SPEECH_MODEL CACHE OUT_DIR [SPLIT] [SEMITONES]
(SEMITONES: the pitch-shifted hearings; default: the setting of the bundle SPEECH_MODEL belongs to)
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from emogesture.audio import load_audio
from emogesture.audio.wave_augment import recording_changes
from emogesture.data.beat import EMOTIONS
from emogesture.data.cache import open_cache
from emogesture.pipeline.generate import bundle_generation
from emogesture.pipeline.perception import perceive, perception_of
from emogesture.pipeline.speech import SpeechLatentEncoder
from emogesture.pipeline.voice_features import front_end_installed


def pink(length: int, rng: np.random.Generator) -> np.ndarray:
    spec = np.fft.rfft(rng.normal(size=length))
    spec /= np.sqrt(np.maximum(np.arange(len(spec)), 1))
    out = np.fft.irfft(spec, length)
    return (0.05 * out / out.std()).astype(np.float32)


def main(speech_model: str, cache_dir: str, out_dir: str, split: str = "test", semitones: str | None = None) -> None:
    encoder = SpeechLatentEncoder.from_run(speech_model)
    perception = perception_of(encoder)
    cache = open_cache(cache_dir)
    test = cache.split(split)
    root = Path(cache.manifest["root"])
    unheard = test.take_emotions(leave_out_speakers=encoder.speakers)
    which = "held-out voices" if unheard else "held-out texts"
    emotion_of = unheard or test.take_emotions()
    takes = list(emotion_of)
    rng = np.random.default_rng(0)
    f32 = np.float32
    variants = {f"{which}, as recorded": lambda w: w,
                **{name: lambda w, c=change: np.asarray(c(w), f32) for name, change in recording_changes(rng).items()},
                "pink noise, no speech": lambda w: pink(len(w), rng)}
    semitones = float(semitones) if semitones is not None else bundle_generation(speech_model).perception_semitones
    rows = {}
    for name, change in variants.items():
        hits, dist, voice, low, trust, labels = [], [], [], [], [], []
        for take in takes:
            wave, _ = load_audio(root / "wave16k" / f"{take}.wav")
            enc, starts = encoder.encode(change(wave), 16000, 8.0, perception_semitones=semitones, front_end=True)
            p = perceive(enc, starts, perception, take)
            hits += [lab == EMOTIONS[emotion_of[take]] for lab in p.labels]
            labels += p.labels
            dist += list(p.distance[:, 0])
            voice += list(p.distance[:, 1])
            low += list(p.trust < 1.0)
            trust += list(p.trust)
        counts = {k: labels.count(k) / len(labels) for k in EMOTIONS if labels.count(k)}
        rows[name] = {"windows": len(hits), "perceived_correctly": float(np.mean(hits)),
                      "median_distance_over_threshold": float(np.median(dist)),
                      "median_voice_distance_over_threshold": float(np.median(voice)),
                      "share_blended_toward_neutral": float(np.mean(low)), "mean_trust": float(np.mean(trust)),
                      "perceived_emotions": counts}
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    front_end = perception is not None and perception.heard is not None and front_end_installed()
    result = {"split": split, "takes": len(takes), "held_out": which, "perception_semitones": semitones,
              "front_end": front_end,
              "thresholds": {"emotion": perception.emotion.threshold,
              "voice": perception.voice.threshold}, "threshold_info": perception.info, "rows": rows}
    (out / "perception_shift.json").write_text(json.dumps(result, indent=1) + "\n")
    lines = ["# Emotion perception on voices unlike the training voices", "",
             f"{len(takes)} takes of the {split} split ({which}), every 10-s window. Emotion distance: "
             "the emotion latent's Mahalanobis distance to the nearest emotion mean; voice distance: the style "
             "latent's to the nearest training speaker; each over its trust threshold (the "
             f"{perception.info['quantile']:g} quantile on the {perception.info['split']} windows). "
             + ("Every window heard by the front end trained on real speech as well (one every 20 s, those between "
                "interpolated) and both read-outs multiplied, as `generate` hears them."
                if front_end else
                f"Each window heard as recorded and with the voice moved {semitones:g} semitones up and down (the "
                "probabilities averaged)." if semitones else "Each window heard once."), "",
             "| audio | windows | perceived emotion correct | median emotion distance / threshold | median voice "
             "distance / threshold | blended toward neutral (`--emotion auto`) | mean trust | most perceived |",
             "|---|---|---|---|---|---|---|---|"]
    for name, r in rows.items():
        top = ", ".join(f"{k} {v:.2f}" for k, v in sorted(r["perceived_emotions"].items(), key=lambda kv: -kv[1])[:3])
        lines.append(f"| {name} | {r['windows']} | {r['perceived_correctly']:.3f} | "
                     f"{r['median_distance_over_threshold']:.2f} | {r['median_voice_distance_over_threshold']:.2f} | "
                     f"{r['share_blended_toward_neutral']:.3f} | "
                     f"{r['mean_trust']:.3f} | {top} |")
    (out / "perception_shift.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main(*sys.argv[1:6])
