"""Audio -> (content, emotion, style) latents with a trained speech disentanglement model."""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from dataclasses import dataclass
from os import PathLike
from pathlib import Path

import numpy as np
import torch

from emogesture.audio import (TARGET_SAMPLE_RATE, FbankConfig, NoiseSuppression, digital_silence, fbank_windows,
                              fill_digital_silence, kaldi_fbank, normalise_fbank, normalise_recording, suppress_noise,
                              suppression_strength, window_starts)
from emogesture.audio.timing import timing_stream
from emogesture.checkpoints import LoadedModel, load_model
from emogesture.config import from_dict
from emogesture.models.perception import EmotionPerception
from emogesture.models.speech import LATENT_PARTS, AudioLatents
from emogesture.pipeline.voice_features import front_end_installed, hearing_plan, whisper_features
from emogesture.runtime import StageTimes, autocast, bf16_weights, hold_bf16_weights, maybe_stage, resolve_precision

FBANK_RATE = 100  # frames per second


@dataclass
class EncodedWindows:
    """Latents of ``W`` windows: ``content/emotion/style [W, 256]``, logits ``[W, 8]`` / ``[W, n]``, and
    (from :meth:`SpeechLatentEncoder.encode`) the windows' timing stream ``[W, 300, 2]`` and how much of the
    recording's steady noise was taken out before it was heard (0–1, :mod:`emogesture.audio.noise`)."""

    content: np.ndarray
    emotion: np.ndarray
    style: np.ndarray
    emotion_logits: np.ndarray
    speaker_logits: np.ndarray
    timing: np.ndarray | None = None
    noise_suppressed: float = 0.0
    #: seconds of digital silence heard as the recording's own quiet (:func:`emogesture.audio.fill_digital_silence`)
    digital_silence_s: float = 0.0
    #: the same windows heard again with the voice moved in pitch (``perception_semitones`` of
    #: :meth:`SpeechLatentEncoder.encode`): emotion latents ``[S, W, 256]`` and logits ``[S, W, 8]``; None: once
    shifted_emotion: np.ndarray | None = None
    shifted_logits: np.ndarray | None = None
    #: the windows heard by the front end trained on real speech (:mod:`emogesture.pipeline.voice_features`),
    #: ``[W, 768]``, where the perception reads it and ``encode`` was asked to hear it; else None
    heard_features: np.ndarray | None = None

    #: What the per-split latents cache stores (the timing stream is recomputed from the windows).
    stored = ("content", "emotion", "style", "emotion_logits", "speaker_logits")

    @property
    def latents(self) -> AudioLatents:
        return AudioLatents(*(torch.from_numpy(x) for x in (self.content, self.emotion, self.style)))


#: On a CPU the speech encoders take as many windows per batch as keep their widest activation (tokens ×
#: MLP width × windows) within this many numbers: the paper encoder (1214 tokens × 3072) takes 3. Larger
#: batches leave the caches: one paper encoder in bf16 took 0.79–0.83 s per window in batches of 2 or 3,
#: 0.82–0.91 in batches of 4 and 0.92–1.20 in batches of 9 (2 cores, interleaved). GPUs take
#: :data:`MAX_ENCODER_BATCH`, the most any device takes.
ENCODER_BATCH_NUMBERS = 12_000_000
MAX_ENCODER_BATCH = 32


class SpeechLatentEncoder:
    """A frozen speech model in eval mode: deterministic, batched, no gradients; ``precision`` ``fp32``,
    ``bf16`` (autocast) or ``auto`` (see :mod:`emogesture.runtime`). A recording it encodes has its digital
    silence (exact zeros) heard as the recording's own quiet (``fill_digital_silence`` False: as it is) and its
    steady background noise taken out where it is noisy (:mod:`emogesture.audio.noise`; ``noise_suppression``
    None: never)."""

    def __init__(self, loaded: LoadedModel, device: str = "cpu", precision: str = "fp32") -> None:
        self.loaded = loaded
        self.model = loaded.model.to(device).eval()
        self.device = device
        self.precision = resolve_precision(precision, device)
        meta = loaded.metadata
        self.fbank_mean = float(meta.require("fbank_mean", loaded.path))
        self.fbank_std = float(meta.require("fbank_std", loaded.path))
        prep = meta.prepare_config or {}
        self.fbank_config = from_dict(FbankConfig, prep["fbank"]) if "fbank" in prep else FbankConfig()
        self.recording_norm = prep.get("recording_norm", "none")
        self.window_frames = loaded.config.encoder.input_frames
        self.noise_suppression: NoiseSuppression | None = NoiseSuppression()
        self.fill_digital_silence = True
        #: the emotion perception its file stores (None: never calibrated; :mod:`emogesture.models.perception`)
        self.perception = (EmotionPerception.from_state(meta.emotion_perception, loaded.tensors)
                           if meta.emotion_perception else None)

    @classmethod
    def from_run(cls, path: str | PathLike[str], device: str = "cpu", precision: str = "fp32") -> "SpeechLatentEncoder":
        """The speech model of a run folder or model JSON, loaded for this encoder alone: under bf16 its
        Linear weights are held in bf16 from here on (:func:`~emogesture.runtime.hold_bf16_weights`)."""
        encoder = cls(load_model(path, "speech", device=device), device, precision)
        hold_bf16_weights(encoder.precision, encoder.model)
        return encoder

    @classmethod
    def of_gesture_model(cls, gesture: LoadedModel, device: str = "cpu", precision: str = "fp32"
                         ) -> "SpeechLatentEncoder":
        """The speech model a gesture model names: an absolute path, or one relative to the gesture
        model's folder (as in the bundled model)."""
        from emogesture.errors import InputFileError

        name = gesture.metadata.speech_model
        if name is None:
            raise InputFileError(gesture.path, "names no speech model; pass one")
        return cls.from_run(Path(gesture.path).parent / name, device, precision)

    @property
    def speakers(self) -> list[int]:
        return list(self.loaded.metadata.require("speakers", self.loaded.path))

    @property
    def batch_size(self) -> int:
        """Windows per batch of :meth:`encode_windows` by default (see :data:`ENCODER_BATCH_NUMBERS`)."""
        if torch.device(self.device).type != "cpu":
            return MAX_ENCODER_BATCH
        enc = self.loaded.config.encoder
        per_window = (enc.num_prefix + enc.num_patches) * int(enc.width * enc.mlp_ratio)
        return max(1, min(MAX_ENCODER_BATCH, ENCODER_BATCH_NUMBERS // per_window))

    @torch.inference_mode()
    def encode_windows(self, windows: np.ndarray, batch_size: int | None = None,
                       renormalise: tuple[float, float] | None = None, progress: Callable[[int], None] | None = None,
                       parts: tuple[str, ...] = LATENT_PARTS) -> EncodedWindows:
        """Normalised fbank windows ``[W, 1024, n_mels]`` -> :class:`EncodedWindows`.

        ``renormalise=(mean, std)``: the windows were normalised with these statistics (another cache's);
        they are mapped to the model's own statistics first. ``parts``: the latents wanted; the encoders
        of the others are skipped and their arrays are ``[W, 0]`` (see ``SpeechDisentangler.encode``).
        ``batch_size``: windows per batch (default :attr:`batch_size`).
        """
        batch_size = batch_size or self.batch_size
        stores: list[list[np.ndarray]] = [[] for _ in range(5)]
        with bf16_weights(self.precision, self.model):
            for i in range(0, len(windows), batch_size):
                x = torch.from_numpy(np.asarray(windows[i : i + batch_size], np.float32)).to(self.device)
                if renormalise is not None and renormalise != (self.fbank_mean, self.fbank_std):
                    raw = x * (2 * renormalise[1]) + renormalise[0]
                    x = (raw - self.fbank_mean) / (2 * self.fbank_std)
                with autocast(self.precision, self.device):
                    enc = self.model.encode(x, parts=parts)
                for store, value in zip(stores, enc):
                    store.append(value.float().cpu().numpy())
                if progress is not None:
                    progress(len(x))
        return EncodedWindows(*(np.concatenate(p) if p else np.zeros((0, 0), np.float32) for p in stores))

    def encode(self, waveform: np.ndarray, sample_rate: int = TARGET_SAMPLE_RATE, hop_seconds: float = 5.0,
               progress: Callable[[int], None] | None = None, times: StageTimes | None = None,
               parts: tuple[str, ...] = LATENT_PARTS, noise_suppression: bool = True,
               perception_semitones: float = 0.0, front_end: bool = False) -> tuple[EncodedWindows, list[float]]:
        """A 16 kHz waveform ``[N]`` of any length -> latents per 10-s window, and the window starts (s).
        ``times``: wall seconds of the stages ``fbank`` and ``speech encoders`` are added to it;
        ``parts``: the latents wanted (an edit source needs only its emotion or its style);
        ``noise_suppression``: False hears a noisy recording with its noise (class docstring);
        ``perception_semitones`` > 0: the emotion encoder hears the recording twice more, its voice (pitch and
        formants) moved that many semitones up and down with the tempo kept, into
        ``shifted_emotion``/``shifted_logits`` (what :func:`emogesture.pipeline.perception.perceive` averages);
        the latents themselves are the recording's own. ``front_end``: where the perception has a read-out of
        the front end trained on real speech and its packages are installed, the windows are heard by it too
        (``heard_features``; one every 20 s heard, those between interpolated:
        :func:`~emogesture.pipeline.voice_features.hearing_plan`)."""
        if sample_rate != self.fbank_config.sample_rate:
            raise ValueError(f"expected {self.fbank_config.sample_rate} Hz audio, got {sample_rate}")
        if perception_semitones < 0:
            raise ValueError(f"perception_semitones must be ≥ 0, got {perception_semitones}")
        starts = window_starts(len(waveform) / sample_rate, 10.0, hop_seconds).tolist()
        with maybe_stage(times, "fbank"):
            windows, timing, strength, silence_s = self._windows_of(waveform, starts, noise_suppression)
        with maybe_stage(times, "speech encoders"):
            enc = self.encode_windows(windows, progress=progress, parts=parts)
        enc.timing, enc.noise_suppressed, enc.digital_silence_s = timing, strength, silence_s
        hears = (front_end and self.perception is not None and self.perception.heard is not None
                 and front_end_installed())
        if hears:  # every window: both read-outs are multiplied (pipeline.perception.heard_probabilities)
            heard, weights = hearing_plan(np.ones(len(starts), bool), hop_seconds)
            if len(heard):
                on_cpu = torch.device(self.device).type == "cpu"  # the front end runs on the CPU
                with maybe_stage(times, "voice features"), \
                        whisper_features(self.precision if on_cpu else "fp32") as hearer:
                    features = hearer(waveform, [starts[i] for i in heard]) if hearer is not None else None
                if features is not None:
                    enc.heard_features = (weights @ features).astype(np.float32)
        # the pitch-moved hearings serve the latents' own read-out, which the front end's replaces
        if perception_semitones > 0 and "emotion" in parts and not hears:
            from emogesture.audio.wave_augment import voice_shift  # scipy's signal module: a second of start-up

            shifted = []
            for semitones in (perception_semitones, -perception_semitones):
                with maybe_stage(times, "fbank"):
                    moved = voice_shift(np.asarray(waveform, np.float64), semitones).astype(np.float32)
                    frames = [int(round(s * FBANK_RATE)) for s in starts]
                    heard = self._heard_windows(self._filled(kaldi_fbank(moved, self.fbank_config))[0], frames,
                                                strength)
                with maybe_stage(times, "speech encoders"):
                    shifted.append(self.encode_windows(heard, parts=("emotion",)))
            enc.shifted_emotion = np.stack([e.emotion for e in shifted])
            enc.shifted_logits = np.stack([e.emotion_logits for e in shifted])
        return enc, starts

    def _windows_of(self, waveform: np.ndarray, starts: list[float], noise_suppression: bool = True,
                    raw_fbank: torch.Tensor | None = None) -> tuple[np.ndarray, np.ndarray, float, float]:
        """A 16 kHz recording's windows starting at ``starts`` (s) as the encoders hear them ``[W, T, n_mels]``,
        their timing stream, the share of its steady noise taken out and the seconds of digital silence filled;
        ``raw_fbank``: the recording's filterbank where the caller has it (:func:`~emogesture.audio.rolled_fbank`)."""
        frames = [int(round(s * FBANK_RATE)) for s in starts]
        raw = kaldi_fbank(waveform, self.fbank_config) if raw_fbank is None else raw_fbank
        fb, silence_s = self._filled(raw)
        strength = 0.0
        if noise_suppression and self.noise_suppression is not None:
            strength = suppression_strength(fb, self.noise_suppression)
        windows = self._heard_windows(fb, frames, strength)
        return windows, timing_stream(windows, lengths=[len(fb) - f for f in frames]), strength, silence_s

    def encode_each(self, waveforms: list[np.ndarray], noise_suppression: bool = True,
                    raw_fbanks: list[torch.Tensor | None] | None = None) -> list[EncodedWindows]:
        """Several 16 kHz recordings of at most 10 s each (a live stream's newest window, say) -> the latents of
        each's one window, the encoders run once for all of them (as :meth:`encode` hears each, without its
        extra hearings); ``raw_fbanks``: each recording's filterbank where the caller has it (None: computed)."""
        raw_fbanks = raw_fbanks or [None] * len(waveforms)
        heard = [self._windows_of(np.asarray(w, np.float32), [0.0], noise_suppression, fb)
                 for w, fb in zip(waveforms, raw_fbanks)]
        enc = self.encode_windows(np.concatenate([h[0] for h in heard]))
        out = []
        for k, (_, timing, strength, silence_s) in enumerate(heard):
            one = EncodedWindows(*(getattr(enc, name)[k:k + 1] for name in EncodedWindows.stored))
            one.timing, one.noise_suppressed, one.digital_silence_s = timing, strength, silence_s
            out.append(one)
        return out

    def _filled(self, fb: torch.Tensor) -> tuple[torch.Tensor, float]:
        """A recording's raw fbank with its digital silence filled (unless ``fill_digital_silence`` is off), and
        the seconds filled."""
        if not self.fill_digital_silence:
            return fb, 0.0
        filled = fill_digital_silence(fb)
        return filled, (float(digital_silence(fb).sum()) / FBANK_RATE if filled is not fb else 0.0)

    def _heard_windows(self, fb: np.ndarray | torch.Tensor, frames: list[int], strength: float) -> np.ndarray:
        """A recording's raw fbank ``[F, n_mels]`` as the encoders hear it, cut into windows ``[W, T, n_mels]``
        starting at ``frames``: its noise taken out by ``strength`` (0: not at all), measured against itself
        (``recording_norm``) and normalised with the model's statistics."""
        if strength > 0:
            fb = suppress_noise(fb, self.noise_suppression, strength)
        fb = normalise_recording(fb, self.recording_norm)
        fb = normalise_fbank(fb, self.fbank_mean, self.fbank_std).numpy()
        return np.asarray(fbank_windows(fb, frames, self.window_frames))


def array_digest(array: np.ndarray, rows: int = 64) -> str:
    """A short content digest (BLAKE2b, 16 hex digits) of an array, its shape and dtype included, read
    ``rows`` leading-axis rows at a time (memory-mapped arrays are not loaded whole)."""
    h = hashlib.blake2b(digest_size=8)
    h.update(f"{array.shape}{array.dtype}".encode())
    for i in range(0, len(array), rows):
        h.update(np.ascontiguousarray(array[i : i + rows]).tobytes())
    return h.hexdigest()
