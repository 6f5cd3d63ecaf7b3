"""Generation pipeline: lengths, seeds, batch independence, edits, seams, CLI errors.

Uses small untrained models written to disk (the behaviour checked here does not depend on training).
"""

from dataclasses import replace
import itertools
import subprocess
import sys

import numpy as np
import pytest
import soundfile as sf
import torch

from emogesture.checkpoints import save_model
from emogesture.errors import EmogestureError
from emogesture.eval.seams import seam_jumps
from emogesture.motion import SkeletonBody
from emogesture.pipeline.generate import EditRequest, GesturePipeline
from emogesture.pipeline.postprocess import choose_seam_candidates, largest_joint_jumps, seam_costs, stitch

from helpers import cli_here, write_tiny_runs


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    d = tmp_path_factory.mktemp("gen")
    write_tiny_runs(d)
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
    np.testing.assert_allclose(a[0].poses, b[0].poses, atol=1e-3)  # sample 0 is sample 0 however many are drawn
    assert np.array_equal(b[0].poses, pipe.generate(wave, seed=3, samples=1)[0].poses)  # same call, same output
    assert not np.allclose(a[0].poses, a[1].poses)  # samples differ
    assert np.all(a[0].poses[:, [1, 2, 4, 5, 7, 8, 10, 11]] == 0)  # lower body at rest


def test_every_sample_matches_its_own_run_and_stages_are_timed(runs):
    """All samples are drawn in one batch; sample k is what a run of that sample alone would give."""
    from emogesture.runtime import StageTimes

    pipe = GesturePipeline.from_run(runs / "gesture")
    wave = pipe.load_speech(runs / "other.wav")
    times = StageTimes()
    three = pipe.generate(wave, seed=5, samples=3, times=times)
    assert set(times) == {"fbank", "speech encoders", "sampling", "motion decoder", "seams and poses"}
    assert all(v > 0 for v in times.values())
    enc = pipe.encode(wave)
    for k in range(3):  # sample k alone: seed sequence [seed, k, window(, candidate)]
        alone = pipe.generate(wave, seed=5, samples=k + 1, encoded=enc)[k]
        # batch composition changes float rounding only
        np.testing.assert_allclose(three[k].poses, alone.poses, atol=1e-3)


def test_bf16_autocast_drifts_little_and_fp32_is_exact(runs):
    fp32 = GesturePipeline.from_run(runs / "gesture", precision="fp32")
    bf16 = GesturePipeline.from_run(runs / "gesture", precision="bf16")
    assert (fp32.precision, bf16.precision, bf16.speech.precision) == ("fp32", "bf16", "bf16")
    wave = fp32.load_speech(runs / "other.wav")
    ea, eb = fp32.encode(wave)[0], bf16.encode(wave)[0]
    assert ea.content.dtype == eb.content.dtype == np.float32
    diff = np.abs(eb.content - ea.content).max() / np.abs(ea.content).max()
    assert 0 < diff < 0.05  # bf16 was used, and stays close
    a = fp32.generate(wave, seed=1, generation=replace(fp32.generation, seam_candidates=1))[0]
    b = bf16.generate(wave, seed=1, generation=replace(bf16.generation, seam_candidates=1))[0]
    assert not np.array_equal(a.poses, b.poses)
    # (the joint drift of a trained model is checked in test_bundled_model.py: an untrained decoder's
    # near-degenerate 6D rotations magnify it)
    again = GesturePipeline.from_run(runs / "gesture", precision="fp32")
    again = again.generate(wave, seed=1, generation=replace(again.generation, seam_candidates=1))[0]
    assert np.array_equal(a.poses, again.poses)


def test_a_bf16_pipeline_holds_its_weights_in_bf16_with_the_same_numbers(runs):
    """``from_run`` under bf16 casts (and packs) the weights once, for good: generation gives the numbers
    of the per-call casts, which a pipeline built around models it does not own still makes."""
    from emogesture.checkpoints import load_model
    from emogesture.pipeline.speech import SpeechLatentEncoder
    from emogesture.runtime import packs_bf16_weights

    held = GesturePipeline.from_run(runs / "gesture", precision="bf16")
    gesture = load_model(runs / "gesture", "gesture")
    per_call = GesturePipeline(gesture, SpeechLatentEncoder(load_model(runs / "speech", "speech"), precision="bf16"),
                               precision="bf16")

    def linears(module):
        return [m for m in module.modules() if isinstance(m, torch.nn.Linear)]

    for module in (held.model.denoiser, held.model.prior, held.speech.model):
        assert all(m.weight.dtype == torch.bfloat16 for m in linears(module))
    assert all(("forward" in vars(m)) == packs_bf16_weights("cpu") for m in linears(held.model.denoiser))
    wave = held.load_speech(runs / "other.wav")
    a = held.generate(wave, seed=3, generation=replace(held.generation, seam_candidates=2))[0]
    b = per_call.generate(wave, seed=3, generation=replace(per_call.generation, seam_candidates=2))[0]
    assert np.array_equal(a.poses, b.poses) and np.array_equal(a.trans, b.trans)
    # the pipeline that does not own its models puts their float32 weights back after each call
    assert all(m.weight.dtype == torch.float32 for m in linears(per_call.model) + linears(per_call.speech.model))
    with pytest.raises(ValueError, match="holds bf16 weights"):  # rounded copies are never saved as the model
        save_model(runs / "held", "gesture", held.model, held.loaded.config)
    with pytest.raises(EmogestureError, match="holds bf16 weights"):  # nor run in float32
        GesturePipeline(held.loaded, held.speech, precision="fp32").generate(wave, seed=3)


def test_bf16_weights_cast_once_give_autocasts_numbers_and_are_put_back():
    from torch import nn

    from emogesture.runtime import autocast, bf16_weights, packs_bf16_weights

    torch.manual_seed(0)
    net = nn.Sequential(nn.Linear(8, 16), nn.LayerNorm(16), nn.GELU(), nn.Linear(16, 4, bias=False))
    x = torch.randn(5, 8)
    weights = [p for p in net.parameters()]
    with torch.inference_mode():
        with torch.autocast("cpu", dtype=torch.bfloat16):
            plain = net(x)
        with autocast("bf16", "cpu", net):
            assert net[0].weight.dtype == torch.bfloat16 and net[1].weight.dtype == torch.float32
            assert "forward" not in vars(net[0])
            cast_once = net(x)
        with bf16_weights("bf16", net, pack=True), torch.autocast("cpu", dtype=torch.bfloat16):
            # where oneDNN runs bf16 natively, the Linears run with their weights packed once
            assert ("forward" in vars(net[0])) == ("forward" in vars(net[3])) == packs_bf16_weights("cpu")
            packed = net(x)
        with autocast("fp32", "cpu", net):
            exact = net(x)
    # autocast's numbers: the same bf16 products (packed ones may sum in another order)
    assert plain.dtype == cast_once.dtype == torch.bfloat16 and exact.dtype == torch.float32
    assert torch.equal(plain, cast_once) and packed.dtype == torch.bfloat16
    assert torch.allclose(plain.float(), packed.float(), rtol=2 ** -7, atol=1e-3)
    assert not any("forward" in vars(layer) for layer in net)  # the layers' own forward is back
    assert all(a is b for a, b in zip(weights, net.parameters()))  # the float32 parameters are back
    with pytest.raises(RuntimeError, match="inside"):
        with autocast("bf16", "cpu", net):
            raise RuntimeError("inside")
    assert all(a is b for a, b in zip(weights, net.parameters()))  # also after an error


def test_device_and_precision_flags(runs, tmp_path):
    from emogesture.errors import EmogestureError
    from emogesture.runtime import native_bf16, resolve_device, resolve_precision

    assert resolve_precision("auto", "cpu") == ("bf16" if native_bf16("cpu") else "fp32")
    assert resolve_precision("fp32", "cpu") == "fp32" and resolve_precision("bf16", "cpu") == "bf16"
    assert resolve_device("cpu") == "cpu"
    with pytest.raises(EmogestureError, match="--precision 'half'"):
        resolve_precision("half", "cpu")
    with pytest.raises(EmogestureError, match="--device 'tpu'"):
        resolve_device("tpu")
    if not torch.cuda.is_available():
        out = subprocess.run([sys.executable, "-m", "emogesture.cli.main", "generate", str(runs / "other.wav"),
                              "--model", str(runs / "gesture"), "-o", str(tmp_path / "o"), "--device", "cuda"],
                             capture_output=True, text=True)
        assert out.returncode == 2 and "no CUDA GPU" in out.stderr and len(out.stderr.strip().splitlines()) == 1
        assert not (tmp_path / "o").exists()


def test_gpu_devices_are_checked_and_bf16_is_native_from_ampere_on(monkeypatch):
    """What --device cuda:N and --precision auto decide on a GPU machine, with torch's view of the GPUs
    stood in for (this machine has none): cuda:N beyond the GPUs torch sees and malformed names are
    one-line errors; bf16 counts as native from compute capability 8.0, not where torch emulates it."""
    from emogesture.errors import EmogestureError
    from emogesture.runtime import native_bf16, resolve_device

    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    monkeypatch.setattr(torch.cuda, "device_count", lambda: 2)
    assert resolve_device("cuda") == "cuda" and resolve_device("CUDA:1") == "cuda:1"
    with pytest.raises(EmogestureError, match="torch sees 2 GPUs"):
        resolve_device("cuda:2")
    for bad in ("cuda:abc", "cudax", "cuda:"):
        with pytest.raises(EmogestureError, match=f"--device '?{bad}"):
            resolve_device(bad)
    monkeypatch.setattr(torch.version, "hip", None)
    monkeypatch.setattr(torch.cuda, "is_bf16_supported", lambda including_emulation=True: True)
    for capability, native in (((7, 0), False), ((7, 5), False), ((8, 0), True), ((9, 0), True)):
        monkeypatch.setattr(torch.cuda, "get_device_capability", lambda device=None, c=capability: c)
        assert native_bf16("cuda:1") is native, capability


@pytest.mark.parametrize("before", ["default", "training", "per-operator"])
def test_float32_generation_on_a_gpu_turns_tf32_off_and_puts_it_back(before):
    """``--precision fp32`` keeps float32 exact on a GPU too: inside the inference context cuDNN's
    convolutions and the matrix products run without TF32, and torch's settings come back exactly as
    they were, whichever way they were set: torch's defaults, the training engine's
    ``float32_matmul_precision("high")``, or torch 2.9's per-operator ``fp32_precision`` (after which
    torch refuses to read its older cuDNN flag). torch checks at every product that its two ways agree,
    which the matrix products' flag read here does too."""
    from emogesture.runtime import autocast

    matmul, cudnn = torch.backends.cuda.matmul, torch.backends.cudnn
    torch_defaults = (torch.get_float32_matmul_precision(), cudnn.allow_tf32,
                      [(b, b.fp32_precision) for b in (matmul, cudnn.conv, cudnn.rnn)])
    torch.set_float32_matmul_precision("highest")
    if before == "training":
        torch.set_float32_matmul_precision("high")
    if before == "per-operator":
        cudnn.conv.fp32_precision = "tf32"
        cudnn.rnn.fp32_precision = "ieee"

    def state():
        try:
            legacy_cudnn = cudnn.allow_tf32
        except RuntimeError:
            legacy_cudnn = "unreadable"
        return (torch.get_float32_matmul_precision(), matmul.fp32_precision, matmul.allow_tf32,
                cudnn.conv.fp32_precision, cudnn.rnn.fp32_precision, legacy_cudnn)

    saved = state()
    try:
        with autocast("fp32", "cuda"):
            with autocast("fp32", "cuda:0"):  # nested (or another thread): restored when the last leaves
                pass
            assert matmul.allow_tf32 is False and cudnn.conv.fp32_precision in ("none", "ieee")
            assert state() != saved
        assert state() == saved
        with autocast("fp32", "cpu"):  # nothing changes on a CPU
            assert state() == saved
    finally:  # this process's settings as they were before the test
        torch.set_float32_matmul_precision(torch_defaults[0])
        cudnn.allow_tf32 = torch_defaults[1]
        for backend, value in torch_defaults[2]:
            backend.fp32_precision = value


def test_a_single_window_draws_one_candidate(runs):
    from emogesture.pipeline.postprocess import candidates_drawn

    assert candidates_drawn(1, 4) == 1 and candidates_drawn(2, 4) == 4
    pipe = GesturePipeline.from_run(runs / "gesture")
    wave = pipe.load_speech(runs / "long.wav")[: 10 * 16000]  # exactly one 10-s window
    drawn = []
    four = pipe.generate(wave, seed=4, generation=replace(pipe.generation, seam_candidates=4), progress=drawn.append)[0]
    assert sum(drawn) == 1
    np.testing.assert_array_equal(four.poses, pipe.generate(wave, seed=4, generation=replace(pipe.generation, seam_candidates=1))[0].poses)


def test_batch_equals_single(runs):
    pipe = GesturePipeline.from_run(runs / "gesture")
    g = np.random.default_rng(1)
    conds = [g.normal(size=(3, 256)).astype(np.float32) for _ in range(3)]
    if pipe.loaded.config.hears_timing:  # the tiny preset's decoder reads the speech's timing stream
        conds.append(g.normal(size=(3, 300, 2)).astype(np.float32))
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
    none = pipe.generate(wave, edit=EditRequest(emotion_label="anger", emotion_weight=0.0), seed=0)[0]
    assert np.allclose(none.poses, plain.poses, atol=1e-6)  # weight 0 = no edit
    half = pipe.generate(wave, edit=EditRequest(emotion_label="anger", emotion_weight=0.5), seed=0)[0]
    full = pipe.generate(wave, edit=EditRequest(emotion_label="anger", emotion_weight=1.0), seed=0)[0]
    styled = pipe.generate(wave, edit=EditRequest(style_from=other.style), seed=0)[0]
    for changed in (half, full, styled):  # a label edit with weight > 0 and a style edit change the output
        assert np.abs(changed.poses - plain.poses).max() > 1e-3
    assert not np.allclose(half.poses, full.poses)


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


def test_seam_candidates_avoid_the_worst_seam(runs):
    # window 0's candidate 0 strokes where window 1 fades in: choosing window by window from candidate 0
    # cannot avoid it, choosing the whole path does (candidate 1 everywhere: no jump at all)
    T, starts = 10, [0, 8]
    cand = np.zeros((2, 2, T, 1))
    cand[0, 0, 8:, 0] = 3.0
    cand[1, 0] = 1.0
    assert np.array_equal(choose_seam_candidates(cand, starts), cand[:, 1])
    assert np.array_equal(choose_seam_candidates(cand[:, :1], starts), cand[:, 0])
    # on random candidates the chosen path's worst seam is the smallest over every path (brute force)
    rng = np.random.default_rng(0)
    cand = rng.normal(size=(4, 3, T, 2)).cumsum(axis=2)
    # the last window ending with the audio overlaps more (the seams' cross-fades are costed in groups of
    # one length), and windows that do not overlap
    for starts in ([0, 7, 14, 21], [0, 7, 14, 18], [0, 10, 17, 30]):
        def worst(windows):
            return max(seam_costs(windows[i - 1][None], windows[i][None], starts[i - 1] + T - starts[i]).item()
                       for i in range(1, len(windows)) if starts[i - 1] + T > starts[i])

        best = min(worst([cand[i, k] for i, k in enumerate(path)]) for path in itertools.product(range(3), repeat=4))
        assert worst(choose_seam_candidates(cand, starts)) == pytest.approx(best)

    # through the pipeline: more candidates never enlarge the worst seam (candidate 0 of every window is
    # the one-candidate draw) and stay deterministic
    pipe = GesturePipeline.from_run(runs / "gesture")
    wave = pipe.load_speech(runs / "long.wav")[: 30 * 16000]
    one = pipe.generate(wave, seed=1, generation=replace(pipe.generation, seam_candidates=1))[0]
    four = pipe.generate(wave, seed=1, generation=replace(pipe.generation, seam_candidates=4))[0]
    assert np.array_equal(four.poses, pipe.generate(wave, seed=1, generation=replace(pipe.generation, seam_candidates=4))[0].poses)
    starts_s = pipe.encode(wave)[1]  # where generation places its windows, and so its seams
    with torch.no_grad():
        jumps = [seam_jumps(SkeletonBody()(torch.from_numpy(q.poses), torch.from_numpy(q.trans)).numpy(), starts_s)
                 for q in (one, four)]
    assert jumps[1]["max_seam_jump_m"] <= jumps[0]["max_seam_jump_m"] + 1e-4
    with pytest.raises(EmogestureError, match="seam_candidates"):
        pipe.generate(wave, generation=replace(pipe.generation, seam_candidates=0))


def test_largest_joint_jumps():
    joints = np.random.default_rng(0).normal(size=(2, 6, 5, 3)).astype(np.float32)
    expected = np.linalg.norm(np.diff(joints, axis=-3), axis=-1).max(axis=-1)
    np.testing.assert_allclose(largest_joint_jumps(joints), expected, rtol=1e-6)
    np.testing.assert_allclose(largest_joint_jumps(torch.from_numpy(joints)), expected, rtol=1e-6)


def test_cli_errors_are_one_line(runs, tmp_path, capsys):
    bad = tmp_path / "bad.wav"
    bad.write_bytes(b"not audio at all")
    short = tmp_path / "short.wav"
    sf.write(short, 0.1 * np.ones(1600, np.float32), 16000)
    # the process as a user runs it: its exit status and all it writes to stderr
    out = subprocess.run([sys.executable, "-m", "emogesture.cli.main", "generate", str(bad), "--model",
                          str(runs / "gesture"), "-o", str(tmp_path / "o")], capture_output=True, text=True)
    assert out.returncode == 2 and "bad.wav" in out.stderr and len(out.stderr.strip().splitlines()) == 1
    for audio, needle in ((short, "too short"), (tmp_path / "none.wav", "none.wav")):
        code, _, err = cli_here(capsys, "generate", audio, "--model", runs / "gesture", "-o", tmp_path / "o")
        assert code == 2 and needle in err and len(err.strip().splitlines()) == 1, err
    code, _, err = cli_here(capsys, "generate", runs / "other.wav", "--model", runs / "speech", "-o", tmp_path / "o")
    assert code == 2 and "'speech' model, but a 'gesture' model is needed" in err
    assert not (tmp_path / "o").exists()


def test_flags_that_would_be_ignored_are_errors(tmp_path, capsys):
    from emogesture.cli.main import main

    for extra in (["--long-audio", "30"], ["--edit-model", "ours"]):
        code = main(["evaluate", "gesture", "--data", str(tmp_path / "c"), "--extractor", str(tmp_path / "x"),
                     "--out", str(tmp_path / "r"), *extra])
        assert code == 2 and "need --model" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()


def test_quiet_windows_settle_and_speech_windows_do_not():
    from emogesture.pipeline.postprocess import settle_quiet_windows

    rng = np.random.default_rng(0)
    t = np.arange(300) / 30.0
    slow = np.sin(2 * np.pi * 0.05 * t)[:, None]  # a posture drifting over twenty seconds
    feats = (slow + 0.3 * rng.standard_normal((3, 300, 4))).astype(np.float32)  # strokes on top
    out = settle_quiet_windows(feats, np.array([1.0, 0.5, 0.0]), fps=30.0)
    assert np.array_equal(out[0], feats[0])  # a window with speech is untouched

    def speed(x):
        return np.abs(np.diff(x, axis=0)).mean()

    assert speed(out[2]) < 0.1 * speed(feats[2]) < speed(out[1]) < speed(feats[1])
    assert np.abs(out[2] - slow)[60:240].mean() < 0.1  # the silent window keeps the slow posture change
