"""Sampling: motion latents drawn by the denoiser for condition windows, decoded to motion features.

A gesture model is conditioned on ``(c, e, s)`` from the frozen speech model, or, in the ``no_audio``
ablation, on one latent ``m`` from its own MFCC autoencoder. These functions draw the motion latents of a
batch of condition windows (DDIM, with the generation settings' guidance and residual noise), decode them
through the motion prior, generate motion for whole condition arrays (optionally with an emotion edit by
label) and reconstruct ground truth through the prior. ``generate`` and the evaluation share them; the
conditions of a prepared split's windows are :mod:`emogesture.eval.split_latents`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import torch
from torch import nn

from emogesture.audio.timing import TIMING_FEATURES
from emogesture.checkpoints import LoadedModel
from emogesture.config import from_dict
from emogesture.diffusion.residual import residual_factor
from emogesture.diffusion.sampling import ddim_sample, make_generators
from emogesture.diffusion.schedulers import make_ddim_scheduler
from emogesture.errors import EmogestureError
from emogesture.models.generation import GenerationConfig
from emogesture.motion import MotionFeatureSpec
from emogesture.pipeline.postprocess import add_residual, filter_output, guide_timing, settle_quiet_windows
from emogesture.runtime import StageTimes, autocast, bf16_weights, maybe_stage, refuse_held_weights
from emogesture.types import EMOTIONS, FPS


def label_latents(gesture: LoadedModel, labels: np.ndarray) -> np.ndarray:
    """Each window's target label ``labels [W]`` (indices of :data:`~emogesture.types.EMOTIONS`) -> the model's
    stored mean emotion latent of that label ``[W, 256]`` float32: what an edit by label moves toward."""
    means = gesture.metadata.emotion_latent_means
    if not means:
        raise EmogestureError(f"{gesture.path}: this model has no emotion latents to edit")
    missing = sorted({EMOTIONS[k] for k in np.asarray(labels).tolist()} - set(means))
    if missing:
        raise EmogestureError(f"{gesture.path}: no mean emotion latent for {', '.join(missing)}; "
                              f"known: {', '.join(means)}")
    table = {EMOTIONS.index(k): np.asarray(v, np.float32) for k, v in means.items()}
    return np.stack([table[int(k)] for k in np.asarray(labels).reshape(-1)]).reshape(len(labels), -1)


def edit_emotion(emotion: np.ndarray, target: np.ndarray, weight: float = 1.0) -> np.ndarray:
    """The one emotion edit: emotion latents ``[W, 256]`` moved toward ``target [W, 256]`` by ``weight``
    (0: unchanged, 1: the target), float32."""
    return ((1.0 - weight) * emotion + weight * target).astype(np.float32)


def emotion_label_edit(gesture: LoadedModel, conditions: list[np.ndarray], labels: np.ndarray,
                       weight: float = 1.0) -> list[np.ndarray]:
    """Conditions ``[c, e, s(, timing)]`` with each window's emotion latent edited toward the stored mean latent
    of its target label ``labels [W]`` (:func:`label_latents`, :func:`edit_emotion`); the timing stream, if
    any, stays the speech's own."""
    if len(conditions) < 3:
        raise EmogestureError(f"{gesture.path}: this model has no emotion latents to edit")
    return [conditions[0], edit_emotion(conditions[1], label_latents(gesture, labels), weight), *conditions[2:]]


def draw_seed(seed: int, sample: int, window: int, candidate: int = 0) -> int:
    """The noise seed of one draw: ``sample`` of a call's samples, ``window`` of its windows, ``candidate`` of
    the window's seam candidates, all derived from the user's ``seed`` (the one scheme of ``generate``, the
    live stream and the evaluation; candidate 0 of a window keeps the seed it has with one candidate)."""
    return int(np.random.SeedSequence([seed, sample, window] + ([candidate] if candidate else [])).generate_state(1)[0])


def window_seeds(seed: int, count: int) -> list[int]:
    """The seeds of ``count`` windows of one sample (:func:`draw_seed`; the same for every model and edit)."""
    return [draw_seed(seed, 0, i) for i in range(count)]


def _motion_statistics(gesture: LoadedModel) -> tuple[np.ndarray, np.ndarray]:
    """The model's per-feature motion mean and std (raw features <-> the prior's normalised ones)."""
    meta = gesture.metadata
    return (np.asarray(meta.require("motion_mean", gesture.path), np.float32),
            np.asarray(meta.require("motion_std", gesture.path), np.float32))


def evaluating(model: nn.Module) -> nn.Module:
    """``model`` in eval mode; a model already there (its root not training) is left as it is: walking a
    model's modules to set the mode took 2.4 ms of a 40-ms tiny generation."""
    return model.eval() if model.training else model


def settings_of(gesture: LoadedModel, generation: GenerationConfig | None) -> GenerationConfig:
    """``generation``, or the model's own settings (a model saved without any: the defaults)."""
    return generation or gesture.generation or GenerationConfig()


@torch.inference_mode()
def sample_latents(gesture: LoadedModel, conditions: list[np.ndarray], seeds: list[int], batch_size: int = 64,
                   generation: GenerationConfig | None = None, residual: bool = True,
                   progress: Callable[[int], None] | None = None,
                   residual_weights: np.ndarray | None = None, precision: str = "fp32") -> torch.Tensor:
    """Raw conditions ``[W, ·]`` and one noise seed per window -> sampled motion latents ``[W, 256]``
    float32 (on the model's device), the residual noise added (:func:`~emogesture.pipeline.postprocess.add_residual`);
    see :func:`generate_from_conditions`. ``precision="bf16"`` runs the denoiser under bf16 autocast (the
    scheduler's arithmetic stays float32)."""
    model = evaluating(gesture.model)
    device = next(model.parameters()).device
    cfg = gesture.config
    settings = settings_of(gesture, generation)
    steps = settings.num_inference_steps
    scheduler = make_ddim_scheduler(cfg.diffusion, steps)
    if any(len(c) != len(seeds) for c in conditions):
        raise ValueError(f"got {len(seeds)} seeds for conditions of {[len(c) for c in conditions]} windows")
    conditions = conditions[: cfg.denoiser.num_conditions]  # the timing stream is the decoder's
    out = []
    with bf16_weights(precision, model.denoiser, pack=True):
        for i in range(0, len(seeds), batch_size):
            conds = [torch.from_numpy(np.ascontiguousarray(c[i : i + batch_size], np.float32)).to(device)
                     for c in conditions]
            if model.audio_ae is not None:
                conds = [model.audio_ae(conds[0])[0]]
            generators = make_generators(seeds[i : i + batch_size])
            with autocast(precision, device):
                z = ddim_sample(model.denoiser, scheduler, conds, generators, num_inference_steps=steps,
                                eta=cfg.diffusion.eta)
            z = z.float()
            if residual:
                weights = residual_weights[i: i + batch_size] if residual_weights is not None else None
                z = add_residual(z, model, generators, settings.residual_scale, weights)
            out.append(z)
            if progress is not None:
                progress(len(z))
    return torch.cat(out)


@torch.no_grad()
def encode_motion(gesture: LoadedModel, motion: np.ndarray, batch_size: int = 64) -> torch.Tensor:
    """Raw motion features ``[W, T, D]`` -> the prior's latents (encoder mean) ``[W, 256]``."""
    model = evaluating(gesture.model)
    refuse_held_weights(model.prior)
    device = next(model.parameters()).device
    mean, std = _motion_statistics(gesture)
    out = []
    for i in range(0, len(motion), batch_size):
        x = torch.from_numpy((np.asarray(motion[i : i + batch_size], np.float32) - mean) / std).to(device)
        out.append(model.prior.encode(x, sample=False)[0])
    return torch.cat(out)


#: Windows per batch of the motion decoder. Its activations grow with the batch (300 query tokens per
#: window, twice with the timing guidance), and past about 32 windows they fall out of the CPU's caches:
#: the tiny decoder took 4.9 / 4.9 / 5.2 / 6.6 ms per window in batches of 8 / 16 / 32 / 64 (2 cores,
#: best of 6, interleaved), which made 10 min of audio (batches of 64) cost more per second than 1 min.
DECODE_BATCH = 16


@torch.inference_mode()
def decode_latents(gesture: LoadedModel, z: torch.Tensor, frames: int, batch_size: int = DECODE_BATCH,
                   timing: np.ndarray | None = None, precision: str = "fp32",
                   generation: GenerationConfig | None = None) -> np.ndarray:
    """Motion latents ``[W, 256]`` -> raw motion features ``[W, frames, D]`` float32; ``timing [W, T, F]``:
    the windows' timing stream, for a decoder that reads one (``vae.timing_features > 0``);
    ``precision="bf16"``: the decoder runs under bf16 autocast. ``generation``: the settings of the steps
    after decoding (:func:`~emogesture.pipeline.postprocess.guide_timing`,
    :func:`~emogesture.pipeline.postprocess.filter_output`; None: the model's own); ``GenerationConfig()``
    (no guidance, no filters) decodes as in training (the prior's reconstruction)."""
    model = evaluating(gesture.model)
    vae = gesture.config.vae
    mean, std = _motion_statistics(gesture)
    reads = vae.timing_features > 0
    settings = settings_of(gesture, generation)
    guidance = settings.timing_guidance if reads else 1.0
    smoothing, cutoff = settings.output_smoothing, settings.output_lowpass_hz
    guided = guidance != 1.0 and timing is not None  # guidance runs in raw feature units, where the 6D columns live
    if guided:
        spec = from_dict(MotionFeatureSpec, gesture.metadata.require("features", gesture.path))
        # "onsets": the deaf decoding keeps the stream's loudness (the column of TIMING_FEATURES)
        keep = (TIMING_FEATURES.index("loudness"),) if settings.timing_guidance_on == "onsets" else ()
    m, s = torch.from_numpy(mean).to(z.device), torch.from_numpy(std).to(z.device)
    out = np.empty((len(z), frames, vae.feature_dim), np.float32)  # filled batch by batch, denormalised
    with bf16_weights(precision, model.prior):
        for i in range(0, len(z), batch_size):
            stream = (torch.from_numpy(np.ascontiguousarray(timing[i: i + batch_size], np.float32)).to(z.device)
                      if reads and timing is not None else None)
            with autocast(precision, z.device):
                if guided:
                    heard, deaf = model.prior.decode_pair(z[i: i + batch_size], frames=frames, timing=stream,
                                                          keep=keep)
                else:
                    x = model.prior.decode(z[i: i + batch_size], frames=frames, timing=stream)
            # to raw units first: the filters are unit-gain, so they commute with the affine map
            x = guide_timing(heard, deaf, m, s, guidance, spec) if guided else torch.addcmul(m, x.float(), s)
            out[i: i + batch_size] = filter_output(x, smoothing, cutoff).cpu().numpy()
    return out


def generate_from_conditions(gesture: LoadedModel, conditions: list[np.ndarray], seeds: list[int],
                             batch_size: int = 64, generation: GenerationConfig | None = None,
                             residual: bool = True, progress: Callable[[int], None] | None = None,
                             sound: np.ndarray | None = None, precision: str = "fp32",
                             times: StageTimes | None = None) -> np.ndarray:
    """Raw conditions ``[W, ·]`` and one noise seed per window -> generated raw motion ``[W, T, D]``: the
    engine of ``generate``, the live stream and the evaluation, the steps after sampling of
    :mod:`~emogesture.pipeline.postprocess` 1-4 included (the seams, step 5, join a recording's windows).

    Window ``i`` draws its noise from its own generator, so results do not depend on ``batch_size``
    (see :func:`draw_seed`). The model runs in eval mode on its own device, with its ``diffusion.eta``;
    ``generation``: the settings (None: the model's own). ``sound [W]``: each window's sound weight in [0, 1]
    (:func:`~emogesture.pipeline.postprocess.residual_weights`; None: every window full of sound, as every
    window of the corpus is): a calibrated model's residual noise is scaled by it (none at all with
    ``residual=False``) and a quiet window settles (step 4). ``times``: wall seconds of ``sampling`` and
    ``motion decoder`` are added to it.
    """
    with maybe_stage(times, "sampling"):
        z = sample_latents(gesture, conditions, seeds, batch_size, generation, residual, progress, sound, precision)
    timing = conditions[-1] if gesture.config.hears_timing else None
    with maybe_stage(times, "motion decoder"):
        drawn = decode_latents(gesture, z, gesture.config.vae.frames, min(batch_size, DECODE_BATCH), timing,
                               precision, generation)
    return drawn if sound is None else settle_quiet_windows(drawn, sound, FPS)


def reconstruct_motion(gesture: LoadedModel, motion: np.ndarray, batch_size: int = 64,
                       timing: np.ndarray | None = None) -> np.ndarray:
    """Ground-truth raw features ``[W, T, D]`` -> their reconstruction through the motion prior
    (encoder mean, then decoder), raw features ``[W, T, D]``; ``timing``: the windows' timing stream,
    for a decoder that reads one."""
    return decode_latents(gesture, encode_motion(gesture, motion, batch_size), motion.shape[1],
                          min(batch_size, DECODE_BATCH), timing, generation=GenerationConfig())


def calibrate_residual(gesture: LoadedModel, conditions: list[np.ndarray], motion: np.ndarray, seed: int = 0,
                       batch_size: int = 64) -> dict:
    """Measure and store the residual-noise calibration of a gesture model (see
    :mod:`emogesture.diffusion.residual`) on windows it was not trained on.

    ``conditions``: raw conditions of those windows (as :func:`window_conditions`); ``motion``: their raw
    motion ``[W, T, D]``. The residual of a window is its motion's prior latent (encoder mean) minus the
    model's sample for its conditions (no residual noise, seeds from ``seed``). Sets
    ``gesture.model.latent_residual_tril`` and returns what was measured.
    """
    if len(motion) < 2:
        raise EmogestureError(f"residual calibration needs at least 2 held-out windows, got {len(motion)}")
    z_hat = sample_latents(gesture, conditions, window_seeds(seed, len(motion)), batch_size, residual=False)
    z = encode_motion(gesture, motion, batch_size).cpu().numpy()
    residuals = z - z_hat.cpu().numpy()
    factor, shrinkage = residual_factor(residuals)
    gesture.model.latent_residual_tril.copy_(torch.from_numpy(factor))
    return {"windows": int(len(motion)), "seed": int(seed), "residual_variance": float(residuals.var(0).mean()),
            "latent_variance": float(z.var(0).mean()), "shrinkage": float(shrinkage)}
