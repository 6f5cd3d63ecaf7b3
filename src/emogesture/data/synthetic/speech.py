"""Speech for the synthetic corpus: run a Debian synthesiser, shape the result, time its words.

Prosody goes through each engine's own controls where it has them — flite
``--setf duration_stretch / int_f0_target_mean / int_f0_target_stddev``, espeak-ng ``-s -p`` and SSML
``<prosody range>``, festival's HTS ``-r`` speed and its diphone voices' ``Duration_Stretch`` — and through resampling where it has not: a voice
without pitch control (flite rms, festival's HTS voice) is pitch-shifted by treating its samples as
faster/slower (which also moves the formants), with the engine's rate compensated. The speaker's
timbre is the same resampling trick (×0.9-1.1). ``run_engine`` can also scale the formants alone (the
same resampling, with the engine's pitch moved the other way where it can be). Then, in numpy/scipy only: resample to 16 kHz
(``resample_poly``), spectral tilt (vocal effort), loudness normalised over voiced frames, the
emotion/speaker gain, breathiness and tremolo, a soft limiter and a seeded noise floor at −66 dBFS. All engines are
deterministic, so the same inputs give the same samples.
"""

from __future__ import annotations

import shutil
import subprocess
from math import gcd
from pathlib import Path
from xml.sax.saxutils import escape

import numpy as np
import soundfile as sf
from scipy.signal import lfilter, resample_poly

from emogesture.audio import TARGET_SAMPLE_RATE as SAMPLE_RATE
from emogesture.audio.intonation import reshape_pitch
from emogesture.audio.wave_augment import time_stretch
from emogesture.data.synthetic.factors import BASE_WORDS_PER_SECOND, Prosody, Voice
from emogesture.data.synthetic.text import syllables, words_of
from emogesture.errors import EmogestureError

TARGET_RMS_DB = -24.0  # speech loudness before the emotion/speaker gain (dBFS over voiced frames)
NOISE_FLOOR_DB = -66.0
_EXECUTABLES = {"flite": "flite", "espeak-ng": "espeak-ng", "festival": "text2wave"}


def check_engines(engines: tuple[str, ...]) -> None:
    """Raise EmogestureError naming the Debian package of every missing speech engine."""
    missing = [e for e in engines if shutil.which(_EXECUTABLES[e]) is None]
    if missing:
        raise EmogestureError(
            f"speech engine(s) not found: {', '.join(missing)}; install the Debian packages "
            "(flite, espeak-ng, festival festvox-us-slt-hts festvox-kallpc16k festvox-kdlpc16k — `make setup` does "
            "it) or choose other engines"
        )


def engine_versions(engines: tuple[str, ...]) -> dict[str, str]:
    """The version line of each engine (recorded in corpus.json; bytes may differ across versions)."""
    args = {"flite": ["flite", "--version"], "espeak-ng": ["espeak-ng", "--version"],
            "festival": ["festival", "--version"]}
    out = {}
    for e in engines:
        proc = subprocess.run(args[e], capture_output=True, text=True)
        out[e] = (proc.stdout or proc.stderr).strip().splitlines()[0] if (proc.stdout or proc.stderr) else ""
    return out


def _engine_command(voice: Voice, text_file: Path, wav: Path, rate: float, pitch: float,
                    pitch_range: float) -> list[str]:
    """Command line that speaks ``text_file`` into ``wav`` at ``rate`` × the engine default speed."""
    if voice.engine == "flite":
        f0 = voice.f0 * 2.0 ** (pitch / 12.0)
        return ["flite", "-voice", voice.name, "--setf", f"duration_stretch={1.0 / rate:.4f}",
                "--setf", f"int_f0_target_mean={f0:.2f}",
                "--setf", f"int_f0_target_stddev={0.12 * f0 * pitch_range:.2f}",
                "-f", str(text_file), "-o", str(wav)]
    if voice.engine == "espeak-ng":
        # -p is roughly 0.15 semitone per unit around the default 50; -s is words per minute (default 175).
        p = int(np.clip(round(50 + pitch / 0.15), 0, 99))
        return ["espeak-ng", "-m", "-v", voice.name, "-p", str(p), "-s", str(int(round(175 * rate))),
                "-a", "100", "-f", str(text_file), "-w", str(wav)]
    if voice.engine == "festival":
        if voice.name.endswith("_diphone"):  # diphone voices stretch their durations
            params = f"(Parameter.set 'Duration_Stretch {1.0 / rate:.4f})"
        else:  # HTS voices take the engine's speed
            params = f'(set! hts_engine_params (append hts_engine_params (list (list "-r" {rate:.4f}))))'
        return ["text2wave", "-eval", f"(voice_{voice.name})", "-eval", params, str(text_file), "-o", str(wav)]
    raise ValueError(f"unknown engine {voice.engine!r}")


def run_engine(text: str, voice: Voice, prosody: Prosody, timbre: float, workdir: Path,
               formant: float = 1.0) -> np.ndarray:
    """Synthesise ``text`` and return float64 mono audio at 16 kHz (before tilt, loudness, noise).

    ``prosody.rate`` is relative to BASE_WORDS_PER_SECOND; ``prosody.pitch`` in semitones. ``formant``
    scales the formants alone: the samples are resampled by it and, for a voice with native pitch
    control, the engine's pitch is set that much lower so that the pitch stays (ignored otherwise).
    """
    formant = formant if voice.native_pitch else 1.0
    shift = 1.0 if voice.native_pitch else 2.0 ** (prosody.pitch / 12.0)
    factor = timbre * shift * formant  # samples played this much faster: pitch × factor, duration / factor
    rate = prosody.rate * (BASE_WORDS_PER_SECOND / voice.wps) / factor
    native_pitch = prosody.pitch - 12.0 * np.log2(formant) if voice.native_pitch else 0.0
    text_file, wav = workdir / "text.txt", workdir / "speech.wav"
    if voice.engine == "espeak-ng":
        pct = int(round((prosody.pitch_range - 1.0) * 100))
        body = f'<speak><prosody range="{pct:+d}%">{escape(text)}</prosody></speak>'
    else:
        body = text
    text_file.write_text(body + "\n", encoding="utf-8")
    wav.unlink(missing_ok=True)
    cmd = _engine_command(voice, text_file, wav, rate, native_pitch, prosody.pitch_range)
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=workdir)
    if proc.returncode != 0 or not wav.is_file():
        raise EmogestureError(f"{cmd[0]} failed (exit {proc.returncode}): {proc.stderr.strip()[-300:]}")
    x, sr = sf.read(str(wav), dtype="float64", always_2d=True)
    x = x.mean(axis=1)
    src = int(round(sr * factor / 25.0)) * 25  # the rate the samples are treated as having
    g = gcd(SAMPLE_RATE, src)
    return resample_poly(x, SAMPLE_RATE // g, src // g) if src != SAMPLE_RATE else x


def _frame_rms(x: np.ndarray, hop: int = 160) -> np.ndarray:
    n = len(x) // hop
    return np.sqrt(np.mean(x[: n * hop].reshape(n, hop) ** 2, axis=1) + 1e-20)


def spectral_tilt(x: np.ndarray, tilt: float) -> np.ndarray:
    """Vocal effort: ``x`` ``[N]`` (16 kHz) with ``tilt`` times its part above about 1 kHz added (negative:
    removed, at most 0.9 of it; the part is ``x`` less its one-pole low-pass at 1 kHz)."""
    a = np.exp(-2 * np.pi * 1000.0 / SAMPLE_RATE)
    low = lfilter([1 - a], [1, -a], x)
    return x + max(tilt, -0.9) * (x - low)


def shape_audio(x: np.ndarray, prosody: Prosody, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Tilt, breathiness, tremolo, loudness and gain, soft limit, noise floor.

    Returns ``(audio [N] float32, clean [N] float32)``; ``clean`` lacks the noise floor.
    """
    x = spectral_tilt(x - x.mean(), prosody.tilt)
    a = np.exp(-2 * np.pi * 1000.0 / SAMPLE_RATE)
    if prosody.breathiness > 0:  # aspiration: high-passed noise following the speech envelope
        env = lfilter([1 - a], [1, -a], np.abs(x))
        hiss = rng.standard_normal(len(x))
        hiss = hiss - lfilter([1 - a], [1, -a], hiss)
        x = x + 1.5 * prosody.breathiness * env * hiss
    if prosody.tremolo > 0:
        t = np.arange(len(x)) / SAMPLE_RATE
        x = x * (1.0 + prosody.tremolo * np.sin(2 * np.pi * 5.5 * t + rng.uniform(0, 2 * np.pi)))
    rms = _frame_rms(x)
    voiced = rms[rms > rms.max() * 10 ** (-35 / 20)]
    level = np.sqrt(np.mean(voiced**2)) if voiced.size else 1.0
    x = x * (10 ** ((TARGET_RMS_DB + prosody.gain_db) / 20) / level)
    knee = 0.8  # soft limiter above the knee, never reaching 1.0
    mag = np.abs(x)
    x = np.where(mag > knee, np.sign(x) * (knee + 0.19 * np.tanh((mag - knee) / 0.19)), x)
    noise = rng.standard_normal(len(x)) * 10 ** (NOISE_FLOOR_DB / 20)
    return (x + noise).astype(np.float32), x.astype(np.float32)


def give_prosody(x: np.ndarray, prosody: Prosody, rng: np.random.Generator) -> np.ndarray:
    """A recorded voice ``x`` ``[N]`` (16 kHz) spoken with ``prosody`` as the corpus's voices are: its pitch
    level and span moved (TD-PSOLA, the formants kept), its tempo (WSOLA), then :func:`shape_audio`'s tilt,
    breathiness, tremolo, loudness and limiter, without the noise floor (``rng`` draws the breath noise and
    the tremolo's phase). ``[about N / rate]`` float32."""
    y = reshape_pitch(x, span=prosody.pitch_range, semitones=prosody.pitch)
    return shape_audio(time_stretch(y, prosody.rate), prosody, rng)[1]


def speech_segments(clean: np.ndarray, min_gap: float = 0.18, min_len: float = 0.05) -> list[tuple[float, float]]:
    """Voiced stretches ``[(start s, end s)]`` of a noise-free signal by a 10 ms energy gate
    (30 dB below the loud frames, and 10 dB above the quietest ones)."""
    hop = SAMPLE_RATE // 100
    rms = _frame_rms(np.asarray(clean, np.float64), hop)
    db = 20 * np.log10(rms)
    gate = max(np.percentile(db, 99) - 30.0, np.percentile(db, 5) + 10.0)  # above the voice's own hiss
    active = db > gate
    segs: list[list[float]] = []
    for i in np.flatnonzero(active):
        t = i * hop / SAMPLE_RATE
        if segs and t - segs[-1][1] <= min_gap:
            segs[-1][1] = t + hop / SAMPLE_RATE
        else:
            segs.append([t, t + hop / SAMPLE_RATE])
    return [(s, e) for s, e in segs if e - s >= min_len]


def word_timings(text: str, segments: list[tuple[float, float]]) -> list[tuple[float, float, str]]:
    """Approximate word intervals: the voiced time is shared out in order by syllable count.

    A word that would straddle a pause is moved wholly to the side holding most of it. Not a
    forced alignment; good to a few hundred milliseconds on these synthetic voices.
    """
    words = words_of(text)
    if not words or not segments:
        return []
    starts = np.array([s for s, _ in segments])
    lengths = np.array([e - s for s, e in segments])
    cum = np.concatenate([[0.0], np.cumsum(lengths)])
    weights = np.array([syllables(w) for w in words], np.float64)
    edges = np.concatenate([[0.0], np.cumsum(weights)]) / weights.sum() * cum[-1]

    def seg_of(tau: float, end: bool) -> int:
        i = int(np.searchsorted(cum, tau, side="left" if end else "right")) - 1
        return int(np.clip(i, 0, len(segments) - 1))

    out = []
    for k, w in enumerate(words):
        i, j = seg_of(edges[k], end=False), seg_of(edges[k + 1], end=True)
        t0 = starts[i] + edges[k] - cum[i]
        t1 = starts[j] + edges[k + 1] - cum[j]
        if j > i:  # straddles a pause
            if segments[i][1] - t0 >= t1 - starts[j]:
                t1 = segments[i][1]
            else:
                t0 = starts[j]
        out.append((float(t0), float(max(t1, t0 + 0.01)), w))
    return out


def textgrid(words: list[tuple[float, float, str]], duration: float) -> str:
    """A long-format Praat TextGrid with one interval tier ``words`` (pauses as empty intervals)."""
    intervals: list[tuple[float, float, str]] = []
    t = 0.0
    for s, e, w in words:
        s, e = round(max(s, t), 4), round(min(e, duration), 4)
        if e <= s:
            continue
        if s > t:
            intervals.append((t, s, ""))
        intervals.append((s, e, w))
        t = e
    if t < duration:
        intervals.append((t, round(duration, 4), ""))
    lines = ['File type = "ooTextFile"', 'Object class = "TextGrid"', "", "xmin = 0", f"xmax = {duration:.4f}",
             "tiers? <exists> ", "size = 1", "item []: ", "    item [1]:", '        class = "IntervalTier" ',
             '        name = "words" ', "        xmin = 0 ", f"        xmax = {duration:.4f} ",
             f"        intervals: size = {len(intervals)} "]
    for k, (s, e, w) in enumerate(intervals, 1):
        lines += [f"        intervals [{k}]:", f"            xmin = {s:.4f} ", f"            xmax = {e:.4f} ",
                  f'            text = "{w}" ']
    return "\n".join(lines) + "\n"
