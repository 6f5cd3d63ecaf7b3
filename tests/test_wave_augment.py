"""Waveform augmentation: seeded, length-keeping, and each transform does what it says."""

import numpy as np
import pytest
import torch

from emogesture.audio.wave_augment import (
    TRANSFORMS,
    WaveAugmentConfig,
    add_noise,
    augment_waveform,
    codec_roundtrip,
    telephone,
    time_stretch,
    voice_shift,
)

SR = 16000


def _f0(x):
    """Pitch of a steady tone by the autocorrelation's first peak (Hz)."""
    ac = np.correlate(x[4000:8000], x[4000:8000], "full")[3999:]
    k = SR // 500 + int(np.argmax(ac[SR // 500: SR // 60]))
    return SR / k


def _voice(seconds=2.0, f0=150.0):
    """A vowel-like buzz: harmonics of f0 shaped by formants near 700 and 1200 Hz, pulsed into syllables."""
    t = np.arange(int(seconds * SR)) / SR
    x = sum(np.sin(2 * np.pi * k * f0 * t) * (np.exp(-((k * f0 - 700) / 200) ** 2) + np.exp(-((k * f0 - 1200) / 250) ** 2))
            for k in range(1, 30))
    return (0.3 * x / np.abs(x).max() * (0.5 + 0.5 * np.sin(2 * np.pi * 3 * t) ** 2)).astype(np.float64)


def test_time_stretch_keeps_the_pitch_and_changes_the_length():
    x = _voice()
    fast = time_stretch(x, 1.25)
    assert len(fast) == pytest.approx(len(x) / 1.25, abs=2)
    assert _f0(fast) == pytest.approx(_f0(x), rel=0.03)


def test_voice_shift_moves_the_pitch_and_keeps_the_length():
    x = _voice()
    up = voice_shift(x, 3.0)
    assert len(up) == len(x)
    assert _f0(up) / _f0(x) == pytest.approx(2 ** (3 / 12), rel=0.03)


def test_noise_is_added_at_the_asked_snr_and_telephone_cuts_the_band():
    x = _voice()
    rng = np.random.default_rng(0)
    for kind in ("white", "pink", "speech"):
        noisy = add_noise(x, rng, 10.0, kind)
        snr = 10 * np.log10(np.mean(x ** 2) / np.mean((noisy - x) ** 2))
        assert snr == pytest.approx(10.0, abs=0.01)
    wide = x + 0.1 * np.sin(2 * np.pi * 6000 * np.arange(len(x)) / SR)
    spec = np.abs(np.fft.rfft(telephone(wide)))
    f = np.fft.rfftfreq(len(x), 1 / SR)
    assert spec[(f > 5500) & (f < 6500)].max() < 0.01 * spec[(f > 500) & (f < 1500)].max()


def test_codec_roundtrip_keeps_the_speech():
    x = _voice(1.0)
    y = codec_roundtrip(x, "mp3", 16)
    assert len(y) == len(x)
    assert np.corrcoef(np.abs(np.fft.rfft(x)), np.abs(np.fft.rfft(y)))[0, 1] > 0.9


def test_the_seed_decides_and_every_transform_can_apply():
    x = _voice()
    a, how_a = augment_waveform(x, np.random.default_rng(7))
    b, how_b = augment_waveform(x, np.random.default_rng(7))
    assert how_a == how_b and np.array_equal(a, b) and len(a) == len(x) and a.dtype == np.float32
    c, _ = augment_waveform(x, np.random.default_rng(8))
    assert not np.array_equal(a, c)
    all_on = WaveAugmentConfig(**{name: 1.0 for name in TRANSFORMS})
    y, how = augment_waveform(x, np.random.default_rng(1), all_on)
    assert len(how) == len(TRANSFORMS) and np.abs(y).max() <= 0.99 and np.isfinite(y).all()
    none, how = augment_waveform(x, np.random.default_rng(1), WaveAugmentConfig(**{name: 0.0 for name in TRANSFORMS}))
    assert how == [] and np.allclose(none, x, atol=1e-6)
    with pytest.raises(ValueError, match="probability"):
        augment_waveform(x, np.random.default_rng(1), WaveAugmentConfig(noise=1.5))


def test_the_pitch_alone_moves_only_when_asked_and_leaves_the_other_draws_alone():
    """``pitch``: the pitch moved alone (formants and length kept); at 0 (the default) nothing is drawn for it,
    so every earlier configuration augments as before."""
    from emogesture.audio.intonation import f0_track

    x = _voice(3.0, 150.0)
    off = {name: 0.0 for name in TRANSFORMS}
    y, how = augment_waveform(x, np.random.default_rng(3), WaveAugmentConfig(**off, pitch=1.0, pitch_semitones=3.0))
    assert len(how) == 1 and how[0].startswith("pitch") and len(y) == len(x)
    moved = 12 * np.log2(np.nanmedian(f0_track(y.astype(np.float64))) / np.nanmedian(f0_track(x)))
    assert moved == pytest.approx(float(how[0].split()[1]), abs=0.3) and abs(moved) > 0.1
    a, how_a = augment_waveform(x, np.random.default_rng(5))
    b, how_b = augment_waveform(x, np.random.default_rng(5), WaveAugmentConfig(pitch=0.0, pitch_semitones=6.0))
    assert how_a == how_b and np.array_equal(a, b)
    with pytest.raises(ValueError, match="pitch"):
        augment_waveform(x, np.random.default_rng(1), WaveAugmentConfig(pitch=2.0))


def test_training_windows_heard_through_augmented_conditions(tmp_path):
    """The augmenter re-cuts the cache's own windows from the waveforms (nothing applied: the same window),
    and the quadruple dataset hands the encoders augmented windows with the clean ones as the target."""
    from emogesture.data.cache import open_cache
    from emogesture.data.datasets import SpeechQuadrupleDataset, WaveWindowAugmenter
    from emogesture.data.prepare import prepare

    from helpers import make_root

    make_root(tmp_path / "root", speakers=(1, 2), takes=(1, 3))
    prepare(tmp_path / "root", tmp_path / "cache", progress=False)
    cache = open_cache(tmp_path / "cache")
    train = cache.split("train")
    off = WaveWindowAugmenter(cache, train, WaveAugmentConfig(**{name: 0.0 for name in TRANSFORMS}))
    for j in (0, len(train) - 1):
        again = off(j, np.random.default_rng(0))
        assert again.shape == train.fbank[j].shape
        assert np.abs(again - np.asarray(train.fbank[j], np.float32)).max() < 0.02  # float16 in the cache
    on = WaveWindowAugmenter(cache, train, WaveAugmentConfig(noise=1.0, reverb=1.0))
    data = SpeechQuadrupleDataset(train, [1, 2], 4, seed=3, augmenter=on, augment_share=1.0)
    a, b = data[0], data[0]
    assert torch.equal(a["inputs"], b["inputs"])  # the seed decides
    assert not torch.allclose(a["inputs"], a["fbank"], atol=0.05)
    plain = SpeechQuadrupleDataset(train, [1, 2], 4, seed=3)[0]
    assert torch.equal(plain["fbank"], a["fbank"]) and "inputs" not in plain  # the same quadruple, clean target
    with pytest.raises(ValueError, match="augment_share"):
        SpeechQuadrupleDataset(train, [1, 2], 4, augmenter=on, augment_share=1.5)


def test_level_jitter_hears_each_window_as_if_recorded_at_another_gain(tmp_path):
    """``level_jitter_db``: each window's input is its fbank as the waveform played at a gain within ±L dB would
    give it (the same shift in every bin), drawn per window from the item's generator; off, nothing changes."""
    from emogesture.data.cache import open_cache
    from emogesture.data.datasets import SpeechQuadrupleDataset, WaveWindowAugmenter
    from emogesture.data.prepare import prepare

    from helpers import make_root

    make_root(tmp_path / "root", speakers=(1, 2), takes=(1, 3))
    prepare(tmp_path / "root", tmp_path / "cache", progress=False)
    cache = open_cache(tmp_path / "cache")
    train = cache.split("train")
    data = SpeechQuadrupleDataset(train, [1, 2], 8, seed=3, level_jitter_db=12.0, fbank_std=cache.stats["fbank_std"])
    plain = SpeechQuadrupleDataset(train, [1, 2], 8, seed=3)
    off = WaveWindowAugmenter(cache, train, WaveAugmentConfig(**{name: 0.0 for name in TRANSFORMS}))
    gains = []
    for i in range(8):
        item = data[i]
        assert torch.equal(item["fbank"], plain[i]["fbank"])  # the same quadruple and target
        shift = (item["inputs"] - item["fbank"]).numpy()
        assert np.allclose(shift, shift[:, :1, :1], atol=1e-4)  # one shift per window, in every bin and frame
        gains += list(shift[:, 0, 0] / data.level_step)
    gains = np.array(gains)
    assert np.all(np.abs(gains) <= 12.0 + 1e-3) and gains.std() > 3  # spread over the range
    # the shift is what a gain does to the waveform: window 0 played 8 dB louder
    c = off.fbank_config
    first = int(round(float(train.start_s[0]) * c.sample_rate / c.frame_shift)) * c.frame_shift
    wave = off.waves[train.takes[0]][first: first + off.window_samples]
    louder = off.window_fbank(wave * 10 ** (8 / 20)) - off.window_fbank(wave)
    assert np.median(louder) == pytest.approx(8 * float(data.level_step), rel=0.02)
    assert torch.equal(data[5]["inputs"], data[5]["inputs"])  # the seed decides
    with pytest.raises(ValueError, match="level_jitter_db"):
        SpeechQuadrupleDataset(train, [1, 2], 4, level_jitter_db=6.0)


def test_a_bank_of_augmented_variants_is_made_once_and_the_same_in_any_number_of_processes(tmp_path):
    """The bank holds K seeded augmented variants per window, made alike by one process or two; the dataset
    draws among them, and different variants of a window differ."""
    from emogesture.data.cache import open_cache
    from emogesture.data.datasets import AugmentedWindowBank, SpeechQuadrupleDataset, WaveWindowAugmenter, \
        VARIANT_STREAM
    from emogesture.data.prepare import prepare

    from helpers import make_root

    make_root(tmp_path / "root", speakers=(1, 2), takes=(1, 3))
    prepare(tmp_path / "root", tmp_path / "cache", progress=False)
    cache = open_cache(tmp_path / "cache")
    train = cache.split("train")
    augmenter = WaveWindowAugmenter(cache, train, WaveAugmentConfig(noise=1.0, reverb=1.0))
    one = AugmentedWindowBank(augmenter, 3, seed=5, processes=1, progress=False)
    two = AugmentedWindowBank(augmenter, 3, seed=5, processes=2, progress=False)
    assert one.fbank.shape == (len(train), 3, *train.fbank.shape[1:]) and np.array_equal(one.fbank, two.fbank)
    j = len(train) - 1
    expected = augmenter(j, np.random.default_rng([5, VARIANT_STREAM, j, 2])).astype(np.float16)
    assert np.array_equal(one.fbank[j, 2], expected)  # variant v of window j: its own seeded draws
    assert not np.allclose(one.fbank[j, 0], one.fbank[j, 1], atol=0.05)
    other = AugmentedWindowBank(augmenter, 3, seed=6, processes=1, progress=False)
    assert not np.array_equal(one.fbank, other.fbank)  # the run's seed decides
    drawn = one(j, np.random.default_rng(0))
    assert drawn.dtype == np.float32 and any(np.array_equal(drawn, one.fbank[j, v]) for v in range(3))
    data = SpeechQuadrupleDataset(train, [1, 2], 4, seed=3, augmenter=one, augment_share=1.0)
    item = data[0]
    assert torch.equal(item["inputs"], data[0]["inputs"])
    assert not torch.allclose(item["inputs"], item["fbank"], atol=0.05)
    with pytest.raises(ValueError, match="variants"):
        AugmentedWindowBank(augmenter, 0, seed=5)


def test_recording_changes_do_what_they_say():
    from emogesture.audio.wave_augment import recording_changes

    t = np.arange(32000) / 16000
    x = 0.3 * np.sin(2 * np.pi * 220 * t) * (1 + 0.5 * np.sin(2 * np.pi * 3 * t))
    changes = recording_changes(np.random.default_rng(1))
    out = {name: np.asarray(change(x)) for name, change in changes.items()}
    rms = lambda y: float(np.sqrt(np.mean(y ** 2)))  # noqa: E731
    assert all(np.all(np.isfinite(y)) for y in out.values())
    assert rms(out["recording level -10 dB"]) == pytest.approx(rms(x) * 10 ** -0.5, rel=1e-6)
    loud = out["recording level +6 dB, clipped"]
    assert np.abs(loud).max() <= 1.0 and rms(loud) > 1.8 * rms(x)
    assert len(out["tempo +15 %"]) == pytest.approx(len(x) / 1.15, rel=0.02)
    assert len(out["tempo -15 %"]) == pytest.approx(len(x) * 1.15, rel=0.02)
    assert rms(out["reverberant room, RT60 0.5 s"]) == pytest.approx(rms(x), rel=0.3)
    assert 5 < 10 * np.log10(rms(x) ** 2 / rms(out["white noise, 10 dB SNR"] - x) ** 2) < 15

