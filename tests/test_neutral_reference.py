"""A neutral reference of the same speaker (``generate --neutral-from``): the speech read against it."""

from __future__ import annotations

from dataclasses import replace

import json

import numpy as np
import pytest
import soundfile as sf

from emogesture.assets import DEMO_CLIPS
from emogesture.cli.main import main
from emogesture.data.beat import EMOTIONS
from emogesture.errors import EmogestureError
from emogesture.pipeline.neutral_reference import NeutralReference
from emogesture.pipeline.perception import heard_probabilities, perceive
from emogesture.train.perception import fit_perception
from emogesture.pipeline.speech import EncodedWindows

NEUTRAL = EMOTIONS.index("neutral")


def voice(n_per: int, seed: int, offset: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Emotion latents ``[8 n, 48]`` around eight emotion centres, the whole voice moved by ``offset`` along
    one direction, and their emotions."""
    rng = np.random.default_rng(seed)
    centres = np.random.default_rng(7).normal(0, 3, (len(EMOTIONS), 48))
    direction = np.random.default_rng(8).normal(0, 1, 48)
    labels = np.repeat(np.arange(len(EMOTIONS)), n_per)
    return (centres[labels] + rng.normal(0, 1, (len(labels), 48)) + offset * direction).astype(np.float32), labels


def windows(emotion: np.ndarray, logits: np.ndarray | None = None) -> EncodedWindows:
    n = len(emotion)
    style = np.random.default_rng(n).normal(0, 1, (n, 48)).astype(np.float32)  # one familiar voice
    return EncodedWindows(np.zeros((n, 4), np.float32), emotion, style,
                          np.zeros((n, len(EMOTIONS)), np.float32) if logits is None else logits,
                          np.zeros((n, 2), np.float32))


@pytest.fixture(scope="module")
def perception():
    train, labels = voice(60, 0)
    held, _ = voice(20, 1)
    return fit_perception(windows(train), labels, np.zeros(len(labels), int), windows(held))


def test_a_voice_read_against_its_own_neutral_is_heard_as_the_corpus_would_be(perception):
    speech, labels = voice(10, 2, offset=2.5)  # a voice whose every emotion lies apart from the corpus's
    calm, _ = voice(10, 3, offset=2.5)
    reference = NeutralReference.of(windows(calm[labels == NEUTRAL]), perception, "calm.wav")
    enc = windows(speech)
    relative = reference.relative(enc)
    alone = heard_probabilities(enc, perception).argmax(1)
    against = heard_probabilities(relative, perception).argmax(1)
    assert np.mean(alone == labels) < 0.6 < 0.9 < np.mean(against == labels)
    # the reference read against itself lies on the corpus's neutral mean; nothing else moves
    np.testing.assert_allclose(reference.relative(windows(calm[labels == NEUTRAL])).emotion.mean(0),
                               perception.neutral(), atol=1e-4)
    for name in ("content", "style", "emotion_logits", "speaker_logits"):
        assert getattr(relative, name) is getattr(enc, name)
    # what is heard is the mean of both hearings; the trust is that of the latents the gesture model gets
    both = heard_probabilities(enc, perception, relative)
    np.testing.assert_allclose(both, 0.5 * (heard_probabilities(enc, perception)
                                            + heard_probabilities(relative, perception)), rtol=1e-6)
    heard = perceive(enc, [0.0] * len(enc.emotion), perception, "talk.wav", relative, "calm.wav")
    np.testing.assert_array_equal(heard.trust, perception.trust(relative.emotion, relative.style))
    assert "read against the speaker's neutral voice in calm.wav" in heard.details("auto")
    assert "against calm.wav;" in heard.summary("auto")
    assert json.loads(heard.to_json())["neutral_reference"] == "calm.wav"
    assert "neutral_reference" not in json.loads(perceive(enc, [0.0] * len(enc.emotion), perception, "t").to_json())
    # a recording mostly beyond the range (generate then points to --neutral-from); one within it is not
    far = windows(speech + 50.0)
    assert perceive(far, [0.0] * len(speech), perception, "far.wav").unlike_training_voices
    near, _ = voice(10, 5)
    assert not perceive(windows(near), [0.0] * len(near), perception, "n.wav").unlike_training_voices


def test_each_hearing_is_read_against_the_reference_heard_the_same_way(perception):
    calm, labels = voice(5, 4)
    calm = calm[labels == NEUTRAL]
    ref = windows(calm)
    ref.shifted_emotion = np.stack([calm + 1.0, calm - 2.0])
    ref.shifted_logits = np.zeros((2, len(calm), len(EMOTIONS)), np.float32)
    reference = NeutralReference.of(ref, perception, "calm.wav")
    assert reference.shifted_offsets.shape == (2, 48) and reference.windows == len(calm)
    enc = windows(calm[:2])
    enc.shifted_emotion = np.stack([calm[:2] + 1.0, calm[:2] - 2.0])
    enc.shifted_logits = np.zeros((2, 2, len(EMOTIONS)), np.float32)
    moved = reference.relative(enc)
    np.testing.assert_allclose(moved.shifted_emotion - moved.emotion[None], 0.0, atol=1e-4)
    once = NeutralReference.of(windows(calm), perception, "calm.wav")  # heard once: one offset for all
    np.testing.assert_allclose(once.relative(enc).shifted_emotion - enc.shifted_emotion,
                               np.broadcast_to(once.offset, (2, 2, 48)), atol=1e-5)


def test_a_reference_needs_a_calibrated_perception_and_latents(perception):
    with pytest.raises(EmogestureError, match=r"^calm\.wav: a neutral reference needs a speech model with a "
                                              r"perception calibration"):
        NeutralReference.of(windows(np.zeros((2, 48), np.float32)), None, "calm.wav")
    with pytest.raises(EmogestureError, match="calm.wav: no emotion latents"):
        NeutralReference.of(windows(np.zeros((0, 48), np.float32)), perception, "calm.wav")


def test_generate_reads_the_speech_against_the_neutral_recording(tmp_path, capsys, one_thread):
    talk, calm = tmp_path / "talk.wav", tmp_path / "calm.wav"
    wave, rate = sf.read(DEMO_CLIPS / "talk.flac", dtype="float32")
    sf.write(talk, wave[: 13 * rate], rate)  # (a short request: the page's work is what is tested)
    sf.write(calm, wave[-10 * rate:], rate)  # its last 10 s, as a recording of the same voice
    args = ["generate", str(talk), "--format", "npz", "--seam-candidates", "1", "--device", "cpu", "--quiet"]
    assert main([*args, "-o", str(tmp_path)]) == 0
    assert main([*args, "-o", str(tmp_path), "--neutral-from", str(calm)]) == 0
    out = capsys.readouterr().out
    assert "heard" in out and "against calm.wav;" in out  # the one-line summary names the reference
    plain = np.load(tmp_path / "talk_seed0_0.npz")["poses"]
    against = np.load(tmp_path / "talk_neutral-calm_seed0_0.npz")["poses"]
    assert plain.shape == against.shape and np.abs(plain - against).max() > 1e-3  # the gesture model hears it
    report = json.loads((tmp_path / "talk_neutral-calm_seed0_perception.json").read_text())
    assert report[0]["neutral_reference"] == str(calm)
    sf.write(tmp_path / "short.wav", wave[:3 * rate], rate)
    sf.write(tmp_path / "silent.wav", np.zeros(12 * rate, np.float32), rate)
    for name, problem in (("missing.wav", "missing.wav"), ("short.wav", "too short: 3.00 s, at least 10 s"),
                          ("silent.wav", "audio is silent")):
        assert main([*args, "-o", str(tmp_path / "x"), "--neutral-from", str(tmp_path / name)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and name in err[0] and problem in err[0], err
    assert not (tmp_path / "x").exists() or not any((tmp_path / "x").iterdir())  # nothing written


def test_a_calm_stretch_of_the_speech_itself_is_a_reference_too(tmp_path, capsys, one_thread):
    talk, calm = DEMO_CLIPS / "talk.flac", tmp_path / "calm.wav"  # 20.475 s at 16 kHz
    wave, rate = sf.read(talk, dtype="float32")
    sf.write(calm, wave[-10 * rate:], rate)
    args = ["generate", str(talk), "--format", "npz", "--seam-candidates", "1", "--device", "cpu", "--quiet"]
    assert main([*args, "-o", str(tmp_path), "--neutral-from", str(calm)]) == 0
    assert main([*args, "-o", str(tmp_path), "--neutral-span", "10.475-20.475", "--verbose"]) == 0
    out = capsys.readouterr().out
    assert "against talk.flac 10.475-20.475 s;" in out
    assert "read against the speaker's neutral voice in" in out  # --verbose: the details under the summary
    assert max(len(line) for line in out.splitlines() if "seed0" not in line) <= 160
    from_file = np.load(tmp_path / "talk_neutral-calm_seed0_0.npz")["poses"]
    from_span = np.load(tmp_path / "talk_neutral-talk-10.475-20.475s_seed0_0.npz")["poses"]
    np.testing.assert_allclose(from_span, from_file, atol=1e-5)  # the same samples, the same reference
    assert main([*args, "-o", str(tmp_path), "--neutral-from", str(calm), "--neutral-span", "0-10"]) == 0  # of it
    for span, problem in (("0-5", "--neutral-span 0-5: 5 s; a neutral reference needs at least 10 s"),
                          ("5-abc", "--neutral-span '5-abc': START-END in seconds"),
                          ("12-2", "--neutral-span 12-2: START-END in seconds, START >= 0"),
                          ("5-30", f"{talk}: 20.5 s long; the neutral span 5-30 s lies beyond its end")):
        assert main([*args, "-o", str(tmp_path / "x"), "--neutral-span", span]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and problem in err[0], err
    assert not (tmp_path / "x").exists() or not any((tmp_path / "x").iterdir())  # nothing written


def test_generate_suggests_a_reference_only_for_its_own_emotion_of_an_unfamiliar_voice(tmp_path, monkeypatch,
                                                                                        one_thread):
    from emogesture.pipeline.animate import NEUTRAL_HINT, AnimationRequest, animate
    from emogesture.pipeline.generate import GesturePipeline
    from emogesture.pipeline.perception_report import PerceivedEmotion

    pipe = GesturePipeline.from_run(None, device="cpu")
    one = replace(pipe.generation, seam_candidates=1)
    talk = DEMO_CLIPS / "talk.flac"
    plain = animate(pipe, AnimationRequest(talk, tmp_path / "a", formats="npz", generation=one))
    assert not any(NEUTRAL_HINT in line for line in plain.summaries)  # the demo voice is a familiar one
    monkeypatch.setattr(PerceivedEmotion, "unlike_training_voices", property(lambda self: True))
    unfamiliar = animate(pipe, AnimationRequest(talk, tmp_path / "b", formats="npz", generation=one))
    assert unfamiliar.summaries[0].endswith(NEUTRAL_HINT)
    label = animate(pipe, AnimationRequest(talk, tmp_path / "c", emotion="anger", formats="npz", generation=one))
    assert not any(NEUTRAL_HINT in line for line in label.summaries)


def test_the_web_page_takes_a_neutral_recording_too(tmp_path, one_thread):
    from emogesture.app.page import AppSession
    from emogesture.pipeline.generate import GesturePipeline

    talk, calm = tmp_path / "talk.wav", tmp_path / "calm.wav"
    wave, rate = sf.read(DEMO_CLIPS / "talk.flac", dtype="float32")
    sf.write(talk, wave[: 13 * rate], rate)  # (a short request: the page's work is what is tested)
    sf.write(calm, wave[-10 * rate:], rate)
    (tmp_path / "work").mkdir()
    session = AppSession(GesturePipeline.from_run(None, device="cpu"), tmp_path / "work")
    session.formats = ("npz", "glb", "mp4")
    video, _, rows, summary, files = session.run(str(talk), "auto", "", 1.0, None, None, 0, 1, "smplx",
                                                 neutral_from=str(calm))
    assert "_neutral-calm_" in video and rows
    assert "against calm.wav" in summary and str(tmp_path) not in summary
    video, _, _, summary, _ = session.run(str(talk), "auto", "", 1.0, None, None, 0, 1, "smplx",
                                          neutral_span=" 3-13 ")  # a calm stretch of the speech itself
    assert "_neutral-talk-3-13s_" in video
    assert "read against the speaker's neutral voice in talk.wav 3-13 s" in summary, summary  # the details too


def test_a_stream_reads_the_speech_against_the_reference_from_its_next_update(one_thread):
    from dataclasses import replace

    from emogesture.pipeline.generate import GesturePipeline
    from emogesture.pipeline.stream import GestureStream

    pipe = GesturePipeline.from_run(None, device="cpu")
    wave = sf.read(DEMO_CLIPS / "talk.flac", dtype="float32")[0]
    reference = pipe.neutral_reference(wave[-10 * 16000:], "calm")
    still = replace(reference, offset=np.zeros_like(reference.offset))  # a reference that moves nothing

    def frames(ref, switch_at: int | None = None) -> np.ndarray:
        stream = GestureStream(pipe, neutral_reference=None if switch_at is not None else ref)
        out = []
        for k, start in enumerate(range(0, 3 * 16000, 8000)):
            if k == switch_at:
                stream.set_neutral_reference(ref)
            out += stream.push(wave[start:start + 8000])
        return np.concatenate([f.sequence.poses for f in out])

    plain = frames(None)
    np.testing.assert_allclose(frames(still), plain, atol=1e-6)
    against = frames(reference)
    assert against.shape == plain.shape and np.abs(against - plain).mean() > 1e-3
    later = frames(reference, switch_at=4)  # set after 2 s: the frames before are the plain stream's
    np.testing.assert_allclose(later[:60], plain[:60], atol=1e-6)
    assert np.abs(later[60:] - plain[60:]).mean() > 1e-3
