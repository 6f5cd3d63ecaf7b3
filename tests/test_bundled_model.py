"""The model shipped inside the package, and `emogesture generate` as a user meets it."""

from __future__ import annotations

from dataclasses import replace
import argparse
import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf
import torch

from emogesture.assets import BUNDLED_MODEL, DEMO_CLIPS, bundled_model_file
from emogesture.bundle import verify_checksums
from emogesture.checkpoints import load_model
from emogesture.data.beat import EMOTIONS
from emogesture.eval.metrics import wrist_speed
from emogesture.motion import SkeletonBody
from emogesture.pipeline.generate import EditRequest, GesturePipeline

from helpers import cli_here

KINDS = ("speech", "gesture", "extractor")


@pytest.fixture(scope="module")
def pipe():
    return GesturePipeline.from_run()


@pytest.fixture(scope="module")
def clip30(tmp_path_factory) -> Path:
    """30.0 s of the shipped synthetic speech (the two demo clips back to back, cut)."""
    a, sr = sf.read(DEMO_CLIPS / "talk.flac", dtype="float32")
    b, _ = sf.read(DEMO_CLIPS / "angry.flac", dtype="float32")
    path = tmp_path_factory.mktemp("clips") / "thirty.wav"
    sf.write(path, np.concatenate([a, b])[: 30 * sr], sr)
    return path


def joints_of(seq) -> np.ndarray:
    with torch.no_grad():
        return SkeletonBody()(torch.from_numpy(seq.poses), torch.from_numpy(seq.trans)).numpy()


def test_shipped_files_match_their_checksums_and_load():
    names = verify_checksums(BUNDLED_MODEL)
    for kind in KINDS:
        assert f"{kind}.json" in names and f"{kind}.safetensors" in names
        loaded = load_model(bundled_model_file(kind), kind)
        assert not loaded.model.training
    assert "MODEL_CARD.md" in names
    total = sum((BUNDLED_MODEL / n).stat().st_size for n in names)
    assert total <= 25 * 1024 * 1024
    speech = load_model(bundled_model_file("speech"), "speech")
    assert speech.metadata.train_splits == ["train"]  # val stays unseen for the calibrations
    assert speech.metadata.emotion_perception["info"]["split"] == "val"
    # each emotion also read by its mean of the three real studio voices (never the real-speech checks' voices)
    assert speech.metadata.emotion_perception["info"]["real_voices"] == ["fr_june", "it_carlo", "ru_ivr"]
    assert speech.metadata.emotion_perception["labels"] == list(EMOTIONS) * 2
    # its arrays are tensors of the weights file; the JSON stays small
    assert (BUNDLED_MODEL / "speech.json").stat().st_size <= 100 * 1024
    assert speech.tensors["emotion_perception.emotion.means"].shape[0] == 16


def test_a_damaged_shipped_file_is_refused(tmp_path):
    from emogesture.errors import InputFileError

    copy = tmp_path / "model"
    copy.mkdir()
    for p in BUNDLED_MODEL.iterdir():
        if p.is_file():
            (copy / p.name).write_bytes(p.read_bytes())
    data = bytearray((copy / "gesture.safetensors").read_bytes())
    data[-10] ^= 0xFF
    (copy / "gesture.safetensors").write_bytes(bytes(data))
    with pytest.raises(InputFileError, match="checksum"):
        verify_checksums(copy)
    with pytest.raises(InputFileError, match="checksum"):
        GesturePipeline.from_run(copy / "gesture.json")


def test_thirty_seconds_give_900_frames_and_the_seed_decides(pipe, clip30):
    wave = pipe.load_speech(clip30)
    a = pipe.generate(wave, seed=5)[0]
    assert a.num_frames == 900 and a.poses.shape == (900, 55, 3)
    b = pipe.generate(wave, seed=5)[0]
    assert np.array_equal(a.poses, b.poses)
    c = pipe.generate(wave, seed=6)[0]
    assert not np.allclose(a.poses, c.poses)


def test_emotion_edits_by_label_read_as_that_label(pipe):
    """Every window of the demo clip re-generated with each label, classified by the extractor."""
    extractor = load_model(bundled_model_file("extractor"), "extractor")
    mean = torch.tensor(extractor.metadata.motion_mean)
    std = torch.tensor(extractor.metadata.motion_std)
    wave = pipe.load_speech(DEMO_CLIPS / "talk.flac")
    enc, starts = pipe.encode(wave)
    per_label = {}
    for label in EMOTIONS:
        conds = pipe.conditions(enc, EditRequest(emotion_label=label))
        seeds = [100 + i for i in range(len(starts))] * 4
        motion = pipe.generate_windows([np.concatenate([c] * 4) for c in conds], seeds)
        with torch.no_grad():
            logits = extractor.model((torch.from_numpy(motion) - mean) / std)[1]
        per_label[label] = float((logits.argmax(1).numpy() == EMOTIONS.index(label)).mean())
    print("edit accuracy per label:", json.dumps(per_label))
    assert sum(v > 0.5 for v in per_label.values()) >= 5, per_label  # most labels


def test_silence_gives_a_calm_animation(pipe, tmp_path):
    silent = tmp_path / "silence.wav"
    sf.write(silent, np.zeros(60 * 16000, np.float32), 16000)
    calm = pipe.generate(pipe.load_speech(silent), seed=0)[0]
    assert calm.num_frames == 1800
    speech = pipe.generate(pipe.load_speech(DEMO_CLIPS / "talk.flac"), seed=0)[0]
    calm_speed, speech_speed = wrist_speed(joints_of(calm)), wrist_speed(joints_of(speech))
    print(f"wrist speed: silence {calm_speed:.3f} m/s, speech {speech_speed:.3f} m/s")
    assert calm_speed < 0.5 * speech_speed


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "emogesture.cli.main", *args], capture_output=True, text=True)


@pytest.mark.training
def test_generate_writes_every_format_and_the_perception(tmp_path):
    out = tmp_path / "out"
    proc = run_cli("generate", str(DEMO_CLIPS / "angry.flac"), "-o", str(out), "--emotion", "sadness",
                   "--format", "npz,bvh", "--samples", "2")
    assert proc.returncode == 0, proc.stderr
    names = sorted(p.name for p in out.iterdir())
    assert names == ["angry_emotion-sadness_seed0_0.bvh", "angry_emotion-sadness_seed0_0.npz",
                     "angry_emotion-sadness_seed0_1.bvh", "angry_emotion-sadness_seed0_1.npz",
                     "angry_emotion-sadness_seed0_perception.json"]
    for name in names:
        assert str(out / name) in proc.stdout
    assert "angry.flac: heard " in proc.stdout
    perception = json.loads((out / "angry_emotion-sadness_seed0_perception.json").read_text())
    assert perception[0]["windows"][0]["emotion"] in EMOTIONS and "trust" in perception[0]["windows"][0]
    again = run_cli("generate", str(DEMO_CLIPS / "angry.flac"), "-o", str(out), "--emotion", "sadness",
                    "--format", "npz,bvh", "--samples", "2")
    assert again.returncode == 2 and "already exists" in again.stderr
    assert sorted(p.name for p in out.iterdir()) == names


def _bad_inputs(tmp_path: Path) -> list[tuple[list[str], str]]:
    text = tmp_path / "notes.wav"
    text.write_text("these are my meeting notes, not audio\n")
    empty = tmp_path / "empty.wav"
    empty.write_bytes(b"")
    whole, sr = sf.read(DEMO_CLIPS / "angry.flac", dtype="float32")
    full = tmp_path / "full.wav"
    sf.write(full, whole, sr)
    truncated = tmp_path / "truncated.wav"
    truncated.write_bytes(full.read_bytes()[: full.stat().st_size // 2])
    short = tmp_path / "short.wav"
    sf.write(short, whole[: sr // 10], sr)
    corrupt = tmp_path / "corrupt_model"
    corrupt.mkdir()
    (corrupt / "model.json").write_text("{ not json")
    foreign = tmp_path / "foreign_model"
    foreign.mkdir()
    (foreign / "model.json").write_text(json.dumps({"name": "some other tool's model"}))
    taken = tmp_path / "taken"
    taken.mkdir()
    (taken / "angry_seed0_0.npz").write_bytes(b"the user's file")
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    clip = str(DEMO_CLIPS / "angry.flac")
    out = str(tmp_path / "o")
    return [
        (["generate", str(text), "-o", out], "notes.wav"),
        (["generate", str(empty), "-o", out], "empty file"),
        (["generate", str(truncated), "-o", out], "truncated"),
        (["generate", str(short), "-o", out], "too short"),
        (["generate", clip, "-o", out, "--emotion", "joy"], "unknown"),
        (["generate", clip, "-o", out, "--model", str(corrupt)], "corrupt_model"),
        (["generate", clip, "-o", out, "--model", str(foreign)], "not an emogesture model"),
        (["generate", clip, "-o", str(taken), "--format", "npz"], "already exists"),
        (["generate", clip, "-o", str(a_file)], "is a file"),
        (["generate", clip, "-o", out, "--emotion-weight", "0.5"], "--emotion-weight"),
    ]


def test_bad_input_is_one_line_and_leaves_nothing(tmp_path, capsys):
    for i, (args, needle) in enumerate(_bad_inputs(tmp_path)):
        if i == 0:  # the process as a user runs it: its exit status and all it writes to stderr
            proc = run_cli(*args)
            code, err = proc.returncode, proc.stderr
        else:  # the others in this process
            code, _, err = cli_here(capsys, *args)
        lines = err.strip().splitlines()
        assert code != 0, args
        assert len(lines) == 1 and needle in lines[0], (args, err)
        assert "Traceback" not in err
        assert not (tmp_path / "o").exists() or not any((tmp_path / "o").iterdir()), args
    assert (tmp_path / "taken" / "angry_seed0_0.npz").read_bytes() == b"the user's file"
    assert not list(tmp_path.glob("**/.*.tmp"))


def test_bf16_autocast_drift_of_the_bundled_model(pipe, clip30):
    """bf16 (what ``--precision auto`` picks on CPUs with native bf16, and on GPUs) stays within a
    stated tolerance of float32: joints 2 mm on average, 20 mm at most (one seam candidate, so no
    discrete choice can differ)."""
    bf16 = GesturePipeline.from_run(precision="bf16")
    wave = pipe.load_speech(clip30)
    a = joints_of(pipe.generate(wave, seed=2, generation=replace(pipe.generation, seam_candidates=1))[0])
    b = joints_of(bf16.generate(wave, seed=2, generation=replace(bf16.generation, seam_candidates=1))[0])
    mm = np.linalg.norm(a - b, axis=-1) * 1000
    assert 0 < mm.mean() < 2 and mm.max() < 20, (mm.mean(), mm.max())


def test_bundle_changes_generation_settings_and_nothing_else(tmp_path, capsys):
    out = tmp_path / "b"
    proc = run_cli("bundle", "--speech", str(bundled_model_file("speech")), "--gesture",
                   str(bundled_model_file("gesture")), "--out", str(out), "--set", "timing_guidance=2.5",
                   "--set", "output_lowpass_hz=3")
    assert proc.returncode == 0, proc.stderr
    names = verify_checksums(out)
    assert "gesture.json" in names and "extractor.json" not in names
    shipped, rebundled = load_model(bundled_model_file("gesture"), "gesture"), load_model(out / "gesture.json", "gesture")
    assert (rebundled.generation.timing_guidance, rebundled.generation.output_lowpass_hz) == (2.5, 3.0)
    assert rebundled.generation.num_inference_steps == shipped.generation.num_inference_steps
    assert rebundled.config == shipped.config
    assert rebundled.weights_sha256 == shipped.weights_sha256
    proc = cli_here(capsys, "bundle", "--speech", bundled_model_file("speech"), "--gesture",
                    bundled_model_file("gesture"), "--out", tmp_path / "c", "--set", "vae.width=8")
    assert proc.returncode != 0 and "generation setting is key=value" in proc.stderr and "Traceback" not in proc.stderr


def test_the_bundle_and_the_experiment_scripts_generate_with_the_tiny_presets_settings():
    from emogesture.models.generation import GenerationConfig

    text = (Path(__file__).parents[1] / "experiments" / "common.sh").read_text()
    array = text.split("\nGENERATION=(", 1)[1].split(")", 1)[0]  # the bash array, over one line or several
    scripted = {k.strip(): v.strip() for k, v in (item.split("=", 1) for item in array.split("--set ")[1:])}
    fields = [f.name for f in dataclasses.fields(GenerationConfig)]
    assert scripted and set(scripted) <= set(fields)
    tiny = GenerationConfig.preset("tiny")
    shipped = load_model(bundled_model_file("gesture"), "gesture").generation
    assert shipped == tiny
    for key, value in scripted.items():
        want = getattr(tiny, key)
        assert (value if isinstance(want, str) else float(value)) == want, key


def test_bundle_help_lists_exactly_the_generation_settings():
    """The CLI's parser does not import the models (a command loads only what it uses), so ``bundle --set``'s
    help names the settings by hand; this keeps it equal to GenerationConfig's fields."""
    from emogesture.cli.main import build_parser
    from emogesture.models.generation import GenerationConfig

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    action = next(a for a in sub.choices["bundle"]._actions if a.dest == "generation")
    listed = action.help.split(":", 1)[1].replace(" ", "").split(",")
    assert listed == [f.name for f in dataclasses.fields(GenerationConfig)]


def test_models_saved_before_the_generation_section_load_with_their_settings(tmp_path):
    """A gesture model whose JSON keeps its generation settings inside its config (as the files of
    2026-11-25 and before do) loads them as its GenerationConfig, and its checksum still holds."""
    from emogesture.checkpoints import content_checksum

    src = load_model(bundled_model_file("gesture"), "gesture")
    meta = json.loads(src.path.read_text())
    meta.pop("generation", None)
    meta["config"]["vae"].update(timing_guidance=3.5, output_smoothing=0.0, output_lowpass_hz=3.0)
    meta["config"]["diffusion"].update(num_inference_steps=25, residual_scale=0.75)
    meta["checksum_sha256"] = content_checksum(meta)
    for name in (meta["weights"],):
        (tmp_path / name).write_bytes((src.path.parent / name).read_bytes())
    (tmp_path / "gesture.json").write_text(json.dumps(meta))
    old = load_model(tmp_path / "gesture.json", "gesture")
    assert (old.generation.timing_guidance, old.generation.output_lowpass_hz) == (3.5, 3.0)
    assert (old.generation.num_inference_steps, old.generation.residual_scale) == (25, 0.75)
    assert old.generation.seam_candidates == 4 and old.config == src.config


def test_speech_encoder_batches_are_bounded_on_a_cpu_and_change_nothing(monkeypatch):
    """On a CPU the speech encoders take as many windows per batch as keep their widest activation
    within ENCODER_BATCH_NUMBERS (the paper encoder: 3 windows; larger batches left the caches); the
    latents depend on the batch only by float32 rounding (matrix products blocked differently; the
    paper encoder in bf16 gave bit-identical latents for batches of 3 and 32)."""
    import numpy as np

    from emogesture.models.vit import ViTConfig
    from emogesture.pipeline import speech as speech_module
    from emogesture.pipeline.speech import SpeechLatentEncoder

    encoder = SpeechLatentEncoder.from_run(bundled_model_file("speech"))
    assert encoder.batch_size == 32  # the tiny encoder: 130 tokens x 256
    paper = ViTConfig.preset("paper")
    assert speech_module.ENCODER_BATCH_NUMBERS // ((paper.num_prefix + paper.num_patches) * 3072) == 3
    windows = np.random.default_rng(0).standard_normal((5, 1024, 128)).astype(np.float32)
    whole = encoder.encode_windows(windows, batch_size=32)
    monkeypatch.setattr(speech_module, "ENCODER_BATCH_NUMBERS", 2 * 130 * 256)
    assert encoder.batch_size == 2
    sizes: list[int] = []
    batched = encoder.encode_windows(windows, progress=sizes.append)
    assert sizes == [2, 2, 1]
    for part in ("content", "emotion", "style"):
        np.testing.assert_allclose(getattr(batched, part), getattr(whole, part), rtol=0, atol=1e-5)
