"""What the speech model's emotion perception does on voices unlike its training voices.

No real speech can be used here, so the held-out (test-text) takes of the synthetic corpus are played
through changes that move a voice away from the training voices: a pitch and tempo shift (+4 and
-4 semitones, by resampling), babble-free white noise at 10 dB SNR, a telephone band (300-3400 Hz),
and pink noise alone (no speech at all). For each, over every 10-s window: how often the perceived
emotion is the take's emotion, the median distance to the nearest emotion mean (in units of the
trust threshold), the same for the voice (style latent to the nearest training speaker), and the
share of windows that `generate --emotion auto` blends toward neutral.

Usage: python experiments/perception_shift.py SPEECH_MODEL CACHE OUT_DIR
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
from scipy.signal import butter, resample_poly, sosfilt

from emogesture.audio import load_audio
from emogesture.data.beat import EMOTIONS
from emogesture.data.cache import open_cache
from emogesture.pipeline.perception import perceive, perception_of
from emogesture.pipeline.speech import SpeechLatentEncoder


def pitch(wave: np.ndarray, semitones: int) -> np.ndarray:
    """Pitch and tempo together, as a tape played faster or slower."""
    up, down = (4, 5) if semitones > 0 else (5, 4)  # ~ +-3.9 semitones
    return resample_poly(wave, up, down).astype(np.float32)


def noise(wave: np.ndarray, snr_db: float, rng: np.random.Generator) -> np.ndarray:
    n = rng.normal(size=len(wave))
    n *= np.sqrt(np.mean(wave ** 2) / np.mean(n ** 2) / 10 ** (snr_db / 10))
    return (wave + n).astype(np.float32)


def telephone(wave: np.ndarray) -> np.ndarray:
    return sosfilt(butter(6, [300, 3400], btype="band", fs=16000, output="sos"), wave).astype(np.float32)


def pink(length: int, rng: np.random.Generator) -> np.ndarray:
    spec = np.fft.rfft(rng.normal(size=length))
    spec /= np.sqrt(np.maximum(np.arange(len(spec)), 1))
    out = np.fft.irfft(spec, length)
    return (0.05 * out / out.std()).astype(np.float32)


def main(speech_model: str, cache_dir: str, out_dir: str) -> None:
    encoder = SpeechLatentEncoder.from_run(speech_model)
    perception = perception_of(encoder)
    cache = open_cache(cache_dir)
    test = cache.split("test")
    root = Path(cache.manifest["root"])
    takes = list(dict.fromkeys(test.takes))
    emotion_of = {t: int(e) for t, e in zip(test.takes, test.emotion)}
    rng = np.random.default_rng(0)
    variants = {
        "held-out texts, as recorded": lambda w: w,
        "pitch and tempo +4 semitones": lambda w: pitch(w, 4),
        "pitch and tempo -4 semitones": lambda w: pitch(w, -4),
        "white noise, 10 dB SNR": lambda w: noise(w, 10, rng),
        "telephone band 300-3400 Hz": telephone,
        "pink noise, no speech": lambda w: pink(len(w), rng),
    }
    rows = {}
    for name, change in variants.items():
        hits, dist, voice, low, trust, labels = [], [], [], [], [], []
        for take in takes:
            wave, _ = load_audio(root / "wave16k" / f"{take}.wav")
            enc, starts = encoder.encode(change(wave), 16000, 8.0)
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
    result = {"split": "test", "takes": len(takes), "thresholds": {"emotion": perception.emotion.threshold,
              "voice": perception.voice.threshold}, "threshold_info": perception.info, "rows": rows}
    (out / "perception_shift.json").write_text(json.dumps(result, indent=1) + "\n")
    lines = ["# Emotion perception on voices unlike the training voices", "",
             f"{len(takes)} held-out takes (test texts) of the default corpus, every 10-s window. Emotion distance: "
             "the emotion latent's Mahalanobis distance to the nearest emotion mean; voice distance: the style "
             "latent's to the nearest training speaker; each over its trust threshold (the "
             f"{perception.info['quantile']:g} quantile on the {perception.info['split']} windows).", "",
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
    main(*sys.argv[1:4])
