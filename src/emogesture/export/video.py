"""MP4 previews of SMPL-X sequences: a lit capsule mannequin, software-rendered, H.264 + AAC.

Each frame is drawn on the CPU (no GPU, no display; :mod:`emogesture.export.raster`, compiled with numba):
every bone is a capsule (a sphere for the head and eyes) projected orthographically onto a front view,
shaded per pixel from the capsule's analytic normal (ambient + Lambert + a little specular, a dark rim as
outline), with a z-buffer and one pixel of edge anti-aliasing. The camera is fixed for the whole sequence:
centred on the upper body of the rest skeleton moved by the sequence's mean root translation. Frames are
converted to yuv420p here and piped to ``ffmpeg`` (libx264, so browsers play it), and the speech, when
given, is muxed in as AAC. A label naming the speech, the emotion / style source and the seed is drawn in
the top-left corner.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from os import PathLike
from pathlib import Path

import numpy as np
import torch

from emogesture.errors import EmogestureError
from emogesture.fileio import atomic_output
from emogesture.motion import JOINT_NAMES, SkeletonBody, rest_joints
from emogesture.types import ARKIT_NAMES, SMPLXSequence

_J = {name: i for i, name in enumerate(JOINT_NAMES)}
_LIGHT = np.array([-0.35, 0.55, 0.75]) / np.linalg.norm([-0.35, 0.55, 0.75])  # x right, y up, z to the viewer
_HALF = (_LIGHT + np.array([0.0, 0.0, 1.0])) / np.linalg.norm(_LIGHT + np.array([0.0, 0.0, 1.0]))

SHIRT = (0.32, 0.45, 0.66)
SKIN = (0.91, 0.76, 0.62)
WOOD = (0.86, 0.72, 0.55)
DARK = (0.15, 0.15, 0.18)
TROUSERS = (0.30, 0.31, 0.36)
EYE_WHITE, LIPS, MOUTH, BROW = (0.96, 0.96, 0.95), (0.74, 0.33, 0.32), (0.28, 0.06, 0.07), (0.32, 0.22, 0.16)
HEAD_RADIUS = 0.105
_ARKIT = {name: i for i, name in enumerate(ARKIT_NAMES)}


def _bones() -> list[tuple[int, int, float, tuple[float, float, float]]]:
    """Capsules ``(joint a, joint b, radius m, colour)`` between SMPL-X joints."""
    j = _J
    bones = [
        (j["pelvis"], j["spine1"], 0.115, SHIRT), (j["spine1"], j["spine2"], 0.12, SHIRT),
        (j["spine2"], j["spine3"], 0.13, SHIRT), (j["spine3"], j["neck"], 0.075, SHIRT),
        (j["neck"], j["head"], 0.055, SKIN),
    ]  # fmt: skip
    for side in ("left", "right"):
        bones += [
            (j["pelvis"], j[f"{side}_hip"], 0.1, TROUSERS), (j[f"{side}_hip"], j[f"{side}_knee"], 0.075, TROUSERS),
            (j["spine3"], j[f"{side}_collar"], 0.06, SHIRT), (j[f"{side}_collar"], j[f"{side}_shoulder"], 0.06, SHIRT),
            (j[f"{side}_shoulder"], j[f"{side}_elbow"], 0.047, WOOD),
            (j[f"{side}_elbow"], j[f"{side}_wrist"], 0.039, WOOD),
            (j[f"{side}_wrist"], j[f"{side}_middle1"], 0.03, SKIN),
        ]  # fmt: skip
        # the hand: a palm to the middle knuckle, then one capsule over the four fingers and one for the thumb
        bones += [(j[f"{side}_middle1"], j[f"{side}_middle3"], 0.026, SKIN),
                  (j[f"{side}_thumb1"], j[f"{side}_thumb3"], 0.012, SKIN)]
    return bones


BONES = _bones()


def head_frame(joints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Head up and forward unit vectors ``[..., 3]`` each, solved from the head, eye and jaw joints of
    the licence-free skeleton (eyes at (±0.03, 0.06, 0.08), jaw at (0, −0.02, 0.03) in the head's frame)."""
    h = joints[..., _J["head"], :]
    m = 0.5 * (joints[..., _J["left_eye_smplhf"], :] + joints[..., _J["right_eye_smplhf"], :]) - h
    jw = joints[..., _J["jaw"], :] - h
    det = 0.06 * 0.03 + 0.08 * 0.02
    up = (0.03 * m - 0.08 * jw) / det
    fwd = (0.06 * jw + 0.02 * m) / det
    return (up / np.linalg.norm(up, axis=-1, keepdims=True).clip(1e-9),
            fwd / np.linalg.norm(fwd, axis=-1, keepdims=True).clip(1e-9))


def face_primitives(centre: np.ndarray, up: np.ndarray, fwd: np.ndarray, face: np.ndarray
                    ) -> list[tuple[np.ndarray, np.ndarray, float, tuple]]:
    """The face drawn on the head sphere at ``centre`` (``up``, ``fwd``: the head's unit axes) from its 52
    ARKit weights ``face``: eyes that open, close and look about, brows, and a mouth whose opening is
    ``jawOpen - mouthClose`` and whose corners rise with a smile and fall with a frown."""
    w = {name: float(face[i]) for name, i in _ARKIT.items()}
    parts: list[tuple[np.ndarray, np.ndarray, float, tuple, float]] = []  # (offset a, offset b, radius, colour, lift)
    for side, name in ((1.0, "Left"), (-1.0, "Right")):
        eye = np.array([side * 0.034, 0.012])
        opening = np.clip(1.0 - w[f"eyeBlink{name}"] + 0.3 * w[f"eyeWide{name}"] - 0.4 * w[f"eyeSquint{name}"], 0.0, 1.3)
        if opening > 0.25:
            r = 0.006 + 0.007 * opening
            parts.append((eye - [0.005, 0], eye + [0.005, 0], r, EYE_WHITE, 0.0))
            look = np.array([side * (w[f"eyeLookOut{name}"] - w[f"eyeLookIn{name}"]),
                             w[f"eyeLookUp{name}"] - w[f"eyeLookDown{name}"]]) * 0.006
            parts.append((eye + look, eye + look, min(0.0065, r * 0.7), DARK, 0.6 * r + 0.3 * min(0.0065, r * 0.7)))
        else:  # a closed eye: a line
            parts.append((eye - [0.011, 0], eye + [0.011, 0], 0.003, DARK, 0.0))
        inner = eye + [-side * 0.010, 0.026 + 0.012 * w["browInnerUp"] - 0.010 * w[f"browDown{name}"]]
        outer = eye + [side * 0.014, 0.025 + 0.012 * w[f"browOuterUp{name}"] - 0.004 * w[f"browDown{name}"]]
        parts.append((inner, outer, 0.0045, BROW, 0.0))
    opening = np.clip(w["jawOpen"] - w["mouthClose"] + 0.3 * w["mouthFunnel"], 0.0, 1.0) * 0.022
    half = 0.022 * (1.0 + 0.3 * (w["mouthSmileLeft"] + w["mouthSmileRight"]) / 2 - 0.45 * w["mouthPucker"]
                    + 0.25 * (w["mouthStretchLeft"] + w["mouthStretchRight"]) / 2)
    middle = np.array([0.0, -0.048 - 0.3 * opening])
    for side, name in ((1.0, "Left"), (-1.0, "Right")):
        corner = np.array([side * half, -0.048 + 0.012 * (w[f"mouthSmile{name}"] - w[f"mouthFrown{name}"])])
        if opening > 0.002:
            parts.append((corner, middle, 0.0015 + opening, MOUTH, 0.0))
        parts.append((corner, middle + [0, opening], 0.0045, LIPS, 0.0))
        parts.append((corner, middle - [0, opening], 0.005, LIPS, 0.0))
    # every end onto the head's front, sunk so that 0.7 of its radius stands out (plus its lift toward the viewer)
    offsets = np.array([[a, b] for a, b, _, _, _ in parts], np.float64)  # [K, 2 ends, (left, up)]
    radius = np.array([p[2] for p in parts])
    lift = np.array([p[4] for p in parts])
    left = np.cross(up, fwd)  # the character's left
    depth = np.sqrt(np.maximum(1.0 - (offsets ** 2).sum(-1) / HEAD_RADIUS ** 2, 0.0))[..., None]
    d = fwd * depth + (left * offsets[..., :1] + up * offsets[..., 1:]) / HEAD_RADIUS
    d /= np.linalg.norm(d, axis=-1, keepdims=True).clip(1e-9)
    ends = centre + (HEAD_RADIUS - 0.3 * radius)[:, None, None] * d + lift[:, None, None] * fwd
    return [(ends[k, 0], ends[k, 1], float(radius[k]), parts[k][3]) for k in range(len(parts))]


@dataclass
class Camera:
    """Orthographic front view: pixel ``(u, v) = (cx + s·x, cy − s·y)``, depth = z (toward the viewer)."""

    cx: float
    cy: float
    scale: float  # pixels per metre
    width: int
    height: int

    @classmethod
    def upper_body(cls, seq: SMPLXSequence, width: int = 640, height: int = 480) -> "Camera":
        """Fixed for the sequence: from the hips to above the head of the rest skeleton, moved by the
        mean root translation."""
        rest = rest_joints(seq.betas)
        shift = seq.trans.mean(0) if seq.num_frames else np.zeros(3)
        bottom = rest[_J["pelvis"], 1] - 0.32 + shift[1]
        top = rest[_J["head"], 1] + 0.3 + shift[1]
        scale = height / (top - bottom)
        centre_x = rest[_J["pelvis"], 0] + shift[0]
        return cls(cx=width / 2 - scale * centre_x, cy=scale * top, scale=scale, width=width, height=height)

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World points ``[..., 3]`` -> pixels ``[..., 2]`` and depths ``[...]`` (m, larger = nearer)."""
        u = self.cx + self.scale * points[..., 0]
        v = self.cy - self.scale * points[..., 1]
        return np.stack([u, v], -1), points[..., 2]


class MannequinRenderer:
    """Draws frames of an SMPL-X sequence as a capsule mannequin (see the module docstring)."""

    def __init__(self, width: int = 640, height: int = 480) -> None:
        if width % 2 or height % 2 or width < 64 or height < 64:
            raise EmogestureError(f"video size {width}x{height}: width and height must be even and at least 64")
        self.width, self.height = width, height
        t = np.linspace(0.0, 1.0, height)[:, None, None]
        top, bottom = np.array([0.95, 0.95, 0.97]), np.array([0.74, 0.77, 0.82])
        self.background = (((1 - t) * top + t * bottom) * np.ones((1, width, 1)) * 255 + 0.5).astype(np.uint8)
        self._x = np.arange(width, dtype=np.float32)
        self._y = np.arange(height, dtype=np.float32)

    def primitives(self, joints: np.ndarray, face: np.ndarray | None = None
                   ) -> list[tuple[np.ndarray, np.ndarray, float, tuple]]:
        """Joint positions ``[55, 3]`` of one frame (and its 52 ARKit weights ``face``, or None) -> capsules
        ``(a [3], b [3], radius m, colour)``."""
        prims = [(joints[a], joints[b], r, c) for a, b, r, c in BONES]
        up, fwd = head_frame(joints)
        centre = joints[_J["head"]] + 0.04 * up + 0.025 * fwd
        prims.append((centre, centre, HEAD_RADIUS, SKIN))
        if face is not None:
            return prims + face_primitives(centre, up, fwd, face)
        for eye in ("left_eye_smplhf", "right_eye_smplhf"):
            d = joints[_J[eye]] + 0.01 * up - centre
            p = centre + 0.1 * d / max(np.linalg.norm(d), 1e-9)
            prims.append((p, p, 0.014, DARK))
        return prims

    def capsules(self, joints: np.ndarray, camera: Camera, face: np.ndarray | None = None) -> np.ndarray:
        """Joint positions ``[55, 3]`` of one frame (and its face weights) -> the capsules ``[K, 11]`` of
        :func:`~emogesture.export.raster.draw_capsules`, projected by ``camera``."""
        prims = self.primitives(joints, face)
        pixels, depth = camera.project(np.array([[a, b] for a, b, _, _ in prims], np.float64))
        radius = np.array([r for _, _, r, _ in prims], np.float64)
        colour = np.array([c for _, _, _, c in prims], np.float64) * 255
        return np.column_stack([pixels[:, 0], depth[:, 0], pixels[:, 1], depth[:, 1],
                                radius * camera.scale, radius, colour])

    def draw(self, joints: np.ndarray, camera: Camera, face: np.ndarray | None = None) -> np.ndarray:
        """One frame: joint positions ``[55, 3]`` (and its 52 ARKit weights, or None) -> RGB ``[H, W, 3]``
        uint8."""
        from emogesture.export.raster import draw_capsules  # numba: loaded when a video is drawn, not at import

        img = self.background.copy()
        zbuf = np.full((self.height, self.width), -np.inf, np.float32)
        draw_capsules(img, zbuf, self.capsules(joints, camera, face), _LIGHT, _HALF)
        return img

    def frames(self, seq: SMPLXSequence, camera: Camera | None = None,
               overlay: np.ndarray | list[np.ndarray | None] | None = None, which: np.ndarray | None = None,
               threads: int = 1, convert: Callable[[np.ndarray], np.ndarray] | None = None) -> Iterator[np.ndarray]:
        """RGB frames ``[H, W, 3]`` uint8 of the whole sequence, in order (forward kinematics batched),
        with its face when it has a face track, the ``overlay`` label pasted (a list of labels: frame ``i`` gets ``overlay[which[i]]``), each
        passed through ``convert`` when given; ``threads > 1`` draws that many frames at once (the drawing
        releases the GIL)."""
        camera = camera or Camera.upper_body(seq, self.width, self.height)
        body = SkeletonBody(seq.betas)
        with torch.no_grad():
            joints = body(torch.from_numpy(seq.poses), torch.from_numpy(seq.trans)).double().numpy()
        if not isinstance(overlay, list):
            overlay, which = [overlay], None
        which = np.zeros(len(joints), int) if which is None else np.asarray(which)
        labels = [None if o is None else _premultiplied(o) for o in overlay]

        def one(i: int) -> np.ndarray:
            frame = self.draw(joints[i], camera, None if seq.arkit is None else seq.arkit[i])
            if labels[which[i]] is not None:
                frame = _paste(frame, *labels[which[i]])
            return frame if convert is None else convert(frame)

        if threads <= 1:
            yield from map(one, range(len(joints)))
            return
        with ThreadPoolExecutor(threads) as pool:
            pending: deque = deque()
            for i in range(len(joints)):
                pending.append(pool.submit(one, i))
                if len(pending) > 2 * threads:  # a few frames ahead, not the whole video in memory
                    yield pending.popleft().result()
            while pending:
                yield pending.popleft().result()


def label_overlay(text: str, width: int) -> np.ndarray | None:
    """The corner label as an RGBA image ``[h, w, 4]`` float in [0, 1] (None for no text)."""
    if not text:
        return None
    from PIL import Image, ImageDraw, ImageFont

    font = ImageFont.load_default(size=15)
    probe = ImageDraw.Draw(Image.new("RGBA", (1, 1)))
    box = probe.multiline_textbbox((0, 0), text, font=font, spacing=4)
    w, h = min(box[2] + 16, width - 8), box[3] + 12
    im = Image.new("RGBA", (w, h), (255, 255, 255, 200))
    ImageDraw.Draw(im).multiline_text((8, 5), text, fill=(25, 28, 35, 255), font=font, spacing=4)
    return np.asarray(im, np.float64) / 255.0


def label_overlays(label: str | Sequence[tuple[float, str]], width: int, fps: float, frames: int
                   ) -> tuple[list[np.ndarray | None], np.ndarray]:
    """A label, or ``(from seconds, text)`` labels in time order -> their overlays and, per frame, the index
    of the one shown (the last that has started; the first before any has)."""
    if isinstance(label, str):
        return [label_overlay(label, width)], np.zeros(frames, int)
    times = np.array([t for t, _ in label], np.float64)
    which = np.searchsorted(times, np.arange(frames) / fps, side="right") - 1
    return [label_overlay(text, width) for _, text in label], which.clip(0, None)


def _premultiplied(overlay: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """An RGBA overlay ``[h, w, 4]`` in [0, 1] -> its colour times its alpha (0-255, plus 0.5 for rounding)
    and one minus its alpha, float32, as :func:`_paste` blends them."""
    alpha = overlay[..., 3:].astype(np.float32)
    return (alpha * overlay[..., :3] * 255 + 0.5).astype(np.float32), 1 - alpha


def _paste(frame: np.ndarray, colour: np.ndarray, keep: np.ndarray, x: int = 8, y: int = 8) -> np.ndarray:
    region = frame[y:y + colour.shape[0], x:x + colour.shape[1]]
    h, w = region.shape[:2]
    region[:] = (colour[:h, :w] + keep[:h, :w] * region).astype(np.uint8)
    return frame


def to_yuv420(frame: np.ndarray) -> np.ndarray:
    """An RGB frame ``[H, W, 3]`` uint8 -> its yuv420p bytes ``[H * W * 3 // 2]`` uint8 (BT.601 limited)."""
    from emogesture.export.raster import rgb_to_yuv420

    out = np.empty(frame.shape[0] * frame.shape[1] * 3 // 2, np.uint8)
    rgb_to_yuv420(frame, out)
    return out


def ffmpeg_binary() -> str:
    path = shutil.which("ffmpeg")
    if path is None:
        raise EmogestureError("ffmpeg is not installed (needed for .mp4 output; e.g. apt-get install ffmpeg)")
    if not os.access(path, os.X_OK):
        raise EmogestureError(f"{path}: ffmpeg is not executable")
    return path


def save_mp4(seq: SMPLXSequence, path: str | PathLike[str], *, audio: tuple[np.ndarray, int] | None = None,
             label: str | Sequence[tuple[float, str]] = "", overwrite: bool = False, width: int = 640,
             height: int = 480, progress: bool = False) -> Path:
    """Render ``seq`` to an H.264 MP4 (yuv420p, the sequence's fps) with ``audio = (waveform [N], rate)``
    muxed in as AAC, atomically; refuses an existing file unless ``overwrite``. ``label``: the text in the
    corner, or ``(from seconds, text)`` pairs for text that changes along the video."""
    import soundfile as sf
    from tqdm import tqdm

    ffmpeg = ffmpeg_binary()
    renderer = MannequinRenderer(width, height)
    overlays, which = label_overlays(label, width, seq.fps, seq.num_frames)
    with atomic_output(path, overwrite) as tmp, tempfile.TemporaryDirectory(prefix="emogesture-mp4-") as work:
        cmd = [ffmpeg, "-nostdin", "-v", "error", "-y", "-f", "rawvideo", "-pix_fmt", "yuv420p",
               "-s", f"{width}x{height}", "-r", f"{float(seq.fps):g}", "-i", "pipe:0"]
        if audio is not None:
            wav = Path(work) / "speech.wav"
            sf.write(str(wav), np.asarray(audio[0], np.float32).clip(-1, 1), int(audio[1]), subtype="PCM_16")
            cmd += ["-i", str(wav), "-map", "0:v:0", "-map", "1:a:0", "-c:a", "aac", "-b:a", "96k"]
        cmd += ["-c:v", "libx264", "-preset", "ultrafast", "-crf", "20", "-pix_fmt", "yuv420p",
                "-movflags", "+faststart", "-f", "mp4", str(tmp)]
        try:
            proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        except OSError as err:
            raise EmogestureError(f"{ffmpeg}: ffmpeg cannot be run ({err.strerror or err})") from None
        try:
            frames = tqdm(renderer.frames(seq, overlay=overlays, which=which, threads=min(os.cpu_count() or 1, 2),
                                          convert=to_yuv420),
                          total=seq.num_frames, desc=f"rendering {Path(path).name}", unit="frame",
                          disable=not progress, leave=False)
            for frame in frames:
                proc.stdin.write(frame.tobytes())
            proc.stdin.close()
        except BrokenPipeError:
            pass
        finally:
            err = proc.stderr.read().decode("utf-8", "replace")
            code = proc.wait()
        if code != 0:
            last = [ln for ln in err.splitlines() if ln.strip()]
            raise EmogestureError(f"{path}: ffmpeg failed ({last[-1] if last else f'exit code {code}'})")
    return Path(path)
