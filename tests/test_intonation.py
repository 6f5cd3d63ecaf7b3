"""Intonation: the pitch track, and TD-PSOLA moving a recording's pitch with its duration kept."""

import numpy as np
import pytest

from emogesture.audio.intonation import f0_track, intonation_span, reshape_pitch

SR = 16000


def _sung(seconds=3.0, centre=140.0, swing_st=2.0, rate_hz=0.7):
    """A vowel-like voice whose pitch glides ``swing_st`` semitones either side of ``centre`` (a pulse train
    through two formant resonances), in syllables with short pauses."""
    n = int(seconds * SR)
    t = np.arange(n) / SR
    f0 = centre * 2 ** (swing_st * np.sin(2 * np.pi * rate_hz * t) / 12)
    phase = np.cumsum(f0) / SR
    pulses = np.diff(np.floor(phase), prepend=0.0)
    from scipy.signal import lfilter

    x = pulses
    for freq, bw in ((700, 130), (1200, 150)):
        r = np.exp(-np.pi * bw / SR)
        x = lfilter([1 - r], [1, -2 * r * np.cos(2 * np.pi * freq / SR), r * r], x)
    gate = (np.sin(2 * np.pi * 2.5 * t) > -0.7).astype(float)
    return (0.3 * x / np.abs(x).max() * gate), f0


def test_the_pitch_track_follows_a_gliding_voice_and_skips_silence():
    x, truth = _sung()
    f0 = f0_track(x)
    assert len(f0) == (len(x) - 640) // 160 + 1
    centres = 160 * np.arange(len(f0)) + 320
    voiced = np.isfinite(f0)
    assert voiced.mean() > 0.6
    err = np.abs(12 * np.log2(f0[voiced] / truth[centres[voiced]]))
    assert np.median(err) < 0.3  # semitones
    assert np.isnan(f0_track(np.zeros(SR))).all()
    assert np.isnan(f0_track(np.random.default_rng(0).normal(size=SR) * 0.1)).mean() > 0.9  # noise is unvoiced


def test_reshape_pitch_widens_narrows_and_moves_the_pitch_with_the_duration_kept():
    x, _ = _sung()
    before = intonation_span(x)
    assert 3.0 < before < 4.5  # ±2 semitones: a 10-90 % span of about 3.6
    wide, flat = reshape_pitch(x, span=2.0), reshape_pitch(x, span=0.5)
    assert len(wide) == len(flat) == len(x)
    assert intonation_span(wide) == pytest.approx(2 * before, rel=0.2)
    assert intonation_span(flat) == pytest.approx(0.5 * before, rel=0.3)
    up = reshape_pitch(x, semitones=3.0)
    med = lambda y: np.nanmedian(12 * np.log2(f0_track(y)))  # noqa: E731
    assert med(up) - med(x) == pytest.approx(3.0, abs=0.4)
    assert np.sqrt(np.mean(up ** 2)) == pytest.approx(np.sqrt(np.mean(x ** 2)), rel=0.25)  # no gain or loss
    assert np.array_equal(reshape_pitch(x), x)  # nothing asked, nothing done
    noise = np.random.default_rng(1).normal(size=SR) * 0.1
    assert np.array_equal(reshape_pitch(noise, span=2.0), noise)  # nothing voiced to move
    with pytest.raises(ValueError, match="16000"):
        f0_track(x, 8000)


def test_a_recorded_voice_given_a_prosody_is_raised_faster_and_louder():
    """give_prosody: a recorded voice spoken with anger's cues as the corpus gives them."""
    from emogesture.data.synthetic.factors import EMOTION_FACTORS, Prosody
    from emogesture.data.synthetic.speech import give_prosody

    x, _ = _sung(seconds=4.0)
    rng = np.random.default_rng(0)
    neutral = give_prosody(x, Prosody(), rng)
    angry = give_prosody(x, EMOTION_FACTORS["anger"].prosody, rng)
    faster = EMOTION_FACTORS["anger"].prosody.rate
    assert len(neutral) == len(x) and len(angry) == pytest.approx(len(x) / faster, rel=0.01)
    assert angry.dtype == np.float32
    rise = 12 * np.log2(np.nanmedian(f0_track(angry)) / np.nanmedian(f0_track(neutral)))
    assert rise == pytest.approx(EMOTION_FACTORS["anger"].prosody.pitch, abs=0.3)
    louder = 20 * np.log10(np.abs(angry).max() / np.abs(neutral).max())
    assert louder > 4.0
