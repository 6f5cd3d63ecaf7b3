"""Skeletons the exports can name their bones by: SMPL-X's own, or Mixamo's.

A :class:`Rig` keeps some of the 55 SMPL-X joints, in an order where every parent comes before its children,
and gives each a bone name. The bones keep SMPL-X's rest geometry (a T-pose, Y up, facing +Z) and its local
rotations, so every bone of a rig points where the SMPL-X joint it stands for points, at every frame.

- ``smplx``: all 55 joints by their SMPL-X names (:data:`~emogesture.motion.JOINT_NAMES`).
- ``mixamo``: the 52 joints Mixamo's humanoid rig has (not the jaw and the eyes), named as Adobe Mixamo
  names them (``mixamorig:Hips``, ``Spine``, ``Spine1``, ``Spine2``, ``Neck``, ``Head``,
  ``LeftShoulder``, ``LeftArm``, ``LeftForeArm``, ``LeftHand``, ``LeftHandIndex1``-``3`` ...,
  ``LeftUpLeg``, ``LeftLeg``, ``LeftFoot``, ``LeftToeBase``), in the same hierarchy: the name game engines'
  humanoid importers (Unity's Humanoid avatar, Unreal's IK retargeter) map by themselves.
"""

from __future__ import annotations

from dataclasses import dataclass

from emogesture.errors import EmogestureError
from emogesture.motion.skeleton import JOINT_NAMES, PARENTS


@dataclass(frozen=True)
class Rig:
    """``joints``: SMPL-X joint indices kept, parents first; ``names``: a bone name for each; ``parents``:
    each bone's parent as an index into ``joints`` (-1 for the root)."""

    name: str
    joints: tuple[int, ...]
    names: tuple[str, ...]
    parents: tuple[int, ...]

    def children(self, bone: int) -> list[int]:
        return [b for b, p in enumerate(self.parents) if p == bone]


def _rig(name: str, names: dict[int, str]) -> Rig:
    joints = tuple(j for j in range(len(JOINT_NAMES)) if j in names)
    position = {j: k for k, j in enumerate(joints)}
    parents = tuple(-1 if PARENTS[j] < 0 else position[PARENTS[j]] for j in joints)
    return Rig(name, joints, tuple(names[j] for j in joints), parents)


def _mixamo_names() -> dict[int, str]:
    body = {"pelvis": "Hips", "spine1": "Spine", "spine2": "Spine1", "spine3": "Spine2", "neck": "Neck",
            "head": "Head", "collar": "Shoulder", "shoulder": "Arm", "elbow": "ForeArm", "wrist": "Hand",
            "hip": "UpLeg", "knee": "Leg", "ankle": "Foot", "foot": "ToeBase"}
    fingers = {"thumb": "Thumb", "index": "Index", "middle": "Middle", "ring": "Ring", "pinky": "Pinky"}
    names = {}
    for j, joint in enumerate(JOINT_NAMES):
        side, _, part = joint.partition("_")
        if part == "":  # pelvis, spine1..3, neck, head, jaw
            if joint in body:
                names[j] = body[joint]
        elif side in ("left", "right") and part in body:
            names[j] = side.capitalize() + body[part]
        elif side in ("left", "right") and part[:-1] in fingers:
            names[j] = f"{side.capitalize()}Hand{fingers[part[:-1]]}{part[-1]}"
    return {j: f"mixamorig:{n}" for j, n in names.items()}


RIGS: dict[str, Rig] = {
    "smplx": _rig("smplx", dict(enumerate(JOINT_NAMES))),
    "mixamo": _rig("mixamo", _mixamo_names()),
}


def rig_named(name: str) -> Rig:
    """The rig called ``name`` (``smplx`` or ``mixamo``); a one-line error for another name."""
    if name not in RIGS:
        raise EmogestureError(f"--skeleton {name!r}: choose {' or '.join(RIGS)}")
    return RIGS[name]
