"""Noise suppression's settings, chosen on val: the held-out voices in steady noise, heard with each setting.

Every take of the val split's held-out voices (the val speakers, never trained on) is played in white
noise at 3, 10 and 20 dB SNR and in pink noise at 10 dB (one draw per take, seeded), then heard by the
speech model with noise suppression off and with each setting (``over_subtraction,floor,percentile``;
:class:`emogesture.audio.noise.NoiseSuppression`, its dynamic-range gate as it is). The share of windows
heard as the take's emotion, per condition. Each recording's dynamic range is reported too, as recorded
and through every other change of the robustness report, to show where the gate leaves recordings alone.

Usage: python experiments/perception/noise_suppression.py SPEECH_MODEL CACHE OUT_DIR [A,FLOOR,PERCENTILE ...]
"""

from __future__ import annotations

import json
import sys
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np
from tqdm import tqdm

from emogesture.audio import NoiseSuppression, dynamic_range_db, kaldi_fbank, load_audio
from emogesture.audio.wave_augment import add_noise, recording_changes
from emogesture.data.beat import EMOTIONS
from emogesture.data.cache import open_cache
from emogesture.pipeline.perception import perceive, perception_of
from emogesture.pipeline.speech import SpeechLatentEncoder

SETTINGS = ("1,0.1,10", "2,0.1,10", "3,0.1,10", "2,0.05,10", "2,0.1,20")
NOISES = {"white noise, 3 dB SNR": (3.0, "white"), "white noise, 10 dB SNR": (10.0, "white"),
          "white noise, 20 dB SNR": (20.0, "white"), "pink noise, 10 dB SNR": (10.0, "pink")}


def main(speech_model: str, cache_dir: str, out_dir: str, *settings: str) -> None:
    encoder = SpeechLatentEncoder.from_run(speech_model)
    perception = perception_of(encoder)
    cache = open_cache(cache_dir)
    val = cache.split("val")
    root = Path(cache.manifest["root"])
    takes = [t for t in dict.fromkeys(val.takes)
             if t in {u for u, s in zip(val.takes, val.speaker_id.tolist()) if s not in encoder.speakers}]
    emotion_of = {t: int(e) for t, e in zip(val.takes, val.emotion)}
    waves = {t: load_audio(root / "wave16k" / f"{t}.wav")[0] for t in takes}
    rng = np.random.default_rng(0)
    noisy = {name: {t: np.asarray(add_noise(w, rng, snr, kind), np.float32) for t, w in waves.items()}
             for name, (snr, kind) in NOISES.items()}
    changes = {"as recorded": lambda w: w, **recording_changes(np.random.default_rng(1))}
    ranges = {name: [dynamic_range_db(kaldi_fbank(np.asarray(change(w), np.float32), encoder.fbank_config))
                     for w in list(waves.values())[::4]] for name, change in changes.items()}
    ranges.update({name: [dynamic_range_db(kaldi_fbank(w, encoder.fbank_config)) for w in list(by_take.values())[::4]]
                   for name, by_take in noisy.items()})

    rows = {}
    for spec in tqdm(("off",) + (settings or SETTINGS), desc="settings", unit="setting"):
        if spec == "off":
            encoder.noise_suppression = None
        else:
            a, floor, q = (float(v) for v in spec.split(","))
            encoder.noise_suppression = replace(NoiseSuppression(), over_subtraction=a, floor=floor,
                                                noise_percentile=q)
        row = {}
        for name, by_take in noisy.items():
            hits = []
            for take, wave in by_take.items():
                enc, starts = encoder.encode(wave, 16000, 8.0)
                heard = perceive(enc, starts, perception, take).labels
                hits += [label == EMOTIONS[emotion_of[take]] for label in heard]
            row[name] = float(np.mean(hits))
        rows[spec] = row
    result = {"split": "val", "takes": len(takes), "windows": len(hits), "rows": rows,
              "default": asdict(NoiseSuppression()),
              "dynamic_range_db": {k: {"min": float(np.min(v)), "median": float(np.median(v)), "max": float(np.max(v))}
                                   for k, v in ranges.items()}}
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / "noise_suppression_val.json").write_text(json.dumps(result, indent=1) + "\n")
    names = list(NOISES)
    lines = ["# Noise suppression on val: held-out voices in steady noise", "",
             f"{len(takes)} takes of the val split's held-out voices, {len(hits)} windows per condition; the share "
             "heard as the take's emotion. Setting: over-subtraction, amplitude floor, noise percentile.", "",
             "| setting | " + " | ".join(names) + " |", "|---" * (len(names) + 1) + "|"]
    lines += [f"| {spec} | " + " | ".join(f"{row[n]:.3f}" for n in names) + " |" for spec, row in rows.items()]
    lines += ["", "Dynamic range (dB between the loud and quiet frames; every 4th take): the gate subtracts nothing "
              f"above {NoiseSuppression().off_above_db:g} dB and fully below {NoiseSuppression().full_below_db:g} dB.",
              "", "| recording | min | median | max |", "|---|---|---|---|"]
    lines += [f"| {k} | {v['min']:.1f} | {v['median']:.1f} | {v['max']:.1f} |"
              for k, v in result["dynamic_range_db"].items()]
    (out / "noise_suppression_val.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main(*sys.argv[1:])
