"""`emogesture live` and `emogesture app` safe for strangers: a stream beyond the capacity is told the server is
busy (close 1013) while the running one goes on; another site's page cannot open a stream; a token is needed
beyond loopback (and wherever one is given) for the page, /health and the stream; /health tells the load; a
silent stream, a stream too long and a message too big are closed with their one-line error; the app's token
gate and its length limit; both pages in a browser with their token. The servers run in this process (the live
one on small untrained models) on 127.0.0.1, each in a thread of its own, stopped on leaving the test (a live
server by itself after ten minutes too)."""

import asyncio
import contextlib
import json
import os
import socket
import threading
import time
import urllib.error
import urllib.request

import numpy as np
import pytest
import soundfile as sf

from emogesture.access import TokenCheck, needs_token, same_origin, server_token, with_token, without_token
from emogesture.errors import EmogestureError

from helpers import ended, headless_chromium, require_chromium, speech_like, wait_for_server, write_tiny_runs

websockets = pytest.importorskip("websockets")

TOKEN = "s3cret-word"


@pytest.fixture(scope="module")
def pipe(tmp_path_factory):
    from emogesture.pipeline.generate import GesturePipeline

    return GesturePipeline.from_run(write_tiny_runs(tmp_path_factory.mktemp("runs")))


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextlib.contextmanager
def live_server(pipe, **options):
    """``serve_live`` on 127.0.0.1 in a thread with its own event loop until the block is left (ten minutes at
    most); yields its port once it answers."""
    from emogesture.live.server import serve_live

    port = free_port()
    loop = asyncio.new_event_loop()
    task = loop.create_task(asyncio.wait_for(serve_live(pipe, "127.0.0.1", port, workers=1, **options), 600))

    def run() -> None:
        with contextlib.suppress(asyncio.CancelledError, TimeoutError):
            loop.run_until_complete(task)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    assert wait_for_server(port, thread.is_alive, 30, interval=0.05), "the live server did not start"
    try:
        yield port
    finally:
        loop.call_soon_threadsafe(task.cancel)
        thread.join(30)
        loop.close()


def get(port: int, path: str, cookie: str | None = None):
    """``GET path``: (status, headers, body); an HTTP error's status too."""
    request = urllib.request.Request(f"http://127.0.0.1:{port}{path}", headers={"Cookie": cookie} if cookie else {})
    try:
        with urllib.request.urlopen(request, timeout=10) as response:
            return response.status, response.headers, response.read()
    except urllib.error.HTTPError as e:
        return e.code, e.headers, e.read()


def health(port: int, query: str = "") -> dict:
    status, _, body = get(port, f"/health{query}")
    assert status == 200
    return json.loads(body)


def pcm(seconds: float) -> bytes:
    return (speech_like(seconds) * 32767).astype("<i2").tobytes()


def opened(ws) -> dict:
    """Start the stream on ``ws`` (neutral emotion: nothing to perceive) and return the server's ready message."""
    ws.send(json.dumps({"sample_rate": 16000, "emotion": "neutral"}))
    return json.loads(ws.recv())


def closed_with(ws) -> tuple[str, int]:
    """The one-line error the server sends before it closes, and the close code."""
    from websockets.exceptions import ConnectionClosedError

    error = json.loads(ws.recv())["error"]
    with pytest.raises(ConnectionClosedError) as closed:
        ws.recv()
    assert "\n" not in error
    return error, closed.value.rcvd.code


def test_a_stream_beyond_capacity_is_told_the_server_is_busy_and_the_running_one_finishes(pipe, tmp_path):
    from websockets.sync.client import connect

    from emogesture.live.client import stream_file
    from emogesture.live.server import LiveLimits

    clip = tmp_path / "clip.wav"
    sf.write(clip, speech_like(1.0), 16000)
    with live_server(pipe, limits=LiveLimits(max_streams=1)) as port:
        url = f"ws://127.0.0.1:{port}/live"
        with connect(url) as first:
            hello = opened(first)
            assert hello["ready"] and hello["capacity"] == 1
            assert health(port) == {"streams": 1, "capacity": 1}
            with connect(url) as second:
                error, code = closed_with(second)
            assert error.startswith("server busy: 1 stream") and code == 1013
            with pytest.raises(EmogestureError, match="server busy"):  # the Python client says so
                asyncio.run(stream_file(url, clip, realtime=False))
            first.send(pcm(1.0))
            frames, done = ended(first)
        assert [f["frame"] for f in frames] == list(range(30)) and done["total_frames"] == 30
        deadline = time.time() + 10
        while health(port)["streams"] and time.time() < deadline:
            time.sleep(0.05)
        with connect(url) as third:  # room again
            assert opened(third)["ready"]


def test_health_tells_the_streams_open_and_the_capacity(pipe):
    from websockets.sync.client import connect

    from emogesture.live.server import LiveLimits

    with live_server(pipe, limits=LiveLimits(max_streams=3)) as port:
        assert health(port) == {"streams": 0, "capacity": 3}
        with connect(f"ws://127.0.0.1:{port}/live") as ws:
            assert opened(ws)["ready"]
            assert health(port) == {"streams": 1, "capacity": 3}


def test_a_page_of_another_site_cannot_open_a_stream(pipe):
    from websockets.exceptions import InvalidStatus
    from websockets.sync.client import connect

    with live_server(pipe) as port:
        url = f"ws://127.0.0.1:{port}/live"
        for origin in ("http://elsewhere.example", f"http://127.0.0.1:{port + 1}", "null"):
            with pytest.raises(InvalidStatus) as refused:
                connect(url, origin=origin)
            assert refused.value.response.status_code == 403
        for origin in (f"http://127.0.0.1:{port}", None):  # the server's own page; a client that is no browser
            with connect(url, origin=origin) as ws:
                assert opened(ws)["ready"]


def test_the_origin_rule():
    assert same_origin(None, "127.0.0.1:8765")
    assert same_origin("http://127.0.0.1:8765", "127.0.0.1:8765")
    assert same_origin("http://example.com", "example.com:80") and same_origin("https://example.com", "example.com")
    assert not same_origin("http://elsewhere.example", "127.0.0.1:8765")
    assert not same_origin("http://127.0.0.1:8766", "127.0.0.1:8765")
    assert not same_origin("https://example.com", "example.com:80")  # the scheme says the port left out
    assert not same_origin("null", "127.0.0.1:8765") and not same_origin("http://localhost:8765", "127.0.0.1:8765")


def test_a_token_is_needed_beyond_loopback_and_wherever_one_is_given():
    for host in ("127.0.0.1", "::1", "[::1]", "localhost", "127.0.0.2"):
        assert not needs_token(host, None) and server_token(host, None) is None
        assert needs_token(host, "x") and server_token(host, "x") == "x"
    for host in ("0.0.0.0", "", "::", "192.168.1.20", "gpu-box.example"):
        assert needs_token(host, None)
        made = server_token(host, None)
        assert len(made) >= 40 and made != server_token(host, None)  # made at start, each time anew
    with pytest.raises(EmogestureError, match="empty token"):
        server_token("0.0.0.0", " ")
    url = with_token("ws://gpu-box:8765/live", TOKEN)
    assert url == f"ws://gpu-box:8765/live?token={TOKEN}" and TOKEN not in without_token(url)
    check = TokenCheck(TOKEN, 8765)
    assert check.allows(f"token={TOKEN}", None) and not check.allows("token=wrong", None)
    assert not check.allows("", None) and not check.allows("", f"{check.cookie}={TOKEN}")  # the cookie is no token
    cookie = check.set_cookie(f"token={TOKEN}").split(";")[0]
    assert check.allows("", cookie) and TOKEN not in cookie and check.set_cookie("token=wrong") is None
    assert TokenCheck(None, 8765).allows("", None)


def test_a_library_server_beyond_loopback_refuses_to_start_without_a_token(pipe):
    from emogesture.live.server import serve_live

    with pytest.raises(EmogestureError, match="give a token"):
        asyncio.run(serve_live(pipe, "0.0.0.0", free_port()))


def test_with_a_token_the_page_health_and_stream_need_it(pipe, tmp_path):
    from websockets.exceptions import InvalidStatus
    from websockets.sync.client import connect

    from emogesture.live.client import stream_file
    from emogesture.live.server import default_max_streams

    with live_server(pipe, token=TOKEN) as port:
        for path in ("/", "/?token=wrong", "/health", "/health?token=wrong", "/mannequin.js"):
            status, _, body = get(port, path)
            assert status == 403 and b"token" in body, path
        status, headers, body = get(port, f"/?token={TOKEN}")
        assert status == 200 and b"emogesture live" in body
        cookie = headers["Set-Cookie"].split(";")[0]
        assert get(port, "/mannequin.js", cookie)[0] == 200  # the page's own requests pass with its cookie
        assert health(port, f"?token={TOKEN}") == {"streams": 0, "capacity": default_max_streams()}
        for query in ("", "?token=wrong"):
            with pytest.raises(InvalidStatus) as refused:
                connect(f"ws://127.0.0.1:{port}/live{query}")
            assert refused.value.response.status_code == 403
        with connect(f"ws://127.0.0.1:{port}/live?token={TOKEN}") as ws:
            assert opened(ws)["ready"]
        clip = tmp_path / "clip.wav"
        sf.write(clip, speech_like(1.0), 16000)
        with pytest.raises(EmogestureError, match="HTTP 403 .a wrong or missing token") as refused:
            asyncio.run(stream_file(f"ws://127.0.0.1:{port}/live", clip, token="wrong"))
        assert "wrong" not in str(refused.value).split("403")[0]  # the token is not repeated in the message


def test_a_silent_stream_is_closed_with_its_one_line_error(pipe):
    from websockets.sync.client import connect

    from emogesture.live.server import LiveLimits

    with live_server(pipe, limits=LiveLimits(idle_timeout=0.3)) as port:
        url = f"ws://127.0.0.1:{port}/live"
        with connect(url) as ws:
            assert opened(ws)["ready"]
            error, code = closed_with(ws)
        assert error.startswith("no message for 0.3 s") and code == 1008
        with connect(url) as ws:  # not even a first message
            error, code = closed_with(ws)
        assert error.startswith("no message for 0.3 s") and code == 1008


def test_a_stream_too_long_and_a_message_too_big_are_closed_with_their_one_line_error(pipe):
    from websockets.sync.client import connect

    from emogesture.live.server import LiveLimits

    with live_server(pipe, limits=LiveLimits(max_stream_minutes=0.5 / 60, max_message_bytes=64 * 1024)) as port:
        url = f"ws://127.0.0.1:{port}/live"
        with connect(url) as ws:
            assert opened(ws)["limits"] == {"message_bytes": 65536, "stream_minutes": 0.5 / 60,
                                                     "idle_s": 60.0}
            ws.send(pcm(1.0))  # 32000 bytes: within a message, beyond the stream's 0.5 s
            error, code = closed_with(ws)
        assert error.startswith("stream too long: more than 0.00833333 min") and code == 1008
        with connect(url, max_size=None) as ws:
            assert opened(ws)["ready"]
            ws.send(b"\0" * 70000)
            error, code = closed_with(ws)
        assert error.startswith("message too big: more than 65536 bytes (0.0625 MiB)") and code == 1009


def test_the_command_line_checks_the_limits_and_the_token_before_loading_a_model(capsys):
    from helpers import cli_here

    ran = cli_here(capsys, "live", "--max-streams", "0")
    assert ran.returncode != 0 and "--max-streams" in ran.stderr
    ran = cli_here(capsys, "live", "--idle-timeout", "-1")
    assert ran.returncode != 0 and "--idle-timeout" in ran.stderr
    ran = cli_here(capsys, "live", "--host", "0.0.0.0", "--token", "")
    assert ran.returncode != 0 and "empty token" in ran.stderr


def test_the_app_gate_lets_in_the_token_and_its_cookie_only():
    pytest.importorskip("starlette")
    from starlette.applications import Starlette
    from starlette.middleware import Middleware
    from starlette.responses import PlainTextResponse
    from starlette.routing import Route
    from starlette.testclient import TestClient

    from emogesture.app.gate import TokenGate

    page = Starlette(routes=[Route("/", lambda r: PlainTextResponse("page")),
                             Route("/config", lambda r: PlainTextResponse("config"))],
                     middleware=[Middleware(TokenGate, token=TOKEN, port=7860)])
    stranger, visitor = TestClient(page), TestClient(page)
    for path in ("/", "/?token=wrong", "/config"):
        assert stranger.get(path).status_code == 403
    opened_page = visitor.get(f"/?token={TOKEN}")
    assert opened_page.status_code == 200 and opened_page.text == "page"
    assert visitor.get("/config").status_code == 200  # the page's own requests: by the cookie
    assert stranger.get("/config").status_code == 403


def test_the_app_with_a_token_in_gradio(tmp_path):
    """The gate around Gradio's whole app: the page needs the token, then its requests pass by the cookie;
    the upload limit is Gradio's."""
    pytest.importorskip("gradio")
    from starlette.testclient import TestClient

    from emogesture.app.page import AppSession, page_app

    app = page_app(AppSession(None, tmp_path), token=TOKEN, max_upload_mb=20)
    with TestClient(app) as visitor, TestClient(app) as stranger:
        for path in ("/", "/?token=wrong", "/config", "/gradio_api/info"):
            assert stranger.get(path).status_code == 403, path
        page = visitor.get(f"/?token={TOKEN}")
        assert page.status_code == 200 and "<html" in page.text.lower()
        config = visitor.get("/config")
        assert config.status_code == 200 and config.json()["max_file_size"] == 20_000_000
    with TestClient(page_app(AppSession(None, tmp_path))) as anyone:  # no token: as before
        assert anyone.get("/").status_code == 200


def test_the_app_refuses_a_recording_longer_than_it_takes_naming_it(tmp_path):
    from emogesture.app.page import AppSession

    speech, short = tmp_path / "talk.wav", tmp_path / "calm.wav"
    sf.write(speech, speech_like(6.0), 16000)
    sf.write(short, speech_like(2.0), 16000)
    session = AppSession(None, tmp_path, max_minutes=0.05)  # 3 s
    with pytest.raises(EmogestureError, match=r"^talk.wav \(speech\) is 6.0 s long; this server takes at most 3.0 s"):
        session.run(str(speech), "auto", "", 1.0, None, None, 0, 1, "smplx")
    with pytest.raises(EmogestureError, match=r"^talk.wav \(emotion from\) is 6.0 s long"):
        session.run(str(short), "auto", "", 1.0, str(speech), None, 0, 1, "smplx")


def test_the_page_passes_its_token_on_and_streams(pipe, tmp_path):
    """Headless chromium with a fake microphone opens the page of a server that needs a token, with the token
    in its URL: the page's script and mannequin load (by the cookie), its stream opens (by the token it passes
    on) and frames arrive. Without the token the page is refused."""
    from selenium.webdriver.support.ui import WebDriverWait

    require_chromium()
    microphone = tmp_path / "microphone.wav"
    sf.write(microphone, speech_like(20.0), 16000, subtype="PCM_16")
    driver = headless_chromium("--use-fake-ui-for-media-stream", "--use-fake-device-for-media-stream",
                               f"--use-file-for-fake-audio-capture={microphone}", size="1100,1000")
    try:
        with live_server(pipe, token=TOKEN) as port:
            driver.get(f"http://127.0.0.1:{port}/")
            assert "403" in driver.page_source and "emogestureLive" not in driver.page_source
            driver.get(f"http://127.0.0.1:{port}/?token={TOKEN}")
            WebDriverWait(driver, 60).until(lambda d: d.execute_script("return window.emogestureLive !== undefined"))
            driver.find_element("id", "emotion-neutral").click()
            driver.find_element("id", "mic").click()
            WebDriverWait(driver, 120).until(lambda d: d.execute_script("return window.emogestureLive.frames") > 30)
            assert driver.execute_script("return window.emogestureLive.socket.url").endswith(f"/live?token={TOKEN}")
    finally:
        driver.quit()


def test_the_app_page_with_its_token_works_in_a_browser(tmp_path):
    """Headless chromium opens the app's page with the token: Gradio's page loads by the cookie the first
    answer set, and a request goes through its queue and back (no speech: its message)."""
    pytest.importorskip("gradio")
    import uvicorn
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import WebDriverWait

    from emogesture.app.page import AppSession, page_app

    require_chromium()
    port = free_port()
    server = uvicorn.Server(uvicorn.Config(page_app(AppSession(None, tmp_path), port=port, token=TOKEN),
                                           host="127.0.0.1", port=port, log_level="warning"))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    driver = headless_chromium()
    try:
        deadline = time.time() + 60
        while not server.started:
            assert thread.is_alive() and time.time() < deadline, "the app did not start"
            time.sleep(0.1)
        driver.get(f"http://127.0.0.1:{port}/")
        assert "403" in driver.page_source and "animate" not in driver.page_source.lower()
        driver.get(f"http://127.0.0.1:{port}/?token={TOKEN}")
        WebDriverWait(driver, 60).until(lambda d: d.find_elements(By.ID, "animate"))
        driver.find_element(By.ID, "animate").click()
        WebDriverWait(driver, 60).until(lambda d: "upload or record some speech first" in d.page_source)
    finally:
        driver.quit()
        server.should_exit = True
        thread.join(30)


def test_a_pass_of_more_than_two_streams_is_drawn_as_a_loaded_one(monkeypatch):
    """The batcher hands a pass of many streams to push_together as a loaded one (one candidate, fewer steps),
    and so every pass, however small, of a server with more than two streams open."""
    from emogesture.live import server as live_server

    seen = []

    def fake(jobs, catch_up=False, loaded=False):
        seen.append((len(jobs), catch_up, loaded))
        return [[] for _ in jobs]

    monkeypatch.setattr(live_server, "push_together", fake)
    batcher = live_server.UpdateBatcher(1)

    async def drain(n):
        loop = asyncio.get_running_loop()
        futures = [loop.create_future() for _ in range(n)]
        batcher.queue = [(object(), np.zeros(10, np.float32), 16000, f) for f in futures]
        await loop.run_in_executor(None, batcher._drain, loop)
        return await asyncio.gather(*futures)

    for n in (1, live_server.LOADED_PASS, live_server.LOADED_PASS + 1, 12):
        assert asyncio.run(drain(n)) == [[]] * n
    assert seen == [(1, True, False), (2, True, False), (3, True, True), (12, True, True)]

    open_streams = [live_server.LOADED_PASS]
    batcher = live_server.UpdateBatcher(1, lambda: open_streams[0])
    seen.clear()
    assert asyncio.run(drain(1)) == [[]]
    open_streams[0] = live_server.LOADED_PASS + 1
    assert asyncio.run(drain(1)) == [[]]
    assert seen == [(1, True, False), (1, True, True)]


def test_the_update_threads_share_the_cores_among_them(monkeypatch):
    """Each update thread's passes get torch threads of their own share of the cores: two passes spreading over
    the same two cores fight for them."""
    from emogesture.live.server import threads_per_worker

    for cores, workers, threads in ((2, 2, 1), (2, 1, 2), (16, 4, 4), (2, 4, 1), (None, 2, 1)):
        monkeypatch.setattr(os, "cpu_count", lambda n=cores: n)
        assert threads_per_worker(workers) == threads
