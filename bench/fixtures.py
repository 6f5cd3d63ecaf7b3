"""What the benchmarks run on: speech of any length and gesture/speech models of either preset.

Speech: the bundled demo clip (real speech, 20.5 s) repeated and cut to the length asked.
Models: ``tiny`` is the bundled model (what a user runs); ``paper`` is built untrained from its
preset (speed does not depend on training) and saved the way training saves it, so the whole
process — loading included — is what ``emogesture generate`` does with a trained paper model.
"""

from __future__ import annotations

import atexit
import shutil
import tempfile
from pathlib import Path

import numpy as np
import soundfile as sf
import torch

from emogesture.assets import DEMO_CLIPS, bundled_model_file
from emogesture.audio import load_audio
from emogesture.checkpoints import save_model
from emogesture.config import to_dict
from emogesture.data.beat import EMOTIONS
from emogesture.data.prepare import PrepareConfig
from emogesture.models.gesture import GestureModel, GestureModelConfig
from emogesture.models.speech import SpeechDisentangler, SpeechModelConfig


def scratch_folder() -> Path:
    """A new temporary folder for one benchmark's speech, models and outputs, removed when the process
    exits (a benchmark writes tens of MB there)."""
    folder = Path(tempfile.mkdtemp(prefix="emogesture-bench-"))
    atexit.register(shutil.rmtree, folder, ignore_errors=True)
    return folder


def speech_file(folder: Path, seconds: float) -> Path:
    """A 16 kHz wav of ``seconds`` of the demo speech (repeated as needed) in ``folder``."""
    path = folder / f"speech_{seconds:g}s.wav"
    if not path.exists():
        wave, _ = load_audio(DEMO_CLIPS / "talk.flac")
        n = int(round(seconds * 16000))
        sf.write(path, np.resize(wave, n).astype(np.float32), 16000)
    return path


def gesture_run(folder: Path, preset: str) -> Path:
    """The gesture model JSON of ``preset`` (its speech model beside it, named in it)."""
    if preset == "tiny":
        return bundled_model_file("gesture")
    out = folder / f"{preset}_gesture" / "model.json"
    if out.exists():
        return out
    torch.manual_seed(0)
    speakers = list(range(1, 31))
    scfg = SpeechModelConfig.preset(preset, num_speakers=len(speakers))
    speech_json = save_model(folder / f"{preset}_speech", "speech", SpeechDisentangler(scfg), scfg, {
        "emotions": list(EMOTIONS), "speakers": speakers, "fbank_mean": -9.0, "fbank_std": 5.0,
        "prepare_config": to_dict(PrepareConfig()), "step": 0})
    import json

    gcfg = GestureModelConfig.preset(preset)
    sha = json.loads(speech_json.read_text())["weights_sha256"]
    return save_model(out.parent, "gesture", GestureModel(gcfg), gcfg, {
        "emotions": list(EMOTIONS), "motion_mean": [0.0] * 282, "motion_std": [0.3] * 282,
        "features": to_dict(PrepareConfig().features), "variant": "joint", "fps": 30,
        "speech_model": str(speech_json), "speech_weights_sha256": sha,
        "emotion_latent_means": {e: [0.01 * i] * 256 for i, e in enumerate(EMOTIONS)}, "step": 0})
