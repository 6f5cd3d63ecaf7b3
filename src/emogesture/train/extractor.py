"""Training the motion feature extractor M (docs/design.md, 'Metrics'; paper supp. D): emotion classification
of motion windows."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import lightning as L
import torch
import torch.nn.functional as F
from torch.utils.data import DataLoader

from emogesture.checkpoints import save_model
from emogesture.config import from_dict, to_dict
from emogesture.data.beat import EMOTIONS
from emogesture.data.cache import open_cache
from emogesture.data.datasets import WindowDataset
from emogesture.models.extractor import ExtractorConfig, MotionFeatureExtractor
from emogesture.models.metadata import ExtractorMetadata
from emogesture.train.engine import step_generator


@dataclass
class ExtractorTrainConfig:
    model: ExtractorConfig = field(default_factory=lambda: ExtractorConfig.preset("tiny"))
    batch_size: int = 32
    lr: float = 5e-4
    weight_decay: float = 1e-2
    noise_std: float = 0.05  # Gaussian noise on normalised features while training
    num_workers: int = 0

    @classmethod
    def preset(cls, size: str = "tiny") -> "ExtractorTrainConfig":
        return cls(model=ExtractorConfig.preset(size))


class ExtractorDataModule(L.LightningDataModule):
    def __init__(self, cache_dir: Path, batch_size: int, seed: int, num_workers: int = 0) -> None:
        super().__init__()
        self.cache = open_cache(cache_dir)
        self.train = self.cache.split("train")
        self.batch_size, self.seed, self.num_workers = batch_size, seed, num_workers

    def train_dataloader(self) -> DataLoader:
        g = torch.Generator().manual_seed(self.seed)
        return DataLoader(WindowDataset(self.train, with_fbank=False), batch_size=self.batch_size, shuffle=True,
                          drop_last=len(self.train) > self.batch_size, generator=g, num_workers=self.num_workers)


class ExtractorModule(L.LightningModule):
    def __init__(self, config: dict, motion_mean: list, motion_std: list, seed: int = 0) -> None:
        super().__init__()
        self.save_hyperparameters()
        self.cfg = from_dict(ExtractorTrainConfig, config)
        self.seed = seed
        torch.manual_seed(seed)
        self.model = MotionFeatureExtractor(self.cfg.model)
        self.register_buffer("mean", torch.tensor(motion_mean, dtype=torch.float32))
        self.register_buffer("std", torch.tensor(motion_std, dtype=torch.float32))

    def training_step(self, batch: dict, batch_idx: int) -> torch.Tensor:
        x = (batch["motion"] - self.mean) / self.std
        if self.cfg.noise_std > 0:
            g = step_generator(self.seed, self.global_step, self.global_rank)
            x = x + self.cfg.noise_std * torch.randn(x.shape, generator=g).to(x.device)
        _, logits = self.model(x)
        loss = F.cross_entropy(logits, batch["emotion"])
        acc = (logits.argmax(1) == batch["emotion"]).float().mean()
        self.log_dict({"train/loss": loss.detach(), "train/acc": acc}, on_step=True, batch_size=len(x))
        self.log("loss", loss.detach(), prog_bar=True, batch_size=len(x))
        return loss

    def configure_optimizers(self):
        opt = torch.optim.AdamW(self.model.parameters(), lr=self.cfg.lr, weight_decay=self.cfg.weight_decay)
        total = max(1, self.trainer.max_steps)
        sched = torch.optim.lr_scheduler.LambdaLR(opt, lambda s: 0.5 * (1 + math.cos(math.pi * min(s, total) / total)))
        return {"optimizer": opt, "lr_scheduler": {"scheduler": sched, "interval": "step"}}


def build(config: ExtractorTrainConfig, cache_dir: Path, seed: int):
    data = ExtractorDataModule(cache_dir, config.batch_size, seed, config.num_workers)
    config.model.feature_dim = int(data.train.motion.shape[2])
    config.model.max_frames = max(config.model.max_frames, int(data.train.motion.shape[1]))
    stats = data.cache.stats
    module = ExtractorModule(to_dict(config), stats["motion_mean"], stats["motion_std"], seed)

    def export(m: ExtractorModule, run_dir: Path) -> None:
        metadata = ExtractorMetadata(emotions=list(EMOTIONS), motion_mean=stats["motion_mean"],
                                     motion_std=stats["motion_std"], features=data.cache.manifest["config"]["features"],
                                     step=m.global_step, train_splits=["train"])
        save_model(run_dir, "extractor", m.model, m.cfg.model, metadata)

    return data, module, export
