"""The face track: ARKit blendshape weights, the SMPL-X jaw and eyes, from the speech and its emotion.

Layers, each ``[T, 52]`` at the motion's frame rate, summed and clipped to ``[0, 1]``:

- the mouth: each phone's viseme (:data:`~emogesture.face.arkit.VISEME_SHAPES`) blended with its neighbours
  by dominance functions (coarticulation: a phone's mouth reaches into the phones around it, lip closures
  most strongly and most briefly), opened wider where the voice is louder and closed where it is silent
  (where no speech phone is heard, as in noise or a language the recogniser does not know, the jaw follows
  the loudness); within every lip closure the lips meet (``mouthClose`` equal to ``jawOpen``). Without phones
  the jaw follows the voice's loudness alone;
- the emotion: each emotion's expression (:data:`~emogesture.face.arkit.EXPRESSIONS`) times its weight per
  frame, a little stronger where the voice is louder, its jaw drop only while speaking;
- brows raised on accented syllables (the loudness's sharpest rises);
- blinks (about 17 a minute, 120-300 ms each) and the eyes' gaze: short saccades between fixations near the
  listener, leading the head's turns, shown by the ``eyeLook*`` shapes and the eye joints.

Every random draw comes from the ``seed`` given.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from emogesture.audio.onsets import frame_energy
from emogesture.face.arkit import (CLOSURES, EXPRESSIONS, INDEX, NUM_BLENDSHAPES, VISEME_OF, VISEME_SHAPES,
                                   vector)
from emogesture.face.phones import Phone
from emogesture.types import EMOTIONS, FPS

JAW_RAD = 0.45  # rad the SMPL-X jaw turns at jawOpen 1
EYE_YAW_RAD, EYE_PITCH_RAD = 0.5, 0.4  # rad of the eyes' turn at eyeLook* 1
BLINKS_PER_MIN = 17.0
SILENCE_DB, VOICE_DB = -38.0, -24.0  # dB below the recording's loudest frame: the mouth closed / fully moving
#: (dominance, reach in s beyond the phone's half-length) of the viseme groups: closures strong and brief
DOMINANCE = {"lips": (6.0, 0.015), "teeth_lip": (3.0, 0.02), "rest": (1.5, 0.02)}
DEFAULT_DOMINANCE = (1.0, 0.045)


@dataclass
class FaceTrack:
    """A face animation at the body's frame rate.

    Attributes:
        arkit: ``[T, 52]`` float32 blendshape weights in ``[0, 1]``, in :data:`~emogesture.face.arkit.ARKIT_NAMES`
            order.
        jaw: ``[T, 3]`` float32 axis-angle of the SMPL-X jaw (joint 22).
        eyes: ``[T, 2, 3]`` float32 axis-angle of the SMPL-X left and right eyes (joints 23, 24).
    """

    arkit: np.ndarray
    jaw: np.ndarray
    eyes: np.ndarray


def voice_level(waveform: np.ndarray, sample_rate: int, n_frames: int, fps: float = FPS) -> np.ndarray:
    """Loudness per frame ``[T]`` in dB below the recording's loudest frame (0 at the loudest)."""
    rms = frame_energy(waveform, sample_rate, fps=fps)
    db = 20 * np.log10(np.maximum(rms, 1e-7))
    db = db - db.max() if db.size else db
    out = np.full(n_frames, -100.0, np.float32)
    out[: min(n_frames, len(db))] = db[:n_frames]
    return out


def _gate(level_db: np.ndarray) -> np.ndarray:
    """0 where the voice is silent, 1 where it speaks, a smooth step between."""
    x = np.clip((level_db - SILENCE_DB) / (VOICE_DB - SILENCE_DB), 0.0, 1.0)
    return x * x * (3 - 2 * x)


def mouth_track(phones: list[Phone] | None, level_db: np.ndarray, fps: float = FPS) -> np.ndarray:
    """The mouth ``[T, 52]`` of ``phones`` (None: the loudness alone), ``level_db`` ``[T]`` from
    :func:`voice_level`."""
    n = len(level_db)
    gate = _gate(level_db)
    t = np.arange(n) / fps
    loud = np.clip((level_db + 30.0) / 24.0, 0.0, 1.0)
    voice_only = np.zeros((n, NUM_BLENDSHAPES), np.float32)
    voice_only[:, INDEX["jawOpen"]] = 0.45 * gate * loud
    if not phones:
        return voice_only
    unheard = np.ones(n, bool)  # frames no speech phone covers (silence, noise, sounds the recogniser lacks)
    total = np.zeros((n, NUM_BLENDSHAPES))
    weight = np.full(n, 1e-6)
    for p in phones:
        group = VISEME_OF.get(p.name, "rest")
        strength, reach = DOMINANCE.get(group, DEFAULT_DOMINANCE)
        centre, half = (p.start + p.end) / 2, max((p.end - p.start) / 2, 0.5 / fps)
        a, b = max(int((centre - half - 4 * reach) * fps), 0), min(int((centre + half + 4 * reach) * fps) + 2, n)
        if a >= b:
            continue
        d = np.maximum(np.abs(t[a:b] - centre) - half, 0.0)  # flat over the phone, falling off beyond it
        dom = strength * np.exp(-0.5 * (d / reach) ** 2)
        total[a:b] += dom[:, None] * VISEME_SHAPES[group]
        weight[a:b] += dom
        if group != "rest":
            unheard[max(int(p.start * fps), 0) : min(int(np.ceil(p.end * fps)), n)] = False
    out = (total / weight[:, None]).astype(np.float32)
    out *= (gate * (0.75 + 0.5 * loud))[:, None]
    out[unheard] = voice_only[unheard]  # there the jaw follows the voice, which is silent in true pauses
    return out


def closure_frames(phones: list[Phone] | None, n: int, fps: float = FPS) -> np.ndarray:
    """``[T]`` bool: the frames within a lip closure (P, B, M)."""
    mask = np.zeros(n, bool)
    for p in phones or ():
        if p.name in CLOSURES:
            centre = int(round((p.start + p.end) / 2 * fps))
            a, b = int(np.ceil(p.start * fps)), int(np.floor(p.end * fps)) + 1
            mask[max(min(a, centre), 0) : min(max(b, centre + 1), n)] = True
    return mask


def expression_track(emotion_weights: np.ndarray, level_db: np.ndarray) -> np.ndarray:
    """The expression ``[T, 52]`` of per-frame emotion weights ``[T, 8]`` (EMOTIONS order)."""
    table = np.stack([vector(EXPRESSIONS[e]) for e in EMOTIONS])  # [8, 52]
    loud = np.clip((level_db + 30.0) / 24.0, 0.0, 1.0)
    out = (emotion_weights @ table) * (0.8 + 0.3 * loud)[:, None]
    out[:, INDEX["jawOpen"]] *= _gate(level_db)
    return out.astype(np.float32)


def accent_brows(level_db: np.ndarray, fps: float = FPS) -> np.ndarray:
    """Brows raised ``[T, 52]`` on the loudness's sharpest rises (accented syllables), at most one every 0.6 s."""
    n = len(level_db)
    out = np.zeros((n, NUM_BLENDSHAPES), np.float32)
    if n < 3:
        return out
    rise = np.maximum(np.diff(np.maximum(level_db, SILENCE_DB), prepend=SILENCE_DB), 0.0)
    rise = np.convolve(rise, np.ones(3) / 3, mode="same")
    threshold = max(np.percentile(rise, 97), 1.0)
    t = np.arange(n)
    last = -np.inf
    for i in np.argsort(-rise):
        if rise[i] < threshold:
            break
        if np.abs(i - last) < 0.6 * fps:
            continue
        last = i
        bump = np.exp(-0.5 * ((t - i - 0.08 * fps) / (0.12 * fps)) ** 2) * min(rise[i] / (3 * threshold), 1.0)
        out[:, INDEX["browInnerUp"]] += 0.3 * bump
        out[:, INDEX["browOuterUpLeft"]] += 0.25 * bump
        out[:, INDEX["browOuterUpRight"]] += 0.25 * bump
    return out


def blink_track(n: int, rng: np.random.Generator, fps: float = FPS, per_minute: float = BLINKS_PER_MIN) -> np.ndarray:
    """``[T]`` eyelid closure in ``[0, 1]``: blinks spaced by a gamma law (at least 1 s apart), 120-300 ms
    each, closing in a third of it and opening in the rest."""
    out = np.zeros(n, np.float32)
    mean_gap = 60.0 / per_minute
    s = rng.uniform(0.3, mean_gap)
    while s * fps < n:
        length = rng.uniform(0.12, 0.3)
        t = np.arange(int(s * fps), min(int((s + length) * fps) + 1, n)) / fps - s
        phase = np.where(t < length / 3, t / (length / 3), 1 - (t - length / 3) / (2 * length / 3))
        out[int(s * fps) : int(s * fps) + len(t)] = np.maximum(out[int(s * fps) : int(s * fps) + len(t)],
                                                           np.sin(np.clip(phase, 0, 1) * np.pi / 2))
        s += max(1.0, rng.gamma(2.0, (mean_gap - 1.0) / 2.0) + 1.0)
    return out


def gaze_track(n: int, rng: np.random.Generator, head_yaw: np.ndarray | None = None, fps: float = FPS) -> np.ndarray:
    """``[T, 2]`` gaze (yaw toward the subject's left, pitch down) in rad: fixations near the listener 0.4-2.5 s
    long joined by 40-ms saccades, the eyes leading the head's turns by 0.2 s."""
    target = np.zeros((n, 2))
    s, current = 0, np.zeros(2)
    while s < n:
        hold = int(rng.uniform(0.4, 2.5) * fps)
        nxt = np.array([rng.normal(0, 0.08), rng.normal(0.02, 0.05)])
        ramp = np.clip(np.arange(min(hold, n - s)) / max(0.04 * fps, 1), 0, 1)[:, None]
        target[s : s + hold] = current + (nxt - current) * ramp
        current, s = nxt, s + hold
    if head_yaw is not None and len(head_yaw) >= n:
        lead = int(0.2 * fps)
        ahead = np.concatenate([head_yaw[lead:n], np.repeat(head_yaw[n - 1 : n], lead)])[:n]
        target[:, 0] += 0.8 * (ahead - head_yaw[:n])
    return np.clip(target, -0.6, 0.6).astype(np.float32)


def compose(mouth: np.ndarray, brows: np.ndarray, expression: np.ndarray | None, blink: np.ndarray,
            gaze: np.ndarray, closed: np.ndarray | None = None) -> FaceTrack:
    """The layers of ``T`` frames -> a :class:`FaceTrack`: ``mouth``, ``brows`` and ``expression`` ``[T, 52]``
    summed (``expression`` may be None), ``blink`` ``[T]`` and ``gaze`` ``[T, 2]`` added, all clipped to
    ``[0, 1]``; the lips meet in the ``closed`` frames ``[T]`` whatever the expression opens."""
    arkit = mouth + brows + (0 if expression is None else expression)
    for side in ("Left", "Right"):
        arkit[:, INDEX[f"eyeBlink{side}"]] = np.maximum(arkit[:, INDEX[f"eyeBlink{side}"]], blink)
    yaw, pitch = gaze[:, 0], gaze[:, 1]
    arkit[:, INDEX["eyeLookOutLeft"]] += np.maximum(yaw, 0) / EYE_YAW_RAD
    arkit[:, INDEX["eyeLookInRight"]] += np.maximum(yaw, 0) / EYE_YAW_RAD
    arkit[:, INDEX["eyeLookInLeft"]] += np.maximum(-yaw, 0) / EYE_YAW_RAD
    arkit[:, INDEX["eyeLookOutRight"]] += np.maximum(-yaw, 0) / EYE_YAW_RAD
    for side in ("Left", "Right"):
        arkit[:, INDEX[f"eyeLookDown{side}"]] += np.maximum(pitch, 0) / EYE_PITCH_RAD
        arkit[:, INDEX[f"eyeLookUp{side}"]] += np.maximum(-pitch, 0) / EYE_PITCH_RAD
    arkit = np.clip(arkit, 0.0, 1.0)
    if closed is not None:
        arkit[closed, INDEX["mouthClose"]] = arkit[closed, INDEX["jawOpen"]]
    n = len(arkit)
    jaw = np.zeros((n, 3), np.float32)
    jaw[:, 0] = JAW_RAD * arkit[:, INDEX["jawOpen"]]
    eyes = np.zeros((n, 2, 3), np.float32)
    eyes[:, :, 0], eyes[:, :, 1] = pitch[:, None], yaw[:, None]
    return FaceTrack(arkit.astype(np.float32), jaw, eyes)


def face_track(waveform: np.ndarray, sample_rate: int, n_frames: int, emotion_weights: np.ndarray | None = None,
               phones: list[Phone] | None = None, head_yaw: np.ndarray | None = None, seed: int = 0,
               fps: float = FPS) -> FaceTrack:
    """The face of a recording ``[N]`` over ``n_frames`` frames.

    ``emotion_weights``: ``[T, 8]`` per frame (EMOTIONS order; None: neutral); ``phones``: from
    :func:`~emogesture.face.phones.recognise_phones` (None: the jaw follows the loudness alone); ``head_yaw``:
    ``[T]`` the head's turn in rad (the eyes lead it); ``seed``: blinks and gaze.
    """
    level = voice_level(waveform, sample_rate, n_frames, fps)
    rng = np.random.default_rng(seed)
    expression = (None if emotion_weights is None else
                  expression_track(np.asarray(emotion_weights, np.float32)[:n_frames], level))
    blink = blink_track(n_frames, rng, fps)
    gaze = gaze_track(n_frames, rng, head_yaw, fps)
    return compose(mouth_track(phones, level, fps), accent_brows(level, fps), expression, blink, gaze,
                   closure_frames(phones, n_frames, fps))
