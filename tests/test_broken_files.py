"""One-line errors naming the file for broken inputs outside model files: cache and run metadata,
ffmpeg that cannot run, a WAV header with an absurd sample rate, and bounded resampling."""

import os
import struct
import subprocess
import sys

import numpy as np
import pytest
import soundfile as sf

from emogesture.audio import load_audio
from emogesture.audio.io import MAX_RESAMPLE_FACTOR, resample
from emogesture.data.cache import open_cache
from emogesture.data.prepare import prepare
from emogesture.errors import EmogestureError, InputFileError
from emogesture.train.engine import check_run_dir

from helpers import cli, make_root


def _one_line(err) -> str:
    text = str(err)
    assert "\n" not in text and "Traceback" not in text
    return text


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    d = tmp_path_factory.mktemp("broken")
    make_root(d / "root", speakers=(1,), takes=(1, 2))
    prepare(d / "root", d / "cache", progress=False)
    return d


def test_corrupt_cache_metadata_is_one_line(cache, tmp_path, capsys):
    import shutil

    copy = tmp_path / "cache"
    shutil.copytree(cache / "cache", copy)
    (copy / "manifest.json").write_text('{"cache_version": ')
    with pytest.raises(InputFileError, match=r"manifest.json: corrupt cache manifest: not valid JSON") as err:
        open_cache(copy)
    _one_line(err.value)
    # prepare assembles a damaged manifest again from its prepared takes
    prepare(cache / "root", copy, progress=False)
    assert "assembling it again" in capsys.readouterr().err and open_cache(copy).splits
    (copy / "prepare_config.json").write_bytes(b"\xff\xfe not text")
    with pytest.raises(EmogestureError, match=r"prepare_config.json: not a readable cache settings file") as err:
        prepare(cache / "root", copy, progress=False)
    assert "delete the cache folder" in _one_line(err.value)
    (copy / "prepare_config.json").write_text("[1, 2]")
    out = subprocess.run(cli("prepare", cache / "root", "--out", copy), capture_output=True, text=True)
    assert out.returncode == 2 and "prepare_config.json: corrupt cache settings file" in out.stderr
    assert len(out.stderr.strip().splitlines()) == 1


def test_corrupt_run_json_is_one_line(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    (run / "run.json").write_text("{ half a file")
    with pytest.raises(InputFileError, match=r"run.json: corrupt run settings file: not valid JSON") as err:
        check_run_dir(run, {"a": 1})
    _one_line(err.value)


def _wav_with_rate(path, rate: int) -> None:
    """A valid 16-bit mono WAV of 0.5 s whose header claims ``rate`` Hz."""
    sf.write(path, np.zeros(8000, np.float32), 16000, subtype="PCM_16")
    blob = bytearray(path.read_bytes())
    fmt = blob.index(b"fmt ")
    struct.pack_into("<I", blob, fmt + 12, rate)  # sample rate
    struct.pack_into("<I", blob, fmt + 16, rate * 2)  # byte rate
    path.write_bytes(bytes(blob))


@pytest.mark.parametrize("rate", [1, 4_000_000])
def test_an_absurd_sample_rate_is_refused(tmp_path, rate):
    wav = tmp_path / f"claims_{rate}.wav"
    _wav_with_rate(wav, rate)
    with pytest.raises(InputFileError, match=rf"claims_{rate}.wav: its header claims a sample rate of {rate} Hz"):
        load_audio(wav)


def _assert_sine(y: np.ndarray, sr: int, freq: float, amplitude: float) -> None:
    """``y`` holds a sine of ``freq`` Hz and ``amplitude``: its spectrum peaks within one bin of ``freq``
    and its RMS (away from the filter's edge transients) is ``amplitude / sqrt(2)`` within 1 %."""
    spectrum = np.abs(np.fft.rfft(y * np.hanning(len(y))))
    peak = np.fft.rfftfreq(len(y), 1 / sr)[spectrum.argmax()]
    assert abs(peak - freq) <= sr / len(y), peak
    middle = y[len(y) // 10: -len(y) // 10]
    assert np.sqrt(np.mean(middle**2)) == pytest.approx(amplitude / np.sqrt(2), rel=0.01)


def test_resampling_is_bounded_for_awkward_rates_and_keeps_a_sine(tmp_path):
    x = np.random.default_rng(0).normal(size=44101)  # one second at 44101 Hz: gcd 1 with 16000
    y = resample(x, 44101, 16000)
    assert abs(len(y) - 16000) <= 1
    y = resample(np.ones(1009), 1009, 16000)  # a prime rate, upsampled
    assert abs(len(y) - 16000) <= 16 and MAX_RESAMPLE_FACTOR >= 160
    # a 440 Hz sine keeps its frequency and amplitude: read from a 44.1 kHz file at 16 kHz, and resampled
    # from the awkward 44101 Hz (whose ratio is approximated)
    wav = tmp_path / "sine_44100.wav"
    sf.write(wav, 0.5 * np.sin(2 * np.pi * 440.0 * np.arange(2 * 44100) / 44100), 44100, subtype="FLOAT")
    y, sr = load_audio(wav)
    assert sr == 16000 and abs(len(y) - 2 * 16000) <= 1
    _assert_sine(y, sr, 440.0, 0.5)
    y = resample(0.5 * np.sin(2 * np.pi * 440.0 * np.arange(2 * 44101) / 44101), 44101, 16000)
    _assert_sine(y, 16000, 440.0, 0.5)


def test_ffmpeg_that_cannot_run_is_one_line(tmp_path):
    fake = tmp_path / "bin"
    fake.mkdir()
    for tool in ("ffmpeg", "ffprobe"):
        (fake / tool).write_bytes(b"\x7fELF garbage, not a program")
        os.chmod(fake / tool, 0o755)
    opus = tmp_path / "speech.weird"
    opus.write_bytes(b"OggS" + bytes(200))  # not for libsndfile: the ffmpeg fallback is tried
    env = {**os.environ, "PATH": f"{fake}{os.pathsep}{os.environ['PATH']}"}
    code = ("import sys\nfrom emogesture.audio import load_audio\nfrom emogesture.errors import EmogestureError\n"
            "try:\n    load_audio(sys.argv[1])\nexcept EmogestureError as e:\n    print(e); sys.exit(2)\n")
    out = subprocess.run([sys.executable, "-c", code, str(opus)], capture_output=True, text=True, env=env)
    assert out.returncode == 2 and "speech.weird: cannot decode audio:" in out.stdout and "cannot be run" in out.stdout
    assert "Traceback" not in out.stderr
    npz = tmp_path / "take.npz"
    from emogesture.motion import save_smplx_npz
    from emogesture.types import SMPLXSequence

    save_smplx_npz(SMPLXSequence(poses=np.zeros((30, 55, 3), np.float32), trans=np.zeros((30, 3))), npz)
    out = subprocess.run(cli("export", npz, "--format", "mp4", "-o", tmp_path / "o"), capture_output=True, text=True,
                         env=env)
    assert out.returncode == 2 and "ffmpeg cannot be run" in out.stderr, out.stderr
    assert len(out.stderr.strip().splitlines()) == 1 and not list((tmp_path / "o").glob("*.mp4"))
