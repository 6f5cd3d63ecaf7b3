"""`emogesture live` with the bundled model: a file streamed over the WebSocket gives the frames the library's
stream gives, one per 1/30 s; the Mixamo skeleton as quaternions; bad clients get a one-line error and the
server and the other streams carry on. The server binds to 127.0.0.1, stops by itself after ten minutes,
and is ended by its process id."""

import asyncio
import json
import os
import signal
import socket
import subprocess
import sys
import time

import numpy as np
import pytest
import soundfile as sf

from emogesture.assets import DEMO_CLIPS

from helpers import canvas_pixels, ended, headless_chromium, require_chromium, wait_for_server

pytestmark = pytest.mark.training
websockets = pytest.importorskip("websockets")


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    work = tmp_path_factory.mktemp("live")
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    proc = subprocess.Popen(["timeout", "600", sys.executable, "-m", "emogesture.cli.main", "live", "--port",
                             str(port)], stdout=open(work / "server.log", "w"), stderr=subprocess.STDOUT, start_new_session=True)
    if not wait_for_server(port, lambda: proc.poll() is None, 120):
        os.killpg(proc.pid, signal.SIGTERM)
        pytest.fail(f"the live server did not start: {(work / 'server.log').read_text()[-2000:]}")
    wave, sr = sf.read(DEMO_CLIPS / "talk.flac", dtype="float32")
    clip = work / "clip.wav"
    sf.write(clip, wave[: int(7.3 * sr)], sr)
    yield f"ws://127.0.0.1:{port}/live", clip, proc
    os.killpg(proc.pid, signal.SIGTERM)
    proc.wait(timeout=30)


def test_a_file_streams_to_one_frame_per_thirtieth_of_a_second_with_smooth_joins(server):
    from emogesture.live.client import stream_file
    from emogesture.motion import SkeletonBody
    from emogesture.pipeline.generate import EditRequest, GesturePipeline
    import torch

    url, clip, proc = server
    result = asyncio.run(stream_file(url, clip, emotion="anger", realtime=False, chunk_seconds=0.07))
    assert result.errors == [] and len(result.poses) == round(7.3 * 30)
    with torch.no_grad():
        joints = SkeletonBody()(torch.from_numpy(result.poses), torch.from_numpy(result.trans)).numpy()
    offline = GesturePipeline.from_run().generate(sf.read(clip, dtype="float32")[0],  # the same emotion, offline
                                                  edit=EditRequest(emotion_label="anger"))[0]
    with torch.no_grad():
        reference = SkeletonBody()(torch.from_numpy(offline.poses), torch.from_numpy(offline.trans)).numpy()
    jump = lambda j: np.linalg.norm(np.diff(j, axis=0), axis=-1).max()  # noqa: E731
    print(f"\nlargest joint jump: streamed {jump(joints):.4f} m, offline {jump(reference):.4f} m")
    assert jump(joints) <= 1.5 * jump(reference)  # sent as fast as possible: the server catches up in big updates
    assert proc.poll() is None


def test_the_mixamo_skeleton_comes_as_quaternions(server):
    from websockets.sync.client import connect

    url, clip, _ = server
    pcm = (sf.read(clip, dtype="float32")[0][:16000] * 32767).astype("<i2").tobytes()
    with connect(url) as ws:
        ws.send(json.dumps({"sample_rate": 16000, "skeleton": "mixamo"}))
        hello = json.loads(ws.recv())
        assert hello["ready"] and len(hello["bones"]) == 52 and hello["bones"][0] == "mixamorig:Hips"
        ws.send(pcm)
        frames, reply = ended(ws)
    assert [f["frame"] for f in frames] == list(range(30)) and reply["total_frames"] == 30
    q = np.array([f["rotations"] for f in frames])
    assert q.shape == (30, 52, 4) and np.allclose(np.linalg.norm(q, axis=-1), 1, atol=1e-3)


def test_a_stream_with_a_face_gets_52_arkit_weights_per_frame(server):
    from websockets.sync.client import connect

    url, clip, proc = server
    wave = sf.read(clip, dtype="float32")[0][: 3 * 16000]
    with connect(url) as ws:
        ws.send(json.dumps({"sample_rate": 16000, "face": True, "emotion": "happiness"}))
        assert json.loads(ws.recv())["ready"]
        for piece in np.array_split(wave, 30):
            ws.send((piece * 32767).astype("<i2").tobytes())
        frames, _ = ended(ws)
    arkit = np.array([f["arkit"] for f in frames])
    poses = np.array([f["poses"] for f in frames])
    assert arkit.shape == (90, 52) and arkit.min() >= 0 and arkit.max() <= 1
    assert arkit[:, 23].mean() > 0.4  # mouthSmileLeft under happiness
    assert arkit[:, 17].std() > 0.02 and np.allclose(poses[:, 22, 0], 0.45 * arkit[:, 17], atol=1e-3)  # the jaw
    with connect(url) as ws:
        ws.send(json.dumps({"sample_rate": 16000, "face": "yes"}))
        assert "face" in json.loads(ws.recv())["error"]
    assert proc.poll() is None


def test_a_stream_in_a_training_speakers_style(server):
    from websockets.sync.client import connect

    url, clip, _ = server
    pcm = (sf.read(clip, dtype="float32")[0][:16000] * 32767).astype("<i2").tobytes()
    with connect(url) as ws:
        ws.send(json.dumps({"sample_rate": 16000}))
        speakers = json.loads(ws.recv())["speakers"]
    assert len(speakers) >= 8
    poses = {}
    for style in speakers[:2]:
        with connect(url) as ws:
            ws.send(json.dumps({"sample_rate": 16000, "style_from": style}))
            assert json.loads(ws.recv())["ready"]
            ws.send(pcm)
            ws.send(json.dumps({"end": True}))
            frames = []
            while not (reply := json.loads(ws.recv())).get("done"):
                frames += reply.get("frames", [])
        poses[style] = np.array([f["poses"] for f in frames])
    assert np.abs(poses[speakers[0]] - poses[speakers[1]]).mean() > 0.005  # the style changes the motion
    with connect(url) as ws:
        ws.send(json.dumps({"sample_rate": 16000, "style_from": 999}))
        assert "style_from 999: one of the model's speakers" in json.loads(ws.recv())["error"]


def test_a_stream_read_against_the_speakers_neutral_voice(server):
    from websockets.sync.client import connect

    url, clip, proc = server
    wave = sf.read(DEMO_CLIPS / "talk.flac", dtype="float32")[0]  # 20.5 s

    def pcm(start: float, end: float) -> bytes:
        return (wave[int(start * 16000):int(end * 16000)] * 32767).astype("<i2").tobytes()

    def stream(neutral: bool):
        replies, reference = [], None
        with connect(url) as ws:
            ws.send(json.dumps({"sample_rate": 16000}))
            ws.recv()
            if neutral:
                ws.send(json.dumps({"neutral": "start"}))
            ws.send(pcm(0.0, 10.5))
            if neutral:  # the rest is sent once the server has the reference
                ws.send(json.dumps({"neutral": "stop"}))
                while "neutral_reference" not in (reply := json.loads(ws.recv())):
                    replies.append(reply)
                reference = reply["neutral_reference"]
            ws.send(pcm(10.5, 20.5))
            ws.send(json.dumps({"end": True}))
            while not (reply := json.loads(ws.recv())).get("done"):
                replies.append(reply)
        assert not [r for r in replies if "error" in r]
        return np.array([f["poses"] for r in replies for f in r.get("frames", [])]), reference

    plain, _ = stream(False)
    against, reference = stream(True)
    assert reference["seconds"] == pytest.approx(10.5) and reference["windows"] >= 1
    assert plain.shape == (614, 55, 3), plain.shape
    assert against.shape == (614, 55, 3), against.shape  # what the reference changes: test_neutral_reference.py

    with connect(url) as ws:  # a stop without a start, a recording too short, a bad value, a clear
        ws.send(json.dumps({"sample_rate": 16000}))
        ws.recv()
        errors = []
        ws.send(json.dumps({"neutral": "stop"}))
        ws.send(pcm(0.0, 1.0)[:1])  # half a sample before the start: the recording keeps whole samples
        ws.send(json.dumps({"neutral": "start"}))
        ws.send(pcm(0.0, 1.0)[1:])
        ws.send(json.dumps({"neutral": "stop"}))
        ws.send(json.dumps({"neutral": "later"}))
        ws.send(json.dumps({"neutral": "clear"}))
        ws.send(json.dumps({"end": True}))
        cleared = False
        while not (reply := json.loads(ws.recv())).get("done"):
            errors += [reply["error"]] if "error" in reply else []
            cleared |= "neutral_reference" in reply and reply["neutral_reference"] is None
    assert len(errors) == 3 and cleared and all("\n" not in e for e in errors)
    assert "no neutral recording" in errors[0]  # at once
    # the bad value is answered at once, the short recording once it is heard (which may come first on a busy machine)
    assert any("start, stop or clear" in e for e in errors[1:])
    assert any("the neutral recording: audio is too short: 1.00 s, at least 10 s" in e for e in errors[1:])
    assert proc.poll() is None


def test_the_client_sends_a_neutral_recording_first_and_keeps_only_the_speechs_frames(server, tmp_path):
    from emogesture.errors import InputFileError
    from emogesture.live.client import stream_file

    url, clip, proc = server
    wave, sr = sf.read(DEMO_CLIPS / "talk.flac", dtype="float32")
    calm = tmp_path / "calm.wav"
    sf.write(calm, wave[int(8 * sr):int(18.5 * sr)], sr)  # 10.5 s of the same speaker
    alone = asyncio.run(stream_file(url, clip, emotion="own", realtime=False, seed=3))
    against = asyncio.run(stream_file(url, clip, emotion="own", realtime=False, seed=3, neutral_from=calm))
    assert not alone.errors + against.errors
    assert len(against.poses) == len(alone.poses) == round(7.3 * 30)
    assert alone.neutral_reference is None and against.neutral_reference["seconds"] == pytest.approx(10.5)
    assert np.isfinite(against.latency).all() and against.latency.min() > 0
    assert np.abs(against.poses - alone.poses).mean() > 1e-4  # another motion: not the lead's frames, not alone
    short = tmp_path / "short.wav"
    sf.write(short, wave[: 3 * sr], sr)
    with pytest.raises(InputFileError, match="short.wav.*too short"):  # said before connecting
        asyncio.run(stream_file(url, clip, neutral_from=short))
    assert proc.poll() is None


def test_bad_clients_get_one_line_errors_and_the_server_carries_on(server):
    from websockets.exceptions import ConnectionClosed
    from websockets.sync.client import connect

    url, clip, proc = server
    for first, needle in (({"sample_rate": 3}, "sample_rate 3"), ("hello", "not JSON"),
                          ({"sample_rate": 16000, "colour": "red"}, "unknown key"),
                          ({"sample_rate": 16000, "emotion": "rage"}, "unknown")):
        with connect(url) as ws:
            ws.send(first if isinstance(first, str) else json.dumps(first))
            reply = json.loads(ws.recv())
            assert needle in reply["error"] and "\n" not in reply["error"]
            with pytest.raises(ConnectionClosed):
                ws.recv()
    pcm = (sf.read(clip, dtype="float32")[0] * 32767).astype("<i2").tobytes()
    with connect(url) as ws:  # a client that drops mid-stream
        ws.send(json.dumps({"sample_rate": 16000}))
        ws.recv()
        ws.send(pcm[:32000])
    with connect(url) as ws:  # text where audio is expected, a bad emotion change, an odd byte count
        ws.send(json.dumps({"sample_rate": 16000}))
        ws.recv()
        errors = []
        ws.send("not json")
        ws.send(json.dumps({"emotion": "rage"}))
        ws.send(pcm[:16001])
        ws.send(pcm[16001:32000])
        ws.send(json.dumps({"emotion": "sadness", "emotion_weight": 0.5}))
        ws.send(json.dumps({"end": True}))
        frames = 0
        while True:
            reply = json.loads(ws.recv())
            errors += [reply["error"]] if "error" in reply else []
            frames += len(reply.get("frames", []))
            if reply.get("done"):
                break
    assert len(errors) == 2 and "not JSON" in errors[0] and "unknown" in errors[1] and frames == 30
    assert proc.poll() is None


def page_with_microphone(tmp_path):
    """Headless chromium whose fake microphone plays the demo's speech."""
    require_chromium()
    wave, sr = sf.read(DEMO_CLIPS / "talk.flac", dtype="float32")
    microphone = tmp_path / "microphone.wav"
    sf.write(microphone, wave, sr, subtype="PCM_16")
    return headless_chromium("--use-fake-ui-for-media-stream", "--use-fake-device-for-media-stream",
                             f"--use-file-for-fake-audio-capture={microphone}", size="1100,1000")


def test_the_page_streams_a_fake_microphone_and_the_mannequin_moves(server, tmp_path):
    """Headless chromium with a fake microphone fed from a WAV file opens the page, streams, and the
    mannequin's canvas changes while frames arrive; the measured latency is on the page."""
    from selenium.webdriver.support.ui import WebDriverWait

    url, clip, proc = server
    driver = page_with_microphone(tmp_path)

    def canvas():
        return canvas_pixels(driver, "#view")

    try:
        driver.get(url.replace("ws://", "http://").removesuffix("/live") + "/")
        WebDriverWait(driver, 60).until(lambda d: d.execute_script("return window.emogestureLive !== undefined"))
        driver.find_element("id", "emotion-anger").click()
        driver.find_element("id", "mic").click()
        WebDriverWait(driver, 60).until(lambda d: d.execute_script("return window.emogestureLive.frames") > 30)
        first = canvas()
        time.sleep(1.5)
        second = canvas()
        frames = driver.execute_script("return window.emogestureLive.frames")
        assert frames > 60 and np.abs(second - first).sum(-1).max() > 30  # frames arrive, the mannequin moves
        drawn = (np.abs(second - second[2, 2]).sum(-1) > 30).mean()
        assert 0.01 < drawn < 0.6
        latency = float(driver.find_element("id", "latency").text)
        assert 0.0 < latency < 5.0
        driver.find_element("id", "neutral").click()  # ten seconds of the speaker's neutral voice
        time.sleep(10.5)
        driver.find_element("id", "neutral").click()
        WebDriverWait(driver, 60).until(lambda d: "against your neutral voice" in d.find_element(
            "id", "neutral-status").text)
        driver.save_screenshot(str(tmp_path / "live.png"))
    finally:
        driver.quit()
    assert proc.poll() is None


def test_streams_at_once_each_get_their_own_frames(server):
    from emogesture.live.client import stream_file

    url, clip, proc = server

    async def both():
        return await asyncio.gather(stream_file(url, clip, emotion="anger", realtime=False, seed=1),
                                    stream_file(url, clip, emotion="sadness", realtime=False, seed=2))

    anger, sadness = asyncio.run(both())
    assert len(anger.poses) == len(sadness.poses) == round(7.3 * 30) and not anger.errors + sadness.errors
    assert np.abs(anger.poses - sadness.poses).mean() > 0.01  # each stream its own emotion and seed
    assert proc.poll() is None


def test_the_page_shows_the_face_a_stream_sends(server, tmp_path):
    """With "a face too" ticked, the page asks for the face, puts each frame's 52 weights on the mannequin's
    face and draws it: the canvas changes where the face is hidden again."""
    from selenium.webdriver.support.ui import WebDriverWait

    url, clip, proc = server
    driver = page_with_microphone(tmp_path)
    try:
        driver.get(url.replace("ws://", "http://").removesuffix("/live") + "/")
        WebDriverWait(driver, 60).until(lambda d: d.execute_script(
            "return window.emogestureLive !== undefined && window.emogestureLive.clip !== undefined"))
        assert driver.execute_script("return window.emogestureLive.clip.face.shown") is False
        driver.find_element("id", "face").click()
        driver.find_element("id", "mic").click()
        WebDriverWait(driver, 60).until(lambda d: d.execute_script("return window.emogestureLive.frames") > 30)
        face = driver.execute_script("const f = window.emogestureLive.clip.face; "
                                     "return {shown: f.shown, weights: Array.from(f.track)};")
        assert face["shown"] is True and len(face["weights"]) == 52 and max(face["weights"]) > 0.05
        driver.find_element("id", "stop").click()
        time.sleep(0.5)
        shown = canvas_pixels(driver, "#view")
        driver.save_screenshot(str(tmp_path / "face.png"))
        driver.execute_script("window.emogestureLive.clip.face.shown = false;")
        time.sleep(0.5)
        hidden = canvas_pixels(driver, "#view")
        assert (np.abs(shown - hidden).sum(-1) > 30).sum() > 20  # the face's pixels
        driver.save_screenshot(str(tmp_path / "face_hidden.png"))
    finally:
        driver.quit()
    assert proc.poll() is None
