"""The page of ``emogesture app`` (module docstring of :mod:`emogesture.app`)."""

from __future__ import annotations

import importlib.util
import json
import shutil
import tempfile
import threading
from collections.abc import Callable
from pathlib import Path

import soundfile as sf

from emogesture.access import check_served, url_host, with_token
from emogesture.assets import ASSETS
from emogesture.audio import TARGET_SAMPLE_RATE, audio_seconds
from emogesture.data.beat import EMOTIONS
from emogesture.errors import EmogestureError, InputFileError
from emogesture.export.fbx import blender_binary
from emogesture.pipeline.animate import AnimationRequest, animate
from emogesture.pipeline.generate import GesturePipeline

VIEWER_JS = (ASSETS / "web" / "mannequin.js").read_text() + "\n" + Path(__file__).with_name("viewer.js").read_text()
VIEWER_HTML = """<div class="emogesture-viewer">
<canvas style="width:100%;height:420px;display:block;border-radius:8px;cursor:grab"></canvas>
<audio controls preload="auto" style="width:100%;margin-top:6px"></audio>
<div class="status" style="font-size:0.9em;opacity:0.75">the animation appears here</div>
</div>"""
EMOTION_CHOICES = ["auto", "own", *EMOTIONS]
MAX_UPLOAD_MINUTES = 10.0  # the longest recording the page takes (each of speech, emotion, style, neutral)
MAX_UPLOAD_MB = 150.0  # the largest file it takes: ten minutes of 48-kHz stereo 16-bit WAV, and some
INTRO = """# emogesture
Speech to emotional 3D body gestures. Give a recording of someone speaking; get a 30 fps animation whose
gestures follow the speech and express an emotion: the speech's own (`auto`, `own`), one you choose, one taken
from a second recording, or a timeline such as `0:neutral,12:anger,30:sadness@0.5` (seconds)."""


def _file_url(path: Path) -> str:
    return f"/gradio_api/file={path}"


def _fbx_available() -> bool:
    try:
        blender_binary()
        return True
    except EmogestureError:
        return False


def _duration(seconds: float) -> str:
    """``seconds`` as a person reads a recording's length: "6.0 s", "12.5 min"."""
    return f"{seconds:.1f} s" if seconds < 60 else f"{seconds / 60:.1f} min"


def perception_rows(report: dict) -> list[list]:
    """The rows of the page's perception table from one recording's perception report."""
    rows = []
    for w in report["windows"]:
        probability = w["probabilities"][w["emotion"]]
        animated = ", ".join(f"{k} {v:.0%}" for k, v in w.get("animated_emotion", {}).items())
        trust = f"{w['trust']:.2f}" if "trust" in w else "-"
        rows.append([f"{w['start_s']:.0f}-{w['end_s']:.0f} s", w["emotion"], f"{probability:.2f}", trust, animated])
    return rows


class AppSession:
    """What the page's button runs: one pipeline for every request (one request at a time), each request
    written into a new folder of ``workdir``; recordings longer than ``max_minutes`` are refused."""

    def __init__(self, pipe: GesturePipeline, workdir: Path, max_minutes: float = MAX_UPLOAD_MINUTES) -> None:
        self.pipe, self.workdir = pipe, Path(workdir)
        self.max_minutes = max_minutes
        self.lock = threading.Lock()
        self.formats = ("npz", "bvh", "glb", "mp4") + (("fbx",) if _fbx_available() else ())

    def check_length(self, path: str, what: str) -> None:
        """Refuse the recording at ``path`` (the page's ``what``) when it is longer than the server takes; the
        message names the file by the name it was uploaded under."""
        name = Path(path).name
        try:
            seconds = audio_seconds(path)
        except InputFileError as e:
            raise EmogestureError(f"{name} ({what}): {e.problem}") from None
        if seconds > 60 * self.max_minutes:
            raise EmogestureError(f"{name} ({what}) is {_duration(seconds)} long; this server takes at most "
                                  f"{_duration(60 * self.max_minutes)} per recording")

    def run(self, speech: str | None, emotion: str, timeline: str, weight: float, emotion_from: str | None,
            style_from: str | None, seed: float, samples: float, skeleton: str,
            neutral_from: str | None = None, neutral_span: str | None = None, face: bool = False) -> tuple:
        """The page's inputs -> (video, 3D view value, perception rows, summary, files). A bad input raises
        :class:`EmogestureError` with the message the page shows."""
        if not speech:
            raise EmogestureError("upload or record some speech first")
        for path, what in ((speech, "speech"), (emotion_from, "emotion from"), (style_from, "style from"),
                           (neutral_from, "neutral voice")):
            if path:
                self.check_length(path, what)
        timeline = (timeline or "").strip()
        label_given = emotion not in ("auto", "own") or emotion_from
        request_emotion = timeline or emotion
        out = Path(tempfile.mkdtemp(prefix="request-", dir=self.workdir))
        request = AnimationRequest(
            Path(speech), out, emotion=request_emotion,
            emotion_weight=float(weight) if (label_given and not timeline and float(weight) < 1.0) else None,
            emotion_from=Path(emotion_from) if emotion_from and not timeline else None,
            style_from=Path(style_from) if style_from else None,
            neutral_from=Path(neutral_from) if neutral_from else None,
            neutral_span=(neutral_span or "").strip() or None, formats=self.formats, seed=int(seed),
            samples=int(samples), skeleton=skeleton, face=bool(face))
        if request.label is not None and emotion_from:
            raise EmogestureError("choose an emotion label or an emotion recording, not both")
        with self.lock:
            result = animate(self.pipe, request, progress=True)
        listen = out / "speech.wav"  # what the 3D view plays with the animation
        sf.write(listen, result.speech, TARGET_SAMPLE_RATE, subtype="PCM_16")
        first = result.files[0]
        video = next(p for p in first if p.suffix == ".mp4")
        glb = next(p for p in first if p.suffix == ".glb")
        report = json.loads(result.perception_path.read_text())[0]
        files = [str(p) for sample in result.files for p in sample] + [str(result.perception_path)]
        note = "" if "fbx" in self.formats else " (fbx needs Blender on the server)"
        ui = {"--neutral-from": "\"the same speaker without emotion\" (under \"from other recordings\")",
              "--neutral-span START-END": "its calm seconds (under \"from other recordings\")",
              "--emotion own": "the emotion \"own\""}
        blocks = []
        for line, more in zip(result.summaries, result.details):  # the summary, then the details behind it
            text = "\n".join([line] + [f"- {d}" for d in more])
            for flag, words in ui.items():
                text = text.replace(flag, words)
            for path in (request.speech, request.emotion_from, request.neutral_from):  # the server's paths
                if path is not None:
                    text = text.replace(str(path), path.name)
            blocks.append(text)
        return (str(video), {"glb": _file_url(glb), "audio": _file_url(listen)}, perception_rows(report),
                "\n\n".join(blocks) + note, files)


def build_app(session: AppSession):
    """The Gradio page (a ``gr.Blocks``) around ``session``."""
    import gradio as gr

    def run(*inputs, progress=gr.Progress(track_tqdm=True)):
        try:
            return session.run(*inputs)
        except EmogestureError as e:
            raise gr.Error(str(e), print_exception=False) from None

    with gr.Blocks(title="emogesture") as page:
        gr.Markdown(INTRO)
        with gr.Row():
            with gr.Column(scale=1):
                speech = gr.Audio(sources=["upload", "microphone"], type="filepath", label="speech", elem_id="speech")
                emotion = gr.Radio(EMOTION_CHOICES, value="auto", label="emotion")
                timeline = gr.Textbox(label="or an emotion timeline (TIME:LABEL[@WEIGHT], seconds)",
                                      placeholder="0:neutral,12:anger,30:sadness@0.5")
                weight = gr.Slider(0.0, 1.0, value=1.0, step=0.05, label="weight of the chosen emotion")
                with gr.Accordion("from other recordings, seed, samples, skeleton", open=False):
                    emotion_from = gr.Audio(sources=["upload"], type="filepath", label="emotion from this recording")
                    style_from = gr.Audio(sources=["upload"], type="filepath",
                                          label="speaker style from this recording")
                    neutral_from = gr.Audio(sources=["upload", "microphone"], type="filepath",
                                            label="the same speaker without emotion (read the emotion against it)")
                    neutral_span = gr.Textbox(label="its calm seconds (START-END), or without it the speech's own",
                                              placeholder="0-15", elem_id="neutral-span")
                    seed = gr.Number(value=0, precision=0, label="seed")
                    samples = gr.Slider(1, 4, value=1, step=1, label="samples")
                    skeleton = gr.Radio(["smplx", "mixamo"], value="smplx", label="skeleton of bvh, glb, fbx")
                face = gr.Checkbox(False, label="a face too (lips, expression, blinks: ARKit blendshapes in every file)",
                                   elem_id="face")
                button = gr.Button("Animate", variant="primary", elem_id="animate")
            with gr.Column(scale=2):
                # no badge: it would cover the first line of the label drawn in the video
                video = gr.Video(label="video", show_label=False, elem_id="video")
                viewer = gr.HTML(value={}, html_template=VIEWER_HTML, js_on_load=VIEWER_JS, elem_id="viewer",
                                 label="3D view")
                summary = gr.Markdown(elem_id="summary")
                table = gr.Dataframe(headers=["window", "heard", "probability", "trust", "animated"],
                                     label="emotion perceived in each window", elem_id="perception")
                files = gr.File(file_count="multiple", label="downloads", elem_id="downloads")
        button.click(run, [speech, emotion, timeline, weight, emotion_from, style_from, seed, samples, skeleton,
                           neutral_from, neutral_span, face],
                     [video, viewer, table, summary, files], concurrency_limit=1)
    return page


def page_app(session: AppSession, host: str = "127.0.0.1", port: int = 7860, token: str | None = None,
             max_upload_mb: float = MAX_UPLOAD_MB):
    """The page around ``session`` as an ASGI app (Gradio mounted on a FastAPI app) for ``host:port``: the files of
    the requests' folder servable, uploads of at most ``max_upload_mb`` MB and, with a ``token``, every request
    behind the gate that asks for it (:class:`~emogesture.app.gate.TokenGate`; the gate wraps the whole app,
    which Gradio's own ``launch`` would not let it do)."""
    import gradio as gr
    from fastapi import FastAPI
    from starlette.middleware import Middleware

    from emogesture.app.gate import TokenGate

    page = build_app(session)
    page.queue(default_concurrency_limit=1)
    gate = [Middleware(TokenGate, token=token, port=port)] if token is not None else []
    app = FastAPI(middleware=gate, docs_url=None, redoc_url=None, openapi_url=None)
    return gr.mount_gradio_app(app, page, "/", server_name=host, server_port=port, footer_links=[],
                               allowed_paths=[str(session.workdir)], show_error=True,
                               max_file_size=int(max_upload_mb * 1e6), ssr_mode=False)


def serve(pipe_factory: Callable[[], GesturePipeline], host: str = "127.0.0.1", port: int = 7860,
          workdir: str | Path | None = None, quiet: bool = False, *, token: str | None = None,
          max_upload_mb: float = MAX_UPLOAD_MB, max_upload_minutes: float = MAX_UPLOAD_MINUTES) -> None:
    """Build the page on the pipeline ``pipe_factory()`` and serve it on ``host:port`` until interrupted;
    requests write into ``workdir`` (default: a new temporary folder, removed when the server stops).
    ``token``: the one visitors must give as ``?token=...`` (:mod:`emogesture.access`; needed beyond loopback);
    uploads of more than ``max_upload_mb`` MB or ``max_upload_minutes`` minutes are refused. Unless ``quiet``,
    prints the page's URL."""
    if importlib.util.find_spec("gradio") is None:
        raise EmogestureError("emogesture app needs Gradio: pip install 'emogesture[app]' (or pip install gradio)")
    check_served(host, token)
    if not max_upload_mb > 0 or not max_upload_minutes > 0:
        raise EmogestureError(f"uploads of at most {max_upload_mb:g} MB and {max_upload_minutes:g} min: give more "
                              "than 0 (--max-upload-mb, --max-upload-minutes)")
    import uvicorn

    owned = workdir is None
    work = Path(tempfile.mkdtemp(prefix="emogesture-app-")) if owned else Path(workdir)
    work.mkdir(parents=True, exist_ok=True)
    try:
        app = page_app(AppSession(pipe_factory(), work, max_upload_minutes), host, port, token, max_upload_mb)
        if not quiet:
            print(f"emogesture app: {with_token(f'http://{url_host(host)}:{port}/', token)}", flush=True)
        try:
            uvicorn.run(app, host=host, port=port, log_level="warning")
        except SystemExit as e:  # uvicorn's way to say it could not bind (its message printed above)
            if e.code:
                raise EmogestureError(f"cannot listen on {host}:{port} (the address is taken or not this "
                                      "machine's)") from None
            raise
    finally:
        if owned:
            shutil.rmtree(work, ignore_errors=True)
