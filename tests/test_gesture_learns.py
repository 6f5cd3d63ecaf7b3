"""A short gesture training learns what it is taught.

Two emotions, each with its own emotion latent and its own posture of the right elbow (bent one way or
the other, moving a little around it); content and style latents are noise shared by both. After a short
training through the training engine (prior, denoiser and alignment, at a narrow width), the reconstruction
loss has fallen and the model, given an emotion's latent and unseen content latents, generates that
emotion's posture — which it can only do by reading the emotion condition (the content and style carry
nothing about it, and a model that ignored the condition would draw either posture at chance or their
average).
"""

import csv

import numpy as np
import torch

from emogesture.checkpoints import load_model, save_model
from emogesture.config import load_config, to_dict
from emogesture.data.beat import EMOTIONS
from emogesture.models.metadata import GestureMetadata
from emogesture.motion.features import FeatureStats, MotionFeatureSpec, poses_to_features
from emogesture.pipeline.sampling import generate_from_conditions, window_seeds
from emogesture.train.gesture import GestureDataModule, GestureModule, GestureTrainConfig, GestureWindows
from emogesture.train.runs import RunOptions, run_training

FRAMES = 60
RIGHT_ELBOW = 19
TAUGHT = {EMOTIONS.index("happiness"): 1.0, EMOTIONS.index("sadness"): -1.0}  # the elbow's bend, radians
NARROW = ["model.vae.timing_features=0", "model.vae.detail_path=0", "model.vae.detail_columns=[]",
          "model.vae.low_frequency_path=4", f"model.vae.frames={FRAMES}", "model.vae.width=32", "model.vae.ff_dim=64",
          "model.vae.heads=2", "model.denoiser.layers=3", "model.denoiser.ff_dim=256", "model.denoiser.dropout=0", "batch_size=16",
          "align_ddim_steps=2", "prior_warmup_steps=60", "generation.residual_scale=0",
          "generation.num_inference_steps=8"]


def windows(emotions: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Feature windows ``[W, FRAMES, 282]``: the rest pose but for the right elbow, bent by its emotion's
    angle with a slow swing of random phase."""
    t = np.arange(FRAMES) / 30.0
    poses = np.zeros((len(emotions), FRAMES, 55, 3), np.float32)
    for i, e in enumerate(emotions):
        poses[i, :, RIGHT_ELBOW, 1] = TAUGHT[int(e)] + 0.25 * np.sin(2 * np.pi * t + rng.uniform(0, 2 * np.pi))
    return poses_to_features(torch.from_numpy(poses)).numpy()


def conditions(emotions: np.ndarray, rng: np.random.Generator, table: dict) -> list[np.ndarray]:
    n = len(emotions)
    emotion = np.stack([table[int(e)] for e in emotions]) + 0.1 * rng.standard_normal((n, 256))
    return [rng.standard_normal((n, 256)).astype(np.float32), emotion.astype(np.float32),
            (table["style"] + 0.1 * rng.standard_normal((n, 256))).astype(np.float32)]


def test_a_short_training_learns_to_follow_the_emotion_condition(tmp_path):
    rng = np.random.default_rng(0)
    table = {k: rng.standard_normal(256) for k in [*TAUGHT, "style"]}
    labels = np.repeat(list(TAUGHT), 24)
    motion = windows(labels, rng)
    stats = FeatureStats.compute(motion)
    config = load_config(GestureTrainConfig, None, NARROW, base=to_dict(GestureTrainConfig.preset("tiny")))
    features = to_dict(MotionFeatureSpec())

    def build(config, data, seed):
        data = GestureDataModule(GestureWindows(motion, stats.mean, stats.std, conditions(labels, rng, table), labels),
                                 config.batch_size, seed)
        module = GestureModule(to_dict(config), stats.mean.tolist(), stats.std.tolist(), features, seed)

        def export(m, run_dir):
            meta = GestureMetadata(emotions=list(EMOTIONS), motion_mean=stats.mean.tolist(),
                                   motion_std=stats.std.tolist(), features=features, variant="joint", fps=30,
                                   train_splits=["train"], step=m.global_step)
            save_model(run_dir, "gesture", m.averaged, m.cfg.model, meta, generation=m.cfg.generation)

        return data, module, export

    run = run_training("train gesture", config, build, tmp_path, tmp_path / "run",
                       RunOptions(steps=240, log_every=10, checkpoint_every=1000, progress=False))
    with open(tmp_path / "run" / "logs" / "metrics.csv") as f:
        rec = [float(r["train/rec"]) for r in csv.DictReader(f) if r.get("train/rec")]
    assert np.mean(rec[-3:]) < 0.5 * np.mean(rec[:3]), rec  # the loss fell

    model = load_model(run.model, "gesture")
    test = np.repeat(list(TAUGHT), 8)
    generated = generate_from_conditions(model, conditions(test, np.random.default_rng(1), table),
                                         window_seeds(0, len(test)), residual=False)
    elbow = MotionFeatureSpec().columns([RIGHT_ELBOW])
    taught = {k: windows(np.array([k]), np.random.default_rng(2))[0][:, elbow].mean(0) for k in TAUGHT}
    shown = generated[:, :, elbow].mean(1)  # [W, 6]: each window's mean elbow rotation
    nearest = [min(TAUGHT, key=lambda k: np.linalg.norm(s - taught[k])) for s in shown]
    assert np.mean(np.array(nearest) == test) >= 0.9, (nearest, test)
