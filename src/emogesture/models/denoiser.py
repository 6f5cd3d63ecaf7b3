"""Latent denoiser Δ (docs/design.md, 'Gesture generation model'; paper §3.3 "Conditional denoising process",
§4 "Denoiser").

Tokens ``[z_t, SE(t), c, e, s]``, each projected to the model width (SE = sinusoidal timestep embedding
followed by a two-layer MLP), pass through the same skip-transformer shape as the VAE encoder (learnable
positional embedding in every attention layer); the FIRST output token, projected to ``latent_dim``, is
the prediction: the noise ε̂ in the paper (the scheduler's ``prediction_type`` says what it is). With
``num_conditions = 1`` the single latent ``m`` of the no-disentanglement ablation replaces ``(c, e, s)``.

The speech's timing reaches the motion through the motion decoder (``MotionVAEConfig.timing_features``);
timing tokens in the denoiser were tried and not adopted (``experiments/rhythm/README.md``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, Sequence

import torch
from torch import nn

from emogesture.config import ANY_VALUE
from emogesture.errors import ConfigError
from emogesture.models.skip_transformer import SkipTransformer, SkipTransformerConfig, sinusoidal_embedding


@dataclass
class DenoiserConfig:
    """Size of the latent denoiser. Defaults are the ``paper`` preset.

    The paper gives "hidden dimension of all transformer layers is 1024" and "the same architecture as
    the prior encoder" (9 layers, 4 heads). ``paper`` reads that as width 1024, 9 layers, 4 heads and
    chooses a feed-forward size of 2 × width = 2048 and MLD's dropout 0.1 (≈84 M parameters).
    """

    RETIRED: ClassVar[dict] = {"timing_tokens": 0, "timing_frames": ANY_VALUE, "timing_features": ANY_VALUE}

    latent_dim: int = 256
    cond_dim: int = 256
    width: int = 1024
    layers: int = 9
    heads: int = 4
    ff_dim: int = 2048
    dropout: float = 0.1
    num_conditions: int = 3
    time_embed_dim: int = 256

    def __post_init__(self) -> None:
        if min(self.latent_dim, self.cond_dim, self.num_conditions, self.time_embed_dim) < 1:
            raise ConfigError("denoiser: latent_dim, cond_dim, num_conditions and time_embed_dim must be ≥ 1")
        self.transformer()  # validates width/heads/layers/dropout

    def transformer(self) -> SkipTransformerConfig:
        return SkipTransformerConfig(self.width, self.layers, self.heads, self.ff_dim, self.dropout, False)

    @property
    def num_tokens(self) -> int:
        """``z_t``, the timestep and one token per condition (5 for ``(c, e, s)``)."""
        return 2 + self.num_conditions

    @classmethod
    def preset(cls, name: str, num_conditions: int = 3) -> "DenoiserConfig":
        """``paper``: width 1024, 9 layers, 4 heads, ff 2048. ``tiny``: width 256 (= latent_dim, the
        narrowest width that does not bottleneck the prediction), 5 layers, 4 heads, ff 512."""
        if name == "paper":
            return cls(num_conditions=num_conditions)
        if name == "tiny":
            return cls(width=256, layers=5, heads=4, ff_dim=512, num_conditions=num_conditions)
        raise ConfigError(f"unknown denoiser preset {name!r}; known: paper, tiny")


class LatentDenoiser(nn.Module):
    """Δ(z_t, t, c, e, s) -> ε̂ (or ẑ0 / v̂, by the scheduler's prediction type); see the module docstring."""

    def __init__(self, config: DenoiserConfig) -> None:
        super().__init__()
        self.config = config
        c = config
        w = c.width
        self.latent_input = nn.Linear(c.latent_dim, w)
        self.time_mlp = nn.Sequential(nn.Linear(c.time_embed_dim, w), nn.SiLU(), nn.Linear(w, w))
        self.condition_inputs = nn.ModuleList(nn.Linear(c.cond_dim, w) for _ in range(c.num_conditions))
        self.pos = nn.Parameter(torch.zeros(1, c.num_tokens, w))
        self.transformer = SkipTransformer(c.transformer())
        self.output = nn.Linear(w, c.latent_dim)
        nn.init.trunc_normal_(self.pos, std=0.02)

    def tokens(self, z_t: torch.Tensor, t: torch.Tensor, conditions: Sequence[torch.Tensor]) -> torch.Tensor:
        """The input token sequence ``[B, num_tokens, width]``: ``[z_t, SE(t), c, e, s]``."""
        c = self.config
        if z_t.dim() != 2 or z_t.shape[-1] != c.latent_dim:
            raise ValueError(f"denoiser expects z_t [B, {c.latent_dim}], got {tuple(z_t.shape)}")
        if len(conditions) != c.num_conditions:
            raise ValueError(f"denoiser expects {c.num_conditions} condition latents, got {len(conditions)} tensors")
        b = z_t.shape[0]
        t = torch.as_tensor(t, device=z_t.device)
        t = t.expand(b) if t.dim() == 0 else t
        if t.shape != (b,):
            raise ValueError(f"denoiser expects timesteps [B={b}] or a scalar, got {tuple(t.shape)}")
        toks = [self.latent_input(z_t), self.time_mlp(sinusoidal_embedding(t, c.time_embed_dim).to(z_t.dtype))]
        for proj, cond in zip(self.condition_inputs, conditions):
            if cond.shape != (b, c.cond_dim):
                raise ValueError(f"denoiser expects conditions [B={b}, {c.cond_dim}], got {tuple(cond.shape)}")
            toks.append(proj(cond))
        return torch.stack(toks, dim=1)

    def forward(self, z_t: torch.Tensor, t: torch.Tensor, conditions: Sequence[torch.Tensor]) -> torch.Tensor:
        """Args: noisy latent ``z_t [B, 256]``; integer timesteps ``t [B]`` (or a 0-d tensor / int for the
        whole batch); ``conditions``: a sequence of ``num_conditions`` tensors ``[B, 256]`` —
        ``(content, emotion, style)`` (an ``AudioLatents`` works) or ``(m,)`` for the ablation.

        Returns: the prediction ``[B, 256]`` read from the first output token (the noise ε̂ with the
        paper's ε-prediction, ẑ0 with ``prediction_type="sample"``).
        """
        y = self.transformer(self.tokens(z_t, t, conditions), self.pos)
        return self.output(y[:, 0])
