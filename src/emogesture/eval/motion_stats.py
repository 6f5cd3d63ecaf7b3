"""How lively and how human a set of motion is: per-joint angular speed, hand speed and posture.

Pure functions of SMPL-X pose arrays and joint positions (no files): the statistics behind
``emogesture motion-stats``, so the synthetic corpus, a model's output and a user's motion capture can
be held against each other and against real conversational motion (docs/design.md, 'How real motion moves').

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
  sides read low on the first and high on the second. Also the wrists' height above the pelvis along the
  body's up axis (10th, 50th and 90th percentile) and the share of frames with the wrists closer than
  ``together_m`` (hands together).
- **Hands**: finger curl, the mean rotation angle of the 30 finger joints (15 per hand; 0 = a flat hand
  as SMPL-X rests it), per hand, and how much the hand shape changes: each finger joint's angle's
  standard deviation over a sequence, averaged.
- **Body turn and lean**: the root's (global orient's) rotation about its mean over a sequence, as the
  root-mean-square geodesic angle, degrees; and the chest's facing (spine3's global rotation) apart as
  yaw (about the world's up axis, y) and pitch (leaning forward and back), each a standard deviation
  over the sequence, degrees. A person talking turns and leans by a few degrees.
- **Onset coupling**, for sequences with their audio: the best Pearson correlation, within
  ``coupling_lag_s``, between the arm joints' mean speed and the speech's onset envelope (the positive
  spectral flux of a log-mel spectrogram, read at the motion frames), both smoothed alike
  (:mod:`emogesture.eval.rhythm`'s functions, over the whole sequence). Over several sequences the
  correlation curves (one value per lag) are averaged, weighted by length, before the best lag is taken:
  the best of each short sequence's own curve would read about 0.06 for motion that has nothing to do
  with its speech (the maximum of a dozen noisy correlations), more than a real speaker's coupling. Real
  conversational motion capture couples weakly (about 0.05, one 64-s take); arms that tick on every
  syllable couple several times more.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from os import PathLike
from pathlib import Path

import numpy as np
import torch

from emogesture.audio import onset_strength
from emogesture.errors import EmogestureError, InputFileError
from emogesture.eval.rhythm import arm_speed, envelope_at_frames, lagged_correlation, smooth
from emogesture.motion.rotations import axis_angle_to_matrix
from emogesture.motion.skeleton import JOINT_NAMES

STAT_JOINTS: tuple[str, ...] = (
    "spine1", "spine2", "spine3", "neck", "head", "left_collar", "right_collar", "left_shoulder",
    "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist",
)  # fmt: skip
_J = {name: i for i, name in enumerate(JOINT_NAMES)}
MOTION_STATS_CONSTANTS = {"still_speed_m_s": 0.05, "open_elbow_deg": 150.0, "speed_quantile": 0.95,
                          "front_m": 0.15, "together_m": 0.2, "coupling_lag_s": 0.2}
TORSO_CHAIN = tuple(_J[name] for name in ("pelvis", "spine1", "spine2", "spine3"))
FINGER_JOINTS: dict[str, tuple[int, ...]] = {
    side: tuple(i for i, name in enumerate(JOINT_NAMES)
                if name.startswith(f"{side}_") and name[len(side) + 1:].rstrip("123") in
                ("index", "middle", "pinky", "ring", "thumb"))
    for side in ("left", "right")
}  # 15 per hand


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


def finger_angles_deg(poses: np.ndarray) -> np.ndarray:
    """Axis-angle poses ``[T, 55, 3]`` -> each finger joint's rotation angle ``[T, 2, 15]`` (left, right
    hand), degrees: 0 for SMPL-X's flat rest hand."""
    poses = np.asarray(poses, np.float64)
    return np.degrees(np.stack([np.linalg.norm(poses[:, list(FINGER_JOINTS[side])], axis=-1)
                                for side in ("left", "right")], axis=1))


def root_turn_deg(poses: np.ndarray) -> float:
    """Axis-angle poses ``[T, 55, 3]`` -> the root-mean-square geodesic angle (degrees) between the root's
    global orientation in each frame and its mean over the sequence (the rotation nearest the mean
    rotation matrix)."""
    rot = axis_angle_to_matrix(torch.as_tensor(np.asarray(poses, np.float64)[:, 0])).numpy()
    u, _, vt = np.linalg.svd(rot.mean(0))
    mean = u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt
    cos = (np.einsum("ab,tac->tbc", mean, rot).trace(axis1=1, axis2=2) - 1.0) / 2.0
    return float(np.degrees(np.sqrt(np.mean(np.arccos(np.clip(cos, -1.0, 1.0)) ** 2))))


def torso_yaw_pitch_deg(poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Axis-angle poses ``[T, 55, 3]`` -> the chest's yaw and pitch ``[T]`` each, degrees: the global
    rotation of spine3 (root, spine1, spine2, spine3 composed) applied to the body's forward axis (+z), its
    direction about the world's up axis (y), unwrapped, and its elevation (positive: leaning forward).
    The arms do not move it."""
    rot = axis_angle_to_matrix(torch.as_tensor(np.asarray(poses, np.float64)[:, list(TORSO_CHAIN)])).numpy()
    chest = rot[:, 0]
    for k in range(1, len(TORSO_CHAIN)):
        chest = chest @ rot[:, k]
    forward = chest[:, :, 2]
    yaw = np.degrees(np.unwrap(np.arctan2(forward[:, 0], forward[:, 2])))
    pitch = -np.degrees(np.arcsin(np.clip(forward[:, 1], -1.0, 1.0)))
    return yaw, pitch


def wrist_heights(joints: np.ndarray) -> np.ndarray:
    """Joint positions ``[T, 55, 3]`` -> each wrist's height above the pelvis along the body's up axis
    ``[T, 2]`` (left, right), m."""
    joints = np.asarray(joints, np.float64)
    _, up, _ = body_frame(joints)
    wrists = joints[:, [_J["left_wrist"], _J["right_wrist"]]] - joints[:, None, _J["pelvis"]]
    return (wrists * up[:, None]).sum(-1)


def onset_coupling(joints: np.ndarray, waveform: np.ndarray, sample_rate: int, fps: float,
                   max_lag_s: float = MOTION_STATS_CONSTANTS["coupling_lag_s"]) -> float:
    """The best correlation within ±``max_lag_s`` between the arm joints' mean speed (joints ``[T, 55, 3]``)
    and the onset envelope of ``waveform [N]`` at the motion frames, both smoothed alike (module docstring)."""
    return float(onset_coupling_curve(joints, waveform, sample_rate, fps, max_lag_s).max())


def onset_coupling_curve(joints: np.ndarray, waveform: np.ndarray, sample_rate: int, fps: float,
                         max_lag_s: float) -> np.ndarray:
    """The correlation of :func:`onset_coupling` at every lag from ``-max_lag_s`` to ``+max_lag_s``:
    ``[2 L + 1]`` for ``L = round(max_lag_s × fps)`` frames, positive lags where the motion follows the
    onsets. Its shape tells when the arms move relative to the speech: a person's peaks narrowly a
    fraction of a second before the onsets."""
    speed = smooth(arm_speed(joints, fps), fps=fps)
    envelope = envelope_at_frames(onset_strength(waveform, sample_rate), sample_rate, len(speed), fps)
    return lagged_correlation(smooth(envelope, fps=fps), speed, max(0, int(round(max_lag_s * fps))))


@dataclass
class _Pool:
    """Running sums over sequences, frame-weighted."""

    angular: list[np.ndarray] = field(default_factory=list)
    wrist_speed: list[np.ndarray] = field(default_factory=list)
    below_pelvis: list[np.ndarray] = field(default_factory=list)
    elbow: list[np.ndarray] = field(default_factory=list)
    in_front: list[np.ndarray] = field(default_factory=list)
    wrist_distance: list[np.ndarray] = field(default_factory=list)
    wrist_height: list[np.ndarray] = field(default_factory=list)
    fingers: list[np.ndarray] = field(default_factory=list)  # [T, 2, 15] degrees
    finger_change: list[float] = field(default_factory=list)  # per sequence, frame-weighted
    root_turn: list[float] = field(default_factory=list)
    yaw_std: list[float] = field(default_factory=list)
    pitch_std: list[float] = field(default_factory=list)
    lengths: list[int] = field(default_factory=list)
    coupling: list[np.ndarray] = field(default_factory=list)  # per sequence, its correlation at each lag
    coupling_lengths: list[int] = field(default_factory=list)
    coupling_fps: list[float] = field(default_factory=list)
    frames: int = 0
    seconds: float = 0.0


def motion_statistics(sequences: Sequence[tuple],
                      still_speed: float = MOTION_STATS_CONSTANTS["still_speed_m_s"],
                      open_elbow_deg: float = MOTION_STATS_CONSTANTS["open_elbow_deg"],
                      quantile: float = MOTION_STATS_CONSTANTS["speed_quantile"],
                      front_m: float = MOTION_STATS_CONSTANTS["front_m"],
                      together_m: float = MOTION_STATS_CONSTANTS["together_m"],
                      coupling_lag_s: float = MOTION_STATS_CONSTANTS["coupling_lag_s"]) -> dict:
    """Statistics pooled over ``sequences`` of ``(poses [T, 55, 3] axis-angle, joints [T, 55, 3] m, fps)``,
    optionally with a fourth item ``(waveform [N], sample_rate)``: the sequence's speech (or None).

    Returns ``{"angular_speed": {joint: rad/frame}, "wrist_speed_mean", "wrist_speed_p95" (m/s),
    "wrist_still_share", "wrist_below_pelvis_share", "elbow_open_share", "hand_in_front_share",
    "wrist_distance_median" (m), "wrist_height_p10/_median/_p90" (m above the pelvis), "hands_together_share",
    "finger_curl_deg", "finger_curl_left_deg", "finger_curl_right_deg", "finger_change_deg",
    "root_turn_deg", "torso_yaw_std_deg", "torso_pitch_std_deg" (per sequence, frame-weighted means),
    "onset_coupling" (the frame-weighted mean correlation curve over the sequences with audio, at its best
    lag; None without) and "onset_coupling_lag_s" (that lag; positive: the arms follow the onsets), "sequences",
    "sequences_with_audio", "frames", "seconds", "constants"}``. Sequences shorter than 2 frames are skipped.
    """
    pool = _Pool()
    for item in sequences:
        poses, joints, fps = item[:3]
        audio = item[3] if len(item) > 3 else None
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
        pool.wrist_height.append(wrist_heights(joints).reshape(-1))
        fingers = finger_angles_deg(poses)
        pool.fingers.append(fingers)
        pool.finger_change.append(float(fingers.std(0).mean()))
        pool.root_turn.append(root_turn_deg(poses))
        yaw, pitch = torso_yaw_pitch_deg(poses)
        pool.yaw_std.append(float(yaw.std()))
        pool.pitch_std.append(float(pitch.std()))
        pool.lengths.append(len(poses))
        if audio is not None:
            pool.coupling.append(onset_coupling_curve(joints, np.asarray(audio[0]), int(audio[1]), fps,
                                                      coupling_lag_s))
            pool.coupling_lengths.append(len(poses))
            pool.coupling_fps.append(float(fps))
        pool.frames += len(poses)
        pool.seconds += len(poses) / fps
    if not pool.angular:
        raise ValueError("no sequence of at least 2 frames")
    angular = np.concatenate(pool.angular).mean(0)
    speed = np.concatenate(pool.wrist_speed)
    heights = np.concatenate(pool.wrist_height)
    fingers = np.concatenate(pool.fingers)

    curve, lag_s = None, None
    if pool.coupling:  # each curve read at the first one's lags (seconds), so frame rates may differ
        lags = [(np.arange(len(c)) - len(c) // 2) / f for c, f in zip(pool.coupling, pool.coupling_fps)]
        curve = np.average(np.stack([np.interp(lags[0], x, c) for x, c in zip(lags, pool.coupling)]), axis=0,
                           weights=pool.coupling_lengths)
        lag_s = round(float(lags[0][int(curve.argmax())]), 3)

    def per_sequence(values: list[float]) -> float:
        return float(np.average(values, weights=pool.lengths))

    return {
        "angular_speed": {name: float(angular[_J[name]]) for name in STAT_JOINTS},
        "wrist_speed_mean": float(speed.mean()),
        "wrist_speed_p95": float(np.quantile(speed, quantile)),
        "wrist_still_share": float((speed < still_speed).mean()),
        "wrist_below_pelvis_share": float(np.concatenate(pool.below_pelvis).mean()),
        "elbow_open_share": float((np.concatenate(pool.elbow) > open_elbow_deg).mean()),
        "hand_in_front_share": float(np.concatenate(pool.in_front).mean()),
        "wrist_distance_median": float(np.median(np.concatenate(pool.wrist_distance))),
        "wrist_height_p10": float(np.quantile(heights, 0.1)),
        "wrist_height_median": float(np.median(heights)),
        "wrist_height_p90": float(np.quantile(heights, 0.9)),
        "hands_together_share": float((np.concatenate(pool.wrist_distance) < together_m).mean()),
        "finger_curl_deg": float(fingers.mean()),
        "finger_curl_left_deg": float(fingers[:, 0].mean()),
        "finger_curl_right_deg": float(fingers[:, 1].mean()),
        "finger_change_deg": per_sequence(pool.finger_change),
        "root_turn_deg": per_sequence(pool.root_turn),
        "torso_yaw_std_deg": per_sequence(pool.yaw_std),
        "torso_pitch_std_deg": per_sequence(pool.pitch_std),
        "onset_coupling": float(curve.max()) if curve is not None else None,
        "onset_coupling_lag_s": lag_s,
        "sequences": len(pool.angular), "sequences_with_audio": len(pool.coupling), "frames": pool.frames,
        "seconds": round(pool.seconds, 2),
        "constants": {"still_speed_m_s": still_speed, "open_elbow_deg": open_elbow_deg, "speed_quantile": quantile,
                      "front_m": front_m, "together_m": together_m, "coupling_lag_s": coupling_lag_s},
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
            ("wrist height above the pelvis p10 / median / p90 (m)", "wrist_height", None),
            ("hands together (wrists < 0.2 m apart)", "hands_together_share", "{:.1%}"),
            ("finger curl, mean joint angle (deg)", "finger_curl_deg", "{:.1f}"),
            ("finger curl left / right (deg)", "finger_curl_sides", None),
            ("hand shape change, joint angle std (deg)", "finger_change_deg", "{:.1f}"),
            ("body turn: root rotation about its mean (deg)", "root_turn_deg", "{:.2f}"),
            ("torso yaw / pitch std (deg)", "torso", None),
            ("onset coupling (arm speed ~ onsets, best r within 0.2 s) at its lag", "onset_coupling", None),
            ("sequences / seconds", "sequences", None))

    def cell(r: dict, key: str, fmt: str | None) -> str:
        if key == "sequences":
            return f"{r['sequences']} / {r['seconds']:.0f}"
        if key == "wrist_height":
            return " / ".join(f"{r[f'wrist_height_{q}']:.2f}" for q in ("p10", "median", "p90"))
        if key == "finger_curl_sides":
            return f"{r['finger_curl_left_deg']:.1f} / {r['finger_curl_right_deg']:.1f}"
        if key == "onset_coupling":
            return "–" if r.get(key) is None else f"{r[key]:.3f} at {r['onset_coupling_lag_s']:+.2f} s"
        if key == "torso":
            return f"{r['torso_yaw_std_deg']:.2f} / {r['torso_pitch_std_deg']:.2f}"
        value = r.get(key)
        return "–" if value is None else fmt.format(value)

    for label, key, fmt in rows:
        cells = [cell(results[n], key, fmt) for n in names]
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


def named_sources(items: Sequence[str]) -> dict[str, list[Path]]:
    """``NAME=SOURCE`` or bare ``SOURCE`` items (each a ``.npz``, a folder of them or a BEAT2 root) -> the
    motion files of each named source, in order. A bare folder is named after itself; bare files are pooled
    as ``"npz files"``. A name given twice is a one-line error."""
    sources: dict[str, list[Path]] = {}
    loose: list[Path] = []
    for item in items:
        name, sep, path = item.partition("=")
        if not sep:
            name, path = "", item
        files = npz_files(path)
        if not name and Path(path).is_file():
            loose += files
            continue
        name = name or Path(path).name
        if name in sources:
            raise EmogestureError(f"{item!r}: the name {name!r} is given twice; name sources with NAME=SOURCE")
        sources[name] = files
    if loose:
        sources["npz files"] = loose
    return sources


def speech_of(motion_file: str | PathLike[str]) -> Path | None:
    """The speech recording of a motion file, where there is one: ``NAME.wav`` beside ``NAME.npz``, or a
    BEAT2 root's ``wave16k/NAME.wav`` for its ``smplxflame_30/NAME.npz``."""
    f = Path(motion_file)
    for candidate in (f.with_suffix(".wav"), f.parent.parent / "wave16k" / f"{f.stem}.wav"):
        if candidate.is_file():
            return candidate
    return None


def file_statistics(files: Sequence[str | PathLike[str]], every: int = 1, progress: bool = False) -> dict:
    """:func:`motion_statistics` of BEAT2/SMPL-X npz files (every ``every``-th file), each posed on the
    licence-free skeleton with its own shape coefficients, with its speech where :func:`speech_of` finds
    it (for the onset coupling)."""
    from tqdm import tqdm

    from emogesture.audio import load_audio
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
            wav = speech_of(f)
            yield seq.poses, joints, float(seq.fps), (load_audio(wav) if wav is not None else None)

    return motion_statistics(list(sequences()))
