"""When the arms move relative to the speech: the onset coupling at every lag, ground truth against a
gesture model under several generation settings.

For every ``EVERY``-th take of a split of the corpus's text split (``val`` by default: texts no model
trained on), the whole take generated as `emogesture generate` does (seed 0), and the corpus's own motion
of it: the correlation of the arm joints' mean speed with the speech's onset envelope at lags from −2 to
+2 s (:func:`emogesture.eval.motion_stats.onset_coupling_curve`; negative lags: the motion moves before
the onsets), averaged over the takes. The rhythm gain's mismatched audio includes the same take's audio
shifted by 1–2.5 s; motion whose curve stays high far from lag 0 scores well against it too, which
widens the gain's spread.

Writes ``OUT_DIR/lag_curve_SPLIT.md`` (a table at every 0.2 s), ``.json`` (every frame) and ``.png``.

Usage: python experiments/rhythm/rhythm_lag_curve.py CORPUS GESTURE_MODEL OUT_DIR [--split val] [--every 8]
       [--settings name:key=value,key=value ...]
(``--settings``: generation settings to compare, each overriding the model's own; default: the model's
own and timing guidance 1, i.e. the decoder's timing response without guidance.)
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
from tqdm import tqdm

from emogesture.audio import load_audio
from emogesture.checkpoints import write_text_atomic
from emogesture.data.beat import read_split_csv
from emogesture.eval.motion_stats import onset_coupling_curve
from emogesture.eval.seams import sequence_joints
from emogesture.motion.io import load_smplx_npz
from emogesture.pipeline.generate import GesturePipeline

MAX_LAG_S = 2.0
FPS = 30.0


def parse_setting(text: str) -> tuple[str, dict[str, str]]:
    """``name:key=value,...`` -> (name, {key: value}); each value is read as its setting's type later."""
    name, _, body = text.partition(":")
    return name, dict(item.split("=", 1) for item in body.split(",") if item)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("corpus", type=Path)
    ap.add_argument("model", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--split", default="val")
    ap.add_argument("--every", type=int, default=8)
    ap.add_argument("--settings", nargs="+", type=parse_setting,
                    default=[("as shipped", {}), ("timing guidance 1", {"timing_guidance": 1.0})])
    args = ap.parse_args()
    split = read_split_csv(args.corpus / "train_test_split.csv")
    takes = sorted(t for t, s in split.items() if s == args.split)[::args.every]
    pipe = GesturePipeline.from_run(args.model)
    shipped = pipe.generation
    # each setting's overrides read as the types of the model's own settings, once
    typed = {name: {k: type(getattr(shipped, k))(v) for k, v in values.items()} for name, values in args.settings}
    configs = {name: replace(shipped, **values) for name, values in typed.items()}
    lag = int(round(MAX_LAG_S * FPS))
    curves: dict[str, list[np.ndarray]] = {"ground truth": [], **{name: [] for name in configs}}
    for take in tqdm(takes, desc="takes", unit="take"):
        wave, sr = load_audio(args.corpus / "wave16k" / f"{take}.wav")
        truth = load_smplx_npz(args.corpus / "smplxflame_30" / f"{take}.npz")
        curves["ground truth"].append(onset_coupling_curve(sequence_joints(pipe, truth), wave, sr, FPS, MAX_LAG_S))
        for name, config in configs.items():
            pipe.generation = config
            seq = pipe.generate(wave, seed=0)[0]
            curves[name].append(onset_coupling_curve(sequence_joints(pipe, seq), wave, sr, FPS, MAX_LAG_S))
    mean = {name: np.mean(c, axis=0) for name, c in curves.items()}
    lags = (np.arange(2 * lag + 1) - lag) / FPS
    shown = np.arange(0, 2 * lag + 1, 6)
    shown_keys = ("timing_guidance", "timing_guidance_on", "residual_scale", "output_lowpass_hz")
    settings = {name: {**{k: getattr(shipped, k) for k in shown_keys}, **values} for name, values in typed.items()}
    lines = [f"# Onset coupling at every lag: `{args.model}` on the {args.split} texts", "",
             f"{len(takes)} takes of the corpus's {args.split} texts (every {args.every}th, ordered by name), each "
             "generated whole (seed 0) and beside the corpus's own motion. Correlation of the arm joints' mean "
             "speed with the onset envelope, both smoothed (σ 0.1 s), at each lag (negative: the motion moves "
             "before the onsets), averaged over the takes. Settings: " + json.dumps(settings) + ".", "",
             "| lag (s) | " + " | ".join(mean) + " |", "|---|" + "---|" * len(mean)]
    for k in shown:
        lines.append(f"| {lags[k]:+.1f} | " + " | ".join(f"{mean[n][k]:.3f}" for n in mean) + " |")
    lines += ["", "| | " + " | ".join(mean) + " |", "|---|" + "---|" * len(mean)]
    lines.append("| lag of the peak (s) | " + " | ".join(f"{lags[int(np.argmax(mean[n]))]:+.2f}" for n in mean) + " |")
    lines.append("| peak | " + " | ".join(f"{mean[n].max():.3f}" for n in mean) + " |")
    early = (lags >= -1.2) & (lags <= -0.5)
    lines.append("| mean over −1.2 to −0.5 s (moving long before the onsets) | "
                 + " | ".join(f"{mean[n][early].mean():.3f}" for n in mean) + " |")
    args.out.mkdir(parents=True, exist_ok=True)
    stem = args.out / f"lag_curve_{args.split}"
    write_text_atomic(stem.with_suffix(".md"), "\n".join(lines) + "\n")
    write_text_atomic(stem.with_suffix(".json"), json.dumps(
        {"takes": takes, "lags_s": lags.round(4).tolist(), "settings": settings,
         "curves": {n: np.round(c, 5).tolist() for n, c in mean.items()}}, indent=1) + "\n")
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 3.6))
    for name, c in mean.items():
        ax.plot(lags, c, label=name, lw=2.2 if name == "ground truth" else 1.4)
    ax.axhline(0, color="grey", lw=0.6)
    ax.axvline(0, color="grey", lw=0.6, ls=":")
    ax.set_xlabel("lag (s): negative = the arms move before the onsets")
    ax.set_ylabel("correlation")
    ax.set_title(f"arm speed against speech onsets ({args.split} texts)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(stem.with_suffix(".png"), dpi=110)
    print(stem.with_suffix(".md").read_text())


if __name__ == "__main__":
    main()
