"""Latent denoiser Δ (docs/design.md, 'Gesture generation model'; paper §3.3 "Conditional denoising process",
§4 "Denoiser").

Tokens ``[z_t, SE(t), c, e, s]``, each projected to the model width (SE = sinusoidal timestep embedding
followed by a two-layer MLP), pass through the same skip-transformer shape as the VAE encoder (learnable
positional embedding in every attention layer); the FIRST output token, projected to ``latent_dim``, is
the prediction: the noise ε̂ in the paper (the scheduler's ``prediction_type`` says what it is). With
``num_conditions = 1`` the single latent ``m`` of the no-disentanglement ablation replaces ``(c, e, s)``.

Beyond the paper (off in both presets unless ``timing_tokens > 0``): a time-resolved speech
stream (:func:`emogesture.audio.timing.timing_stream`, ``[B, 300, 2]`` per 10-s window) enters as
``timing_tokens`` more tokens, token ``k`` holding the stream of frames ``[k·span, (k+1)·span)`` through its
own Linear (so that attention spread evenly over them is already a full linear map of the stream). The
latent token attends to the speech of every span of the window it covers: (c, e, s) are one vector each
per window and cannot say when inside the window a syllable falls.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import torch
from torch import nn

from emogesture.errors import ConfigError
from emogesture.models.skip_transformer import SkipTransformer, SkipTransformerConfig, sinusoidal_embedding


@dataclass
class DenoiserConfig:
    """Size of the latent denoiser. Defaults are the ``paper`` preset.

    The paper gives "hidden dimension of all transformer layers is 1024" and "the same architecture as
    the prior encoder" (9 layers, 4 heads). ``paper`` reads that as width 1024, 9 layers, 4 heads and
    chooses a feed-forward size of 2 × width = 2048 and MLD's dropout 0.1 (≈84 M parameters).
    """

    latent_dim: int = 256
    cond_dim: int = 256
    width: int = 1024
    layers: int = 9
    heads: int = 4
    ff_dim: int = 2048
    dropout: float = 0.1
    num_conditions: int = 3
    time_embed_dim: int = 256
    #: Tokens of the timing stream (0 = the paper's denoiser, no stream), each ``timing_frames /
    #: timing_tokens`` frames of ``timing_features`` numbers.
    timing_tokens: int = 0
    timing_frames: int = 300
    timing_features: int = 2

    def __post_init__(self) -> None:
        if min(self.latent_dim, self.cond_dim, self.num_conditions, self.time_embed_dim) < 1:
            raise ConfigError("denoiser: latent_dim, cond_dim, num_conditions and time_embed_dim must be ≥ 1")
        if self.timing_tokens < 0 or (self.timing_tokens and (
                self.timing_frames % self.timing_tokens or self.timing_features < 1)):
            raise ConfigError(f"denoiser: timing_tokens ({self.timing_tokens}) must be ≥ 0 and divide timing_frames "
                              f"({self.timing_frames}); timing_features ≥ 1")
        self.transformer()  # validates width/heads/layers/dropout

    def transformer(self) -> SkipTransformerConfig:
        return SkipTransformerConfig(self.width, self.layers, self.heads, self.ff_dim, self.dropout, False)

    @property
    def num_tokens(self) -> int:
        """``z_t``, the timestep, one token per condition (5 for ``(c, e, s)``) and the timing tokens."""
        return 2 + self.num_conditions + self.timing_tokens

    @property
    def num_inputs(self) -> int:
        """How many condition tensors ``forward`` takes: the latents, then the timing stream if any."""
        return self.num_conditions + (1 if self.timing_tokens else 0)

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
        if c.timing_tokens:  # one Linear per timing token (a batched weight), initialised like nn.Linear
            fan_in = c.timing_frames // c.timing_tokens * c.timing_features
            bound = fan_in ** -0.5
            self.timing_weight = nn.Parameter(torch.empty(c.timing_tokens, fan_in, w).uniform_(-bound, bound))
            self.timing_bias = nn.Parameter(torch.empty(c.timing_tokens, w).uniform_(-bound, bound))
        self.pos = nn.Parameter(torch.zeros(1, c.num_tokens, w))
        self.transformer = SkipTransformer(c.transformer())
        self.output = nn.Linear(w, c.latent_dim)
        nn.init.trunc_normal_(self.pos, std=0.02)

    def tokens(self, z_t: torch.Tensor, t: torch.Tensor, conditions: Sequence[torch.Tensor]) -> torch.Tensor:
        """The input token sequence ``[B, num_tokens, width]``: ``[z_t, SE(t), c, e, s]`` (+ timing tokens)."""
        c = self.config
        if z_t.dim() != 2 or z_t.shape[-1] != c.latent_dim:
            raise ValueError(f"denoiser expects z_t [B, {c.latent_dim}], got {tuple(z_t.shape)}")
        if len(conditions) != c.num_inputs:
            timing = " and a timing stream" if c.timing_tokens else ""
            raise ValueError(f"denoiser expects {c.num_conditions} condition latents{timing}, got {len(conditions)} tensors")
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
        toks = torch.stack(toks, dim=1)
        if c.timing_tokens:
            stream = conditions[c.num_conditions]
            if stream.shape != (b, c.timing_frames, c.timing_features):
                raise ValueError(f"denoiser expects a timing stream [B={b}, {c.timing_frames}, {c.timing_features}], "
                                 f"got {tuple(stream.shape)}")
            spans = stream.reshape(b, c.timing_tokens, -1).to(toks.dtype)
            toks = torch.cat([toks, torch.einsum("bki,kiw->bkw", spans, self.timing_weight) + self.timing_bias], dim=1)
        return toks

    def forward(self, z_t: torch.Tensor, t: torch.Tensor, conditions: Sequence[torch.Tensor]) -> torch.Tensor:
        """Args: noisy latent ``z_t [B, 256]``; integer timesteps ``t [B]`` (or a 0-d tensor / int for the
        whole batch); ``conditions``: a sequence of ``num_conditions`` tensors ``[B, 256]`` —
        ``(content, emotion, style)`` (an ``AudioLatents`` works) or ``(m,)`` for the ablation — followed,
        when ``timing_tokens > 0``, by the timing stream ``[B, timing_frames, timing_features]``.

        Returns: the prediction ``[B, 256]`` read from the first output token (the noise ε̂ with the
        paper's ε-prediction, ẑ0 with ``prediction_type="sample"``).
        """
        y = self.transformer(self.tokens(z_t, t, conditions), self.pos)
        return self.output(y[:, 0])
