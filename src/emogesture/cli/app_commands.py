"""``emogesture app``: the web page (Gradio), on this machine only unless told otherwise."""

from __future__ import annotations

import argparse
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("app", help="a web page to animate speech (Gradio; on 127.0.0.1 unless --host)",
                       description="Serve a web page to upload or record speech, choose its emotion and style, and "
                       "get the video, a 3D view and the files. Needs Gradio (pip install 'emogesture[app]').")
    p.add_argument("--host", default="127.0.0.1",
                   help="address to listen on (default 127.0.0.1: this machine only; 0.0.0.0 for the network)")
    p.add_argument("--port", type=int, default=7860, help="port (default 7860)")
    p.add_argument("--model", type=Path, help="run folder of `emogesture train gesture` (default: the bundled model)")
    p.add_argument("--speech-model", type=Path, help="speech model run (default: the one the model names)")
    p.add_argument("--device", default="auto", help="auto (a CUDA GPU when visible, else cpu), cpu, cuda or cuda:N")
    p.add_argument("--precision", default="auto", choices=["auto", "fp32", "bf16"], help="as for generate")
    p.add_argument("--workdir", type=Path, help="folder for the requests' files (default: a temporary folder, "
                   "removed when the server stops)")
    p.add_argument("--token", metavar="SECRET",
                   help="the token visitors must give as ?token=SECRET (needed beyond 127.0.0.1: without it one is "
                   "made and printed with the page's URL; given on 127.0.0.1, enforced there too)")
    p.add_argument("--max-upload-minutes", type=float, metavar="MIN", default=None,
                   help="the longest recording the page takes, in minutes (default 10)")
    p.add_argument("--max-upload-mb", type=float, metavar="MB", default=None,
                   help="the largest file the page takes, in MB (default 150)")
    p.add_argument("--quiet", action="store_true", help="no start-up message (but a token made at start is printed)")
    p.set_defaults(func=run_app)


def run_app(args: argparse.Namespace) -> int:
    from emogesture.access import server_token, url_host, with_token
    from emogesture.app import serve
    from emogesture.pipeline.generate import GesturePipeline
    from emogesture.runtime import resolve_device

    token = server_token(args.host, args.token)
    if args.quiet and token is not None and args.token is None:  # a token made here is no use unsaid
        print(f"emogesture app: {with_token(f'http://{url_host(args.host)}:{args.port}/', token)}", flush=True)
    device = resolve_device(args.device)
    limits = {"max_upload_mb": args.max_upload_mb, "max_upload_minutes": args.max_upload_minutes}
    serve(lambda: GesturePipeline.from_run(args.model, args.speech_model, device=device, precision=args.precision),
          host=args.host, port=args.port, workdir=args.workdir, quiet=args.quiet, token=token,
          **{k: v for k, v in limits.items() if v is not None})
    return 0
