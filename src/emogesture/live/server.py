"""``emogesture live``: a WebSocket server that animates speech as it arrives (:class:`GestureStream`).

Protocol, on ``ws://HOST:PORT/live`` (every text message is one JSON object):

1. The client's first message: ``{"sample_rate": 16000, "emotion": "auto"}``; also optional
   ``emotion_weight`` (0-1, with a label), ``seed`` (integer), ``skeleton`` (``smplx`` or ``mixamo``),
   ``style_from`` (a training speaker's BEAT id: gesture in that speaker's style) and ``face`` (true: a face
   too). The server answers
   ``{"ready": true, "fps": 30, "skeleton": ..., "bones": [names], "speakers": [ids for style_from]}``.
2. Then binary messages: little-endian 16-bit mono PCM at that rate, in chunks of any size.
3. At any time, text messages ``{"emotion": "anger", "emotion_weight": 0.8}`` change the emotion from the
   next update on (about every 0.25 s of audio); ``{"end": true}`` flushes the last frames, the server sends
   ``{"done": true, "total_frames": N}`` and closes. ``{"neutral": "start"}`` ... ``{"neutral": "stop"}``:
   the audio between the two (animated as usual) is the speaker's neutral voice, speaking without emotion
   (at least 10 s; the first 60 s are kept); from the next update after the reply on, the speech's emotion is read against it
   (:mod:`emogesture.pipeline.neutral_reference`, as ``generate --neutral-from``), and the server answers
   ``{"neutral_reference": {"seconds": s, "windows": n}}``; ``{"neutral": "clear"}`` goes back to the speech
   alone (answer ``{"neutral_reference": null}``).
4. The server sends ``{"frames": [...], "audio_s": seconds received}`` as soon as frames are decided, in
   order, one frame per 1/30 s of audio: ``{"frame": i, "time": i / 30, "poses": [[x, y, z] x 55]
   (axis-angle, SMPL-X order), "trans": [x, y, z]}``; with ``"skeleton": "mixamo"``,
   ``"rotations"``:
   a unit quaternion ``[x, y, z, w]`` per bone of ``bones`` (Mixamo's 52) in place of ``poses``. With
   ``"face": true`` each frame also has ``"arkit"``: the 52 ARKit blendshape weights in Apple's order (the jaw
   and eyes are in the poses).
5. A message the server cannot use (malformed JSON, an unknown key or emotion, text where audio is
   expected, a wrong sample rate) gets ``{"error": "one line"}``; a bad first message also closes the
   connection (code 1008). Other streams never notice.

Streams share one pipeline; their updates run on a few worker threads (one per core, at most four; one
stream's updates one after another), while each connection's messages are read as they arrive. A stream
whose audio waited while the workers were busy is updated once for all of it (its frames then come in a
larger batch), so a loaded server falls behind by a bounded amount instead of without end.
"""

from __future__ import annotations

import asyncio
import json
import os
from concurrent.futures import ThreadPoolExecutor
from functools import partial
from http import HTTPStatus
from pathlib import Path

import numpy as np
import torch

from emogesture.assets import ASSETS
from emogesture.audio import TARGET_SAMPLE_RATE, resample
from emogesture.errors import EmogestureError
from emogesture.export.gltf import glb_bytes, sequence_to_gltf
from emogesture.motion.rigs import rig_named
from emogesture.motion.rotations import axis_angle_to_matrix, matrix_to_quaternion
from emogesture.pipeline.generate import GesturePipeline
from emogesture.pipeline.perception import perception_of
from emogesture.pipeline.stream import GestureStream, StreamFrames
from emogesture.types import SMPLXSequence

PAGE = Path(__file__).with_name("page.html")
RATES = (8000, 48000)
FIRST_KEYS = {"sample_rate", "emotion", "emotion_weight", "seed", "skeleton", "style_from", "face"}
NEUTRAL_SECONDS = 60.0  # the most of a neutral recording kept (the least: neutral_reference.MIN_SECONDS)


def speaker_styles(pipe: GesturePipeline) -> dict[int, np.ndarray]:
    """The training speakers' mean style latents by BEAT speaker id (empty when the speech model has no
    perception calibration, which holds them)."""
    perception = perception_of(pipe.speech)
    speakers = sorted(pipe.speech.loaded.metadata.speakers or [])
    if perception is None or len(perception.voice.means) != len(speakers):
        return {}
    return {int(k): mean for k, mean in zip(speakers, perception.voice.means)}


def open_stream(pipe: GesturePipeline, first: dict) -> tuple[GestureStream, int, str]:
    """The first message -> the stream, its sample rate and its skeleton; a one-line error for a bad one."""
    if not isinstance(first, dict):
        raise EmogestureError("the first message must be a JSON object such as {\"sample_rate\": 16000}")
    unknown = set(first) - FIRST_KEYS
    if unknown:
        raise EmogestureError(f"unknown key(s) {sorted(unknown)}; known: {sorted(FIRST_KEYS)}")
    rate = first.get("sample_rate")
    if not isinstance(rate, int) or isinstance(rate, bool) or not RATES[0] <= rate <= RATES[1]:
        raise EmogestureError(f"sample_rate {rate!r}: an integer from {RATES[0]} to {RATES[1]} Hz")
    skeleton = first.get("skeleton", "smplx")
    rig_named(str(skeleton))
    seed = first.get("seed", 0)
    if not isinstance(seed, int) or isinstance(seed, bool):
        raise EmogestureError(f"seed {seed!r}: an integer")
    style = None
    if "style_from" in first:
        styles = speaker_styles(pipe)
        if first["style_from"] not in styles:
            raise EmogestureError(f"style_from {first['style_from']!r}: one of the model's speakers "
                                  f"{sorted(styles) or '(this model lists none)'}")
        style = styles[first["style_from"]]
    face = first.get("face", False)
    if not isinstance(face, bool):
        raise EmogestureError(f"face {face!r}: true or false")
    stream = GestureStream(pipe, emotion=str(first.get("emotion", "auto")), emotion_weight=first.get("emotion_weight"),
                           style=style, seed=seed, face=face)
    return stream, rate, str(skeleton)


def frames_message(frames: list[StreamFrames], fps: float, skeleton: str, audio_s: float) -> str:
    """Decided frames -> the JSON text the server sends (module docstring, point 4)."""
    out = []
    for block in frames:
        poses, trans = block.sequence.poses, block.sequence.trans
        if skeleton == "mixamo":
            rig = rig_named(skeleton)
            q = matrix_to_quaternion(axis_angle_to_matrix(torch.from_numpy(poses[:, list(rig.joints)]))).numpy()
        for k in range(len(block)):
            i = block.start + k
            frame = {"frame": i, "time": round(i / fps, 5), "trans": np.round(trans[k], 5).tolist()}
            if skeleton == "mixamo":
                frame["rotations"] = np.round(q[k], 5).tolist()
            else:
                frame["poses"] = np.round(poses[k], 5).tolist()
            if block.sequence.arkit is not None:
                frame["arkit"] = np.round(block.sequence.arkit[k], 4).tolist()
            out.append(frame)
    return json.dumps({"frames": out, "audio_s": round(audio_s, 4)}, separators=(",", ":"))


class LiveServer:
    """The server's state: one pipeline, ``workers`` threads running the streams' updates (one stream's
    updates always one after another; the model's weights are held, never swapped, so updates of different
    streams may run at once)."""

    def __init__(self, pipe: GesturePipeline, workers: int = 1) -> None:
        self.pipe = pipe
        self.worker = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="emogesture-live")
        self.streams = 0

    async def handle(self, connection) -> None:
        try:
            first = json.loads(await connection.recv())
            stream, rate, skeleton = open_stream(self.pipe, first)
        except (ValueError, TypeError, EmogestureError) as e:
            message = str(e) if isinstance(e, EmogestureError) else f"the first message is not JSON ({e})"
            await connection.send(json.dumps({"error": message}))
            await connection.close(1008, message[:120])
            return
        rig = rig_named(skeleton)
        await connection.send(json.dumps({"ready": True, "fps": self.pipe.fps, "skeleton": skeleton,
                                          "bones": list(rig.names), "speakers": sorted(speaker_styles(self.pipe))}))
        self.streams += 1
        try:
            await self._run(connection, stream, rate, skeleton)
        finally:
            self.streams -= 1

    async def _run(self, connection, stream: GestureStream, rate: int, skeleton: str) -> None:
        """Read the client's messages as they come (so the connection never stalls), and turn the audio that
        waits into frames whenever the worker is free: one update for all of it when the stream fell behind."""
        loop = asyncio.get_running_loop()
        audio, state = bytearray(), {"end": False, "closed": False, "neutral": None, "tasks": set()}
        wake = asyncio.Event()

        async def read() -> None:
            try:
                async for message in connection:
                    if isinstance(message, bytes):
                        audio.extend(message)
                        if state["neutral"] is not None and len(state["neutral"]) < 2 * rate * NEUTRAL_SECONDS:
                            state["neutral"].extend(message)
                    else:
                        try:
                            action = self._control(stream, message)
                            state["end"] = action == "end"
                            if action.startswith("neutral"):
                                await self._neutral(connection, stream, action, state, rate, len(audio) % 2)
                        except EmogestureError as e:
                            await connection.send(json.dumps({"error": str(e)}))
                    wake.set()
                    if state["end"]:
                        return
            finally:
                state["closed"] = True
                wake.set()

        reader = asyncio.create_task(read())
        try:
            while True:
                await wake.wait()
                wake.clear()
                whole = len(audio) // 2 * 2
                if whole:
                    samples = np.frombuffer(bytes(audio[:whole]), "<i2").astype(np.float32) / 32768.0
                    del audio[:whole]
                    push = partial(stream.push, samples, rate, catch_up=True)
                    frames = await loop.run_in_executor(self.worker, push)
                    if frames:
                        await connection.send(frames_message(frames, self.pipe.fps, skeleton, stream.seconds))
                    if len(audio) >= 2:
                        wake.set()  # more came while the worker was busy
                        continue
                if state["end"]:
                    frames = await loop.run_in_executor(self.worker, stream.end)
                    if frames:
                        await connection.send(frames_message(frames, self.pipe.fps, skeleton, stream.seconds))
                    await connection.send(json.dumps({"done": True, "total_frames": stream.sent}))
                    await connection.close()
                    return
                if state["closed"]:
                    return
        finally:
            reader.cancel()

    async def _neutral(self, connection, stream: GestureStream, action: str, state: dict, rate: int,
                       odd: int) -> None:
        """Start, stop or clear the speaker's neutral recording (module docstring, point 3); ``odd``: 1 when
        the audio received so far ends half-way through a sample. The reference is made by a worker while
        the connection's messages go on being read."""
        if action == "neutral start":
            if state["neutral"] is not None:
                raise EmogestureError("a neutral recording is already being taken; send {\"neutral\": \"stop\"}")
            state["neutral"], state["neutral_skip"] = bytearray(), odd  # whole samples only
            return
        if action == "neutral clear":
            state["neutral"] = None
            stream.set_neutral_reference(None)
            await connection.send(json.dumps({"neutral_reference": None}))
            return
        if state["neutral"] is None:
            raise EmogestureError("no neutral recording is being taken; send {\"neutral\": \"start\"} first")
        pcm, state["neutral"] = bytes(state["neutral"][state["neutral_skip"]:]), None
        pcm = pcm[: len(pcm) // 2 * 2]
        wave = resample(np.frombuffer(pcm, "<i2").astype(np.float32) / 32768.0, rate, TARGET_SAMPLE_RATE)
        task = asyncio.create_task(self._take_reference(connection, stream, wave, len(pcm) // 2 / rate))
        state["tasks"].add(task)
        task.add_done_callback(state["tasks"].discard)

    async def _take_reference(self, connection, stream: GestureStream, wave: np.ndarray, seconds: float) -> None:
        """Make the neutral reference of ``wave`` (16 kHz) in a worker, set it and tell the client; a problem
        is a one-line error to the client, the stream going on."""
        try:
            reference = await asyncio.get_running_loop().run_in_executor(self.worker, partial(
                self.pipe.neutral_reference, wave, "the neutral recording", perceived=False))
        except EmogestureError as e:
            message = {"error": str(e)}
        except Exception as e:  # noqa: BLE001 - a client's bad audio must not end the stream
            message = {"error": f"the neutral recording could not be heard: {type(e).__name__}: {e}"[:300]}
        else:
            stream.set_neutral_reference(reference)
            message = {"neutral_reference": {"seconds": round(seconds, 3), "windows": reference.windows}}
        try:
            await connection.send(json.dumps(message))
        except Exception:  # noqa: BLE001 - the client left
            pass

    @staticmethod
    def _control(stream: GestureStream, text: str) -> str:
        """A text message after the first -> ``"emotion"`` (the emotion changed), ``"end"``, or ``"neutral
        start"``, ``"neutral stop"``, ``"neutral clear"``; anything else is a one-line :class:`EmogestureError`
        the server answers, the stream going on."""
        try:
            message = json.loads(text)
        except ValueError:
            raise EmogestureError("expected binary audio or a JSON object; got text that is not JSON") from None
        if not isinstance(message, dict):
            raise EmogestureError("expected a JSON object")
        if message.get("end"):
            return "end"
        if set(message) == {"neutral"}:
            if message["neutral"] not in ("start", "stop", "clear"):
                raise EmogestureError(f"neutral {message['neutral']!r}: start, stop or clear")
            return f"neutral {message['neutral']}"
        if set(message) <= {"emotion", "emotion_weight"} and message:
            stream.set_emotion(str(message.get("emotion", "auto")), message.get("emotion_weight"))
            return "emotion"
        raise EmogestureError(f"unknown message {sorted(message)}; send emotion, emotion_weight, neutral or end")


def default_workers() -> int:
    """Update threads: one per CPU core, at most four."""
    return max(1, min(4, os.cpu_count() or 1))


async def serve_live(pipe: GesturePipeline, host: str = "127.0.0.1", port: int = 8765,
                     ready: asyncio.Future | None = None, workers: int | None = None) -> None:
    """Serve ``/live`` (and the page at ``/``) on ``host:port`` until cancelled, with ``workers`` update
    threads (None: :func:`default_workers`)."""
    from websockets.asyncio.server import serve

    server = LiveServer(pipe, workers or default_workers())
    rest = SMPLXSequence(poses=np.zeros((1, 55, 3), np.float32), trans=np.zeros((1, 3), np.float32))
    files = {  # path -> (content type, body): the page, its mannequin code and the mannequin at rest
        "/": ("text/html; charset=utf-8", PAGE.read_bytes()),
        "/mannequin.js": ("text/javascript; charset=utf-8", (ASSETS / "web" / "mannequin.js").read_bytes()),
        "/mannequin.glb": ("model/gltf-binary", glb_bytes(*sequence_to_gltf(rest, "mannequin"))),
    }

    def http(connection, request):
        if request.path == "/live":
            return None  # the WebSocket handshake goes on
        if request.path in files:
            kind, body = files[request.path]
            response = connection.respond(HTTPStatus.OK, "")
            response.body = body
            for key, value in (("Content-Type", kind), ("Content-Length", str(len(body)))):
                del response.headers[key]  # a multi-valued mapping: replace, do not add
                response.headers[key] = value
            return response
        return connection.respond(HTTPStatus.NOT_FOUND, "not found: the stream is at /live, the page at /\n")

    async with serve(server.handle, host, port, process_request=http, max_size=4 * 2 ** 20) as running:
        if ready is not None:
            ready.set_result(running)
        await asyncio.get_running_loop().create_future()
