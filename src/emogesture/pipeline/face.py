"""The face of a generated animation (``generate --face``): the emotion animated per frame, and the face track
(:mod:`emogesture.face`) put into the sequence (``arkit``, the SMPL-X jaw and eyes)."""

from __future__ import annotations

import numpy as np

from emogesture.face.phones import Phone
from emogesture.face.track import (FaceTrack, accent_brows, blink_track, compose, expression_track, face_track,
                                   gaze_track, mouth_track, voice_level)
from emogesture.pipeline.perception_report import PerceivedEmotion
from emogesture.pipeline.timeline import EmotionTimeline
from emogesture.types import EMOTIONS, FPS, SMPLXSequence

JAW, LEFT_EYE, RIGHT_EYE = 22, 23, 24
#: the joints whose turn about the vertical axis is the head's (spine, neck, head)
HEAD_CHAIN = (0, 3, 6, 9, 12, 15)
WINDOW_S = 10.0


def _per_frame(values: np.ndarray, starts_s: list[float], n: int, fps: float) -> np.ndarray:
    """Per-window rows ``[W, K]`` (windows of WINDOW_S from ``starts_s``) -> ``[T, K]``, linear between the
    windows' centres."""
    centres = np.asarray(starts_s, np.float64) + WINDOW_S / 2
    t = np.arange(n) / fps
    return np.stack([np.interp(t, centres, values[:, k]) for k in range(values.shape[1])], 1)


def heard_per_frame(heard: PerceivedEmotion, mode: str, n: int, fps: float = FPS) -> np.ndarray:
    """``[T, 8]`` the speech's own emotion per frame: as heard (``own``), or under ``auto`` blended toward
    neutral where the perception does not trust a window."""
    probs = np.asarray(heard.probabilities, np.float64)
    if mode == "auto" and heard.trust is not None:
        trust = np.clip(np.asarray(heard.trust, np.float64), 0.0, 1.0)[:, None]
        probs = trust * probs + (1 - trust) * np.eye(len(EMOTIONS))[0]
    return _per_frame(probs, heard.starts_s, n, fps)


def animated_emotions(heard: PerceivedEmotion, mode: str, n: int, *, label: str | None = None, weight: float = 1.0,
                      source: PerceivedEmotion | None = None, timeline: EmotionTimeline | None = None,
                      fps: float = FPS) -> np.ndarray:
    """``[T, 8]`` the emotion the face shows per frame, as the body is asked for it: the speech's own
    (``mode``), moved by ``weight`` toward ``label`` or toward the emotion heard in ``source`` (an
    ``--emotion-from`` recording, its windows averaged), or the keyframes of ``timeline`` in force."""
    eye = np.eye(len(EMOTIONS))
    if timeline is not None:  # before the first keyframe, and at ``auto`` ones, the speech's own under auto
        auto, as_heard = heard_per_frame(heard, "auto", n, fps), heard_per_frame(heard, "own", n, fps)
        out = auto.copy()
        t = np.arange(n) / fps
        for k, frame in enumerate(timeline.keyframes):
            end = timeline.keyframes[k + 1].time if k + 1 < len(timeline.keyframes) else np.inf
            span = (t >= frame.time) & (t < end)
            if frame.label == "own":
                out[span] = as_heard[span]
            elif frame.label != "auto":
                out[span] = (1 - frame.weight) * auto[span] + frame.weight * eye[EMOTIONS.index(frame.label)]
        return out
    own = heard_per_frame(heard, mode, n, fps)
    if label is not None:
        return (1 - weight) * own + weight * eye[EMOTIONS.index(label)]
    if source is not None:
        return (1 - weight) * own + weight * np.asarray(source.probabilities, np.float64).mean(0)
    return own


def head_yaw(seq: SMPLXSequence) -> np.ndarray:
    """``[T]`` the head's turn about the vertical axis in rad (the chain's turns summed)."""
    return seq.poses[:, list(HEAD_CHAIN), 1].sum(1)


def with_face(seq: SMPLXSequence, waveform: np.ndarray, sample_rate: int, emotions: np.ndarray,
              phones: list[Phone] | None, seed: int) -> SMPLXSequence:
    """``seq`` with its face: ``arkit`` ``[T, 52]`` and the jaw and eye joints set from the face track of
    ``waveform`` (``emotions`` ``[T, 8]`` from :func:`animated_emotions`; ``phones``: None, the jaw follows the
    loudness alone)."""
    return face_on(seq, face_track(waveform, sample_rate, seq.num_frames, emotions, phones=phones,
                                   head_yaw=head_yaw(seq), seed=seed, fps=seq.fps))


class StreamFace:
    """The face of a stream (``GestureStream(face=True)``), update by update: the jaw follows the voice's
    loudness (phones are not recognised live), the brows the accents of the newest 10 s, the expression the
    emotion of each update, and the blinks and gaze are drawn from ``seed`` along the stream's own time, a
    minute at a time."""

    CHUNK_S = 60.0

    def __init__(self, seed: int, fps: float = FPS) -> None:
        self.seed, self.fps = int(seed), fps
        self.blink, self.gaze = np.zeros(0, np.float32), np.zeros((0, 2), np.float32)

    def _drawn_until(self, frame: int) -> None:
        chunk = int(self.CHUNK_S * self.fps)
        while len(self.blink) < frame:
            rng = np.random.default_rng([self.seed, len(self.blink) // chunk])
            self.blink = np.concatenate([self.blink, blink_track(chunk, rng, self.fps)])
            self.gaze = np.concatenate([self.gaze, gaze_track(chunk, rng, fps=self.fps)])

    def frames(self, window: np.ndarray, sample_rate: int, start: int, count: int, emotion: np.ndarray) -> FaceTrack:
        """The face of frames ``start .. start + count`` (the newest of the 10-s ``window`` ``[N]``, which ends
        at the instant of the last), under the emotion weights ``[8]``."""
        level = voice_level(window, sample_rate, int(round(len(window) / sample_rate * self.fps)), self.fps)
        tail = slice(len(level) - count, len(level))
        self._drawn_until(start + count)
        expression = expression_track(np.tile(np.asarray(emotion, np.float32), (count, 1)), level[tail])
        return compose(mouth_track(None, level, self.fps)[tail], accent_brows(level, self.fps)[tail], expression,
                       self.blink[start : start + count], self.gaze[start : start + count])


def face_on(seq: SMPLXSequence, face: FaceTrack) -> SMPLXSequence:
    """``seq`` with ``face``'s ARKit weights, jaw and eyes (the same number of frames)."""
    poses = seq.poses.copy()
    poses[:, JAW] = face.jaw
    poses[:, LEFT_EYE], poses[:, RIGHT_EYE] = face.eyes[:, 0], face.eyes[:, 1]
    return SMPLXSequence(poses=poses, trans=seq.trans, betas=seq.betas, expressions=seq.expressions, fps=seq.fps,
                         gender=seq.gender, model=seq.model, arkit=face.arkit)
