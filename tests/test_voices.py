"""The synthetic corpus's voices: one per BEAT speaker, every one of them speaks, two families held out of the
training actors, formant scaling that leaves the pitch, and the split by text and actor together."""

from __future__ import annotations

import numpy as np
import pytest

from emogesture.data.beat import ACTOR_SPLIT, SPEAKERS, actor_split, format_take_name, write_split_csv
from emogesture.data.prepare import assign_splits
from emogesture.data.synthetic.factors import VOICES, Prosody, make_speaker
from emogesture.data.synthetic.speech import run_engine


def _family(voice) -> str:
    if voice.name.endswith("_diphone"):
        return "festival diphone"
    if "klatt" in voice.name:
        return "espeak-ng klatt"
    return voice.engine


def test_one_voice_per_speaker_and_two_families_never_heard_in_training():
    assert len(VOICES) == len(SPEAKERS) == 30
    assert len({(v.engine, v.name) for v in VOICES}) == 30  # thirty different voices
    held_out = set(ACTOR_SPLIT["val"]) | set(ACTOR_SPLIT["test"])
    train = {_family(make_speaker(0, k).voice) for k in SPEAKERS if SPEAKERS[k] not in held_out}
    test = {_family(make_speaker(0, k).voice) for k in SPEAKERS if SPEAKERS[k] in ACTOR_SPLIT["test"]}
    assert {"festival diphone", "espeak-ng klatt"} <= test and not train & {"festival diphone", "espeak-ng klatt"}
    assert {"flite", "espeak-ng", "festival"} <= train


def _f0(x: np.ndarray, sr: int = 16000) -> float:
    """Median autocorrelation pitch of the loud 40-ms frames (Hz)."""
    win, out = int(0.04 * sr), []
    for i in range(0, len(x) - win, sr // 100):
        fr = x[i: i + win] * np.hanning(win)
        if np.sqrt((fr ** 2).mean()) < 0.05 * np.abs(x).max():
            continue
        ac = np.correlate(fr, fr, "full")[win - 1:]
        k = sr // 400 + int(np.argmax(ac[sr // 400: sr // 60]))
        if ac[k] > 0.4 * ac[0]:
            out.append(sr / k)
    return float(np.median(out))


def _centroid(x: np.ndarray, sr: int = 16000) -> float:
    spec = np.abs(np.fft.rfft(x)) ** 2
    freq = np.fft.rfftfreq(len(x), 1 / sr)
    keep = freq < 4000
    return float((spec[keep] * freq[keep]).sum() / spec[keep].sum())


def test_every_voice_speaks_and_formants_move_without_the_pitch(tmp_path):
    text = "Please remember to bring the blue folder to the meeting on Monday morning."
    for voice in VOICES:
        x = run_engine(text, voice, Prosody(), 1.0, tmp_path)
        assert len(x) > 16000 and np.abs(x).max() > 0.01, voice
    espeak = next(v for v in VOICES if v.engine == "espeak-ng")
    low, high = (run_engine(text, espeak, Prosody(), 1.0, tmp_path, formant=f) for f in (0.92, 1.08))
    assert _f0(high) == pytest.approx(_f0(low), rel=0.06)  # the pitch stays
    assert _centroid(high) > 1.05 * _centroid(low)  # the spectrum moves up with the formants


def test_split_by_text_and_actor_holds_out_either(tmp_path):
    takes = [format_take_name(s, t) for s in (1, 11, 22) for t in (1, 2, 3)]
    by_text = {t: {"1": "train", "2": "val", "3": "test"}[t.rsplit("_", 1)[1]] for t in takes}
    write_split_csv(tmp_path / "train_test_split.csv", by_text)
    both = assign_splits(tmp_path, takes, "csv+actor")
    for t in takes:
        pair = {by_text[t], actor_split(t)}
        assert both[t] == ("test" if "test" in pair else "val" if "val" in pair else "train")
    assert [t for t in takes if both[t] == "train"] == [format_take_name(1, 1)]
    assert assign_splits(tmp_path, takes, "actor") == {t: actor_split(t) for t in takes}
