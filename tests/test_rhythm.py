"""The rhythm measure (eval.rhythm) and the timing stream (audio.timing): each can tell timing from none."""

import numpy as np
import pytest
import torch

from emogesture.audio.timing import timing_stream
from emogesture.eval import rhythm as R
from emogesture.models.denoiser import DenoiserConfig
from emogesture.errors import ConfigError

W, T = 40, 300


def impulses(rng, n=W, t=T, rate=0.06):
    return (rng.random((n, t)) < rate).astype(float)


def stroke_speed(events, delay=0):
    """A motion whose speed bumps a little after each event (a Gaussian of 3 frames), plus noise."""
    out = R.smooth(np.roll(events, delay, axis=1), sigma_s=0.1)
    return out + 0.02 * np.random.default_rng(5).random(out.shape)


def mismatches(audio, seed=0):
    texts = np.arange(len(audio))
    out = {f"other {d}": audio[idx] for d, idx in enumerate(R.other_window_pairs(texts, seed, 4))}
    out.update({f"roll {s}": np.roll(audio, s, axis=1) for s in (30, 45, 60, 75)})
    return out


def test_motion_that_follows_the_audio_gains_far_above_its_spread_and_finds_the_lag():
    rng = np.random.default_rng(0)
    audio = impulses(rng)
    r = R.rhythm_gain(stroke_speed(audio, delay=6), audio, mismatches(audio))
    assert r["gain"] > 0.3 and R.discriminates(r)
    assert r["lag_s"] == pytest.approx(6 / 30, abs=1.5 / 30)


def test_motion_blind_to_the_audio_stays_within_noise_and_a_still_pose_scores_zero():
    rng = np.random.default_rng(1)
    audio = impulses(rng)
    blind = R.rhythm_gain(stroke_speed(impulses(rng)), audio, mismatches(audio))
    assert R.within_noise(blind) and not R.discriminates(blind)
    still = R.rhythm_gain(np.zeros((W, T)), audio, mismatches(audio))
    assert still["score"] == still["gain"] == 0.0 and R.within_noise(still)


def test_the_measure_depends_on_which_audio_goes_with_which_window():
    rng = np.random.default_rng(2)
    audio = impulses(rng)
    speed = stroke_speed(audio)
    own = R.rhythm_gain(speed, audio, mismatches(audio))["score"]
    swapped = R.rhythm_gain(speed, audio[::-1], mismatches(audio))["score"]
    assert own > 0.5 and abs(swapped) < 0.15


def test_arm_speed_envelope_and_window_helpers():
    joints = np.zeros((2, 40, 55, 3))
    joints[:, :, 20, 0] = np.arange(40) / 30.0  # the left wrist moves at 1 m/s
    assert R.arm_speed(joints, position_smooth_s=0) == pytest.approx(np.full((2, 40), 1 / 6))
    assert R.arm_speed(joints)[:, 10:30] == pytest.approx(np.full((2, 20), 1 / 6))  # the low-pass keeps steady motion
    # frame-to-frame jitter is not a gesture: the low-pass removes nearly all of its speed, a 0.4-s stroke keeps most
    t = np.arange(90)
    jitter, stroke = np.zeros((90, 55, 3)), np.zeros((90, 55, 3))
    jitter[:, 20, 0] = 0.01 * np.random.default_rng(0).normal(size=90)
    stroke[:, 20, 0] = 0.1 * np.exp(-0.5 * ((t - 45) / 6) ** 2)
    assert R.arm_speed(jitter).mean() < 0.25 * R.arm_speed(jitter, position_smooth_s=0).mean()
    assert R.arm_speed(stroke).max() > 0.8 * R.arm_speed(stroke, position_smooth_s=0).max()
    env = R.envelope_at_frames(np.arange(4.0), 16000, 3, fps=30, hop_length=512)  # values at 32-ms hops
    assert env == pytest.approx([0, 1 / 30 / 0.032, 2 / 30 / 0.032])
    takes, starts = R.consecutive_windows({"a": 650, "b": 299}, 300)
    assert takes == ["a", "a"] and starts == [0, 300]
    cut = R.cut_windows({"a": np.arange(650.0)}, ["a"], [300], 300, shift_frames=100)  # past the end: earlier
    assert cut[0, 0] == 200
    pairs = R.other_window_pairs([0, 0, 1, 1], seed=3, draws=2)
    assert all((np.array([0, 0, 1, 1])[p] != np.array([0, 0, 1, 1])).all() for p in pairs)
    assert [p.tolist() for p in pairs] == [p.tolist() for p in R.other_window_pairs([0, 0, 1, 1], seed=3, draws=2)]
    with pytest.raises(ValueError):
        R.rhythm_gain(np.zeros((2, 300)), np.zeros((2, 300)), {"one": np.zeros((2, 300))})


def test_timing_stream_marks_an_onset_in_its_motion_frame_and_is_silent_on_silence():
    fbank = np.full((2, 1024, 128), -1.0, np.float32)
    fbank[0, 500:] = 1.0  # a step up at fbank frame 500 = 5.0 s = motion frame 150
    stream = timing_stream(fbank)
    assert stream.shape == (2, 300, 2) and stream.dtype == np.float32
    assert int(np.argmax(stream[0, :, 1])) == 150
    assert stream[0].mean(0) == pytest.approx([0, 0], abs=1e-5) and stream[0].std(0) == pytest.approx([1, 1], rel=1e-2)
    assert not stream[1].any()  # a window without change carries no timing


def test_timing_stream_repeats_the_last_real_frame_past_the_audio():
    level = -1.0 + 0.5 * np.sin(2 * np.pi * np.arange(1024) / 37.0)  # syllables every 0.37 s
    fbank = np.broadcast_to(level[None, :, None], (3, 1024, 128)).astype(np.float32).copy()
    fbank[:, 998:] = 0.0  # a window aligned to end with its audio: zeros past the fbank's last frame
    padded = timing_stream(fbank)
    assert padded[0, -1, 1] > 2 * padded[0, :-1, 1].max()  # the zeros read as the window's strongest onset
    stream = timing_stream(fbank, lengths=[998, 998, 1024])
    assert np.abs(stream[0, -1]).max() < 2.5 and stream[0, -1, 1] < stream[0, :-1, 1].max()
    edge = fbank.copy()
    edge[0, 998:] = edge[0, 997]
    np.testing.assert_allclose(stream[0], timing_stream(edge[:1])[0], atol=1e-5)
    np.testing.assert_array_equal(stream[2], padded[2])  # a window of real frames is unchanged
    assert not timing_stream(fbank[:1], lengths=[0]).any()  # no real frame: silence
    with pytest.raises(ValueError, match="lengths"):
        timing_stream(fbank, lengths=[998])


def test_a_decoder_that_reads_timing_starts_as_the_plain_one_and_checks_its_stream():
    from emogesture.models.gesture import GestureModelConfig
    from emogesture.models.motion_vae import MotionVAE, MotionVAEConfig

    cfg = MotionVAEConfig.preset("tiny", frames=60)
    cfg.timing_features = 2
    vae = MotionVAE(cfg).eval()
    z = torch.randn(2, 256)
    stream = torch.randn(2, 60, 2)
    with torch.no_grad():
        start = vae.decode(z, timing=stream)
        vae.timing_to_query.weight.normal_()
        moved = vae.decode(z, timing=stream)
    assert start.shape == (2, 60, 282) and not torch.allclose(start, moved)  # zero at first, then it counts
    with pytest.raises(ValueError, match="timing stream"):
        vae.decode(z)
    gm = GestureModelConfig.preset("tiny")
    gm.vae.timing_features = 2
    assert gm.hears_timing and gm.timing_features == 2 and gm.denoiser.num_conditions == 3
    with pytest.raises(ConfigError):
        GestureModelConfig(variant="no_prior", vae=cfg, denoiser=DenoiserConfig(width=256, layers=3, heads=2))
