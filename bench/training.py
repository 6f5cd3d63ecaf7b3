"""Training throughput: windows per second of the speech and gesture trainings, tiny and paper, fp32 and bf16.

Each measurement is a few optimisation steps of the real training step (``SpeechModule`` /
``GestureModule`` under Lightning, the preset's batch size and losses) on random inputs of the right
shapes (speed does not depend on the data): the first WARMUP steps are not timed. The gesture training
is timed in its joint phase (denoiser and the no-gradient DDIM of L_align on, as after the prior's
warm-up), the phase where most of its steps are spent. A speech step reads 4 windows per quadruple.

Usage: python bench/training.py [--models speech,gesture] [--presets tiny,paper] [--precisions fp32,bf16]
                                [--steps 6] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from pathlib import Path

import lightning as L
import torch
from torch.utils.data import DataLoader, Dataset

sys.path.insert(0, str(Path(__file__).resolve().parent))
import machine  # noqa: E402

from emogesture.config import to_dict  # noqa: E402
from emogesture.data.prepare import PrepareConfig  # noqa: E402
from emogesture.train.gesture import GestureModule, GestureTrainConfig  # noqa: E402
from emogesture.train.speech import SpeechModule, SpeechTrainConfig  # noqa: E402

WARMUP = 2


class RandomBatches(Dataset):
    def __init__(self, make, length: int) -> None:
        self.make, self.length = make, length

    def __len__(self) -> int:
        return self.length

    def __getitem__(self, i: int) -> dict:
        return self.make(torch.Generator().manual_seed(i))


class StepClock(L.Callback):
    def __init__(self) -> None:
        self.times: list[float] = []

    def on_train_batch_start(self, trainer, module, batch, batch_idx) -> None:
        if len(self.times) == WARMUP:
            self.start = time.perf_counter()
        self.times.append(time.perf_counter())

    def on_train_end(self, trainer, module) -> None:
        self.total = time.perf_counter() - self.start


def module_and_items(model: str, preset: str, batch: int | None = None):
    if model == "speech":
        cfg = SpeechTrainConfig.preset(preset)
        cfg.batch_size = batch or cfg.batch_size
        n_mels, frames = cfg.model.encoder.input_bins, cfg.model.encoder.input_frames
        speakers = cfg.model.num_speakers

        def item(g):
            return {"fbank": torch.randn(4, frames, n_mels, generator=g),
                    "emotion": torch.randint(0, 8, (), generator=g),
                    "speaker": torch.randint(0, speakers, (4,), generator=g)}
        return SpeechModule(to_dict(cfg)), item, cfg.batch_size, 4
    cfg = GestureTrainConfig.preset(preset)
    cfg.batch_size = batch or cfg.batch_size
    cfg.prior_warmup_steps = 0
    features = to_dict(PrepareConfig().features)
    d = cfg.model.vae.feature_dim
    module = GestureModule(to_dict(cfg), [0.0] * d, [0.3] * d, features)
    conds = cfg.model.denoiser.num_conditions

    frames = cfg.model.vae.frames

    def item(g):
        latents = [torch.randn(cfg.model.denoiser.cond_dim, generator=g) for _ in range(conds)]
        # a model that hears the speech's timing (the tiny preset's does) reads its stream last
        stream = [torch.rand(frames, cfg.model.timing_features, generator=g)] if cfg.model.hears_timing else []
        return {"motion": torch.randn(frames, d, generator=g) * 0.3,
                "emotion": torch.randint(0, 8, (), generator=g), "conditions": latents + stream}
    return module, item, cfg.batch_size, 1


def throughput(model: str, preset: str, precision: str, steps: int, accelerator: str = "cpu",
               batch: int | None = None) -> dict:
    """Seconds per step and windows per second; ``batch`` overrides the preset's batch size (the paper
    preset's batches take minutes per step on a CPU; windows per second hardly depends on it there)."""
    module, item, batch, windows_per_item = module_and_items(model, preset, batch)
    clock = StepClock()
    loader = DataLoader(RandomBatches(item, batch * (steps + WARMUP)), batch_size=batch)
    trainer = L.Trainer(max_steps=steps + WARMUP, accelerator=accelerator, devices=1, logger=False,
                        enable_checkpointing=False, enable_progress_bar=False, enable_model_summary=False,
                        precision="bf16-mixed" if precision == "bf16" else "32-true", callbacks=[clock])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        trainer.fit(module, loader)
    per_step = clock.total / steps
    return {"model": model, "preset": preset, "precision": precision, "batch": batch,
            "windows_per_step": batch * windows_per_item, "seconds_per_step": round(per_step, 3),
            "windows_per_second": round(batch * windows_per_item / per_step, 2)}


def table(rows: list[dict]) -> str:
    lines = ["| training | preset | precision | windows per step | s per step | windows / s |",
             "|---|---|---|---|---|---|"]
    lines += [f"| {r['model']} | {r['preset']} | {r['precision']} | {r['windows_per_step']} | "
              f"{r['seconds_per_step']} | {r['windows_per_second']} |" if "skipped" not in r else
              f"| {r['model']} | {r['preset']} | {r['precision']} | not run: {r['skipped']} | | |" for r in rows]
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--models", default="speech,gesture")
    ap.add_argument("--presets", default="tiny,paper")
    ap.add_argument("--precisions", default="fp32,bf16")
    ap.add_argument("--steps", type=int, default=6, help="timed steps per measurement (default 6)")
    ap.add_argument("--accelerator", default="cpu", choices=["cpu", "gpu"])
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    rows = []
    for model in args.models.split(","):
        for preset in args.presets.split(","):
            for precision in args.precisions.split(","):
                rows.append(throughput(model, preset, precision, args.steps, args.accelerator))
                print(rows[-1], flush=True)
    print(table(rows))
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        device = "cuda" if args.accelerator == "gpu" else "cpu"
        args.json.write_text(json.dumps({"machine": machine.describe(device), "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
