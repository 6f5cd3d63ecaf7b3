"""Label-preserving waveform augmentation: the conditions a real recording meets that synthetic speech never does.

A speech model that has only heard clean synthetic voices takes a room, a microphone, a telephone line or
a codec for a new voice or a new emotion. Each transform below changes how the speech sounds, not what is
said nor how it is said (no emotion prosody is touched: pitch moves by at most a few semitones, as between
speakers, and tempo by at most ±15 %):

- ``voice``: resampled by a factor (pitch and formants together, ±4 semitones), the duration kept by a
  WSOLA time stretch;
- ``pitch`` (off unless asked for, drawn before the others): the pitch alone moved (TD-PSOLA, formants and
  duration kept), as one person's voice differs from another's with the same vocal tract;
- ``tempo``: WSOLA time stretch (pitch and formants kept);
- ``reverb``: a synthetic room impulse response (exponentially decaying noise, RT60 0.15–0.9 s, with the
  direct path) mixed at a random direct-to-reverberant ratio;
- ``noise``: white, pink or speech-shaped noise at 0–30 dB SNR;
- ``telephone``: 300–3400 Hz band, 8-kHz sampling and μ-law companding;
- ``codec``: MP3 or Opus at a low bit rate through ffmpeg (:func:`codec_roundtrip`);
- ``loudness``: ±10 dB;
- ``microphone``: a random colouring (a spectral tilt and two peaking bands of ±6 dB).

:func:`augment_waveform` draws which transforms apply and their settings from a ``numpy.random.Generator``,
so the same seed gives the same result; nothing reads the global random state. The output has the input's
length (a tempo change is cut or padded back), so the windows and their labels stay aligned.
"""

from __future__ import annotations

import shutil
import subprocess
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.fft import irfft, next_fast_len, rfft, rfftfreq
from scipy.signal import butter, fftconvolve, lfilter, resample_poly, sosfilt

from emogesture.audio.intonation import reshape_pitch
from emogesture.audio.io import TARGET_SAMPLE_RATE as SAMPLE_RATE

TRANSFORMS = ("voice", "tempo", "reverb", "noise", "telephone", "codec", "loudness", "microphone")


@dataclass(frozen=True)
class WaveAugmentConfig:
    """Probability of each transform (applied in :data:`TRANSFORMS` order) and its range."""

    voice: float = 0.5
    voice_semitones: float = 4.0
    tempo: float = 0.3
    tempo_range: float = 0.15
    reverb: float = 0.4
    noise: float = 0.5
    snr_db: tuple[float, float] = (0.0, 30.0)
    telephone: float = 0.15
    codec: float = 0.0  # an ffmpeg process per window: off unless asked for
    loudness: float = 0.5
    microphone: float = 0.5
    pitch: float = 0.0  # the pitch alone (formants kept); its draw comes first, and only when > 0
    pitch_semitones: float = 3.0

    def validate(self) -> None:
        for name in TRANSFORMS:
            p = getattr(self, name)
            if not 0.0 <= p <= 1.0:
                raise ValueError(f"{name}: probability {p} is not in [0, 1]")
        if not 0.0 <= self.pitch <= 1.0 or not 0 <= self.pitch_semitones <= 12:
            raise ValueError(f"pitch: probability {self.pitch} (0-1) and pitch_semitones {self.pitch_semitones} (0-12)")
        if not 0 <= self.tempo_range < 0.5 or not 0 <= self.voice_semitones <= 12:
            raise ValueError("tempo_range must be in [0, 0.5) and voice_semitones in [0, 12]")


def time_stretch(x: np.ndarray, rate: float, frame: int = 640, hop: int = 160, search: int = 160) -> np.ndarray:
    """WSOLA: ``x`` played ``rate`` times as fast (``rate`` 1.25: 80 % of the length) with its pitch kept.

    Frames of ``frame`` samples (Hann window, 50 % of it added per ``hop``) are read at ``hop × rate``
    steps, each shifted by up to ``search`` samples to the offset that best continues the previous one.
    """
    x = np.asarray(x, np.float64)
    if rate == 1.0 or len(x) < 2 * frame:
        return x.copy()
    window = np.hanning(frame)
    n_out = int(len(x) / rate)
    out = np.zeros(n_out + frame)
    norm = np.zeros(n_out + frame)
    pad = np.concatenate([np.zeros(search), x, np.zeros(frame + search)])
    previous_end = None
    for k, o in enumerate(range(0, n_out, hop)):
        centre = int(round(o * rate)) + search
        if previous_end is None:
            best = centre
        else:  # the shift whose frame start best matches the natural continuation of the last frame
            seg = pad[centre - search: centre + search + hop]
            target = pad[previous_end: previous_end + hop]
            corr = np.correlate(seg, target, "valid")
            best = centre - search + int(np.argmax(corr))
        out[o: o + frame] += window * pad[best: best + frame]
        norm[o: o + frame] += window
        previous_end = best + hop
    return out[:n_out] / np.maximum(norm[:n_out], 1e-3)


def _fit_length(x: np.ndarray, n: int) -> np.ndarray:
    return x[:n] if len(x) >= n else np.concatenate([x, np.zeros(n - len(x))])


def voice_shift(x: np.ndarray, semitones: float) -> np.ndarray:
    """Pitch and formants moved by ``semitones`` (a resampling), the duration kept (a time stretch)."""
    factor = 2.0 ** (semitones / 12.0)
    up, down = int(round(1000 / factor)), 1000
    moved = resample_poly(x, up, down)  # factor times fewer samples: played at 16 kHz, factor higher
    return _fit_length(time_stretch(moved, len(moved) / len(x)), len(x))


def room_impulse(rng: np.random.Generator, rt60: float, sample_rate: int = SAMPLE_RATE) -> np.ndarray:
    """A synthetic room impulse response: the direct path, then noise decaying by 60 dB in ``rt60`` s."""
    n = int(rt60 * sample_rate)
    t = np.arange(n) / sample_rate
    tail = rng.standard_normal(n) * np.exp(-6.9 * t / rt60)
    tail[: int(0.002 * sample_rate)] = 0.0  # the first reflections arrive a few ms after the direct sound
    tail = lfilter([1.0], [1.0, -0.6], tail)  # walls absorb the high frequencies
    h = tail / np.sqrt((tail ** 2).sum())
    h[0] = 1.0
    return h


def reverberant(x: np.ndarray, rng: np.random.Generator, rt60: float, wet: float) -> np.ndarray:
    """``x`` ``[N]`` in a room of ``rt60`` s (:func:`room_impulse`): ``1 - wet`` of the direct sound plus
    ``wet`` of its reverberation brought to the same power; ``[N]``."""
    room = fftconvolve(x, room_impulse(rng, rt60))[: len(x)]
    return (1 - wet) * x + wet * room * np.sqrt(np.mean(x ** 2) / (np.mean(room ** 2) + 1e-12))


def recording_changes(rng: np.random.Generator) -> dict[str, Callable[[np.ndarray], np.ndarray]]:
    """Fixed changes that move a recording away from the training voices and conditions, by name (the rows
    of the robustness reports): pitch and formants ±4 semitones with the tempo kept, tempo ±15 % with the
    pitch kept, white noise at 10 dB SNR, a telephone band, a reverberant room (RT60 0.5 s, half of it
    reverberation), a recording 10 dB quieter and one 6 dB louder (clipped at full scale, as a recorder
    would). Each maps a waveform ``[N]`` to one of the same rate; the noise and the room draw from ``rng``."""
    return {
        "pitch +4 semitones": lambda w: voice_shift(w, 4.0),
        "pitch -4 semitones": lambda w: voice_shift(w, -4.0),
        "tempo +15 %": lambda w: time_stretch(w, 1.15),
        "tempo -15 %": lambda w: time_stretch(w, 1 / 1.15),
        "white noise, 10 dB SNR": lambda w: add_noise(w, rng, 10.0, "white"),
        "telephone band 300-3400 Hz": telephone,
        "reverberant room, RT60 0.5 s": lambda w: reverberant(w, rng, 0.5, 0.5),
        "recording level -10 dB": lambda w: w * 10 ** (-10 / 20),
        "recording level +6 dB, clipped": lambda w: np.clip(w * 10 ** (6 / 20), -1.0, 1.0),
    }


def add_noise(x: np.ndarray, rng: np.random.Generator, snr_db: float, kind: str) -> np.ndarray:
    """``x`` plus ``kind`` noise (white, pink, speech) at ``snr_db`` below the speech's power."""
    noise = rng.standard_normal(len(x))
    if kind == "pink":  # -3 dB per octave (Kellet's filter)
        noise = lfilter([0.049922, -0.095993, 0.050612, -0.004408], [1, -2.494956, 2.017265, -0.522189], noise)
    elif kind == "speech":  # the speech's own long-term spectrum
        n = next_fast_len(len(x), real=True)
        spec = np.abs(rfft(x, n)) + 1e-9
        noise = irfft(rfft(noise, n) * spec / spec.mean(), n)[: len(x)]
    power = np.mean(x ** 2) + 1e-12
    return x + noise * np.sqrt(power / (np.mean(noise ** 2) + 1e-12) / 10 ** (snr_db / 10))


def telephone(x: np.ndarray, sample_rate: int = SAMPLE_RATE) -> np.ndarray:
    """300–3400 Hz, resampled through 8 kHz, μ-law companded to 8 bits."""
    sos = butter(4, [300, 3400], btype="band", fs=sample_rate, output="sos")
    y = resample_poly(sosfilt(sos, x), 1, 2)
    peak = np.abs(y).max() + 1e-9
    mu = 255.0
    c = np.sign(y / peak) * np.log1p(mu * np.abs(y / peak)) / np.log1p(mu)
    c = np.round(c * 127) / 127
    y = np.sign(c) * np.expm1(np.abs(c) * np.log1p(mu)) / mu * peak
    return _fit_length(resample_poly(y, 2, 1), len(x))


def microphone(x: np.ndarray, rng: np.random.Generator, sample_rate: int = SAMPLE_RATE) -> np.ndarray:
    """A random colouring: a tilt of ±4 dB per decade-ish and two peaking bands of ±6 dB."""
    n = next_fast_len(len(x), real=True)  # a length the FFT is fast at (10 s + 25 ms has a prime factor 401)
    spec = rfft(x, n)
    f = rfftfreq(n, 1 / sample_rate)
    gain_db = rng.uniform(-4, 4) * np.log10(np.maximum(f, 50) / 1000)
    for _ in range(2):
        centre, width, gain = np.exp(rng.uniform(np.log(200), np.log(6000))), rng.uniform(0.3, 1.0), rng.uniform(-6, 6)
        gain_db += gain * np.exp(-0.5 * (np.log2(np.maximum(f, 1) / centre) / width) ** 2)
    return irfft(spec * 10 ** (gain_db / 20), n)[: len(x)]


def codec_roundtrip(x: np.ndarray, codec: str, bitrate_k: int, sample_rate: int = SAMPLE_RATE) -> np.ndarray:
    """``x`` encoded with ``codec`` (``mp3`` or ``opus``) at ``bitrate_k`` kbit/s by ffmpeg and decoded again."""
    if shutil.which("ffmpeg") is None:
        raise RuntimeError("codec augmentation needs ffmpeg (apt-get install ffmpeg)")
    fmt = {"mp3": ("libmp3lame", "mp3"), "opus": ("libopus", "ogg")}[codec]
    pcm = (np.clip(x, -1, 1) * 32767).astype("<i2").tobytes()
    base = ["ffmpeg", "-loglevel", "error", "-f", "s16le", "-ar", str(sample_rate), "-ac", "1"]
    enc = subprocess.run(base + ["-i", "-", "-c:a", fmt[0], "-b:a", f"{bitrate_k}k", "-f", fmt[1], "-"],
                         input=pcm, capture_output=True, check=True).stdout
    dec = subprocess.run(["ffmpeg", "-loglevel", "error", "-i", "-", "-f", "s16le", "-ar", str(sample_rate), "-ac", "1",
                          "-"], input=enc, capture_output=True, check=True).stdout
    return _fit_length(np.frombuffer(dec, "<i2").astype(np.float64) / 32767, len(x))


def augment_waveform(x: np.ndarray, rng: np.random.Generator, config: WaveAugmentConfig = WaveAugmentConfig()
                     ) -> tuple[np.ndarray, list[str]]:
    """A 16-kHz waveform ``[N]`` -> ``(augmented [N] float32, the transforms applied with their settings)``."""
    config.validate()
    y = np.asarray(x, np.float64)
    n = len(y)
    applied: list[str] = []
    if config.pitch > 0 and rng.random() < config.pitch:
        st = rng.uniform(-config.pitch_semitones, config.pitch_semitones)
        y = reshape_pitch(y, semitones=st)
        applied.append(f"pitch {st:+.1f} st")
    draws = rng.random(len(TRANSFORMS))  # one draw per transform whatever applies: the settings stay aligned
    on = {name: draws[i] < getattr(config, name) for i, name in enumerate(TRANSFORMS)}
    if on["voice"]:
        st = rng.uniform(-config.voice_semitones, config.voice_semitones)
        y = voice_shift(y, st)
        applied.append(f"voice {st:+.1f} st")
    if on["tempo"]:
        rate = float(np.exp(rng.uniform(np.log(1 - config.tempo_range), np.log(1 + config.tempo_range))))
        y = _fit_length(time_stretch(y, rate), n)
        applied.append(f"tempo x{rate:.2f}")
    if on["reverb"]:
        rt60, wet = rng.uniform(0.15, 0.9), rng.uniform(0.2, 0.8)
        y = reverberant(y, rng, rt60, wet)
        applied.append(f"reverb rt60 {rt60:.2f} s")
    if on["microphone"]:
        y = microphone(y, rng)
        applied.append("microphone")
    if on["telephone"]:
        y = telephone(y)
        applied.append("telephone")
    if on["noise"]:
        snr, kind = rng.uniform(*config.snr_db), ("white", "pink", "speech")[int(rng.integers(3))]
        y = add_noise(y, rng, snr, kind)
        applied.append(f"{kind} noise {snr:.0f} dB")
    if on["codec"]:
        codec, rate_k = ("mp3", "opus")[int(rng.integers(2))], int(rng.choice([8, 16, 24]))
        y = codec_roundtrip(y, codec, rate_k)
        applied.append(f"{codec} {rate_k}k")
    if on["loudness"]:
        db = rng.uniform(-10, 10)
        y = y * 10 ** (db / 20)
        applied.append(f"{db:+.0f} dB")
    peak = np.abs(y).max()
    if peak > 0.99:  # never clip: scale down instead
        y *= 0.99 / peak
    return y.astype(np.float32), applied
