"""Emotion along a timeline: keyframes parsed with one-line errors, windows sharing the keyframes in force,
and on a minute of real speech, anger then sadness moves the wrists faster and higher in the first half."""

import json
import subprocess

import numpy as np
import pytest
import soundfile as sf

from emogesture.data.real_speech import RECORDINGS, load_real_recording
from emogesture.errors import EmogestureError
from emogesture.motion import load_smplx_npz
from emogesture.pipeline.animate import AnimationRequest
from emogesture.pipeline.timeline import EmotionTimeline, Keyframe, timeline_latents

from helpers import cli, fk


def test_keyframes_parse_and_the_first_starts_at_zero():
    t = EmotionTimeline.parse("12:Anger, 30:sadness@0.5")
    assert t.keyframes == (Keyframe(0, "auto"), Keyframe(12, "anger"), Keyframe(30, "sadness", 0.5))
    assert t.text == "0:auto,12:anger,30:sadness@0.5" and t.tag == "0s-auto_12s-anger_30s-sadnessx0.5"
    assert t.in_force(29.9).label == "anger" and t.in_force(30).label == "sadness"
    assert EmotionTimeline.parse("0:own").keyframes == (Keyframe(0, "own"),)


@pytest.mark.parametrize("text, message", [
    ("0:neutral,5:rage", "keyframe '5:rage': unknown label 'rage'"),
    ("0:neutral,12:anger,10:sadness", "keyframe '10:sadness': times must increase (10 s after 12 s)"),
    ("0:neutral,12:anger,12:sadness", "times must increase"),
    ("0:anger@1.5", "keyframe '0:anger@1.5': weight 1.5 must be between 0 and 1"),
    ("0:anger@-0.1", "weight -0.1 must be between 0 and 1"),
    ("0:auto@0.5", "a weight blends toward a label; auto takes none"),
    ("zero:anger", "keyframe 'zero:anger': expected TIME:LABEL"),
    ("0:anger,,5:fear", "keyframe '': expected TIME:LABEL"),
    ("-3:anger", "TIME in seconds from 0"),
    ("0:anger@lots", "expected TIME:LABEL or TIME:LABEL@WEIGHT"),
])
def test_bad_keyframes_are_one_line_errors(text, message):
    with pytest.raises(EmogestureError, match=message.replace("(", r"\(").replace(")", r"\)")) as err:
        AnimationRequest("talk.wav", "out", emotion=text)
    assert "\n" not in str(err.value)


def test_a_timeline_takes_no_other_emotion_edit_and_must_fit_the_recording():
    with pytest.raises(EmogestureError, match="takes no --emotion-from or --emotion-weight"):
        AnimationRequest("talk.wav", "out", emotion="0:anger", emotion_weight=0.5)
    with pytest.raises(EmogestureError, match="keyframe '70:sadness' starts after the end of talk.wav \\(60.0 s\\)"):
        EmotionTimeline.parse("0:anger,70:sadness").check_duration(60.0, "talk.wav")


def test_windows_take_the_keyframes_by_the_time_each_holds():
    t = EmotionTimeline.parse("0:anger,12:sadness@0.5,30:own")
    shares = t.shares([0.0, 7.0, 14.0, 28.0], 10.0, 35.0)
    np.testing.assert_allclose(shares, [[1, 0, 0], [0.5, 0.5, 0], [0, 1, 0], [0, 2 / 7, 5 / 7]], atol=1e-9)
    own, auto = np.full((4, 2), 1.0), np.full((4, 2), 3.0)
    means = {"anger": [10.0, 10.0], "sadness": [-10.0, -10.0]}
    mixed = timeline_latents(t, shares, own, auto, means)
    np.testing.assert_allclose(mixed[:, 0], [10.0, 0.5 * 10 + 0.5 * (0.5 * 3 - 5), -3.5, 2 / 7 * -3.5 + 5 / 7 * 1.0],
                               rtol=1e-6)
    assert t.window_report(shares)[1] == {"anger": 0.5, "sadness x0.5": 0.5}


@pytest.fixture(scope="module")
def real_minute(tmp_path_factory):
    wave = np.concatenate([load_real_recording(r) for r in (*RECORDINGS, RECORDINGS[0])])[: 60 * 16000]
    path = tmp_path_factory.mktemp("real") / "minute.wav"
    sf.write(path, wave, 16000)
    return path


def wrist_speed_and_height(npz):
    """Mean wrist speed (m/s) and height above the pelvis (m) in the first and the second half, leaving out
    5 s on both sides of the middle."""
    seq = load_smplx_npz(npz)
    joints = fk(seq)
    wrists = joints[:, [20, 21]]
    speed = np.linalg.norm(np.diff(wrists, axis=0), axis=-1).mean(1) * seq.fps
    height = (wrists[:, :, 1] - joints[:, None, 0, 1]).mean(1)
    half, gap = len(joints) // 2, int(5 * seq.fps)
    return [(speed[part].mean(), height[part].mean()) for part in (slice(0, half - gap), slice(half + gap, None))]


def test_anger_then_sadness_on_a_minute_of_real_speech(real_minute, tmp_path):
    found = {}
    for timeline in ("0:anger,30:sadness", "0:sadness,30:anger"):
        out = subprocess.run(cli("generate", real_minute, "-o", tmp_path, "--emotion", timeline, "--format", "npz",
                                 "--quiet"), capture_output=True, text=True)
        assert out.returncode == 0, out.stderr
        tag = EmotionTimeline.parse(timeline).tag
        found[timeline] = wrist_speed_and_height(tmp_path / f"minute_emotion-{tag}_seed0_0.npz")
        report = json.loads((tmp_path / f"minute_emotion-{tag}_seed0_perception.json").read_text())
        first, second = timeline.split(",")[0][2:], timeline.split(",")[1][3:]
        assert report[0]["windows"][0]["animated_emotion"] == {first: 1.0}
        assert report[0]["windows"][-1]["animated_emotion"] == {second: 1.0}
    (angry_first, sad_later), (sad_first, angry_later) = found["0:anger,30:sadness"], found["0:sadness,30:anger"]
    # each half of the speech under either emotion: faster and higher wrists where it is angry (the halves say
    # different things, so one half's anger is not measured against the other half's sadness)
    for angry, sad in ((angry_first, sad_first), (angry_later, sad_later)):
        assert angry[0] > 1.5 * sad[0] and angry[1] > sad[1] + 0.05
