"""Speech -> SMPL-X gestures (docs/design.md, 'Generation and editing'): windows, latent diffusion, decoding,
seamless stitching, editing.

Audio of any length is covered by 10-s windows every ``hop_seconds`` (default :data:`HOP_SECONDS`,
7 s, so neighbours overlap by 3 s); each window is generated on its own and the overlaps are cross-faded in the 6D
rotation features (a raised-cosine ramp, re-orthonormalised when turned into rotations). Two
independent samples can disagree in the overlap, and a cross-fade between poses far apart is a fast
movement; so every window is drawn ``seam_candidates`` times (default 4, each from its own seed) and
one candidate per window is kept, chosen together over the whole audio: the sequence whose worst seam
moves least, a seam's cost being the largest frame-to-frame joint displacement (licence-free skeleton)
of its cross-fade, over the overlap and the frames on either side. Output length is
``round(duration * 30)`` frames.

A calibrated model's residual noise (the strokes the per-window audio latents leave open, see
:mod:`emogesture.diffusion.residual`) is weighted per window by how much of it holds sound
(:data:`FULL_RESIDUAL_ACTIVITY`): silence gets none. A window with less sound than that also settles
(:func:`settle_quiet_windows`): its motion is blended, by the same weight, toward itself smoothed over
:data:`SETTLE_SIGMA_SECONDS`, so a silent stretch gives a calm animation that keeps the posture and a slow
sway. (The training speech has no long pauses, so a model's motion for silence is whatever it makes of
speech it never heard; a model trained on corpus version 5 moves its wrists at 0.11 m/s there, 60 % of
its speed on speech.)

Editing swaps latents (paper §3.4): the emotion and/or the speaker style of every window can come
from a second audio (window ``i`` takes that audio's window ``i mod n``), or the emotion from a label
(the per-class mean emotion latent stored with the model), blended with a weight.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from os import PathLike
from pathlib import Path

import numpy as np
import torch
from scipy.ndimage import gaussian_filter1d

from emogesture.assets import bundled_model_file
from emogesture.audio import TARGET_SAMPLE_RATE, check_speech, load_audio, window_activity
from emogesture.checkpoints import LoadedModel, load_model
from emogesture.config import from_dict
from emogesture.errors import EmogestureError, InputFileError
from emogesture.models.speech import LATENT_PARTS
from emogesture.motion import MotionFeatureSpec, SkeletonBody, features_to_poses
from emogesture.pipeline.conditions import decode_latents, sample_latents
from emogesture.pipeline.perception import PerceivedEmotion, auto_emotion, auto_style, perceive, perception_of
from emogesture.pipeline.speech import EncodedWindows, SpeechLatentEncoder
from emogesture.runtime import StageTimes, hold_bf16_weights, maybe_stage, resolve_precision
from emogesture.types import SMPLXSequence

WINDOW_SECONDS = 10.0
#: Seconds between the starts of a long audio's windows. 7 s (3-s overlaps) rather than 8 s (2-s): on
#: four 65-s stretches of the val texts the seams' 99th-percentile jump over that inside windows fell
#: from 0.85-1.11 to 0.76-0.97 (wrist speed unchanged), for one window in eight more; 6 s did no
#: better (experiments/README.md, "Longer overlaps").
HOP_SECONDS = 7.0
#: Draws denoised together: each DDIM step is one batched denoiser call, so larger batches spread its
#: fixed cost; every draw has its own generator, so the result does not depend on the batch.
SAMPLING_BATCH = 256
#: Seams whose cross-fades are costed in one forward kinematics (:func:`choose_seam_candidates`): with 4
#: candidates a window, 16 seams are 256 cross-fades of ~90 frames, about 150 MB of work space.
SEAMS_PER_BATCH = 16
#: Share of a window's frames with sound (:func:`emogesture.audio.window_activity`) from which its
#: residual noise is added in full; below it the noise shrinks linearly to none for silence.
FULL_RESIDUAL_ACTIVITY = 0.5
#: Standard deviation (s) of the Gaussian over time toward which a quiet window's motion settles.
SETTLE_SIGMA_SECONDS = 1.0


def settle_quiet_windows(features: np.ndarray, weights: np.ndarray, fps: float) -> np.ndarray:
    """Drawn windows' motion features ``[W, T, D]`` with their sound weights ``[W]`` in [0, 1] (1: at
    least :data:`FULL_RESIDUAL_ACTIVITY` of the window holds sound) -> the same, each window blended by
    ``1 − weight`` toward itself smoothed over time (a Gaussian of :data:`SETTLE_SIGMA_SECONDS`): a
    silent window keeps its slow posture changes and loses its strokes; a window with speech is unchanged."""
    quiet = np.asarray(weights, np.float64) < 1.0
    if not quiet.any():
        return features
    out = features.copy()
    smooth = gaussian_filter1d(features[quiet].astype(np.float64), SETTLE_SIGMA_SECONDS * fps, axis=1, mode="nearest")
    w = np.asarray(weights, np.float64)[quiet][:, None, None]
    out[quiet] = (w * features[quiet] + (1.0 - w) * smooth).astype(features.dtype)
    return out


@dataclass
class EditRequest:
    """What to take from elsewhere: emotion latents (from an audio or a label) and/or style latents."""

    emotion_from: np.ndarray | None = None  # [n, 256] emotion latents of another audio's windows
    emotion_label: str | None = None
    emotion_weight: float = 1.0  # 0 = the speech's own emotion, 1 = the target emotion
    style_from: np.ndarray | None = None  # [n, 256]


EMOTION_MODES = ("auto", "own")


def crossfade_ramp(overlap: int) -> np.ndarray:
    """The incoming window's weights ``[overlap]`` over an overlap (raised cosine from 0 to 1)."""
    return 0.5 - 0.5 * np.cos(np.pi * (np.arange(overlap) + 0.5) / overlap)


def crossfade_weights(num_frames: int, starts: list[int], window: int) -> np.ndarray:
    """Per-window frame weights ``[W, window]`` that sum to 1 over overlapping windows.

    Each window ramps up (raised cosine) over its overlap with the previous window and down over its
    overlap with the next one.
    """
    w = np.ones((len(starts), window), np.float64)
    for i in range(1, len(starts)):
        overlap = starts[i - 1] + window - starts[i]
        if overlap > 0:
            ramp = crossfade_ramp(overlap)
            w[i, :overlap] *= ramp
            w[i - 1, window - overlap :] *= 1.0 - ramp
    return w


def largest_joint_jumps(joints: np.ndarray | torch.Tensor) -> np.ndarray:
    """Joint positions ``[..., T, J, 3]`` -> the largest joint displacement between frames ``[..., T - 1]``.

    The square root is taken of the largest squared displacement (the same number), with the three
    coordinates summed apart: an order of magnitude faster than a norm over a last axis of three."""
    joints = torch.as_tensor(joints)
    step = (joints[..., 1:, :, :] - joints[..., :-1, :, :]).square_()
    return (step[..., 0] + step[..., 1] + step[..., 2]).amax(-1).sqrt_().numpy()


def feature_jumps(frames: np.ndarray) -> np.ndarray:
    """Frame-to-frame change ``[K, L, D] -> [K, L - 1]`` (Euclidean norm over the features)."""
    return np.linalg.norm(np.diff(frames, axis=1), axis=-1)


def _crossfade_frames(previous: np.ndarray, incoming: np.ndarray, overlap: int) -> np.ndarray:
    """Every cross-fade of candidates ``previous [Ka, T, D]`` into ``incoming [Kb, T, D]`` over ``overlap``
    frames, with the frame on either side: ``[Ka · Kb, L, D]`` (``L = overlap + 2``, or ``overlap`` when the
    windows overlap whole)."""
    ka, kb, t, d = len(previous), len(incoming), previous.shape[1], previous.shape[2]
    frames = np.empty((ka, kb, overlap + 2 * (overlap < t), d), np.result_type(previous, incoming))
    faded = frames[:, :, 1: overlap + 1] if overlap < t else frames
    if overlap < t:  # the frame before the overlap (previous window) and after it (the incoming one)
        frames[:, :, 0] = previous[:, None, t - overlap - 1]
        frames[:, :, -1] = incoming[None, :, overlap]
    ramp = crossfade_ramp(overlap).astype(frames.dtype)[None, None, :, None]
    np.multiply(1 - ramp, previous[:, None, t - overlap:], out=faded)
    faded += ramp * incoming[None, :, :overlap]
    return frames.reshape(ka * kb, *frames.shape[2:])


def seam_costs(previous: np.ndarray, incoming: np.ndarray, overlap: int,
               jumps: Callable[[np.ndarray], np.ndarray] = feature_jumps) -> np.ndarray:
    """The cost of each seam between candidates ``previous [Ka, T, D]`` and ``incoming [Kb, T, D]``
    overlapping by ``overlap`` frames -> ``[Ka, Kb]``: the largest jump of their cross-fade, taken over
    the overlap plus the frame on either side (``jumps`` maps frames ``[K, L, D]`` to jumps ``[K, L - 1]``).
    """
    return jumps(_crossfade_frames(previous, incoming, overlap)).max(axis=1).reshape(len(previous), len(incoming))


def _all_seam_costs(candidates: Sequence[np.ndarray], starts: list[int],
                    jumps: Callable[[np.ndarray], np.ndarray]) -> list[np.ndarray]:
    """:func:`seam_costs` of every seam (window ``i - 1`` into ``i``, ``i >= 1``; zeros where windows do not
    overlap). The cross-fades of up to :data:`SEAMS_PER_BATCH` seams of one overlap go through ``jumps``
    together: one forward kinematics for a minute of audio instead of one per seam (a 60-s clip's 8
    seams took about a quarter of the time), with memory bounded for long audio."""
    costs = {i: np.zeros((len(candidates[i - 1]), len(candidates[i]))) for i in range(1, len(candidates))}
    by_overlap: dict[int, list[int]] = {}
    for i in range(1, len(candidates)):
        overlap = starts[i - 1] + candidates[i].shape[1] - starts[i]
        if overlap > 0:
            by_overlap.setdefault(overlap, []).append(i)
    for overlap, seams in by_overlap.items():
        for first in range(0, len(seams), SEAMS_PER_BATCH):
            chunk = seams[first: first + SEAMS_PER_BATCH]
            frames = [_crossfade_frames(candidates[i - 1], candidates[i], overlap) for i in chunk]
            worst = jumps(np.concatenate(frames)).max(axis=1)
            for i, part in zip(chunk, np.split(worst, np.cumsum([len(f) for f in frames])[:-1])):
                costs[i] = part.reshape(costs[i].shape)
    return list(costs.values())


def choose_seam_candidates(candidates: Sequence[np.ndarray], starts: list[int],
                           jumps: Callable[[np.ndarray], np.ndarray] = feature_jumps) -> np.ndarray:
    """Per window, its candidates ``[K_i, T, D]`` (a ``[W, K, T, D]`` array works) -> windows ``[W, T, D]``.

    One candidate per window, chosen together (a bottleneck Viterbi path): the sequence whose largest
    seam cost (:func:`seam_costs`, the largest jump of a cross-fade) is smallest, and among those the
    one with the smallest sum of seam costs. Unlike choosing window by window, this can also pick the
    earlier window of a seam, e.g. one that does not stroke where the next one fades in. Ties go to the
    lower candidate index; with one candidate per window, or no overlaps, candidate 0 everywhere.
    """
    # per candidate of the current window, the best path ending there: its worst seam and its cost sum
    worst, total = np.zeros(len(candidates[0])), np.zeros(len(candidates[0]))
    back = []
    for cost in _all_seam_costs(candidates, starts, jumps):
        path_worst, path_total = np.maximum(worst[:, None], cost), total[:, None] + cost
        best = np.array([np.lexsort((path_total[:, b], path_worst[:, b]))[0] for b in range(cost.shape[1])])
        back.append(best)
        cols = np.arange(cost.shape[1])
        worst, total = path_worst[best, cols], path_total[best, cols]
    pick = [int(np.lexsort((total, worst))[0])]
    for b in reversed(back):
        pick.append(int(b[pick[-1]]))
    pick.reverse()
    return np.stack([candidates[i][k] for i, k in enumerate(pick)])


def stitch(windows: np.ndarray, starts: list[int], num_frames: int) -> np.ndarray:
    """Cross-fade generated windows ``[W, T, D]`` placed at frame ``starts`` into ``[num_frames, D]``."""
    n, t, d = windows.shape
    weights = crossfade_weights(num_frames, starts, t)
    out = np.zeros((max(num_frames, max(starts) + t), d), np.float64)
    norm = np.zeros(len(out), np.float64)
    for win, s, w in zip(windows, starts, weights):
        out[s : s + t] += w[:, None] * win
        norm[s : s + t] += w
    out = out[:num_frames] / np.maximum(norm[:num_frames, None], 1e-8)
    return out.astype(np.float32)


def candidates_drawn(windows: int, seam_candidates: int) -> int:
    """Candidates drawn per window: ``seam_candidates``, or 1 when a single window has no seam to
    choose for (candidate 0 would be kept: the same output, a quarter of the sampling)."""
    return seam_candidates if windows > 1 else 1


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
        extra = gesture.extra
        if extra.get("variant") == "no_audio":
            raise EmogestureError(f"{gesture.path}: the no_audio ablation has no speech latents to edit or generate "
                                  "from in this pipeline")
        self.mean = np.asarray(extra["motion_mean"], np.float32)
        self.std = np.asarray(extra["motion_std"], np.float32)
        self.spec = from_dict(MotionFeatureSpec, extra["features"])
        self.fps = int(extra.get("fps", 30))
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
        want = gesture.extra.get("speech_weights_sha256")
        if want and speech.loaded.meta["weights_sha256"] != want:
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

    def encode(self, waveform: np.ndarray, hop_seconds: float = HOP_SECONDS, progress: Callable[[int], None] | None = None,
               times: StageTimes | None = None, parts: tuple[str, ...] = LATENT_PARTS
               ) -> tuple[EncodedWindows, list[float]]:
        """A 16 kHz waveform -> speech latents of its 10-s windows every ``hop_seconds``, and their starts (s);
        ``parts``: the latents wanted (default all three; an edit source needs fewer)."""
        return self.speech.encode(waveform, TARGET_SAMPLE_RATE, hop_seconds, progress, times, parts)

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

    def conditions(self, enc: EncodedWindows, edit: EditRequest | None, emotion_mode: str = "auto"
                   ) -> list[np.ndarray]:
        """Condition latents ``[c, e, s]`` ``[W, 256]`` of encoded windows: ``emotion_mode`` ``auto``
        blends untrusted emotion latents toward neutral and the style latents of an unfamiliar voice toward
        the typical training style (:mod:`emogesture.pipeline.perception`), ``own`` keeps them; then the
        edit, if any. A model that hears timing also gets the windows' own timing
        stream ``[W, 300, 2]`` (never the edit source's)."""
        if emotion_mode not in EMOTION_MODES:
            raise EmogestureError(f"emotion mode {emotion_mode!r}: choose one of {', '.join(EMOTION_MODES)}")
        c, e, s = enc.content.copy(), enc.emotion.copy(), enc.style.copy()
        if emotion_mode == "auto":
            perception = perception_of(self.speech)
            e, s = auto_emotion(e, s, perception), auto_style(s, perception)
        if edit is not None:
            n = len(c)
            target = None
            if edit.emotion_from is not None:
                target = edit.emotion_from[np.arange(n) % len(edit.emotion_from)]
            elif edit.emotion_label is not None:
                means = self.loaded.extra.get("emotion_latent_means", {})
                if edit.emotion_label not in means:
                    raise EmogestureError(f"unknown emotion {edit.emotion_label!r}; known: {', '.join(means)}")
                target = np.broadcast_to(np.asarray(means[edit.emotion_label], np.float32), e.shape)
            if target is not None:
                e = ((1.0 - edit.emotion_weight) * e + edit.emotion_weight * target).astype(np.float32)
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
                         residual_weights: np.ndarray | None = None, times: StageTimes | None = None
                         ) -> np.ndarray:
        """Condition latents ``[W, 256]`` x3 and one seed per window -> raw features ``[W, T, D]``
        (``residual_weights [W]`` scale each window's residual noise)."""
        timing = conditions[-1] if self.loaded.config.hears_timing else None
        with maybe_stage(times, "sampling"):
            z = sample_latents(self.loaded, conditions, seeds, batch_size=SAMPLING_BATCH, progress=progress,
                               residual_weights=residual_weights, precision=self.precision)
        with maybe_stage(times, "motion decoder"):
            return decode_latents(self.loaded, z, self.loaded.config.vae.frames, timing=timing,
                                  precision=self.precision)

    def draw_windows(self, waveform: np.ndarray, *, edit: EditRequest | None = None, seed: int = 0,
                     samples: int = 1, hop_seconds: float = HOP_SECONDS, seam_candidates: int = 4,
                     emotion_mode: str = "auto", encoded: tuple[EncodedWindows, list[float]] | None = None,
                     progress: Callable[[int], None] | None = None, times: StageTimes | None = None
                     ) -> tuple[np.ndarray, list[int]]:
        """A 16 kHz waveform ``[N]`` -> every window drawn, before stitching: raw motion features
        ``[samples, W, K, T, D]`` (``K`` candidates per window, see :func:`candidates_drawn`) and the
        windows' start frames. Arguments as in :meth:`generate`.

        Every sample's every candidate of every window is drawn in one batched pass (each from its own
        generator, so the result does not depend on how many are drawn together).
        """
        if seam_candidates < 1:
            raise EmogestureError(f"seam_candidates must be at least 1, got {seam_candidates}")
        enc, starts_s = encoded if encoded is not None else self.encode(waveform, hop_seconds, times=times)
        conds = self.conditions(enc, edit, emotion_mode)
        starts = [int(round(s * self.fps)) for s in starts_s]
        n = len(starts)
        k_cand = candidates_drawn(n, seam_candidates)
        draws = [(k, i, c) for k in range(samples) for i in range(n) for c in range(k_cand)]
        rows = np.array([i for _, i, _ in draws])
        picked = [c[rows] for c in conds]
        # residual noise stands for strokes the audio leaves open: none without sound, in full from half
        # a window of it (every window of the corpus's speech has at least 0.6)
        activity = window_activity(waveform, TARGET_SAMPLE_RATE, starts_s)
        weights = np.clip(activity / FULL_RESIDUAL_ACTIVITY, 0.0, 1.0)[rows]
        # candidate 0 of window i keeps the seed it has with one candidate
        seeds = [int(np.random.SeedSequence([seed, k, i] + ([c] if c else [])).generate_state(1)[0])
                 for k, i, c in draws]
        drawn = settle_quiet_windows(self.generate_windows(picked, seeds, progress, weights, times), weights, self.fps)
        return drawn.reshape(samples, n, k_cand, *drawn.shape[1:]), starts

    def to_sequence(self, feats: np.ndarray) -> SMPLXSequence:
        """Raw motion features ``[T, D]`` -> an SMPL-X sequence of ``T`` frames."""
        poses, trans = features_to_poses(torch.from_numpy(np.ascontiguousarray(feats, np.float32)), self.spec)
        trans_np = trans.numpy() if trans is not None else np.zeros((len(feats), 3), np.float32)
        return SMPLXSequence(poses=poses.numpy(), trans=trans_np, fps=self.fps)

    def generate(self, waveform: np.ndarray, *, edit: EditRequest | None = None, seed: int = 0, samples: int = 1,
                 hop_seconds: float = HOP_SECONDS, seam_candidates: int = 4, emotion_mode: str = "auto",
                 encoded: tuple[EncodedWindows, list[float]] | None = None,
                 progress: Callable[[int], None] | None = None, times: StageTimes | None = None
                 ) -> list[SMPLXSequence]:
        """A 16 kHz waveform ``[N]`` -> ``samples`` SMPL-X sequences of ``round(N / 16000 * 30)`` frames.

        ``seam_candidates``: samples drawn per window, of which one per window is kept so that the
        worst seam moves least (see the module docstring); 1 = every window independent.
        ``emotion_mode``: see :meth:`conditions`. ``encoded``: the waveform's ``encode(waveform,
        hop_seconds)`` when already computed. ``progress(n)`` is called as ``n`` more windows are drawn.
        ``times``: wall seconds per stage are added to it (``fbank``, ``speech encoders``, ``sampling``,
        ``motion decoder``, ``seams and poses``). The windows are drawn by :meth:`draw_windows`.
        """
        drawn, starts = self.draw_windows(waveform, edit=edit, seed=seed, samples=samples, hop_seconds=hop_seconds,
                                          seam_candidates=seam_candidates, emotion_mode=emotion_mode,
                                          encoded=encoded, progress=progress, times=times)
        num_frames = int(round(len(waveform) / TARGET_SAMPLE_RATE * self.fps))
        with maybe_stage(times, "seams and poses"):
            return [self.to_sequence(stitch(choose_seam_candidates(candidates, starts, self.joint_jumps), starts,
                                            num_frames)) for candidates in drawn]

    def encode_file_latents(self, path: str | PathLike[str]) -> EncodedWindows:
        """Latents of another audio file (for ``--emotion-from`` / ``--style-from``)."""
        enc, _ = self.encode(self.load_speech(path))
        return enc


def output_stem(speech: Path, seed: int, sample: int, edit_tag: str = "") -> str:
    """The file name, without extension, of one generated sample: ``<speech stem><edit>_seed<seed>_<sample>``."""
    return f"{speech.stem}{edit_tag}_seed{seed}_{sample}"
