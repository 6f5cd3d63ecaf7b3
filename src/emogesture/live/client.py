"""A minimal client of ``emogesture live``: stream a recording to the server, collect the frames and how late
each arrived. A model of what a game-engine client does (protocol: :mod:`emogesture.live.server`).

Example::

    result = asyncio.run(stream_file("ws://127.0.0.1:8765/live", "talk.wav", emotion="anger"))
    result = asyncio.run(stream_file(url, "talk.wav", emotion="own", neutral_from="calm.wav"))
    result = asyncio.run(stream_file("ws://gpu-box:8765/live", "talk.wav", token="the printed token"))
    print(len(result.poses), np.median(result.latency))
"""

from __future__ import annotations

import asyncio
import json
import time
from dataclasses import dataclass, field
from os import PathLike

import numpy as np

from emogesture.access import with_token, without_token
from emogesture.audio import TARGET_SAMPLE_RATE, load_audio
from emogesture.errors import EmogestureError


REFERENCE_TIMEOUT = 120.0  # seconds the client waits for the server to make the neutral reference


@dataclass
class LiveResult:
    """What came back: ``poses [T, 55, 3]`` and ``trans [T, 3]`` (SMPL-X skeleton), and per frame the seconds
    from the moment the client sent the audio of that frame's instant to the moment the frame arrived."""

    poses: np.ndarray
    trans: np.ndarray
    latency: np.ndarray
    errors: list[str] = field(default_factory=list)
    #: the server's answer to a neutral recording: ``{"seconds": s, "windows": n}`` (None: none made)
    neutral_reference: dict | None = None


def _pcm(path: str | PathLike[str]) -> np.ndarray:
    return (np.clip(load_audio(path)[0], -1, 1) * 32767).astype("<i2")


async def stream_file(url: str, path: str | PathLike[str], *, emotion: str = "auto", chunk_seconds: float = 0.1,
                      realtime: bool = True, changes: dict[float, str] | None = None, seed: int = 0,
                      neutral_from: str | PathLike[str] | None = None, face: bool = False,
                      token: str | None = None) -> LiveResult:
    """Send ``path`` to the server at ``url`` in ``chunk_seconds`` pieces (at the pace of speech when
    ``realtime``), changing the emotion at the seconds given in ``changes`` (``{15.0: "sadness"}``).

    ``neutral_from``: a recording of the same speaker speaking without emotion, sent first (as fast as it goes)
    between ``{"neutral": "start"}`` and ``{"neutral": "stop"}``; the speech follows once the server has made
    its reference, and the frames of the neutral recording are left out of the result. ``face``: ask for the
    face too (each frame's ``arkit``). ``token``: the server's token (also accepted inside ``url`` as
    ``?token=...``). A server that refuses the stream or closes it (busy, a wrong token, a limit) is an
    :class:`EmogestureError` saying why."""
    from websockets.exceptions import ConnectionClosedError, InvalidStatus

    url = with_token(url, token)
    shown = without_token(url)  # for messages: the token is not repeated
    try:
        return await _stream(url, path, emotion=emotion, chunk_seconds=chunk_seconds, realtime=realtime,
                             changes=changes, seed=seed, neutral_from=neutral_from, face=face)
    except InvalidStatus as e:
        status = e.response.status_code
        hint = " (a wrong or missing token?)" if status == 403 else ""
        raise EmogestureError(f"{shown}: the server refused the stream: HTTP {status}{hint}") from None
    except ConnectionClosedError as e:
        reason = e.rcvd.reason if e.rcvd is not None and e.rcvd.reason else "the connection was lost"
        raise EmogestureError(f"{shown}: the server closed the stream: {reason}") from None
    except _Problem as e:
        raise EmogestureError(f"{shown}: {e}") from None


class _Problem(Exception):
    """What went wrong with a stream, said with the server's URL by :func:`stream_file`."""


async def _stream(url: str, path: str | PathLike[str], *, emotion: str, chunk_seconds: float, realtime: bool,
                  changes: dict[float, str] | None, seed: int, neutral_from: str | PathLike[str] | None,
                  face: bool) -> LiveResult:
    """:func:`stream_file` on a URL that holds the token, if any."""
    from websockets.asyncio.client import connect
    from websockets.exceptions import ConnectionClosedError

    pcm = _pcm(path)
    lead = np.zeros(0, "<i2")
    if neutral_from is not None:
        from emogesture.pipeline.neutral_reference import check_reference

        lead = _pcm(neutral_from)
        check_reference(lead.astype(np.float32) / 32767, str(neutral_from))  # too short or silent: say so here
    skip = int(np.ceil(len(lead) / TARGET_SAMPLE_RATE * 30.0 - 1e-9))  # the frames of the neutral recording
    pcm = np.concatenate([lead, pcm])
    step = max(1, int(round(chunk_seconds * TARGET_SAMPLE_RATE)))
    sent_at = np.full(len(pcm) + 1, np.nan)  # when the sample at each index left
    referenced = asyncio.Event()
    frames: dict[int, dict] = {}
    arrived: dict[int, float] = {}
    errors: list[str] = []
    reference: dict | None = None
    pending = dict(sorted((changes or {}).items()))
    async with connect(url, max_size=16 * 2 ** 20) as ws:
        await ws.send(json.dumps({"sample_rate": TARGET_SAMPLE_RATE, "emotion": emotion, "seed": seed,
                                  **({"face": True} if face else {})}))
        hello = json.loads(await ws.recv())
        if "error" in hello:
            raise _Problem(hello["error"])

        async def send() -> None:
            if len(lead):
                await ws.send(json.dumps({"neutral": "start"}))
                for i in range(0, len(lead), step):
                    await ws.send(lead[i:i + step].tobytes())
                    sent_at[i:min(i + step, len(lead)) + 1] = time.perf_counter()
                await ws.send(json.dumps({"neutral": "stop"}))
                try:
                    await asyncio.wait_for(referenced.wait(), REFERENCE_TIMEOUT)
                except asyncio.TimeoutError:
                    errors.append(f"no neutral reference came back in {REFERENCE_TIMEOUT:.0f} s; the speech is "
                                  "heard alone")
            start = time.perf_counter()
            for i in range(len(lead), len(pcm), step):
                at_speech = (i - len(lead)) / TARGET_SAMPLE_RATE
                for at in [t for t in pending if t <= at_speech]:
                    await ws.send(json.dumps({"emotion": pending.pop(at)}))
                if realtime:
                    await asyncio.sleep(max(0.0, start + at_speech - time.perf_counter()))
                chunk = pcm[i:min(i + step, len(pcm))]
                await ws.send(chunk.tobytes())
                sent_at[i:i + len(chunk) + 1] = time.perf_counter()
            await ws.send(json.dumps({"end": True}))

        sender = asyncio.create_task(send())
        try:
            async for message in ws:
                reply = json.loads(message)
                now = time.perf_counter()
                if "error" in reply:
                    errors.append(reply["error"])
                if reply.get("neutral_reference"):
                    reference = reply["neutral_reference"]
                if "neutral_reference" in reply or "error" in reply:
                    referenced.set()  # made, or could not be: the speech goes on either way
                for frame in reply.get("frames", []):
                    frames[frame["frame"]] = frame
                    arrived[frame["frame"]] = now
                if reply.get("done"):
                    break
        except BaseException as e:  # the server closed the stream (a limit) or the connection was lost
            sender.cancel()
            await asyncio.gather(sender, return_exceptions=True)
            if isinstance(e, ConnectionClosedError) and errors:
                raise _Problem(f"the server closed the stream: {errors[-1]}") from None
            raise
        await sender
    order = sorted(frames)
    if order != list(range(len(order))):
        raise _Problem("frames arrived with gaps")
    order = order[skip:]
    index = np.minimum((np.array(order) / 30.0 * TARGET_SAMPLE_RATE).astype(int), len(pcm))
    latency = np.array([arrived[i] for i in order]) - sent_at[index]
    poses = np.array([frames[i]["poses"] for i in order], np.float32).reshape(-1, 55, 3)
    trans = np.array([frames[i]["trans"] for i in order], np.float32).reshape(-1, 3)
    return LiveResult(poses, trans, latency, errors, reference)
