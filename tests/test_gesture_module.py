"""The gesture training module's parts on their own: presets, feature and joint losses, bf16 noise, devices, the edit targets and seam statistics of its report."""


import numpy as np
import pytest

from emogesture.data.beat import EMOTIONS
from emogesture.eval.gesture_models import edit_targets
from emogesture.eval.seams import seam_jumps


def test_tiny_presets_predict_z0_and_no_prior_has_its_own_prior_lr():
    from emogesture.config import from_dict, to_dict
    from emogesture.errors import ConfigError
    from emogesture.motion import MotionFeatureSpec
    from emogesture.train.gesture import GestureModule, GestureTrainConfig

    assert GestureTrainConfig.preset("paper").model.diffusion.prediction_type == "epsilon"
    cfg = GestureTrainConfig.preset("tiny", "no_prior")
    assert cfg.model.diffusion.prediction_type == "sample" and cfg.prior_lr == 1e-4 and cfg.lr == 1e-3
    assert cfg.losses.align == cfg.losses.valign == 0.1 and GestureTrainConfig.preset("paper").losses.align == 1.0
    cfg.model.vae.frames, cfg.model.vae.feature_dim = 60, 282  # the tiny prior reads 48 cosines
    module = GestureModule(to_dict(cfg), [0.0] * 282, [1.0] * 282, to_dict(MotionFeatureSpec()))
    groups = module.configure_optimizers().param_groups
    prior = {id(p) for p in module.model.prior.parameters()}
    assert [g["lr"] for g in groups] == [1e-3, 1e-4]
    assert {id(p) for p in groups[1]["params"]} == prior and not prior & {id(p) for p in groups[0]["params"]}
    cfg.model.denoiser.width = 192  # narrower than the 256-d latent: refused for training
    with pytest.raises(ConfigError, match="bottleneck"):
        from_dict(GestureTrainConfig, to_dict(cfg))


def test_edit_targets_are_seeded_and_never_the_own_emotion():
    emotion = np.arange(400) % len(EMOTIONS)
    t = edit_targets(emotion, seed=3)
    assert np.all(t != emotion) and set(t.tolist()) == set(range(len(EMOTIONS)))
    assert np.array_equal(t, edit_targets(emotion, seed=3)) and not np.array_equal(t, edit_targets(emotion, seed=4))
    two = edit_targets(np.array([0, 1, 1, 0]), available=[0, 1])
    assert two.tolist() == [1, 0, 0, 1]


def test_seam_jumps_find_a_jump_at_a_seam():
    fps, t = 30, np.arange(600) / 30
    joints = np.zeros((600, 55, 3))
    joints[..., 0] = 0.05 * np.sin(2 * np.pi * 0.5 * t)[:, None]  # smooth motion, at most ~5 mm per frame
    starts = [0.0, 8.0, 10.0]  # windows 0-10 s, 8-18 s, 10-20 s: overlaps at frames 240-299 and 300-539
    smooth = seam_jumps(joints, starts, fps=fps)
    assert smooth["max_seam_jump_m"] <= smooth["p99_inside_jump_m"] * 1.01
    broken = joints.copy()
    broken[270:, :, 0] += 0.1  # a 10-cm step inside the first overlap
    r = seam_jumps(broken, starts, fps=fps)
    assert r["max_seam_jump_m"] == pytest.approx(abs(0.1 + joints[270, 0, 0] - joints[269, 0, 0]), abs=1e-9)
    assert r["max_seam_jump_m"] > r["p99_inside_jump_m"]
    assert r["seam_share_above_p99"] > 0 and r["seam_jumps"] + r["inside_jumps"] == 599
    with pytest.raises(Exception, match="too short"):
        seam_jumps(joints, [0.0], fps=fps)


def test_seam_statistics_flag_hard_cuts_and_leave_out_take_changes():
    from emogesture.eval.seams import seam_statistics, split_jumps

    rng = np.random.default_rng(0)
    starts_s = [0.0, 8.0, 16.0, 24.0, 32.0, 40.0, 48.0, 55.0]  # 65 s, windows every 8 s
    smooth = np.abs(rng.normal(0.02, 0.005, size=1949))  # the same motion everywhere: seams like the inside
    stats = seam_statistics(*split_jumps(smooth, starts_s))
    assert 0.8 < stats["p99_seam_jump_m"] / stats["p99_inside_jump_m"] < 1.2
    cut = smooth.copy()  # a hard cut in the middle of every overlap, as stitching without a cross-fade gives
    for s in starts_s[1:]:
        cut[int(s * 30) + 25: int(s * 30) + 35] += 0.1
    bad = seam_statistics(*split_jumps(cut, starts_s))
    assert bad["p99_seam_jump_m"] / bad["p99_inside_jump_m"] > 3
    jumpy = smooth.copy()
    jumpy[1715:1725] += 0.1  # a fast move where the speech changes take (inside the last overlap)
    assert seam_statistics(*split_jumps(jumpy, starts_s))["max_seam_jump_m"] > 0.1
    kept = seam_statistics(*split_jumps(jumpy, starts_s, [57.3]))
    assert kept["max_seam_jump_m"] < 0.1 and kept["seam_jumps"] < stats["seam_jumps"]


def test_windows_own_jumps_keep_the_faster_window_where_two_overlap():
    from emogesture.eval.seams import windows_own_jumps

    jumps = np.array([[1.0, 1.0, 1.0, 1.0], [2.0, 0.5, 0.5, 0.5]])  # two 5-frame windows, starts 0 and 2
    assert windows_own_jumps(jumps, [0, 2], 7).tolist() == [1.0, 1.0, 2.0, 1.0, 0.5, 0.5]
    assert windows_own_jumps(jumps, [0, 2], 5).tolist() == [1.0, 1.0, 2.0, 1.0]  # cut to the timeline


def test_model_info_gesture_prints_the_paper_counts(capsys):
    import torch

    from emogesture.cli.main import main
    from emogesture.models.gesture import GestureModel, GestureModelConfig

    assert main(["model-info", "gesture", "--preset", "paper"]) == 0
    text = capsys.readouterr().out
    with torch.device("meta"):
        counts = GestureModel(GestureModelConfig.preset("paper")).count_parameters()
    for name in ("prior", "denoiser", "total"):
        assert f"{counts[name]:,}" in text
    assert 17e6 < counts["prior"] < 19e6 and 80e6 < counts["denoiser"] < 90e6
    assert "50 DDIM steps" in text


def test_bf16_mixed_training_noises_float32_latents(monkeypatch):
    """Under bf16 autocast (``--precision bf16-mixed``) the prior's latents come out in bf16, but the
    forward diffusion mixes them with the noise in float32: in bf16, 1 − ᾱ₀ = 0.00085 rounds to 0 (no noise
    at all at t = 0) while sampling runs the float32 schedule."""
    import torch

    from emogesture.config import to_dict
    from emogesture.data.prepare import PrepareConfig
    from emogesture.train import gesture
    from emogesture.train.gesture import GestureModule, GestureTrainConfig

    cfg = GestureTrainConfig.preset("tiny")
    cfg.prior_warmup_steps, cfg.align_every = 0, 0
    d, frames = cfg.model.vae.feature_dim, cfg.model.vae.frames
    module = GestureModule(to_dict(cfg), [0.0] * d, [0.3] * d, to_dict(PrepareConfig().features))
    g = torch.Generator().manual_seed(0)
    conditions = [torch.randn(2, cfg.model.denoiser.cond_dim, generator=g) for _ in range(3)]
    if cfg.model.hears_timing:
        conditions.append(torch.rand(2, frames, cfg.model.timing_features, generator=g))
    batch = {"motion": torch.randn(2, frames, d, generator=g) * 0.3, "emotion": torch.zeros(2, dtype=torch.long),
             "conditions": conditions}
    seen, real = [], gesture.add_noise

    def spy(scheduler, z0, noise, t):
        seen.append((z0.dtype, noise.dtype))
        return real(scheduler, z0, noise, t)

    monkeypatch.setattr(gesture, "add_noise", spy)
    monkeypatch.setattr(module, "log", lambda *a, **k: None)
    monkeypatch.setattr(module, "log_dict", lambda *a, **k: None)
    with torch.autocast("cpu", dtype=torch.bfloat16):
        z, _, _ = module.model.prior.encode(batch["motion"], generator=g)
        loss = module.training_step(batch, 0)
    assert z.dtype == torch.bfloat16  # what made the difference
    assert seen == [(torch.float32, torch.float32)] and torch.isfinite(loss)


def test_train_refuses_more_devices_than_it_has(monkeypatch, tmp_path, capsys):
    import torch

    from emogesture.cli.main import main

    args = ["train", "gesture", "--data", str(tmp_path / "cache"), "--speech", str(tmp_path / "speech"),
            "--out", str(tmp_path / "run")]
    assert main([*args, "--devices", "0"]) == 2
    assert "--devices 0: at least 1" in capsys.readouterr().err
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    monkeypatch.setattr(torch.cuda, "device_count", lambda: 1)
    assert main([*args, "--device", "cuda", "--devices", "2"]) == 2
    err = capsys.readouterr().err
    assert "--devices 2: torch sees 1 GPU(s)" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "run").exists()


def test_the_bundled_gesture_model_s_flops_are_counted():
    """The benchmarks' floor counts the bundled model's FLOPs on the meta device, its computed buffers (the
    detail path's columns and cosines) moved there too."""
    from emogesture.assets import bundled_model_file
    from emogesture.checkpoints import load_model
    from emogesture.models.gesture import gesture_flops

    config = load_model(bundled_model_file("gesture"), "gesture").config
    assert config.vae.detail_path > 0  # the path whose buffers are built on the CPU
    flops = gesture_flops(config)
    assert flops["decode"] > 0 and flops["prior"] > flops["decode"] and flops["denoiser"] > 0
