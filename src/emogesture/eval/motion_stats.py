"""How lively and how human a set of motion is: per-joint angular speed, hand speed and posture.

Pure functions of SMPL-X pose arrays and joint positions (no files): the statistics behind
``emogesture motion-stats``, so the synthetic corpus, a model's output and a user's motion capture can
be held against each other and against real conversational motion (issue 17's table).

- **Angular speed** of a joint: the geodesic angle between its local rotation in consecutive frames,
  radians per frame, averaged over frames.
- **Wrist speed**: frame-to-frame displacement of both wrists (pooled) times the frame rate, m/s; its
  mean and 95th percentile, and the share of wrist-frames slower than ``still_speed``.
- **Posture**: the share of wrist-frames with the wrist below the pelvis (height = the y axis, SMPL-X's
  up) and of elbow-frames opened beyond ``open_elbow_deg`` (the angle at the elbow between the upper
  arm and the forearm; 180° = straight).
- **Gesture space**, in the body's own frame (:func:`body_frame`): the share of hand-frames with the
  wrist at least ``front_m`` ahead of the shoulders' midpoint (a hand in front of the chest; both hands
  pooled) and the median distance between the wrists. Real conversational motion capture keeps a hand
  in front in about half its frames, with the wrists about half a metre apart; arms hanging out to the
  sides read low on the first and high on the second.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from os import PathLike
from pathlib import Path

import numpy as np
import torch

from emogesture.errors import InputFileError
from emogesture.motion.rotations import axis_angle_to_matrix
from emogesture.motion.skeleton import JOINT_NAMES

STAT_JOINTS: tuple[str, ...] = (
    "spine1", "spine2", "spine3", "neck", "head", "left_collar", "right_collar", "left_shoulder",
    "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist",
)  # fmt: skip
_J = {name: i for i, name in enumerate(JOINT_NAMES)}
MOTION_STATS_CONSTANTS = {"still_speed_m_s": 0.05, "open_elbow_deg": 150.0, "speed_quantile": 0.95,
                          "front_m": 0.15}


def joint_angular_speed(poses: np.ndarray) -> np.ndarray:
    """Axis-angle poses ``[T, J, 3]`` -> geodesic angle between consecutive frames ``[T-1, J]`` (rad/frame)."""
    rot = axis_angle_to_matrix(torch.as_tensor(np.asarray(poses, np.float64)))
    rel = torch.einsum("tjab,tjac->tjbc", rot[:-1], rot[1:])  # R_t^T R_{t+1}
    cos = (rel.diagonal(dim1=-2, dim2=-1).sum(-1) - 1.0) / 2.0
    return torch.arccos(cos.clamp(-1.0, 1.0)).numpy()


def elbow_angles_deg(joints: np.ndarray) -> np.ndarray:
    """Joint positions ``[T, 55, 3]`` -> the angle at each elbow ``[T, 2]`` (left, right), degrees."""
    out = []
    for side in ("left", "right"):
        shoulder, elbow, wrist = (joints[:, _J[f"{side}_{n}"]] for n in ("shoulder", "elbow", "wrist"))
        a, b = shoulder - elbow, wrist - elbow
        cos = (a * b).sum(-1) / np.maximum(np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1), 1e-12)
        out.append(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))
    return np.stack(out, axis=1)


def body_frame(joints: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Joint positions ``[T, 55, 3]`` -> the body's own axes, each ``[T, 3]`` unit vectors: ``x`` from the
    right to the left shoulder, ``up`` from the pelvis to spine3 made orthogonal to ``x``, and
    ``forward = x × up`` (the way the chest faces)."""
    joints = np.asarray(joints, np.float64)
    x = joints[:, _J["left_shoulder"]] - joints[:, _J["right_shoulder"]]
    x /= np.maximum(np.linalg.norm(x, axis=-1, keepdims=True), 1e-12)
    up = joints[:, _J["spine3"]] - joints[:, _J["pelvis"]]
    up -= (up * x).sum(-1, keepdims=True) * x
    up /= np.maximum(np.linalg.norm(up, axis=-1, keepdims=True), 1e-12)
    return x, up, np.cross(x, up)


def hands_in_front(joints: np.ndarray, front_m: float = MOTION_STATS_CONSTANTS["front_m"]) -> np.ndarray:
    """Joint positions ``[T, 55, 3]`` -> ``[T, 2]`` bool (left, right): the wrist is at least ``front_m``
    ahead of the shoulders' midpoint along the body's forward axis (:func:`body_frame`)."""
    joints = np.asarray(joints, np.float64)
    _, _, forward = body_frame(joints)
    chest = 0.5 * (joints[:, _J["left_shoulder"]] + joints[:, _J["right_shoulder"]])
    wrists = joints[:, [_J["left_wrist"], _J["right_wrist"]]]
    return ((wrists - chest[:, None]) * forward[:, None]).sum(-1) >= front_m


def wrist_distance(joints: np.ndarray) -> np.ndarray:
    """Joint positions ``[T, 55, 3]`` -> the distance between the two wrists ``[T]`` (m)."""
    joints = np.asarray(joints, np.float64)
    return np.linalg.norm(joints[:, _J["left_wrist"]] - joints[:, _J["right_wrist"]], axis=-1)


@dataclass
class _Pool:
    """Running sums over sequences, frame-weighted."""

    angular: list[np.ndarray] = field(default_factory=list)
    wrist_speed: list[np.ndarray] = field(default_factory=list)
    below_pelvis: list[np.ndarray] = field(default_factory=list)
    elbow: list[np.ndarray] = field(default_factory=list)
    in_front: list[np.ndarray] = field(default_factory=list)
    wrist_distance: list[np.ndarray] = field(default_factory=list)
    frames: int = 0
    seconds: float = 0.0


def motion_statistics(sequences: Sequence[tuple[np.ndarray, np.ndarray, float]],
                      still_speed: float = MOTION_STATS_CONSTANTS["still_speed_m_s"],
                      open_elbow_deg: float = MOTION_STATS_CONSTANTS["open_elbow_deg"],
                      quantile: float = MOTION_STATS_CONSTANTS["speed_quantile"],
                      front_m: float = MOTION_STATS_CONSTANTS["front_m"]) -> dict:
    """Statistics pooled over ``sequences`` of ``(poses [T, 55, 3] axis-angle, joints [T, 55, 3] m, fps)``.

    Returns ``{"angular_speed": {joint: rad/frame}, "wrist_speed_mean", "wrist_speed_p95" (m/s),
    "wrist_still_share", "wrist_below_pelvis_share", "elbow_open_share", "hand_in_front_share",
    "wrist_distance_median" (m), "sequences", "frames", "seconds", "constants"}``. Sequences shorter
    than 2 frames are skipped.
    """
    pool = _Pool()
    for poses, joints, fps in sequences:
        poses, joints = np.asarray(poses), np.asarray(joints, np.float64)
        if len(poses) < 2:
            continue
        pool.angular.append(joint_angular_speed(poses))
        wrists = joints[:, [_J["left_wrist"], _J["right_wrist"]]]
        pool.wrist_speed.append((np.linalg.norm(np.diff(wrists, axis=0), axis=-1) * fps).reshape(-1))
        pool.below_pelvis.append((wrists[..., 1] < joints[:, None, _J["pelvis"], 1]).reshape(-1))
        pool.elbow.append(elbow_angles_deg(joints).reshape(-1))
        pool.in_front.append(hands_in_front(joints, front_m).reshape(-1))
        pool.wrist_distance.append(wrist_distance(joints))
        pool.frames += len(poses)
        pool.seconds += len(poses) / fps
    if not pool.angular:
        raise ValueError("no sequence of at least 2 frames")
    angular = np.concatenate(pool.angular).mean(0)
    speed = np.concatenate(pool.wrist_speed)
    return {
        "angular_speed": {name: float(angular[_J[name]]) for name in STAT_JOINTS},
        "wrist_speed_mean": float(speed.mean()),
        "wrist_speed_p95": float(np.quantile(speed, quantile)),
        "wrist_still_share": float((speed < still_speed).mean()),
        "wrist_below_pelvis_share": float(np.concatenate(pool.below_pelvis).mean()),
        "elbow_open_share": float((np.concatenate(pool.elbow) > open_elbow_deg).mean()),
        "hand_in_front_share": float(np.concatenate(pool.in_front).mean()),
        "wrist_distance_median": float(np.median(np.concatenate(pool.wrist_distance))),
        "sequences": len(pool.angular), "frames": pool.frames, "seconds": round(pool.seconds, 2),
        "constants": {"still_speed_m_s": still_speed, "open_elbow_deg": open_elbow_deg, "speed_quantile": quantile,
                      "front_m": front_m},
    }


def motion_stats_markdown(results: dict[str, dict]) -> str:
    """A table with one column per source (name -> :func:`motion_statistics` result)."""
    names = list(results)
    lines = ["| statistic | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
    for joint in STAT_JOINTS:
        lines.append(f"| {joint} angular speed (rad/frame) | "
                     + " | ".join(f"{results[n]['angular_speed'][joint]:.4f}" for n in names) + " |")
    rows = (("wrist speed mean (m/s)", "wrist_speed_mean", "{:.3f}"), ("wrist speed p95 (m/s)", "wrist_speed_p95", "{:.3f}"),
            ("wrist below the pelvis", "wrist_below_pelvis_share", "{:.1%}"),
            ("elbow opened beyond 150°", "elbow_open_share", "{:.1%}"),
            ("wrist slower than 0.05 m/s", "wrist_still_share", "{:.1%}"),
            ("a hand >= 0.15 m in front of the chest", "hand_in_front_share", "{:.1%}"),
            ("wrists' median distance (m)", "wrist_distance_median", "{:.3f}"),
            ("sequences / seconds", None, None))
    for label, key, fmt in rows:
        if key is None:
            cells = [f"{results[n]['sequences']} / {results[n]['seconds']:.0f}" for n in names]
        else:
            cells = [fmt.format(results[n][key]) for n in names]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def npz_files(path: str | PathLike[str]) -> list[Path]:
    """The motion files of a source: one ``.npz``, a folder of them, or a BEAT2 root (its
    ``smplxflame_30/``); sorted. Raises a one-line error when there are none."""
    p = Path(path)
    if p.is_file():
        if p.suffix != ".npz":
            raise InputFileError(p, "not an .npz motion file")
        return [p]
    if not p.is_dir():
        raise InputFileError(p, "not found")
    folder = p / "smplxflame_30" if (p / "smplxflame_30").is_dir() else p
    files = sorted(folder.glob("*.npz"))
    if not files:
        raise InputFileError(folder, "holds no .npz motion files")
    return files


def file_statistics(files: Sequence[str | PathLike[str]], every: int = 1, progress: bool = False) -> dict:
    """:func:`motion_statistics` of BEAT2/SMPL-X npz files (every ``every``-th file), each posed on the
    licence-free skeleton with its own shape coefficients."""
    from tqdm import tqdm

    from emogesture.motion.body import SkeletonBody
    from emogesture.motion.io import load_smplx_npz

    if every < 1:
        raise ValueError(f"every must be at least 1, got {every}")
    chosen = list(files)[::every]

    def sequences():
        for f in tqdm(chosen, desc="motion statistics", unit="file", disable=not progress, leave=False):
            seq = load_smplx_npz(f)
            body = SkeletonBody(np.asarray(seq.betas[:10], np.float32) if len(seq.betas) else None)
            with torch.no_grad():
                joints = body(torch.from_numpy(seq.poses), torch.from_numpy(seq.trans)).numpy()
            yield seq.poses, joints, float(seq.fps)

    return motion_statistics(list(sequences()))
