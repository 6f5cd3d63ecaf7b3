"""Training runs as library calls: what ``emogesture train speech|extractor|gesture`` does.

Each function builds the run's config (a preset, then an optional YAML file, then ``key=value`` overrides),
opens or resumes the run folder (re-running the same call resumes; other settings are refused unless
``overwrite``), trains and exports ``<out>/model.json``::

    from emogesture.train.runs import RunOptions, train_speech, train_gesture
    speech = train_speech("cache/synthetic", "runs/speech", options=RunOptions(steps=600))
    gesture = train_gesture("cache/synthetic", "runs/gesture", speech="runs/speech",
                            overrides=["generation.timing_guidance=5"], options=RunOptions(steps=2400))
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from os import PathLike
from pathlib import Path
from typing import Any

from emogesture.config import load_config, to_dict
from emogesture.errors import EmogestureError

#: the names a user may give for a precision or an accelerator, and Lightning's for them
_PRECISIONS = {"fp32": "32-true", "32-true": "32-true", "bf16": "bf16-mixed", "bf16-mixed": "bf16-mixed"}
_ACCELERATORS = {"cpu": "cpu", "cuda": "gpu", "gpu": "gpu", "auto": "auto"}


@dataclass
class RunOptions:
    """How a run trains, apart from what it trains: steps, devices, precision, checkpoints, seed."""

    steps: int = 1000
    #: processes / GPUs; more than 1 uses DDP
    devices: int = 1
    #: cpu, cuda (= gpu) or auto
    accelerator: str = "cpu"
    #: fp32 (= 32-true; on GPUs its matrix products use TF32) or bf16 (= bf16-mixed: autocast, float32 weights)
    precision: str = "32-true"
    checkpoint_every: int = 200
    log_every: int = 20
    #: seed of weights, sampling and augmentation
    seed: int = 0
    #: start the run folder again from scratch
    overwrite: bool = False
    #: a progress bar with ETA
    progress: bool = True


@dataclass
class TrainedRun:
    """What a run left: its exported model and the step it reached."""

    model: Path
    step: int
    #: False in the non-zero ranks of a multi-process run (only rank 0 exports)
    exported: bool = True


def train_speech(data: str | PathLike[str], out: str | PathLike[str], *, preset: str = "tiny",
                 losses: str = "full", config_file: str | PathLike[str] | None = None,
                 overrides: Sequence[str] = (), init_from: str | PathLike[str] | None = None,
                 options: RunOptions | None = None) -> TrainedRun:
    """The speech disentanglement model (content / emotion / style); ``losses``: ``full`` (the paper),
    ``emotion_only`` / ``style_only`` (its ablations) or ``adversarial``; ``init_from``: DeiT weights for the
    three audio encoders, or a trained speech model of the same architecture to start from."""
    from emogesture.train.speech import SpeechTrainConfig, build

    config = load_config(SpeechTrainConfig, config_file, list(overrides),
                         base=to_dict(SpeechTrainConfig.preset(preset, losses)))
    if init_from is not None:
        config.init_from = str(Path(init_from).resolve())
    options = options or RunOptions()
    return run_training("train speech", config, lambda c, d, s: build(c, d, s, options.progress), data, out, options)


def train_extractor(data: str | PathLike[str], out: str | PathLike[str], *, preset: str = "tiny",
                    config_file: str | PathLike[str] | None = None, overrides: Sequence[str] = (),
                    options: RunOptions | None = None) -> TrainedRun:
    """The motion feature extractor M that the gesture metrics read motion with."""
    from emogesture.train.extractor import ExtractorTrainConfig, build

    config = load_config(ExtractorTrainConfig, config_file, list(overrides),
                         base=to_dict(ExtractorTrainConfig.preset(preset)))
    return run_training("train extractor", config, build, data, out, options or RunOptions())


def train_gesture(data: str | PathLike[str], out: str | PathLike[str], *, speech: str | PathLike[str] | None = None,
                  preset: str = "tiny", variant: str = "joint", config_file: str | PathLike[str] | None = None,
                  overrides: Sequence[str] = (), options: RunOptions | None = None) -> TrainedRun:
    """The gesture generator (motion prior + latent diffusion) on the latents of the speech model ``speech``
    (a run folder or model JSON; every variant but ``no_audio`` needs one)."""
    from emogesture.runtime import process_device
    from emogesture.train.gesture import GestureTrainConfig, build

    if variant != "no_audio" and speech is None:
        raise EmogestureError("a trained speech model is needed (--speech RUN), except for the no_audio variant")
    options = options or RunOptions()
    config = load_config(GestureTrainConfig, config_file, list(overrides),
                         base=to_dict(GestureTrainConfig.preset(preset, variant)))
    speech = Path(speech) if speech is not None else None
    # the speech model that encodes the windows' latents (once; later runs and the other DDP processes read
    # them from the cache) is loaded where this process trains
    device = process_device(options.accelerator)
    return run_training("train gesture", config, lambda c, d, s: build(c, d, s, speech, device), data, out, options,
                        {"speech": str(speech.resolve()) if speech is not None else None})


def run_training(command: str, config: Any, build: Callable, data: str | PathLike[str], out: str | PathLike[str],
                 options: RunOptions, more: dict | None = None) -> TrainedRun:
    """Train one run: ``build(config, data, seed)`` gives the data module, the Lightning module and the export
    function; the run folder records ``command``, the config, the data and ``more``, and resumes when they match."""
    from emogesture.train.engine import RunSettings, check_run_dir, fit, make_trainer

    data, out = Path(data), Path(out)
    precision = _PRECISIONS.get(options.precision)
    accelerator = _ACCELERATORS.get(options.accelerator)
    if precision is None:
        raise EmogestureError(f"precision {options.precision!r}: use one of {', '.join(_PRECISIONS)}")
    if accelerator is None:
        raise EmogestureError(f"device {options.accelerator!r}: use one of {', '.join(_ACCELERATORS)}")
    if options.devices < 1:
        raise EmogestureError(f"--devices {options.devices}: at least 1")
    if accelerator == "gpu":
        import torch

        if not torch.cuda.is_available():
            raise EmogestureError(f"--device {options.accelerator}: no CUDA GPU is visible to torch; use --device cpu")
        if options.devices > (count := torch.cuda.device_count()):
            raise EmogestureError(f"--devices {options.devices}: torch sees {count} GPU(s)")
    settings = RunSettings(max_steps=options.steps, devices=options.devices, accelerator=accelerator,
                           precision=precision, checkpoint_every=options.checkpoint_every,
                           log_every=options.log_every, progress=options.progress, seed=options.seed)
    blob = {"command": command, "config": to_dict(config), "data": str(data.resolve()),
            "seed": options.seed, "precision": precision, **(more or {})}
    resume = check_run_dir(out, blob, options.overwrite)
    datamodule, module, export = build(config, data, options.seed)
    trainer = make_trainer(out, settings, lambda m: export(m, out))
    fit(trainer, module, datamodule, out, resume)
    return TrainedRun(out / "model.json", int(trainer.global_step), bool(trainer.is_global_zero))
