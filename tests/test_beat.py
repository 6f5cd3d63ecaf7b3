"""BEAT/BEAT2 conventions: names, emotions, splits, sem files, TextGrids, text groups."""

import pytest

from emogesture.data.beat import (
    EMOTIONS,
    actor_split,
    format_take_name,
    group_takes_by_text,
    parse_take_name,
    read_sem,
    read_split_csv,
    read_textgrid_words,
    sem_frame_scores,
    write_split_csv,
)
from emogesture.errors import InputFileError

# Range boundaries of every emotion (docs/design.md, 'Data'), inclusive.
BOUNDARIES = {
    "neutral": (1, 64),
    "happiness": (65, 72),
    "anger": (73, 80),
    "sadness": (81, 86),
    "contempt": (87, 94),
    "surprise": (95, 102),
    "fear": (103, 110),
    "disgust": (111, 118),
}


def test_label_order():
    assert EMOTIONS == tuple(BOUNDARIES)


@pytest.mark.parametrize("emotion", list(BOUNDARIES))
def test_every_take_id_of_each_range_maps_to_its_emotion(emotion):
    lo, hi = BOUNDARIES[emotion]
    for take in range(lo, hi + 1):
        info = parse_take_name(f"2_scott_0_{take}_{take}")
        assert info.emotion_name == emotion, take
        assert EMOTIONS[info.emotion] == emotion


def test_range_edges_explicitly():
    expected = {1: 0, 64: 0, 65: 1, 72: 1, 73: 2, 80: 2, 81: 3, 86: 3, 87: 4, 94: 4, 95: 5, 102: 5,
                103: 6, 110: 6, 111: 7, 118: 7}
    for take, label in expected.items():
        assert parse_take_name(f"5_stewart_0_{take}_{take}").emotion == label


def test_conversations_are_neutral_and_fields_parse():
    info = parse_take_name("10_kieks_1_9_9")
    assert (info.speaker_id, info.speaker, info.take_type, info.take, info.end) == (10, "kieks", 1, 9, 9)
    assert info.emotion_name == "neutral" and not info.is_speech
    # the emotion comes from the take id, not the speaker id or the end field
    assert parse_take_name("2_scott_0_103_103").emotion_name == "fear"
    assert parse_take_name("/x/y/2_scott_0_81_81.npz").emotion_name == "sadness"


@pytest.mark.parametrize("bad", ["scott_0_1_1", "2_scott_0_1", "2_Scott_0_1_1", "2_scott_0_119_119", "", "a.wav"])
def test_unknown_patterns_are_clear_errors(bad):
    with pytest.raises(ValueError, match="take|range"):
        parse_take_name(bad)


def test_format_round_trip():
    assert format_take_name(2, 103) == "2_scott_0_103_103"
    assert parse_take_name(format_take_name(30, 111)).speaker == "katya"


def test_actor_split():
    assert actor_split("11_nidal_0_1_1") == "val"
    assert actor_split("22_luqi_0_65_65") == "test"
    assert actor_split("2_scott_0_65_65") == "train"


def test_split_csv_round_trip_and_errors(tmp_path):
    table = {"2_scott_0_1_1": "train", "2_scott_0_65_65": "test", "3_solomon_0_1_1": "val"}
    p = tmp_path / "train_test_split.csv"
    write_split_csv(p, table)
    assert p.read_text().splitlines()[0] == "id,type"
    assert read_split_csv(p) == table
    bad = tmp_path / "bad.csv"
    bad.write_text("name,split\nx,train\n")
    with pytest.raises(InputFileError, match="bad.csv"):
        read_split_csv(bad)
    with pytest.raises(InputFileError, match="missing.csv"):
        read_split_csv(tmp_path / "missing.csv")


def test_sem_to_frame_scores(tmp_path):
    p = tmp_path / "2_scott_0_1_1.txt"
    p.write_text("beat\t0.50\t1.00\t0.50\t0.8\thello\ndeictic\t2.0\t2.5\t0.5\t0.3\tthere\n")
    segs = read_sem(p)
    assert [s.kind for s in segs] == ["beat", "deictic"]
    scores = sem_frame_scores(segs, 90, fps=30)
    assert scores.shape == (90,)
    assert scores[14] == 0 and scores[15] == pytest.approx(0.8) and scores[29] == pytest.approx(0.8)
    assert scores[30] == 0 and scores[60] == pytest.approx(0.3) and scores[75] == 0
    assert scores.sum() == pytest.approx(15 * 0.8 + 15 * 0.3)
    bad = tmp_path / "bad.txt"
    bad.write_text("beat\tnot-a-number\n")
    with pytest.raises(InputFileError, match="bad.txt"):
        read_sem(bad)


def test_textgrid_words(tmp_path):
    p = tmp_path / "t.TextGrid"
    p.write_text(
        'File type = "ooTextFile"\nObject class = "TextGrid"\n\nxmin = 0\nxmax = 2\ntiers? <exists>\nsize = 1\n'
        'item []:\n    item [1]:\n        class = "IntervalTier"\n        name = "words"\n        xmin = 0\n'
        '        xmax = 2\n        intervals: size = 3\n        intervals [1]:\n            xmin = 0\n'
        '            xmax = 0.5\n            text = ""\n        intervals [2]:\n            xmin = 0.5\n'
        '            xmax = 1.2\n            text = "hello"\n        intervals [3]:\n            xmin = 1.2\n'
        '            xmax = 2\n            text = "world"\n'
    )
    assert read_textgrid_words(p) == [(0.5, 1.2, "hello"), (1.2, 2.0, "world")]


def test_group_takes_by_text():
    names = ["2_scott_0_65_65", "1_wayne_0_65_65", "2_scott_0_66_66", "3_solomon_0_65_65", "2_scott_1_65_65"]
    groups = group_takes_by_text(names)
    assert [i.speaker for i in groups[(0, 65)]] == ["wayne", "scott", "solomon"]
    assert len(groups[(0, 66)]) == 1 and len(groups[(1, 65)]) == 1
