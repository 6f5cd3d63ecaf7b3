"""Motion feature extractor M (docs/design.md, 'Metrics'; paper supp. D): judges generated motion.

A transformer encoder over motion-feature windows with a [CLS] token, trained to classify emotion
(cross-entropy). Its [CLS] output features feed FGD and Div; its classifier gives GA.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn

from emogesture.errors import ConfigError


@dataclass
class ExtractorConfig:
    """Size of the motion feature extractor; defaults are the ``paper`` preset.

    The paper gives no size (it follows Petrovich et al.'s TEMOS/ACTOR encoders); ``paper`` uses
    their usual width 256, 6 layers, 4 heads, feed-forward 1024.
    """

    feature_dim: int = 282
    max_frames: int = 300
    width: int = 256
    depth: int = 6
    heads: int = 4
    ff_dim: int = 1024
    dropout: float = 0.1
    num_emotions: int = 8

    def __post_init__(self) -> None:
        if self.width % self.heads:
            raise ConfigError(f"extractor: width {self.width} is not divisible by heads {self.heads}")

    @classmethod
    def preset(cls, name: str, feature_dim: int = 282) -> "ExtractorConfig":
        if name == "paper":
            return cls(feature_dim=feature_dim)
        if name == "tiny":
            return cls(feature_dim=feature_dim, width=64, depth=2, heads=4, ff_dim=128, dropout=0.1)
        raise ConfigError(f"unknown extractor preset {name!r}; known: paper, tiny")


class MotionFeatureExtractor(nn.Module):
    """``motion [B, T, D]`` (normalised features) -> ``features [B, width]``, ``logits [B, 8]``."""

    def __init__(self, config: ExtractorConfig) -> None:
        super().__init__()
        self.config = config
        c = config
        self.input = nn.Linear(c.feature_dim, c.width)
        self.cls_token = nn.Parameter(torch.zeros(1, 1, c.width))
        self.pos_embed = nn.Parameter(torch.zeros(1, c.max_frames + 1, c.width))
        layer = nn.TransformerEncoderLayer(
            c.width, c.heads, c.ff_dim, c.dropout, activation="gelu", batch_first=True, norm_first=True
        )
        self.encoder = nn.TransformerEncoder(layer, c.depth, enable_nested_tensor=False)
        self.norm = nn.LayerNorm(c.width)
        self.classifier = nn.Linear(c.width, c.num_emotions)
        nn.init.trunc_normal_(self.cls_token, std=0.02)
        nn.init.trunc_normal_(self.pos_embed, std=0.02)

    def forward(self, motion: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Args: motion ``[B, T, D]`` with ``T <= max_frames``.

        Returns: ``features [B, width]`` (the normalised [CLS] output) and ``logits [B, num_emotions]``.
        """
        b, t, d = motion.shape
        if d != self.config.feature_dim or t > self.config.max_frames:
            raise ValueError(
                f"extractor expects [B, T<={self.config.max_frames}, {self.config.feature_dim}], got {tuple(motion.shape)}"
            )
        x = torch.cat([self.cls_token.expand(b, -1, -1), self.input(motion)], dim=1)
        x = self.encoder(x + self.pos_embed[:, : t + 1])
        features = self.norm(x[:, 0])
        return features, self.classifier(features)
