"""The audio encoder of OpenAI's Whisper (MIT licence), as the front end that hears emotion in a real voice runs it.

Whisper's encoder is two convolutions over the log-mel spectrogram (the second halving the frame rate to 50 per
second), sinusoidal positions, pre-norm transformer layers and a final layer norm. The front end
(:mod:`emogesture.pipeline.voice_features`) builds it from :class:`WhisperEncoderConfig` and loads the weights of
Whisper tiny.en into it; this module only computes."""

from __future__ import annotations

from dataclasses import dataclass

import torch
import torch.nn.functional as F
from torch import nn

from emogesture.kernels import linear_gelu


@dataclass(frozen=True)
class WhisperEncoderConfig:
    """The encoder's shape (Whisper tiny's by default)."""

    n_mels: int = 80
    width: int = 384
    heads: int = 6
    layers: int = 4
    positions: int = 1500  # 30 s at 50 frames a second: the longest input


class WhisperEncoderLayer(nn.Module):
    """Pre-norm self-attention (query, key and value from one product) and a GELU feed-forward of 4 × width."""

    def __init__(self, width: int, heads: int) -> None:
        super().__init__()
        self.heads = heads
        self.attention_norm = nn.LayerNorm(width)
        self.qkv = nn.Linear(width, 3 * width)
        self.out = nn.Linear(width, width)
        self.ffn_norm = nn.LayerNorm(width)
        self.ffn_in = nn.Linear(width, 4 * width)
        self.ffn_out = nn.Linear(4 * width, width)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """``x [B, T, width]`` -> ``[B, T, width]``."""
        b, t, d = x.shape
        q, k, v = self.qkv(self.attention_norm(x)).view(b, t, 3, self.heads, d // self.heads).permute(2, 0, 3, 1, 4)
        x = x + self.out(F.scaled_dot_product_attention(q, k, v).transpose(1, 2).reshape(b, t, d))
        # the GELU inside the product's oneDNN call where it can run (bf16 on a CPU), on its float32 sums: apart,
        # the [B, T, 4 × width] activation is written, read and written again (8 windows in bf16 on 2 cores:
        # 128 against 143 ms)
        h = self.ffn_norm(x)
        hidden = linear_gelu(self.ffn_in, h)
        return x + self.ffn_out(F.gelu(self.ffn_in(h)) if hidden is None else hidden)


class WhisperEncoder(nn.Module):
    """Whisper's audio encoder."""

    def __init__(self, config: WhisperEncoderConfig = WhisperEncoderConfig()) -> None:
        super().__init__()
        self.config = config
        self.conv1 = nn.Conv1d(config.n_mels, config.width, 3, padding=1)
        self.conv2 = nn.Conv1d(config.width, config.width, 3, stride=2, padding=1)
        self.register_buffer("positions", torch.zeros(config.positions, config.width), persistent=True)
        self.layers = nn.ModuleList(WhisperEncoderLayer(config.width, config.heads) for _ in range(config.layers))
        self.norm = nn.LayerNorm(config.width)

    def forward(self, mel: torch.Tensor) -> torch.Tensor:
        """Log-mel ``mel [B, n_mels, F]`` (Whisper's scale, 100 frames a second, ``F`` even and at most
        ``2 × positions``) -> the last layer's states ``[B, F / 2, width]``."""
        if mel.shape[-1] > 2 * self.config.positions:
            raise ValueError(f"{mel.shape[-1]} frames: the encoder takes at most {2 * self.config.positions}")
        x = F.gelu(self.conv1(mel))
        x = F.gelu(self.conv2(x)).transpose(1, 2)
        x = x + self.positions[: x.shape[1]].to(x.dtype)
        for layer in self.layers:
            x = layer(x)
        return self.norm(x)
