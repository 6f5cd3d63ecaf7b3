"""Streamed against offline motion on the same audio: takes of a corpus's test texts (its
``train_test_split.csv``; never trained on by the bundled model, whose speakers include some of these voices),
each animated by `generate` (offline) and by a `GestureStream` fed 100-ms pieces; per take, the largest
frame-to-frame joint jump, its 99th percentile, and the onset coupling of the arms' speed with the speech
(`eval.motion_stats.onset_coupling`) for the take's own audio and for another take's.

Usage: python experiments/live/stream_quality.py CORPUS OUT.md [--split test] [--takes 8] [--seed 0] [--loaded]
[--steps N]
(``--loaded``: every update drawn as a loaded server draws it, one candidate; ``--steps``: its DDIM steps,
default ``LOADED_STEPS``)
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np
import torch

from emogesture.audio import load_audio
from emogesture.checkpoints import write_text_atomic
from emogesture.eval.motion_stats import onset_coupling
from emogesture.motion import SkeletonBody
from emogesture.pipeline.generate import GesturePipeline
from emogesture.pipeline import stream as live
from emogesture.pipeline.stream import GestureStream, push_together


def joints(poses: np.ndarray, trans: np.ndarray) -> np.ndarray:
    with torch.no_grad():
        return SkeletonBody()(torch.from_numpy(poses), torch.from_numpy(trans)).numpy()


def jumps(j: np.ndarray) -> np.ndarray:
    return np.linalg.norm(np.diff(j, axis=0), axis=-1).max(-1)


def streamed(pipe: GesturePipeline, wave: np.ndarray, seed: int, loaded: bool = False
             ) -> tuple[np.ndarray, np.ndarray]:
    stream = GestureStream(pipe, seed=seed)
    blocks = [b for i in range(0, len(wave), 1600)
              for b in push_together([(stream, wave[i:i + 1600], 16000)], loaded=loaded)[0]] + stream.end()
    return (np.concatenate([b.sequence.poses for b in blocks]), np.concatenate([b.sequence.trans for b in blocks]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("corpus", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--split", default="test")
    ap.add_argument("--takes", type=int, default=8)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--loaded", action="store_true")
    ap.add_argument("--steps", type=int, default=None)
    args = ap.parse_args()
    with open(args.corpus / "train_test_split.csv") as f:
        names = sorted(r["id"] for r in csv.DictReader(f) if r["type"] == args.split)
    names = names[:: max(1, len(names) // args.takes)][: args.takes]
    pipe = GesturePipeline.from_run()
    if args.steps is not None:
        live.LOADED_STEPS = args.steps
    waves = [load_audio(args.corpus / "wave16k" / f"{n}.wav")[0] for n in names]
    rows, table = [], []
    for k, (name, wave) in enumerate(zip(names, waves)):
        other = waves[(k + 1) % len(waves)]
        other = np.resize(other, len(wave))
        off = pipe.generate(wave, seed=args.seed)[0]
        jo, js = joints(off.poses, off.trans), joints(*streamed(pipe, wave, args.seed, args.loaded))
        row = [name, len(js) == len(jo), jumps(js).max() / jumps(jo).max(), np.quantile(jumps(js), 0.99) /
               np.quantile(jumps(jo), 0.99)]
        row += [onset_coupling(j, w, 16000, 30) for j in (js, jo) for w in (wave, other)]
        rows.append(row)
        table.append(f"| {name} | {row[1]} | " + " | ".join(f"{v:.3f}" for v in row[2:]) + " |")
        print(table[-1], flush=True)
    values = np.array([r[2:] for r in rows], np.float64)
    mean = values.mean(0)
    text = (f"# Streamed against offline motion ({args.split} texts of {args.corpus.name}, {len(rows)} takes)\n\n"
            "`python experiments/live/stream_quality.py` (the bundled model; the stream fed 100-ms pieces; seed "
            f"{args.seed}; " + (f"drawn as a loaded server draws: one candidate, {live.LOADED_STEPS} DDIM steps"
                                if args.loaded else "drawn as one stream alone") + "). Jump: the largest frame-to-frame joint displacement (and its 99th percentile), streamed "
            "over offline. Coupling: onset coupling of the arms' speed with the take's own audio, and with another "
            "take's (mismatched).\n\n"
            "| take | same frames | largest jump, stream / offline | p99 jump, stream / offline | coupling stream | "
            "stream, mismatched | coupling offline | offline, mismatched |\n|---|---|---|---|---|---|---|---|\n"
            + "\n".join(table) + "\n| **mean** | | " + " | ".join(f"{v:.3f}" for v in mean) + " |\n\n"
            f"Streamed coupling over offline (means): {mean[2] / mean[4]:.2f}.\n")
    write_text_atomic(args.out, text)
    print(args.out)


if __name__ == "__main__":
    main()
