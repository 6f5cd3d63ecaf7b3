"""Speech-model training through the command line: a short run, evaluation, resume after a kill, DDP."""

import json
import shutil
import signal
import subprocess
import time

import numpy as np
import pytest

from emogesture.data.beat import write_split_csv
from emogesture.data.prepare import prepare
from emogesture.train.engine import checkpoint_step

from helpers import cli, cli_here as run_main, make_root


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    d = tmp_path_factory.mktemp("speech")
    names = make_root(d / "root", speakers=(1, 2, 3), takes=(1, 2, 3, 4, 65, 66, 67, 68))
    write_split_csv(d / "root" / "train_test_split.csv",
                    {n: "test" if n.split("_")[3] in ("3", "4", "67", "68") else "train" for n in names})
    prepare(d / "root", d / "cache", progress=False)
    return d / "cache"


TRAIN = ("train", "speech", "--quiet", "--set", "batch_size=2", "--set", "samples_per_epoch=64")


# the setup of the reports: adversarial losses, the train split only
REPORT_SETUP = ("--losses", "adversarial", "--set", "train_splits=[train]")


def test_train_evaluate_and_refuse_other_settings(cache, tmp_path, capsys):
    run = tmp_path / "run"
    out = subprocess.run(cli(*TRAIN, *REPORT_SETUP, "--data", cache, "--out", run, "--steps", 60),
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-2000:]
    meta = json.loads((run / "model.json").read_text())
    assert meta["kind"] == "speech" and meta["extra"]["step"] == 60 and meta["extra"]["speakers"] == [1, 2, 3]
    assert meta["extra"]["train_splits"] == ["train"]
    # the exported weights are the weight average kept in the checkpoint, not the last raw weights
    import torch
    from safetensors.torch import load_file

    exported = load_file(run / "model.safetensors")
    state = torch.load(run / "checkpoints" / "last.ckpt", map_location="cpu", weights_only=True)["state_dict"]
    assert all(torch.equal(v, state[f"ema.{k}"]) for k, v in exported.items())
    assert any(not torch.equal(v, state[f"model.{k}"]) for k, v in exported.items())
    code, _, err = run_main(capsys, "evaluate", "speech", run, "--data", cache, "--quadruples", 4)
    assert code == 0, err[-2000:]
    report = json.loads((run / "eval" / "speech_test.json").read_text())
    assert (run / "eval" / "speech_test_emotion_confusion.png").stat().st_size > 0
    # a trained tiny model hears what the fixture's tones carry: emotion and speaker above chance
    assert report["chance"] == {"emotion": 0.5, "speaker": pytest.approx(1 / 3)}
    assert report["EA"] >= 0.75 and report["SA"] > 0.5, (report["EA"], report["SA"])
    assert report["split_use"]["held_out"] and report["checks"]["EA >= 0.9"]["value"] == report["EA"]
    assert report["EA_perceived"] is None  # no perception calibration: the head's EA only
    # the quadruples pair test texts with texts of no split it trained on: here there is none
    assert report["reconstruction_partner_split"] is None and report["reconstruction_l1"]["XCon"] is None
    assert "not measured" in (run / "eval" / "speech_test.md").read_text()
    # a split the model trained on is refused, in one line
    code, _, err = run_main(capsys, "evaluate", "speech", run, "--data", cache, "--split", "train", "--out",
                            tmp_path / "e")
    assert code == 2 and "trained on the train split" in err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "e").exists()
    code, _, err = run_main(capsys, "evaluate", "speech", run, "--data", cache)
    assert code == 2 and "--overwrite" in err
    code, _, err = run_main(capsys, *TRAIN, *REPORT_SETUP, "--data", cache, "--out", run, "--steps", 60, "--set",
                            "lr=0.1")
    assert code == 2 and "other settings" in err and len(err.strip().splitlines()) == 1


def test_a_stored_config_with_a_removed_option_at_its_off_value_still_reads():
    """Options tried and not adopted (emotion scramble, real voices taught as neutral or given emotions, the pull,
    emotion-labelled real speech in the quadruples) are gone; a run stored before, that left them off, still
    reads; one that used them is a one-line error."""
    from emogesture.config import from_dict, to_dict
    from emogesture.errors import ConfigError
    from emogesture.train.speech import SpeechTrainConfig

    old = {**to_dict(SpeechTrainConfig()), "emotion_scramble": 0, "emotion_scramble_share": 0.5, "real_neutral": [],
           "real_neutral_weight": 1.0, "real_neutral_pull": 0.0, "real_emotion_share": 0.0, "real_labelled": "",
           "real_labelled_weight": 1.0}
    assert from_dict(SpeechTrainConfig, old) == SpeechTrainConfig()
    for key, value in (("emotion_scramble", 64), ("real_neutral", ["fr_june"]), ("real_neutral_pull", 1.0),
                       ("real_labelled", "data/ravdess.csv")):
        with pytest.raises(ConfigError, match=f"{key} = .*: this option was removed"):
            from_dict(SpeechTrainConfig, {**old, key: value})


def test_killed_run_resumes_from_its_checkpoint(cache, tmp_path, capsys):
    run = tmp_path / "run"
    args = cli(*TRAIN, "--data", cache, "--out", run, "--steps", 400, "--checkpoint-every", 3)
    proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    last = run / "checkpoints" / "last.ckpt"
    deadline = time.monotonic() + 180
    while time.monotonic() < deadline and proc.poll() is None:
        if last.is_file() and checkpoint_step(last) >= 6:
            proc.send_signal(signal.SIGKILL)
            break
        time.sleep(0.2)
    proc.wait()
    assert proc.returncode == -signal.SIGKILL
    saved = checkpoint_step(last)  # the checkpoint survived the kill intact
    assert saved >= 6  # a kill in the middle of a write may leave its hidden temp file; the next run clears it
    code, out, err = run_main(capsys, *TRAIN, "--data", cache, "--out", run, "--steps", saved + 3,
                              "--checkpoint-every", 3, "--log-every", 1)
    assert code == 0, err[-2000:]
    assert f"at step {saved}" in out
    assert checkpoint_step(last) == saved + 3 and not list(run.rglob("*.tmp"))
    assert json.loads((run / "model.json").read_text())["extra"]["step"] == saved + 3
    # a further session keeps the earlier session's log instead of letting Lightning replace it
    first_log = (run / "logs" / "metrics.csv").read_text()
    code, _, err = run_main(capsys, *TRAIN, "--data", cache, "--out", run, "--steps", saved + 4, "--log-every", 1)
    assert code == 0, err[-2000:]
    assert (run / "logs" / "metrics.1.csv").read_text() == first_log
    # a run folder moved elsewhere resumes there, and its last checkpoint stays the one a next resume reads
    moved = tmp_path / "moved"
    shutil.copytree(run, moved)
    code, out, err = run_main(capsys, *TRAIN, "--data", cache, "--out", moved, "--steps", saved + 5)
    assert code == 0 and f"at step {saved + 4}" in out, err[-2000:]
    assert checkpoint_step(moved / "checkpoints" / "last.ckpt") == saved + 5
    assert not list((moved / "checkpoints").glob("last-v*"))
    assert str(saved + 3) in (run / "logs" / "metrics.csv").read_text().split("\n", 1)[1]


def test_data_workers_draw_the_same_windows_and_leave_the_trainer_their_cores(cache, tmp_path, capsys):
    import os

    from safetensors.numpy import load_file

    from emogesture.train.engine import trainer_threads

    weights = []
    for workers in (0, 2):  # 8 steps over two epochs of augmented windows, one trainer thread each time
        run = tmp_path / f"workers{workers}"
        out = subprocess.run(cli(*TRAIN, "--data", cache, "--out", run, "--steps", 8, "--set", "samples_per_epoch=8",
                                 "--set", "wave_augment=0.5", "--set", f"num_workers={workers}"),
                             capture_output=True, text=True, env={**os.environ, "OMP_NUM_THREADS": "1"}, timeout=300)
        assert out.returncode == 0, out.stderr[-2000:]
        weights.append(load_file(run / "model.safetensors"))
    assert all(np.array_equal(weights[0][k], weights[1][k]) for k in weights[0])
    # the worker count is no setting of what is learned: a run resumes with another
    code, out, err = run_main(capsys, *TRAIN, "--data", cache, "--out", run, "--steps", 9, "--set",
                              "samples_per_epoch=8", "--set", "wave_augment=0.5", "--set", "num_workers=0")
    assert code == 0 and "at step 8" in out, err[-2000:]
    assert trainer_threads(2, 2, {}) == 1 and trainer_threads(1, 8, {}) == 7
    assert trainer_threads(0, 2, {}) is None and trainer_threads(2, 2, {"OMP_NUM_THREADS": "2"}) is None


def test_a_bank_of_augmented_variants_trains_and_needs_augmentation(cache, tmp_path, capsys):
    run = tmp_path / "bank"
    out = subprocess.run(cli(*TRAIN, "--data", cache, "--out", run, "--steps", 2, "--set", "samples_per_epoch=8",
                             "--set", "wave_augment=0.5", "--set", "wave_variants=2"), capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert json.loads((run / "run.json").read_text())["config"]["wave_variants"] == 2
    code, _, err = run_main(capsys, *TRAIN, "--data", cache, "--out", tmp_path / "bad", "--steps", 1,
                            "--set", "wave_variants=2")
    assert code != 0 and "wave_variants 2" in err and "Traceback" not in err


def test_the_banks_bar_shows_on_a_terminal_unless_quiet(cache, monkeypatch):
    import io
    import sys

    from emogesture.train.speech import SpeechDataModule

    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    for progress in (True, False):
        err = Terminal()
        monkeypatch.setattr(sys, "stderr", err)
        data = SpeechDataModule(cache, 2, 8, 0, wave_augment=0.5, wave_variants=1, progress=progress)
        data.setup("fit")
        assert ("augmented windows" in err.getvalue()) == progress


def test_two_process_ddp_gives_identical_weights(cache, tmp_path):
    run = tmp_path / "ddp"
    out = subprocess.run(cli(*TRAIN, "--data", cache, "--out", run, "--steps", 3, "--devices", 2),
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    digests = [(run / "rank_digests" / f"rank{r}.txt").read_text().split() for r in (0, 1)]
    assert digests[0] == digests[1] and digests[0][0] == "3"


def test_train_splits_concatenate_and_never_take_the_test_split(cache):
    from emogesture.data.cache import concat_splits, open_cache
    from emogesture.errors import ConfigError
    from emogesture.train.speech import SpeechDataModule

    c = open_cache(cache)
    train, test = c.split("train"), c.split("test")
    both = concat_splits(c, ["train", "test"])
    assert len(both) == len(train) + len(test) and both.takes == train.takes + test.takes
    assert np.array_equal(both.fbank[len(train):], test.fbank) and np.array_equal(both.text[: len(train)], train.text)
    assert concat_splits(c, ["train"]).fbank is not None and len(concat_splits(c, ["train"])) == len(train)
    with pytest.raises(ConfigError, match="test split"):
        SpeechDataModule(cache, 2, 8, 0, splits=("train", "test"))


def test_content_use_sees_whether_the_decoder_reads_the_content_latent():
    from types import SimpleNamespace

    import torch

    from emogesture.eval.speech import content_use

    fbank = np.random.default_rng(0).normal(size=(5, 64, 8)).astype(np.float32)
    fbank[:, ::2] += 1.0  # timing the time-averaged spectrum cannot have
    fbank += np.arange(5, dtype=np.float32)[:, None, None]  # windows that differ

    def encode(x):  # content = the window's level, emotion and style = nothing
        level = x.mean(dim=(1, 2))[:, None].expand(-1, 4)
        return SimpleNamespace(content=level, emotion=torch.zeros_like(level), style=torch.zeros_like(level))

    def model(reads_content: bool):
        def decode(c, e, s):
            out = c[:, :1, None].expand(-1, 64, 8) if reads_content else torch.zeros(len(c), 64, 8)
            return out + e[:, :1, None]
        return SimpleNamespace(model=SimpleNamespace(encode=encode, decode=decode), device="cpu")

    use = content_use(model(True), SimpleNamespace(fbank=fbank), seed=0, batch_size=2)
    assert use["time_mean"] == pytest.approx(np.abs(fbank - fbank.mean(1, keepdims=True)).mean(), rel=1e-5)
    assert use["self"] == pytest.approx(use["time_mean"], rel=0.05)  # the window level is its time mean, nearly
    assert use["content_shuffled"] > use["self"] + 0.5  # another window's level is off by at least 1
    use = content_use(model(False), SimpleNamespace(fbank=fbank), seed=0, batch_size=2)
    assert use["content_shuffled"] == use["self"]


def _deit_layout(width: int, depth: int, seed: int = 0) -> dict:
    """Random tensors in timm's DeiT (distilled, patch 16, 384 px) layout at a small width and depth."""
    import torch

    g = torch.Generator().manual_seed(seed)
    shapes = {"patch_embed.proj.weight": [width, 3, 16, 16], "patch_embed.proj.bias": [width],
              "cls_token": [1, 1, width], "dist_token": [1, 1, width], "pos_embed": [1, 2 + 24 * 24, width],
              "norm.weight": [width], "norm.bias": [width], "head.weight": [10, width], "head.bias": [10]}
    for i in range(depth):
        for name, shape in {"norm1": [width], "attn.qkv": [3 * width, width], "attn.proj": [width, width],
                            "norm2": [width], "mlp.fc1": [4 * width, width], "mlp.fc2": [width, 4 * width]}.items():
            shapes[f"blocks.{i}.{name}.weight"], shapes[f"blocks.{i}.{name}.bias"] = shape, [shape[0]]
    return {k: torch.randn(*s, generator=g) for k, s in shapes.items()}


def test_init_from_deit_weights_starts_every_encoder_there(cache, tmp_path, capsys):
    import torch
    from safetensors.torch import save_file

    from emogesture.config import to_dict
    from emogesture.train.speech import SpeechModule, SpeechTrainConfig

    deit = _deit_layout(width=32, depth=1)
    weights = tmp_path / "deit_small_layout.safetensors"
    save_file(deit, str(weights))
    config = SpeechTrainConfig.preset("paper")
    config.model.encoder.width, config.model.encoder.depth, config.model.encoder.heads = 32, 1, 2
    random_start = SpeechModule(to_dict(config)).model
    config.init_from = str(weights)
    module = SpeechModule(to_dict(config))
    for name in ("content_encoder", "emotion_encoder", "style_encoder"):
        vit = getattr(module.model, name).vit.state_dict()
        for key in ("blocks.0.attn.qkv.weight", "blocks.0.mlp.fc2.bias", "cls_token", "dist_token", "norm.weight"):
            assert torch.equal(vit[key], deit[key]), (name, key)
            assert not torch.equal(getattr(random_start, name).vit.state_dict()[key], deit[key])
        # one-channel patch kernels: the mean of the three colour channels
        assert torch.allclose(vit["patch_embed.proj.weight"], deit["patch_embed.proj.weight"].mean(1, keepdim=True))
    # the weight average that gets exported starts from the same weights
    averaged = module.averaged.content_encoder.vit.state_dict()["blocks.0.attn.qkv.weight"]
    assert torch.equal(averaged, deit["blocks.0.attn.qkv.weight"])

    missing = tmp_path / "no_such_weights.safetensors"
    code, _, err = run_main(capsys, *TRAIN, "--preset", "paper", "--data", cache, "--out", tmp_path / "run",
                            "--steps", 1, "--init-from", missing)
    assert code != 0 and "Traceback" not in err
    assert f"{missing}: pretrained weights file not found" in err.strip().splitlines()[-1]


def test_init_from_a_trained_speech_model_starts_every_weight_there(tmp_path):
    import torch

    from emogesture.checkpoints import save_model
    from emogesture.config import to_dict
    from emogesture.errors import ConfigError
    from emogesture.models.metadata import SpeechMetadata
    from emogesture.train.speech import SpeechModule, SpeechTrainConfig

    config = SpeechTrainConfig.preset("tiny", "adversarial")
    config.model.num_speakers = 3
    trained = SpeechModule(to_dict(config), seed=1).model
    with torch.no_grad():
        for p in trained.parameters():
            p.add_(0.01)
    save_model(tmp_path / "stage1", "speech", trained, config.model,
               SpeechMetadata(emotions=["neutral"], speakers=[1, 2, 3], fbank_mean=0.0, fbank_std=1.0,
                              prepare_config={}, train_splits=["train"], step=5))
    config.init_from = str(tmp_path / "stage1")
    module = SpeechModule(to_dict(config), seed=2)
    random_start = SpeechModule(to_dict(SpeechTrainConfig.preset("tiny", "adversarial")), seed=2).model
    for (name, value), start in zip(module.model.state_dict().items(), trained.state_dict().values()):
        assert torch.equal(value, start), name
    assert not torch.equal(random_start.decoder.state_dict()[next(iter(random_start.decoder.state_dict()))],
                           trained.decoder.state_dict()[next(iter(trained.decoder.state_dict()))])
    # the exported average starts there too
    assert torch.equal(module.averaged.fusion.state_dict()[next(iter(module.averaged.fusion.state_dict()))],
                       trained.fusion.state_dict()[next(iter(trained.fusion.state_dict()))])

    config.model.heard_bins = 96  # what the encoders hear may change from one stage to the next
    assert SpeechModule(to_dict(config), seed=2).model.config.heard_bins == 96
    config.model.latent_dim = 128
    with pytest.raises(ConfigError, match="another architecture.*latent_dim"):
        SpeechModule(to_dict(config))
