"""The generation settings of a gesture model whose decoder hears the speech's timing,
swept on the val texts: timing guidance w (``timing_guidance``), output smoothing σ in frames
(``output_smoothing``), the output low-pass's cutoff c in Hz (``output_lowpass_hz``, 0 = off)
and the residual-noise scale r (``residual_scale``) of its :class:`GenerationConfig`. The same trained model, the same seeds
and the same evaluator for every row; writes a markdown table.

Usage: python experiments/rhythm/timing_guidance_sweep.py GESTURE_RUN CACHE EXTRACTOR_RUN OUT.md [--split val]
       [--settings r,w,σ[,c] ...] [--other w,σ[,c]] [--seed N] [--on stream|onsets]
(``--seed``: the sampling seed of every row, default 0; ``--settings``: the rows to generate, default the
sweep below; ``--other``: the setting of the last row, which reads another window's timing stream;
``--on``: what every row's guidance scales, ``timing_guidance_on``, default the model's own.)
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path

import numpy as np

from emogesture.checkpoints import load_model, write_text_atomic
from emogesture.provenance import split_use
from emogesture.data.cache import open_cache
from emogesture.eval.gesture import GestureEvaluator
from emogesture.eval.rhythm import other_window_pairs
from emogesture.models.generation import TIMING_GUIDANCE_ON
from emogesture.eval.split_latents import model_conditions
from emogesture.pipeline.sampling import generate_from_conditions, window_seeds
from emogesture.pipeline.speech import SpeechLatentEncoder

# (r, w, σ, c): the trained decoder as it is, then guidance alone, then guidance with smoothing, then the low-pass
SETTINGS = [(1.0, 1.0, 0.0), (0.0, 1.0, 0.0), (0.0, 2.0, 0.0), (0.0, 3.0, 0.0), (1.0, 2.0, 0.0), (1.0, 3.0, 0.0),
            (1.0, 2.0, 1.5), (1.0, 3.0, 1.0), (1.0, 3.0, 1.5), (1.0, 3.0, 1.75), (1.0, 3.0, 2.0), (1.0, 3.5, 1.75),
            (1.0, 3.5, 2.0), (1.0, 4.0, 2.0), (0.5, 3.0, 1.5), (1.5, 3.0, 1.5), (1.0, 4.0, 0.0, 2.5),
            (1.0, 4.0, 0.0, 2.75)]
SETTINGS = [s if len(s) == 4 else (*s, 0.0) for s in SETTINGS]


def numbers(count: int):
    """An argparse type: ``count`` comma-separated numbers, and an optional last one (the cutoff c, default 0)."""
    def parse(text: str) -> tuple[float, ...]:
        try:
            values = tuple(float(v) for v in text.split(","))
        except ValueError:
            values = ()
        if len(values) not in (count, count + 1):
            raise argparse.ArgumentTypeError(f"expected {count} or {count + 1} comma-separated numbers, got {text!r}")
        return values if len(values) > count else (*values, 0.0)
    return parse


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", type=Path)
    ap.add_argument("cache", type=Path)
    ap.add_argument("extractor", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--split", default="val")
    ap.add_argument("--settings", nargs="+", type=numbers(3), default=SETTINGS, metavar="r,w,σ[,c]")
    ap.add_argument("--other", type=numbers(2), default=(4.0, 0.0, 2.75), metavar="w,σ[,c]")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--on", choices=TIMING_GUIDANCE_ON, default=None)
    args = ap.parse_args()
    gesture = load_model(args.run, "gesture")
    if not gesture.config.hears_timing:
        raise SystemExit(f"{args.run}: this model reads no timing stream")
    speech = SpeechLatentEncoder.of_gesture_model(gesture)
    use = split_use(args.split, {"gesture": gesture, "speech": speech.loaded})
    cache = open_cache(args.cache)
    conds = model_conditions(gesture, cache, args.split, speech)
    seeds = window_seeds(args.seed, len(conds[0]))
    on = args.on or gesture.generation.timing_guidance_on
    other = other_window_pairs(cache.split(args.split).text, 0, 1)[0]
    ev = GestureEvaluator(cache, args.split, load_model(args.extractor, "extractor"))
    rows = []
    gt, _ = ev.score(np.asarray(ev.windows.motion, np.float32), None, 0)
    gt_stats = ev.motion_stats(np.asarray(ev.windows.motion, np.float32))
    rows.append(("ground truth", gt, gt_stats))
    for r, w, s, c in [*args.settings, ("other", *args.other)]:
        settings = replace(gesture.generation, residual_scale=1.0 if r == "other" else r, timing_guidance=w,
                           output_smoothing=s, output_lowpass_hz=c,
                           timing_guidance_on=on)
        stream = conds[-1][other] if r == "other" else conds[-1]
        motion = generate_from_conditions(gesture, [*conds[:-1], stream], seeds, generation=settings,
                                          residual=settings.residual_scale > 0)
        row, _ = ev.score(motion, None, 0)
        setting = f"w {w:g}, σ {s:g}" + (f", low-pass {c:g} Hz" if c else "")
        name = (f"r 1, {setting}, the stream of another window" if r == "other" else f"r {r:g}, {setting}")
        rows.append((name, row, ev.motion_stats(motion)))
        wrists = [round(rows[-1][2]["angular_speed"][j], 4) for j in ("left_wrist", "right_wrist")]
        print(name, json.dumps({k: round(row[k], 4) for k in ("GA", "FGD", "Speed", "Jerk", "Rhythm")}),
              f"gain/spread {row['rhythm']['gain_over_spread']:.1f}", wrists,
              flush=True)
    lines = [f"# Timing guidance, output smoothing and residual noise of `{args.run}` ({args.split} split)", "",
             f"Split use: {json.dumps(use)}. One trained model; every row the same seeds ({args.seed}) and evaluator; "
             f"guidance on the {on} (`timing_guidance_on`). "
             "r: residual-noise scale; w: timing guidance; σ: output smoothing (frames); low-pass: the output "
             "low-pass's cutoff (`output_lowpass_hz`). Rhythm: rhythm gain "
             "(`emogesture.eval.rhythm`), its spread (the standard deviation of the mismatched audio's scores) and the "
             "gain in spreads; shifted 1 s: the score against the same take's audio 1 s later, which motion that "
             "moves long before the speech's onsets follows too.", "",
             "| setting | rhythm gain | spread | gain / spread | shifted 1 s | GA | FGD | Div | wrist speed (m/s) | "
             "jerk (m/s³) | wrists L / R (rad/frame) |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, row, st in rows:
        rh = row["rhythm"]
        lines.append(f"| {name} | {rh['gain']:.3f} | {rh['spread']:.4f} | {rh['gain_over_spread']:.1f} | "
                     f"{rh['mismatched']['shifted 1 s']:.3f} | {row['GA']:.3f} | {row['FGD']:.2f} | {row['Div']:.2f} | "
                     f"{row['Speed']:.3f} | {row['Jerk']:.1f} | {st['angular_speed']['left_wrist']:.4f} / "
                     f"{st['angular_speed']['right_wrist']:.4f} |")
    write_text_atomic(args.out, "\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
