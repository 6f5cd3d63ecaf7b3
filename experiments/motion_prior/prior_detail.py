"""What a gesture model's motion prior keeps of each joint's rotation (why the generated wrists turned slowly).

For the first WINDOWS windows of a split: the angular speed of each joint's local rotation (rad per
frame, `eval.motion_stats.joint_angular_speed`) of the ground truth, of the ground truth low-passed
as the model's output filter does, of the prior's reconstruction (encoder mean, decoder as trained),
and of the same latents decoded as at generation (timing guidance, output filter); and the
reconstruction's mean upper-body joint error and how well it follows the motion's own feature
columns (Pearson correlation over all frames, per 6D column; the lowest and highest of a joint
group's moving columns). No sampling: the latents are the motion's own.

Usage: python experiments/motion_prior/prior_detail.py CACHE [NAME=]MODEL [...] [--split val] [--windows 200] > REPORT.md
(NAME labels the model's rows; without it, the path does.)
Reports: experiments/motion_prior/reports/prior_detail/val.md (the bundle, and the run with losses.finger_features=0.1; 2026-11-24,
commit 2ce0daa) and experiments/motion_prior/reports/prior_detail/prior_only_400_val.md (priors trained alone for 400 steps;
2026-11-24, commits 1166d7b and f45fdf7).
"""

from __future__ import annotations

import argparse

import numpy as np
import torch

from emogesture.audio.timing import timing_stream
from emogesture.data.cache import open_cache
from emogesture.eval.motion_stats import joint_angular_speed
from emogesture.models.generation import GenerationConfig
from emogesture.motion.filters import lowpass
from emogesture.motion import features_to_poses
from emogesture.motion.skeleton import JOINT_NAMES
from emogesture.pipeline.sampling import decode_latents, encode_motion
from emogesture.pipeline.generate import GesturePipeline

JOINTS = ("spine3", "neck", "head", "left_collar", "right_shoulder", "right_elbow", "left_wrist", "right_wrist")
UPPER = ("spine3", "neck", "head", "left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist",
         "right_wrist")


def speeds(pipe: GesturePipeline, feats: np.ndarray) -> list[float]:
    poses, _ = features_to_poses(torch.from_numpy(np.array(feats, np.float32)), pipe.spec)
    s = np.stack([joint_angular_speed(p.numpy()) for p in poses]).mean((0, 1))
    return [float(s[JOINT_NAMES.index(j)]) for j in JOINTS]


def column_correlation(pipe: GesturePipeline, rec: np.ndarray, motion: np.ndarray, names: tuple[str, ...]) -> str:
    """The lowest and highest correlation of ``rec`` with ``motion`` over the named joints' 6D columns
    that move (a column constant in the motion has no correlation)."""
    cols = pipe.spec.columns(JOINT_NAMES.index(n) for n in names)
    r = [np.corrcoef(rec[..., c].ravel(), motion[..., c].ravel())[0, 1] for c in cols if motion[..., c].std() > 0]
    return f"{min(r):.2f}–{max(r):.2f}"


def joints(pipe: GesturePipeline, feats: np.ndarray) -> np.ndarray:
    with torch.no_grad():
        return pipe.body.forward_features(torch.from_numpy(np.array(feats, np.float32)), pipe.spec).numpy()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("cache")
    ap.add_argument("models", nargs="+", metavar="[NAME=]MODEL")
    ap.add_argument("--split", default="val")
    ap.add_argument("--windows", type=int, default=200)
    args = ap.parse_args()
    windows = open_cache(args.cache).split(args.split)
    n = min(args.windows, len(windows.motion))
    motion = np.asarray(windows.motion[:n], np.float32)
    stream = timing_stream(windows.fbank[:n], frames=motion.shape[1])
    print(f"{args.split}, {n} windows; rad/frame")
    print("| motion | " + " | ".join(JOINTS) + " | upper-body joint error | correlation: wrists' columns | elbows' |")
    print("|---" * (len(JOINTS) + 4) + "|")
    upper = [JOINT_NAMES.index(j) for j in UPPER]

    def row(name: str, values: list[float], *extra: str) -> None:
        cells = [*extra, "", "", ""][:3]
        print(f"| {name} | " + " | ".join(f"{v:.4f}" for v in values) + " | " + " | ".join(cells) + " |")

    for i, spec in enumerate(args.models):
        name, _, path = spec.rpartition("=")
        name = name or path
        pipe = GesturePipeline.from_run(path)
        if i == 0:  # every model poses the same skeleton
            truth = joints(pipe, motion)
            row("ground truth", speeds(pipe, motion))
            cutoff = pipe.generation.output_lowpass_hz
            if cutoff:
                row(f"ground truth, low-passed at {cutoff:g} Hz", speeds(pipe, lowpass(torch.tensor(motion), cutoff).numpy()))
        z = encode_motion(pipe.loaded, motion)
        rec = decode_latents(pipe.loaded, z, motion.shape[1], timing=stream, generation=GenerationConfig())
        err = np.linalg.norm(joints(pipe, rec)[..., upper, :] - truth[..., upper, :], axis=-1).mean()
        row(f"{name}: reconstruction", speeds(pipe, rec), f"{err * 1000:.1f} mm",
            column_correlation(pipe, rec, motion, ("left_wrist", "right_wrist")),
            column_correlation(pipe, rec, motion, ("left_elbow", "right_elbow")))
        row(f"{name}: decoded as at generation", speeds(pipe, decode_latents(pipe.loaded, z, motion.shape[1], timing=stream)))


if __name__ == "__main__":
    main()
