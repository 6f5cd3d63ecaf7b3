"""Speech -> SMPL-X gestures (docs/design.md, 'Generation and editing'): windows, latent diffusion, decoding,
the steps after sampling, editing.

Audio of any length is covered by 10-s windows every ``hop_seconds`` (7 s by default, so neighbours
overlap by 3 s); each window is drawn on its own, ``seam_candidates`` times, and the steps after sampling
(:mod:`emogesture.pipeline.postprocess`: residual noise, timing guidance, filters, quiet windows, seams)
make one sequence of ``round(duration * 30)`` frames. Their settings are the model's
:class:`~emogesture.models.generation.GenerationConfig`, replaced per call by ``generation=``.

Editing swaps latents (paper §3.4): the emotion and/or the speaker style of every window can come
from a second audio (window ``i`` takes that audio's window ``i mod n``), or the emotion from a label
(the per-class mean emotion latent stored with the model), blended with a weight.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass
from os import PathLike
from pathlib import Path

import numpy as np
import torch

from emogesture.assets import bundled_model_file
from emogesture.audio import TARGET_SAMPLE_RATE, check_speech, load_audio, window_activity, without_mean
from emogesture.checkpoints import LoadedModel, load_model
from emogesture.provenance import trained_with
from emogesture.config import from_dict
from emogesture.errors import EmogestureError, InputFileError
from emogesture.models.speech import LATENT_PARTS
from emogesture.models.generation import GenerationConfig
from emogesture.motion import MotionFeatureSpec, SkeletonBody, features_to_poses
from emogesture.pipeline.sampling import draw_seed, edit_emotion, generate_from_conditions, label_latents
from emogesture.pipeline.postprocess import (candidates_drawn, choose_seam_candidates, largest_joint_jumps,
                                             residual_weights, stitch)
from emogesture.pipeline.neutral_reference import NeutralReference, check_reference, reference_name
from emogesture.pipeline.perception import (auto_emotion, auto_style, fallback_style_of, heard_by_front_end, perceive,
                                           perception_of)
from emogesture.pipeline.perception_report import PerceivedEmotion
from emogesture.pipeline.speech import EncodedWindows, SpeechLatentEncoder
from emogesture.pipeline.timeline import EmotionTimeline, timeline_latents
from emogesture.runtime import StageTimes, hold_bf16_weights, maybe_stage, resolve_precision
from emogesture.types import EMOTIONS, SMPLXSequence

WINDOW_SECONDS = 10.0
#: Seconds between the starts of a long audio's windows, unless a model's settings say otherwise
#: (experiments/gesture_model/README.md, "Longer overlaps": 3-s overlaps make smoother seams than 2-s ones).
HOP_SECONDS = GenerationConfig().hop_seconds
#: Draws denoised together: each DDIM step is one batched denoiser call, so larger batches spread its
#: fixed cost; every draw has its own generator, so the result does not depend on the batch.
SAMPLING_BATCH = 256


@dataclass
class EditRequest:
    """What to take from elsewhere: emotion latents (from an audio or a label) and/or style latents."""

    emotion_from: np.ndarray | None = None  # [n, 256] emotion latents of another audio's windows
    emotion_label: str | None = None
    emotion_weight: float = 1.0  # 0 = the speech's own emotion, 1 = the target emotion
    style_from: np.ndarray | None = None  # [n, 256]
    #: emotion keyframes along the speech (in place of the other emotion edits; pipeline/timeline.py)
    emotion_timeline: EmotionTimeline | None = None


EMOTION_MODES = ("auto", "own")


class GesturePipeline:
    """A trained gesture model and its speech model, ready to animate speech. ``precision``: ``fp32``,
    ``bf16`` (autocast of the denoiser and the motion decoder) or ``auto`` (see :mod:`emogesture.runtime`)."""

    def __init__(self, gesture: LoadedModel, speech: SpeechLatentEncoder | None, device: str = "cpu",
                 precision: str = "fp32") -> None:
        self.loaded = gesture
        self.model = gesture.model.to(device).eval()
        self.speech = speech
        self.device = device
        self.precision = resolve_precision(precision, device)
        meta = gesture.metadata
        if meta.variant == "no_audio":
            raise EmogestureError(f"{gesture.path}: the no_audio ablation has no speech latents to edit or generate "
                                  "from in this pipeline")
        self.mean = np.asarray(meta.require("motion_mean", gesture.path), np.float32)
        self.std = np.asarray(meta.require("motion_std", gesture.path), np.float32)
        self.spec = from_dict(MotionFeatureSpec, meta.require("features", gesture.path))
        self.fps = meta.fps or 30
        #: how this pipeline generates unless a call says otherwise: the model's stored settings
        self.generation = gesture.generation or GenerationConfig()
        self.body = SkeletonBody()  # joint positions for choosing seam candidates

    @classmethod
    def from_run(cls, run: str | PathLike[str] | None = None, speech_run: str | PathLike[str] | None = None,
                 device: str = "cpu", precision: str = "fp32") -> "GesturePipeline":
        """A gesture model's run folder (or model JSON; None = the bundled model) and its speech model
        (default: the one the gesture model names, a path relative to the gesture model's folder or absolute).

        The models are loaded for this pipeline alone: under bf16 the Linear weights of the speech model,
        the denoiser and the motion prior are held in bf16 from here on, the denoiser's packed where
        oneDNN can (:func:`~emogesture.runtime.hold_bf16_weights`)."""
        gesture = load_model(run if run is not None else bundled_model_file("gesture"), "gesture", device=device)
        if speech_run is not None:
            speech = SpeechLatentEncoder.from_run(speech_run, device, precision)
        else:
            speech = SpeechLatentEncoder.of_gesture_model(gesture, device, precision)
        if not trained_with(gesture, speech.loaded):
            raise InputFileError(speech.loaded.path, "is not the speech model this gesture model was trained with")
        pipe = cls(gesture, speech, device, precision)
        hold_bf16_weights(pipe.precision, pipe.model.denoiser, pack=True)
        hold_bf16_weights(pipe.precision, pipe.model.prior)
        return pipe

    def load_speech(self, path: str | PathLike[str]) -> np.ndarray:
        """A speech file -> 16 kHz waveform ``[N]``; at least 1 s long. Silence is allowed (a calm
        animation); a note says so."""
        wave, sr = load_audio(path)
        if check_speech(wave, sr, path, allow_silence=True):
            print(f"note: {path} is silent; the animation will be calm", file=sys.stderr)
        return wave

    def joint_jumps(self, features: np.ndarray) -> np.ndarray:
        """Raw motion features ``[K, L, D]`` -> largest joint displacement between frames ``[K, L - 1]`` (m)."""
        with torch.no_grad():
            joints = self.body.forward_features(torch.from_numpy(np.ascontiguousarray(features, np.float32)), self.spec)
        return largest_joint_jumps(joints)

    def encode(self, waveform: np.ndarray, progress: Callable[[int], None] | None = None, times: StageTimes | None = None,
               parts: tuple[str, ...] = LATENT_PARTS, generation: GenerationConfig | None = None,
               perceived: bool = True, front_end: bool | None = None) -> tuple[EncodedWindows, list[float]]:
        """A 16 kHz waveform -> speech latents of its 10-s windows every ``hop_seconds`` of the settings,
        and their starts (s); ``parts``: the latents wanted (default all three; an edit
        source needs fewer); ``generation``: the settings (None: the pipeline's; their ``noise_suppression``
        and ``perception_semitones``); ``perceived`` False: only the latents are wanted, not what
        :meth:`perceive` reads, so the recording is heard once; ``front_end``: whether the front end trained on
        real speech hears the windows too (None: when ``perceived``)."""
        settings = generation or self.generation
        return self.speech.encode(waveform, TARGET_SAMPLE_RATE, settings.hop_seconds, progress, times, parts,
                                  noise_suppression=settings.noise_suppression,
                                  perception_semitones=settings.perception_semitones if perceived else 0.0,
                                  front_end=perceived if front_end is None else front_end)

    def edit_source_parts(self, edit: str) -> tuple[str, ...]:
        """The latents a second recording must give for ``edit`` (``emotion`` or ``style``): its emotion
        (and its style, which ``--emotion auto`` and the perception report read), or its style."""
        if edit == "style":
            return ("style",)
        if edit != "emotion":
            raise EmogestureError(f"unknown edit source {edit!r}; known: emotion, style")
        return ("emotion", "style") if perception_of(self.speech) is not None else ("emotion",)

    def perceive(self, enc: EncodedWindows, starts_s: list[float], source: str) -> PerceivedEmotion:
        """What emotion the speech model hears in each window of an encoded audio, and how far it trusts it."""
        return perceive(enc, starts_s, perception_of(self.speech), source)

    def perceive_against(self, encoded: tuple[EncodedWindows, list[float]], source: str,
                         reference: NeutralReference | None
                         ) -> tuple[PerceivedEmotion, tuple[EncodedWindows, list[float]]]:
        """What is heard in an encoded audio (:meth:`perceive`) and the encoding the gesture model is to be
        given: with a neutral ``reference`` of the speaker, heard both alone and against it, and the windows
        moved by it (:mod:`emogesture.pipeline.neutral_reference`); without one, the audio's own."""
        if reference is None:
            return self.perceive(*encoded, source), encoded
        enc, starts = encoded
        relative = reference.relative(enc)
        heard = perceive(enc, starts, perception_of(self.speech), source, relative=relative,
                         neutral_reference=reference.source)
        return heard, (relative, starts)

    def load_neutral_reference(self, path: str | PathLike[str],
                               span: tuple[float, float] | None = None) -> np.ndarray:
        """A recording of the speaker speaking without emotion (with ``span``, its seconds ``start`` to ``end``)
        -> 16 kHz waveform ``[N]``; a one-line error for one that cannot be a neutral reference (too short,
        silent; :func:`check_reference`)."""
        wave, _ = load_audio(path, remove_mean=span is None)
        if span is not None:
            start, end = span
            seconds = len(wave) / TARGET_SAMPLE_RATE
            if end > seconds + 1e-6:
                raise InputFileError(path, f"{seconds:.1f} s long; the neutral span {start:g}-{end:g} s lies beyond "
                                     "its end")
            wave = wave[int(round(start * TARGET_SAMPLE_RATE)):int(round(end * TARGET_SAMPLE_RATE))]
            wave = without_mean(wave)  # heard as a recording of those seconds would be
        check_reference(wave, reference_name(path, span))
        return wave

    def neutral_reference(self, waveform: np.ndarray, source: str, generation: GenerationConfig | None = None,
                          perceived: bool = True) -> NeutralReference:
        """The neutral reference (:mod:`emogesture.pipeline.neutral_reference`) of a 16 kHz waveform ``[N]``
        of the speaker speaking without emotion, heard as the speech is (the same settings; ``perceived``
        False: heard once, for speech that is itself heard once, as a stream's)."""
        check_reference(waveform, source)
        enc, _ = self.encode(waveform, parts=("emotion",), generation=generation, perceived=perceived)
        return NeutralReference.of(enc, perception_of(self.speech), source)

    def conditions(self, enc: EncodedWindows, edit: EditRequest | None, emotion_mode: str = "auto",
                   starts_s: list[float] | None = None, duration_s: float | None = None) -> list[np.ndarray]:
        """Condition latents ``[c, e, s]`` ``[W, 256]`` of encoded windows: ``emotion_mode`` ``auto``
        blends untrusted emotion latents toward neutral and the style latents of an unfamiliar voice toward
        the model's fallback style (:mod:`emogesture.pipeline.perception`), ``own`` keeps them; then the
        edit, if any. A model that hears timing also gets the windows' own timing
        stream ``[W, 300, 2]`` (never the edit source's). An emotion timeline needs the windows' start
        seconds ``starts_s`` and the recording's ``duration_s``."""
        if emotion_mode not in EMOTION_MODES:
            raise EmogestureError(f"emotion mode {emotion_mode!r}: choose one of {', '.join(EMOTION_MODES)}")
        c, e, s = enc.content.copy(), enc.emotion.copy(), enc.style.copy()
        perception = perception_of(self.speech)
        if emotion_mode == "auto":
            e, s = (auto_emotion(e, s, perception, heard_by_front_end(enc, perception)),
                    auto_style(s, perception, fallback_style_of(self.loaded)))
        if edit is not None:
            n = len(c)
            target = None
            if edit.emotion_timeline is not None:
                if starts_s is None or duration_s is None:
                    raise EmogestureError("an emotion timeline needs the windows' start times and the duration")
                shares = edit.emotion_timeline.shares(starts_s, WINDOW_SECONDS, duration_s)
                e = timeline_latents(edit.emotion_timeline, shares, enc.emotion,
                                     auto_emotion(enc.emotion, enc.style, perception,
                                                  heard_by_front_end(enc, perception)),
                                     self.loaded.metadata.emotion_latent_means or {})
            elif edit.emotion_from is not None:
                target = edit.emotion_from[np.arange(n) % len(edit.emotion_from)]
            elif edit.emotion_label is not None:
                if edit.emotion_label not in EMOTIONS:
                    raise EmogestureError(f"unknown emotion {edit.emotion_label!r}; known: {', '.join(EMOTIONS)}")
                target = label_latents(self.loaded, np.full(n, EMOTIONS.index(edit.emotion_label)))
            if target is not None:
                e = edit_emotion(e, target, edit.emotion_weight)
            if edit.style_from is not None:
                s = edit.style_from[np.arange(n) % len(edit.style_from)].astype(np.float32)
        if self.loaded.config.hears_timing:
            if enc.timing is None:
                raise EmogestureError(f"{self.loaded.path}: this model hears the speech's timing; encode the audio "
                                      "with SpeechLatentEncoder.encode (it computes the timing stream)")
            return [c, e, s, enc.timing]
        return [c, e, s]

    def generate_windows(self, conditions: list[np.ndarray], seeds: list[int],
                         progress: Callable[[int], None] | None = None,
                         sound: np.ndarray | None = None, times: StageTimes | None = None,
                         generation: GenerationConfig | None = None) -> np.ndarray:
        """Condition latents ``[W, 256]`` x3 and one seed per window -> raw features ``[W, T, D]``, the steps
        after sampling up to the seams included (:func:`~emogesture.pipeline.sampling.generate_from_conditions`;
        ``sound [W]``: the windows' sound weights; ``generation``: None = the pipeline's)."""
        return generate_from_conditions(self.loaded, conditions, seeds, SAMPLING_BATCH, generation or self.generation,
                                        progress=progress, sound=sound, precision=self.precision, times=times)

    def settings(self, generation: GenerationConfig | None = None) -> GenerationConfig:
        """The settings of one call: ``generation``, or the pipeline's (:attr:`generation`) when None. A call
        changes one setting with ``dataclasses.replace(pipe.generation, seam_candidates=1)``."""
        return generation or self.generation

    def draw_windows(self, waveform: np.ndarray, *, edit: EditRequest | None = None, seed: int = 0,
                     samples: int = 1, emotion_mode: str = "auto", encoded: tuple[EncodedWindows, list[float]] | None = None,
                     progress: Callable[[int], None] | None = None, times: StageTimes | None = None,
                     generation: GenerationConfig | None = None) -> tuple[np.ndarray, list[int]]:
        """A 16 kHz waveform ``[N]`` -> every window drawn, before stitching: raw motion features
        ``[samples, W, K, T, D]`` (``K`` candidates per window, see :func:`candidates_drawn`) and the
        windows' start frames. Arguments as in :meth:`generate`.

        Every sample's every candidate of every window is drawn in one batched pass (each from its own
        generator, so the result does not depend on how many are drawn together).
        """
        settings = self.settings(generation)
        if encoded is None:
            # heard once; by the front end too where ``auto`` blends toward what it hears, as ``generate`` does
            encoded = self.encode(waveform, times=times, generation=settings, perceived=False,
                                  front_end=emotion_mode == "auto")
        enc, starts_s = encoded
        conds = self.conditions(enc, edit, emotion_mode, starts_s, len(waveform) / TARGET_SAMPLE_RATE)
        starts = [int(round(s * self.fps)) for s in starts_s]
        n = len(starts)
        k_cand = candidates_drawn(n, settings.seam_candidates)
        draws = [(k, i, c) for k in range(samples) for i in range(n) for c in range(k_cand)]
        rows = np.array([i for _, i, _ in draws])
        picked = [c[rows] for c in conds]
        weights = residual_weights(window_activity(waveform, TARGET_SAMPLE_RATE, starts_s))[rows]
        # candidate 0 of window i keeps the seed it has with one candidate
        seeds = [draw_seed(seed, k, i, c) for k, i, c in draws]
        drawn = self.generate_windows(picked, seeds, progress, weights, times, settings)
        return drawn.reshape(samples, n, k_cand, *drawn.shape[1:]), starts

    def to_sequence(self, feats: np.ndarray) -> SMPLXSequence:
        """Raw motion features ``[T, D]`` -> an SMPL-X sequence of ``T`` frames."""
        poses, trans = features_to_poses(torch.from_numpy(np.ascontiguousarray(feats, np.float32)), self.spec)
        trans_np = trans.numpy() if trans is not None else np.zeros((len(feats), 3), np.float32)
        return SMPLXSequence(poses=poses.numpy(), trans=trans_np, fps=self.fps)

    def generate(self, waveform: np.ndarray, *, edit: EditRequest | None = None, seed: int = 0, samples: int = 1,
                 emotion_mode: str = "auto",
                 encoded: tuple[EncodedWindows, list[float]] | None = None,
                 progress: Callable[[int], None] | None = None, times: StageTimes | None = None,
                 generation: GenerationConfig | None = None) -> list[SMPLXSequence]:
        """A 16 kHz waveform ``[N]`` -> ``samples`` SMPL-X sequences of ``round(N / 16000 * 30)`` frames.

        ``generation``: the settings of this call (None: the model's; :attr:`generation`), among them
        ``seam_candidates`` (samples drawn per window, one kept per window so that the worst seam moves
        least; 1 = every window independent) and ``hop_seconds`` (seconds between window starts).
        ``emotion_mode``: see :meth:`conditions`. ``encoded``: the waveform's ``encode(waveform,
        hop_seconds)`` when already computed. ``progress(n)`` is called as ``n`` more windows are drawn.
        ``times``: wall seconds per stage are added to it (``fbank``, ``speech encoders``, ``sampling``,
        ``motion decoder``, ``seams and poses``). The windows are drawn by :meth:`draw_windows`.
        """
        drawn, starts = self.draw_windows(waveform, edit=edit, seed=seed, samples=samples, emotion_mode=emotion_mode,
                                          encoded=encoded, progress=progress, times=times, generation=generation)
        num_frames = int(round(len(waveform) / TARGET_SAMPLE_RATE * self.fps))
        with maybe_stage(times, "seams and poses"):
            return [self.to_sequence(stitch(choose_seam_candidates(candidates, starts, self.joint_jumps), starts,
                                            num_frames)) for candidates in drawn]

    def encode_file_latents(self, path: str | PathLike[str]) -> EncodedWindows:
        """Latents of another audio file (for ``--emotion-from`` / ``--style-from``)."""
        enc, _ = self.encode(self.load_speech(path), perceived=False)
        return enc


def output_stem(speech: Path, seed: int, sample: int, edit_tag: str = "") -> str:
    """The file name, without extension, of one generated sample: ``<speech stem><edit>_seed<seed>_<sample>``."""
    return f"{speech.stem}{edit_tag}_seed{seed}_{sample}"


def bundle_generation(speech_model: str | PathLike[str]) -> GenerationConfig:
    """The generation settings of the bundle a speech model file belongs to (the ``gesture.json`` beside
    it), so that its perception is measured as ``generate`` hears with it; the defaults without one."""
    beside = Path(speech_model).parent / "gesture.json" if str(speech_model).endswith(".json") else None
    if beside is not None and beside.exists():
        return GesturePipeline.from_run(beside).generation
    return GenerationConfig()
