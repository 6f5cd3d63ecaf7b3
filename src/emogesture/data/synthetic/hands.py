"""Hand shapes of the synthetic corpus: a relaxed curl at rest, and shapes that change with the strokes.

Each hand is driven by six channels (radians, per frame): the curl of the index, middle, pinky, ring
finger and thumb (SMPL-X's order of a hand's fingers) and the fingers' spread. At rest a hand is loosely
curled — each speaker its own amount, an emotion adding tension (anger, fear) or looseness — and never
quite still. A stroke brings a hand shape with it, formed just before the apex and held a little after:
an open palm with spread fingers, a point, a precision grip, a fist, a limp hand. Which shapes a stroke
takes depends on the emotion (anger points and makes fists, sadness lets the hand hang limp, happiness
and surprise open it) and on the speaker's own habits.

:func:`finger_poses` maps the channels onto the 15 local rotations of a hand: a finger's curl is shared
out over its three joints (:data:`JOINT_SHARE`) as flexion; the spread turns the first knuckles apart.
The right hand mirrors the left (the Y and Z rotation components negated).
"""

from __future__ import annotations

import numpy as np

from emogesture.data.synthetic.factors import smooth_noise
from emogesture.types import FPS

FINGERS = ("index", "middle", "pinky", "ring", "thumb")  # SMPL-X order in each hand, 3 joints each
JOINT_SHARE = np.array([0.85, 1.0, 0.7])  # a finger's curl at its proximal, middle and distal joint
SPREAD_SIDE = np.array([-1.0, -0.3, 1.0, 0.4])  # index and middle toward the thumb, ring and pinky away
#: curl of index, middle, pinky, ring and thumb, and the spread (rad), of each shape
HAND_SHAPES: dict[str, tuple[float, ...]] = {
    "open": (0.08, 0.1, 0.14, 0.12, 0.1, 0.2),  # an open palm, fingers spread: offering, reaching
    "point": (0.05, 1.15, 1.25, 1.2, 0.65, 0.0),  # the index out
    "grip": (0.75, 0.6, 0.55, 0.6, 0.75, 0.0),  # a precision grip, the thumb to the index
    "fist": (1.35, 1.4, 1.45, 1.4, 0.9, 0.0),  # tension
    "limp": (0.55, 0.6, 0.7, 0.65, 0.35, 0.05),  # loose, falling
}
SHAPES = tuple(HAND_SHAPES)
#: per emotion: curl added to the rest (tension > 0) and the weights of the stroke shapes (SHAPES order)
EMOTION_HANDS: dict[str, tuple[float, tuple[float, ...]]] = {
    "neutral": (0.0, (0.35, 0.15, 0.3, 0.05, 0.15)),
    "happiness": (-0.05, (0.55, 0.15, 0.2, 0.0, 0.1)),
    "anger": (0.3, (0.1, 0.3, 0.1, 0.5, 0.0)),
    "sadness": (0.1, (0.1, 0.0, 0.1, 0.0, 0.8)),
    "contempt": (0.0, (0.2, 0.35, 0.15, 0.05, 0.25)),
    "surprise": (-0.1, (0.7, 0.1, 0.1, 0.05, 0.05)),
    "fear": (0.25, (0.3, 0.0, 0.3, 0.3, 0.1)),
    "disgust": (0.1, (0.3, 0.2, 0.1, 0.2, 0.2)),
}
REST_CURL = 0.3  # rad added to a speaker's own finger curl (0.05-0.4): a loosely curled hand at rest
IDLE_CURL = (0.06, 0.4)  # (rad, s): each finger's slow drift
MIN_CURL, MAX_CURL = -0.15, 1.6


def speaker_habits(seed: int, speaker_id: int) -> np.ndarray:
    """A speaker's liking for each stroke shape ``[len(SHAPES)]`` (multiplies the emotion's weights), drawn
    from ``default_rng([seed, 505, speaker_id])``."""
    return np.exp(np.random.default_rng([seed, 505, speaker_id]).normal(0.0, 0.6, len(SHAPES)))


def rest_channels(n: int, speaker_curl: float, emotion: str, rng: np.random.Generator) -> np.ndarray:
    """One hand at rest ``[n, 6]``: curl of the five fingers and the spread, drifting slowly."""
    tension = EMOTION_HANDS[emotion][0]
    x = np.zeros((n, 6))
    x[:, :5] = REST_CURL + speaker_curl + tension
    x[:, 4] *= 0.6  # the thumb curls less
    x += IDLE_CURL[0] * smooth_noise(rng, n, IDLE_CURL[1] * FPS, 6) * np.array([1, 1, 1, 1, 0.7, 0.5])
    return x


def stroke_shape(rng: np.random.Generator, emotion: str, habits: np.ndarray) -> str:
    """The shape a stroke's hand takes: the emotion's weights times the speaker's habits."""
    w = np.asarray(EMOTION_HANDS[emotion][1]) * habits
    return SHAPES[int(rng.choice(len(SHAPES), p=w / w.sum()))]


def add_shape(channels: np.ndarray, shape: str, bump: np.ndarray, strength: float = 1.0) -> None:
    """Move a hand's channels ``[n, 6]`` toward ``shape`` by ``bump [n]`` (0..1) × ``strength``, in place."""
    target = np.asarray(HAND_SHAPES[shape])
    rest = np.median(channels, axis=0)
    channels += strength * bump[:, None] * (target - rest)[None]


def finger_poses(channels: np.ndarray, mirror: np.ndarray) -> np.ndarray:
    """A hand's channels ``[n, 6]`` -> its 15 local axis-angle rotations ``[n, 15, 3]`` (SMPL-X order)."""
    n = len(channels)
    curl = np.clip(channels[:, :5], MIN_CURL, MAX_CURL)
    spread = np.clip(channels[:, 5], -0.1, 0.4)
    out = np.zeros((n, 15, 3))
    for f in range(4):
        for k in range(3):
            out[:, 3 * f + k, 2] = -curl[:, f] * JOINT_SHARE[k]
        out[:, 3 * f, 1] = SPREAD_SIDE[f] * spread
    thumb = curl[:, 4]
    for k in range(3):  # the thumb folds across the palm: flexion with a turn toward it
        out[:, 12 + k] = np.stack([0.3 * thumb, -0.5 * thumb, -0.4 * thumb], axis=1) * JOINT_SHARE[k]
    return out * mirror
