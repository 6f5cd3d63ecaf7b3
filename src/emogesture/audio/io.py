"""Reading speech audio (docs/design.md, 'Audio front end'): any libsndfile format, detected by content; ffmpeg
as the fallback.

``load_audio`` returns a float32 mono waveform at 16 kHz with its mean removed. The container/codec is
detected from the file's bytes, never from its name (BEAT ships 32-bit float WAV and MP3 data named
``.wav``). libsndfile (through soundfile) is tried first; if it cannot open the file and an ``ffmpeg`` /
``ffprobe`` binary is on ``PATH``, the file is decoded by ffmpeg to raw float32 at its native rate, and the
channel mix-down and resampling are done here as for every other file.

Every failure is an :class:`~emogesture.errors.InputFileError` whose one-line message names the file.
"""

from __future__ import annotations

import json
import shutil
import subprocess
from fractions import Fraction
from os import PathLike
from pathlib import Path

import numpy as np
import soundfile as sf

from emogesture.errors import InputFileError

__all__ = ["TARGET_SAMPLE_RATE", "load_audio", "audio_seconds", "check_speech", "resample"]

TARGET_SAMPLE_RATE = 16000
_SILENCE_PEAK = 1e-4
_SILENCE_RMS = 1e-5


def _one_line(text: str, limit: int = 200, strip_prefix: str = "") -> str:
    lines = [ln.strip() for ln in str(text).splitlines() if ln.strip()]
    line = lines[-1] if lines else "unknown error"
    if strip_prefix and line.startswith(strip_prefix):
        line = line[len(strip_prefix):].lstrip(": ") or line
    return line if len(line) <= limit else line[: limit - 3] + "..."


def _check_wav_length(path: Path) -> None:
    """A RIFF/WAVE file whose ``data`` chunk claims more bytes than the file holds is truncated (libsndfile
    would silently read what is there). Streaming placeholders (0 or 0xFFFFFFFF) are accepted."""
    try:
        size = path.stat().st_size
        with path.open("rb") as fh:
            head = fh.read(12)
            if len(head) < 12 or head[:4] != b"RIFF" or head[8:12] != b"WAVE":
                return
            offset = 12
            while offset + 8 <= size:
                fh.seek(offset)
                chunk = fh.read(8)
                cid, length = chunk[:4], int.from_bytes(chunk[4:8], "little")
                if cid == b"data":
                    available = size - offset - 8
                    if length not in (0, 0xFFFFFFFF) and length > available:
                        raise InputFileError(path, f"truncated WAV: its header declares {length} bytes of audio "
                                             f"but the file holds {available}")
                    return
                offset += 8 + length + (length & 1)
    except OSError:
        return  # reading proper reports it


SAMPLE_RATE_RANGE = (1000, 768000)  # Hz: what a speech recording's header may claim
MAX_RESAMPLE_FACTOR = 1000  # polyphase up/down factors above this use the nearest ratio within it


def _run_tool(path: Path, cmd: list[str]) -> subprocess.CompletedProcess:
    """Run ffmpeg/ffprobe for ``path``; a binary that cannot be started is a one-line error."""
    try:
        return subprocess.run(cmd, capture_output=True, stdin=subprocess.DEVNULL, check=False)
    except OSError as err:
        raise InputFileError(path, f"cannot decode audio: {cmd[0]} cannot be run ({err.strerror or err})") from None


def _read_soundfile(path: Path) -> tuple[np.ndarray, int]:
    data, sr = sf.read(str(path), dtype="float32", always_2d=True)
    return data, int(sr)


def _read_ffmpeg(path: Path, soundfile_error: str) -> tuple[np.ndarray, int]:
    ffmpeg, ffprobe = shutil.which("ffmpeg"), shutil.which("ffprobe")
    if ffmpeg is None or ffprobe is None:
        raise InputFileError(
            path, f"cannot decode audio: not a format libsndfile reads, or corrupt ({soundfile_error}); "
            "ffmpeg is not installed to try other formats"
        )
    url = f"file:{path}"  # 'file:' so names starting with '-' or holding ':' are taken literally
    probe = _run_tool(path, [ffprobe, "-v", "error", "-select_streams", "a:0", "-show_entries",
                             "stream=sample_rate,channels", "-of", "json", url])
    streams = []
    if probe.returncode == 0:
        try:
            streams = json.loads(probe.stdout.decode("utf-8", "replace") or "{}").get("streams", [])
        except json.JSONDecodeError:
            streams = []
    if not streams:
        detail = (_one_line(probe.stderr.decode("utf-8", "replace"), strip_prefix=url)
                  if probe.stderr.strip() else "no audio stream")
        raise InputFileError(
            path, f"cannot decode audio: not a recognised audio format, or corrupt (libsndfile: {soundfile_error}; "
            f"ffmpeg: {detail})"
        )
    try:
        sr = int(streams[0]["sample_rate"])
        channels = int(streams[0]["channels"])
    except (KeyError, TypeError, ValueError):
        raise InputFileError(path, "cannot decode audio: ffprobe reports no sample rate / channel count") from None
    if sr <= 0 or channels <= 0:
        raise InputFileError(path, f"cannot decode audio: bad stream parameters ({sr} Hz, {channels} channels)")
    _check_sample_rate(path, sr)
    dec = _run_tool(path, [ffmpeg, "-nostdin", "-v", "error", "-i", url, "-map", "0:a:0", "-vn", "-f", "f32le",
                           "-acodec", "pcm_f32le", "-ac", str(channels), "-ar", str(sr), "pipe:1"])
    if dec.returncode != 0:
        detail = _one_line(dec.stderr.decode("utf-8", "replace"), strip_prefix=url)
        raise InputFileError(path, f"cannot decode audio with ffmpeg ({detail})")
    raw = dec.stdout[: len(dec.stdout) // (4 * channels) * 4 * channels]
    data = np.frombuffer(raw, dtype="<f4").astype(np.float32).reshape(-1, channels)
    return data, sr


def _check_sample_rate(path: Path, sr: int) -> None:
    low, high = SAMPLE_RATE_RANGE
    if not low <= sr <= high:
        raise InputFileError(path, f"its header claims a sample rate of {sr} Hz, outside {low}-{high} Hz "
                             "(a damaged or mislabelled file)")


def resample(waveform: np.ndarray, orig_sr: int, target_sr: int) -> np.ndarray:
    """Polyphase resampling along the last axis (float64 out), with the exact ratio ``target/gcd :
    orig/gcd`` when both factors are at most :data:`MAX_RESAMPLE_FACTOR`, else the nearest ratio within
    it (e.g. 44101 Hz -> 16000 Hz: a duration error below 1e-6 instead of a 16000-tap-per-phase filter)."""
    x = np.asarray(waveform, dtype=np.float64)
    if orig_sr == target_sr:
        return x
    ratio = Fraction(int(target_sr), int(orig_sr))
    if max(ratio.numerator, ratio.denominator) > MAX_RESAMPLE_FACTOR:
        ratio = ratio.limit_denominator(MAX_RESAMPLE_FACTOR)
        while ratio.numerator > MAX_RESAMPLE_FACTOR:  # upsampling by more than the bound: coarser ratio
            ratio = Fraction(int(target_sr), int(orig_sr)).limit_denominator(max(1, ratio.denominator // 2))
    from scipy.signal import resample_poly  # imported here: scipy.signal costs ~1 s at start-up

    return resample_poly(x, ratio.numerator, ratio.denominator, axis=-1)


def load_audio(
    path: str | PathLike[str], target_sr: int = TARGET_SAMPLE_RATE, *, remove_mean: bool = True
) -> tuple[np.ndarray, int]:
    """Read a speech file as a float32 mono waveform ``[N]`` at ``target_sr`` (docs/design.md, 'Audio front end').

    Steps: decode (libsndfile, else ffmpeg) to float in ``[-1, 1]``; mix channels down by their mean;
    resample with :func:`scipy.signal.resample_poly`; subtract the waveform mean (``remove_mean``).

    Returns:
        ``(waveform, target_sr)``.

    Raises:
        InputFileError: missing file, a directory, an empty or undecodable file, no samples, NaN/inf.
    """
    p = Path(path)
    if int(target_sr) != target_sr or target_sr <= 0:
        raise ValueError(f"target_sr must be a positive integer, got {target_sr}")
    target_sr = int(target_sr)
    if not p.exists():
        raise InputFileError(p, "file not found")
    if p.is_dir():
        raise InputFileError(p, "is a directory, not an audio file")
    try:
        with p.open("rb") as fh:
            first = fh.read(1)
    except OSError as err:
        raise InputFileError(p, f"cannot read file ({err.strerror or err})") from None
    if not first:
        raise InputFileError(p, "empty file (0 bytes)")
    _check_wav_length(p)
    try:
        data, sr = _read_soundfile(p)
    except Exception as err:  # libsndfile's errors are RuntimeError / TypeError / ValueError subclasses
        data, sr = _read_ffmpeg(p, _one_line(str(err)))
    _check_sample_rate(p, sr)
    if data.shape[0] == 0 or data.shape[1] == 0:
        raise InputFileError(p, "contains no audio samples")
    if not np.isfinite(data).all():
        raise InputFileError(p, "contains NaN or infinite samples")
    # one channel is its own mean (the same numbers without a mean over a [N, 1] array: 40 ms for 10 min)
    mono = data[:, 0].astype(np.float64) if data.shape[1] == 1 else data.astype(np.float64).mean(axis=1)
    out = resample(mono, sr, target_sr)
    if out.size == 0:
        raise InputFileError(p, "contains no audio samples after resampling")
    return without_mean(out) if remove_mean else np.ascontiguousarray(out, dtype=np.float32), target_sr


def without_mean(waveform: np.ndarray) -> np.ndarray:
    """A waveform ``[N]`` less its mean (taken in float64), as float32: what :func:`load_audio` does to a
    recording, for a stretch cut out of one, so that it is heard as a recording of those samples would be."""
    wave = np.asarray(waveform, np.float64)
    out = np.empty(wave.shape, np.float32)
    return np.subtract(wave, wave.mean(), out=out, casting="same_kind")  # in float64, rounded once into out


def audio_seconds(path: str | PathLike[str]) -> float:
    """A recording's length in seconds: from its header when libsndfile reads one that states it, else by
    decoding it (:func:`load_audio`, whose one-line errors it raises)."""
    try:
        info = sf.info(str(path))
        if info.frames > 0 and info.samplerate > 0:
            return info.frames / info.samplerate
    except Exception:  # noqa: BLE001 - not a format libsndfile reads: decode it
        pass
    waveform, sr = load_audio(path, remove_mean=False)
    return waveform.size / sr


def check_speech(
    waveform: np.ndarray, sample_rate: int, path: str | PathLike[str], min_seconds: float = 1.0,
    allow_silence: bool = False,
) -> bool:
    """Reject audio that cannot drive gesture generation: shorter than ``min_seconds``, or silent
    (unless ``allow_silence``). Returns whether the audio is silent.

    Silent means a peak magnitude below 1e-4 or an RMS below 1e-5 (after the mean removal of
    :func:`load_audio`, so a pure DC offset is silent too).

    Raises:
        InputFileError: naming ``path``.
    """
    w = np.asarray(waveform).reshape(-1)
    if w.dtype.kind != "f":
        w = w.astype(np.float64)
    duration = w.size / float(sample_rate)
    if duration < min_seconds:
        raise InputFileError(
            path, f"audio is too short: {duration:.2f} s, at least {min_seconds:g} s of speech is needed"
        )
    if not np.isfinite(w).all():
        raise InputFileError(path, "audio contains NaN or infinite samples")
    peak = float(np.abs(w).max())  # exact in the samples' own precision
    rms = float(np.sqrt(np.mean(np.square(w, dtype=np.float64))))
    silent = peak < _SILENCE_PEAK or rms < _SILENCE_RMS
    if silent and not allow_silence:
        raise InputFileError(path, f"audio is silent (peak {peak:.1e}, RMS {rms:.1e})")
    return silent
