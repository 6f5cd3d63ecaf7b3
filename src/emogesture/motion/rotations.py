"""Rotation conversions in torch, batched over any leading dims and differentiable.

Axis-angle (rotation vector) <-> rotation matrix goes through ``roma``. The continuous 6D
representation (Zhou et al., CVPR 2019) is defined here and only here:

    6D = the first two COLUMNS of the rotation matrix, column 0 then column 1:
    ``[R00, R10, R20, R01, R11, R21]``.

``rot6d_to_matrix`` rebuilds the matrix by Gram-Schmidt, so any 6D vector whose two halves are
not parallel maps to a valid rotation; ``rot6d_to_matrix(matrix_to_rot6d(R)) == R``.
"""

from __future__ import annotations

import roma
import torch

_EPS = 1e-8


def axis_angle_to_matrix(axis_angle: torch.Tensor) -> torch.Tensor:
    """Rotation vectors ``[..., 3]`` (angle = norm, radians) -> rotation matrices ``[..., 3, 3]``."""
    _check_last(axis_angle, (3,), "axis_angle")
    return roma.rotvec_to_rotmat(axis_angle)


def matrix_to_axis_angle(matrix: torch.Tensor) -> torch.Tensor:
    """Rotation matrices ``[..., 3, 3]`` -> rotation vectors ``[..., 3]`` with angle in ``[0, pi]``."""
    _check_last(matrix, (3, 3), "matrix")
    return roma.rotmat_to_rotvec(matrix)


def matrix_to_rot6d(matrix: torch.Tensor) -> torch.Tensor:
    """Rotation matrices ``[..., 3, 3]`` -> 6D ``[..., 6]``: first column, then second column."""
    _check_last(matrix, (3, 3), "matrix")
    return torch.cat([matrix[..., :, 0], matrix[..., :, 1]], dim=-1)


def rot6d_to_matrix(rot6d: torch.Tensor) -> torch.Tensor:
    """6D ``[..., 6]`` (two columns, see module doc) -> rotation matrices ``[..., 3, 3]``.

    Gram-Schmidt: ``b1 = a1/|a1|``, ``b2`` = ``a2`` minus its ``b1`` component, normalised,
    ``b3 = b1 x b2``; the result has columns ``[b1, b2, b3]``.
    """
    _check_last(rot6d, (6,), "rot6d")
    a1, a2 = rot6d[..., :3], rot6d[..., 3:]
    b1 = a1 / a1.norm(dim=-1, keepdim=True).clamp_min(_EPS)
    b2 = a2 - (b1 * a2).sum(dim=-1, keepdim=True) * b1
    b2 = b2 / b2.norm(dim=-1, keepdim=True).clamp_min(_EPS)
    b3 = torch.linalg.cross(b1, b2, dim=-1)
    return torch.stack([b1, b2, b3], dim=-1)


def axis_angle_to_rot6d(axis_angle: torch.Tensor) -> torch.Tensor:
    """Rotation vectors ``[..., 3]`` -> 6D ``[..., 6]``."""
    return matrix_to_rot6d(axis_angle_to_matrix(axis_angle))


def rot6d_to_axis_angle(rot6d: torch.Tensor) -> torch.Tensor:
    """6D ``[..., 6]`` -> rotation vectors ``[..., 3]``."""
    return matrix_to_axis_angle(rot6d_to_matrix(rot6d))


def interpolate_rotations(a: torch.Tensor, b: torch.Tensor, w: torch.Tensor | float) -> torch.Tensor:
    """Geodesic (slerp) blend from ``a`` (``w = 0``) to ``b`` (``w = 1``).

    Args:
        a, b: rotations of the same shape, either matrices ``[..., 3, 3]`` or 6D ``[..., 6]``.
        w: blend weight, a float or a tensor broadcastable to the leading dims ``[...]``
            (e.g. ``[T, 1]`` for ``a`` of shape ``[T, J, 6]`` to ramp over frames).

    Returns:
        The blended rotations in the representation of ``a``: ``a @ exp(w * log(a^T b))``.
        With 6D input the output is the 6D of the (orthonormal) blended matrix.
    """
    if a.shape != b.shape:
        raise ValueError(f"interpolate_rotations: shapes differ, {tuple(a.shape)} vs {tuple(b.shape)}")
    six_d = a.shape[-1] == 6
    ma = rot6d_to_matrix(a) if six_d else a
    mb = rot6d_to_matrix(b) if six_d else b
    _check_last(ma, (3, 3), "a")
    w = torch.as_tensor(w, dtype=ma.dtype, device=ma.device)
    relative = matrix_to_axis_angle(ma.transpose(-1, -2) @ mb)
    out = ma @ axis_angle_to_matrix(w.unsqueeze(-1) * relative)
    return matrix_to_rot6d(out) if six_d else out


def _check_last(x: torch.Tensor, shape: tuple[int, ...], name: str) -> None:
    if not isinstance(x, torch.Tensor):
        raise TypeError(f"{name} must be a torch.Tensor, got {type(x).__name__}")
    if tuple(x.shape[len(x.shape) - len(shape):]) != shape or x.dim() < len(shape):
        raise ValueError(f"{name} must have shape [..., {', '.join(map(str, shape))}], got {tuple(x.shape)}")
