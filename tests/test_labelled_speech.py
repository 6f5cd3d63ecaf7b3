"""Emotion-labelled real speech a user holds: layouts, the speaker split, the manifest and its errors, the
recordings joined per speaker and emotion, and a model's report on them."""

import subprocess

import numpy as np
import pytest
import soundfile as sf

from emogesture.data.labelled_speech import (assign_speaker_splits, labelled_recordings, manifest_text,
                                             read_manifest, scan_layout)
from emogesture.errors import EmogestureError, InputFileError

from helpers import cli, cli_here, make_root


def _clip(path, seconds=1.5, f0=150.0):
    path.parent.mkdir(parents=True, exist_ok=True)
    t = np.arange(int(seconds * 16000)) / 16000
    sf.write(path, (0.3 * np.sin(2 * np.pi * f0 * t) * (np.sin(2 * np.pi * 3 * t) > 0)).astype(np.float32), 16000)
    return path


def _ravdess(root, actors=(1, 2, 3, 4, 5), seconds=1.5):
    for actor in actors:
        for emotion in ("01", "02", "05"):  # neutral, calm (no counterpart here), angry
            for statement in ("01", "02"):
                _clip(root / f"Actor_{actor:02d}" / f"03-01-{emotion}-01-{statement}-01-{actor:02d}.wav", seconds,
                      120.0 + 30 * actor + int(emotion))
        _clip(root / f"Actor_{actor:02d}" / f"03-02-05-01-01-01-{actor:02d}.wav")  # song: left out
        _clip(root / f"Actor_{actor:02d}" / "notes.wav")  # another name: left out


def test_layouts_name_emotions_and_speakers(tmp_path):
    _ravdess(tmp_path / "ravdess", actors=(1, 2))
    clips = scan_layout("ravdess", tmp_path / "ravdess")
    assert len(clips) == 8 and {c.speaker for c in clips} == {"actor01", "actor02"}
    assert {c.emotion for c in clips} == {"neutral", "anger"} and all(c.split == "train" for c in clips)
    for name in ("1001_DFA_ANG_XX", "1001_IEO_HAP_HI", "1002_DFA_NEU_XX", "1002_DFA_XYZ_XX"):
        _clip(tmp_path / "crema" / "AudioWAV" / f"{name}.wav")
    clips = scan_layout("crema-d", tmp_path / "crema")
    assert [(c.speaker, c.emotion) for c in clips] == [("1001", "anger"), ("1001", "happiness"), ("1002", "neutral")]
    _clip(tmp_path / "own" / "ana" / "Sad" / "a.wav")
    _clip(tmp_path / "own" / "ana" / "bored" / "b.wav")  # no emotion of the corpus: left out
    _clip(tmp_path / "own" / "ben" / "surprised" / "c.flac")
    clips = scan_layout("folders", tmp_path / "own")
    assert [(c.speaker, c.emotion) for c in clips] == [("ana", "sadness"), ("ben", "surprise")]
    with pytest.raises(InputFileError, match="no recordings named as the crema-d layout"):
        scan_layout("crema-d", tmp_path / "own")
    with pytest.raises(EmogestureError, match="layout 'beat': unknown"):
        scan_layout("beat", tmp_path / "own")
    calm = scan_layout("ravdess", tmp_path / "ravdess", calm="neutral")  # RAVDESS's calm heard as neutral
    assert len(calm) == 12 and [c.emotion for c in calm].count("neutral") == 8
    with pytest.raises(EmogestureError, match="calm 'sad': one of drop, neutral"):
        scan_layout("ravdess", tmp_path / "ravdess", calm="sad")


def test_speakers_are_split_whole_and_by_the_seed(tmp_path):
    _ravdess(tmp_path / "r")
    clips = scan_layout("ravdess", tmp_path / "r")
    split = assign_speaker_splits(clips, 1, 2, seed=0)
    where = {}
    for c in split:
        where.setdefault(c.speaker, set()).add(c.split)
    assert all(len(s) == 1 for s in where.values())
    assert sorted(s.pop() for s in where.values()) == ["test", "test", "train", "train", "val"]
    assert assign_speaker_splits(clips, 1, 2, seed=0) == split
    others = [assign_speaker_splits(clips, 1, 2, seed=s) for s in range(1, 6)]
    assert any(o != split for o in others)  # the seed decides who is held out
    with pytest.raises(EmogestureError, match="5 speakers cannot give 3 val and 2 test"):
        assign_speaker_splits(clips, 3, 2)
    # speakers named (a published split, one balanced by sex), or named beside a count drawn from the rest
    named = assign_speaker_splits(clips, ["actor02", "actor03"], ["actor05"])
    assert {c.speaker: c.split for c in named} == {"actor01": "train", "actor02": "val", "actor03": "val",
                                                   "actor04": "train", "actor05": "test"}
    mixed = {c.speaker: c.split for c in assign_speaker_splits(clips, 1, ["actor01"], seed=3)}
    assert mixed["actor01"] == "test" and list(mixed.values()).count("val") == 1
    with pytest.raises(EmogestureError, match="speaker 'actor09': none of the recordings"):
        assign_speaker_splits(clips, ["actor09"], 1)
    with pytest.raises(EmogestureError, match="named for both val and test"):
        assign_speaker_splits(clips, ["actor01"], ["actor01"])


def test_the_manifest_round_trip_and_its_errors(tmp_path, capsys):
    _ravdess(tmp_path / "data" / "r")
    out = tmp_path / "data" / "labels.csv"
    run = subprocess.run(cli("labelled-speech", "ravdess", tmp_path / "data" / "r", "--out", out,
                             "--val-speakers", "1", "--test-speakers", "1"), capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert "20 recordings of 5 speakers (train 3, val 1, test 1); anger 10, neutral 10" in run.stdout
    assert out.read_text().splitlines()[1].startswith("r/Actor_")  # relative to the manifest's folder
    clips = read_manifest(out)
    assert clips == assign_speaker_splits(scan_layout("ravdess", tmp_path / "data" / "r"), 1, 1)
    again = cli_here(capsys, "labelled-speech", "ravdess", tmp_path / "data" / "r", "--out", out)
    assert again.returncode != 0 and "exists" in again.stderr and "Traceback" not in again.stderr
    text = out.read_text()
    for broken, message in ((text.replace("path,emotion", "file,emotion"), "its first line must be"),
                            (text.replace(",anger,", ",furious,", 1), "line [0-9]+: emotion 'furious' unknown"),
                            (text.replace(",train\n", ",dev\n", 1), "split 'dev'"),
                            (text.replace("r/Actor_", "r/Nobody_", 1), "line 2: recording .* not found"),
                            (text.replace(",val\n", ",train\n", 1), "is in more than one split")):
        (tmp_path / "data" / "bad.csv").write_text(broken)
        with pytest.raises(InputFileError, match=message):
            read_manifest(tmp_path / "data" / "bad.csv")
    with pytest.raises(InputFileError, match="manifest not found"):
        read_manifest(tmp_path / "none.csv")


def test_recordings_are_joined_per_speaker_and_emotion_and_repeated_to_length(tmp_path):
    _ravdess(tmp_path / "r", actors=(1, 2), seconds=1.0)
    clips = scan_layout("ravdess", tmp_path / "r")
    recordings = labelled_recordings(clips, "train")
    assert list(recordings) == ["actor01_anger", "actor01_neutral", "actor02_anger", "actor02_neutral"]
    wave, emotion = recordings["actor01_anger"]
    assert emotion == "anger" and len(wave) == pytest.approx(2.3 * 16000, abs=2)  # two clips and a gap
    long = labelled_recordings(clips, "train", min_seconds=11.0)["actor01_anger"][0]
    assert len(long) >= 11 * 16000 and np.allclose(long[: len(wave)], wave)
    with pytest.raises(EmogestureError, match="no recording of the val split"):
        labelled_recordings(clips, "val")


def test_manifest_paths_outside_its_folder_stay_absolute(tmp_path):
    _ravdess(tmp_path / "r", actors=(1,))
    clips = scan_layout("ravdess", tmp_path / "r")
    text = manifest_text(clips, tmp_path / "elsewhere")
    assert text.splitlines()[1].startswith(str(tmp_path / "r"))


def test_report_on_labelled_speakers_never_trained_on(tmp_path, capsys):
    make_root(tmp_path / "root", speakers=(1,), takes=(1, 2))  # take 2 (neutral) is the test split
    from emogesture.data.prepare import prepare

    prepare(tmp_path / "root", tmp_path / "cache", progress=False)
    for actor in (1, 2, 3):
        for statement in range(4):
            _clip(tmp_path / "r" / f"03-01-01-01-{statement:02d}-01-{actor:02d}.wav", 3.0, 110.0 + 20 * actor)
    manifest = tmp_path / "labels.csv"
    assert cli_here(capsys, "labelled-speech", "ravdess", tmp_path / "r", "--out", manifest, "--val-speakers", "1",
                    "--test-speakers", "1").returncode == 0
    out = cli_here(capsys, "evaluate", "real", "--data", tmp_path / "cache", "--out", tmp_path / "report",
                   "--labelled", manifest, "--seeds", "1")
    assert out.returncode == 0, out.stderr[-2000:]
    md = (tmp_path / "report" / "real_speech.md").read_text()
    val = [c.speaker for c in read_manifest(manifest) if c.split == "val"][0]
    assert f"| {val}_neutral | real |" in md and "its val speakers, never trained on" in md
    rows = [line for line in md.splitlines() if line.startswith("| actor")]
    assert len(rows) == 1  # one speaker, one emotion; the packaged recordings not among them
