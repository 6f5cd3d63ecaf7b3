"""Rotation conversions in torch, batched over any leading dims and differentiable.

Axis-angle (rotation vector) <-> rotation matrix: Rodrigues' formula one way, a unit quaternion
(largest-component branch, so it stays accurate near pi) the other way. The continuous 6D
representation (Zhou et al., CVPR 2019) is defined here and only here:

    6D = the first two COLUMNS of the rotation matrix, column 0 then column 1:
    ``[R00, R10, R20, R01, R11, R21]``.

``rot6d_to_matrix`` rebuilds the matrix by Gram-Schmidt, so any 6D vector whose two halves are
not parallel maps to a valid rotation; ``rot6d_to_matrix(matrix_to_rot6d(R)) == R``.
"""

from __future__ import annotations

import torch

_EPS = 1e-8


def axis_angle_to_matrix(axis_angle: torch.Tensor) -> torch.Tensor:
    """Rotation vectors ``[..., 3]`` (angle = norm, radians) -> rotation matrices ``[..., 3, 3]``."""
    _check_last(axis_angle, (3,), "axis_angle")
    theta2 = (axis_angle * axis_angle).sum(-1, keepdim=True).unsqueeze(-1)  # [..., 1, 1]
    small = theta2 < 1e-8
    theta2_safe = torch.where(small, torch.ones_like(theta2), theta2)
    theta = theta2_safe.sqrt()
    # sin(t)/t and (1 - cos t)/t^2, with their Taylor series near zero
    a = torch.where(small, 1.0 - theta2 / 6.0, torch.sin(theta) / theta)
    b = torch.where(small, 0.5 - theta2 / 24.0, (1.0 - torch.cos(theta)) / theta2_safe)
    k = _skew(axis_angle)
    eye = torch.eye(3, dtype=axis_angle.dtype, device=axis_angle.device).expand_as(k)
    return eye + a * k + b * (k @ k)


def matrix_to_axis_angle(matrix: torch.Tensor) -> torch.Tensor:
    """Rotation matrices ``[..., 3, 3]`` -> rotation vectors ``[..., 3]`` with angle in ``[0, pi]``."""
    _check_last(matrix, (3, 3), "matrix")
    q = matrix_to_quaternion(matrix)  # [..., 4] as (x, y, z, w), w >= 0
    xyz, w = q[..., :3], q[..., 3:]
    sin_half = xyz.norm(dim=-1, keepdim=True)
    angle = 2.0 * torch.atan2(sin_half, w)
    small = sin_half < 1e-6
    # angle / sin(angle/2) -> 2 / w (1 + ...) near zero
    scale = torch.where(small, 2.0 / w.clamp_min(_EPS), angle / torch.where(small, torch.ones_like(sin_half), sin_half))
    return xyz * scale


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
    return torch.stack(_gram_schmidt(*rot6d.unbind(-1)), dim=-1).unflatten(-1, (3, 3))


def rot6d_planes_to_matrix(planes: torch.Tensor) -> torch.Tensor:
    """:func:`rot6d_to_matrix` in coordinate-plane layout: ``planes [R, 6, ...] -> [R, 3, 3, ...]``.

    Each of the 6 numbers (and of the 9 matrix entries) is a contiguous plane over the trailing dims
    (e.g. frames), so every step is a plain vectorised operation: for the 34 × 9600 rotations of a
    training batch, forward and backward 12 ms against 30 for the ``[..., 6]`` layout.
    """
    if planes.dim() < 2 or planes.shape[1] != 6:
        raise ValueError(f"planes must be [R, 6, ...], got {tuple(planes.shape)}")
    return torch.stack(_gram_schmidt(*planes.unbind(1)), dim=1).unflatten(1, (3, 3))


def _gram_schmidt(x1, y1, z1, x2, y2, z2) -> tuple[torch.Tensor, ...]:
    """The 6D numbers (column 0, then column 1) -> the 9 entries of the rotation, row by row.

    Written per coordinate (no norm or cross product over a dimension of 3, which run several times
    slower on a CPU than the same arithmetic on whole planes)."""
    r1 = (x1 * x1 + y1 * y1 + z1 * z1).clamp_min(_EPS * _EPS).sqrt()  # clamped first: no inf gradient at 0
    x1, y1, z1 = x1 / r1, y1 / r1, z1 / r1
    d = x1 * x2 + y1 * y2 + z1 * z2
    x2, y2, z2 = x2 - d * x1, y2 - d * y1, z2 - d * z1
    r2 = (x2 * x2 + y2 * y2 + z2 * z2).clamp_min(_EPS * _EPS).sqrt()
    x2, y2, z2 = x2 / r2, y2 / r2, z2 / r2
    # columns b1, b2 and b3 = b1 × b2
    return (x1, x2, y1 * z2 - z1 * y2,
            y1, y2, z1 * x2 - x1 * z2,
            z1, z2, x1 * y2 - y1 * x2)


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


def matrix_to_euler_zyx(matrix: torch.Tensor) -> torch.Tensor:
    """Rotation matrices ``[..., 3, 3]`` -> Euler angles ``[..., 3]`` (radians) as ``(z, y, x)`` with
    ``R = Rz(z) @ Ry(y) @ Rx(x)`` (BVH's ``Zrotation Yrotation Xrotation`` channel order); ``y`` in
    ``[-pi/2, pi/2]``. At gimbal lock (``|y| = pi/2``) ``x`` is 0 and ``z`` carries the rest."""
    _check_last(matrix, (3, 3), "matrix")
    m = matrix
    y = torch.asin((-m[..., 2, 0]).clamp(-1.0, 1.0))
    cos_y = torch.sqrt(m[..., 0, 0] ** 2 + m[..., 1, 0] ** 2)
    regular = cos_y > 1e-6
    z = torch.where(regular, torch.atan2(m[..., 1, 0], m[..., 0, 0]), torch.atan2(-m[..., 0, 1], m[..., 1, 1]))
    x = torch.where(regular, torch.atan2(m[..., 2, 1], m[..., 2, 2]), torch.zeros_like(y))
    return torch.stack([z, y, x], dim=-1)


def euler_zyx_to_matrix(euler: torch.Tensor) -> torch.Tensor:
    """Euler angles ``[..., 3]`` as ``(z, y, x)`` radians -> ``Rz(z) @ Ry(y) @ Rx(x)`` ``[..., 3, 3]``."""
    _check_last(euler, (3,), "euler")
    z, y, x = euler.unbind(-1)
    axes = torch.eye(3, dtype=euler.dtype, device=euler.device)
    return (axis_angle_to_matrix(z[..., None] * axes[2]) @ axis_angle_to_matrix(y[..., None] * axes[1])
            @ axis_angle_to_matrix(x[..., None] * axes[0]))


def _skew(v: torch.Tensor) -> torch.Tensor:
    """Cross-product matrices ``[..., 3, 3]`` of vectors ``[..., 3]``."""
    x, y, z = v.unbind(-1)
    o = torch.zeros_like(x)
    return torch.stack([o, -z, y, z, o, -x, -y, x, o], dim=-1).reshape(*v.shape[:-1], 3, 3)


def matrix_to_quaternion(m: torch.Tensor) -> torch.Tensor:
    """Rotation matrices ``[..., 3, 3]`` -> unit quaternions ``[..., 4]`` (x, y, z, w), w >= 0.

    Of the four algebraically equal solutions, each row uses the one built on its largest
    quaternion component, which avoids dividing by a small number.
    """
    m00, m01, m02 = m[..., 0, 0], m[..., 0, 1], m[..., 0, 2]
    m10, m11, m12 = m[..., 1, 0], m[..., 1, 1], m[..., 1, 2]
    m20, m21, m22 = m[..., 2, 0], m[..., 2, 1], m[..., 2, 2]
    # 4 * component^2 for w, x, y, z
    sq = torch.stack([1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22], -1)
    r = sq.clamp_min(_EPS).sqrt()  # 2 * |component|
    rw, rx, ry, rz = r.unbind(-1)
    cand = torch.stack([
        torch.stack([m21 - m12, m02 - m20, m10 - m01, rw * rw], -1) / (2 * rw.unsqueeze(-1)),
        torch.stack([rx * rx, m01 + m10, m02 + m20, m21 - m12], -1) / (2 * rx.unsqueeze(-1)),
        torch.stack([m01 + m10, ry * ry, m12 + m21, m02 - m20], -1) / (2 * ry.unsqueeze(-1)),
        torch.stack([m02 + m20, m12 + m21, rz * rz, m10 - m01], -1) / (2 * rz.unsqueeze(-1)),
    ], -2)  # [..., 4 candidates, (x, y, z, w)]
    best = sq.argmax(-1, keepdim=True)
    q = torch.gather(cand, -2, best.unsqueeze(-1).expand(*best.shape[:-1], 1, 4)).squeeze(-2)
    q = q / q.norm(dim=-1, keepdim=True).clamp_min(_EPS)
    return torch.where(q[..., 3:] < 0, -q, q)


def _check_last(x: torch.Tensor, shape: tuple[int, ...], name: str) -> None:
    if not isinstance(x, torch.Tensor):
        raise TypeError(f"{name} must be a torch.Tensor, got {type(x).__name__}")
    if tuple(x.shape[len(x.shape) - len(shape):]) != shape or x.dim() < len(shape):
        raise ValueError(f"{name} must have shape [..., {', '.join(map(str, shape))}], got {tuple(x.shape)}")
