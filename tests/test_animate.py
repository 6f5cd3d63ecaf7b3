"""Animating speech from Python (:mod:`emogesture.pipeline.animate`): the same files as ``emogesture generate``,
the request's checks, and refused outputs. Uses the bundled model and the demo clips."""

from __future__ import annotations

from dataclasses import replace

import re

import numpy as np
import pytest

from emogesture.assets import DEMO_CLIPS
from emogesture.cli.main import main
from emogesture.errors import EmogestureError, OutputExistsError
from emogesture.pipeline.animate import AnimationRequest, animate
from emogesture.pipeline.generate import GesturePipeline

TALK, ANGRY = DEMO_CLIPS / "talk.flac", DEMO_CLIPS / "angry.flac"


@pytest.fixture(scope="module")
def pipe(one_thread):
    return GesturePipeline.from_run(None, device="cpu", precision="fp32")


def test_animate_writes_the_bytes_the_command_writes(pipe, tmp_path, capsys):
    reported, written = [], []
    request = AnimationRequest(TALK, tmp_path / "py", emotion_from=ANGRY, emotion_weight=0.5, formats=("npz",),
                               generation=replace(pipe.generation, seam_candidates=2))
    result = animate(pipe, request, report=reported.append, written=lambda path, seq: written.append(path))
    assert capsys.readouterr().out == ""  # the library prints nothing
    code = main(["generate", str(TALK), "-o", str(tmp_path / "cli"), "--emotion-from", str(ANGRY),
                 "--emotion-weight", "0.5", "--format", "npz", "--seam-candidates", "2", "--device", "cpu",
                 "--precision", "fp32", "--quiet"])  # the fixture's device and precision
    assert code == 0
    stdout = capsys.readouterr().out.splitlines()

    names = ["talk_emotion-angry_seed0_0.npz", "talk_emotion-angry_seed0_perception.json"]
    for folder in ("py", "cli"):
        assert sorted(p.name for p in (tmp_path / folder).iterdir()) == names
    for name in names:
        assert (tmp_path / "py" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes(), name
    assert result.files == [[tmp_path / "py" / names[0]]] and written == result.files[0]
    assert result.perception_path == tmp_path / "py" / names[1]
    assert [p.source for p in result.perceived] == [str(TALK), str(ANGRY)]
    assert reported == result.summaries and len(result.sequences) == 1
    heard = pipe.load_speech(TALK)  # the speech as heard comes back (the app plays it with the 3D view)
    assert result.speech is not None and np.array_equal(result.speech, heard)
    seq = result.sequences[0]
    assert stdout == [*reported, f"{tmp_path / 'cli' / names[0]}  ({seq.num_frames} frames, {seq.duration:.2f} s)",
                      str(tmp_path / "cli" / names[1])]


@pytest.mark.parametrize("kwargs, needle", [
    ({"emotion_weight": 0.5}, "--emotion-weight needs --emotion LABEL or --emotion-from WAV"),
    ({"emotion": "own", "emotion_weight": 0.5}, "--emotion-weight needs"),
    ({"emotion": "anger", "emotion_weight": 1.5}, "--emotion-weight 1.5: must be between 0 and 1"),
    ({"emotion_from": ANGRY, "emotion_weight": -0.1}, "must be between 0 and 1"),
    ({"samples": 0}, "--samples must be at least 1"),
    ({"emotion": "joy"}, "--emotion 'joy': unknown"),
    ({"emotion": "anger", "emotion_from": ANGRY}, "choose one target emotion"),
    ({"formats": ("npz", "gif")}, "--format 'npz,gif'"),
])
def test_a_bad_request_is_one_line_naming_the_problem(tmp_path, kwargs, needle):
    with pytest.raises(EmogestureError, match=re.escape(needle)) as err:
        AnimationRequest(TALK, tmp_path / "o", **kwargs)
    assert "\n" not in str(err.value)
    assert not (tmp_path / "o").exists()


def test_out_must_be_a_folder_and_a_changed_request_is_checked_again(pipe, tmp_path):
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    with pytest.raises(EmogestureError, match="a_file: is a file; --out must be a folder"):
        AnimationRequest(TALK, a_file)
    request = AnimationRequest(TALK, tmp_path / "o")
    request.samples = 0
    with pytest.raises(EmogestureError, match="--samples must be at least 1"):
        animate(pipe, request)
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("taken", ["talk_style-angry_seed3_perception.json", "talk_style-angry_seed3_1.bvh"])
def test_existing_outputs_are_refused_and_nothing_is_written(pipe, tmp_path, taken):
    out = tmp_path / "out"
    out.mkdir()
    (out / taken).write_text("the user's file")
    request = AnimationRequest(TALK, out, style_from=ANGRY, formats="npz,bvh", seed=3, samples=2)
    with pytest.raises(OutputExistsError, match="already exists"):
        animate(pipe, request)
    assert [p.name for p in out.iterdir()] == [taken] and (out / taken).read_text() == "the user's file"


@pytest.mark.parametrize("kwargs, tag, emotion", [
    ({}, "", "emotion: own (auto)"),
    ({"emotion": " Happiness"}, "_emotion-happiness", "emotion: happiness"),
    ({"emotion": "own", "style_from": "b/calm.wav"}, "_style-calm_own", "emotion: own (own)"),
    ({"emotion_from": ANGRY, "emotion_weight": 0.25, "style_from": "calm.wav"}, "_emotion-angry_style-calm",
     "emotion from angry.flac x0.25"),
    ({"neutral_from": "b/calm.wav"}, "_neutral-calm", "emotion: own (auto) against calm.wav"),
    ({"emotion": "anger", "neutral_from": "calm.wav"}, "_emotion-anger_neutral-calm", "emotion: anger"),
])
def test_output_names_and_video_label(tmp_path, kwargs, tag, emotion):
    request = AnimationRequest("a/talk.flac", tmp_path, seed=7, samples=2, **kwargs)
    assert request.tag == tag
    assert request.stems() == [tmp_path / f"talk{tag}_seed7_{k}" for k in (0, 1)]
    assert request.perception_path == tmp_path / f"talk{tag}_seed7_perception.json"
    style = "style from calm.wav" if "style_from" in kwargs else f"style: own ({request.mode})"
    assert request.video_label(1) == f"talk.flac\n{emotion}  |  {style}\nseed 7, sample 1"
