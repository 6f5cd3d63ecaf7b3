"""Bodies that turn SMPL-X poses into joint positions (and, with SMPL-X files, vertices).

``SkeletonBody`` is a licence-free differentiable forward-kinematics layer over the mannequin-x
rest skeleton; ``SMPLXBody`` wraps the user's own SMPL-X model files through the optional
``smplx`` package. ``load_body`` picks one.
"""

from __future__ import annotations

from os import PathLike
from pathlib import Path

import numpy as np
import torch

from emogesture.errors import EmogestureError, InputFileError
from emogesture.motion.features import MotionFeatureSpec, features_to_matrices
from emogesture.motion.rotations import axis_angle_to_matrix
from emogesture.motion.skeleton import PARENTS, joint_depths, rest_joints, rest_offsets
from emogesture.types import NUM_JOINTS


def _check_inputs(poses: torch.Tensor, trans: torch.Tensor | None, tail: tuple[int, ...]) -> None:
    if poses.dim() < len(tail) + 1 or tuple(poses.shape[-len(tail):]) != tail:
        raise ValueError(f"poses must be [..., {', '.join(map(str, tail))}], got {tuple(poses.shape)}")
    lead = tuple(poses.shape[: -len(tail)])
    if trans is not None and tuple(trans.shape) != lead + (3,):
        raise ValueError(f"trans must be {lead + (3,)}, got {tuple(trans.shape)}")


class SkeletonBody(torch.nn.Module):
    """Differentiable forward kinematics on the mannequin-x rest skeleton (see ``skeleton.py``).

    The pelvis sits at its rest position plus ``trans`` and turns by joint 0's rotation (the
    SMPL-X global orientation); every other joint ``j`` is at
    ``pos[parent] + R_world[parent] @ offset[j]`` with ``R_world[j] = R_world[parent] @ R_local[j]``.
    Joints are processed one tree depth at a time (11 steps), vectorised over the batch.
    """

    def __init__(self, shape: np.ndarray | None = None) -> None:
        """Args: shape: SMPL-X shape coefficients (first 10 used), None = mean body."""
        super().__init__()
        self.register_buffer("offsets", torch.from_numpy(rest_offsets(shape)), persistent=False)
        self.register_buffer("rest", torch.from_numpy(rest_joints(shape)), persistent=False)
        depths = joint_depths()
        levels = [[j for j in range(NUM_JOINTS) if depths[j] == d] for d in range(max(depths) + 1)]
        self._num_levels = len(levels)
        for d in range(1, len(levels)):
            slot = {j: k for k, j in enumerate(levels[d - 1])}
            self.register_buffer(f"_joints_{d}", torch.tensor(levels[d]), persistent=False)
            parent_slots = torch.tensor([slot[PARENTS[j]] for j in levels[d]])
            self.register_buffer(f"_parents_{d}", parent_slots, persistent=False)
        order = [j for level in levels for j in level]
        self._level_sizes = [len(level) for level in levels]
        self.register_buffer("_order", torch.tensor(order), persistent=False)
        self.register_buffer("_unsort", torch.tensor(np.argsort(order)), persistent=False)

    def forward(self, poses: torch.Tensor, trans: torch.Tensor | None = None) -> torch.Tensor:
        """Axis-angle ``poses [B, T, 55, 3]`` (or ``[T, 55, 3]``, any leading dims) and optional
        ``trans [B, T, 3]`` -> joint positions ``[B, T, 55, 3]`` in metres."""
        _check_inputs(poses, trans, (NUM_JOINTS, 3))
        return self.forward_matrices(axis_angle_to_matrix(poses), trans)

    def forward_features(self, features: torch.Tensor, spec: MotionFeatureSpec | None = None) -> torch.Tensor:
        """Raw motion features ``[..., T, D]`` -> joint positions ``[..., T, 55, 3]`` (differentiable)."""
        return self.forward_matrices(*features_to_matrices(features, spec))

    def forward_matrices(self, rotations: torch.Tensor, trans: torch.Tensor | None = None) -> torch.Tensor:
        """Local rotation matrices ``[..., 55, 3, 3]`` and optional ``trans [..., 3]``
        -> joint positions ``[..., 55, 3]``."""
        _check_inputs(rotations, trans, (NUM_JOINTS, 3, 3))
        lead = rotations.shape[:-3]
        local = rotations.reshape(-1, NUM_JOINTS, 3, 3)
        offsets = self.offsets.to(dtype=local.dtype)
        root = offsets[0].expand(local.shape[0], 3)
        if trans is not None:
            root = root + trans.reshape(-1, 3).to(local.dtype)
        # one gather into depth order, then each depth is a contiguous part (the backward of indexing
        # every depth out of ``local`` would write a full-size zero gradient per depth)
        by_depth = local.index_select(1, self._order).split(self._level_sizes, dim=1)
        world_rot = [by_depth[0]]
        world_pos = [root[:, None]]
        for d in range(1, self._num_levels):
            joints = getattr(self, f"_joints_{d}")
            parents = getattr(self, f"_parents_{d}")
            # index_select, not indexing: its backward adds into the gradient (index_add_) where
            # indexing's sorts the indices first (index_put_ with accumulate), 10 % of a training FK
            parent_rot = world_rot[-1].index_select(1, parents)
            bone = torch.einsum("nkij,kj->nki", parent_rot, offsets[joints])
            world_pos.append(world_pos[-1].index_select(1, parents) + bone)
            world_rot.append(parent_rot @ by_depth[d])
        positions = torch.cat(world_pos, dim=1).index_select(1, self._unsort)
        return positions.reshape(*lead, NUM_JOINTS, 3)


def _resolve_model_file(model_path: str | PathLike[str], gender: str) -> Path:
    path = Path(model_path)
    if not path.exists():
        raise InputFileError(path, "SMPL-X model file not found")
    if path.is_dir():
        stem = f"SMPLX_{gender.upper()}"
        for folder in (path, path / "smplx"):
            for name in (f"{stem}.npz", f"{stem}.pkl", f"{stem}_2020.npz"):
                if (folder / name).is_file():
                    return folder / name
        raise InputFileError(path, f"no {stem}.npz or {stem}.pkl SMPL-X model file in this folder")
    if path.suffix.lower() not in (".npz", ".pkl"):
        raise InputFileError(path, "SMPL-X model file must be .npz or .pkl")
    return path


class SMPLXBody(torch.nn.Module):
    """The user's SMPL-X model (needs ``pip install 'emogesture[smplx]'`` and licensed model files).

    Built with ``use_pca=False`` and ``flat_hand_mean=True`` (BEAT2's convention); as many shape
    (up to 300) and expression (up to 100) coefficients as the model file holds.
    """

    def __init__(
        self, model_path: str | PathLike[str], gender: str = "neutral", betas: np.ndarray | None = None
    ) -> None:
        """Args: model_path: a SMPL-X .npz/.pkl file or a folder holding ``SMPLX_<GENDER>.npz``;
        gender: 'neutral', 'male' or 'female'; betas: shape ``[B]`` (truncated/zero-padded)."""
        super().__init__()
        path = _resolve_model_file(model_path, gender)
        try:
            import smplx
        except ImportError as err:
            raise EmogestureError(
                "the SMPL-X body needs the 'smplx' package: pip install 'emogesture[smplx]'"
            ) from err
        try:
            self.model = smplx.SMPLX(
                str(path), gender=gender, ext=path.suffix.lower()[1:], use_pca=False, flat_hand_mean=True,
                num_betas=300, num_expression_coeffs=100, use_face_contour=False, batch_size=1,
            )  # fmt: skip
        except Exception as err:  # smplx raises assorted errors for a bad file
            raise InputFileError(path, f"cannot load SMPL-X model ({type(err).__name__}: {err})") from err
        self.num_betas = int(self.model.num_betas)
        self.num_expressions = int(self.model.num_expression_coeffs)
        shape = np.zeros(self.num_betas, np.float32)
        if betas is not None:
            given = np.asarray(betas, np.float32).reshape(-1)[: self.num_betas]
            shape[: given.size] = given
        self.register_buffer("betas", torch.from_numpy(shape), persistent=False)

    def _run(self, poses: torch.Tensor, trans: torch.Tensor | None, expressions: torch.Tensor | None):
        _check_inputs(poses, trans, (NUM_JOINTS, 3))
        lead = poses.shape[:-2]
        p = poses.reshape(-1, NUM_JOINTS, 3).to(self.betas.dtype)
        n = p.shape[0]
        expr = p.new_zeros(n, self.num_expressions)
        if expressions is not None:
            e = expressions.reshape(n, -1).to(p.dtype)[:, : self.num_expressions]
            expr[:, : e.shape[1]] = e
        out = self.model(
            betas=self.betas[None].expand(n, -1),
            global_orient=p[:, 0],
            body_pose=p[:, 1:22].reshape(n, 63),
            jaw_pose=p[:, 22],
            leye_pose=p[:, 23],
            reye_pose=p[:, 24],
            left_hand_pose=p[:, 25:40].reshape(n, 45),
            right_hand_pose=p[:, 40:55].reshape(n, 45),
            expression=expr,
            transl=None if trans is None else trans.reshape(n, 3).to(p.dtype),
            return_verts=True,
        )
        return lead, out

    def forward(self, poses: torch.Tensor, trans: torch.Tensor | None = None) -> torch.Tensor:
        """Axis-angle ``poses [B, T, 55, 3]`` (any leading dims), ``trans [B, T, 3]``
        -> joint positions ``[B, T, 55, 3]`` (SMPL-X's first 55 joints)."""
        lead, out = self._run(poses, trans, None)
        return out.joints[:, :NUM_JOINTS].reshape(*lead, NUM_JOINTS, 3)

    def vertices(
        self, poses: torch.Tensor, trans: torch.Tensor | None = None, expressions: torch.Tensor | None = None
    ) -> torch.Tensor:
        """Posed mesh vertices ``[B, T, V, 3]`` for ``poses [B, T, 55, 3]`` (+ ``expressions [B, T, E]``)."""
        lead, out = self._run(poses, trans, expressions)
        return out.vertices.reshape(*lead, -1, 3)


def load_body(
    model_path: str | PathLike[str] | None = None, gender: str = "neutral", shape: np.ndarray | None = None
) -> torch.nn.Module:
    """``SMPLXBody(model_path)`` when a model path is given, else the licence-free ``SkeletonBody``.

    Both map ``poses [B, T, 55, 3]`` (+ ``trans [B, T, 3]``) to joints ``[B, T, 55, 3]``.
    """
    if model_path is not None:
        return SMPLXBody(model_path, gender=gender, betas=shape)
    return SkeletonBody(shape)
