"""``emogesture live``: a WebSocket server that animates speech as it arrives (:class:`GestureStream`).

Who may connect (:mod:`emogesture.access`): on a loopback address (127.0.0.1, ::1, localhost) anyone on this
machine; on any other address, or when a token is given, only clients that give the server's token as
``?token=...`` on the URL of the page, of ``/health`` and of ``/live`` (the page passes its own on; a browser
also gets it as a cookie); without it the answer is HTTP 403. A browser's WebSocket from another site's page
(its ``Origin`` another host or port than the server's) is refused with 403 too. ``GET /health``
answers ``{"streams": n, "capacity": N}``: the streams open and the most taken at once.

Protocol, on ``ws://HOST:PORT/live`` (every text message is one JSON object):

0. A stream beyond the server's capacity (``--max-streams``) gets ``{"error": "server busy: ..."}`` and is
   closed with code 1013 (try again later); the streams running go on undisturbed.
1. The client's first message: ``{"sample_rate": 16000, "emotion": "auto"}``; also optional
   ``emotion_weight`` (0-1, with a label), ``seed`` (integer), ``skeleton`` (``smplx`` or ``mixamo``),
   ``style_from`` (a training speaker's BEAT id: gesture in that speaker's style) and ``face`` (true: a face
   too). The server answers
   ``{"ready": true, "fps": 30, "skeleton": ..., "bones": [names], "speakers": [ids for style_from],
   "capacity": N, "limits": {"message_bytes": b, "stream_minutes": m, "idle_s": s}}``.
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
6. Limits (:class:`LiveLimits`), each told in one ``{"error": ...}`` line before the close: a message over
   :data:`MAX_MESSAGE_BYTES` (4 MiB: two minutes of 16-kHz audio) closes the stream with code 1009; more
   audio than ``--max-stream-minutes`` (default 60) in one stream, or no message at all for
   ``--idle-timeout`` seconds (default 60; not counted while the server makes a neutral reference), close
   it with code 1008.

Streams share one pipeline; the updates of every stream whose audio waits are drawn together in one batched
pass (the speech encoders, the diffusion draws and their decoding for all at once, each stream's filterbank
on its own; one stream's updates one after another), while each connection's messages are read as they
arrive. A stream whose audio waited while a pass ran is updated once for all of it (its frames then come in a larger batch), so a loaded
server falls behind by a bounded amount instead of without end.
"""

from __future__ import annotations

import asyncio
import json
import os
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from functools import partial
from http import HTTPStatus
from pathlib import Path
from urllib.parse import urlsplit

import numpy as np
import torch

from emogesture.access import FORBIDDEN_TEXT, FOREIGN_ORIGIN_TEXT, TokenCheck, check_served, same_origin
from emogesture.assets import ASSETS
from emogesture.audio import TARGET_SAMPLE_RATE, resample
from emogesture.errors import EmogestureError
from emogesture.export.gltf import glb_bytes, sequence_to_gltf
from emogesture.motion.rigs import rig_named
from emogesture.motion.rotations import axis_angle_to_matrix, matrix_to_quaternion
from emogesture.pipeline.generate import GesturePipeline
from emogesture.pipeline.perception import perception_of
from emogesture.pipeline.stream import GestureStream, StreamFrames, push_together
from emogesture.types import SMPLXSequence

PAGE = Path(__file__).with_name("page.html")
RATES = (8000, 48000)
FIRST_KEYS = {"sample_rate", "emotion", "emotion_weight", "seed", "skeleton", "style_from", "face"}
NEUTRAL_SECONDS = 60.0  # the most of a neutral recording kept (the least: neutral_reference.MIN_SECONDS)
MAX_MESSAGE_BYTES = 4 * 2 ** 20  # the largest message a client may send: two minutes of 16-kHz audio
MAX_STREAM_MINUTES = 60.0  # the most audio one stream may carry
IDLE_TIMEOUT = 60.0  # seconds without a message from the client before its stream is closed
#: streams taken at once per CPU core by default: twelve on two cores keep a median latency of 0.4 s and a 95th
#: percentile of 0.7 s, sixteen do not (bench/results/live_many.md)
STREAMS_PER_CORE = 6
BUSY, POLICY, TOO_BIG = 1013, 1008, 1009  # close codes: try again later, policy violation, message too big


def default_max_streams() -> int:
    """Streams taken at once: :data:`STREAMS_PER_CORE` per CPU core, at least one."""
    return max(1, STREAMS_PER_CORE * (os.cpu_count() or 1))


@dataclass(frozen=True)
class LiveLimits:
    """What the server takes (module docstring, points 0 and 6)."""

    max_streams: int = field(default_factory=default_max_streams)
    max_stream_minutes: float = MAX_STREAM_MINUTES
    idle_timeout: float = IDLE_TIMEOUT
    max_message_bytes: int = MAX_MESSAGE_BYTES

    def __post_init__(self) -> None:
        if isinstance(self.max_streams, bool) or not isinstance(self.max_streams, int) or self.max_streams < 1:
            raise EmogestureError(f"at most {self.max_streams} streams at once: give at least 1 (--max-streams)")
        if not self.max_stream_minutes > 0:
            raise EmogestureError(f"{self.max_stream_minutes} minutes per stream: give more than 0 "
                                  "(--max-stream-minutes)")
        if not self.idle_timeout > 0:
            raise EmogestureError(f"an idle timeout of {self.idle_timeout} s: give more than 0 (--idle-timeout)")
        if self.max_message_bytes < 1024:
            raise EmogestureError(f"messages of at most {self.max_message_bytes} bytes: give at least 1024")

    def announced(self) -> dict:
        """The limits as the ready message states them."""
        return {"message_bytes": self.max_message_bytes, "stream_minutes": self.max_stream_minutes,
                "idle_s": self.idle_timeout}

    def stream_bytes(self, rate: int) -> int:
        """The most bytes of audio one stream at ``rate`` may carry."""
        return int(2 * rate * 60 * self.max_stream_minutes)

    def busy(self) -> str:
        n = self.max_streams
        return f"server busy: {n} {'stream' if n == 1 else 'streams'} at once, the most it takes; try again later"

    def idle(self) -> str:
        return f"no message for {self.idle_timeout:g} s: the stream is closed (send audio, or {{\"end\": true}})"

    def too_long(self) -> str:
        return (f"stream too long: more than {self.max_stream_minutes:g} min of audio, the most one stream takes; "
                "start a new stream")


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
        # rounded and turned into lists a block at a time (each frame's on its own costs the event loop)
        moved = np.round(trans, 5).tolist()
        turned = np.round(q if skeleton == "mixamo" else poses, 5).tolist()
        face = None if block.sequence.arkit is None else np.round(block.sequence.arkit, 4).tolist()
        for k in range(len(block)):
            i = block.start + k
            frame = {"frame": i, "time": round(i / fps, 5), "trans": moved[k],
                     "rotations" if skeleton == "mixamo" else "poses": turned[k]}
            if face is not None:
                frame["arkit"] = face[k]
            out.append(frame)
    return json.dumps({"frames": out, "audio_s": round(audio_s, 4)}, separators=(",", ":"))


#: with more streams than this open (or in one pass), every pass is drawn as a loaded one (one candidate per
#: update, fewer DDIM steps: :data:`~emogesture.pipeline.stream.LOADED_STEPS`): the draws and their decoding are
#: most of a pass's cost, and a loaded server's passes are mostly small ones, its threads taking turns
#: (``experiments/live/README.md``)
LOADED_PASS = 2


class UpdateBatcher:
    """The streams' audio that waits together becomes frames in one batched pass: each stream's push joins a
    queue, and a free one of ``threads`` threads takes everything queued at once
    (:func:`~emogesture.pipeline.stream.push_together`), so that the more streams wait, the larger and cheaper
    per stream each pass is, while another pass may run beside it; while more than :data:`LOADED_PASS` streams
    are open (``open_streams``: how many; None: the pass's own) or in one pass, the pass is drawn as a loaded
    one."""

    def __init__(self, threads: int = 1, open_streams: Callable[[], int] | None = None) -> None:
        self.open_streams = open_streams
        self.queue: list[tuple] = []
        self.lock = threading.Lock()
        self.thread = ThreadPoolExecutor(max_workers=threads, thread_name_prefix="emogesture-live-batch")

    async def push(self, stream: GestureStream, samples: np.ndarray, rate: int) -> list[StreamFrames]:
        """``stream.push(samples, rate, catch_up=True)``, drawn together with the other streams' that wait."""
        loop = asyncio.get_running_loop()
        future = loop.create_future()
        with self.lock:
            self.queue.append((stream, samples, rate, future))
        loop.run_in_executor(self.thread, self._drain, loop)
        return await future

    def _drain(self, loop: asyncio.AbstractEventLoop) -> None:
        with self.lock:
            jobs, self.queue = self.queue, []
        if not jobs:
            return  # an earlier pass took them
        try:
            load = max(len(jobs), self.open_streams() if self.open_streams is not None else 0)
            results: list = push_together([job[:3] for job in jobs], catch_up=True, loaded=load > LOADED_PASS)
        except Exception as e:  # noqa: BLE001 - the pass's streams are told; the server and other passes go on
            results = [e] * len(jobs)  # (not retried alone: the pass may have taken in some of their audio)
        for (*_, future), result in zip(jobs, results):
            settle = future.set_exception if isinstance(result, Exception) else future.set_result
            loop.call_soon_threadsafe(lambda f=future, s=settle, r=result: f.done() or s(r))


class LiveServer:
    """The server's state: one pipeline, the streams' updates drawn together in batched passes
    (:class:`UpdateBatcher`, ``workers`` passes at once), and ``workers`` threads for the rest (a stream's
    last frames, neutral references); one stream's updates always one after another."""

    def __init__(self, pipe: GesturePipeline, workers: int = 1, limits: LiveLimits | None = None) -> None:
        self.pipe = pipe
        self.batcher = UpdateBatcher(workers, lambda: self.streams)
        self.worker = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="emogesture-live")
        self.limits = limits or LiveLimits()
        self.streams = 0  # connections admitted and not yet closed

    def health(self) -> dict:
        """``GET /health``: the streams open and the most taken at once."""
        return {"streams": self.streams, "capacity": self.limits.max_streams}

    async def handle(self, connection) -> None:
        """One connection: admitted when the server has room (else told it is busy), then its stream."""
        from websockets.exceptions import ConnectionClosed

        if self.streams >= self.limits.max_streams:
            await self._close(connection, BUSY, self.limits.busy())
            return
        self.streams += 1
        try:
            await self._open(connection)
        except ConnectionClosed:
            pass  # the client left
        finally:
            self.streams -= 1

    async def _open(self, connection) -> None:
        """Read the first message (a bad one, or none within the idle timeout, closes the connection), answer
        ready, and run the stream."""
        try:
            first = json.loads(await asyncio.wait_for(connection.recv(), self.limits.idle_timeout))
            stream, rate, skeleton = open_stream(self.pipe, first)
        except TimeoutError:
            await self._close(connection, POLICY, self.limits.idle())
            return
        except (ValueError, TypeError, EmogestureError) as e:
            message = str(e) if isinstance(e, EmogestureError) else f"the first message is not JSON ({e})"
            await self._close(connection, POLICY, message)
            return
        rig = rig_named(skeleton)
        await connection.send(json.dumps({"ready": True, "fps": self.pipe.fps, "skeleton": skeleton,
                                          "bones": list(rig.names), "speakers": sorted(speaker_styles(self.pipe)),
                                          "capacity": self.limits.max_streams, "limits": self.limits.announced()}))
        await self._run(connection, stream, rate, skeleton)

    @staticmethod
    async def _close(connection, code: int, message: str) -> None:
        """Tell the client why in one ``{"error": ...}`` line, then close with ``code``; a client already
        gone is let go."""
        from websockets.exceptions import ConnectionClosed

        try:
            await connection.send(json.dumps({"error": message}))
            await connection.close(code, message.encode()[:120].decode(errors="ignore"))
        except ConnectionClosed:
            pass

    async def _receive(self, connection, state: dict) -> str | bytes | None:
        """The client's next message; None when the client left, or when it was silent for the idle timeout
        (then ``state["stop"]`` says so; a neutral reference being made for it is no silence)."""
        from websockets.exceptions import ConnectionClosed

        while True:
            try:
                return await asyncio.wait_for(connection.recv(), self.limits.idle_timeout)
            except TimeoutError:
                if not state["tasks"]:
                    state["stop"] = (POLICY, self.limits.idle())
                    return None
            except ConnectionClosed:
                return None

    async def _run(self, connection, stream: GestureStream, rate: int, skeleton: str) -> None:
        """Read the client's messages as they come (so the connection never stalls), and turn the audio that
        waits into frames whenever the worker is free: one update for all of it when the stream fell behind."""
        loop = asyncio.get_running_loop()
        audio = bytearray()
        state = {"end": False, "closed": False, "neutral": None, "tasks": set(), "stop": None, "received": 0}
        most = self.limits.stream_bytes(rate)
        wake = asyncio.Event()

        async def read() -> None:
            try:
                while (message := await self._receive(connection, state)) is not None:
                    if isinstance(message, bytes):
                        state["received"] += len(message)
                        if state["received"] > most:
                            state["stop"] = (POLICY, self.limits.too_long())
                            return
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
                if state["stop"] is not None:
                    await self._close(connection, *state["stop"])
                    return
                whole = len(audio) // 2 * 2
                if whole:
                    samples = np.frombuffer(bytes(audio[:whole]), "<i2").astype(np.float32) / 32768.0
                    del audio[:whole]
                    frames = await self.batcher.push(stream, samples, rate)
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


def threads_per_worker(workers: int) -> int:
    """Torch's threads for each update thread's passes: the CPU cores shared out among the ``workers`` update
    threads, at least one. Two passes each spreading over both of two cores fight for them (their threads wait
    spinning for each other), and the event loop and the clients are left no core: on two cores, two update
    threads of one torch thread each gave 12 streams a median of 0.33-0.37 s against 0.47-0.57 s, and one
    stream 0.20 s against 0.24 s (``experiments/live/README.md``)."""
    return max(1, (os.cpu_count() or 1) // max(1, workers))


def _respond(connection, kind: str, body: bytes, cookie: str | None = None):
    """An HTTP 200 response with ``body`` of content type ``kind`` (and a ``Set-Cookie``)."""
    response = connection.respond(HTTPStatus.OK, "")
    response.body = body
    for key, value in (("Content-Type", kind), ("Content-Length", str(len(body)))):
        del response.headers[key]  # a multi-valued mapping: replace, do not add
        response.headers[key] = value
    if cookie is not None:
        response.headers["Set-Cookie"] = cookie
    return response


def _header(request, name: str) -> str | None:
    """A request header's value (several joined as cookies are), None when absent."""
    values = request.headers.get_all(name)
    return "; ".join(values) if values else None


def _explain_too_big(protocol, limit: int) -> None:
    """Make ``protocol`` (websockets' Sans-I/O connection) send the client one ``{"error": ...}`` line before
    the close (code 1009) that answers a message over ``limit`` bytes, as every other limit does."""
    fail = protocol.fail
    message = json.dumps({"error": f"message too big: more than {limit} bytes ({limit / 2 ** 20:.3g} MiB); send "
                                   "the audio in smaller messages"})

    def fail_explained(code: int, reason: str = "") -> None:
        if code == TOO_BIG and protocol.state.name == "OPEN":
            protocol.send_text(message.encode())
        fail(code, reason)

    protocol.fail = fail_explained


def _connection(protocol, *args, limit: int, **kwargs):
    """websockets' server connection, its messages over ``limit`` bytes explained (:func:`_explain_too_big`)."""
    from websockets.asyncio.server import ServerConnection

    _explain_too_big(protocol, limit)
    return ServerConnection(protocol, *args, **kwargs)


async def serve_live(pipe: GesturePipeline, host: str = "127.0.0.1", port: int = 8765,
                     ready: asyncio.Future | None = None, workers: int | None = None, *,
                     limits: LiveLimits | None = None, token: str | None = None) -> None:
    """Serve ``/live``, the page at ``/`` and ``/health`` on ``host:port`` until cancelled, with ``workers``
    update threads (None: :func:`default_workers`), within ``limits`` (None: :class:`LiveLimits`' defaults).
    ``token``: the one clients must give (module docstring); needed beyond loopback."""
    from websockets.asyncio.server import serve

    check_served(host, token)
    limits = limits or LiveLimits()
    workers = workers or default_workers()
    server = LiveServer(pipe, workers, limits)
    tokens = TokenCheck(token, port)
    rest = SMPLXSequence(poses=np.zeros((1, 55, 3), np.float32), trans=np.zeros((1, 3), np.float32),
                         arkit=np.zeros((1, 52), np.float32))  # its face at rest, for the streams that ask for one
    files = {  # path -> (content type, body): the page, its mannequin code and the mannequin at rest
        "/": ("text/html; charset=utf-8", PAGE.read_bytes()),
        "/mannequin.js": ("text/javascript; charset=utf-8", (ASSETS / "web" / "mannequin.js").read_bytes()),
        "/mannequin.glb": ("model/gltf-binary", glb_bytes(*sequence_to_gltf(rest, "mannequin"))),
    }

    def http(connection, request):
        url = urlsplit(request.path)
        if not tokens.allows(url.query, _header(request, "Cookie")):
            return connection.respond(HTTPStatus.FORBIDDEN, FORBIDDEN_TEXT)
        if url.path == "/live":
            if not same_origin(_header(request, "Origin"), _header(request, "Host")):
                return connection.respond(HTTPStatus.FORBIDDEN, FOREIGN_ORIGIN_TEXT)
            return None  # the WebSocket handshake goes on
        if url.path == "/health":
            return _respond(connection, "application/json", json.dumps(server.health()).encode())
        if url.path in files:
            return _respond(connection, *files[url.path], tokens.set_cookie(url.query))
        return connection.respond(HTTPStatus.NOT_FOUND, "not found: the stream is at /live, the page at /\n")

    threads = torch.get_num_threads()
    torch.set_num_threads(threads_per_worker(workers))  # the update threads start with it (and restored after)
    try:
        async with serve(server.handle, host, port, process_request=http, max_size=limits.max_message_bytes,
                         create_connection=partial(_connection, limit=limits.max_message_bytes)) as running:
            if ready is not None:
                ready.set_result(running)
            await asyncio.get_running_loop().create_future()
    finally:
        torch.set_num_threads(threads)
