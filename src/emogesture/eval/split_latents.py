"""The speech latents and gesture-model conditions of every window of a prepared split (a windows cache), for
training, calibrating and evaluating models; the latents are cached in the windows cache."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from emogesture.audio import mfcc_from_log_mel
from emogesture.audio.timing import timing_stream
from emogesture.checkpoints import LoadedModel
from emogesture.data.cache import WindowsCache
from emogesture.errors import EmogestureError
from emogesture.motion import write_npz_atomic
from emogesture.pipeline.speech import EncodedWindows, SpeechLatentEncoder, array_digest


def network_digest(encoder: SpeechLatentEncoder) -> str:
    """12 hex digits naming the speech network's weights: its file's checksum, or where a perception calibration
    added arrays to the file, the checksum of the file it was copied from (the latents are the same)."""
    info = ((encoder.loaded.metadata.emotion_perception or {}).get("info") or {})
    return str(info.get("calibrated_from") or encoder.loaded.weights_sha256)[:12]


def encode_split(encoder: SpeechLatentEncoder, cache: WindowsCache, split: str,
                 batch_size: int | None = None) -> EncodedWindows:
    """Latents of every window of a prepared split, cached in the windows cache's ``latents/`` folder
    (never next to the model: the bundled model lives inside the installed package).

    The cache file is keyed by what the latents depend on: the model's weights checksum, the cache's
    statistics digest and a digest of the split's filterbank windows themselves, so a changed model
    or re-prepared windows (a rebuilt corpus, one changed take) are never served stale latents.
    """
    windows = cache.split(split)
    key = f"{network_digest(encoder)}_{cache.manifest['digest']}_{split}_{array_digest(windows.fbank)}"
    if encoder.precision != "fp32":
        key += f"_{encoder.precision}"
    device = torch.device(encoder.device).type
    if device != "cpu":  # another device's float32 differs in the last bits
        key += f"_{device}"
    path = Path(cache.root) / "latents" / f"{key}.npz"
    if path.is_file():
        with np.load(path) as z:
            return EncodedWindows(*(z[k] for k in EncodedWindows.stored))
    enc = encoder.encode_windows(windows.fbank, batch_size,
                                 renormalise=(cache.stats["fbank_mean"], cache.stats["fbank_std"]))
    write_npz_atomic(path, {k: getattr(enc, k) for k in EncodedWindows.stored}, overwrite=True)
    return enc


def mfcc_windows(fbank_windows, fbank_mean: float, fbank_std: float, batch: int = 256) -> np.ndarray:
    """Cached normalised fbank windows ``[W, 1024, n_mels]`` -> flattened pooled MFCCs ``[W, 13 * 128]``."""
    out = []
    for i in range(0, len(fbank_windows), batch):
        x = torch.from_numpy(np.asarray(fbank_windows[i : i + batch], np.float32)) * (2 * fbank_std) + fbank_mean
        out.append(mfcc_from_log_mel(x, 13, time_pool=8).flatten(1).numpy())
    return np.concatenate(out)


def window_conditions(variant: str, cache: WindowsCache, split: str,
                      speech: SpeechLatentEncoder | None, timing: bool = False) -> list[np.ndarray]:
    """Raw condition arrays of every window of a split: ``[c, e, s]`` latents ``[W, 256]`` each, or
    ``[mfcc [W, 13 * 128]]`` for the ``no_audio`` variant (its autoencoder runs inside the model);
    ``timing``: followed by the windows' timing stream ``[W, T, 2]`` (:func:`timing_stream`)."""
    w = cache.split(split)
    if variant == "no_audio":
        return [mfcc_windows(w.fbank, cache.stats["fbank_mean"], cache.stats["fbank_std"])]
    if speech is None:
        raise EmogestureError(f"variant {variant} needs a speech model for its conditions")
    enc = encode_split(speech, cache, split)
    out = [enc.content, enc.emotion, enc.style]
    if timing:
        out.append(timing_stream(w.fbank, frames=int(w.motion.shape[1])))
    return out


def model_conditions(gesture: LoadedModel, cache: WindowsCache, split: str,
                     speech: SpeechLatentEncoder | None) -> list[np.ndarray]:
    """:func:`window_conditions` of what ``gesture`` takes (its variant, its timing stream if any)."""
    return window_conditions(gesture.config.variant, cache, split, speech, timing=gesture.config.hears_timing)
