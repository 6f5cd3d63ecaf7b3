"""Streaming with the bundled model: one frame per 1/30 s of audio whatever the chunks, joins no rougher than
offline generation, an emotion changed mid-stream that shows in the motion, calm motion from silence."""

import numpy as np
import pytest
import soundfile as sf

from emogesture.assets import DEMO_CLIPS
from emogesture.errors import EmogestureError
from emogesture.pipeline.generate import GesturePipeline
from emogesture.pipeline.stream import GestureStream
from emogesture.types import SMPLXSequence

from helpers import fk

pytestmark = pytest.mark.training


@pytest.fixture(scope="module")
def pipe():
    return GesturePipeline.from_run()


@pytest.fixture(scope="module")
def talk():
    wave, sr = sf.read(DEMO_CLIPS / "talk.flac", dtype="float32")
    assert sr == 16000
    return wave


def stream(pipe, wave, chunks, sample_rate=16000, **options):
    s = GestureStream(pipe, **options)
    out, i = [], 0
    for n in chunks:
        out += s.push(wave[i:i + n], sample_rate)
        i += n
    out += s.push(wave[i:], sample_rate) + s.end()
    assert all(a.start + len(a) == b.start for a, b in zip(out, out[1:])) and out[0].start == 0
    return (np.concatenate([f.sequence.poses for f in out]), np.concatenate([f.sequence.trans for f in out]),
            [f.start for f in out])  # where each update's frames begin: the joins


def joints(poses, trans):
    return fk(SMPLXSequence(poses=poses, trans=trans))


def largest_jump(poses, trans):
    return np.linalg.norm(np.diff(joints(poses, trans), axis=0), axis=-1).max()


def test_one_frame_per_thirtieth_of_a_second_whatever_the_chunks(pipe, talk):
    wave = talk[: int(7.37 * 16000)]
    rng = np.random.default_rng(0)
    poses, _, _ = stream(pipe, wave, rng.integers(1, 9000, 40))
    assert len(poses) == round(7.37 * 30)
    at_44k = np.interp(np.arange(int(len(wave) * 44100 / 16000)) * 16000 / 44100, np.arange(len(wave)), wave)
    poses, _, _ = stream(pipe, at_44k.astype(np.float32), [4410] * 10, sample_rate=44100)
    assert abs(len(poses) - round(7.37 * 30)) <= 1


def test_a_stream_that_fell_far_behind_still_sends_every_frame(pipe, talk):
    s = GestureStream(pipe)
    out = s.push(talk, catch_up=True) + s.end()  # 20.5 s at once: more than one window to catch up on
    assert sum(len(f) for f in out) == round(len(talk) / 16000 * 30) and len(out) >= 3
    assert all(a.start + len(a) == b.start for a, b in zip(out, out[1:]))


def test_joins_are_no_rougher_than_offline_generation(pipe, talk):
    poses, trans, starts = stream(pipe, talk, [1600] * (len(talk) // 1600))  # 100-ms chunks
    offline = pipe.generate(talk)[0]
    assert len(poses) == offline.num_frames
    # the target, at most 1.5 on average over held-out takes, is experiments/live/stream_quality.py's; one clip's
    # largest jump scatters around it (0.61-1.56 per take for the bundled model), so one clip gets 1.75
    assert largest_jump(poses, trans) <= 1.75 * largest_jump(offline.poses, offline.trans)
    steps = np.linalg.norm(np.diff(joints(poses, trans), axis=0), axis=-1).max(-1)  # [T - 1]: frame t -> t + 1
    at_joins = steps[[start - 1 for start in starts[1:]]]
    offline_steps = np.linalg.norm(np.diff(joints(offline.poses, offline.trans), axis=0), axis=-1).max(-1)
    # the joins' steps against the offline motion's: no larger than its largest, and their p90 no larger than its
    # p90 (a hard cut gives 0.48 and 0.38 against 0.11 and 0.05, a 0.1-s blend of one candidate 0.23 and 0.15).
    # Not against the stream's own p99: one of 80 ordinary frames lies above it in about half of all streams.
    assert len(at_joins) > 50 and at_joins.max() <= offline_steps.max()
    assert np.quantile(at_joins, 0.9) <= np.quantile(offline_steps, 0.9)


def test_an_emotion_changed_mid_stream_shows_in_the_motion(pipe, talk):
    wave = np.concatenate([talk, talk[: 10 * 16000]])  # 30 s
    s = GestureStream(pipe, emotion="anger")
    out = []
    for i in range(0, len(wave), 1600):
        if i == 15 * 16000:
            s.set_emotion("sadness")
        out += s.push(wave[i:i + 1600])
    out += s.end()
    j = joints(np.concatenate([f.sequence.poses for f in out]), np.concatenate([f.sequence.trans for f in out]))
    wrists = j[:, [20, 21]]
    speed = np.linalg.norm(np.diff(wrists, axis=0), axis=-1).mean(1) * 30
    height = (wrists[:, :, 1] - j[:, None, 0, 1]).mean(1)
    angry, sad = slice(60, 15 * 30), slice(15 * 30 + 45, None)  # 1.5 s for the change to take effect
    # the bundled model: anger about 1.28 times as fast as sadness, its wrists 6-7 cm higher (anger all
    # through: 0.83 and 0.4 cm)
    assert speed[angry].mean() > 1.2 * speed[sad].mean() and height[angry].mean() > height[sad].mean() + 0.05


def wrist_speed(poses, trans):
    return (np.linalg.norm(np.diff(joints(poses, trans)[:, [20, 21]], axis=0), axis=-1).mean(1) * 30).mean()


def test_silence_is_calm_and_bad_emotions_are_one_line_errors(pipe, talk):
    silence = stream(pipe, np.zeros(12 * 16000, np.float32), [1600] * 120)[:2]
    speech = stream(pipe, talk[: 12 * 16000], [1600] * 120)[:2]
    assert len(silence[0]) == 360 and wrist_speed(*silence) < 0.3 * wrist_speed(*speech)
    s = GestureStream(pipe)
    with pytest.raises(EmogestureError, match="unknown"):
        s.set_emotion("rage")
    with pytest.raises(EmogestureError, match="needs an emotion label"):
        s.set_emotion("auto", 0.5)


def test_streams_pushed_together_get_the_frames_each_gets_alone(pipe, talk):
    """push_together (the live server's batched pass) gives every stream the frames it gets pushed alone:
    different emotions, seeds and chunk sizes, so that some rounds have nothing due for some streams."""
    from emogesture.pipeline.stream import push_together

    wave = talk[: 4 * 16000]
    options = [dict(emotion="anger", seed=1), dict(emotion="sadness", seed=2), dict(seed=3)]
    chunks = [4000, 1600, 6400]

    def pieces(n):
        return [wave[i:i + n] for i in range(0, len(wave), n)]

    alone = []
    for opt, n in zip(options, chunks):
        s = GestureStream(pipe, **opt)
        alone.append([f for piece in pieces(n) for f in s.push(piece)] + s.end())
    streams = [GestureStream(pipe, **opt) for opt in options]
    queues = [pieces(n) for n in chunks]
    got = [[] for _ in options]
    while any(queues):
        jobs = [(j, (streams[j], queues[j].pop(0), 16000)) for j in range(len(streams)) if queues[j]]
        for (j, _), frames in zip(jobs, push_together([job for _, job in jobs])):
            got[j] += frames
    for j, s in enumerate(streams):
        got[j] += s.end()
        assert [f.start for f in got[j]] == [f.start for f in alone[j]] and len(got[j]) > 5
        together = np.concatenate([f.sequence.poses for f in got[j]])
        assert np.abs(together - np.concatenate([f.sequence.poses for f in alone[j]])).max() < 1e-3


def test_a_streams_filterbank_rolls_on_with_its_audio(pipe, talk):
    """Each update computes only the newest frames of its window's filterbank; what it hears is the filterbank of
    the window computed whole, whatever the pieces."""
    import torch

    from emogesture.audio import kaldi_fbank

    s = GestureStream(pipe)
    rng = np.random.default_rng(1)
    i = 0
    for n in rng.integers(1, 9000, 25):
        s.push(talk[i:i + n])
        i += n
        assert torch.equal(s._raw_fbank(), kaldi_fbank(s.audio, pipe.speech.fbank_config))


def test_a_loaded_pass_draws_one_candidate_with_fewer_steps_and_joins_smoothly(pipe, talk, monkeypatch):
    """A server with many streams draws each update once, with LOADED_STEPS DDIM steps; the motion still has a
    frame per 1/30 s and no join rougher than the offline motion allows (as the joins test asks)."""
    from emogesture.pipeline import stream as live

    drawn = []
    generate_windows = pipe.generate_windows

    def spy(conds, seeds, **kw):
        drawn.append((len(seeds), kw.get("generation")))
        return generate_windows(conds, seeds, **kw)

    monkeypatch.setattr(pipe, "generate_windows", spy)
    s = GestureStream(pipe)
    out = [f for i in range(0, len(talk), 1600) for f in live.push_together([(s, talk[i:i + 1600], 16000)],
                                                                            loaded=True)[0]] + s.end()
    assert drawn and all(n == 1 and g.num_inference_steps == live.LOADED_STEPS for n, g in drawn[:-1])
    poses = np.concatenate([f.sequence.poses for f in out])
    trans = np.concatenate([f.sequence.trans for f in out])
    monkeypatch.undo()
    offline = pipe.generate(talk)[0]
    assert len(poses) == offline.num_frames
    assert largest_jump(poses, trans) <= 1.75 * largest_jump(offline.poses, offline.trans)
