"""Latency of `emogesture live` with the bundled model: a 60-s real recording (the packaged real speech,
joined) streamed at the pace of speech in 100-ms chunks by 1 and by 4 clients at once; per client, the seconds
from sending the audio of an instant to receiving its frame (median, 95th percentile), and the frames' count.

Also (``--long MINUTES``, default 10): one stream of that many minutes of the recording repeated, fed to the
library's stream as fast as it goes: the frames against round(seconds x 30), and the process's resident memory
after each minute (no growth expected: the stream keeps a fixed 10-s buffer and no frames).

``--face``: every stream asks for the face too (52 ARKit weights per frame).

``--seconds``: each stream's length (default 60); the server's resident memory is read after each row.

``--max-streams N``: the server's capacity (default: the most streams of a row); the clients of a row beyond it
connect a second after the others and must be told the server is busy; the row's latency is the admitted ones'.

Usage: python bench/live.py [--streams 1 4] [--seconds 60] [--long 10] [--face] [--max-streams N]
                            [--out bench/results/live.md]
"""

from __future__ import annotations

import argparse
import asyncio
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

import numpy as np
import soundfile as sf

from emogesture.checkpoints import write_text_atomic
from emogesture.data.real_speech import RECORDINGS, load_real_recording
from emogesture.errors import EmogestureError
from emogesture.live.client import stream_file


def real_speech(folder: Path, seconds: float = 60.0) -> Path:
    """The packaged real recordings joined (repeated as needed) into one of ``seconds`` seconds."""
    wave = np.concatenate([load_real_recording(r) for r in RECORDINGS])
    wave = np.resize(wave, int(seconds * 16000))
    path = folder / "speech.wav"
    sf.write(path, wave, 16000)
    return path


def server_memory_mb(pid: int) -> tuple[float, float]:
    """The server process's resident memory now and at its peak (MB)."""
    with open(f"/proc/{pid}/status") as f:
        fields = dict(line.split(":", 1) for line in f if ":" in line)
    return int(fields["VmRSS"].split()[0]) / 1024, int(fields["VmHWM"].split()[0]) / 1024


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--streams", type=int, nargs="+", default=[1, 4])
    ap.add_argument("--seconds", type=float, default=60.0, help="length of each stream's recording (s)")
    ap.add_argument("--long", type=float, default=10.0, help="minutes of the long stream (0: none)")
    ap.add_argument("--face", action="store_true", help="every stream with a face (52 ARKit weights a frame)")
    ap.add_argument("--workers", type=int, default=None, help="the server's update threads (default: its own)")
    ap.add_argument("--max-streams", type=int, default=None,
                    help="the server's capacity (default: the most streams of a row); clients beyond it must be refused")
    ap.add_argument("--out", type=Path, default=Path(__file__).parent / "results" / "live.md")
    args = ap.parse_args()
    capacity = args.max_streams or max(args.streams)
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    server = subprocess.Popen([sys.executable, "-m", "emogesture.cli.main", "live", "--port", str(port),
                               "--max-streams", str(capacity),
                               *(["--workers", str(args.workers)] if args.workers else [])],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        for _ in range(120):
            try:
                urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=2)
                break
            except OSError as e:
                if getattr(e, "code", None):
                    break
                time.sleep(1)
        with tempfile.TemporaryDirectory() as work:
            clip = real_speech(Path(work), args.seconds)
            rows, refusals = [], []
            for n in args.streams:
                async def one(k: int):
                    if k < capacity:
                        return await stream_file(f"ws://127.0.0.1:{port}/live", clip, seed=k, face=args.face)
                    await asyncio.sleep(1.0)  # once the admitted streams run
                    try:
                        await stream_file(f"ws://127.0.0.1:{port}/live", clip, seed=k, face=args.face)
                    except EmogestureError as e:
                        return str(e).split(": ", 1)[-1]  # (without the URL)
                    raise SystemExit(f"stream {k + 1} of {n} was admitted beyond a capacity of {capacity}")

                async def run_all():
                    return await asyncio.gather(*(one(k) for k in range(n)))
                results = asyncio.run(run_all())
                refused = [r for r in results if isinstance(r, str)]
                results = [r for r in results if not isinstance(r, str)]
                if refused:
                    refusals.append(f"{n} streams asked of a capacity of {capacity}: {len(refused)} told "
                                    f"\"{refused[0]}\"")
                lat = np.concatenate([r.latency for r in results])
                frames = sorted({len(r.poses) for r in results})
                worst = max(np.quantile(r.latency, 0.95) for r in results)
                rss, peak = server_memory_mb(server.pid)
                rows.append(f"| {n} | {np.median(lat):.3f} | {np.quantile(lat, 0.95):.3f} | {worst:.3f} | {lat.max():.3f} | "
                            f"{', '.join(map(str, frames))} | {rss:.0f} ({peak:.0f}) |")
                print(rows[-1], flush=True)
    finally:
        os.killpg(server.pid, signal.SIGTERM)
    text = ("# emogesture live: latency on this machine\n\n"
            f"`python bench/live.py` ({os.cpu_count()} CPU cores, the clients on the same cores; the bundled model; a "
            f"{args.seconds:g}-s real recording streamed at the pace of speech in 100-ms chunks per client"
            + ("; each stream with a face" if args.face else "") + "). Latency: from the client sending the audio of "
            "an instant to it receiving the frame of that instant; median and 95th percentile over every stream's "
            "frames, the worst stream's 95th percentile; the server's resident memory after the run (its peak so "
            "far).\n\n"
            "| streams at once | median (s) | 95th percentile (s) | worst stream's p95 (s) | largest (s) | frames per "
            "stream | server memory, MB |\n|---|---|---|---|---|---|---|\n" + "\n".join(rows) + "\n")
    if refusals:
        text += "\nThe latency of the admitted streams; " + "; ".join(refusals) + ".\n"
    if args.long > 0:
        text += long_stream(args.long)
    write_text_atomic(args.out, text)
    print(args.out)


def resident_mb() -> float:
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmRSS")) / 1024


def long_stream(minutes: float) -> str:
    """One stream of ``minutes`` minutes through the library: frames and resident memory per minute."""
    from emogesture.pipeline.generate import GesturePipeline
    from emogesture.pipeline.stream import GestureStream

    pipe = GesturePipeline.from_run()
    wave = np.concatenate([load_real_recording(r) for r in RECORDINGS])
    stream = GestureStream(pipe)
    memory, frames, sent = [], 0, 0
    start = time.perf_counter()
    total = int(minutes * 60 * 16000)
    while sent < total:
        piece = np.resize(wave[sent % len(wave):], min(1600, total - sent))
        frames += sum(len(b) for b in stream.push(piece))
        sent += len(piece)
        if sent % (60 * 16000) == 0:
            memory.append(resident_mb())
            print(f"minute {len(memory)}: {memory[-1]:.0f} MB", flush=True)
    frames += sum(len(b) for b in stream.end())
    seconds = time.perf_counter() - start
    return (f"\nA {minutes:g}-minute stream through the library, fed as fast as it goes ({seconds:.0f} s): "
            f"{frames} frames for {round(total / 16000 * 30)} expected; resident memory after each minute (MB): "
            + ", ".join(f"{m:.0f}" for m in memory) + ".\n")


if __name__ == "__main__":
    main()
