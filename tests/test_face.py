"""The face track: ARKit weights, lips that close and rest, the emotion's expression, blinks and gaze; the npz
carries it and ``generate --face`` writes it; on real read speech (Debian's LibriVox clips, forced-aligned)
the lips meet on P, B and M and open with the voice."""

from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from emogesture.audio.onsets import frame_energy
from emogesture.errors import InputFileError
from emogesture.face.arkit import EXPRESSIONS, INDEX, VISEME_GROUPS, vector
from emogesture.face.phones import Phone, recogniser_installed
from emogesture.face.track import face_track
from emogesture.motion import load_smplx_npz, save_smplx_npz
from emogesture.types import ARKIT_NAMES, EMOTIONS
from helpers import cli_here, experiment_module, gesture_like, speech_like

SR = 16000
LIBRIVOX = Path("/usr/share/pocketsphinx/test/data/librivox")


def openness(arkit: np.ndarray) -> np.ndarray:
    return np.maximum(arkit[:, INDEX["jawOpen"]] - arkit[:, INDEX["mouthClose"]], 0.0)


def talk_and_pause() -> tuple[np.ndarray, list[Phone]]:
    """2 s of speech-like sound, 1.5 s of silence, 2 s of speech; phones: ``M AA`` repeated in the speech."""
    voice = speech_like(2.0, SR, seed=1)
    wave = np.concatenate([voice, np.zeros(int(1.5 * SR), np.float32), speech_like(2.0, SR, seed=2)])
    phones = []
    for start in (0.0, 3.5):
        phones += [Phone("M" if k % 2 == 0 else "AA", start + 0.1 * k, start + 0.1 * (k + 1)) for k in range(20)]
    phones.insert(20, Phone("SIL", 2.0, 3.5))
    return wave, phones


def test_the_tables_name_arkit_shapes():
    assert len(ARKIT_NAMES) == 52 and len(set(ARKIT_NAMES)) == 52
    assert set(EXPRESSIONS) == set(EMOTIONS)
    for shape in [*EXPRESSIONS.values(), *(s for _, s in VISEME_GROUPS.values())]:
        v = vector(shape)  # an unknown name is a KeyError
        assert v.min() >= 0 and v.max() <= 1


def test_lips_meet_open_and_rest():
    wave, phones = talk_and_pause()
    n = int(len(wave) / SR * 30)
    face = face_track(wave, SR, n, phones=phones)
    assert face.arkit.shape == (n, 52) and face.arkit.min() >= 0 and face.arkit.max() <= 1
    op = openness(face.arkit)
    closures = [p for p in phones if p.name == "M"]
    vowels = [op[int(p.start * 30) : int(np.ceil(p.end * 30))].mean() for p in phones if p.name == "AA"]
    lowest = [op[max(int(p.start * 30) - 1, 0) : int(np.ceil(p.end * 30)) + 1].min() for p in closures]
    assert np.mean(np.array(lowest) < 0.5 * np.median(vowels)) >= 0.9
    assert np.mean(vowels) > 0.25
    pause = op[int(2.1 * 30) : int(3.4 * 30)]
    assert pause.max() < 0.1  # the mouth at rest while the voice is silent
    assert np.abs(face.jaw[:, 0] - 0.45 * face.arkit[:, INDEX["jawOpen"]]).max() < 1e-6


def test_without_phones_the_jaw_follows_the_voice():
    wave, _ = talk_and_pause()
    n = int(len(wave) / SR * 30)
    op = openness(face_track(wave, SR, n).arkit)
    assert op[int(2.1 * 30) : int(3.4 * 30)].max() < 0.1
    assert op[: 60].mean() > 0.1
    energy = frame_energy(wave, SR, fps=30)[:n]
    assert np.corrcoef(op, energy)[0, 1] > 0.5


def test_the_emotion_shows_on_the_face():
    wave, phones = talk_and_pause()
    n = int(len(wave) / SR * 30)

    def under(label: str) -> np.ndarray:
        weights = np.zeros((n, 8), np.float32)
        weights[:, EMOTIONS.index(label)] = 1.0
        return face_track(wave, SR, n, weights, phones=phones).arkit.mean(0)

    happy, sad, angry = under("happiness"), under("sadness"), under("anger")
    assert happy[INDEX["mouthSmileLeft"]] >= sad[INDEX["mouthSmileLeft"]] + 0.1
    assert sad[INDEX["browInnerUp"]] > happy[INDEX["browInnerUp"]]
    assert angry[INDEX["browDownLeft"]] > happy[INDEX["browDownLeft"]]
    closed = face_track(wave, SR, n, np.tile(np.eye(8)[EMOTIONS.index("surprise")], (n, 1)), phones=phones).arkit
    m = phones[2]  # the jaw drop of surprise does not part the lips of an M
    assert openness(closed)[int(np.ceil(m.start * 30)) : int(m.end * 30) + 1].max() == 0.0


def test_blinks_and_gaze_are_seeded_and_human():
    n = 30 * 120
    wave = speech_like(120.0, SR, seed=3)
    a, b, c = (face_track(wave, SR, n, seed=s) for s in (0, 0, 1))
    assert np.array_equal(a.arkit, b.arkit) and not np.array_equal(a.arkit, c.arkit)
    blink = a.arkit[:, INDEX["eyeBlinkLeft"]] > 0.5
    starts = np.flatnonzero(np.diff(blink.astype(int)) == 1)
    assert 8 <= len(starts) / 2 <= 30  # per minute
    ends = np.flatnonzero(np.diff(blink.astype(int)) == -1)
    assert np.all((ends[: len(starts)] - starts[: len(ends)]) <= 0.4 * 30)
    assert a.eyes.std() > 0.01 and np.abs(a.eyes).max() <= 0.6


def test_the_npz_carries_the_face(tmp_path):
    seq = gesture_like(20)
    seq.arkit = np.random.default_rng(0).uniform(0, 1, (20, 52)).astype(np.float32)
    save_smplx_npz(seq, tmp_path / "f.npz")
    back = load_smplx_npz(tmp_path / "f.npz")
    assert np.array_equal(back.arkit, seq.arkit)
    assert list(np.load(tmp_path / "f.npz")["arkit_names"]) == list(ARKIT_NAMES)
    assert load_smplx_npz(save_smplx_npz(gesture_like(20), tmp_path / "g.npz")).arkit is None
    bad = dict(np.load(tmp_path / "f.npz"))
    bad["arkit"] = bad["arkit"][:, :40]
    np.savez(tmp_path / "bad.npz", **bad)
    with pytest.raises(InputFileError, match="bad.npz.*'arkit' must be"):
        load_smplx_npz(tmp_path / "bad.npz")


def test_generate_writes_the_face(tmp_path, capsys):
    sr = 16000
    sf.write(tmp_path / "s.wav", speech_like(6.0, sr, seed=4), sr)
    ran = cli_here(capsys, "generate", tmp_path / "s.wav", "-o", tmp_path / "out", "--face", "--format",
                   "npz,arkit", "--emotion", "happiness", "--quiet")
    assert ran.returncode == 0, ran.stderr
    seq = load_smplx_npz(next((tmp_path / "out").glob("*.npz")))
    assert len(list((tmp_path / "out").glob("*.arkit.csv"))) == 1
    assert seq.arkit is not None and seq.arkit.shape == (seq.num_frames, 52)
    assert seq.arkit[:, INDEX["mouthSmileLeft"]].mean() > 0.4
    assert seq.poses[:, 22, 0].std() > 0.01  # the jaw moves


@pytest.mark.apt
@pytest.mark.skipif(not LIBRIVOX.is_dir() or not recogniser_installed(), reason="needs pocketsphinx-testdata")
def test_lips_follow_real_read_speech():
    """Phones recognised without the words; scored against the transcript's forced alignment
    (experiments/face/lips.py, on the LibriVox clips)."""
    lips = experiment_module("face/lips")
    r = lips.checks(lips.recordings(librivox_only=True))
    assert r["bilabials"] >= 20 and r["bilabials_closed"] >= 0.8 and r["open_over_bilabial"] >= 2
    assert all(abs(lag) <= 1 for lag in r["lags"]) and r["weights_within_0_1"]
    assert r["smile_happy"] - r["smile_sad"] >= 0.1 and r["brow_down_angry"] > r["brow_down_happy"]


def test_the_live_link_csv_round_trips(tmp_path):
    import csv

    from emogesture.export import export_sequence
    from emogesture.export.arkit_csv import COLUMNS

    seq = gesture_like(40)
    seq.arkit = np.random.default_rng(1).uniform(0, 1, (40, 52)).astype(np.float32)
    path, = export_sequence(seq, tmp_path / "take", ("arkit",))
    assert path.name == "take.arkit.csv"
    rows = list(csv.reader(path.open()))
    assert tuple(rows[0]) == COLUMNS and rows[0][2] == "EyeBlinkLeft" and "JawOpen" in rows[0]
    assert len(rows) == 41 and rows[31][0] == "00:00:01:00.000" and rows[1][1] == "61"
    back = np.array([[float(v) for v in r[2:54]] for r in rows[1:]])
    assert np.abs(back - seq.arkit).max() <= 1e-4
    with pytest.raises(Exception, match="no face track"):
        export_sequence(gesture_like(5), tmp_path / "plain", ("arkit",))


def test_arkit_needs_the_face(tmp_path, capsys):
    sf.write(tmp_path / "s.wav", speech_like(2.0, SR, seed=5), SR)
    ran = cli_here(capsys, "generate", tmp_path / "s.wav", "-o", tmp_path / "out", "--format", "arkit")
    assert ran.returncode != 0 and "--face" in ran.stderr and "Traceback" not in ran.stderr
