"""The face track as a Live Link Face CSV (Epic's iPhone app's recording format), which Unreal's Live Link and
the Maya and Blender CSV importers read.

One row per frame: ``Timecode`` (``HH:MM:SS:FF.mmm`` from 00:00:00:00 at the sequence's frame rate),
``BlendShapeCount`` (61), the 52 ARKit weights under their capitalised names in Apple's order, then the
head's and the eyes' rotations in radians (``HeadYaw, HeadPitch, HeadRoll, LeftEyeYaw, LeftEyePitch,
LeftEyeRoll, RightEyeYaw, RightEyePitch, RightEyeRoll``) from the SMPL-X poses: the head's as the turns of
the spine, neck and head summed; each eye's its joint's.
"""

from __future__ import annotations

from os import PathLike
from pathlib import Path

import numpy as np

from emogesture.errors import EmogestureError
from emogesture.fileio import atomic_output
from emogesture.types import ARKIT_NAMES, SMPLXSequence

ROTATIONS = ("HeadYaw", "HeadPitch", "HeadRoll", "LeftEyeYaw", "LeftEyePitch", "LeftEyeRoll", "RightEyeYaw",
             "RightEyePitch", "RightEyeRoll")
COLUMNS = ("Timecode", "BlendShapeCount", *(n[0].upper() + n[1:] for n in ARKIT_NAMES), *ROTATIONS)
HEAD_CHAIN = (3, 6, 9, 12, 15)  # spine1-3, neck, head
LEFT_EYE, RIGHT_EYE = 23, 24


def timecode(frame: int, fps: float) -> str:
    """Frame ``frame`` -> ``HH:MM:SS:FF.mmm`` (the sub-frame part is zero)."""
    per_second = max(int(round(fps)), 1)
    seconds, ff = divmod(frame, per_second)
    minutes, ss = divmod(seconds, 60)
    hh, mm = divmod(minutes, 60)
    return f"{hh:02d}:{mm:02d}:{ss:02d}:{ff:02d}.000"


def arkit_rows(seq: SMPLXSequence) -> np.ndarray:
    """``[T, 61]``: the 52 weights, then the head's yaw, pitch and roll and each eye's (rad)."""
    if seq.arkit is None:
        raise EmogestureError("the animation has no face track to write as ARKit (generate it with --face)")
    head = seq.poses[:, list(HEAD_CHAIN)].sum(1)  # small turns: their axis-angles add
    rotations = [head[:, 1], head[:, 0], head[:, 2]]
    for eye in (LEFT_EYE, RIGHT_EYE):
        rotations += [seq.poses[:, eye, 1], seq.poses[:, eye, 0], seq.poses[:, eye, 2]]
    return np.concatenate([seq.arkit, np.stack(rotations, 1)], 1)


def save_arkit_csv(seq: SMPLXSequence, path: str | PathLike[str], overwrite: bool = False) -> Path:
    """Write ``seq``'s face track as a Live Link Face CSV at ``path`` (atomic; an existing file is replaced only
    with ``overwrite``)."""
    rows = arkit_rows(seq)
    lines = [",".join(COLUMNS)]
    count = str(rows.shape[1])
    for t, row in enumerate(rows):
        lines.append(",".join([timecode(t, seq.fps), count, *(f"{v:.6f}" for v in row)]))
    with atomic_output(path, overwrite) as tmp:
        tmp.write_text("\n".join(lines) + "\n")
    return Path(path)
