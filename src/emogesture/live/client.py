"""A minimal client of ``emogesture live``: stream a recording to the server, collect the frames and how late
each arrived. A model of what a game-engine client does (protocol: :mod:`emogesture.live.server`).

Example::

    result = asyncio.run(stream_file("ws://127.0.0.1:8765/live", "talk.wav", emotion="anger"))
    print(len(result.poses), np.median(result.latency))
"""

from __future__ import annotations

import asyncio
import json
import time
from dataclasses import dataclass, field
from os import PathLike

import numpy as np

from emogesture.audio import TARGET_SAMPLE_RATE, load_audio
from emogesture.errors import EmogestureError


@dataclass
class LiveResult:
    """What came back: ``poses [T, 55, 3]`` and ``trans [T, 3]`` (SMPL-X skeleton), and per frame the seconds
    from the moment the client sent the audio of that frame's instant to the moment the frame arrived."""

    poses: np.ndarray
    trans: np.ndarray
    latency: np.ndarray
    errors: list[str] = field(default_factory=list)


async def stream_file(url: str, path: str | PathLike[str], *, emotion: str = "auto", chunk_seconds: float = 0.1,
                      realtime: bool = True, changes: dict[float, str] | None = None, seed: int = 0) -> LiveResult:
    """Send ``path`` to the server at ``url`` in ``chunk_seconds`` pieces (at the pace of speech when
    ``realtime``), changing the emotion at the seconds given in ``changes`` (``{15.0: "sadness"}``)."""
    from websockets.asyncio.client import connect

    wave = load_audio(path)[0]
    pcm = (np.clip(wave, -1, 1) * 32767).astype("<i2")
    step = max(1, int(round(chunk_seconds * TARGET_SAMPLE_RATE)))
    sent_at = np.full(len(pcm) + 1, np.nan)  # when the sample at each index left
    frames: dict[int, dict] = {}
    arrived: dict[int, float] = {}
    errors: list[str] = []
    pending = dict(sorted((changes or {}).items()))
    async with connect(url, max_size=16 * 2 ** 20) as ws:
        await ws.send(json.dumps({"sample_rate": TARGET_SAMPLE_RATE, "emotion": emotion, "seed": seed}))
        hello = json.loads(await ws.recv())
        if "error" in hello:
            raise EmogestureError(f"{url}: {hello['error']}")

        async def send() -> None:
            start = time.perf_counter()
            for i in range(0, len(pcm), step):
                for at in [t for t in pending if t * TARGET_SAMPLE_RATE <= i]:
                    await ws.send(json.dumps({"emotion": pending.pop(at)}))
                if realtime:
                    await asyncio.sleep(max(0.0, start + i / TARGET_SAMPLE_RATE - time.perf_counter()))
                await ws.send(pcm[i:i + step].tobytes())
                sent_at[i:i + step + 1] = time.perf_counter()
            await ws.send(json.dumps({"end": True}))

        sender = asyncio.create_task(send())
        async for message in ws:
            reply = json.loads(message)
            now = time.perf_counter()
            if "error" in reply:
                errors.append(reply["error"])
            for frame in reply.get("frames", []):
                frames[frame["frame"]] = frame
                arrived[frame["frame"]] = now
            if reply.get("done"):
                break
        await sender
    order = sorted(frames)
    if order != list(range(len(order))):
        raise EmogestureError(f"{url}: frames arrived with gaps")
    index = np.minimum((np.array(order) / 30.0 * TARGET_SAMPLE_RATE).astype(int), len(pcm))
    latency = np.array([arrived[i] for i in order]) - sent_at[index]
    poses = np.array([frames[i]["poses"] for i in order], np.float32).reshape(-1, 55, 3)
    trans = np.array([frames[i]["trans"] for i in order], np.float32).reshape(-1, 3)
    return LiveResult(poses, trans, latency, errors)
