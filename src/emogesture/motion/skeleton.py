"""The SMPL-X skeleton: joint names, kinematic tree, joint groups and rest joint positions.

Rest positions come from the licence-free ``mannequin-x`` skeleton (calibrated to SMPL-X's
neutral body, Y-up, facing +Z, left = +X), which lacks SMPL-X's jaw and eye joints; those three
are placed at fixed approximate offsets from the head (see ``JAW_OFFSET`` / ``EYE_OFFSET``).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from emogesture.types import NUM_JOINTS

_FINGERS = ("index", "middle", "pinky", "ring", "thumb")
_HAND = tuple(f"{finger}{k}" for finger in _FINGERS for k in (1, 2, 3))

JOINT_NAMES: tuple[str, ...] = (
    "pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2",
    "left_ankle", "right_ankle", "spine3", "left_foot", "right_foot", "neck", "left_collar",
    "right_collar", "head", "left_shoulder", "right_shoulder", "left_elbow", "right_elbow",
    "left_wrist", "right_wrist", "jaw", "left_eye_smplhf", "right_eye_smplhf",
    *(f"left_{n}" for n in _HAND),
    *(f"right_{n}" for n in _HAND),
)  # fmt: skip
#: The 30 finger joints (three per finger, five fingers per hand), by index into :data:`JOINT_NAMES`.
FINGER_JOINTS: tuple[int, ...] = tuple(i for i, n in enumerate(JOINT_NAMES) if n.split("_", 1)[-1] in _HAND)


def _hand_parents(wrist: int, first: int) -> list[int]:
    parents = []
    for finger in range(5):
        base = first + 3 * finger
        parents += [wrist, base, base + 1]
    return parents


PARENTS: tuple[int, ...] = (
    -1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 15, 15, 15,
    *_hand_parents(20, 25),
    *_hand_parents(21, 40),
)  # fmt: skip

LOWER_BODY_JOINTS: tuple[int, ...] = (1, 2, 4, 5, 7, 8, 10, 11)
UPPER_BODY_JOINTS: tuple[int, ...] = tuple(j for j in range(NUM_JOINTS) if j not in LOWER_BODY_JOINTS)
ARM_JOINTS: tuple[int, ...] = (16, 17, 18, 19, 20, 21)
WRIST_JOINTS: tuple[int, ...] = (20, 21)
JAW, LEFT_EYE, RIGHT_EYE, HEAD = 22, 23, 24, 15

#: Approximate jaw position relative to the head joint (metres; Y-up, +Z forward).
JAW_OFFSET = np.array([0.0, -0.02, 0.03], np.float32)
#: Approximate left-eye position relative to the head joint; the right eye mirrors X.
EYE_OFFSET = np.array([0.03, 0.06, 0.08], np.float32)

_SHAPE_DIM = 10


def _mannequin_names() -> dict[str, int]:
    """SMPL-X index of every mannequin-x joint name that exists in SMPL-X (52 of them)."""
    caps = ("Pelvis", "L_Hip", "R_Hip", "Spine1", "L_Knee", "R_Knee", "Spine2", "L_Ankle", "R_Ankle",
            "Spine3", "L_Foot", "R_Foot", "Neck", "L_Collar", "R_Collar", "Head", "L_Shoulder",
            "R_Shoulder", "L_Elbow", "R_Elbow", "L_Wrist", "R_Wrist")  # fmt: skip
    mapping = {name: i for i, name in enumerate(caps)}
    for side, first in (("L", 25), ("R", 40)):
        for k, name in enumerate(_HAND):
            mapping[f"{side}_{name.capitalize()}"] = first + k
    return mapping


MANNEQUIN_TO_SMPLX: dict[str, int] = _mannequin_names()


def shape_key(shape: np.ndarray | None) -> tuple[float, ...]:
    """The first 10 shape coefficients as a hashable tuple (zero-padded; None = the mean body)."""
    if shape is None:
        return (0.0,) * _SHAPE_DIM
    betas = np.asarray(shape, dtype=np.float64).reshape(-1)[:_SHAPE_DIM]
    if not np.all(np.isfinite(betas)):
        raise ValueError("shape coefficients must be finite")
    betas = np.pad(betas, (0, _SHAPE_DIM - betas.size))
    return tuple(float(b) for b in betas.astype(np.float32))


@lru_cache(maxsize=16)
def _rest_joints_cached(key: tuple[float, ...]) -> np.ndarray:
    from mannequin import Mannequin

    model = Mannequin("wooden", shape=np.asarray(key, np.float32), flat_hand_mean=True)
    positions = model.joint_transforms(model.rest_pose())[:, :3, 3]
    joints = np.zeros((NUM_JOINTS, 3), np.float32)
    found = set()
    for m_index, name in enumerate(model.joint_names):
        if name in MANNEQUIN_TO_SMPLX:
            joints[MANNEQUIN_TO_SMPLX[name]] = positions[m_index]
            found.add(name)
    missing = set(MANNEQUIN_TO_SMPLX) - found
    if missing:  # pragma: no cover - guards against a mannequin-x release renaming joints
        raise RuntimeError(f"mannequin-x skeleton lacks joints {sorted(missing)}")
    mirror = np.array([-1.0, 1.0, 1.0], np.float32)
    joints[JAW] = joints[HEAD] + JAW_OFFSET
    joints[LEFT_EYE] = joints[HEAD] + EYE_OFFSET
    joints[RIGHT_EYE] = joints[HEAD] + EYE_OFFSET * mirror
    joints.setflags(write=False)
    return joints


def rest_joints(shape: np.ndarray | None = None) -> np.ndarray:
    """Rest (zero-pose) joint positions ``[55, 3]`` float32 in metres, Y-up, SMPL-X order.

    Args:
        shape: SMPL-X shape coefficients ``[B]``; the first 10 are used (zero-padded when
            shorter), ``None`` = the mean body.

    The 52 body and finger joints come from ``mannequin-x`` (wooden design, flat hand mean).
    Jaw and eyes are NOT in mannequin-x: they are placed at the fixed approximate offsets
    ``JAW_OFFSET`` (2 cm down, 3 cm forward) and ``EYE_OFFSET`` (+-3 cm sideways, 6 cm up,
    8 cm forward) from the head joint, independent of shape. Results are cached per shape.
    """
    return _rest_joints_cached(shape_key(shape)).copy()


def rest_offsets(shape: np.ndarray | None = None) -> np.ndarray:
    """Rest bone offsets ``[55, 3]``: joint minus parent position; row 0 is the pelvis position."""
    joints = rest_joints(shape)
    offsets = joints.copy()
    parents = np.asarray(PARENTS[1:])
    offsets[1:] = joints[1:] - joints[parents]
    return offsets


def joint_depths() -> tuple[int, ...]:
    """Depth of every joint in the tree ``[55]`` (pelvis = 0)."""
    depths = [0] * NUM_JOINTS
    for j in range(1, NUM_JOINTS):
        depths[j] = depths[PARENTS[j]] + 1
    return tuple(depths)
