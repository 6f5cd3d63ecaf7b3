"""Real recorded speech (Debian's pocketsphinx-testdata): the recordings, and the report that holds a model's
perception and motion on them against held-out corpus takes."""

import json
import subprocess

import numpy as np
import pytest

from emogesture.data.prepare import prepare
from emogesture.data.real_speech import RECORDINGS, load_real_recording, real_recordings
from emogesture.errors import EmogestureError, InputFileError, OutputExistsError
from emogesture.eval.real_speech import evaluate_real_speech, real_speech_checks

from helpers import cli, make_root


def test_the_real_recordings_are_whole_and_leave_tidigits_out():
    found = real_recordings()
    assert [r.name for r in found] == ["librivox", "cards", "cmu", "prompts"]
    assert not any("tidigits" in c for r in RECORDINGS for c in r.clips)  # LDC data, left out
    seconds = {r.name: len(load_real_recording(r)) / 16000 for r in found}
    assert seconds == pytest.approx({"librivox": 25.93, "cards": 10.85, "cmu": 10.41, "prompts": 67.6}, abs=0.05)
    for r in found:
        wave = load_real_recording(r)
        assert wave.dtype == np.float32 and np.abs(wave).max() <= 1.01  # the mean removed from full scale
        # speech, not noise: loud 10-ms frames, and pauses an order of magnitude quieter
        frames = np.sqrt((wave[: len(wave) // 160 * 160].reshape(-1, 160) ** 2).mean(1))
        loud = np.quantile(frames, 0.9)
        assert loud > 0.05 and (frames < 0.1 * loud).mean() > 0.05


def test_missing_recordings_are_a_one_line_error(tmp_path):
    with pytest.raises(EmogestureError, match="pocketsphinx-testdata asterisk-core-sounds-en-g722"):
        real_recordings(tmp_path)
    with pytest.raises(InputFileError, match="not found"):
        load_real_recording(RECORDINGS[0], tmp_path)
    with pytest.raises(InputFileError, match="install Debian's asterisk-core-sounds-en-g722"):
        load_real_recording(RECORDINGS[-1], tmp_path)


def _checks(heard, trusted, front, distance):
    return real_speech_checks({"pooled": {"real": {"heard_share": heard, "trusted_share": trusted}},
                               "motion": {"real": {"hand_in_front_share": front[0], "wrist_distance_median": distance[0]},
                                          "reference": {"hand_in_front_share": front[1],
                                                        "wrist_distance_median": distance[1]}}})


def test_each_check_can_fail_and_pass():
    good = _checks(0.8, 0.75, (0.40, 0.45), (0.55, 0.58))
    assert all(c["pass"] for c in good.values())
    for bad in (_checks(0.6, 0.75, (0.40, 0.45), (0.55, 0.58)), _checks(0.8, 0.5, (0.40, 0.45), (0.55, 0.58)),
                _checks(0.8, 0.75, (0.24, 0.45), (0.55, 0.58)), _checks(0.8, 0.75, (0.40, 0.45), (0.65, 0.58))):
        assert sum(not c["pass"] for c in bad.values()) == 1


def test_report_of_the_bundled_model(tmp_path):
    make_root(tmp_path / "root", speakers=(1,), takes=(1, 2))  # take 2 (neutral) is the test split
    prepare(tmp_path / "root", tmp_path / "cache", progress=False)
    r = evaluate_real_speech(None, tmp_path / "cache", tmp_path / "out", "test", seeds=1, progress=False)
    assert set(r["real"]) == {"librivox", "cards", "cmu", "prompts"} and set(r["reference"]) == {"1_wayne_0_2_2"}
    assert r["pooled"]["real"]["windows"] == sum(row["windows"] for row in r["real"].values()) >= 6
    assert r["split_use"]["held_out"] and len(r["checks"]) == 4
    for row in (*r["real"].values(), *r["reference"].values()):  # each recording's own motion beside the pooled
        assert 0.0 <= row["hand_in_front_share"] <= 1.0 and 0.1 < row["wrist_distance_median"] < 1.5
    fronts = [row["hand_in_front_share"] for row in r["real"].values()]
    assert min(fronts) <= r["motion"]["real"]["hand_in_front_share"] <= max(fronts)
    assert r["motion"]["real"]["seconds"] == pytest.approx(25.93 + 10.85 + 10.41 + 67.6, abs=0.1)
    written = json.loads((tmp_path / "out" / "real_speech.json").read_text())
    assert written["checks"] == r["checks"]
    assert "| librivox | real |" in (tmp_path / "out" / "real_speech.md").read_text()
    with pytest.raises(OutputExistsError):
        evaluate_real_speech(None, tmp_path / "cache", tmp_path / "out", "test", seeds=1, progress=False)
    out = subprocess.run(cli("evaluate", "real", "--data", tmp_path / "cache", "--out", tmp_path / "o2",
                             "--seeds", "0"), capture_output=True, text=True)
    assert out.returncode != 0 and "--seeds 0" in out.stderr and "Traceback" not in out.stderr


def test_training_voices_are_other_people_and_missing_ones_are_a_one_line_error(tmp_path, monkeypatch):
    from emogesture.data import real_speech
    from emogesture.data.real_speech import TRAINING_VOICES, TrainingVoice, load_voice, real_voice

    check_folders = {r.folder for r in RECORDINGS}
    assert not any(v.folder in check_folders or "Allison" in str(v.folder) for v in TRAINING_VOICES.values())
    with pytest.raises(EmogestureError, match="unknown; known: fr_june"):
        real_voice("es_allison")
    monkeypatch.setitem(real_speech.TRAINING_VOICES, "fr_june",
                        TrainingVoice("fr_june", "", tmp_path / "nowhere", "asterisk-core-sounds-fr-g722"))
    with pytest.raises(InputFileError, match="install Debian's asterisk-core-sounds-fr-g722"):
        load_voice(real_voice("fr_june"))


def test_a_training_voice_leaves_out_damaged_and_silent_clips(tmp_path):
    import soundfile as sf

    from emogesture.data.real_speech import TrainingVoice, load_voice

    tone = (0.3 * np.sin(2 * np.pi * 220 * np.arange(8000) / 8000)).astype(np.float32)  # 1 s at 8 kHz
    (tmp_path / "silence").mkdir()
    sf.write(tmp_path / "a.wav", tone, 8000)
    (tmp_path / "b.wav").write_bytes(b"RIFF not a wave at all")  # ffmpeg's concat demuxer stops here, exit 0
    sf.write(tmp_path / "c.wav", tone[:4000], 8000)
    sf.write(tmp_path / "silence" / "1.wav", np.zeros(8000, np.float32), 8000)
    voice = TrainingVoice("fr_june", "", tmp_path, "asterisk-prompt-test", "*.wav")
    wave = load_voice(voice)
    assert abs(len(wave) - 1.5 * 16000) < 200  # a and c, resampled to 16 kHz; b and the silence left out
    (tmp_path / "a.wav").write_bytes(b"garbage")
    (tmp_path / "c.wav").write_bytes(b"garbage")
    with pytest.raises(EmogestureError, match="fr_june: ffmpeg could not decode"):
        load_voice(voice)


def test_a_voice_decoded_clip_by_clip_takes_clips_of_any_rate_and_leaves_out_damaged_ones(tmp_path):
    import soundfile as sf

    from emogesture.data.real_speech import TrainingVoice, load_voice

    t8, t22 = np.arange(8000) / 8000, np.arange(22050) / 22050
    sf.write(tmp_path / "a.wav", (0.3 * np.sin(2 * np.pi * 220 * t8)).astype(np.float32), 8000)
    (tmp_path / "b.wav").write_bytes(b"RIFF not a wave at all")
    sf.write(tmp_path / "c.wav", (0.3 * np.sin(2 * np.pi * 220 * t22[:11025])).astype(np.float32), 22050)
    voice = TrainingVoice("letters_xx", "", tmp_path, "klettres-data", "*.wav", clip_by_clip=True)
    wave = load_voice(voice)
    assert wave.dtype == np.float32 and abs(len(wave) - 1.5 * 16000) < 200  # a (8 kHz) and c (22.05 kHz); b out
    (tmp_path / "a.wav").write_bytes(b"garbage")
    (tmp_path / "c.wav").write_bytes(b"garbage")
    with pytest.raises(EmogestureError, match="letters_xx: ffmpeg could not decode"):
        load_voice(voice)


def test_training_voices_speak_every_emotion_as_the_corpus_gives_it(monkeypatch):
    from emogesture.data import real_speech
    from emogesture.data.beat import EMOTIONS
    from emogesture.data.real_speech import training_voice_emotions

    t = np.arange(40 * 16000) / 16000
    voiced = (np.sin(2 * np.pi * 3 * t) > -0.3).astype(np.float32)  # syllables and pauses
    hum = (0.1 * voiced * np.sin(2 * np.pi * 150 * t)).astype(np.float32)
    monkeypatch.setattr(real_speech, "load_voice", lambda voice: hum)
    monkeypatch.setattr(real_speech, "real_voice", lambda name: name)
    waves, labels = training_voice_emotions(["a", "b"], 2, 1.5, seed=3)
    assert labels.tolist() == list(range(8)) * 4 and all(len(w) <= 160000 and len(w) > 150000 for w in waves)
    assert np.array_equal(waves[0], hum[:160000])  # neutral as recorded
    rms = [float(np.sqrt(np.mean(w ** 2))) for w in waves[:8]]
    assert rms[EMOTIONS.index("anger")] > 1.5 * rms[0] > 1.5 * rms[EMOTIONS.index("sadness")]
    again, _ = training_voice_emotions(["a", "b"], 2, 1.5, seed=3)
    other, _ = training_voice_emotions(["a", "b"], 2, 1.5, seed=4)
    assert np.array_equal(again[1], waves[1]) and not np.array_equal(other[1], waves[1])
    with pytest.raises(EmogestureError, match="stretches 0"):
        training_voice_emotions(["a"], 0, 1.5)


def test_the_training_voices_are_whole():
    from emogesture.data.real_speech import TRAINING_VOICES, load_voice

    for name, voice in TRAINING_VOICES.items():
        if name.startswith("letters_"):
            continue
        wave = load_voice(voice)
        assert wave.dtype == np.float32 and 8 * 60 < len(wave) / 16000 < 30 * 60, name
        frames = np.sqrt((wave[: len(wave) // 160 * 160].reshape(-1, 160) ** 2).mean(1))
        assert np.quantile(frames, 0.9) > 0.02 and (frames < 0.1 * np.quantile(frames, 0.9)).mean() > 0.02, name


def test_the_list_readers_decode_clip_by_clip(tmp_path):
    """One letter reader and the word readers of each file format (Ogg Vorbis, WAV, Opus): whole, speech; the
    word readers, a validation set, are never a calibration's voices."""
    from emogesture.data.real_speech import TRAINING_VOICES, WORD_READERS, load_voice, real_voice
    from emogesture.train.perception import calibrate_perception_run

    for name in ("letters_ar", "words_en", "words_fr", "words_nn"):
        wave = load_voice(real_voice(name))
        assert wave.dtype == np.float32 and 50 < len(wave) / 16000 < 300, name
        frames = np.sqrt((wave[: len(wave) // 160 * 160].reshape(-1, 160) ** 2).mean(1))
        assert np.quantile(frames, 0.9) > 0.02 and (frames < 0.1 * np.quantile(frames, 0.9)).mean() > 0.02, name
    assert len(WORD_READERS) == 13 and not set(WORD_READERS) & set(TRAINING_VOICES)
    with pytest.raises(EmogestureError, match="real voice 'words_xx': unknown"):
        real_voice("words_xx")
    with pytest.raises(EmogestureError, match="real voice 'words_en': unknown"):
        calibrate_perception_run(tmp_path, tmp_path, tmp_path / "out", real_voices=["letters_ar", "words_en"])