"""SMPL-X sequences as BVH motion capture files (Blender, Unity, Maya, MotionBuilder).

The file's skeleton is the SMPL-X kinematic tree with SMPL-X joint names (``pelvis``, ``left_hip``,
... ``right_thumb3``; all 55 joints), or with ``skeleton="mixamo"`` Mixamo's 52 bones by Mixamo's names
(:mod:`emogesture.motion.rigs`), and the rest bone offsets of the body used
(:func:`emogesture.motion.rest_offsets` for the sequence's shape, the licence-free skeleton), so that
joint world positions computed from the file equal :class:`emogesture.motion.SkeletonBody`'s.

Conventions, written into every file's ``HIERARCHY`` comment-free body and documented here:

- units: metres; axes: Y up, the body facing +Z, its left along +X (SMPL-X's own frame);
- 30 fps (the sequence's rate), one MOTION line per frame;
- the root ``pelvis`` has ``OFFSET 0 0 0`` and six channels ``Xposition Yposition Zposition
  Zrotation Yrotation Xrotation``; its position channels hold the pelvis's world position (rest
  pelvis + ``trans``), so readers that add the OFFSET and readers that replace it agree;
- every other joint has three channels ``Zrotation Yrotation Xrotation``, Euler angles in degrees of
  its local rotation, ``R = Rz · Ry · Rx`` (intrinsic Z, then Y, then X);
- leaf joints end in an ``End Site`` half their own bone's length beyond them;
- joints the model does not animate (legs, fingers, jaw and eyes for the gesture model) keep the
  rotations the sequence holds: zero, the rest pose.
"""

from __future__ import annotations

import io
from os import PathLike
from pathlib import Path

import numpy as np
import torch

from emogesture.fileio import atomic_output
from emogesture.motion import PARENTS, axis_angle_to_matrix, matrix_to_euler_zyx, rest_joints
from emogesture.motion.rigs import RIGS, Rig, rig_named
from emogesture.types import SMPLXSequence

ROOT_CHANNELS = "Xposition Yposition Zposition Zrotation Yrotation Xrotation"
JOINT_CHANNELS = "Zrotation Yrotation Xrotation"


def bvh_hierarchy(offsets: np.ndarray, rig: Rig = RIGS["smplx"]) -> tuple[str, list[int]]:
    """The ``HIERARCHY`` section for rest ``offsets [55, 3]`` (row 0 ignored: the root's is 0) and the
    SMPL-X joints whose channels appear in a MOTION line, in order (depth first, SMPL-X child order)."""
    lines, order = ["HIERARCHY"], []

    def joint(b: int, depth: int) -> None:
        j = rig.joints[b]
        pad = "  " * depth
        head = "ROOT" if b == 0 else "JOINT"
        off = np.zeros(3) if b == 0 else offsets[j]
        lines.extend([f"{pad}{head} {rig.names[b]}", f"{pad}{{",
                      f"{pad}  OFFSET {off[0]:.6f} {off[1]:.6f} {off[2]:.6f}",
                      f"{pad}  CHANNELS {6 if b == 0 else 3} {ROOT_CHANNELS if b == 0 else JOINT_CHANNELS}"])
        order.append(j)
        for k in rig.children(b):
            joint(k, depth + 1)
        if not rig.children(b):
            end = 0.5 * offsets[j]
            lines.extend([f"{pad}  End Site", f"{pad}  {{", f"{pad}    OFFSET {end[0]:.6f} {end[1]:.6f} {end[2]:.6f}",
                          f"{pad}  }}"])
        lines.append(f"{pad}}}")

    joint(0, 0)
    return "\n".join(lines) + "\n", order


def bvh_channels(seq: SMPLXSequence, order: list[int], root_rest: np.ndarray) -> np.ndarray:
    """The MOTION values ``[T, 3 + 3 * len(order)]``: root position (m), then per joint in ``order`` its
    ``(Z, Y, X)`` Euler angles in degrees."""
    with torch.no_grad():
        rot = axis_angle_to_matrix(torch.from_numpy(seq.poses.astype(np.float64)))
        euler = np.degrees(matrix_to_euler_zyx(rot).numpy())  # [T, 55, 3] as (z, y, x)
    position = seq.trans.astype(np.float64) + root_rest[None]
    return np.concatenate([position, euler[:, order].reshape(seq.num_frames, -1)], axis=1)


def sequence_to_bvh(seq: SMPLXSequence, skeleton: str = "smplx") -> str:
    """The whole BVH text of ``seq`` with the bones of ``skeleton`` (``smplx`` or ``mixamo``; see the module
    docstring for its conventions)."""
    joints = rest_joints(seq.betas)
    offsets = joints.copy()
    offsets[1:] = joints[1:] - joints[np.asarray(PARENTS[1:])]
    hierarchy, order = bvh_hierarchy(offsets, rig_named(skeleton))
    values = bvh_channels(seq, order, joints[0].astype(np.float64))
    out = io.StringIO()
    out.write(hierarchy)
    out.write(f"MOTION\nFrames: {seq.num_frames}\nFrame Time: {1.0 / float(seq.fps):.8f}\n")
    np.savetxt(out, values, fmt="%.6f", delimiter=" ")
    return out.getvalue()


def save_bvh(seq: SMPLXSequence, path: str | PathLike[str], overwrite: bool = False,
             skeleton: str = "smplx") -> Path:
    """Write ``seq`` as a BVH file with the bones of ``skeleton``, atomically; refuses an existing file
    unless ``overwrite``."""
    text = sequence_to_bvh(seq, skeleton)
    with atomic_output(path, overwrite) as tmp:
        tmp.write_text(text)
    return Path(path)
