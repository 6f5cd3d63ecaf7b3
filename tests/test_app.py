"""`emogesture app` in a real browser (headless Debian chromium driven by selenium): upload a clip, choose anger,
animate; the video plays for the clip's duration, the 3D view draws the mannequin and moves with the speech, the
downloads arrive; a request without speech is a message in the page and the server goes on; two browsers at
once get their own results. The server binds to 127.0.0.1, stops by itself after ten minutes, and is ended by
its process id."""

import os
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from emogesture.app.page import perception_rows
from emogesture.assets import DEMO_CLIPS

from helpers import canvas_pixels, headless_chromium, require_chromium

pytestmark = pytest.mark.training


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    require_chromium()
    pytest.importorskip("selenium")
    work = tmp_path_factory.mktemp("app")
    port = _free_port()
    proc = subprocess.Popen(["timeout", "600", sys.executable, "-m", "emogesture.cli.main", "app", "--host",
                             "127.0.0.1", "--port", str(port), "--workdir", str(work / "requests"), "--quiet"],
                            stdout=open(work / "server.log", "w"), stderr=subprocess.STDOUT, start_new_session=True)
    url = f"http://127.0.0.1:{port}/"
    deadline = time.time() + 180
    while True:
        try:
            urllib.request.urlopen(url, timeout=5)
            break
        except OSError:
            if proc.poll() is not None or time.time() > deadline:
                os.killpg(proc.pid, signal.SIGTERM)
                pytest.fail(f"the app did not start: {(work / 'server.log').read_text()[-2000:]}")
            time.sleep(1)
    clip = work / "clip.wav"
    wave, sr = sf.read(DEMO_CLIPS / "talk.flac", dtype="float32")
    sf.write(clip, wave[: 10 * sr], sr)
    sf.write(work / "short.wav", wave[: 4 * sr], sr)  # two browsers at once: shorter work for each
    yield url, clip, proc
    os.killpg(proc.pid, signal.SIGTERM)
    proc.wait(timeout=30)


def _open(driver, url):
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import WebDriverWait

    driver.get(url)
    WebDriverWait(driver, 60).until(lambda d: d.find_elements(By.ID, "animate"))


def _request(driver, clip, emotion, length="0:10", face=False):
    """Upload ``clip`` (the player shows its ``length`` once it is in), choose ``emotion`` (and a face), press
    Animate."""
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import WebDriverWait

    driver.find_element(By.CSS_SELECTOR, "#speech input[type=file]").send_keys(str(clip))
    WebDriverWait(driver, 60).until(lambda d: length in d.find_element(By.ID, "speech").text)
    next(label for label in driver.find_elements(By.CSS_SELECTOR, "label") if label.text.strip() == emotion).click()
    if face:
        driver.find_element(By.CSS_SELECTOR, "#face input[type=checkbox]").click()
    driver.find_element(By.ID, "animate").click()


def _video_src(driver, timeout=300):
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import WebDriverWait

    WebDriverWait(driver, timeout).until(lambda d: d.find_elements(By.CSS_SELECTOR, "#video video[src]"))
    return driver.find_element(By.CSS_SELECTOR, "#video video").get_attribute("src")


def test_upload_choose_anger_animate_watch_and_download(server, tmp_path):
    from selenium.webdriver.support.ui import WebDriverWait

    url, clip, proc = server
    driver = headless_chromium()
    try:
        _open(driver, url)
        _request(driver, clip, "anger", face=True)
        src = _video_src(driver)
        assert "emotion-anger" in src
        duration = WebDriverWait(driver, 60).until(lambda d: d.execute_script(
            "const v = document.querySelector('#video video'); return v.readyState >= 1 ? v.duration : null;"))
        assert duration == pytest.approx(10.0, abs=0.2)
        WebDriverWait(driver, 120).until(lambda d: d.execute_script(
            "return document.querySelector('#viewer canvas').dataset.loaded || null;"))
        # the face asked for is in the glb, and the view draws its 52 morph targets
        assert driver.execute_script("return document.querySelector('#viewer canvas').dataset.face;") == "52"
        time.sleep(1.0)
        still = canvas_pixels(driver, '#viewer canvas')
        background = still[2, 2]
        drawn = (np.abs(still - background).sum(-1) > 30).mean()
        assert 0.01 < drawn < 0.6  # the mannequin is on the canvas, and not everywhere
        driver.execute_script("document.querySelector('#viewer audio').play();")
        frames = [int(driver.execute_script("return document.querySelector('#viewer canvas').dataset.frame;"))]
        time.sleep(1.5)
        moving = canvas_pixels(driver, '#viewer canvas')
        frames.append(int(driver.execute_script("return document.querySelector('#viewer canvas').dataset.frame;")))
        assert frames[1] > frames[0] and np.abs(moving - still).sum(-1).max() > 30  # it moves with the speech
        links = driver.execute_script("return [...document.querySelectorAll('#downloads a')].map(a => a.href);")
        suffixes = {Path(link).suffix for link in links}
        assert {".npz", ".bvh", ".glb", ".mp4", ".json"} <= suffixes
        for link in links:
            body = urllib.request.urlopen(link, timeout=30).read()
            assert len(body) > 100
            if link.endswith(".glb"):
                assert body[:4] == b"glTF"
        rows = driver.execute_script("return document.querySelectorAll('#perception tbody tr').length;")
        assert rows >= 1
        driver.save_screenshot(str(tmp_path / "app.png"))
    finally:
        driver.quit()
    assert proc.poll() is None


def test_a_bad_request_is_a_message_and_two_browsers_get_their_own_results(server):
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import WebDriverWait

    url, clip, proc = server
    first, second = headless_chromium(), headless_chromium()
    try:
        _open(first, url)
        first.find_element(By.ID, "animate").click()  # no speech
        WebDriverWait(first, 60).until(lambda d: "upload or record some speech first" in d.page_source)
        assert "Traceback" not in first.page_source and proc.poll() is None
        _open(second, url)
        short = clip.with_name("short.wav")
        _request(first, short, "happiness", length="0:04")
        _request(second, short, "sadness", length="0:04")
        a, b = _video_src(first), _video_src(second)
        assert "emotion-happiness" in a and "emotion-sadness" in b
    finally:
        first.quit()
        second.quit()
    assert proc.poll() is None


def test_perception_rows_from_a_report():
    report = {"windows": [{"start_s": 0.0, "end_s": 10.0, "emotion": "anger",
                           "probabilities": {"anger": 0.61}, "trust": 0.5, "animated_emotion": {"anger": 1.0}}]}
    assert perception_rows(report) == [["0-10 s", "anger", "0.61", "0.50", "anger 100%"]]


def test_the_app_without_gradio_says_what_to_install(monkeypatch):
    import importlib.util

    from emogesture.app.page import serve
    from emogesture.errors import EmogestureError

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "gradio" else real(name, *a))
    with pytest.raises(EmogestureError, match=r"pip install 'emogesture\[app\]'"):
        serve(lambda: None)
