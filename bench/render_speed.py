"""Render speed of the MP4 preview: wall seconds of `save_mp4` per second of animation.

The targets: at most 0.5 s of compute per second of animation on a 2-core machine, and, with the face drawn,
at least 3 times faster than the numpy renderer it replaced (0.438 s per s of a 60-s animation on the
machine of bench/results/render.md). Motion is smooth random rotations on every joint (speed of rendering
does not depend on which motion); ``--face`` adds a face track of smooth random ARKit weights.
Usage: python bench/render_speed.py [SECONDS] [--face]   (default 20)
"""

from __future__ import annotations

import os
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from emogesture.export import save_mp4
from emogesture.types import SMPLXSequence


def main(seconds: float = 20.0, face: bool = False) -> None:
    frames = int(round(seconds * 30))
    rng = np.random.default_rng(0)
    t = np.linspace(0, seconds, frames)[:, None, None]
    amp = rng.uniform(0.05, 0.3, (1, 55, 3))
    amp[:, 16:22] *= 3
    poses = (amp * np.sin(2 * np.pi * rng.uniform(0.2, 1.0, (1, 55, 3)) * t + rng.uniform(0, 6, (1, 55, 3))))
    seq = SMPLXSequence(poses=poses.astype(np.float32), trans=np.zeros((frames, 3), np.float32))
    if face:
        phase = rng.uniform(0, 6, (1, 52))
        seq.arkit = (0.5 + 0.5 * np.sin(2 * np.pi * rng.uniform(0.3, 2.0, (1, 52)) * t[:, :, 0] + phase)
                     ).astype(np.float32)
    audio = (0.05 * rng.normal(size=int(seconds * 16000)).astype(np.float32), 16000)
    with tempfile.TemporaryDirectory() as d:
        cpu0, child0, wall0 = time.process_time(), resource.getrusage(resource.RUSAGE_CHILDREN), time.perf_counter()
        save_mp4(seq, Path(d) / "bench.mp4", audio=audio, label="bench.wav\nemotion: own  |  style: own\nseed 0")
        wall = time.perf_counter() - wall0
        child1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = time.process_time() - cpu0
        ffmpeg = (child1.ru_utime + child1.ru_stime) - (child0.ru_utime + child0.ru_stime)
    print(f"{frames} frames ({seconds:g} s of animation{', with the face' if face else ''}) on {os.cpu_count()} cores: wall {wall:.2f} s = "
          f"{wall / seconds:.3f} s per s of animation (target <= 0.5); CPU: rendering {cpu / frames * 1000:.1f} ms "
          f"per frame, ffmpeg {ffmpeg / frames * 1000:.1f} ms per frame")


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "--face"]
    main(float(args[0]) if args else 20.0, face="--face" in sys.argv[1:])
