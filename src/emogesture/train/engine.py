"""Shared run machinery for every trainer: a run folder, atomic checkpoints, logs, resume.

A run folder holds ``checkpoints/last.ckpt`` (full training state, for resuming), the exported
model (``model.safetensors`` + ``model.json``, see :mod:`emogesture.checkpoints`), ``run.json``
(the command's settings) and logs (CSV and TensorBoard). Every file is written atomically, so a
run killed at any moment leaves either the previous or the new checkpoint, never a broken one;
re-running the same command resumes from ``last.ckpt``.
"""

from __future__ import annotations

import copy
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import lightning as L
import numpy as np
import torch
from lightning.fabric.plugins.io.torch_io import TorchCheckpointIO
from lightning.pytorch.callbacks import Callback, ModelCheckpoint, TQDMProgressBar
from lightning.pytorch.loggers import CSVLogger, TensorBoardLogger

from emogesture.config import changed_keys
from emogesture.errors import EmogestureError
from emogesture.fileio import read_json


class AtomicCheckpointIO(TorchCheckpointIO):
    """Lightning checkpoints written to a temporary file, then renamed into place."""

    def save_checkpoint(self, checkpoint: dict[str, Any], path: Any, storage_options: Any | None = None) -> None:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.tmp")
        super().save_checkpoint(checkpoint, tmp, storage_options)
        os.replace(tmp, path)


class ExportModel(Callback):
    """Write the exported model files every time Lightning saves a checkpoint (rank 0 only)."""

    def __init__(self, export) -> None:
        self.export = export

    def on_save_checkpoint(self, trainer: L.Trainer, module: L.LightningModule, checkpoint: dict) -> None:
        if trainer.is_global_zero:
            self.export(module)

    def on_train_end(self, trainer: L.Trainer, module: L.LightningModule) -> None:
        if trainer.is_global_zero:
            self.export(module)


class RankDigest(Callback):
    """With several processes, each rank writes a checksum of its weights at the end of training
    (``rank_digests/rank<r>.txt``): data-parallel ranks must hold identical weights."""

    def __init__(self, run_dir: Path) -> None:
        self.run_dir = run_dir

    def on_train_end(self, trainer: L.Trainer, module: L.LightningModule) -> None:
        import hashlib

        h = hashlib.sha256()
        for name, value in sorted(module.state_dict().items()):
            h.update(name.encode())
            h.update(value.detach().cpu().contiguous().numpy().tobytes())
        d = self.run_dir / "rank_digests"
        d.mkdir(exist_ok=True)
        (d / f"rank{trainer.global_rank}.txt").write_text(f"{trainer.global_step} {h.hexdigest()}\n")


def step_generator(seed: int, step: int, rank: int, *stream: int) -> torch.Generator:
    """The CPU generator of one training step on one rank: a function of (run seed, step, rank) and an
    optional stream number, so a resumed run draws what an uninterrupted one would have drawn."""
    state = np.random.SeedSequence([seed, step, rank, *stream]).generate_state(1)[0]
    return torch.Generator().manual_seed(int(state))


def make_ema(model: torch.nn.Module, decay: float) -> torch.nn.Module | None:
    """A frozen copy of ``model`` that :func:`update_ema` keeps as the exponential moving average of its
    weights (None when ``decay`` is 0). Registered as a submodule of the LightningModule, it is saved in
    ``last.ckpt`` and resumes with it; the exported model is the average.

    Not torch's ``AveragedModel``: its first update copies the weights where this warm-up averages them,
    ``get_ema_multi_avg_fn`` has no warm-up (a custom average sees its own update count, not the global
    step), and its state (``module.*`` and ``n_averaged``) would not load the ``ema.*`` entries of
    existing checkpoints."""
    if decay <= 0:
        return None
    if not decay < 1:
        raise EmogestureError(f"ema_decay must be in [0, 1), got {decay}")
    return copy.deepcopy(model).requires_grad_(False)


@torch.no_grad()
def update_ema(ema: torch.nn.Module, model: torch.nn.Module, decay: float, step: int) -> None:
    """``ema ← d·ema + (1 − d)·model`` for every parameter (buffers are copied), with the usual warm-up
    ``d = min(decay, (1 + step) / (10 + step))`` so early averages do not hold the random initialisation."""
    d = min(decay, (1 + step) / (10 + step))
    torch._foreach_lerp_(list(ema.parameters()), list(model.parameters()), 1.0 - d)
    for b_ema, b in zip(ema.buffers(), model.buffers()):
        b_ema.copy_(b)


class AveragedWeightsMixin:
    """For a LightningModule that trains ``self.model``: call :meth:`init_weight_average` in ``__init__``;
    the average then follows every optimiser step and :attr:`averaged` is the model to export."""

    def init_weight_average(self, decay: float) -> None:
        self.ema_decay = decay
        self.ema = make_ema(self.model, decay)

    @property
    def averaged(self) -> torch.nn.Module:
        """The weight average when ``ema_decay > 0``, else the trained weights."""
        return self.model if self.ema is None else self.ema

    def on_train_batch_end(self, outputs, batch, batch_idx: int) -> None:
        if self.ema is not None:
            update_ema(self.ema, self.model, self.ema_decay, self.global_step)


def checkpoint_step(path: Path) -> int:
    """The global step stored in a Lightning checkpoint (read without unpickling objects)."""
    # runs of before 2026-11-26 stored the extractor's learning rate as a numpy float (a plain number,
    # allowed here; nothing else is unpickled)
    with torch.serialization.safe_globals([np.float64(0).__reduce__()[0], np.dtype, type(np.dtype(np.float64))]):
        return int(torch.load(path, map_location="cpu", weights_only=True)["global_step"])


@dataclass
class RunSettings:
    """Engine settings common to every ``emogesture train`` command."""

    max_steps: int = 1000
    devices: int = 1
    accelerator: str = "cpu"  # cpu, gpu, auto
    precision: str = "32-true"  # or bf16-mixed
    checkpoint_every: int = 200  # steps
    log_every: int = 20  # steps
    progress: bool = True
    seed: int = 0


def last_checkpoint(run_dir: Path) -> Path | None:
    p = run_dir / "checkpoints" / "last.ckpt"
    return p if p.is_file() else None


#: Settings that say how the work is spread, not what is learned: a run resumes with other values.
RUNTIME_SETTINGS = ("num_workers",)


def _learning_settings(blob: dict) -> dict:
    config = {k: v for k, v in blob.get("config", {}).items() if k not in RUNTIME_SETTINGS}
    return {**blob, "config": config} if "config" in blob else blob


def check_run_dir(run_dir: Path, settings_blob: dict, overwrite: bool = False) -> bool:
    """Create or re-open a run folder; returns True when resuming.

    A folder holding another command's run, or this command's with other settings (but for
    :data:`RUNTIME_SETTINGS`), is refused (one line), unless ``overwrite``.
    """
    run_json = run_dir / "run.json"
    if run_json.is_file():
        old = _learning_settings(read_json(run_json, "run settings file"))
        if old != _learning_settings(settings_blob) and not overwrite:
            changed = changed_keys(old, _learning_settings(settings_blob))
            raise EmogestureError(
                f"{run_dir}: holds a run with other settings ({', '.join(changed)}); "
                "use another --out, or --overwrite to start it again"
            )
    elif run_dir.exists() and any(run_dir.iterdir()) and not overwrite:
        raise EmogestureError(f"{run_dir}: exists and is not a run folder; use another --out")
    run_dir.mkdir(parents=True, exist_ok=True)
    tmp = run_json.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(settings_blob, indent=1, sort_keys=True))
    os.replace(tmp, run_json)
    return last_checkpoint(run_dir) is not None and not overwrite


def make_trainer(run_dir: Path, settings: RunSettings, export, extra_callbacks: list | None = None) -> L.Trainer:
    """A Lightning Trainer writing into ``run_dir`` with atomic checkpoints every N steps."""
    ckpt = ModelCheckpoint(
        dirpath=run_dir / "checkpoints",
        filename="step{step:07d}",
        auto_insert_metric_name=False,
        every_n_train_steps=settings.checkpoint_every,
        save_last=True,
        # a run folder copied or moved elsewhere and resumed there: Lightning would write last-v1.ckpt beside
        # the old last.ckpt, and the next resume would start again from the old one
        enable_version_counter=False,
        save_top_k=1,
        monitor=None,
    )
    callbacks = [ckpt, ExportModel(export), *(extra_callbacks or [])]
    if settings.devices > 1:
        callbacks.append(RankDigest(run_dir))
    if settings.progress:
        callbacks.append(TQDMProgressBar(refresh_rate=max(1, settings.log_every // 4)))
    strategy: Any = "auto"
    if settings.devices > 1:
        # a training phase may leave a module out (the gesture model's prior-only steps); DDP then
        # skips its parameters instead of waiting for their gradients
        strategy = "ddp_find_unused_parameters_true"
    return L.Trainer(
        default_root_dir=run_dir,
        max_steps=settings.max_steps,
        max_epochs=-1,
        accelerator=settings.accelerator,
        devices=settings.devices,
        strategy=strategy,
        precision=settings.precision,
        logger=[CSVLogger(run_dir, name="logs", version=""), TensorBoardLogger(run_dir, name="tb", version="")],
        callbacks=callbacks,
        plugins=[AtomicCheckpointIO()],
        log_every_n_steps=settings.log_every,
        enable_progress_bar=settings.progress,
        enable_model_summary=False,
        num_sanity_val_steps=0,
        deterministic=False,
        use_distributed_sampler=True,
    )


def keep_previous_log(run_dir: Path) -> Path | None:
    """Move ``logs/metrics.csv`` of an earlier session of the run to ``logs/metrics.<k>.csv`` (k = 1, 2, ...)
    before resuming: Lightning's CSV logger would otherwise replace it."""
    old = run_dir / "logs" / "metrics.csv"
    if not old.is_file():
        return None
    k = 1
    while (kept := old.with_name(f"metrics.{k}.csv")).exists():
        k += 1
    os.replace(old, kept)
    return kept


def trainer_threads(num_workers: int, cpus: int, env: dict) -> int | None:
    """How many threads the training process keeps for itself when ``num_workers`` data-loading
    processes work beside it: one core less per worker (at least one). None: leave torch's own choice
    (no workers, or ``OMP_NUM_THREADS`` in ``env`` says how many)."""
    if num_workers <= 0 or "OMP_NUM_THREADS" in env:
        return None
    return max(1, cpus - num_workers)


def fit(trainer: L.Trainer, module: L.LightningModule, datamodule: L.LightningDataModule, run_dir: Path,
        resume: bool) -> None:
    """``trainer.fit``, resuming from ``last.ckpt`` when asked (weights-only loading). With data-loading
    workers (``num_workers``) the training process leaves them their cores (:func:`trainer_threads`)."""
    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    threads = trainer_threads(getattr(datamodule, "num_workers", 0), cpus, dict(os.environ))
    ckpt_path = last_checkpoint(run_dir) if resume else None
    if ckpt_path is not None and trainer.is_global_zero:
        print(f"resuming from {ckpt_path} at step {checkpoint_step(ckpt_path)}", flush=True)
        keep_previous_log(run_dir)
    saved = torch.get_num_threads(), torch.get_float32_matmul_precision()
    try:  # (the process's own settings come back after: a caller's work goes on as before)
        if threads is not None:
            torch.set_num_threads(threads)
        torch.set_float32_matmul_precision("high")
        trainer.fit(module, datamodule=datamodule, ckpt_path=str(ckpt_path) if ckpt_path else None, weights_only=True)
    finally:
        torch.set_num_threads(saved[0])
        torch.set_float32_matmul_precision(saved[1])
