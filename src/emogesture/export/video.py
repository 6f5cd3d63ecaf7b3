"""MP4 previews of SMPL-X sequences: a lit capsule mannequin, software-rendered, H.264 + AAC.

Each frame is drawn with numpy alone (no GPU, no display): every bone is a capsule (a sphere for the
head and eyes) projected orthographically onto a front view, shaded per pixel from the capsule's
analytic normal (ambient + Lambert + a little specular, a dark rim as outline), with a z-buffer and
one pixel of edge anti-aliasing. The camera is fixed for the whole sequence: centred on the upper body
of the rest skeleton moved by the sequence's mean root translation. Frames are piped to ``ffmpeg``
(libx264, yuv420p, so browsers play it) and the speech, when given, is muxed in as AAC. A label
naming the speech, the emotion / style source and the seed is drawn in the top-left corner.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import shutil
import subprocess
import tempfile
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from os import PathLike
from pathlib import Path

import numpy as np
import torch

from emogesture.errors import EmogestureError
from emogesture.fileio import atomic_output
from emogesture.motion import JOINT_NAMES, SkeletonBody, rest_joints
from emogesture.types import SMPLXSequence

_J = {name: i for i, name in enumerate(JOINT_NAMES)}
_LIGHT = np.array([-0.35, 0.55, 0.75]) / np.linalg.norm([-0.35, 0.55, 0.75])  # x right, y up, z to the viewer
_HALF = (_LIGHT + np.array([0.0, 0.0, 1.0])) / np.linalg.norm(_LIGHT + np.array([0.0, 0.0, 1.0]))
_LIGHT32, _HALF32 = _LIGHT.astype(np.float32), _HALF.astype(np.float32)

SHIRT = (0.32, 0.45, 0.66)
SKIN = (0.91, 0.76, 0.62)
WOOD = (0.86, 0.72, 0.55)
DARK = (0.15, 0.15, 0.18)
TROUSERS = (0.30, 0.31, 0.36)


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

    def primitives(self, joints: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, float, tuple]]:
        """Joint positions ``[55, 3]`` of one frame -> capsules ``(a [3], b [3], radius m, colour)``."""
        prims = [(joints[a], joints[b], r, c) for a, b, r, c in BONES]
        up, fwd = head_frame(joints)
        centre = joints[_J["head"]] + 0.04 * up + 0.025 * fwd
        prims.append((centre, centre, 0.105, SKIN))
        for eye in ("left_eye_smplhf", "right_eye_smplhf"):
            d = joints[_J[eye]] + 0.01 * up - centre
            p = centre + 0.1 * d / max(np.linalg.norm(d), 1e-9)
            prims.append((p, p, 0.014, DARK))
        return prims

    def draw(self, joints: np.ndarray, camera: Camera) -> np.ndarray:
        """One frame: joint positions ``[55, 3]`` -> RGB ``[H, W, 3]`` uint8."""
        img = self.background.copy()
        zbuf = np.full((self.height, self.width), -np.inf, np.float32)
        for a, b, radius, colour in self.primitives(joints):
            self._capsule(img, zbuf, camera, a, b, radius, np.asarray(colour, np.float32) * 255)
        return img

    def _capsule(self, img, zbuf, camera: Camera, a, b, radius: float, colour: np.ndarray) -> None:
        (pa, pb), (za, zb) = camera.project(np.stack([a, b]))
        r = radius * camera.scale
        x0 = max(int(np.floor(min(pa[0], pb[0]) - r - 1)), 0)
        x1 = min(int(np.ceil(max(pa[0], pb[0]) + r + 2)), self.width)
        y0 = max(int(np.floor(min(pa[1], pb[1]) - r - 1)), 0)
        y1 = min(int(np.ceil(max(pa[1], pb[1]) + r + 2)), self.height)
        if x0 >= x1 or y0 >= y1:
            return
        xs, ys = self._x[None, x0:x1], self._y[y0:y1, None]
        ab = (pb - pa).astype(np.float32)
        pa = pa.astype(np.float32)
        length2 = float(ab @ ab)
        if length2 > 1e-9:
            t = ((xs - pa[0]) * np.float32(ab[0] / length2) + (ys - pa[1]) * np.float32(ab[1] / length2))
            np.minimum(np.maximum(t, 0.0, out=t), 1.0, out=t)
        else:
            t = np.zeros((y1 - y0, x1 - x0), np.float32)
        dx = xs - (pa[0] + t * ab[0])
        dy = ys - (pa[1] + t * ab[1])
        d2 = dx * dx + dy * dy
        # from here on only the pixels the capsule covers, by their index in the whole frame
        covered = np.flatnonzero(d2 < (r + 0.5) ** 2)
        if not len(covered):
            return
        bw = x1 - x0
        pix = (y0 + covered // bw) * self.width + (x0 + covered % bw)
        t, dx, dy = t.ravel()[covered], dx.ravel()[covered], dy.ravel()[covered]
        dist = np.sqrt(d2.ravel()[covered])
        rel = np.minimum(dist * np.float32(1.0 / r), 1.0)
        nz = np.sqrt(1.0 - rel * rel)
        depth = np.float32(za) + t * np.float32(zb - za) + np.float32(radius) * nz
        zflat = zbuf.reshape(-1)
        keep = depth > zflat[pix]
        if not keep.any():
            return
        pix, dist, rel, nz, depth, dx, dy = pix[keep], dist[keep], rel[keep], nz[keep], depth[keep], dx[keep], dy[keep]
        inv = np.float32(1.0 / r)
        nx, ny = dx * inv, dy * -inv
        lambert = np.maximum(nx * _LIGHT32[0] + ny * _LIGHT32[1] + nz * _LIGHT32[2], 0.0)
        spec = np.maximum(nx * _HALF32[0] + ny * _HALF32[1] + nz * _HALF32[2], 0.0)
        spec *= spec
        spec *= spec
        spec *= spec  # the 8th power, then cubed below: a highlight of power 24
        shade = (0.36 + 0.64 * lambert) * np.where(rel > 0.88, np.float32(0.55), np.float32(1.0))
        rgb = colour * shade[:, None] + (40.8 * spec * spec * spec)[:, None]
        alpha = np.minimum(np.float32(r + 0.5) - dist, 1.0)[:, None]
        flat = img.reshape(-1, 3)
        old = flat[pix]
        flat[pix] = np.minimum(alpha * (rgb - old) + old + 0.5, 255.0)
        solid = alpha[:, 0] >= 0.5
        zflat[pix[solid]] = depth[solid]

    def frames(self, seq: SMPLXSequence, camera: Camera | None = None,
               overlay: np.ndarray | list[np.ndarray | None] | None = None, which: np.ndarray | None = None,
               workers: int = 1) -> Iterator[np.ndarray]:
        """RGB frames ``[H, W, 3]`` uint8 of the whole sequence, in order (forward kinematics batched),
        with the ``overlay`` label pasted (a list of labels: frame ``i`` gets ``overlay[which[i]]``);
        ``workers > 1`` draws chunks of frames in that many forked processes (the drawing is numpy alone)."""
        camera = camera or Camera.upper_body(seq, self.width, self.height)
        body = SkeletonBody(seq.betas)
        with torch.no_grad():
            joints = body(torch.from_numpy(seq.poses), torch.from_numpy(seq.trans)).double().numpy()
        if not isinstance(overlay, list):
            overlay, which = [overlay], None
        which = np.zeros(len(joints), int) if which is None else np.asarray(which)
        job = (self, joints, camera, overlay, which)
        if workers <= 1 or len(joints) < 2 * _CHUNK or "fork" not in mp.get_all_start_methods():
            for i in range(len(joints)):
                yield _draw(job, i)
            return
        global _JOB
        _JOB = job  # inherited by the forked workers
        chunks = [(i, min(i + _CHUNK, len(joints))) for i in range(0, len(joints), _CHUNK)]
        with mp.get_context("fork").Pool(workers) as pool:
            for block in pool.imap(_draw_chunk, chunks):
                yield from block
        _JOB = None


_CHUNK = 16  # frames a worker draws per task
_JOB = None


def _draw(job, i: int) -> np.ndarray:
    renderer, joints, camera, overlays, which = job
    frame = renderer.draw(joints[i], camera)
    overlay = overlays[which[i]]
    return frame if overlay is None else _paste(frame, overlay)


def _draw_chunk(bounds: tuple[int, int]) -> np.ndarray:
    return np.stack([_draw(_JOB, i) for i in range(*bounds)])


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


def _paste(frame: np.ndarray, overlay: np.ndarray, x: int = 8, y: int = 8) -> np.ndarray:
    h, w = overlay.shape[:2]
    region = frame[y:y + h, x:x + w].astype(np.float64) / 255.0
    a = overlay[: region.shape[0], : region.shape[1], 3:]
    blended = a * overlay[: region.shape[0], : region.shape[1], :3] + (1 - a) * region
    frame[y:y + h, x:x + w] = (blended * 255 + 0.5).astype(np.uint8)
    return frame


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
        cmd = [ffmpeg, "-nostdin", "-v", "error", "-y", "-f", "rawvideo", "-pix_fmt", "rgb24",
               "-s", f"{width}x{height}", "-r", f"{float(seq.fps):g}", "-i", "pipe:0"]
        if audio is not None:
            wav = Path(work) / "speech.wav"
            sf.write(str(wav), np.asarray(audio[0], np.float32).clip(-1, 1), int(audio[1]), subtype="PCM_16")
            cmd += ["-i", str(wav), "-map", "0:v:0", "-map", "1:a:0", "-c:a", "aac", "-b:a", "96k"]
        cmd += ["-c:v", "libx264", "-preset", "superfast", "-crf", "20", "-pix_fmt", "yuv420p",
                "-movflags", "+faststart", "-f", "mp4", str(tmp)]
        try:
            proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        except OSError as err:
            raise EmogestureError(f"{ffmpeg}: ffmpeg cannot be run ({err.strerror or err})") from None
        try:
            frames = tqdm(renderer.frames(seq, overlay=overlays, which=which, workers=min(os.cpu_count() or 1, 2)),
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
