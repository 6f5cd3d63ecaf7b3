"""Joint training of the motion prior and the latent denoiser (paper Fig. 2; docs/design.md, 'Gesture generation model').

Each step: (1) prior forward on the motion m -> m̂: L_rec (smooth L1, features), L_Vrec (smooth L1,
joint positions of the licence-free skeleton), L_KL; (2) z_m = P_E(m) without gradient, noised at a
random t: L_LD = ||target - Δ(z_t, t, c, e, s[, timing stream])||², target = ε in the paper (the noise; z_m or v by
``model.diffusion.prediction_type``; the tiny preset regresses z_m, so its logged ``ld`` is in latent
units and not comparable with ε-runs); (3) without gradient, the full DDIM loop from noise
with the current Δ -> z̃, then m̃ = P_D(z̃) WITH gradient: L_align, L_Valign against m.
The audio model is frozen: c, e, s are computed once per window by the speech run and cached.
When training ends, a model with ``generation.residual_scale > 0`` (tiny) measures its residual-noise
calibration on the cache's validation windows (:func:`emogesture.pipeline.sampling.calibrate_residual`).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import ClassVar

import lightning as L
import numpy as np
import torch
import torch.nn.functional as F
from torch.utils.data import DataLoader, Dataset

from emogesture.checkpoints import LoadedModel, check_model_output, load_model, save_model, stored_weights_dtype
from emogesture.provenance import refuse_trained_split, trained_splits
from emogesture.config import from_dict, to_dict
from emogesture.data.beat import EMOTIONS
from emogesture.data.cache import open_cache
from emogesture.diffusion.sampling import add_noise, ddim_sample, draw_noise, sample_timesteps, training_target
from emogesture.diffusion.schedulers import make_ddim_scheduler, make_ddpm_scheduler
from emogesture.errors import ConfigError
from emogesture.models.generation import GenerationConfig
from emogesture.models.metadata import GestureMetadata
from emogesture.models.gesture import GestureModel, GestureModelConfig
from emogesture.motion import MotionFeatureSpec, SkeletonBody
from emogesture.eval.split_latents import model_conditions, window_conditions
from emogesture.pipeline.sampling import calibrate_residual
from emogesture.pipeline.speech import SpeechLatentEncoder
from emogesture.train.engine import AveragedWeightsMixin, step_generator

LOSS_TERMS = ("rec", "vrec", "kl", "ld", "align", "valign", "audio_rec")


@dataclass
class GestureLossWeights:
    RETIRED: ClassVar[dict] = {"vspeed": 0.0, "align_speed": 0.0, "vaccel": 0.0, "align_accel": 0.0,
                               "finger_features": 1.0, "wrist_features": 1.0}

    rec: float = 1.0
    vrec: float = 1.0
    kl: float = 1e-4
    ld: float = 1.0
    align: float = 1.0
    valign: float = 1.0
    # tried and not adopted: joint speed and acceleration terms (experiments/rhythm/), finger and wrist feature
    # weights (experiments/motion_prior/)
    audio_rec: float = 1.0  # no_audio variant: MFCC autoencoder reconstruction


@dataclass
class GestureTrainConfig:
    model: GestureModelConfig = field(default_factory=lambda: GestureModelConfig.preset("tiny"))
    #: How the trained model will generate (stored with it; changeable later without retraining).
    generation: GenerationConfig = field(default_factory=lambda: GenerationConfig.preset("tiny"))
    losses: GestureLossWeights = field(default_factory=GestureLossWeights)
    batch_size: int = 32
    lr: float = 1e-4
    #: Learning rate of the motion prior (None = ``lr``); the tiny ``no_prior`` ablation's linear map
    #: over a whole flattened window (300 × D inputs) needs a smaller one than the networks.
    prior_lr: float | None = None
    weight_decay: float = 0.0
    align_ddim_steps: int = 50  # DDIM steps of the no-gradient sampling in step (3) (paper: 50)
    align_every: int = 1  # run step (3) every N steps (paper: every step)
    #: Step (2) noises each window at this many random timesteps (paper: 1). The denoiser is small next
    #: to the prior, so on a CPU its extra samples cost little and it learns several times faster.
    ld_repeats: int = 1
    disjoint_prior_steps: int = 500  # variant "disjoint": prior-only steps before the denoiser-only phase
    #: Other variants: prior-only steps before joint training starts (paper: 0). The denoiser and the
    #: alignment then start on settled latents instead of the random ones of an untrained encoder.
    prior_warmup_steps: int = 0
    #: Exponential moving average of the weights (0 = off); the exported model is the average.
    ema_decay: float = 0.0
    #: Joint positions enter L_Vrec and L_Valign in metres × this (smooth L1 is quadratic below 1 unit):
    #: 1 = metres (MLD); the tiny preset uses 100 (centimetres) so joint errors of a few cm weigh in.
    joint_scale: float = 1.0
    num_workers: int = 0

    def __post_init__(self) -> None:
        negative = [k for k, v in vars(self.losses).items() if v < 0]
        if negative:
            raise ConfigError(f"gesture training: loss weights must be ≥ 0, got {', '.join(negative)} below 0")
        if self.ld_repeats < 1 or self.batch_size < 1 or self.align_ddim_steps < 1 or self.align_every < 0:
            raise ConfigError("gesture training: ld_repeats, batch_size and align_ddim_steps must be ≥ 1, "
                              "align_every ≥ 0")
        if self.prior_warmup_steps < 0 or self.disjoint_prior_steps < 0:
            raise ConfigError("gesture training: prior_warmup_steps and disjoint_prior_steps must be ≥ 0")
        if self.lr <= 0 or (self.prior_lr is not None and self.prior_lr <= 0):
            raise ConfigError("gesture training: lr and prior_lr must be > 0 (prior_lr may be unset)")
        den = self.model.denoiser
        if den.width < den.latent_dim:
            # z_t enters and the prediction leaves through one width-d token, so the prediction spans at
            # most `width` of the latent's dimensions (for ε at large t even z_t itself cannot pass, as the
            # ideal ε̂ is ≈ z_t); measured with ε: samples drift far off the latents.
            # Checked here, for new trainings; older models of that shape still load and run.
            raise ConfigError(f"gesture training: denoiser width {den.width} is below latent_dim "
                              f"{den.latent_dim}; its prediction would pass through a rank bottleneck")

    @classmethod
    def preset(cls, size: str = "tiny", variant: str = "joint") -> "GestureTrainConfig":
        cfg = cls(model=GestureModelConfig.preset(size, variant), generation=GenerationConfig.preset(size, variant))
        if size == "paper":
            cfg.batch_size = 64
        else:
            cfg.lr, cfg.align_ddim_steps, cfg.align_every = 1e-3, 10, 2
            cfg.ema_decay, cfg.joint_scale, cfg.ld_repeats = 0.99, 100.0, 4
            # L_align / L_Valign at 0.1: a sampled latent cannot know the window's exact strokes, and at
            # weight 1 the decoder learns their average (held-out FGD 34.0 at 1, 15.3 at 0.1)
            cfg.losses.align = cfg.losses.valign = 0.1
            if variant == "no_prior":
                cfg.prior_lr = 1e-4
            elif variant in ("joint", "no_audio"):
                cfg.prior_warmup_steps = 450
        return cfg


class GestureWindows(Dataset):
    """Normalised motion windows with their condition latents (and emotion labels)."""

    def __init__(self, motion, mean, std, conditions: list[np.ndarray], emotion: np.ndarray) -> None:
        self.motion, self.mean, self.std = motion, mean, std
        self.conditions, self.emotion = conditions, emotion

    def __len__(self) -> int:
        return len(self.motion)

    def __getitem__(self, i: int) -> dict:
        m = (np.asarray(self.motion[i], np.float32) - self.mean) / self.std
        return {"motion": torch.from_numpy(m), "emotion": torch.tensor(int(self.emotion[i])),
                "conditions": [torch.from_numpy(np.asarray(c[i], np.float32)) for c in self.conditions]}


class GestureModule(AveragedWeightsMixin, L.LightningModule):
    def __init__(self, config: dict, motion_mean: list, motion_std: list, features: dict, seed: int = 0) -> None:
        super().__init__()
        self.save_hyperparameters()
        self.cfg = from_dict(GestureTrainConfig, config)
        self.seed = seed
        torch.manual_seed(seed)
        self.model = GestureModel(self.cfg.model)
        self.spec = from_dict(MotionFeatureSpec, features)
        self.register_buffer("mean", torch.tensor(motion_mean, dtype=torch.float32))
        self.register_buffer("std", torch.tensor(motion_std, dtype=torch.float32))
        self.body = SkeletonBody()
        for p in self.body.parameters():
            p.requires_grad_(False)
        self.ddpm = make_ddpm_scheduler(self.cfg.model.diffusion)
        self.ddim = make_ddim_scheduler(self.cfg.model.diffusion)
        self.init_weight_average(self.cfg.ema_decay)

    def joints(self, normalised: torch.Tensor) -> torch.Tensor:
        """Normalised features ``[B, T, D]`` -> joint positions ``[B, T, 55, 3]`` (differentiable)."""
        return self.body.forward_features(torch.addcmul(self.mean, normalised, self.std), self.spec)

    def feature_loss(self, motion: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        """Smooth L1 between normalised features ``[B, T, D]``."""
        return F.smooth_l1_loss(motion, target)

    def joint_loss(self, joints: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        """Smooth L1 between joint positions ``[B, T, 55, 3]`` in units of ``1 / joint_scale`` metres."""
        # smooth L1 of (x·s, y·s) is s × smooth L1 of (x, y) with its quadratic zone narrowed to 1/s:
        # the same loss without scaling both [B, T, 55, 3] tensors first
        s = self.cfg.joint_scale
        return s * F.smooth_l1_loss(joints, target, beta=1.0 / s)

    def conditions(self, batch: dict) -> tuple[list[torch.Tensor], torch.Tensor | None]:
        conds = list(batch["conditions"])
        if self.model.audio_ae is None:
            return conds, None
        m, rec = self.model.audio_ae(conds[0])
        return [m.detach()], F.mse_loss(rec, conds[0])

    def training_step(self, batch: dict, batch_idx: int) -> torch.Tensor:
        cfg, w = self.cfg, self.cfg.losses
        g = step_generator(self.seed, self.global_step, self.global_rank)
        m = batch["motion"]
        b = m.shape[0]
        conds, audio_rec = self.conditions(batch)
        variant = cfg.model.variant
        if variant == "disjoint":
            phase_prior = self.global_step < cfg.disjoint_prior_steps
            phase_denoiser = not phase_prior
        else:
            phase_prior, phase_denoiser = True, self.global_step >= cfg.prior_warmup_steps
        losses: dict[str, torch.Tensor] = {}
        prior = self.model.prior
        gt: list[torch.Tensor] = []

        def joints_gt() -> torch.Tensor:  # ground-truth joint positions, computed once per step
            if not gt:
                with torch.no_grad():
                    gt.append(self.joints(m))
            return gt[0]

        # the speech's timing stream ends the conditions of a model that reads one (its motion decoder)
        stream = conds[-1] if cfg.model.vae.timing_features else None
        conds = conds[: cfg.model.denoiser.num_conditions]
        if phase_prior:
            rec, z, mu, logvar = prior(m, generator=g, timing=stream)
            losses["rec"] = self.feature_loss(rec, m)
            joints_rec = self.joints(rec)
            losses["vrec"] = self.joint_loss(joints_rec, joints_gt())
            if variant != "no_prior":
                losses["kl"] = prior.kl_loss(mu, logvar)
        else:
            with torch.no_grad():
                z, _, _ = prior.encode(m, generator=g)
        if phase_denoiser:
            # float32 even where the prior ran under bf16 autocast: the noising mixes z0 and the noise by
            # the schedule's √ᾱ and √(1-ᾱ), and in bf16 1-ᾱ rounds to 0 at t = 0 (0.00085) and to 0.0039
            # at t = 5 (0.0052), while sampling runs the float32 schedule
            z0 = z.detach().float()
            r = cfg.ld_repeats  # each window noised at r timesteps: r × the denoiser's samples per step
            z0r, conds_r = z0.repeat(r, 1), [c.repeat(r, *[1] * (c.dim() - 1)) for c in conds]
            noise = draw_noise(g, b * r, z0.shape[1]).to(z0.device)
            t = sample_timesteps(g, b * r, cfg.model.diffusion.num_train_timesteps).to(z0.device)
            pred = self.model.denoiser(add_noise(self.ddpm, z0r, noise, t), t, conds_r)
            losses["ld"] = F.mse_loss(pred, training_target(self.ddpm, z0r, noise, t))
            if variant != "disjoint" and cfg.align_every > 0 and self.global_step % cfg.align_every == 0:
                z_tilde = ddim_sample(self.model.denoiser, self.ddim, conds, g,
                                      num_inference_steps=cfg.align_ddim_steps, eta=cfg.model.diffusion.eta)
                m_tilde = prior.decode(z_tilde.detach(), frames=m.shape[1], timing=stream)
                losses["align"] = self.feature_loss(m_tilde, m)
                joints_tilde = self.joints(m_tilde)
                losses["valign"] = self.joint_loss(joints_tilde, joints_gt())
        if audio_rec is not None:
            losses["audio_rec"] = audio_rec
        total = sum(getattr(w, k) * v for k, v in losses.items())
        self.log_dict({f"train/{k}": v.detach() for k, v in losses.items()}, on_step=True, batch_size=b)
        self.log("loss", total.detach(), prog_bar=True, batch_size=b)
        return total

    def configure_optimizers(self):
        prior = [p for p in self.model.prior.parameters() if p.requires_grad]
        in_prior = {id(p) for p in prior}
        rest = [p for p in self.model.parameters() if p.requires_grad and id(p) not in in_prior]
        prior_lr = self.cfg.lr if self.cfg.prior_lr is None else self.cfg.prior_lr
        groups = [{"params": rest}, {"params": prior, "lr": prior_lr}]
        # the fused kernel: one pass over all 5.4 M parameters of the tiny model, 3.5 ms a step on a 2-core
        # CPU against 16 ms for the per-tensor one (the same update; checkpoints load either way)
        fused = self.device.type in ("cpu", "cuda")
        return torch.optim.AdamW(groups, lr=self.cfg.lr, weight_decay=self.cfg.weight_decay, fused=fused)


class GestureDataModule(L.LightningDataModule):
    def __init__(self, dataset: Dataset, batch_size: int, seed: int, num_workers: int = 0) -> None:
        super().__init__()
        self.dataset, self.batch_size, self.seed, self.num_workers = dataset, batch_size, seed, num_workers

    def train_dataloader(self) -> DataLoader:
        return DataLoader(self.dataset, batch_size=self.batch_size, shuffle=True, drop_last=True,
                          generator=torch.Generator().manual_seed(self.seed), num_workers=self.num_workers)


def build(config: GestureTrainConfig, cache_dir: Path, seed: int, speech_run: Path | None, device: str = "cpu"):
    """Data, module and export of a gesture training; ``device`` encodes the windows' speech latents
    (once, then cached beside the windows) in float32."""
    cache = open_cache(cache_dir)
    train = cache.split("train")
    variant = config.model.variant
    speech = None if variant == "no_audio" else SpeechLatentEncoder.from_run(speech_run, device=device)
    timing = config.model.hears_timing
    conds = window_conditions(variant, cache, "train", speech, timing)
    mean = np.asarray(cache.stats["motion_mean"], np.float32)
    std = np.asarray(cache.stats["motion_std"], np.float32)
    config.model.vae.feature_dim = int(train.motion.shape[2])
    config.model.vae.frames = int(train.motion.shape[1])
    data = GestureDataModule(GestureWindows(train.motion, mean, std, conds, train.emotion),
                             config.batch_size, seed, config.num_workers)
    features = cache.manifest["config"]["features"]
    module = GestureModule(to_dict(config), mean.tolist(), std.tolist(), features, seed)
    metadata = GestureMetadata(emotions=list(EMOTIONS), motion_mean=mean.tolist(), motion_std=std.tolist(),
                               features=features, variant=variant, fps=30, train_splits=["train"])
    if speech is not None:
        enc_e = conds[1]
        metadata = metadata.replace(
            speech_model=str(Path(speech.loaded.path).resolve()),
            speech_weights_sha256=speech.loaded.weights_sha256,
            emotion_latent_means={EMOTIONS[k]: enc_e[train.emotion == k].mean(0).tolist()
                                  for k in sorted(set(train.emotion.tolist()))})

    # residual-noise calibration on the held-out validation windows, once, when training ends
    calibration = None
    if config.generation.residual_scale > 0:
        speech_trained = trained_splits(speech.loaded) if speech is not None else []
        if "val" in speech_trained:
            print(f"note: the speech model {speech.loaded.path} trained on the val split, so the residual noise is "
                  "not calibrated there (the model samples without it); `emogesture calibrate gesture --split` "
                  "on windows no part saw can add it", file=sys.stderr)
        elif "val" in cache.splits:
            calibration = (window_conditions(variant, cache, "val", speech, timing), cache.split("val").motion)
        else:
            print(f"note: {cache_dir} has no val windows, so the model will not be calibrated and will sample "
                  "without residual noise (`emogesture calibrate gesture` can add it later)", file=sys.stderr)

    def export(m: GestureModule, run_dir: Path) -> None:
        done = metadata.replace(step=m.global_step)
        # measured afresh at every export of the last step: the checkpoint of that step is saved before
        # the weight average takes its last update, and the export when training ends comes after it
        if calibration is not None and m.global_step >= (m.trainer.max_steps or 0) > 0:
            was_training = m.averaged.training
            stats = calibrate_residual(LoadedModel(m.averaged, m.cfg.model, done, run_dir, generation=m.cfg.generation),
                                       *calibration, seed=seed)
            m.averaged.train(was_training)
            done = done.replace(residual_calibration={**stats, "step": m.global_step, "split": "val"})
        save_model(run_dir, "gesture", m.averaged, m.cfg.model, done, generation=m.cfg.generation)

    return data, module, export


def calibrate_run(run: Path, cache_dir: Path, out: Path, split: str = "val", seed: int = 0,
                  overwrite: bool = False, scale: float = 1.0) -> dict:
    """Write a copy of the gesture model of ``run`` to ``out`` with its residual-noise calibration
    measured on ``split`` of the cache and ``generation.residual_scale = scale`` (``emogesture calibrate
    gesture``); returns what was measured. For models trained before calibration existed, or to
    calibrate on other held-out windows."""
    out = Path(out)
    if scale < 0:
        raise ConfigError(f"residual scale must be ≥ 0, got {scale}")
    check_model_output(out, overwrite)
    gesture = load_model(run, "gesture")
    cache = open_cache(cache_dir)
    variant = gesture.config.variant
    speech = None if variant == "no_audio" else SpeechLatentEncoder.of_gesture_model(gesture)
    refuse_trained_split(split, gesture, *([speech.loaded] if speech is not None else []), purpose="calibrate")
    windows = cache.split(split)
    stats = calibrate_residual(gesture, model_conditions(gesture, cache, split, speech), windows.motion, seed=seed)
    stats.update(step=gesture.metadata.step, split=split)
    save_model(out, "gesture", gesture.model, gesture.config, gesture.metadata.replace(residual_calibration=stats),
               generation=replace(gesture.generation, residual_scale=float(scale)),
               weights_dtype=stored_weights_dtype(gesture))
    return stats
