"""Emotion perception: distances, trust, the auto blend, and what calibration refuses."""

from __future__ import annotations

import numpy as np
import pytest

from emogesture.data.beat import EMOTIONS
from emogesture.errors import EmogestureError
from emogesture.models.perception import EmotionPerception, log_softmax
from emogesture.pipeline.perception import auto_emotion, auto_style, perceive
from emogesture.train.perception import fit_perception
from emogesture.pipeline.speech import EncodedWindows


def clusters(n_per: int, seed: int, shift: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    centres = np.random.default_rng(99).normal(0, 3, (8, 48))
    labels = np.repeat(np.arange(8), n_per)
    return centres[labels] + rng.normal(0, 1, (len(labels), 48)) + shift, labels


def windows(emotion: np.ndarray, style: np.ndarray | None = None) -> EncodedWindows:
    """Encoded windows with these emotion (and style) latents; the style defaults to a copy."""
    n = len(emotion)
    style = emotion.copy() if style is None else style
    return EncodedWindows(np.zeros((n, 4)), emotion, style, np.zeros((n, 8)), np.zeros((n, 2)))


def fitted(n_per: int = 60):
    train, labels = clusters(n_per, 0)
    held, _ = clusters(20, 1)
    return fit_perception(windows(train), labels, labels % 2, windows(held), quantile=0.99), train, held


def test_in_distribution_is_trusted_and_far_away_is_not():
    p, train, held = fitted()
    assert p.labels == list(EMOTIONS)
    assert (p.trust(held, held) == 1.0).mean() >= 0.95  # about 1 % above each 0.99 quantile
    far, _ = clusters(20, 2, shift=6.0)
    assert (p.trust(far, far) < 1.0).mean() > 0.9
    assert p.trust(far, far).mean() < 0.2
    # an unfamiliar voice alone (style far, emotion familiar) is enough to distrust the window
    assert p.trust(held, far).mean() < 0.2 and p.trust(held, held).mean() > 0.95
    # distances grow with the shift
    d = [np.median(p.emotion.nearest(clusters(20, 3, s)[0])) for s in (0.0, 1.0, 3.0)]
    assert d[0] < d[1] < d[2]
    assert 0.5 < np.median(p.emotion.nearest(held)) < 2.0  # about 1 for typical windows


def test_auto_blends_untrusted_windows_toward_neutral_only():
    p, train, _ = fitted()
    inside = train[:5]
    outside = train[:5] + 50.0
    assert np.allclose(auto_emotion(inside.astype(np.float32), inside, p), inside, atol=1e-5)
    blended = auto_emotion(outside.astype(np.float32), outside, p)
    assert np.allclose(blended, np.broadcast_to(p.neutral(), blended.shape), atol=1e-4)
    assert auto_emotion(outside, outside, None) is outside  # an uncalibrated model keeps its latents


def test_auto_moves_an_unfamiliar_voice_to_the_typical_training_style():
    p, train, _ = fitted()
    k = p.typical_speaker()
    centre = p.voice.means.mean(0)
    assert all(np.linalg.norm(p.voice.means[k] - centre) <= np.linalg.norm(m - centre) + 1e-9 for m in p.voice.means)
    inside = train[:5].astype(np.float32)
    assert np.allclose(auto_style(inside, p), inside, atol=1e-5)  # a familiar voice keeps its style
    outside = inside + 50.0
    moved = auto_style(outside, p)
    assert np.allclose(moved, np.broadcast_to(p.typical_style(), moved.shape), atol=1e-4)
    half = p.voice.means[k] + (2 * 0.75 * p.voice.threshold) * p.voice.axes[0] * np.sqrt(p.voice.variances[0] * 
                                                                                     train.shape[1])
    t = p.voice.trust(half[None])[0]
    assert 0.0 < t < 1.0  # partly trusted: partly moved
    assert np.allclose(auto_style(half[None].astype(np.float32), p)[0], t * half + (1 - t) * p.typical_style(),
                       atol=1e-4)
    assert auto_style(outside, None) is outside


def test_auto_moves_an_unfamiliar_voice_to_the_gesture_models_fallback_style():
    p, train, _ = fitted()
    fallback = p.voice.means[(p.typical_speaker() + 1) % len(p.voice.means)].astype(np.float32)
    inside = train[:5].astype(np.float32)
    assert np.allclose(auto_style(inside, p, fallback), inside, atol=1e-5)  # a familiar voice keeps its style
    moved = auto_style(inside + 50.0, p, fallback)
    assert np.allclose(moved, np.broadcast_to(fallback, moved.shape), atol=1e-4)
    assert not np.allclose(moved, np.broadcast_to(p.typical_style(), moved.shape), atol=1e-2)
    with pytest.raises(EmogestureError, match="fallback style has shape"):
        auto_style(inside + 50.0, p, fallback[:10])


def test_the_heard_emotion_adds_the_nearest_mean_only_within_the_range():
    p, train, held = fitted()
    inside = held[(p.emotion.nearest(held) <= p.emotion.threshold)][:16]
    nearest = p.emotion.distances(inside).argmin(1)
    flat = np.zeros((len(inside), 8))  # a head that cannot tell: the nearest mean decides
    assert (p.read(inside, flat).argmax(1) == nearest).all()
    assert np.allclose(np.exp(p.read(inside, flat)).sum(1), 1.0)
    sure = np.full((len(inside), 8), -1e4)
    sure[:, 5] = 1e4  # a head that is certain outvotes the means
    assert (p.read(inside, sure).argmax(1) == 5).all()
    # beyond the calibrated range the head alone decides, whatever the nearest mean
    far = inside + 40.0 * p.emotion.axes[0] * np.sqrt(p.emotion.variances[0])
    assert (p.emotion.nearest(far) > p.emotion.threshold).all()
    leaning = np.zeros((len(far), 8))
    leaning[:, 2] = 0.1
    assert np.allclose(p.read(far, leaning), log_softmax(leaning))
    # what perceive reports: these probabilities and their argmax; an uncalibrated model keeps the head's softmax
    heard = perceive(windows(inside, inside), list(range(len(inside))), p, "take")
    assert heard.labels == [EMOTIONS[k] for k in nearest] and np.allclose(heard.probabilities.sum(1), 1.0)
    raw = perceive(EncodedWindows(np.zeros((len(inside), 4)), inside, inside, sure, np.zeros((len(inside), 2))),
                   list(range(len(inside))), None, "take")
    assert set(raw.labels) == {EMOTIONS[5]} and raw.distance is None


def test_an_emotion_the_calibration_never_saw_is_never_heard_within_the_range():
    train, labels = clusters(60, 0)
    keep = labels != 3
    held, held_labels = clusters(20, 1)
    p = fit_perception(windows(train[keep]), labels[keep], labels[keep] % 2, windows(held[held_labels != 3]))
    assert EMOTIONS[3] not in p.labels
    near = train[labels == 0][:5]  # familiar windows (neutral) and windows near no known mean
    far = train[labels == 3][:5]
    assert (p.emotion.nearest(near) <= p.emotion.threshold).all()
    assert (p.emotion.nearest(far) > p.emotion.threshold).all()
    head = np.zeros((5, 8))
    head[:, 3] = 1e3  # a head sure of the emotion the calibration never saw
    assert (p.read(near, head).argmax(1) != 3).all() and (p.read(far, head).argmax(1) == 3).all()


def test_the_temperature_makes_the_read_outs_confidence_its_accuracy_and_changes_no_label():
    rng = np.random.default_rng(5)
    centres = rng.normal(0, 0.5, (8, 48))  # overlapping emotions, held-out windows more spread than the
    labels = np.repeat(np.arange(8), 80)   # training ones: the means' posterior is overconfident on them
    train = centres[labels] + rng.normal(0, 1, (len(labels), 48))
    held_labels = np.repeat(np.arange(8), 60)
    held = centres[held_labels] + rng.normal(0, 1.5, (len(held_labels), 48))
    logits = np.zeros((len(held), 8))  # a head that cannot tell
    held_windows = EncodedWindows(np.zeros((len(held), 4)), held, held, logits, np.zeros((len(held), 2)))
    plain = fit_perception(windows(train), labels, labels % 2, held_windows)
    tempered = fit_perception(windows(train), labels, labels % 2, held_windows, held_out_emotions=held_labels)
    assert plain.temperature == 1.0 and tempered.temperature > 1.5
    inside = tempered.emotion.nearest(held) <= tempered.emotion.threshold
    before, after = plain.read(held, logits)[inside], tempered.read(held, logits)[inside]
    assert (before.argmax(1) == after.argmax(1)).all()
    right = (after.argmax(1) == held_labels[inside]).mean()
    assert abs(np.exp(after.max(1)).mean() - right) < 0.05 < np.exp(before.max(1)).mean() - right
    # stored with the calibration; a calibration from before the temperature reads as 1
    record, tensors = tempered.to_state()
    assert EmotionPerception.from_state(record, tensors).temperature == tempered.temperature
    del record["temperature"]
    assert EmotionPerception.from_state(record, tensors).temperature == 1.0


def test_round_trip_and_refusals():
    p, train, held = fitted(10)
    record, tensors = p.to_state()
    assert not any(isinstance(v, list) and len(v) > 8 for r in (record["emotion"], record["voice"]) for v in r.values())
    assert {k.split(".", 1)[0] for k in tensors} == {"emotion_perception"}
    # a file written when the arrays were kept in the JSON reads the same
    old = {**record, **{part: {**record[part], **{k: tensors[f"emotion_perception.{part}.{k}"].tolist()
                                                  for k in ("means", "axes", "variances")}}
                        for part in ("emotion", "voice")}}
    assert np.array_equal(EmotionPerception.from_state(old, {}).emotion.axes, p.emotion.axes)
    q = EmotionPerception.from_state(*p.to_state())
    assert np.allclose(q.trust(held, held + 1.0), p.trust(held, held + 1.0))
    assert q.voice.threshold == p.voice.threshold
    labels = np.repeat(np.arange(8), 10)
    with pytest.raises(EmogestureError, match="neutral"):
        fit_perception(windows(train[labels > 0]), labels[labels > 0], labels[labels > 0] % 2, windows(train))


def test_calibration_refuses_a_split_the_model_trained_on(tmp_path):
    from emogesture.checkpoints import save_model
    from emogesture.config import to_dict
    from emogesture.data.prepare import PrepareConfig
    from emogesture.errors import InputFileError
    from emogesture.models.speech import SpeechDisentangler, SpeechModelConfig
    from emogesture.train.perception import calibrate_perception_run

    cfg = SpeechModelConfig.preset("tiny", num_speakers=2)
    save_model(tmp_path / "speech", "speech", SpeechDisentangler(cfg), cfg, {
        "emotions": list(EMOTIONS), "speakers": [1, 2], "fbank_mean": -9.0, "fbank_std": 5.0,
        "prepare_config": to_dict(PrepareConfig()), "train_splits": ["train", "val"], "step": 0})
    with pytest.raises(InputFileError, match="trained on the val split"):
        calibrate_perception_run(tmp_path / "speech", tmp_path / "no_cache", tmp_path / "out")
    with pytest.raises(EmogestureError, match="test split"):
        calibrate_perception_run(tmp_path / "speech", tmp_path / "no_cache", tmp_path / "out", split="test")
    assert not (tmp_path / "out").exists()


def test_real_voices_emotions_get_their_own_means_beside_the_corpus():
    train, labels = clusters(60, 0)
    held, _ = clusters(20, 1)
    offset = np.random.default_rng(5).normal(0, 4, 48)  # what sets a real voice apart, whatever its emotion
    real, real_labels = clusters(20, 2, shift=offset)
    plain = fit_perception(windows(train), labels, labels % 2, windows(held))
    both = fit_perception(windows(train), labels, labels % 2, windows(held), real=windows(real),
                          real_emotions=real_labels)
    assert both.labels == list(EMOTIONS) * 2 and both.info["real_windows"] == len(real_labels)
    assert np.allclose(both.neutral(), train[labels == 0].mean(0))  # auto still blends toward the corpus's neutral
    other, other_labels = clusters(10, 3, shift=offset)  # another real voice of the same kind
    flat = np.zeros((len(other), 8))
    assert (plain.emotion.nearest(other) > plain.emotion.threshold).mean() > 0.9
    assert (both.emotion.nearest(other) <= both.emotion.threshold).mean() > 0.9
    assert (both.read(other, flat).argmax(1) == other_labels).mean() > 0.9
    # each emotion's probability sums its two means; the corpus's windows are read as before
    lp = both.emotion.log_posteriors(other[:3])
    summed = both.summed(other[:3], flat[:3])
    assert np.allclose(summed[:, 2], log_softmax(flat[:3])[:, 2] + np.logaddexp(lp[:, 2], lp[:, 10]))
    inside = held[plain.emotion.nearest(held) <= plain.emotion.threshold][:20]
    assert (both.read(inside, np.zeros((len(inside), 8))).argmax(1)
            == plain.read(inside, np.zeros((len(inside), 8))).argmax(1)).mean() >= 0.95
    q = EmotionPerception.from_state(*both.to_state())
    assert np.allclose(q.read(other, flat), both.read(other, flat))


def test_telephone_band_means_change_what_is_heard_and_nothing_else():
    train, labels = clusters(60, 0)
    held, _ = clusters(20, 1)
    offset = np.random.default_rng(6).normal(0, 4, 48)  # what the band does to every window
    band, band_labels = clusters(20, 2, shift=offset)
    plain = fit_perception(windows(train), labels, labels % 2, windows(held))
    both = fit_perception(windows(train), labels, labels % 2, windows(held), band=windows(band),
                          band_emotions=band_labels)
    assert both.labels == plain.labels and both.band_labels == list(EMOTIONS)
    assert both.info["band_windows"] == len(band_labels) and both.emotion.threshold == plain.emotion.threshold
    heard, heard_labels = clusters(10, 3, shift=offset)  # other windows through the same band
    flat = np.zeros((len(heard), 8))
    assert (plain.read(heard, flat).argmax(1) == heard_labels).mean() < 0.5
    assert (both.read(heard, flat).argmax(1) == heard_labels).mean() > 0.9
    # the trust, the latents auto animates and the real-voice posterior are the corpus's alone
    assert np.array_equal(both.trust(heard, heard), plain.trust(heard, heard))
    assert np.array_equal(both.in_corpus_frame(heard), heard) and both.real_voices_posterior(heard) is None
    assert np.allclose(auto_emotion(heard, heard, both), auto_emotion(heard, heard, plain))
    inside = held[plain.emotion.nearest(held) <= plain.emotion.threshold][:20]
    assert (both.read(inside, np.zeros((len(inside), 8))).argmax(1)
            == plain.read(inside, np.zeros((len(inside), 8))).argmax(1)).mean() >= 0.95
    q = EmotionPerception.from_state(*both.to_state())
    assert np.allclose(q.read(heard, flat), both.read(heard, flat))
    assert EmotionPerception.from_state(*plain.to_state()).band_means is None
    broken, tensors = both.to_state()
    broken["band_labels"] = broken["band_labels"][:-1]
    with pytest.raises(EmogestureError, match="7 condition labels for condition means of shape"):
        EmotionPerception.from_state(broken, tensors)


def test_real_voice_latents_and_the_calibrations_refusal_of_an_unknown_voice(tmp_path, monkeypatch):
    from emogesture.assets import bundled_model_file
    from emogesture.data import real_speech
    from emogesture.train.perception import calibrate_perception_run, real_voice_latents
    from emogesture.pipeline.speech import SpeechLatentEncoder

    t = np.arange(20 * 16000) / 16000
    hum = (0.1 * (np.sin(2 * np.pi * 3 * t) > -0.3) * np.sin(2 * np.pi * 150 * t)).astype(np.float32)
    monkeypatch.setattr(real_speech, "load_voice", lambda voice: hum)
    encoder = SpeechLatentEncoder.from_run(bundled_model_file("speech"))
    latents, emotions = real_voice_latents(encoder, ["fr_june"], 1, 1.5)
    assert emotions.tolist() == list(range(8)) and latents.emotion.shape == (8, encoder.loaded.config.latent_dim)
    assert latents.emotion_logits.shape == (8, 8) and np.isfinite(latents.emotion).all()
    assert len({tuple(np.round(z, 4)) for z in latents.emotion}) == 8  # each emotion's prosody heard differently
    with pytest.raises(EmogestureError, match="real voice 'es_allison': unknown; known: fr_june"):
        calibrate_perception_run(bundled_model_file("speech"), tmp_path / "no_cache", tmp_path / "out",
                                 real_voices=["es_allison"])
    with pytest.raises(EmogestureError, match="condition 'loud': unknown; known: telephone, quieter, noisy"):
        calibrate_perception_run(bundled_model_file("speech"), tmp_path / "no_cache", tmp_path / "out",
                                 condition_means=["telephone", "loud"])
    assert not (tmp_path / "out").exists()


def test_condition_latents_hear_every_take_of_the_split_through_each_condition(tmp_path):
    import soundfile as sf

    from emogesture.assets import bundled_model_file
    from emogesture.train.perception import CONDITIONS, condition_latents
    from emogesture.pipeline.speech import SpeechLatentEncoder

    t = np.arange(20 * 16000) / 16000
    hum = (0.1 * (np.sin(2 * np.pi * 3 * t) > -0.3) * np.sin(2 * np.pi * 150 * t)).astype(np.float32)
    (tmp_path / "wave16k").mkdir()
    sf.write(tmp_path / "wave16k" / "a.wav", hum, 16000)
    sf.write(tmp_path / "wave16k" / "b.wav", hum[: 12 * 16000], 16000)

    class Split:
        def take_emotions(self):
            return {"a": 3, "b": 0}

    class Cache:
        manifest = {"root": str(tmp_path)}

        def split(self, name):
            assert name == "train"
            return Split()

    encoder = SpeechLatentEncoder.from_run(bundled_model_file("speech"))
    clean = encoder.encode(hum, parts=("emotion",), hop_seconds=8.0)[0]
    n = len(clean.emotion)
    heard = {}
    for condition in CONDITIONS:
        band, emotions = condition_latents(encoder, Cache(), (condition,))
        assert emotions.tolist() == [3] * n + [0] * (len(emotions) - n) and len(emotions) > n
        assert band.emotion.shape == (len(emotions), encoder.loaded.config.latent_dim)
        assert np.isfinite(band.emotion).all()
        assert not np.allclose(band.emotion[:n], clean.emotion, atol=1e-3)  # heard so, not as recorded
        heard[condition] = band.emotion
    both, emotions = condition_latents(encoder, Cache(), ("telephone", "noisy"))  # one after the other
    assert len(emotions) == 2 * len(heard["telephone"])
    np.testing.assert_allclose(both.emotion[: len(heard["telephone"])], heard["telephone"], atol=1e-6)
    again, _ = condition_latents(encoder, Cache(), ("quieter",))  # the levels drawn from the seed
    np.testing.assert_array_equal(again.emotion, heard["quieter"])


def test_auto_moves_a_real_voice_into_the_corpus_frame_of_the_emotion_heard():
    train, labels = clusters(60, 0)
    held, _ = clusters(20, 1)
    offset = np.random.default_rng(5).normal(0, 4, 48)
    real, real_labels = clusters(20, 2, shift=offset)
    both = fit_perception(windows(train), labels, labels % 2, windows(held), real=windows(real),
                          real_emotions=real_labels)
    plain = fit_perception(windows(train), labels, labels % 2, windows(held))
    other, other_labels = clusters(10, 3, shift=offset)
    moved = both.in_corpus_frame(other)
    corpus_means = both.emotion.means[:8]
    assert (np.linalg.norm(moved - corpus_means[other_labels], axis=1)
            < 0.5 * np.linalg.norm(other - corpus_means[other_labels], axis=1)).all()
    assert (both.emotion.distances(moved)[:, :8].argmin(1) == other_labels).mean() > 0.9
    assert np.allclose(both.in_corpus_frame(held), held, atol=1e-3)  # the corpus's own windows stay
    assert np.allclose(plain.in_corpus_frame(other), other)  # no real voices' means: nothing moves
    # auto animates what it hears: the real window, trusted for its voice, gets the corpus's latent of its emotion
    style = held[:len(other)]
    trusted = both.trust(other, style) == 1.0
    assert trusted.mean() > 0.9
    assert np.allclose(auto_emotion(other.astype(np.float32), style, both)[trusted], moved[trusted], atol=1e-4)
    # generate's message and report say so; the corpus's own windows do not
    heard = perceive(windows(other, style), list(range(len(other))), both, "real.wav")
    assert (heard.real_voices > 0.5).mean() > 0.9 and "sound more like the real voices" in " ".join(heard.details("auto"))
    assert '"real_voices"' in heard.to_json()
    familiar = perceive(windows(held, held), list(range(len(held))), both, "corpus.wav")
    assert (familiar.real_voices < 0.5).mean() > 0.95
    assert "sound more like the real voices" not in " ".join(perceive(windows(held[:5], held[:5]), list(range(5)),
                                                                      both, "corpus.wav").details("auto"))
    assert perceive(windows(other, style), list(range(len(other))), plain, "real.wav").real_voices is None


def test_the_summary_is_one_short_line_whatever_the_names():
    """generate's line per recording stays within 160 characters with long file names, a neutral reference, a
    dozen windows and every blend; the details name the reference's full path."""
    from emogesture.pipeline.perception_report import PerceivedEmotion

    n = 12
    name = "/some/very/long/folder/name/" + "an interview of somebody, recorded badly" * 3 + ".wav"
    heard = PerceivedEmotion(name, [7.0 * i for i in range(n)], ["surprise"] * n, np.full((n, 8), 0.125),
                             np.full((n, 2), 2.0), np.zeros(n), noise_suppressed=0.5, digital_silence_s=3.0,
                             neutral_reference=name.replace(".wav", " calm.wav") + " 10.475-20.475 s")
    for mode in ("auto", "own"):
        line = heard.summary(mode)
        assert len(line) <= 160 and "\n" not in line, line
        assert "…" in line and line.count("surprise") == 1 and "10.475-20.475 s" in line
    assert "auto: 12 toward neutral, 12 fallback style" in heard.summary("auto")
    assert any(heard.neutral_reference in d for d in heard.details("auto")) and len(heard.details("auto")) == 5
