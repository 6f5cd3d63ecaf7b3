"""``emogesture live`` (the streaming server) and ``emogesture live-client`` (stream a file to it)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from emogesture.live.server import LiveLimits


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("live", help="stream speech in, gestures out, over a WebSocket (on 127.0.0.1 unless --host)",
                       description="Serve ws://HOST:PORT/live: 16-bit PCM in, SMPL-X frames out as soon as each is "
                       "decided, the emotion changeable while streaming (protocol: emogesture.live.server).")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1: this machine only)")
    p.add_argument("--port", type=int, default=8765, help="port (default 8765)")
    p.add_argument("--model", type=Path, help="run folder of `emogesture train gesture` (default: the bundled model)")
    p.add_argument("--speech-model", type=Path, help="speech model run (default: the one the model names)")
    p.add_argument("--device", default="auto", help="auto, cpu, cuda or cuda:N")
    p.add_argument("--precision", default="auto", choices=["auto", "fp32", "bf16"], help="as for generate")
    p.add_argument("--workers", type=int, default=None,
                   help="threads drawing the streams' updates, each pass for every stream that waits (default: one "
                   "per CPU core, at most 4)")
    p.add_argument("--token", metavar="SECRET",
                   help="the token clients must give as ?token=SECRET (needed beyond 127.0.0.1: without it one is "
                   "made and printed with the page's URL; given on 127.0.0.1, enforced there too)")
    p.add_argument("--max-streams", type=int, metavar="N", default=None,
                   help="streams taken at once; one more is told the server is busy (default: 6 per CPU core)")
    p.add_argument("--max-stream-minutes", type=float, metavar="MIN", default=None,
                   help="the most audio one stream may carry, in minutes (default 60)")
    p.add_argument("--idle-timeout", type=float, metavar="S", default=None,
                   help="seconds without a message from a client before its stream is closed (default 60)")
    p.set_defaults(func=run_live)

    p = sub.add_parser("live-client", help="stream a recording to `emogesture live` and report the latency",
                       description="Send SPEECH to a live server in chunks at the pace of speech; print how many "
                       "frames came back and how late; optionally save them as a BEAT2 npz.")
    p.add_argument("speech", type=Path, help="speech audio (any format generate reads)")
    p.add_argument("--url", default="ws://127.0.0.1:8765/live", help="the server (default ws://127.0.0.1:8765/live)")
    p.add_argument("--token", metavar="SECRET", help="the server's token (the one it printed; or ?token= in --url)")
    p.add_argument("--emotion", default="auto", help="auto, own or an emotion label")
    p.add_argument("--neutral-from", type=Path, metavar="WAV",
                   help="a recording of the same speaker speaking without emotion (at least 10 s), sent first: "
                   "the speech's emotion is heard against it (its own frames are left out)")
    p.add_argument("--chunk", type=float, default=0.1, help="seconds of audio per message (default 0.1)")
    p.add_argument("--fast", action="store_true", help="send as fast as possible instead of at the pace of speech")
    p.add_argument("-o", "--out", type=Path, help="write the frames received as this .npz")
    p.add_argument("--overwrite", action="store_true", help="replace --out if it exists")
    p.set_defaults(func=run_live_client)


def _limits(args: argparse.Namespace) -> LiveLimits:
    """The server's limits from the options (those left out: the defaults)."""
    from emogesture.live.server import LiveLimits

    given = {"max_streams": args.max_streams, "max_stream_minutes": args.max_stream_minutes,
             "idle_timeout": args.idle_timeout}
    return LiveLimits(**{k: v for k, v in given.items() if v is not None})


def run_live(args: argparse.Namespace) -> int:
    import asyncio

    from emogesture.access import server_token, url_host, with_token
    from emogesture.errors import EmogestureError
    from emogesture.live.server import serve_live
    from emogesture.pipeline.generate import GesturePipeline
    from emogesture.runtime import resolve_device

    if args.workers is not None and args.workers < 1:
        raise EmogestureError(f"--workers {args.workers}: at least 1")
    limits = _limits(args)
    token = server_token(args.host, args.token)

    pipe = GesturePipeline.from_run(args.model, args.speech_model, device=resolve_device(args.device),
                                    precision=args.precision)
    where = f"{url_host(args.host)}:{args.port}"
    print(f"emogesture live: {with_token(f'ws://{where}/live', token)} (the page: "
          f"{with_token(f'http://{where}/', token)})", flush=True)
    print(f"  at most {limits.max_streams} streams at once, {limits.max_stream_minutes:g} min of audio per stream, "
          f"closed after {limits.idle_timeout:g} s without a message; GET /health tells the load", flush=True)
    try:
        asyncio.run(serve_live(pipe, args.host, args.port, workers=args.workers, limits=limits, token=token))
    except OSError as e:
        raise EmogestureError(f"cannot listen on {args.host}:{args.port} ({e.strerror or e})") from None
    return 0


def run_live_client(args: argparse.Namespace) -> int:
    import asyncio

    import numpy as np

    from emogesture.fileio import check_output
    from emogesture.live.client import stream_file
    from emogesture.motion import save_smplx_npz
    from emogesture.types import SMPLXSequence

    if args.out is not None:
        check_output(args.out, args.overwrite)
    try:
        result = asyncio.run(stream_file(args.url, args.speech, emotion=args.emotion, chunk_seconds=args.chunk,
                                         realtime=not args.fast, neutral_from=args.neutral_from, token=args.token))
    except OSError as e:
        from emogesture.access import without_token
        from emogesture.errors import EmogestureError

        raise EmogestureError(f"{without_token(args.url)}: cannot connect ({e.strerror or e})") from None
    for error in result.errors:
        print(f"server: {error}")
    if result.neutral_reference is not None:
        print(f"read against the neutral voice in {args.neutral_from} ({result.neutral_reference['seconds']:.1f} s, "
              f"{result.neutral_reference['windows']} windows)")
    lat = result.latency
    print(f"{len(result.poses)} frames; latency from audio sent to frame received: median {np.median(lat):.3f} s, "
          f"95th percentile {np.quantile(lat, 0.95):.3f} s, largest {lat.max():.3f} s")
    if args.out is not None:
        save_smplx_npz(SMPLXSequence(poses=result.poses, trans=result.trans), args.out, overwrite=args.overwrite)
        print(args.out)
    return 0
