"""experiments/voice_encoder_perception.py's speaker encoder: resemblyzer's shipped weights read through the
project's own mel front end. Its embeddings are unit length and non-negative, do not move with the recording's
level, and tell two real voices apart better than two halves of one voice."""

from pathlib import Path

import numpy as np

from emogesture.audio import load_audio
from emogesture.data.real_speech import RECORDINGS, load_real_recording

from helpers import experiment_module


def _module():
    return experiment_module("voice_encoder_perception")


def test_speaker_encoder_embeds_voices_not_levels():
    v = _module()
    model = v.load_speaker_encoder()
    reader = load_real_recording(next(r for r in RECORDINGS if r.name == "librivox")).astype(np.float64)
    cards = load_real_recording(next(r for r in RECORDINGS if r.name == "cards")).astype(np.float64)
    first, second, other = (v.embed(model, x) for x in (reader[: 10 * 16000], reader[10 * 16000: 20 * 16000], cards))
    for e in (first, second, other):
        assert e.shape == (256,) and np.all(e >= 0) and abs(np.linalg.norm(e) - 1) < 1e-5
    quiet = v.embed(model, reader[: 10 * 16000] * 0.05)
    assert float(first @ quiet) > 0.9999  # brought to -30 dBFS first
    assert float(first @ second) > float(first @ other) + 0.1  # the same reader, against another man


def test_windows_follow_the_pipeline():
    v = _module()
    wave = load_audio(Path(__file__).resolve().parents[1] / "src/emogesture/assets/demo/talk.flac")[0]
    parts = v.windows(wave)
    assert len(parts) >= 3 and all(len(p) == 160000 for p in parts)
    assert np.array_equal(parts[-1], wave[-160000:])  # the last window ends with the recording
