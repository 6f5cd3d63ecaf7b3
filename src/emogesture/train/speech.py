"""Training the speech disentanglement model (docs/design.md, 'Speech disentanglement model') with Lightning."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

import lightning as L
import torch
from torch.utils.data import DataLoader

from emogesture.audio import augment_fbank
from emogesture.audio.wave_augment import WaveAugmentConfig
from emogesture.checkpoints import load_model, model_paths, save_model
from emogesture.config import ANY_VALUE, changed_keys, from_dict, to_dict
from emogesture.data.beat import EMOTIONS
from emogesture.data.cache import concat_splits, open_cache
from emogesture.data.datasets import AugmentedWindowBank, SpeechQuadrupleDataset, WaveWindowAugmenter
from emogesture.errors import ConfigError
from emogesture.models.metadata import SpeechMetadata
from emogesture.models.pretrained import adapt_deit_to_audio, init_speech_model_from_pretrained, load_deit_state_dict
from emogesture.models.speech import SpeechDisentangler, SpeechModelConfig
from emogesture.models.speech_losses import SpeechLossConfig, speech_losses
from emogesture.train.engine import AveragedWeightsMixin, step_generator


@dataclass
class SpeechTrainConfig:
    """Everything a speech-model run needs besides the engine settings; stored in the run."""

    #: Tried and not adopted, removed: a word-order scramble of the emotion encoder's input
    #: (experiments/speech_model/), real voices taught as neutral or given the corpus's emotions, a pull of
    #: the real windows' emotion latents toward the batch's (experiments/real_voices_in_training/), and
    #: emotion-labelled real speech in each quadruple, superseded by the front end's read-out
    #: (experiments/ravdess/; see :func:`emogesture.config.from_dict`).
    RETIRED: ClassVar[dict] = {"emotion_scramble": 0, "emotion_scramble_share": ANY_VALUE, "real_neutral": [],
                               "real_neutral_weight": ANY_VALUE, "real_neutral_pull": 0.0,
                               "real_emotion_share": ANY_VALUE, "real_labelled": "",
                               "real_labelled_weight": ANY_VALUE}

    model: SpeechModelConfig = field(default_factory=lambda: SpeechModelConfig.preset("tiny"))
    losses: SpeechLossConfig = field(default_factory=SpeechLossConfig)
    batch_size: int = 16  # quadruples per step (x4 windows)
    lr: float = 1e-3
    weight_decay: float = 5e-7
    betas: tuple[float, float] = (0.95, 0.999)
    lr_decay: float = 0.85  # the authors' x0.85 per epoch ...
    lr_decay_every: int = 200  # ... with an "epoch" of this many steps ...
    lr_decay_start: int = 1000  # ... from this step on
    #: Exponential moving average of the weights (0 = off); the exported model is the average.
    ema_decay: float = 0.99
    augment: bool = True
    #: Share of the training windows the encoders hear through augmented recording conditions (room,
    #: noise, microphone, telephone, codec, voice shift, tempo: :mod:`emogesture.audio.wave_augment`, drawn
    #: per window from the item's seeded generator); the reconstruction target stays the clean window.
    #: The waveforms are read from the corpus the cache was prepared from. 0 = off.
    wave_augment: float = 0.0
    wave: WaveAugmentConfig = field(default_factory=WaveAugmentConfig)
    #: Augmented variants of each training window, made once before training (0: every augmented window
    #: drawn afresh, in the data workers). With ``K`` > 0, ``K`` draws of the augmented conditions per window
    #: are made in parallel on every core and kept in memory (float16; about 2 GB for 1200 windows at 8), and
    #: an augmented window is one of them, drawn per item; the fbank masks, noise and shifts are still drawn
    #: afresh. On a CPU this takes the waveform augmentation, most of a step's work, off the training steps
    #: (:class:`emogesture.data.datasets.AugmentedWindowBank`).
    wave_variants: int = 0
    #: Every training window heard at a level moved by a gain drawn from ±this many dB (after the wave
    #: augmentation; 0 = off), so that the recording's level, which goes with emotion in the corpus, tells the
    #: encoders less and a quiet or loud microphone moves the perceived emotion less.
    level_jitter_db: float = 0.0
    freq_mask: int = 24
    time_mask: int = 96
    noise_std: float = 0.05
    max_shift: int = 10
    samples_per_epoch: int = 4096
    #: Data-loading processes. With ``wave_augment`` (and no ``wave_variants``) the waveform augmentation
    #: is most of a step on a CPU, and workers do it beside the training (2 workers on 2 cores: a step about
    #: 30 % faster); what is drawn does not depend on how many there are.
    num_workers: int = 0
    #: Cache splits the model learns from. ``["train", "val"]`` adds the validation texts (never the test
    #: texts): with few texts per emotion, more texts is what helps emotion recognition generalise.
    train_splits: list[str] = field(default_factory=lambda: ["train"])
    #: Where the weights start (``train speech --init-from``; empty: random): DeiT weights (timm's layout,
    #: ``.safetensors`` or ``.pth``, e.g. deit_base_distilled_patch16_384) for the three audio encoders (the
    #: paper's initialisation: the encoders' width, depth and patch size must be DeiT's, as in the ``paper``
    #: preset), or a trained speech model (its run folder or ``.json``) of the same architecture, whole: a
    #: second stage that trains it on with other settings (augmentation, learning rate).
    init_from: str = ""

    @classmethod
    def preset(cls, size: str = "tiny", losses: str = "full") -> "SpeechTrainConfig":
        """``size``: tiny | paper (the paper's encoders, the authors' lr 1e-5); ``losses``: full |
        emotion_only | style_only (the two ablations of supp. Table A.1) | adversarial (full plus the
        latent classifiers and adversaries, an extension)."""
        cfg = cls(model=SpeechModelConfig.preset(size), losses=SpeechLossConfig.preset(losses))
        if size == "paper":
            cfg.lr, cfg.batch_size, cfg.lr_decay_start, cfg.lr_decay_every = 1e-5, 8, 5 * 1000, 1000
            cfg.ema_decay = 0.0
        else:  # a short CPU run: decay from step 600 on, ×0.85 every 100 steps
            cfg.lr_decay_start, cfg.lr_decay_every = 600, 100
        return cfg


class SpeechDataModule(L.LightningDataModule):
    def __init__(self, cache_dir: Path, batch_size: int, samples_per_epoch: int, seed: int, num_workers: int = 0,
                 splits: Sequence[str] = ("train",), wave_augment: float = 0.0,
                 wave: WaveAugmentConfig | None = None, wave_variants: int = 0, progress: bool = True,
                 level_jitter_db: float = 0.0):
        super().__init__()
        self.cache = open_cache(cache_dir)
        if "test" in splits:
            raise ConfigError("train_splits: the test split is for evaluation only")
        self.train = concat_splits(self.cache, splits)
        self.speakers = sorted(set(self.train.speaker_id.tolist()))
        self.batch_size, self.seed, self.num_workers = batch_size, seed, num_workers
        augmenter = (WaveWindowAugmenter(self.cache, self.train, wave or WaveAugmentConfig())
                     if wave_augment > 0 else None)
        self.wave_variants, self.progress = wave_variants, progress
        self.dataset = SpeechQuadrupleDataset(self.train, self.speakers, samples_per_epoch, seed, augmenter,
                                              wave_augment, level_jitter_db, self.cache.stats["fbank_std"])

    def setup(self, stage: str) -> None:
        """With ``wave_variants``, the augmented-window bank is made here: after the run's checks, before the
        first step (minutes of work that a refused run should not wait for)."""
        heard = self.dataset.augmenter
        if self.wave_variants > 0 and isinstance(heard, WaveWindowAugmenter):
            self.dataset.augmenter = AugmentedWindowBank(heard, self.wave_variants, self.seed,
                                                        progress=self.progress)

    def train_dataloader(self) -> DataLoader:
        return DataLoader(self.dataset, batch_size=self.batch_size, shuffle=False, drop_last=True,
                          num_workers=self.num_workers, persistent_workers=False)


class SpeechModule(AveragedWeightsMixin, L.LightningModule):
    """Wraps :class:`SpeechDisentangler` with the quadruple losses and the optimiser."""

    def __init__(self, config: dict, seed: int = 0) -> None:
        super().__init__()
        self.save_hyperparameters()
        self.cfg = from_dict(SpeechTrainConfig, config)
        self.seed = seed
        torch.manual_seed(seed)  # weight initialisation, reproducible per run seed
        self.model = SpeechDisentangler(self.cfg.model)
        if self.cfg.init_from:
            start_weights(self.model, self.cfg.init_from)
        # the linear heads of switched-off extension terms take no part (DDP requires every trained
        # parameter to receive a gradient)
        for term, heads in (("latent_classes", ("emotion_from_latent", "speaker_from_latent")),
                            ("adversarial", ("speaker_adversary", "emotion_adversary"))):
            if getattr(self.cfg.losses, term) == 0:
                for name in heads:
                    getattr(self.model, name).requires_grad_(False)
        self.init_weight_average(self.cfg.ema_decay)

    def on_train_epoch_start(self) -> None:
        loader = self.trainer.train_dataloader
        if loader is not None and hasattr(loader.dataset, "epoch"):
            loader.dataset.epoch = self.current_epoch

    def training_step(self, batch: dict, batch_idx: int) -> torch.Tensor:
        fbank = batch["fbank"]
        inputs = batch.get("inputs", fbank)  # the windows as heard (wave_augment), the clean ones the target
        if self.cfg.augment:
            g = step_generator(self.seed, self.global_step, self.global_rank)
            b, k, t, f = fbank.shape
            inputs = augment_fbank(inputs.reshape(b * k, t, f).cpu(), g, self.cfg.freq_mask, self.cfg.time_mask,
                                   self.cfg.noise_std, self.cfg.max_shift).reshape(b, k, t, f).to(fbank.device)
        losses = speech_losses(self.model, inputs, batch["emotion"], batch["speaker"], self.cfg.losses, target=fbank)
        self.log_dict({f"train/{k}": v.detach() for k, v in losses.items()}, on_step=True, prog_bar=False,
                      batch_size=fbank.shape[0])
        self.log("loss", losses["total"].detach(), prog_bar=True, batch_size=fbank.shape[0])
        return losses["total"]

    def configure_optimizers(self):
        c = self.cfg
        params = [p for p in self.model.parameters() if p.requires_grad]
        opt = torch.optim.Adam(params, lr=c.lr, betas=tuple(c.betas), weight_decay=c.weight_decay)

        def factor(step: int) -> float:
            if step < c.lr_decay_start:
                return 1.0
            return c.lr_decay ** ((step - c.lr_decay_start) // c.lr_decay_every + 1)

        sched = torch.optim.lr_scheduler.LambdaLR(opt, factor)
        return {"optimizer": opt, "lr_scheduler": {"scheduler": sched, "interval": "step"}}


def start_weights(model: SpeechDisentangler, path: str) -> None:
    """Load ``model``'s starting weights from ``path`` (:attr:`SpeechTrainConfig.init_from`): a trained speech
    model of the same architecture (every weight), or DeiT weights (the three audio encoders)."""
    weights, meta = model_paths(path)
    if not (weights.is_file() and meta.is_file()):
        init_speech_model_from_pretrained(model, adapt_deit_to_audio(load_deit_state_dict(path),
                                                                     model.content_encoder.vit.config))
        return
    start = load_model(path, "speech")
    old, new = to_dict(start.config), to_dict(model.config)
    old["heard_bins"] = new["heard_bins"]  # what the encoders hear, not their architecture
    if old != new:
        changed = ", ".join(changed_keys(old, new))
        raise ConfigError(f"{meta}: a speech model of another architecture ({changed}); --init-from needs the "
                          "same model settings (and the same training speakers)")
    model.load_state_dict(start.model.state_dict())


def speech_model_metadata(cache, speakers: list[int], step: int, train_splits: list[str]) -> SpeechMetadata:
    """What a speech model file carries besides weights: label tables and fbank statistics."""
    return SpeechMetadata(emotions=list(EMOTIONS), speakers=speakers, fbank_mean=cache.stats["fbank_mean"],
                          fbank_std=cache.stats["fbank_std"], prepare_config=cache.manifest["config"],
                          train_splits=list(train_splits), step=step)


def build(config: SpeechTrainConfig, cache_dir: Path, seed: int, progress: bool = True):
    """Data module, Lightning module and export function of one run (``progress``: a bar while the
    augmented-window bank is made)."""
    if not 0.0 <= config.wave_augment <= 1.0:
        raise ConfigError(f"wave_augment {config.wave_augment}: a share of the windows, 0-1")
    if config.wave_variants < 0 or (config.wave_variants > 0 and config.wave_augment == 0):
        raise ConfigError(f"wave_variants {config.wave_variants}: must be >= 0, and needs wave_augment > 0")
    if not 0.0 <= config.level_jitter_db <= 30.0:
        raise ConfigError(f"level_jitter_db {config.level_jitter_db}: dB, 0-30")
    try:
        config.wave.validate()
    except ValueError as err:
        raise ConfigError(f"wave: {err}") from None
    data = SpeechDataModule(cache_dir, config.batch_size, config.samples_per_epoch, seed, config.num_workers,
                            config.train_splits, config.wave_augment, config.wave, config.wave_variants, progress,
                            config.level_jitter_db)
    if data.train.fbank.shape[1:] != (config.model.encoder.input_frames, config.model.encoder.input_bins):
        raise ConfigError(
            f"{cache_dir}: windows are {tuple(data.train.fbank.shape[1:])} but the model expects "
            f"({config.model.encoder.input_frames}, {config.model.encoder.input_bins})"
        )
    config.model.num_speakers = len(data.speakers)
    module = SpeechModule(to_dict(config), seed)

    def export(m: SpeechModule, run_dir: Path) -> None:
        metadata = speech_model_metadata(data.cache, data.speakers, m.global_step, config.train_splits)
        save_model(run_dir, "speech", m.averaged, m.cfg.model, metadata)

    return data, module, export
