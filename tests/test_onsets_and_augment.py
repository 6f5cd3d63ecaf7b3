"""Spectrogram augmentation, onset detection, frame energy, segment scrambling and long-audio fbank chunks."""

from __future__ import annotations


import numpy as np
import pytest
import torch

from emogesture.audio import (
    augment_fbank,
    detect_onsets,
    frame_energy,
    kaldi_fbank,
    onset_strength,
)

from helpers import speech_like

SR = 16000


def _runs(mask: torch.Tensor) -> list[tuple[int, int]]:
    idx = torch.nonzero(mask).flatten().tolist()
    if not idx:
        return []
    runs, start, prev = [], idx[0], idx[0]
    for i in idx[1:]:
        if i != prev + 1:
            runs.append((start, prev + 1))
            start = i
        prev = i
    runs.append((start, prev + 1))
    return runs


def _bursts(times: list[float], seconds: float = 5.0, freq: float = 1000.0) -> np.ndarray:
    x = np.zeros(int(seconds * SR))
    n = np.arange(int(0.08 * SR))
    burst = np.sin(2 * np.pi * freq * n / SR) * np.exp(-n / (0.015 * SR))
    for t in times:
        i = int(t * SR)
        x[i : i + n.size] += burst
    x += 1e-4 * np.random.default_rng(1).standard_normal(x.size)
    return x.astype(np.float32)


def test_augment_is_deterministic_per_seed() -> None:
    x = torch.randn(3, 1024, 128)
    a = augment_fbank(x, torch.Generator().manual_seed(7))
    b = augment_fbank(x, torch.Generator().manual_seed(7))
    c = augment_fbank(x, torch.Generator().manual_seed(8))
    assert torch.equal(a, b)
    assert not torch.equal(a, c)
    assert not torch.equal(a, x) and a.shape == x.shape
    single = augment_fbank(x[0], torch.Generator().manual_seed(7))
    assert single.shape == (1024, 128)


def test_augment_masks_within_limits() -> None:
    x = torch.ones(32, 300, 64)
    y = augment_fbank(x, torch.Generator().manual_seed(0), noise_std=0.0, max_shift=0)
    widths_f, widths_t = [], []
    for ex in y:
        zero = ex == 0
        freq_runs = _runs(zero.all(0))
        time_runs = _runs(zero.all(1))
        assert len(freq_runs) <= 1 and len(time_runs) <= 1
        wf = freq_runs[0][1] - freq_runs[0][0] if freq_runs else 0
        wt = time_runs[0][1] - time_runs[0][0] if time_runs else 0
        widths_f.append(wf)
        widths_t.append(wt)
        # Every zero lies in the masked band or the masked span.
        expected = torch.zeros_like(zero)
        for lo, hi in freq_runs:
            expected[:, lo:hi] = True
        for lo, hi in time_runs:
            expected[lo:hi, :] = True
        assert torch.equal(zero, expected)
    assert max(widths_f) <= 24 and max(widths_t) <= 96
    assert max(widths_f) > 12 and max(widths_t) > 48  # the masks are really drawn over their range


def test_augment_shift_and_noise() -> None:
    x = torch.randn(4, 200, 16)
    shifted = augment_fbank(x, torch.Generator().manual_seed(3), freq_mask=0, time_mask=0, noise_std=0.0,
                            max_shift=10)
    for a, b in zip(shifted, x):
        matches = [s for s in range(-10, 11) if torch.equal(a, torch.roll(b, s, 0))]
        assert matches
    noisy = augment_fbank(x, torch.Generator().manual_seed(3), freq_mask=0, time_mask=0, noise_std=0.1,
                          max_shift=0)
    assert float((noisy - x).std()) == pytest.approx(0.1, rel=0.05)
    off = augment_fbank(x, torch.Generator().manual_seed(3), freq_mask=0, time_mask=0, noise_std=0.0, max_shift=0)
    assert torch.equal(off, x)


@pytest.mark.parametrize("kind", ["tone", "click"])
def test_onsets_at_known_times(kind: str) -> None:
    truth = [0.5, 1.3, 2.2, 3.05, 4.1]
    if kind == "tone":
        x = _bursts(truth)
    else:
        x = np.zeros(5 * SR, np.float32)
        for t in truth:
            x[int(t * SR)] = 1.0
    onsets = detect_onsets(x)
    hop = 512 / SR
    for t in truth:
        assert np.min(np.abs(onsets - t)) <= hop + 1e-9, (kind, t, onsets)
    # Nothing away from the events (librosa's picker at 16 kHz / hop 512 may mark two adjacent frames).
    for o in onsets:
        assert min(abs(o - t) for t in truth) <= 3 * hop, (kind, o, onsets)


def test_no_onsets_on_steady_tone_or_silence() -> None:
    t = np.arange(5 * SR) / SR
    tone = 0.5 * np.sin(2 * np.pi * 440 * t)
    onsets = detect_onsets(tone)
    # The tone starts at t=0 (the zero-padded first frames see it switch on); nothing after that.
    assert np.all(onsets < 0.2), onsets
    assert detect_onsets(np.zeros(3 * SR)).size == 0


def test_onset_strength_shape() -> None:
    x = _bursts([1.0, 2.0], seconds=3.0)
    env = onset_strength(x)
    assert env.shape == (1 + x.size // 512,) and env.dtype == np.float32
    assert (env >= 0).all()
    assert abs(int(env.argmax()) * 512 / SR - 1.0) <= 0.1 or abs(int(env.argmax()) * 512 / SR - 2.0) <= 0.1


def test_frame_energy() -> None:
    x = np.concatenate([np.zeros(SR), 0.5 * np.sin(2 * np.pi * 300 * np.arange(SR) / SR)]).astype(np.float32)
    e = frame_energy(x, SR, fps=30)
    assert e.shape == (60,) and e.dtype == np.float32
    assert np.allclose(e[:29], 0.0)
    assert np.allclose(e[31:], 0.5 / np.sqrt(2), rtol=0.02)
    assert frame_energy(x[: int(1.01 * SR)], SR).shape == (round(1.01 * 30),)


def test_scramble_segments_permutes_whole_segments() -> None:
    from emogesture.audio import scramble_segments

    x = torch.arange(2 * 22 * 3, dtype=torch.float32).reshape(2, 22, 3)
    y = scramble_segments(x, torch.Generator().manual_seed(0), 5)  # 4 segments of 5 frames + 2 frames
    assert y.shape == x.shape
    for b in range(2):
        starts = [int(y[b, 5 * k, 0] - x[b, 0, 0]) // 3 for k in range(4)]
        assert sorted(starts) == [0, 5, 10, 15]  # every segment once, kept whole
        for k, s in enumerate(starts):
            assert torch.equal(y[b, 5 * k : 5 * k + 5], x[b, s : s + 5])
        assert torch.equal(y[b, 20:], x[b, 20:])  # the partial tail stays last
    assert torch.equal(y, scramble_segments(x, torch.Generator().manual_seed(0), 5))  # seeded
    assert not all(torch.equal(scramble_segments(x, torch.Generator().manual_seed(s), 5), y) for s in range(1, 5))
    assert torch.equal(scramble_segments(x, torch.Generator(), 22), x)  # one segment: nothing to move
    with pytest.raises(ValueError, match="segment"):
        scramble_segments(x, torch.Generator(), 0)


def test_window_activity_counts_frames_with_sound():
    from emogesture.audio import window_activity

    sr = 16000
    t = np.arange(20 * sr) / sr
    wave = 0.3 * np.sin(2 * np.pi * 200 * t)
    wave[10 * sr:] = 0.0  # sound for 10 s, then digital silence
    act = window_activity(wave.astype(np.float32), sr, [0.0, 5.0, 10.0])
    assert act == pytest.approx([1.0, 0.5, 0.0], abs=0.01)
    # one length per window: the newest quarter second of each part, and the whole
    each = window_activity(wave.astype(np.float32), sr, [9.75, 19.75, 5.0], window_seconds=[0.25, 0.25, 10.0])
    assert each == pytest.approx([1.0, 0.0, 0.5], abs=0.01)
    quiet = wave * 1e-4  # -90 dBFS: below the absolute floor
    assert window_activity(quiet.astype(np.float32), sr, [0.0]).item() == 0.0


@pytest.mark.parametrize("options", [{}, {"snip_edges": False, "use_energy": True}, {"dither": 1.0}])
def test_long_audio_fbank_in_chunks_equals_the_whole_computation(monkeypatch, options) -> None:
    """Long audio goes through the filterbank in chunks of frames (bounded memory, linear time); every
    frame is computed alone, so the chunks change nothing (the dither's draws included)."""
    import emogesture.audio.fbank as fbank_module

    x = speech_like()
    whole = kaldi_fbank(x, generator=torch.Generator().manual_seed(3), **options)
    monkeypatch.setattr(fbank_module, "FBANK_CHUNK_FRAMES", 7)  # 98 frames: 14 chunks
    chunked = kaldi_fbank(x, generator=torch.Generator().manual_seed(3), **options)
    assert whole.shape == chunked.shape and len(whole) > 7 * 10
    assert torch.equal(whole, chunked)
