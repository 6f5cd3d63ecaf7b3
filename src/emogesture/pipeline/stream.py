"""Streaming: speech pushed in pieces of any size, motion frames out as soon as they are decided.

The offline pipeline draws each 10-s window once with the whole recording known. A stream cannot wait, so
:class:`GestureStream` draws a window at every ``hop_seconds`` of audio received (an *update*): the window
ending at the newest sample (the first 10 s padded with silence in front), ``candidates`` draws of it, and
emits the frames of the newest hop from its end. Each update over sound draws new noise, so the frames of
successive updates come from different draws; over silence the same noise is drawn again, and the motion
settles.
Each update joins its frames to the last frame already sent: of the candidates, the one whose frame at that
instant lies nearest (the smallest largest joint jump, as the offline seam chooser measures), its offset from
the sent frame fading out over ``blend_seconds`` (a raised cosine in the feature domain). The emotion can be
changed at any time and is read at the next update.

Latency budget: a sample waits for the update that covers it (up to one hop, half a hop on average), then for
that update's work (the speech encoders on one 10-s window, ``candidates`` diffusion draws and their decoding:
about 0.05 s on two CPU cores with the bundled model), then its frame is sent.

Frame ``i`` stands for the instant ``i / 30`` s from the stream's start; a stream of ``s`` seconds gives
``round(s × 30)`` frames, the last ones when :meth:`GestureStream.end` flushes it.

Example (the bundled model; 100-ms pieces of a recording, the emotion changed half-way)::

    stream = GestureStream(GesturePipeline.from_run(), emotion="anger")
    for i, piece in enumerate(np.array_split(wave, len(wave) // 1600)):
        if i == 100:
            stream.set_emotion("sadness")
        for frames in stream.push(piece):
            send(frames.start, frames.sequence.poses, frames.sequence.trans)
    for frames in stream.end():
        send(frames.start, frames.sequence.poses, frames.sequence.trans)
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import torch

from emogesture.audio import TARGET_SAMPLE_RATE, resample, rolled_fbank, window_activity
from emogesture.errors import EmogestureError
from emogesture.pipeline.animate import emotion_request
from emogesture.pipeline.face import StreamFace, face_on, heard_per_frame
from emogesture.pipeline.generate import WINDOW_SECONDS, EditRequest, GesturePipeline
from emogesture.pipeline.neutral_reference import NeutralReference
from emogesture.pipeline.perception import perceive, perception_of
from emogesture.pipeline.postprocess import residual_weights
from emogesture.types import EMOTIONS, SMPLXSequence

__all__ = ["GestureStream", "StreamFrames", "StreamSettings", "push_together"]


@dataclass(frozen=True)
class StreamSettings:
    """``hop_seconds``: audio between updates; ``candidates``: draws per update, the nearest one kept;
    ``blend_seconds``: how long a join's offset takes to fade."""

    hop_seconds: float = 0.25
    candidates: int = 2
    blend_seconds: float = 0.5

    def __post_init__(self) -> None:
        if not 0.05 <= self.hop_seconds <= 5.0:
            raise EmogestureError(f"stream hop {self.hop_seconds} s: between 0.05 and 5 s")
        if self.candidates < 1 or self.blend_seconds < 0:
            raise EmogestureError("stream candidates must be at least 1 and blend_seconds at least 0")


@dataclass
class StreamFrames:
    """Frames decided by one update: the first frame's index ``start`` and the SMPL-X poses of the frames
    ``start, start + 1, ...`` (``sequence.poses [n, 55, 3]``, ``sequence.trans [n, 3]``)."""

    start: int
    sequence: SMPLXSequence

    def __len__(self) -> int:
        return self.sequence.num_frames


@dataclass
class _Update:
    """One stream's update up to its draws: the conditions ``[K, ...]`` each, seeds and sound weights of its
    ``K`` candidates, the frame it reaches (``target``), how many frames it sends (``new``) and the window's
    speech latents (for the face)."""

    conds: list[np.ndarray]
    seeds: list[int]
    sound: np.ndarray
    target: int
    new: int
    enc: object


#: how a loaded pass draws (:func:`push_together` with ``loaded``): one candidate per update, with this many DDIM
#: steps (the draws and their decoding are most of a pass's cost; chosen on val takes streamed against offline:
#: 3, 5 and 10 steps join alike, ``experiments/live/README.md``)
LOADED_STEPS = 3


def draw_together(pipe: GesturePipeline, plans: list[_Update], steps: int | None = None) -> list[np.ndarray]:
    """The draws ``[K, T, D]`` of each update of ``plans`` (of streams on ``pipe``), all in one batched pass;
    ``steps``: DDIM steps (None: the pipeline's)."""
    conds = [np.concatenate([p.conds[i] for p in plans]) for i in range(len(plans[0].conds))]
    generation = None if steps is None else replace(pipe.generation, num_inference_steps=steps)
    drawn = pipe.generate_windows(conds, [s for p in plans for s in p.seeds],
                                  sound=np.concatenate([p.sound for p in plans]), generation=generation)
    return np.split(drawn, np.cumsum([len(p.seeds) for p in plans])[:-1])


def push_together(jobs: list[tuple["GestureStream", np.ndarray, int]], catch_up: bool = False,
                  loaded: bool = False) -> list[list[StreamFrames]]:
    """Each job's samples pushed into its stream (``(stream, samples [N], sample_rate)``, as
    :meth:`GestureStream.push`; one job per stream, all on one pipeline): the updates that fall due together
    are drawn in one batched pass (each stream's filterbank on its own; the speech encoders, the diffusion draws
    and their decoding for all at once). ``loaded``: the pass draws as a server with many streams does, one
    candidate per update and :data:`LOADED_STEPS` DDIM steps. Returns each job's frames."""
    rests = []
    for stream, samples, rate in jobs:
        x = np.asarray(samples, np.float32).reshape(-1)
        rests.append(resample(x, rate, TARGET_SAMPLE_RATE) if rate != TARGET_SAMPLE_RATE else x)
    out: list[list[StreamFrames]] = [[] for _ in jobs]
    while any(len(x) for x in rests):
        due = []
        for i, (stream, _, _) in enumerate(jobs):
            if len(rests[i]):
                rests[i], ready = stream._advance(rests[i], catch_up)
                if ready:
                    due.append(i)
        drawing = [i for i in due if jobs[i][0]._start_update() > 0]  # those with frames to send
        if drawing:
            pipe = jobs[drawing[0]][0].pipe
            heard = pipe.speech.encode_each([jobs[i][0].audio for i in drawing],
                                            noise_suppression=pipe.generation.noise_suppression,
                                            raw_fbanks=[jobs[i][0]._raw_fbank() for i in drawing])
            plans = [jobs[i][0]._plan(enc, 1 if loaded else None) for i, enc in zip(drawing, heard)]
            for i, plan, drawn in zip(drawing, plans, draw_together(pipe, plans, LOADED_STEPS if loaded else None)):
                out[i].append(jobs[i][0]._finish(plan, drawn))
    return [[f for f in frames if len(f)] for frames in out]


class GestureStream:
    """One stream of speech into frames (module docstring). ``emotion``: ``auto``, ``own`` or a label, with
    ``emotion_weight`` for a label (None = 1); ``style``: a style latent ``[D]`` to gesture in (another
    voice's, e.g. a training speaker's mean) instead of the speech's own; ``seed``: every draw of the stream
    derives from it; ``neutral_reference``: the speaker's neutral voice to read the speech's emotion against
    (:mod:`emogesture.pipeline.neutral_reference`; :meth:`set_neutral_reference` changes it); ``face``: the
    frames carry a face too (ARKit weights in ``sequence.arkit``, the jaw and eyes in the poses:
    :class:`~emogesture.pipeline.face.StreamFace`)."""

    def __init__(self, pipe: GesturePipeline, *, emotion: str = "auto", emotion_weight: float | None = None,
                 style: np.ndarray | None = None, seed: int = 0, settings: StreamSettings | None = None,
                 neutral_reference: NeutralReference | None = None, face: bool = False) -> None:
        self.pipe, self.seed = pipe, int(seed)
        self.face = StreamFace(self.seed, pipe.fps) if face else None
        self.settings = settings or StreamSettings()
        self.fps = pipe.fps
        self.window = int(round(WINDOW_SECONDS * TARGET_SAMPLE_RATE))
        self.frames_per_window = pipe.loaded.config.vae.frames
        self.audio = np.zeros(self.window, np.float32)  # the newest 10 s (silence before the stream)
        self.received = 0  # samples received (at 16 kHz)
        self.sent = 0  # frames sent
        self.updates = 0
        self._fbank: torch.Tensor | None = None  # the filterbank of ``audio`` when ``received`` was ``_fbank_at``
        self._fbank_at = 0
        self.draws = 0  # noise draws so far (a new one at each update over sound)
        self.last: np.ndarray | None = None  # the last sent frame's features [D]
        self.style = None if style is None else np.asarray(style, np.float32).reshape(1, -1)
        self.neutral_reference = neutral_reference
        self.set_emotion(emotion, emotion_weight)

    @property
    def seconds(self) -> float:
        return self.received / TARGET_SAMPLE_RATE

    def set_emotion(self, emotion: str = "auto", weight: float | None = None) -> None:
        """Change the emotion from the next update on (a one-line error for an unknown one)."""
        mode, label = emotion_request(emotion)
        if weight is not None and not 0.0 <= float(weight) <= 1.0:
            raise EmogestureError(f"emotion_weight {weight}: must be between 0 and 1")
        if weight is not None and label is None:
            raise EmogestureError("emotion_weight needs an emotion label to blend toward")
        self.mode, self.label, self.weight = mode, label, 1.0 if weight is None else float(weight)
        self.edit = EditRequest(emotion_label=label, emotion_weight=1.0 if weight is None else float(weight),
                                style_from=self.style) if label is not None or self.style is not None else None

    def set_neutral_reference(self, reference: NeutralReference | None) -> None:
        """Read the speech's emotion against the speaker's neutral voice from the next update on (None: the
        speech alone)."""
        self.neutral_reference = reference

    def push(self, samples: np.ndarray, sample_rate: int = TARGET_SAMPLE_RATE,
             catch_up: bool = False) -> list[StreamFrames]:
        """Mono samples ``[N]`` (float in [-1, 1]) at ``sample_rate`` -> the frames decided by the updates
        they complete (possibly none). ``catch_up``: where the samples complete several hops, update once, at
        the last (a server that fell behind spends one window on all the audio that waited), or every 9.75 s of
        audio when more waited (an update's frames lie within its 10-s window). :func:`push_together` does
        the same for several streams, their updates drawn in one batched pass."""
        return push_together([(self, samples, sample_rate)], catch_up)[0]

    def _advance(self, x: np.ndarray, catch_up: bool) -> tuple[np.ndarray, bool]:
        """Take in the samples of ``x`` (16 kHz) up to the next update: the samples left, and whether an update
        is due now."""
        hop = int(round(self.settings.hop_seconds * TARGET_SAMPLE_RATE))
        most = max(1, int((self.window - hop) // hop))  # hops one update may cover: its frames lie in the window
        hops = min(most, 1 + (max(0, (self.received + len(x)) // hop - self.updates - 1) if catch_up else 0))
        room = hop * (self.updates + hops) - self.received  # samples until the update
        piece, x = x[:room], x[room:]
        self._append(piece)
        if self.received == hop * (self.updates + hops):
            self.updates += hops - 1
            return x, True
        return x, False

    def end(self) -> list[StreamFrames]:
        """The frames left: those of the audio since the last update."""
        if int(round(self.seconds * self.fps)) <= self.sent:
            return []
        frames = self._update()
        return [frames] if len(frames) else []

    def _append(self, piece: np.ndarray) -> None:
        n = len(piece)
        if n >= self.window:
            self.audio[:] = piece[-self.window:]
        elif n:
            self.audio[:-n] = self.audio[n:]
            self.audio[-n:] = piece
        self.received += n

    def _update(self) -> StreamFrames:
        """Draw the window ending now and send the frames up to now, joined to the last frame sent."""
        if self._start_update() <= 0:
            return StreamFrames(self.sent, self.pipe.to_sequence(np.zeros((0, self.pipe.spec.dim), np.float32)))
        enc = self.pipe.speech.encode_each([self.audio], noise_suppression=self.pipe.generation.noise_suppression,
                                           raw_fbanks=[self._raw_fbank()])
        plan = self._plan(enc[0])
        return self._finish(plan, draw_together(self.pipe, [plan])[0])

    def _raw_fbank(self) -> torch.Tensor:
        """The filterbank of the newest 10 s (:attr:`audio`), only its newest frames computed anew
        (:func:`~emogesture.audio.rolled_fbank`)."""
        self._fbank = rolled_fbank(self._fbank, self.audio, self.received - self._fbank_at,
                                   self.pipe.speech.fbank_config)
        self._fbank_at = self.received
        return self._fbank

    def _start_update(self) -> int:
        """Count the update due now; the frames it is to send (0: none yet)."""
        self.updates += 1
        return int(round(self.seconds * self.fps)) - self.sent

    def _plan(self, enc, candidates: int | None = None) -> "_Update":
        """The update due now, up to its draws, from the window's speech latents ``enc`` (as
        ``pipe.encode(self.audio, perceived=False)`` gives them): its conditions, seeds and sound;
        ``candidates``: its draws (None: the stream's setting)."""
        target = int(round(self.seconds * self.fps))
        new = target - self.sent
        reference = self.neutral_reference  # read once: another thread may change it
        if reference is not None:
            enc = reference.relative(enc)
        conds = self.pipe.conditions(enc, self.edit, self.mode)
        k = candidates or self.settings.candidates
        hop = self.settings.hop_seconds  # the share of the newest hop's frames with sound, and the window's
        newest, whole = window_activity(self.audio, TARGET_SAMPLE_RATE, [WINDOW_SECONDS - hop, 0.0],
                                        window_seconds=[hop, WINDOW_SECONDS])
        if newest > 0.1:
            self.draws += 1  # new noise where the newest audio has sound; over silence the same draw goes on
        # the stream's own seeds: one per draw and candidate (its draws are not a recording's windows)
        seeds = [int(np.random.SeedSequence([self.seed, self.draws, c]).generate_state(1)[0]) for c in range(k)]
        weight = residual_weights(np.array([whole]))
        return _Update(conds=[np.repeat(c[:1], k, 0) for c in conds], seeds=seeds, sound=np.repeat(weight, k),
                       target=target, new=new, enc=enc)

    def _finish(self, plan: "_Update", drawn: np.ndarray) -> StreamFrames:
        """The update's frames from its draws ``drawn [K, T, D]``: the candidate nearest the last frame sent,
        joined to it."""
        new, end = plan.new, self.frames_per_window  # window frame `end` is the instant of frame `target`
        chosen = drawn[:, end - new:end]
        if self.last is None:
            frames = chosen[0]
        else:
            before = drawn[:, end - new - 1]  # each candidate at the instant of the last frame sent
            best = 0
            if len(drawn) > 1:
                jumps = self.pipe.joint_jumps(np.stack([np.broadcast_to(self.last, before.shape), before], 1))[:, 0]
                best = int(np.argmin(jumps))
            fade = self._fade(new)
            frames = chosen[best] + fade[:, None] * (self.last - before[best])[None]
        self.last = frames[-1].copy()
        start, self.sent = self.sent, plan.target
        sequence = self.pipe.to_sequence(frames)
        if self.face is not None:
            sequence = face_on(sequence, self.face.frames(self.audio, TARGET_SAMPLE_RATE, start, new,
                                                          self._emotion(plan.enc)))
        return StreamFrames(start, sequence)

    def _emotion(self, enc) -> np.ndarray:
        """``[8]`` the emotion the face shows at this update: the label at its weight over the speech's own under
        ``auto``, or the speech's own as ``mode`` says."""
        heard = perceive(enc, [0.0], perception_of(self.pipe.speech), "stream")
        own = heard_per_frame(heard, "auto" if self.label is not None else self.mode, 1, self.fps)[0]
        if self.label is None:
            return own
        return (1 - self.weight) * own + self.weight * np.eye(len(own))[EMOTIONS.index(self.label)]

    def _fade(self, count: int) -> np.ndarray:
        """The share ``[count]`` of a join's offset left at each of the next frames: 1 -> 0 over the blend."""
        span = max(self.settings.blend_seconds * self.fps, 1e-6)
        done = np.arange(1, count + 1) / span  # frames after the join
        return np.where(done < 1.0, 0.5 * (1 + np.cos(np.pi * np.clip(done, 0, 1))), 0.0)
