"""Waveform augmentation speed: what hearing a training window through changed recording conditions costs.

The speech model's training hears most of its windows through :mod:`emogesture.audio.wave_augment`, done
in data-loading workers beside the training step on the same cores, so on a CPU machine its cost is a
large share of a speech-training step. This times, on one 10-s window at 16 kHz (one thread), each
transform alone and the whole per-window work of the training's data workers (the augmentation drawn as
each stage of the bundled model's recipe draws it, then the filterbank), and reports windows per second
per core and the core-seconds a step of the tiny preset (16 quadruples, 64 windows) spends on it.

Usage: OMP_NUM_THREADS=1 python bench/augment.py [--repeats 20] [--out bench/results/augment-cpu]
(writes OUT.json and OUT.md)
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import machine  # noqa: E402

from emogesture.audio import wave_augment as wa  # noqa: E402
from emogesture.audio.fbank import FbankConfig, kaldi_fbank  # noqa: E402

WINDOW_SAMPLES = 160_400  # a 10-s fbank window's waveform (999 hops of 10 ms and one 25-ms frame)
STEP_WINDOWS = 64  # the tiny preset's speech step: 16 quadruples of 4 windows
#: The recipe's two speech stages: half the windows augmented with the defaults, then three quarters of
#: them with voices moved by up to 6 semitones and more level changes.
STAGES = {"speech (first stage)": (0.5, wa.WaveAugmentConfig()),
          "speech_tuned (second stage)": (0.75, wa.WaveAugmentConfig(voice=0.6, voice_semitones=6.0, loudness=0.6))}


def speechlike(rng: np.random.Generator, n: int = WINDOW_SAMPLES) -> np.ndarray:
    """Noise shaped into syllables (4 Hz bursts) at about -24 dBFS: the timings do not depend on the words."""
    t = np.arange(n) / 16000
    envelope = np.clip(np.sin(2 * np.pi * 4 * t), 0, None) ** 2
    return 0.1 * envelope * rng.standard_normal(n)


def timed(f, repeats: int) -> float:
    f()
    start = time.perf_counter()
    for _ in range(repeats):
        f()
    return (time.perf_counter() - start) / repeats


def measure(repeats: int) -> dict:
    rng = np.random.default_rng(0)
    x = speechlike(rng)
    fbank = FbankConfig()
    transforms = {
        "voice (±4 semitones)": lambda: wa.voice_shift(x, 3.0),
        "tempo (WSOLA)": lambda: wa.time_stretch(x, 1.1),
        "reverb": lambda: wa.reverberant(x, rng, 0.6, 0.5),
        "noise, white": lambda: wa.add_noise(x, rng, 10.0, "white"),
        "noise, pink": lambda: wa.add_noise(x, rng, 10.0, "pink"),
        "noise, speech-shaped": lambda: wa.add_noise(x, rng, 10.0, "speech"),
        "telephone": lambda: wa.telephone(x),
        "microphone": lambda: wa.microphone(x, rng),
        "filterbank (every window)": lambda: kaldi_fbank(x.astype(np.float32), fbank),
    }
    out = {"transforms_ms": {name: round(timed(f, repeats) * 1e3, 2) for name, f in transforms.items()}, "stages": {}}
    for name, (share, config) in STAGES.items():
        draws = np.random.default_rng(1)

        def window() -> None:
            y = wa.augment_waveform(x, draws, config)[0] if draws.random() < share else x
            kaldi_fbank(np.asarray(y, np.float32), fbank)

        seconds = timed(window, repeats * 4)
        out["stages"][name] = {"augmented_share": share, "ms_per_window": round(seconds * 1e3, 2),
                               "windows_per_s_per_core": round(1 / seconds, 1),
                               "core_s_per_step": round(seconds * STEP_WINDOWS, 2)}
    return out


def markdown(result: dict) -> str:
    lines = ["| transform, one 10-s window | ms |", "|---|---|"]
    lines += [f"| {k} | {v} |" for k, v in result["transforms_ms"].items()]
    lines += ["", "| recipe stage | windows augmented | ms per window | windows/s per core | "
              "core-s per step (64 windows) |", "|---|---|---|---|---|"]
    lines += [f"| {k} | {v['augmented_share']:.0%} | {v['ms_per_window']} | {v['windows_per_s_per_core']} | "
              f"{v['core_s_per_step']} |" for k, v in result["stages"].items()]
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeats", type=int, default=20)
    ap.add_argument("--out", type=Path, default=None, help="write OUT.json and OUT.md")
    args = ap.parse_args()
    result = {"machine": machine.describe(), **measure(args.repeats)}
    m = result["machine"]
    md = (f"# Waveform augmentation speed\n\n{m['cpu']}, {m['cores']} cores, one thread, numpy {np.__version__}; "
          f"`bench/augment.py`, one 10-s window.\n\n" + markdown(result))
    print(md)
    if args.out is not None:
        machine.write_json(args.out.with_suffix(".json"), result)
        args.out.with_suffix(".md").write_text(md)


if __name__ == "__main__":
    main()
