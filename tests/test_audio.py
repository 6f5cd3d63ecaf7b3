"""Audio front end: loading, Kaldi fbank (vs kaldi_native_fbank), windows, augmentation, onsets."""

from __future__ import annotations

import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf
import torch

from emogesture.audio import (
    rolled_fbank,
    FBANK_MEAN,
    FBANK_STD,
    FLOAT32_EPS,
    WINDOW_CONTENT_FRAMES,
    WINDOW_FRAMES,
    FbankConfig,
    check_speech,
    denormalise_fbank,
    fbank_window,
    fbank_windows,
    kaldi_fbank,
    kaldi_mel_banks,
    load_audio,
    normalise_fbank,
    num_fbank_frames,
    window_starts,
)
from emogesture.errors import ConfigError, InputFileError

from helpers import speech_like

SR = 16000
HAVE_FFMPEG = shutil.which("ffmpeg") is not None and shutil.which("ffprobe") is not None


# ----------------------------------------------------------------------------------------------------------
# Signals


def knf_fbank(x: np.ndarray, window_type: str, num_bins: int, snip_edges: bool = True) -> np.ndarray:
    knf = pytest.importorskip("kaldi_native_fbank")
    opts = knf.FbankOptions()
    opts.frame_opts.samp_freq = SR
    opts.frame_opts.dither = 0.0
    opts.frame_opts.window_type = window_type
    opts.frame_opts.preemph_coeff = 0.97
    opts.frame_opts.remove_dc_offset = True
    opts.frame_opts.snip_edges = snip_edges
    opts.frame_opts.round_to_power_of_two = True
    opts.mel_opts.num_bins = num_bins
    opts.mel_opts.low_freq = 20.0
    opts.mel_opts.high_freq = 0.0
    opts.use_energy = False
    fb = knf.OnlineFbank(opts)
    fb.accept_waveform(SR, x.tolist())
    fb.input_finished()
    return np.stack([fb.get_frame(i) for i in range(fb.num_frames_ready)])


# ----------------------------------------------------------------------------------------------------------
# Kaldi fbank


# Our 'hann' is Kaldi's symmetric "hanning"; kaldi_native_fbank's "hann" is the periodic variant.
@pytest.mark.parametrize(
    ("ours", "theirs", "snip_edges"),
    [("hamming", "hamming", True), ("hann", "hanning", True), ("hamming", "hamming", False),
     ("povey", "povey", True), ("rectangular", "rectangular", True)],
)
def test_fbank_matches_kaldi_native_fbank(ours: str, theirs: str, snip_edges: bool) -> None:
    x = speech_like()
    ref = knf_fbank(x, theirs, 80, snip_edges)
    got = kaldi_fbank(x, num_mel_bins=80, window=ours, snip_edges=snip_edges).numpy()
    assert got.shape == ref.shape
    diff = float(np.abs(got - ref).max())
    print(f"\nfbank vs kaldi_native_fbank, 80 bins, {ours} (snip_edges={snip_edges}): max |diff| = {diff:.2e}")
    assert diff <= 2e-3, f"max abs diff {diff:.3e} vs kaldi_native_fbank ({ours})"


def test_mel_banks_match_kaldi_native_fbank() -> None:
    knf = pytest.importorskip("kaldi_native_fbank")
    for bins in (23, 40, 80):
        mel_opts = knf.MelBanksOptions(num_bins=bins, low_freq=20.0, high_freq=0.0)
        ref = knf.MelBanks(mel_opts, knf.FrameExtractionOptions()).get_matrix()
        ours = kaldi_mel_banks(bins, 512, 16000.0, 20.0, 0.0)
        assert ours.shape == ref.shape == (bins, 257)
        assert np.abs(ours - ref).max() < 1e-4


def _expected_empty_bins(num_bins: int, n_fft: int = 512, sr: int = SR, low: float = 20.0) -> list[int]:
    """Independently: filter m is empty iff no FFT bin 0..n_fft/2-1 has its HTK mel strictly inside it."""
    mel = lambda f: 1127.0 * math.log(1.0 + f / 700.0)  # noqa: E731
    lo, hi = mel(low), mel(sr / 2)
    delta = (hi - lo) / (num_bins + 1)
    fft_mels = [mel(k * sr / n_fft) for k in range(n_fft // 2)]
    return [m for m in range(num_bins)
            if not any(lo + m * delta < v < lo + (m + 2) * delta for v in fft_mels)]


def test_fbank_128_bins_has_the_expected_empty_bin_at_log_eps() -> None:
    x = speech_like()
    cfg = FbankConfig()
    assert (cfg.num_mel_bins, cfg.window, cfg.sample_rate, cfg.dither) == (128, "hamming", 16000, 0.0)
    fb = kaldi_fbank(x)
    assert fb.shape == (num_fbank_frames(x.size), 128) and fb.dtype == torch.float32
    assert torch.isfinite(fb).all()
    expected = _expected_empty_bins(128)
    assert expected == cfg.empty_bins() == [3], expected
    floor = math.log(FLOAT32_EPS)
    at_floor = [m for m in range(128) if torch.allclose(fb[:, m], torch.tensor(floor, dtype=torch.float32))]
    assert at_floor == expected
    print(f"\n128 bins: empty filter(s) {expected} stay at log(eps) = {floor:.4f}")
    # On broadband input every non-empty filter carries energy.
    noise = np.random.default_rng(2).standard_normal(SR).astype(np.float32) * 0.1
    fb_noise = kaldi_fbank(noise)
    others = [m for m in range(128) if m not in expected]
    assert (fb_noise[:, others].mean(0) > floor + 3).all()
    assert torch.allclose(fb_noise[:, expected], torch.tensor(floor, dtype=torch.float32))


def _htk_expected_bin(freq: float, num_bins: int = 128, low: float = 20.0, high: float = SR / 2) -> int:
    mel = lambda f: 1127.0 * math.log(1.0 + f / 700.0)  # noqa: E731
    delta = (mel(high) - mel(low)) / (num_bins + 1)
    return int(round((mel(freq) - mel(low)) / delta - 1.0))  # filter m is centred at mel_low + (m + 1) delta


@pytest.mark.parametrize("freq", [250.0, 440.0, 1000.0, 2000.0, 3500.0, 5000.0, 7000.0])
def test_pure_tone_lands_in_the_expected_mel_bin(freq: float) -> None:
    t = np.arange(SR) / SR
    x = 0.5 * np.sin(2 * np.pi * freq * t)
    fb = kaldi_fbank(x)
    peak = int(fb.mean(0).argmax())
    expected = _htk_expected_bin(freq)
    # At low frequencies the filters are narrower than the 31.25 Hz FFT bins, so allow the neighbour.
    tolerance = 1 if freq < 1000 else 0
    assert abs(peak - expected) <= tolerance, (freq, peak, expected)


def test_sine_sweep_moves_monotonically_through_the_bins() -> None:
    t = np.arange(4 * SR) / SR
    f_lo, f_hi = 200.0, 7500.0
    k = (f_hi / f_lo) ** (1 / 4.0)
    inst = f_lo * k**t
    x = 0.5 * np.sin(2 * np.pi * f_lo * (k**t - 1) / np.log(k))
    fb = kaldi_fbank(x)
    peaks = fb.argmax(1).numpy()
    centres = inst[200 + 160 * np.arange(len(peaks))]  # frame centre = 160 t + 200 samples
    expected = np.array([_htk_expected_bin(f) for f in centres])
    assert np.all(np.diff(peaks) >= -1)
    assert np.mean(np.abs(peaks - expected) <= 1) > 0.95


def test_a_rolled_filterbank_equals_the_whole_one() -> None:
    """A buffer that moved on by whole frame shifts reuses its frames; the result is the filterbank computed whole
    (every frame is its own), for any shift, and a shift that cannot reuse anything is computed whole."""
    x = speech_like(14.0, seed=3)
    buffer = 16000 * 10
    config = FbankConfig()
    previous = kaldi_fbank(x[:buffer], config)
    for shift in (160, 4000, 4160, 4001, 0, 150000, buffer + 160):
        now = x[shift: shift + buffer] if shift + buffer <= len(x) else x[-buffer:]
        rolled = rolled_fbank(previous, now, shift, config)
        assert rolled.shape == (998, config.num_features)
        assert torch.equal(rolled, kaldi_fbank(now, config)), shift
    assert torch.equal(rolled_fbank(None, x[:buffer], 4000, config), previous)


def test_fbank_input_handling() -> None:
    x = speech_like(1.0)
    a = kaldi_fbank(x)
    b = kaldi_fbank(torch.from_numpy(x.astype(np.float64)))
    assert torch.allclose(a, b, atol=1e-5)
    batch = kaldi_fbank(np.stack([x, x[::-1].copy()]))
    assert batch.shape == (2, *a.shape) and torch.allclose(batch[0], a, atol=1e-5)
    # Not rescaled: an int16-scaled input shifts the log energies by 2 ln 32768.
    noise = np.random.default_rng(3).standard_normal(SR) * 0.1
    live = [m for m in range(128) if m not in FbankConfig().empty_bins()]
    shift = kaldi_fbank(noise * 32768.0)[:, live] - kaldi_fbank(noise)[:, live]
    assert torch.allclose(shift, torch.tensor(2 * math.log(32768.0)), atol=1e-3)
    # Shorter than one frame: no rows, not an error.
    assert kaldi_fbank(np.zeros(399, np.float32)).shape == (0, 128)
    assert kaldi_fbank(np.zeros(400, np.float32)).shape == (1, 128)
    assert num_fbank_frames(160000) == WINDOW_CONTENT_FRAMES == 998
    assert kaldi_fbank(x, use_energy=True).shape == (a.shape[0], 129)
    with pytest.raises(ConfigError):
        kaldi_fbank(x, not_an_option=1)
    with pytest.raises(ConfigError):
        FbankConfig(window="gaussian")
    with pytest.raises(ConfigError):
        FbankConfig(low_freq=9000.0)


# ----------------------------------------------------------------------------------------------------------
# load_audio / check_speech

NATIVE_SR = 44100
DURATION = 1.5


def _tone(sr: int, n: int) -> np.ndarray:
    t = np.arange(n) / sr
    return 0.3 * np.sin(2 * np.pi * 440.0 * t) + 0.2 * np.sin(2 * np.pi * 1000.0 * t)


def _stereo_source(sr: int = NATIVE_SR) -> np.ndarray:
    ref = _tone(sr, int(DURATION * sr))
    return np.stack([ref, 0.5 * ref], axis=1)  # mono mix-down = 0.75 * ref


def _check_loaded(path: Path, native_sr: int, n_native: int, min_corr: float = 0.99, length_tol: int = 1) -> None:
    wave, sr = load_audio(path)
    assert sr == SR and wave.dtype == np.float32 and wave.ndim == 1
    expected_len = math.ceil(n_native * SR / native_sr)
    assert abs(wave.size - expected_len) <= length_tol, (path.name, wave.size, expected_len)
    ref = 0.75 * _tone(SR, expected_len)
    m = min(wave.size, ref.size)
    corr = float(np.corrcoef(wave[:m], ref[:m])[0, 1])
    assert corr > min_corr, (path.name, corr)
    assert abs(float(wave.mean())) < 1e-6
    assert np.std(wave) == pytest.approx(np.std(ref), rel=0.05)


@pytest.mark.parametrize(
    ("suffix", "fmt", "subtype", "sr", "min_corr"),
    [
        (".wav", "WAV", "PCM_16", 44100, 0.999),
        (".wav", "WAV", "PCM_32", 44100, 0.999),
        (".wav", "WAV", "FLOAT", 44100, 0.999),
        (".wav", "WAV", "PCM_16", 48000, 0.999),
        (".wav", "WAV", "FLOAT", 16000, 0.999),
        (".flac", "FLAC", "PCM_16", 44100, 0.999),
        (".flac", "FLAC", "PCM_24", 22050, 0.999),
        (".ogg", "OGG", "VORBIS", 44100, 0.99),
    ],
)
def test_load_audio_formats(tmp_path: Path, suffix: str, fmt: str, subtype: str, sr: int, min_corr: float) -> None:
    data = _stereo_source(sr)
    path = tmp_path / f"tone_{subtype.lower()}_{sr}{suffix}"
    sf.write(path, data, sr, format=fmt, subtype=subtype)
    _check_loaded(path, sr, data.shape[0], min_corr)


def test_load_audio_detects_format_by_content(tmp_path: Path) -> None:
    data = _stereo_source()
    flac_as_wav = tmp_path / "really_flac.wav"
    sf.write(flac_as_wav, data, NATIVE_SR, format="FLAC", subtype="PCM_16")
    _check_loaded(flac_as_wav, NATIVE_SR, data.shape[0])
    wav_as_mp3 = tmp_path / "really_wav.mp3"
    sf.write(wav_as_mp3, data, NATIVE_SR, format="WAV", subtype="FLOAT")
    _check_loaded(wav_as_mp3, NATIVE_SR, data.shape[0])


@pytest.mark.skipif(not HAVE_FFMPEG, reason="needs the ffmpeg binary")
def test_load_audio_mp3_named_wav(tmp_path: Path) -> None:
    data = _stereo_source()
    src = tmp_path / "src.wav"
    sf.write(src, data, NATIVE_SR, subtype="PCM_16")
    mp3 = tmp_path / "speech.wav"  # MP3 data under a .wav name, as in BEAT
    subprocess.run(["ffmpeg", "-nostdin", "-v", "error", "-y", "-i", str(src), "-f", "mp3", str(mp3)], check=True)
    assert mp3.read_bytes()[:3] in (b"ID3", b"\xff\xfb", b"\xff\xf3")
    _check_loaded(mp3, NATIVE_SR, data.shape[0], min_corr=0.99)


@pytest.mark.skipif(not HAVE_FFMPEG, reason="needs the ffmpeg binary")
def test_load_audio_ffmpeg_fallback_for_formats_libsndfile_lacks(tmp_path: Path) -> None:
    data = _stereo_source()
    src = tmp_path / "src.wav"
    sf.write(src, data, NATIVE_SR, subtype="PCM_16")
    aac = tmp_path / "speech_aac.wav"  # AAC in MP4: libsndfile cannot open it
    subprocess.run(["ffmpeg", "-nostdin", "-v", "error", "-y", "-i", str(src), "-c:a", "aac", "-f", "mp4", str(aac)],
                   check=True)
    with pytest.raises(sf.LibsndfileError):
        sf.info(str(aac))
    # AAC pads its last frame, so allow up to one AAC frame (1024 native samples) of extra length.
    _check_loaded(aac, NATIVE_SR, data.shape[0], min_corr=0.99, length_tol=math.ceil(1024 * SR / NATIVE_SR))


def test_load_audio_remove_mean_flag(tmp_path: Path) -> None:
    path = tmp_path / "dc.wav"
    sf.write(path, 0.25 + 0.1 * _tone(SR, SR), SR, subtype="FLOAT")
    with_mean, _ = load_audio(path, remove_mean=False)
    without, _ = load_audio(path)
    assert with_mean.mean() == pytest.approx(0.25, abs=1e-3)
    assert abs(without.mean()) < 1e-6


def test_load_audio_errors(tmp_path: Path) -> None:
    missing = tmp_path / "nope.wav"
    with pytest.raises(InputFileError, match="nope.wav"):
        load_audio(missing)
    empty = tmp_path / "empty.wav"
    empty.write_bytes(b"")
    with pytest.raises(InputFileError, match="empty.wav") as err:
        load_audio(empty)
    assert "\n" not in str(err.value)
    corrupt = tmp_path / "corrupt.wav"
    corrupt.write_bytes(np.random.default_rng(0).integers(0, 256, 20000, dtype=np.uint8).tobytes())
    with pytest.raises(InputFileError, match="corrupt.wav") as err:
        load_audio(corrupt)
    assert "\n" not in str(err.value) and str(corrupt) in str(err.value)
    no_samples = tmp_path / "no_samples.wav"
    sf.write(no_samples, np.zeros((0, 1), np.float32), SR)
    with pytest.raises(InputFileError, match="no audio samples"):
        load_audio(no_samples)
    with pytest.raises(InputFileError, match="directory"):
        load_audio(tmp_path)


def test_check_speech(tmp_path: Path) -> None:
    path = tmp_path / "x.wav"
    speech = speech_like(2.0)
    check_speech(speech, SR, path)
    with pytest.raises(InputFileError, match="silent"):
        check_speech(np.zeros(2 * SR, np.float32), SR, path)
    with pytest.raises(InputFileError, match="silent"):
        check_speech(np.full(2 * SR, 1e-6, np.float32), SR, path)
    with pytest.raises(InputFileError, match="too short") as err:
        check_speech(speech[: SR // 2], SR, path)
    assert str(path) in str(err.value)
    check_speech(speech[: SR // 2], SR, path, min_seconds=0.25)


# ----------------------------------------------------------------------------------------------------------
# Windows and normalisation


def test_normalisation_round_trip() -> None:
    x = torch.randn(50, 128) * 4 - 9
    y = normalise_fbank(x)
    assert torch.allclose(y, (x - FBANK_MEAN) / (2 * FBANK_STD))
    assert torch.allclose(denormalise_fbank(y), x, atol=1e-5)
    xn = x.numpy()
    assert np.allclose(denormalise_fbank(normalise_fbank(xn, -3.0, 2.0), -3.0, 2.0), xn, atol=1e-5)


def test_fbank_window_crop_and_pad() -> None:
    x = torch.arange(1500 * 4, dtype=torch.float32).reshape(1500, 4) + 1
    w = fbank_window(x, 100)
    assert w.shape == (WINDOW_FRAMES, 4) and torch.equal(w, x[100:1124])
    tail = fbank_window(x, 1000)
    assert torch.equal(tail[:500], x[1000:]) and (tail[500:] == 0).all()
    head = fbank_window(x, -10, 20)
    assert (head[:10] == 0).all() and torch.equal(head[10:], x[:10])
    clip = fbank_window(x, 0, content_frames=WINDOW_CONTENT_FRAMES)
    assert torch.equal(clip[:998], x[:998]) and (clip[998:] == 0).all()
    short = fbank_window(x[:300].numpy(), 0)
    assert isinstance(short, np.ndarray) and short.shape == (1024, 4) and (short[300:] == 0).all()
    ws = fbank_windows(x, [0, 500, 1000])
    assert ws.shape == (3, 1024, 4) and torch.equal(ws[1], fbank_window(x, 500))
    assert fbank_windows(x.numpy(), np.array([0, 10])).shape == (2, 1024, 4)


def test_window_starts() -> None:
    assert window_starts(4.0).tolist() == [0.0]
    assert window_starts(10.0).tolist() == [0.0]
    assert window_starts(25.0).tolist() == [0.0, 5.0, 10.0, 15.0]
    s = window_starts(23.37)
    assert s[0] == 0.0 and s[-1] == pytest.approx(13.37) and np.all(np.diff(s) <= 5.0 + 1e-9)
    assert window_starts(23.37, hop_seconds=10.0).tolist() == pytest.approx([0.0, 10.0, 13.37])
    snapped = window_starts(23.37, snap_seconds=0.1)
    assert snapped[-1] == pytest.approx(13.4)
    for d in (10.5, 17.0, 31.9, 600.0):
        s = window_starts(d)
        assert s[0] == 0 and s[-1] + 10.0 == pytest.approx(d) and np.all(np.diff(s) > 0)
        assert np.all(np.diff(s) <= 5.0 + 1e-9)  # overlapping coverage, no gaps


# ----------------------------------------------------------------------------------------------------------
# Augmentation


# ----------------------------------------------------------------------------------------------------------
# Onsets and energy
