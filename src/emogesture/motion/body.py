"""The body that turns SMPL-X poses into joint positions: ``SkeletonBody``, a licence-free differentiable
forward-kinematics layer over the mannequin-x rest skeleton (no SMPL-X model files are needed or read)."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import torch

from emogesture.motion.features import MotionFeatureSpec, split_features
from emogesture.motion.rotations import axis_angle_to_matrix, rot6d_planes_to_matrix
from emogesture.motion.skeleton import PARENTS, joint_depths, rest_joints, rest_offsets
from emogesture.types import NUM_JOINTS


def _check_inputs(poses: torch.Tensor, trans: torch.Tensor | None, tail: tuple[int, ...]) -> None:
    if poses.dim() < len(tail) + 1 or tuple(poses.shape[-len(tail):]) != tail:
        raise ValueError(f"poses must be [..., {', '.join(map(str, tail))}], got {tuple(poses.shape)}")
    lead = tuple(poses.shape[: -len(tail)])
    if trans is not None and tuple(trans.shape) != lead + (3,):
        raise ValueError(f"trans must be {lead + (3,)}, got {tuple(trans.shape)}")


@lru_cache(maxsize=16)
def _kinematic_plan(rotated: tuple[int, ...]) -> tuple[tuple[int, ...], tuple[tuple, ...]]:
    """How :class:`SkeletonBody` walks the tree when only the joints ``rotated`` have a local rotation
    (the others stay at rest, e.g. the legs of upper-body features).

    Returns ``(rows, depths)``. World rotations are formed only for joints with children (a leaf's is
    never used): ``rows`` are the rows of the rotations passed in that are used, depth by depth (the
    rotations of leaves are not even converted). ``depths`` has one entry per depth ``d ≥ 1``:
    ``(joints, position_parents, rotation_parents, turned, turned_parents, kept_parents)``: the joints
    at depth ``d`` (their positions in this order); their parents' slots among depth ``d - 1``'s
    positions and world rotations; how many of ``rows`` this depth takes (joints with children and a
    local rotation, whose world rotation is their parent's times it, the parents' slots in
    ``turned_parents``); ``kept_parents``: the slots of the parents of joints with children and no
    local rotation, which take their parent's world rotation as it is (after the turned ones).
    The pelvis (depth 0) must be among ``rotated``.
    """
    depths = joint_depths()
    levels = [[j for j in range(NUM_JOINTS) if depths[j] == d] for d in range(max(depths) + 1)]
    has_children = set(PARENTS[1:])
    row = {j: k for k, j in enumerate(rotated)}
    rows = [row[0]]
    entries: list[tuple] = []
    rotation_slots = {0: 0}  # joint -> slot among the previous depth's world rotations
    for d in range(1, len(levels)):
        joints = levels[d]
        position_slot = {j: k for k, j in enumerate(levels[d - 1])}
        parents = [PARENTS[j] for j in joints]
        turned = [j for j in joints if j in has_children and j in row]
        kept = [j for j in joints if j in has_children and j not in row]
        rows += [row[j] for j in turned]
        entries.append((
            tuple(joints), tuple(position_slot[p] for p in parents), tuple(rotation_slots[p] for p in parents),
            len(turned), tuple(rotation_slots[PARENTS[j]] for j in turned),
            tuple(rotation_slots[PARENTS[j]] for j in kept),
        ))  # fmt: skip
        rotation_slots = {j: k for k, j in enumerate(turned + kept)}
    return tuple(rows), tuple(entries)


class SkeletonBody(torch.nn.Module):
    """Differentiable forward kinematics on the mannequin-x rest skeleton (see ``skeleton.py``).

    The pelvis sits at its rest position plus ``trans`` and turns by joint 0's rotation (the
    SMPL-X global orientation); every other joint ``j`` is at
    ``pos[parent] + R_world[parent] @ offset[j]`` with ``R_world[j] = R_world[parent] @ R_local[j]``.
    Joints are processed one tree depth at a time (11 steps), vectorised over the frames, in
    coordinate-plane layout (``[joints, 3, 3, frames]``: every gather takes whole planes of frames, and
    a depth's bones and rotation products are multiply-adds of planes). Leaves' world rotations are not formed,
    nor products with the rest rotation of joints that upper-body features leave out.
    """

    def __init__(self, shape: np.ndarray | None = None) -> None:
        """Args: shape: SMPL-X shape coefficients (first 10 used), None = mean body."""
        super().__init__()
        self.register_buffer("offsets", torch.from_numpy(rest_offsets(shape)), persistent=False)
        self.register_buffer("rest", torch.from_numpy(rest_joints(shape)), persistent=False)
        depths = joint_depths()
        order = sorted(range(NUM_JOINTS), key=lambda j: depths[j])  # stable: the plan's depth order
        self.register_buffer("_unsort", torch.tensor(np.argsort(order)), persistent=False)
        self._plans: dict = {}

    def forward(self, poses: torch.Tensor, trans: torch.Tensor | None = None) -> torch.Tensor:
        """Axis-angle ``poses [B, T, 55, 3]`` (or ``[T, 55, 3]``, any leading dims) and optional
        ``trans [B, T, 3]`` -> joint positions ``[B, T, 55, 3]`` in metres."""
        _check_inputs(poses, trans, (NUM_JOINTS, 3))
        return self.forward_matrices(axis_angle_to_matrix(poses), trans)

    def forward_features(self, features: torch.Tensor, spec: MotionFeatureSpec | None = None) -> torch.Tensor:
        """Raw motion features ``[..., T, D]`` -> joint positions ``[..., T, 55, 3]`` (differentiable).

        The same as ``forward_matrices(*features_to_matrices(features, spec))`` without forming the
        rest rotations of the joints the features leave out, nor the rotations of leaves."""
        spec = spec or MotionFeatureSpec()
        rot6d, trans = split_features(features, spec)
        if 0 not in spec.joints:
            raise ValueError("forward kinematics from features needs the pelvis (joint 0) among spec.joints")
        rows, plan = self._plan(spec.joints, features.device)
        planes = rot6d.reshape(-1, len(spec.joints), 6).permute(1, 2, 0).index_select(0, rows)  # [R, 6, N]
        trans = None if trans is None else trans.reshape(-1, 3)
        joints = self._kinematics(rot6d_planes_to_matrix(planes), plan, trans)
        return joints.reshape(*features.shape[:-1], NUM_JOINTS, 3)

    def forward_matrices(self, rotations: torch.Tensor, trans: torch.Tensor | None = None) -> torch.Tensor:
        """Local rotation matrices ``[..., 55, 3, 3]`` and optional ``trans [..., 3]``
        -> joint positions ``[..., 55, 3]``."""
        _check_inputs(rotations, trans, (NUM_JOINTS, 3, 3))
        lead = rotations.shape[:-3]
        rows, plan = self._plan(tuple(range(NUM_JOINTS)), rotations.device)
        local = rotations.reshape(-1, NUM_JOINTS, 9).permute(1, 2, 0).index_select(0, rows)  # [R, 9, N]
        trans = None if trans is None else trans.reshape(-1, 3)
        return self._kinematics(local.unflatten(1, (3, 3)), plan, trans).reshape(*lead, NUM_JOINTS, 3)

    def _plan(self, rotated: tuple[int, ...], device: torch.device) -> tuple[torch.Tensor, list[tuple]]:
        """:func:`_kinematic_plan` with its indices as tensors on ``device`` (made once): an index that takes
        every row of the depth above in order is None (the rows are used as they are), and each depth's
        entry ends with its number of kept parents."""
        key = (rotated, device)
        if key not in self._plans:
            rows, entries = _kinematic_plan(rotated)

            def index(slots: tuple[int, ...], source: int) -> torch.Tensor | None:
                """The slots as an index, or None where they take all ``source`` rows in order."""
                if slots == tuple(range(source)):
                    return None
                return torch.tensor(slots, dtype=torch.long, device=device)

            plan, positions, rotations = [], 1, 1  # rows at the depth above: the pelvis's
            for joints, pos, rot, turned, turned_parents, kept in entries:
                plan.append((torch.tensor(joints, dtype=torch.long, device=device), index(pos, positions),
                             index(rot, rotations), turned, index(turned_parents, rotations),
                             index(kept, rotations), len(kept)))
                positions, rotations = len(joints), turned + len(kept)
            self._plans[key] = (torch.tensor(rows, dtype=torch.long, device=device), plan)
        return self._plans[key]

    def _kinematics(self, local: torch.Tensor, plan: list[tuple], trans: torch.Tensor | None) -> torch.Tensor:
        """The plan's local rotations ``[R, 3, 3, N]`` (its ``rows``, depth by depth, the pelvis first; each
        matrix entry a contiguous plane over the N frames) and ``trans [N, 3]`` or None -> joint positions
        ``[N, 55, 3]``. In this layout a depth's bones and rotation products are a few multiply-adds of
        whole planes (batched 3 × 3 matrix products were slower: forward and backward of a training
        batch's kinematics with the 6D conversion 67 -> 48 ms, without gradients 21 -> 12.5)."""
        n = local.shape[-1]
        offsets = self.offsets.to(dtype=local.dtype)
        by_depth = local.split([1] + [entry[3] for entry in plan])
        world_rot = by_depth[0]  # [1, 3, 3, N]: the pelvis
        root = offsets[0, :, None].expand(3, n) if trans is None else offsets[0, :, None] + trans.to(local.dtype).T
        world_pos = [root[None]]  # [1, 3, N]
        for (joints, position_parents, rotation_parents, turned, turned_parents, kept_parents, kept), turns in zip(
            plan, by_depth[1:]
        ):
            bone = _rotate(_take(world_rot, rotation_parents), offsets[joints])  # [k, 3, N]
            world_pos.append(_take(world_pos[-1], position_parents) + bone)
            parts = []
            if turned:
                parts.append(_compose(_take(world_rot, turned_parents), turns))
            if kept:
                parts.append(_take(world_rot, kept_parents))
            if parts:
                world_rot = parts[0] if len(parts) == 1 else torch.cat(parts)
        positions = torch.cat(world_pos).index_select(0, self._unsort)  # [55, 3, N]
        return positions.permute(2, 0, 1)


def _take(rows: torch.Tensor, index: torch.Tensor | None) -> torch.Tensor:
    """``rows[index]`` along dim 0; ``index`` None: all rows as they are (no copy, nor its backward)."""
    return rows if index is None else rows.index_select(0, index)


def _rotate(rotations: torch.Tensor, vectors: torch.Tensor) -> torch.Tensor:
    """``rotations [k, 3, 3, N]`` (planes) times ``vectors [k, 3]`` (one per k) -> ``[k, 3, N]``."""
    c0, c1, c2 = rotations.unbind(2)  # the columns [k, 3, N] (unbind's backward is one stack, not 3 fills)
    v = vectors[:, :, None, None]
    return c0 * v[:, 0] + c1 * v[:, 1] + c2 * v[:, 2]


def _compose(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Matrix products ``a @ b`` of planes ``[k, 3, 3, N]``: entry (i, j) = sum over l of a[i, l] b[l, j]."""
    (a0, a1, a2), (b0, b1, b2) = a.unbind(2), b.unbind(1)  # a's columns, b's rows: [k, 3, N]
    return a0[:, :, None] * b0[:, None] + a1[:, :, None] * b1[:, None] + a2[:, :, None] * b2[:, None]
