"""Steady noise taken out of a noisy recording before the speech model hears it; a recording in range untouched."""

import numpy as np
import pytest
import torch

from emogesture.audio import NoiseSuppression, dynamic_range_db, kaldi_fbank, suppress_noise
from emogesture.checkpoints import load_model, save_model
from emogesture.config import to_dict
from emogesture.data.beat import EMOTIONS
from emogesture.data.prepare import PrepareConfig
from emogesture.models.speech import SpeechDisentangler, SpeechModelConfig
from emogesture.pipeline.speech import SpeechLatentEncoder


def _speech(seconds: float = 8.0) -> np.ndarray:
    """Voiced bursts with pauses between them, a quiet floor (about 45 dB below the bursts)."""
    rng = np.random.default_rng(0)
    t = np.arange(int(seconds * 16000)) / 16000
    f0 = 140 + 30 * np.sin(2 * np.pi * 0.7 * t)
    voiced = sum(np.sin(2 * np.pi * k * np.cumsum(f0) / 16000) / k for k in range(1, 12))
    return (0.2 * voiced * (np.sin(2 * np.pi * 2.5 * t) > 0.2) + 0.001 * rng.normal(size=t.size)).astype(np.float32)


def _noisy(x: np.ndarray, snr_db: float, seed: int = 1) -> np.ndarray:
    noise = np.random.default_rng(seed).normal(size=x.size)
    noise *= np.sqrt(np.mean(x ** 2) / np.mean(noise ** 2) / 10 ** (snr_db / 10))
    return (x + noise).astype(np.float32)


def test_a_quiet_recording_is_left_as_it_is():
    fb = kaldi_fbank(_speech())
    assert dynamic_range_db(fb) > 25
    assert suppress_noise(fb) is fb


def test_noise_is_taken_out_of_the_pauses_and_the_speech_kept():
    clean = kaldi_fbank(_speech())
    noisy = kaldi_fbank(_noisy(_speech(), 10.0))
    assert dynamic_range_db(noisy) < 15
    out = suppress_noise(noisy)
    assert isinstance(out, torch.Tensor) and out.dtype == noisy.dtype and out.shape == noisy.shape
    loud = clean.mean(1) > np.percentile(clean.mean(1), 70)
    pause = clean.mean(1) < np.percentile(clean.mean(1), 20)
    # the pauses fall by about 10 dB (at most the floor's 20 dB, ln 100 = 4.6), the speech's loudest bins hardly move
    assert float((noisy - out)[pause].mean()) > 1.5
    floor = torch.quantile(noisy, 0.1, dim=0)
    strong = loud[:, None] & (clean > floor + np.log(10.0))  # speech 10 dB above the noise: kept within 2 dB
    assert int(strong.sum()) > 1000 and float((noisy - out)[strong].mean()) < np.log(10 ** 0.2)
    # the dynamic range comes back toward the clean recording's
    assert dynamic_range_db(out) > dynamic_range_db(noisy) + 2
    assert (out - clean).abs().mean() < 0.8 * (noisy - clean).abs().mean()  # 0.69: the floor keeps 20 dB at most


def test_strength_follows_the_noise():
    x = _speech()
    change = [float((kaldi_fbank(y) - suppress_noise(kaldi_fbank(y))).mean()) for y in
              (_noisy(x, 0.0), _noisy(x, 30.0), _noisy(x, 40.0))]
    assert change[0] > change[1] > 0 and change[2] == 0.0  # dynamic range 1.5, 16 and 24 dB


def test_short_recordings_arrays_and_settings():
    noisy = kaldi_fbank(_noisy(_speech(8.0), 10.0))
    short = noisy[:400]  # 4 s: left alone
    assert suppress_noise(short) is short
    as_numpy = suppress_noise(noisy.numpy())
    assert isinstance(as_numpy, np.ndarray) and as_numpy.dtype == np.float32
    np.testing.assert_allclose(as_numpy, suppress_noise(noisy).numpy(), atol=1e-5)
    assert suppress_noise(noisy, NoiseSuppression(over_subtraction=0.0)) is noisy
    with pytest.raises(ValueError, match="noise suppression settings"):
        NoiseSuppression(full_below_db=20.0, off_above_db=10.0)


def test_the_encoder_hears_noisy_speech_through_the_suppression(tmp_path):
    torch.manual_seed(0)
    cfg = SpeechModelConfig.preset("tiny", num_speakers=2)
    save_model(tmp_path / "m", "speech", SpeechDisentangler(cfg), cfg, {
        "emotions": list(EMOTIONS), "speakers": [1, 2], "fbank_mean": -9.0, "fbank_std": 5.0,
        "prepare_config": to_dict(PrepareConfig()), "step": 0})
    encoder = SpeechLatentEncoder(load_model(tmp_path / "m", "speech"))
    raw = SpeechLatentEncoder(load_model(tmp_path / "m", "speech"))
    raw.noise_suppression = None
    clean, noisy = _speech(), _noisy(_speech(), 10.0)
    np.testing.assert_array_equal(encoder.encode(clean)[0].emotion, raw.encode(clean)[0].emotion)
    heard, unheard = encoder.encode(noisy)[0], raw.encode(noisy)[0]
    assert np.abs(heard.emotion - unheard.emotion).mean() > 1e-3
    assert np.abs(heard.timing - unheard.timing).mean() > 1e-3  # the timing stream hears the cleaned recording too


def test_a_bundle_can_hear_noisy_recordings_as_they_are(tmp_path):
    from emogesture.models.generation import GenerationConfig
    from emogesture.pipeline.generate import GesturePipeline

    settings = GenerationConfig.preset("tiny").with_overrides(["noise_suppression=false"])
    assert settings.noise_suppression is False and GenerationConfig().noise_suppression is True
    pipe = GesturePipeline.from_run()
    noisy = _noisy(_speech(12.0), 10.0)
    on, off = pipe.encode(noisy)[0], pipe.encode(noisy, generation=settings)[0]
    raw = pipe.speech.encode(noisy, hop_seconds=settings.hop_seconds, noise_suppression=False)[0]
    np.testing.assert_array_equal(off.emotion, raw.emotion)
    assert np.abs(on.emotion - off.emotion).mean() > 1e-3


def test_silence_stays_at_the_log_floor():
    from emogesture.audio.windows import LOG_FLOOR

    silence = kaldi_fbank(np.zeros(8 * 16000, np.float32))
    assert dynamic_range_db(silence) == 0.0
    assert torch.equal(suppress_noise(silence), silence)
    gaps = np.concatenate([_noisy(_speech(), 10.0), np.zeros(3 * 16000, np.float32)])
    assert float(suppress_noise(kaldi_fbank(gaps)).min()) >= LOG_FLOOR - 1e-5


def test_generate_says_when_it_took_noise_out(tmp_path):
    from emogesture.pipeline.generate import GesturePipeline

    pipe = GesturePipeline.from_run()
    quiet, noisy = _speech(12.0), _noisy(_speech(12.0), 10.0)
    heard = [pipe.perceive(*pipe.encode(wave), source=name)
             for wave, name in ((quiet, "quiet.wav"), (noisy, "noisy.wav"))]
    assert heard[0].noise_suppressed == 0.0 and "background noise" not in " ".join(heard[0].details("auto"))
    assert heard[1].noise_suppressed == 1.0 and "steady background noise taken out (100%)" in " ".join(heard[1].details("auto"))
    assert '"noise_suppressed": 1.0' in heard[1].to_json()


def test_digital_silence_is_heard_as_the_recordings_own_quiet():
    from emogesture.audio import digital_silence, fill_digital_silence

    speech = _speech()
    gap = np.zeros(16000 // 2, np.float32)
    joined = np.concatenate([speech, gap, speech])
    fb = kaldi_fbank(joined)
    silent = digital_silence(fb)
    assert 40 <= silent.sum() <= 50  # the half second of zeros, less the frames that reach into the speech
    filled = fill_digital_silence(fb)
    assert isinstance(filled, torch.Tensor) and filled.shape == fb.shape
    np.testing.assert_array_equal(filled[~silent].numpy(), fb[~silent].numpy())  # the rest untouched
    quiet = np.percentile(fb[~silent].numpy(), 1, axis=0)
    np.testing.assert_allclose(filled[silent].numpy(), np.broadcast_to(quiet, (silent.sum(), quiet.size)), rtol=1e-5)
    assert not digital_silence(filled).any()
    # a recording without digital silence, and one that is nearly all silence, are returned as they are
    plain = kaldi_fbank(speech)
    assert fill_digital_silence(plain) is plain
    nearly = kaldi_fbank(np.concatenate([np.zeros(16000 * 3, np.float32), speech[:1600]]))
    assert fill_digital_silence(nearly) is nearly


def test_the_encoder_fills_digital_silence_and_says_so(tmp_path):
    from emogesture.pipeline.generate import GesturePipeline

    pipe = GesturePipeline.from_run()
    speech = _speech(6.0)
    joined = np.concatenate([speech, np.zeros(16000, np.float32), speech])
    heard = pipe.perceive(*pipe.encode(joined), source="joined.wav")
    assert 0.9 <= heard.digital_silence_s <= 1.0
    assert "digital silence heard as the recording's own quiet" in " ".join(heard.details("auto"))
    assert '"digital_silence_s": ' in heard.to_json()
    pipe.speech.fill_digital_silence = False
    try:
        raw = pipe.encode(joined)[0]
    finally:
        pipe.speech.fill_digital_silence = True
    assert raw.digital_silence_s == 0.0
    assert np.abs(raw.emotion - pipe.encode(joined)[0].emotion).mean() > 1e-4
    plain = pipe.perceive(*pipe.encode(speech), source="plain.wav")
    assert plain.digital_silence_s == 0.0 and "digital silence" not in " ".join(plain.details("auto"))


@pytest.mark.parametrize("frames", [1, 2, 3, 40, 997])
def test_column_percentiles_are_numpys(frames):
    """The few order statistics a low (or high) percentile needs give numpy's values, interpolation included."""
    from emogesture.audio.noise import column_percentiles

    x = np.random.default_rng(frames).normal(size=(frames, 5))
    x[:, 0] = 1.5  # ties
    for q in (0.0, 1.0, 10.0, 33.3, 50.0, 90.0, 99.0, 100.0):
        np.testing.assert_allclose(column_percentiles(x, q), np.percentile(x, q, axis=0), rtol=0, atol=1e-12)
