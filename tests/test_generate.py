"""Generation pipeline: lengths, seeds, batch independence, edits, seams, CLI errors.

Uses small untrained models written to disk (the behaviour checked here does not depend on training).
"""

import subprocess
import sys

import numpy as np
import pytest
import soundfile as sf
import torch

from emogesture.checkpoints import save_model
from emogesture.config import to_dict
from emogesture.data.beat import EMOTIONS
from emogesture.data.prepare import PrepareConfig
from emogesture.errors import EmogestureError
from emogesture.models.gesture import GestureModel, GestureModelConfig
from emogesture.models.speech import SpeechDisentangler, SpeechModelConfig
from emogesture.pipeline.generate import EditRequest, GesturePipeline, choose_seam_candidates, stitch


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    d = tmp_path_factory.mktemp("gen")
    torch.manual_seed(0)
    scfg = SpeechModelConfig.preset("tiny", num_speakers=2)
    speech_json = save_model(d / "speech", "speech", SpeechDisentangler(scfg), scfg, {
        "emotions": list(EMOTIONS), "speakers": [1, 2], "fbank_mean": -9.0, "fbank_std": 5.0,
        "prepare_config": to_dict(PrepareConfig()), "step": 0})
    gcfg = GestureModelConfig.preset("tiny")
    gcfg.diffusion.num_inference_steps = 5
    import json
    sha = json.loads(speech_json.read_text())["weights_sha256"]
    save_model(d / "gesture", "gesture", GestureModel(gcfg), gcfg, {
        "emotions": list(EMOTIONS), "motion_mean": [0.0] * 282, "motion_std": [0.3] * 282,
        "features": to_dict(PrepareConfig().features), "variant": "joint", "fps": 30,
        "speech_model": str(speech_json), "speech_weights_sha256": sha,
        "emotion_latent_means": {e: [float(i)] * 256 for i, e in enumerate(EMOTIONS)}, "step": 0})
    rng = np.random.default_rng(0)
    t = np.arange(int(65 * 16000)) / 16000
    wave = (0.3 * np.sin(2 * np.pi * 180 * t) * (np.sin(2 * np.pi * 1.5 * t) > 0) + 0.01 * rng.normal(size=t.size))
    sf.write(d / "long.wav", wave.astype(np.float32), 16000)
    sf.write(d / "other.wav", wave[: 12 * 16000][::-1].astype(np.float32), 16000)
    return d


def test_length_determinism_and_samples(runs):
    pipe = GesturePipeline.from_run(runs / "gesture")
    wave = pipe.load_speech(runs / "long.wav")
    a = pipe.generate(wave, seed=3, samples=2)
    assert [s.num_frames for s in a] == [1950, 1950]  # round(65 s * 30)
    assert a[0].poses.shape == (1950, 55, 3)
    b = pipe.generate(wave, seed=3, samples=1)
    assert np.array_equal(a[0].poses, b[0].poses)  # same seed, same output
    assert not np.allclose(a[0].poses, a[1].poses)  # samples differ
    assert np.all(a[0].poses[:, [1, 2, 4, 5, 7, 8, 10, 11]] == 0)  # lower body at rest


def test_batch_equals_single(runs):
    pipe = GesturePipeline.from_run(runs / "gesture")
    g = np.random.default_rng(1)
    conds = [g.normal(size=(3, 256)).astype(np.float32) for _ in range(3)]
    batch = pipe.generate_windows(conds, [11, 22, 33])
    single = pipe.generate_windows([c[1:2] for c in conds], [22])
    np.testing.assert_allclose(batch[1], single[0], atol=1e-5)


def test_identity_edit_reproduces_the_unedited_output(runs):
    pipe = GesturePipeline.from_run(runs / "gesture")
    wave = pipe.load_speech(runs / "long.wav")
    plain = pipe.generate(wave, seed=0)[0]
    own = pipe.encode(wave)[0]
    edit = EditRequest(emotion_from=own.emotion, style_from=own.style)
    assert np.allclose(pipe.generate(wave, edit=edit, seed=0)[0].poses, plain.poses, atol=1e-6)
    other = pipe.encode_file_latents(runs / "other.wav")
    edited = pipe.generate(wave, edit=EditRequest(emotion_from=other.emotion), seed=0)[0]
    assert not np.allclose(edited.poses, plain.poses)
    half = pipe.generate(wave, edit=EditRequest(emotion_label="anger", emotion_weight=0.0), seed=0)[0]
    assert np.allclose(half.poses, plain.poses, atol=1e-6)  # weight 0 = no edit


def test_stitch_crossfades_without_jumps():
    rng = np.random.default_rng(0)
    T, starts, n = 300, [0, 240, 480, 720], 1020
    # independent smooth windows with different offsets: raw seams would jump by ~1
    windows = np.stack([np.cumsum(rng.normal(0, 0.01, (T, 4)), 0) + rng.normal(0, 1, 4) for _ in starts])
    out = stitch(windows, starts, n)
    assert out.shape == (n, 4)
    jumps = np.abs(np.diff(out, axis=0)).max(1)
    inside = np.abs(np.diff(windows, axis=1)).max(2).ravel()
    assert jumps.max() < 5 * np.percentile(inside, 99)  # no raw-offset jump (~1) survives
    np.testing.assert_allclose(out[:200], windows[0][:200])  # outside overlaps a window is copied exactly


def test_seam_candidates_continue_the_previous_window(runs):
    # window 1's candidate 2 starts where window 0 ends; window 2's candidate 1 continues that one
    T, starts = 10, [0, 8, 16]
    cand = np.full((3, 3, T, 1), 5.0)
    cand[0, 0, :, 0] = np.arange(T)
    cand[1, 2, :, 0] = 8 + np.arange(T)
    cand[1, 0, :, 0] = 0.0
    cand[2, 1, :, 0] = 16 + np.arange(T)
    chosen = choose_seam_candidates(cand, starts)
    assert np.array_equal(chosen[:, 0, 0], [0.0, 8.0, 16.0])
    assert np.array_equal(choose_seam_candidates(cand[:, :1], starts), cand[:, 0])
    # through the pipeline: one candidate is the old behaviour, more candidates never enlarge the
    # mismatch between neighbouring windows and stay deterministic
    pipe = GesturePipeline.from_run(runs / "gesture")
    wave = pipe.load_speech(runs / "long.wav")[: 30 * 16000]
    one = pipe.generate(wave, seed=1, seam_candidates=1)[0]
    four = pipe.generate(wave, seed=1, seam_candidates=4)[0]
    assert np.array_equal(four.poses, pipe.generate(wave, seed=1, seam_candidates=4)[0].poses)
    np.testing.assert_allclose(one.poses[:200], four.poses[:200])  # window 0 is candidate 0 either way
    with pytest.raises(EmogestureError, match="seam_candidates"):
        pipe.generate(wave, seam_candidates=0)


def test_cli_errors_are_one_line(runs, tmp_path):
    bad = tmp_path / "bad.wav"
    bad.write_bytes(b"not audio at all")
    silent = tmp_path / "silent.wav"
    sf.write(silent, np.zeros(32000, np.float32), 16000)
    for audio, needle in ((bad, "bad.wav"), (silent, "silent"), (tmp_path / "none.wav", "none.wav")):
        out = subprocess.run([sys.executable, "-m", "emogesture.cli.main", "generate", str(audio), "--model",
                              str(runs / "gesture"), "-o", str(tmp_path / "o")], capture_output=True, text=True)
        assert out.returncode == 2 and needle in out.stderr and len(out.stderr.strip().splitlines()) == 1
    out = subprocess.run([sys.executable, "-m", "emogesture.cli.main", "generate", str(runs / "other.wav"), "--model",
                          str(runs / "speech"), "-o", str(tmp_path / "o")], capture_output=True, text=True)
    assert out.returncode == 2 and "'speech' model, but a 'gesture' model is needed" in out.stderr
