"""Helpers shared by the tests: a small BEAT2-layout folder, small untrained models, the command line,
speech-like audio and gesture-like motion with its forward kinematics, the end of a live stream."""

import json
import sys
from pathlib import Path
from typing import NamedTuple

import time

import numpy as np
import soundfile as sf
import torch

from emogesture.data.beat import format_take_name, write_split_csv
from emogesture.motion import SkeletonBody, save_smplx_npz
from emogesture.types import SMPLXSequence

SECONDS = 21.0


def gesture_like(frames: int = 45, seed: int = 0) -> SMPLXSequence:
    """Smooth random rotations on every joint (large on the arms), a drifting root, non-zero shape."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 2 * np.pi, frames)[:, None, None]
    amp = rng.uniform(0.05, 0.4, (1, 55, 3))
    amp[:, 16:22] *= 3.0
    poses = amp * np.sin(t * rng.uniform(0.5, 2.0, (1, 55, 3)) + rng.uniform(0, 6, (1, 55, 3)))
    trans = 0.1 * np.sin(t[:, 0] * np.array([1.0, 0.5, 0.7]))
    betas = np.zeros(300, np.float32)
    betas[:10] = rng.normal(0, 1, 10)
    return SMPLXSequence(poses=poses.astype(np.float32), trans=trans.astype(np.float32), betas=betas)


def fk(seq: SMPLXSequence) -> np.ndarray:
    with torch.no_grad():
        return SkeletonBody(seq.betas)(torch.from_numpy(seq.poses), torch.from_numpy(seq.trans)).numpy()


def speech_like(seconds: float = 3.0, sr: int = 16000, seed: int = 0) -> np.ndarray:
    """Harmonic source with a gliding f0, three formant-like resonances, syllable-rate AM and a little noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * sr)) / sr
    f0 = 120.0 + 20.0 * np.sin(2 * np.pi * 0.7 * t)
    phase = 2 * np.pi * np.cumsum(f0) / sr
    x = np.zeros_like(t)
    for h in range(1, 60):
        fh = h * f0
        env = (np.exp(-(((fh - 700) / 300) ** 2)) + 0.6 * np.exp(-(((fh - 1200) / 400) ** 2))
               + 0.3 * np.exp(-(((fh - 2500) / 500) ** 2)) + 0.01)
        x += np.where(fh < sr / 2, env * np.sin(h * phase) / h**0.3, 0.0)
    x *= 0.2 + 0.8 * np.sin(2 * np.pi * 2.5 * t) ** 2
    x = 0.5 * x / np.abs(x).max() + 1e-3 * rng.standard_normal(t.size)
    return x.astype(np.float32)


def make_root(root: Path, speakers=(1, 2), takes=(1, 2, 65, 66), seed=0) -> list[str]:
    """A small BEAT2-layout folder: tone-burst audio and smooth random upper-body motion."""
    rng = np.random.default_rng(seed)
    for d in ("smplxflame_30", "wave16k", "sem"):
        (root / d).mkdir(parents=True, exist_ok=True)
    names, splits = [], {}
    t = np.arange(int(SECONDS * 16000)) / 16000
    for spk in speakers:
        for take in takes:
            name = format_take_name(spk, take)
            names.append(name)
            f0 = 120 + 40 * spk + take
            wave = 0.3 * np.sin(2 * np.pi * f0 * t) * (np.sin(2 * np.pi * 2.0 * t) > 0)
            sf.write(root / "wave16k" / f"{name}.wav", wave.astype(np.float32), 16000, subtype="PCM_16")
            T = int(SECONDS * 30)
            poses = np.cumsum(rng.normal(0, 0.01, (T, 55, 3)), axis=0).astype(np.float32)
            save_smplx_npz(SMPLXSequence(poses=poses, trans=np.zeros((T, 3))), root / "smplxflame_30" / f"{name}.npz")
            (root / "sem" / f"{name}.txt").write_text("beat\t1.0\t2.0\t1.0\t0.5\tword\n")
            splits[name] = "test" if take in (2, 66) else "train"
    write_split_csv(root / "train_test_split.csv", splits)
    return names


def write_tiny_runs(folder: Path) -> Path:
    """Small untrained speech and gesture models written as runs under ``folder`` (``speech``, ``gesture``), with
    five denoising steps; returns the gesture run (``GesturePipeline.from_run`` takes it). Seeds torch."""
    from emogesture.checkpoints import save_model
    from emogesture.config import to_dict
    from emogesture.data.beat import EMOTIONS
    from emogesture.data.prepare import PrepareConfig
    from emogesture.models.generation import GenerationConfig
    from emogesture.models.gesture import GestureModel, GestureModelConfig
    from emogesture.models.speech import SpeechDisentangler, SpeechModelConfig

    torch.manual_seed(0)
    scfg = SpeechModelConfig.preset("tiny", num_speakers=2)
    speech_json = save_model(folder / "speech", "speech", SpeechDisentangler(scfg), scfg, {
        "emotions": list(EMOTIONS), "speakers": [1, 2], "fbank_mean": -9.0, "fbank_std": 5.0,
        "prepare_config": to_dict(PrepareConfig()), "step": 0})
    gcfg = GestureModelConfig.preset("tiny")
    sha = json.loads(speech_json.read_text())["weights_sha256"]
    save_model(folder / "gesture", "gesture", GestureModel(gcfg), gcfg, {
        "emotions": list(EMOTIONS), "motion_mean": [0.0] * 282, "motion_std": [0.3] * 282,
        "features": to_dict(PrepareConfig().features), "variant": "joint", "fps": 30,
        "speech_model": str(speech_json), "speech_weights_sha256": sha,
        "emotion_latent_means": {e: [float(i)] * 256 for i, e in enumerate(EMOTIONS)}, "step": 0},
        generation=GenerationConfig(num_inference_steps=5))
    return folder / "gesture"


def ended(ws) -> tuple[list[dict], dict]:
    """Ends the live stream on ``ws`` (a websockets sync client): the frames that come until the server is
    done, and its last reply."""
    ws.send(json.dumps({"end": True}))
    frames = []
    while True:
        reply = json.loads(ws.recv())
        frames += reply.get("frames", [])
        if reply.get("done"):
            return frames, reply


def cli(*args) -> list[str]:
    """The ``emogesture`` command line run with this interpreter."""
    return [sys.executable, "-m", "emogesture.cli.main", *map(str, args)]


class Ran(NamedTuple):
    """What a command run in this process gave, named as ``subprocess.run``'s result names it."""

    returncode: int
    stdout: str
    stderr: str


def cli_here(capsys, *args) -> Ran:
    """The ``emogesture`` command line run in this process (no start-up of its own; ``capsys``: pytest's
    fixture)."""
    from emogesture.cli.main import main

    capsys.readouterr()
    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return Ran(code, out.out, out.err)


CHROMIUM, CHROMEDRIVER = "/usr/bin/chromium", "/usr/bin/chromedriver"


def require_chromium() -> None:
    """Skip without Debian's chromium and its driver (fail in CI, where `make test` installs them)."""
    import os

    import pytest

    if not (Path(CHROMIUM).exists() and Path(CHROMEDRIVER).exists()):
        if os.environ.get("CI"):
            pytest.fail("chromium and chromium-driver are missing (make test installs them)")
        pytest.skip("chromium and chromium-driver are missing (make test installs them)")


def headless_chromium(*flags: str, size: str = "1400,1800"):
    """A selenium driver of headless chromium with WebGL in software (SwiftShader) and autoplay allowed."""
    from selenium import webdriver
    from selenium.webdriver.chrome.options import Options
    from selenium.webdriver.chrome.service import Service

    options = Options()
    options.binary_location = CHROMIUM
    for flag in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", f"--window-size={size}",
                 "--use-gl=angle", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
                 "--autoplay-policy=no-user-gesture-required", *flags):
        options.add_argument(flag)
    return webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)


def canvas_pixels(driver, selector: str) -> np.ndarray:
    """The RGB pixels ``[H, W, 3]`` (int16) of the page's canvas at ``selector``."""
    import base64
    import io

    from PIL import Image

    data = driver.execute_script(f"return document.querySelector({selector!r}).toDataURL('image/png');")
    return np.asarray(Image.open(io.BytesIO(base64.b64decode(data.split(",", 1)[1]))).convert("RGB"), np.int16)


def experiment_module(name: str):
    """The script ``experiments/<name>.py`` imported as a module (experiments are scripts, not a package); ``name``
    may name a topic folder, e.g. ``perception/perception_readout``."""
    import importlib.util

    path = Path(__file__).resolve().parents[1] / "experiments" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(path.stem, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def wait_for_server(port, running, timeout, interval=0.5):
    """Whether the server on 127.0.0.1:``port`` answers HTTP (any status) before ``timeout`` seconds pass
    while ``running()`` holds."""
    import urllib.error
    import urllib.request

    deadline = time.time() + timeout
    while True:
        try:
            urllib.request.urlopen(f"http://127.0.0.1:{port}/nothing", timeout=2)
            return True
        except urllib.error.HTTPError:
            return True  # it answers
        except OSError:
            if not running() or time.time() > deadline:
                return False
            time.sleep(interval)
