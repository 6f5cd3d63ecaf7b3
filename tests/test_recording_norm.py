"""A recording measured against itself (``recording_norm``): gain and channel leave the speech model's input alone."""

import numpy as np
import pytest
import torch

from emogesture.audio import kaldi_fbank, normalise_recording, speech_level
from emogesture.checkpoints import load_model, save_model
from emogesture.config import to_dict
from emogesture.data.beat import EMOTIONS
from emogesture.data.prepare import PrepareConfig, prepare
from emogesture.errors import EmogestureError
from emogesture.models.speech import SpeechDisentangler, SpeechModelConfig
from emogesture.pipeline.speech import SpeechLatentEncoder


def _speech(seconds: float = 6.0, seed: int = 0) -> np.ndarray:
    """Voiced bursts with pauses between them (a few syllables per second) and a little noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * 16000)) / 16000
    f0 = 140 + 30 * np.sin(2 * np.pi * 0.7 * t)
    voiced = sum(np.sin(2 * np.pi * k * np.cumsum(f0) / 16000) / k for k in range(1, 12))
    return (0.2 * voiced * (np.sin(2 * np.pi * 2.5 * t) > 0.2) + 0.01 * rng.normal(size=t.size)).astype(np.float32)


def test_level_ignores_the_gain_and_spectrum_the_channel():
    x = _speech()
    fb, louder = kaldi_fbank(x), kaldi_fbank(10 * x)
    heard = fb > -14.0  # away from Kaldi's log floor (-15.9), which no gain moves
    clean = heard.all(0)  # bins never at the floor
    assert heard.float().mean() > 0.95 and int(clean.sum()) > 100
    assert (louder - fb)[heard].abs().mean() > 4.0  # 20 dB moves every bin by ln(100)
    np.testing.assert_allclose(normalise_recording(louder, "level")[heard], normalise_recording(fb, "level")[heard],
                               atol=0.01)
    np.testing.assert_allclose(normalise_recording(louder, "spectrum")[:, clean],
                               normalise_recording(fb, "spectrum")[:, clean], atol=0.01)
    tilt = torch.linspace(-2.0, 2.0, fb.shape[1])  # a microphone's colouring: a fixed offset per bin
    np.testing.assert_allclose(normalise_recording(fb + tilt, "spectrum")[:, clean],
                               normalise_recording(fb, "spectrum")[:, clean], atol=1e-4)
    coloured, plain = normalise_recording(fb + tilt, "level"), normalise_recording(fb, "level")
    change = (coloured - plain)[:, clean]  # the level alone keeps the colouring: one offset for every bin
    np.testing.assert_allclose(change - change[:, :1], (tilt[clean] - tilt[clean][0]).expand_as(change), atol=1e-4)
    assert normalise_recording(fb, "none") is fb
    # the level taken out is the recording's speech level, which a gain of 20 dB moves by 20 dB
    assert 10 / np.log(10) * (speech_level(louder) - speech_level(fb)) == pytest.approx(20.0, abs=0.2)
    as_numpy = normalise_recording(fb.numpy(), "level")
    assert isinstance(as_numpy, np.ndarray) and as_numpy.dtype == np.float32
    np.testing.assert_allclose(as_numpy, normalise_recording(fb, "level").numpy(), atol=1e-5)


def test_pauses_do_not_count():
    x = _speech()
    paused = np.concatenate([x, np.zeros(4 * 16000, np.float32), x])
    a, b = normalise_recording(kaldi_fbank(x), "level"), normalise_recording(kaldi_fbank(paused), "level")
    assert abs(float(a[:200].mean() - b[:200].mean())) < 0.05  # the silence does not lower the measured level
    c = kaldi_fbank(paused)
    offset_all = float(c.mean())  # what a plain mean would subtract: pulled far down by the silence
    assert abs(float((c - b)[0, 0]) - offset_all) > 1.0


def test_unknown_mode_is_refused(tmp_path):
    with pytest.raises(ValueError, match="recording normalisation 'loud'"):
        normalise_recording(kaldi_fbank(_speech(1.0)), "loud")
    with pytest.raises(EmogestureError, match="recording_norm 'loud'"):
        prepare(tmp_path, tmp_path / "cache", PrepareConfig(recording_norm="loud"))


def test_default_keeps_the_digest_of_older_caches():
    assert PrepareConfig().digest() == PrepareConfig(recording_norm="none").digest()
    assert PrepareConfig(recording_norm="level").digest() != PrepareConfig().digest()


def _encoder(tmp_path, mode: str) -> SpeechLatentEncoder:
    torch.manual_seed(0)
    cfg = SpeechModelConfig.preset("tiny", num_speakers=2)
    save_model(tmp_path / mode, "speech", SpeechDisentangler(cfg), cfg, {
        "emotions": list(EMOTIONS), "speakers": [1, 2], "fbank_mean": -9.0, "fbank_std": 5.0,
        "prepare_config": to_dict(PrepareConfig(recording_norm=mode)), "step": 0})
    return SpeechLatentEncoder(load_model(tmp_path / mode, "speech"))


def test_a_model_hears_every_recording_as_its_cache_did(tmp_path):
    """A speech model trained on a level-normalised cache gives the same latents at any input gain."""
    x = _speech(12.0)
    level = _encoder(tmp_path, "level")
    a, _ = level.encode(x)
    b, _ = level.encode(4.0 * x)
    plain = _encoder(tmp_path, "none")
    c, _ = plain.encode(x)
    d, _ = plain.encode(4.0 * x)
    moved, kept = np.abs(c.emotion - d.emotion).mean(), np.abs(a.emotion - b.emotion).mean()
    assert kept < 0.1 * moved  # only the bins at Kaldi's log floor (which no gain moves) still differ

