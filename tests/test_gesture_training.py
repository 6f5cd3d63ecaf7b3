"""Gesture-model training and model evaluation through the command line, on a small fixture.

The short version of experiments/gesture_model/gesture_model.sh: every variant trains a few steps, then
``evaluate gesture --model`` generates with all of them and writes the Table-1 report and the checks.
Also unit tests of the pieces of that report (seam jumps, edit targets, checks).
"""

from dataclasses import replace
import dataclasses
import json
import subprocess

import numpy as np
import pytest

from emogesture.checkpoints import load_model, save_model
from emogesture.data.beat import write_split_csv
from emogesture.data.cache import open_cache
from emogesture.data.prepare import prepare
from emogesture.errors import EmogestureError
from emogesture.models.generation import GenerationConfig
from emogesture.models.speech import SpeechDisentangler, SpeechModelConfig
from emogesture.train.runs import RunOptions, train_extractor, train_gesture
from emogesture.train.speech import speech_model_metadata

from helpers import cli, cli_here, make_root

VARIANTS = ("joint", "disjoint", "no_prior", "no_audio")
TINY_RESIDUAL_SCALE = GenerationConfig.preset("tiny").residual_scale
SMALL = ("--set", "batch_size=4", "--set", "align_ddim_steps=2", "--set", "align_every=1",
         "--set", "disjoint_prior_steps=2", "--set", "prior_warmup_steps=2",
         "--set", "generation.num_inference_steps=3")

#: the paper preset (ε-prediction, no timing stream, no residual noise, 50 DDIM steps) with narrow networks
PAPER_AT_TINY_WIDTH = ("--set", "batch_size=4", "--set", "align_ddim_steps=2", "--set", "model.vae.width=32",
                       "--set", "model.vae.layers=3", "--set", "model.vae.ff_dim=64", "--set", "model.vae.heads=2",
                       "--set", "model.vae.dropout=0", "--set", "model.denoiser.width=256",
                       "--set", "model.denoiser.layers=3", "--set", "model.denoiser.ff_dim=64",
                       "--set", "model.denoiser.dropout=0")


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    d = tmp_path_factory.mktemp("gesture")
    names = make_root(d / "root", speakers=(1, 2), takes=(1, 2, 3, 65, 66, 67))
    split_of = {"3": "test", "67": "test", "2": "val"}  # val: the held-out windows of the residual calibration
    write_split_csv(d / "root" / "train_test_split.csv", {n: split_of.get(n.split("_")[3], "train") for n in names})
    prepare(d / "root", d / "cache", progress=False)
    cache = open_cache(d / "cache")
    cfg = SpeechModelConfig.preset("tiny", num_speakers=2)
    save_model(d / "speech", "speech", SpeechDisentangler(cfg), cfg, speech_model_metadata(cache, [1, 2], 0, ["train"]))
    run = train_extractor(d / "cache", d / "ext", options=RunOptions(steps=5, progress=False))  # as a library call
    assert run.model == d / "ext" / "model.json" and run.step == 5
    # the joint variant through the command; the others as library calls in this process (no start-up each)
    out = subprocess.run(cli("train", "gesture", "--variant", "joint", "--data", d / "cache", "--speech", d / "speech",
                             "--out", d / "joint", "--steps", 4, "--checkpoint-every", 2, "--log-every", 1, "--quiet",
                             *SMALL), capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-2000:]
    options = RunOptions(steps=4, checkpoint_every=2, log_every=1, progress=False)
    for variant in VARIANTS[1:]:
        train_gesture(d / "cache", d / variant, speech=d / "speech", variant=variant, overrides=SMALL[1::2],
                      options=options)
    # the decoder hears the speech's timing
    train_gesture(d / "cache", d / "timing", speech=d / "speech", overrides=(*SMALL[1::2], "model.vae.timing_features=2"),
                  options=options)
    # the paper's design, at a CPU test's width
    train_gesture(d / "cache", d / "paper", speech=d / "speech", preset="paper", overrides=PAPER_AT_TINY_WIDTH[1::2],
                  options=RunOptions(steps=4, progress=False))
    return d


def test_every_variant_trains_and_logs_its_terms(trained):
    expected = {"joint": {"rec", "vrec", "kl", "ld", "align", "valign"},
                "disjoint": {"rec", "vrec", "kl", "ld"},
                "no_prior": {"rec", "vrec", "ld", "align", "valign"},
                "no_audio": {"rec", "vrec", "kl", "ld", "align", "valign", "audio_rec"}}
    for variant in VARIANTS:
        header = (trained / variant / "logs" / "metrics.csv").read_text().splitlines()[0].split(",")
        logged = {h.removeprefix("train/") for h in header if h.startswith("train/")}
        assert logged == expected[variant], variant
        model = load_model(trained / variant, "gesture")
        assert model.config.variant == variant and model.metadata.step == 4
    means = load_model(trained / "joint", "gesture").metadata.emotion_latent_means
    assert set(means) == {"neutral", "happiness"} and len(means["neutral"]) == 256


def test_training_as_a_library_call_refuses_what_the_command_refuses(trained, tmp_path):
    with pytest.raises(EmogestureError, match="a trained speech model is needed"):
        train_gesture(trained / "cache", tmp_path / "g")
    with pytest.raises(EmogestureError, match="precision 'half'"):
        train_extractor(trained / "cache", tmp_path / "x", options=RunOptions(precision="half"))
    again = train_extractor(trained / "cache", trained / "ext", options=RunOptions(steps=5, progress=False))
    assert again.step == 5  # the same call again resumes the finished run


def truth_stretches(r: dict) -> int:
    return len(r["long_audio"]["ground_truth"]["per_stretch"])


def test_evaluate_models_writes_table_checks_and_long_audio(trained, tmp_path, capsys):
    d = trained
    args = ["evaluate", "gesture", "--data", d / "cache", "--extractor", d / "ext", "--out", tmp_path / "r",
            "--long-audio", 30]
    for name, variant in (("ours", "joint"), ("disjoint", "disjoint"), ("no prior", "no_prior"),
                          ("no audio model", "no_audio"), ("with timing", "timing")):
        args += ["--model", f"{name}={d / variant}"]
    out = cli_here(capsys, *args)
    assert out.returncode == 0, out.stderr[-3000:]
    r = json.loads((tmp_path / "r" / "gesture_models_test.json").read_text())
    rows = r["table"]["rows"]
    assert {"GT", "mean pose", "ours", "ours, emotion edit", "disjoint", "no prior", "no audio model"} <= set(rows)
    assert rows["ours"]["FGD"] > 0 and np.isfinite(rows["ours"]["GA"])
    assert rows["ours"]["FGD"] < rows["mean pose"]["FGD"] and rows["ours"]["Div"] > 0  # it moves, unlike the mean pose
    use = r["table"]["split_use"]  # every part named with its training splits; test held out
    assert use["held_out"] and use["trained_on"]["ours"] == ["train"] and use["trained_on"]["extractor"] == ["train"]
    assert r["long_audio"]["expected_frames"] == 900
    assert r["long_audio"]["candidates_1"]["frames"] == r["long_audio"]["candidates_4"]["frames"] == 900
    assert r["long_audio"]["candidates_1"]["seeds"] == 4  # unselected windows: four draws' seam jumps pooled
    stretches = r["long_audio"]["stretches"]  # over stretches starting at different takes
    assert r["long_audio"]["candidates_1"]["stretches"] == len(stretches) == truth_stretches(r) >= 2
    assert stretches[0]["takes"] == r["long_audio"]["takes"] and stretches[1]["takes"][0] != stretches[0]["takes"][0]
    assert sum(v["seam_jumps"] for v in stretches) == r["long_audio"]["candidates_1"]["seam_jumps"]
    truth = r["long_audio"]["ground_truth"]  # the seam statistics of the same stretches' real motion
    assert 0 < truth["p99_seam_jump_m"] <= truth["max_seam_jump_m"]
    assert truth["takes"] >= 1 and truth["seam_jumps"] > 0 and 0 <= truth["seam_share_above_p99"] <= 1
    whole = r["long_audio"]["every_take"]  # every take generated whole, next to its ground truth
    assert whole["takes"] == whole["ground_truth"]["takes"] >= 1 and whole["seam_jumps"] > 0
    assert len(r["long_audio"]["emotions"]) == len(r["long_audio"]["takes"])
    assert set(r["prior_reconstruction"]) == {"mean pose", "ours", "disjoint", "no audio model", "with timing"}
    assert "FGD / FGD(no prior) < 1" in r["checks"] and "GA / GA(GT) >= 0.7" in r["checks"]
    md = (tmp_path / "r" / "gesture_models_test.md").read_text()
    assert "## Checks" in md and "| ours, emotion edit |" in md and "generated whole" in md
    # the rhythm gain of every source, the timing model's control with another window's stream
    assert "with timing, timing stream of another window" in rows
    assert rows["mean pose"]["Rhythm"] == 0.0 and all(np.isfinite(row["Rhythm"]) for row in rows.values())
    assert set(rows["GT"]["rhythm"]["mismatched"]) >= {"other window, draw 0", "shifted 1 s"}
    assert "rhythm: the ground truth's gain / its spread >= 5" in r["checks"]
    assert "rhythm: no audio model, |gain| within 3 spreads of 0" in r["checks"]
    assert set(whole["rhythm"]) == {"ours", "ground truth"} and "## Rhythm" in md
    # outputs are never replaced silently
    again = cli_here(capsys, *args)
    assert again.returncode != 0 and "--overwrite" in again.stderr and len(again.stderr.strip().splitlines()) == 1


def test_generation_is_seeded_and_batch_independent(trained):
    from emogesture.pipeline.sampling import generate_from_conditions, window_seeds

    model = load_model(trained / "joint", "gesture")
    rng = np.random.default_rng(0)
    conds = [rng.normal(size=(5, 256)).astype(np.float32) for _ in range(3)]
    conds.append(rng.normal(size=(5, 300, 2)).astype(np.float32))  # the tiny decoder's timing stream
    a = generate_from_conditions(model, conds, window_seeds(1, 5), batch_size=5)
    b = generate_from_conditions(model, conds, window_seeds(1, 5), batch_size=2)
    c = generate_from_conditions(model, conds, window_seeds(2, 5), batch_size=5)
    assert np.allclose(a, b, atol=1e-5) and not np.allclose(a, c)
    # the model's DDIM η is used: stochastic steps (η = 1) draw from the same per-window seeds
    model.config.diffusion.eta = 1.0
    try:
        d = generate_from_conditions(model, conds, window_seeds(1, 5), batch_size=5)
        e = generate_from_conditions(model, conds, window_seeds(1, 5), batch_size=2)
    finally:
        model.config.diffusion.eta = 0.0
    assert np.allclose(d, e, atol=1e-5) and not np.allclose(a, d)


def test_training_ends_with_a_residual_calibration_on_val(trained, tmp_path, capsys):
    from emogesture.checkpoints import content_checksum, file_sha256, model_paths
    from emogesture.pipeline.sampling import generate_from_conditions, window_seeds
    from safetensors.torch import load_file, save_file

    val_windows = len(open_cache(trained / "cache").split("val"))
    for variant in VARIANTS:
        model = load_model(trained / variant, "gesture")
        stats = model.metadata.residual_calibration
        assert stats["split"] == "val" and stats["windows"] == val_windows and stats["step"] == 4, variant
        assert model.model.calibrated and model.generation.residual_scale == TINY_RESIDUAL_SCALE > 0
    model = load_model(trained / "joint", "gesture")
    rng = np.random.default_rng(1)
    conds = [rng.normal(size=(3, 256)).astype(np.float32) for _ in range(3)]
    conds.append(rng.normal(size=(3, 300, 2)).astype(np.float32))  # the tiny decoder's timing stream
    plain = generate_from_conditions(model, conds, window_seeds(0, 3), residual=False)
    noisy = generate_from_conditions(model, conds, window_seeds(0, 3))
    assert not np.allclose(plain, noisy)
    # `calibrate gesture` writes a calibrated copy (never over an existing model); with the training seed it
    # measures what training stored (the last step's checkpoint is saved before the weight average's last
    # update, so the export when training ends must measure again)
    same = cli_here(capsys, "calibrate", "gesture", "--model", trained / "joint", "--data", trained / "cache",
                    "--out", tmp_path / "same")
    assert same.returncode == 0, same.stderr[-2000:]
    np.testing.assert_allclose(load_model(tmp_path / "same", "gesture").model.latent_residual_tril.numpy(),
                               model.model.latent_residual_tril.numpy(), atol=1e-5)
    args = ["calibrate", "gesture", "--model", trained / "joint", "--data", trained / "cache", "--out", tmp_path / "cal",
            "--seed", 3, "--scale", 0.5]
    out = cli_here(capsys, *args)
    assert out.returncode == 0 and f"{val_windows} val windows" in out.stdout, out.stderr[-2000:]
    copy = load_model(tmp_path / "cal", "gesture")
    assert copy.generation.residual_scale == 0.5 and copy.metadata.residual_calibration["seed"] == 3
    again = cli_here(capsys, *args)
    assert again.returncode != 0 and "--overwrite" in again.stderr
    # ... and a model file from before calibration existed loads uncalibrated: no residual noise
    weights, meta_path = model_paths(tmp_path / "cal")
    state = load_file(str(weights))
    del state["latent_residual_tril"]
    save_file(state, str(weights))
    meta = json.loads(meta_path.read_text())
    meta["weights_sha256"] = file_sha256(weights)
    meta["checksum_sha256"] = content_checksum(meta)
    meta_path.write_text(json.dumps(meta))
    old = load_model(tmp_path / "cal", "gesture")
    assert not old.model.calibrated
    np.testing.assert_allclose(generate_from_conditions(old, conds, window_seeds(0, 3)),
                               generate_from_conditions(old, conds, window_seeds(0, 3), residual=False))


def test_a_model_that_hears_timing_generates_from_speech_and_its_stream_matters(trained):
    from emogesture.audio import load_audio
    from emogesture.eval.split_latents import model_conditions
    from emogesture.pipeline.sampling import (emotion_label_edit, generate_from_conditions,
                                                reconstruct_motion, window_seeds)
    from emogesture.pipeline.generate import GesturePipeline
    from emogesture.pipeline.speech import SpeechLatentEncoder

    model = load_model(trained / "timing", "gesture")
    assert model.config.hears_timing and model.config.vae.timing_features == 2
    assert model.metadata.residual_calibration["split"] == "val"  # calibrated with its stream
    cache = open_cache(trained / "cache")
    conds = model_conditions(model, cache, "test", SpeechLatentEncoder.of_gesture_model(model))
    assert len(conds) == 4 and conds[3].shape == (len(conds[0]), 300, 2)
    seeds = window_seeds(0, len(conds[0]))
    own = generate_from_conditions(model, conds, seeds, residual=False)
    other = generate_from_conditions(model, [*conds[:3], np.roll(conds[3], 40, axis=1)], seeds, residual=False)
    assert not np.allclose(own, other)  # the stream changes the motion, all else equal
    # the generation settings (guidance, output smoothing and low-pass) act at generation only, never on
    # the prior's reconstruction; smoothing and the low-pass lower the frame-to-frame change
    g = model.generation
    assert (g.timing_guidance, g.timing_guidance_on) == (6.0, "onsets")  # the tiny preset's
    assert (g.output_smoothing, g.output_lowpass_hz) == (0.0, 4.0)

    def settings(guidance, smoothing, cutoff):
        return dataclasses.replace(g, timing_guidance=guidance, output_smoothing=smoothing, output_lowpass_hz=cutoff)

    made = {}
    for setting in ((1.0, 0.0, 0.0), (3.0, 0.0, 0.0), (1.0, 2.0, 0.0), (1.0, 0.0, 2.75)):
        made[setting] = generate_from_conditions(model, conds, seeds, generation=settings(*setting), residual=False)
    assert not np.allclose(made[1.0, 0.0, 0.0], made[3.0, 0.0, 0.0])
    # guidance on the onsets alone: the deaf decoding keeps the loudness, so the guided motion differs
    # from guidance on the whole stream, and without guidance (w = 1) nothing does
    for w in (3.0, 1.0):
        on = {which: generate_from_conditions(model, conds, seeds, residual=False, generation=dataclasses.replace(
            settings(w, 0.0, 0.0), timing_guidance_on=which)) for which in ("stream", "onsets")}
        assert np.allclose(on["stream"], on["onsets"]) == (w == 1.0)
    np.testing.assert_array_equal(on["stream"], made[1.0, 0.0, 0.0])
    change = {k: np.abs(np.diff(v, axis=1)).mean() for k, v in made.items()}
    assert change[1.0, 2.0, 0.0] < 0.8 * change[1.0, 0.0, 0.0] and change[1.0, 0.0, 2.75] < 0.8 * change[1.0, 0.0, 0.0]
    model.generation = settings(4.0, 1.75, 2.75)
    gt = np.asarray(cache.split("test").motion[:2], np.float32)
    plain = reconstruct_motion(model, gt, timing=conds[3][:2])
    model.generation = settings(1.0, 0.0, 0.0)
    np.testing.assert_allclose(reconstruct_motion(model, gt, timing=conds[3][:2]), plain, atol=1e-5)
    edited = emotion_label_edit(model, conds, np.zeros(len(conds[0]), np.int64))  # an edit keeps the own stream
    assert len(edited) == 4 and edited[3] is conds[3] and edited[0] is conds[0]
    wave, _ = load_audio(next((trained / "root" / "wave16k").glob("*.wav")))
    pipe = GesturePipeline.from_run(trained / "timing")
    seq = pipe.generate(wave, seed=0, generation=replace(pipe.generation, seam_candidates=2))[0]
    assert len(seq.poses) == int(round(len(wave) / 16000 * 30))


def test_the_papers_design_trains_and_generates_through_the_pipeline(trained):
    """The paper preset's gesture model (ε-prediction, no timing stream, no residual noise) goes the same way
    as tiny's: trained, stored with its generation settings, and animating speech through the pipeline."""
    from emogesture.audio import load_audio
    from emogesture.pipeline.generate import GesturePipeline

    model = load_model(trained / "paper", "gesture")
    assert model.config.diffusion.prediction_type == "epsilon" and not model.config.hears_timing
    assert model.generation == GenerationConfig.preset("paper") and not model.model.calibrated
    pipe = GesturePipeline.from_run(trained / "paper")
    wave, _ = load_audio(next((trained / "root" / "wave16k").glob("*.wav")))
    fast = dataclasses.replace(pipe.generation, num_inference_steps=5)
    a, b = (pipe.generate(wave, seed=s, generation=replace(fast, seam_candidates=2))[0] for s in (0, 1))
    assert len(a.poses) == int(round(len(wave) / 16000 * 30)) and np.isfinite(a.poses).all()
    assert not np.allclose(a.poses, b.poses)  # the seed draws the motion


def test_calibrate_style_chooses_the_speaker_with_typical_motion(trained, tmp_path, capsys):
    from emogesture.provenance import calibration_splits
    from emogesture.pipeline.perception import fallback_style_of
    from emogesture.pipeline.speech import SpeechLatentEncoder
    from emogesture.train.fallback_style import speaker_style_means, typicality_cost

    out = cli_here(capsys, "calibrate", "style", "--model", trained / "timing", "--data", trained / "cache",
                   "--out", tmp_path / "styled", "--windows", 3)
    assert out.returncode == 0 and "fallback style: training speaker" in out.stdout, out.stderr[-2000:]
    styled = load_model(tmp_path / "styled", "gesture")
    record = styled.metadata.fallback_style
    assert record["split"] == "val" and 1 <= record["windows"] <= 3 and set(record["candidates"]) == {"1", "2"}
    costs = {int(k): c["cost"] for k, c in record["candidates"].items()}
    assert record["speaker"] == min(costs, key=costs.get)
    for c in record["candidates"].values():  # each cost is the candidate's distance from the reference
        assert c["cost"] == pytest.approx(typicality_cost(c, record["reference"]))
    means = speaker_style_means(SpeechLatentEncoder.of_gesture_model(styled), open_cache(trained / "cache"))
    np.testing.assert_allclose(fallback_style_of(styled), means[record["speaker"]], atol=1e-6)
    assert calibration_splits(styled)["fallback_style"] == "val"  # val is no longer held out for this model
    assert fallback_style_of(load_model(trained / "timing", "gesture")) is None
    again = cli_here(capsys, "calibrate", "style", "--model", trained / "timing", "--data", trained / "cache",
                     "--out", tmp_path / "styled")
    assert again.returncode != 0 and "--overwrite" in again.stderr


def test_typicality_cost_is_in_units_of_the_real_speech_tolerances():
    from emogesture.train.fallback_style import typicality_cost

    ref = {"in_front": 0.4, "wrist_distance": 0.5}
    assert typicality_cost(ref, ref) == 0.0
    assert typicality_cost({"in_front": 0.5, "wrist_distance": 0.5}, ref) == pytest.approx(1.0)
    assert typicality_cost({"in_front": 0.4, "wrist_distance": 0.55}, ref) == pytest.approx(1.0)


def test_a_speech_model_calibrated_after_the_gesture_model_trained_bundles_and_generates(trained, tmp_path, capsys):
    from emogesture.provenance import trained_with
    from emogesture.pipeline.generate import GesturePipeline

    out = cli_here(capsys, "calibrate", "speech", "--model", trained / "speech", "--data", trained / "cache",
                   "--out", tmp_path / "calibrated")
    assert out.returncode == 0, out.stderr[-2000:]
    calibrated, gesture = load_model(tmp_path / "calibrated", "speech"), load_model(trained / "joint", "gesture")
    # the calibration's arrays live in the weights file, so its checksum changed; it names the file it came from
    assert calibrated.weights_sha256 != load_model(trained / "speech", "speech").weights_sha256
    assert trained_with(gesture, calibrated) and calibrated.tensors
    out = cli_here(capsys, "bundle", "--speech", tmp_path / "calibrated", "--gesture", trained / "joint",
                   "--out", tmp_path / "bundle")
    assert out.returncode == 0, out.stderr[-2000:]
    pipe = GesturePipeline.from_run(tmp_path / "bundle" / "gesture.json")
    assert pipe.speech.perception is not None and pipe.speech.perception.labels == calibrated.metadata.emotion_perception["labels"]
    other = tmp_path / "other"  # a speech model the gesture model never trained with is still refused
    import torch

    torch.manual_seed(1)
    save_model(other, "speech", SpeechDisentangler(calibrated.config), calibrated.config,
               load_model(trained / "speech", "speech").metadata)
    out = cli_here(capsys, "bundle", "--speech", other, "--gesture", trained / "joint", "--out", tmp_path / "b2")
    assert out.returncode != 0 and "is not the speech model" in out.stderr
