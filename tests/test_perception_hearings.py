"""The emotion heard in a window: the mean of the recording heard as it is and with its voice moved in pitch."""

import numpy as np
import pytest
import torch

from emogesture.audio.wave_augment import voice_shift
from emogesture.checkpoints import load_model, save_model
from emogesture.config import to_dict
from emogesture.data.beat import EMOTIONS
from emogesture.data.prepare import PrepareConfig
from emogesture.errors import ConfigError
from emogesture.models.speech import SpeechDisentangler, SpeechModelConfig
from emogesture.pipeline.perception import heard_probabilities, perceive
from emogesture.pipeline.speech import EncodedWindows, SpeechLatentEncoder


def _voice(seconds: float = 12.0) -> np.ndarray:
    """A voiced tone with a gliding pitch, in syllables."""
    t = np.arange(int(seconds * 16000)) / 16000
    f0 = 150 + 40 * np.sin(2 * np.pi * 0.4 * t)
    voiced = sum(np.sin(2 * np.pi * k * np.cumsum(f0) / 16000) / k for k in range(1, 10))
    return (0.2 * voiced * (np.sin(2 * np.pi * 3.0 * t) > 0.0)).astype(np.float32)


@pytest.fixture(scope="module")
def encoder(tmp_path_factory):
    torch.manual_seed(0)
    cfg = SpeechModelConfig.preset("tiny", num_speakers=2)
    path = tmp_path_factory.mktemp("hearings") / "m"
    save_model(path, "speech", SpeechDisentangler(cfg), cfg, {
        "emotions": list(EMOTIONS), "speakers": [1, 2], "fbank_mean": -9.0, "fbank_std": 5.0,
        "prepare_config": to_dict(PrepareConfig()), "step": 0})
    return SpeechLatentEncoder(load_model(path, "speech"))


def test_the_encoder_hears_the_voice_moved_up_and_down_and_keeps_its_own_latents(encoder):
    wave = _voice() + np.float32(1e-3) * np.sin(np.arange(12 * 16000, dtype=np.float32))  # no digital silence
    once, starts = encoder.encode(wave)
    thrice, starts3 = encoder.encode(wave, perception_semitones=3.0)
    assert once.shifted_emotion is None and starts == starts3
    for k in EncodedWindows.stored:  # the latents the gesture model gets are the recording's own
        np.testing.assert_array_equal(getattr(once, k), getattr(thrice, k))
    w = len(starts)
    assert thrice.shifted_emotion.shape == (2, w, once.emotion.shape[1])
    assert thrice.shifted_logits.shape == (2, w, len(EMOTIONS))
    up = encoder.encode(voice_shift(wave.astype(np.float64), 3.0).astype(np.float32))[0]
    np.testing.assert_allclose(thrice.shifted_emotion[0], up.emotion, atol=1e-5)
    assert np.abs(thrice.shifted_emotion[0] - once.emotion).mean() > 1e-4
    assert np.abs(thrice.shifted_emotion[0] - thrice.shifted_emotion[1]).mean() > 1e-4
    # a source asked only for its style is heard once
    assert encoder.encode(wave, parts=("style",), perception_semitones=3.0)[0].shifted_emotion is None
    with pytest.raises(ValueError, match="perception_semitones"):
        encoder.encode(wave, perception_semitones=-1.0)


def test_the_heard_emotion_is_the_mean_of_the_three_readings():
    def logits(k: int, n: int = 2) -> np.ndarray:
        x = np.zeros((n, len(EMOTIONS)), np.float32)
        x[:, k] = 2.0
        return x

    empty = np.zeros((2, 4), np.float32)
    enc = EncodedWindows(empty, empty, empty, logits(EMOTIONS.index("contempt")), empty)
    alone = heard_probabilities(enc, None)
    assert alone.argmax(1).tolist() == [EMOTIONS.index("contempt")] * 2
    enc.shifted_emotion = np.stack([empty, empty])
    enc.shifted_logits = np.stack([logits(0), logits(0)])  # both moved voices sound neutral
    mean = heard_probabilities(enc, None)
    np.testing.assert_allclose(mean, (alone + 2 * heard_probabilities(EncodedWindows(
        empty, empty, empty, logits(0), empty), None)) / 3, rtol=1e-6)
    np.testing.assert_allclose(mean.sum(1), 1.0, rtol=1e-6)
    assert perceive(enc, [0.0, 5.0], None, "x.wav").labels == ["neutral", "neutral"]


def test_the_bundle_hears_three_times_unless_told_otherwise_or_its_front_end_hears():
    from emogesture.models.generation import GenerationConfig
    from emogesture.pipeline.generate import GesturePipeline

    assert GenerationConfig().perception_semitones == 3.0
    once = GenerationConfig.preset("tiny").with_overrides(["perception_semitones=0"])
    with pytest.raises(ConfigError, match="perception_semitones"):
        GenerationConfig.preset("tiny").with_overrides(["perception_semitones=-2"])
    pipe = GesturePipeline.from_run()
    wave = _voice(14.0)
    if pipe.speech.perception is not None and pipe.speech.perception.heard is not None:
        front = pipe.encode(wave)[0]  # the front end trained on real speech hears what it must: heard once
        assert front.shifted_emotion is None
    hop = pipe.generation.hop_seconds

    def encode(settings):  # as generate hears it without the front end
        return pipe.speech.encode(wave, hop_seconds=hop, perception_semitones=settings.perception_semitones)

    heard = encode(pipe.generation)
    single = encode(once)
    assert heard[0].shifted_emotion is not None and single[0].shifted_emotion is None
    assert pipe.encode(wave, perceived=False)[0].shifted_emotion is None  # latents alone: heard once
    np.testing.assert_array_equal(heard[0].emotion, single[0].emotion)
    p3, p1 = pipe.perceive(*heard, source="v.wav"), pipe.perceive(*single, source="v.wav")
    assert np.abs(p3.probabilities - p1.probabilities).max() > 1e-4
    np.testing.assert_array_equal(p3.trust, p1.trust)  # the trust is the recording's own


def test_a_split_gives_the_takes_of_the_voices_a_model_never_heard():
    from emogesture.data.cache import SplitWindows

    empty = np.zeros((5, 1, 1), np.float32)
    split = SplitWindows(empty, empty, empty[..., 0], ["a", "a", "b", "c", "c"], np.array([1, 1, 2, 3, 3]),
                         np.array([4, 4, 0, 7, 7]), np.zeros(5, np.int64), np.zeros(5))
    assert split.take_emotions() == {"a": 4, "b": 0, "c": 7}
    assert split.take_emotions(leave_out_speakers=[1, 3]) == {"b": 0}
    assert split.take_emotions(leave_out_speakers=np.array([1, 2, 3])) == {}
