"""The MLD-style "skip transformer": a U-Net-like stack of transformer layers (paper §3.3, supp. Fig. A.7).

With ``num_layers = 2k + 1`` layers there are ``k`` input blocks, one middle block and ``k`` output
blocks (9 layers: 4 + 1 + 4). Output block ``i`` first fuses the output of its mirrored input block
(the last input block pairs with the first output block) by ``Linear(cat([x, skip]), 2d -> d)``, then
runs its layer. A final LayerNorm closes the stack.

Choices (documented, not from the paper's text):

- **Pre-norm** layers (``x + attn(norm(x))``), like the audio ViT of this project, with a final
  LayerNorm. MLD used post-norm; pre-norm trains more stably from scratch and needs no warm-up.
- **Positional embedding in every attention layer** (DETR style, "PE injected into each multi-head
  attention layer"): the caller passes ``pos [1 or B, N, d]`` and every self-attention adds it to its
  queries and keys (values are not shifted); cross-attention adds it to its queries. Memory tokens get
  no positional term (the VAE decoder's memory is a single token).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
import torch.nn.functional as F
from torch import nn

from emogesture.errors import ConfigError
from emogesture.kernels import attention
from emogesture.models.vit import LN_EPS, Attention, CrossAttention, Mlp, init_transformer_weights


@dataclass
class SkipTransformerConfig:
    """Shape of one skip transformer. ``layers`` must be odd and ≥ 3 (9 in the paper)."""

    width: int = 256
    layers: int = 9
    heads: int = 4
    ff_dim: int = 1024
    dropout: float = 0.1
    cross_attention: bool = False

    def __post_init__(self) -> None:
        if self.layers < 3 or self.layers % 2 == 0:
            raise ConfigError(f"skip transformer: layers must be odd and >= 3, got {self.layers}")
        if self.width % self.heads:
            raise ConfigError(f"skip transformer: width {self.width} is not divisible by heads {self.heads}")
        if not 0.0 <= self.dropout < 1.0:
            raise ConfigError(f"skip transformer: dropout must be in [0, 1), got {self.dropout}")

    @property
    def num_skips(self) -> int:
        """Number of input blocks = number of output blocks = number of fuse Linears."""
        return (self.layers - 1) // 2


class PosSelfAttention(Attention):
    """Self-attention with a positional term added to queries and keys only (values from ``x``).

    Keeps :class:`~emogesture.models.vit.Attention`'s parameters (one ``qkv`` Linear, ``proj``).
    """

    def forward(self, x: torch.Tensor, pos: torch.Tensor | None = None) -> torch.Tensor:
        """``x [B, N, W]``, ``pos [1 or B, N, W]`` or None ``-> [B, N, W]``."""
        b, n, w = x.shape
        hd = w // self.heads
        if pos is not None and torch.is_grad_enabled():
            qk = F.linear(x + pos, self.qkv.weight[: 2 * w], self.qkv.bias[: 2 * w])
            v = F.linear(x, self.qkv.weight[2 * w :], self.qkv.bias[2 * w :])
        else:
            # without autograd, one product of x for q, k and v through the qkv Linear itself (so it runs as
            # that layer runs, e.g. packed under runtime.bf16_weights), and pos's part of q and k (the same
            # for every sample) added once: (x + pos) W = x W + pos W
            qkv = self.qkv(x)
            if pos is not None:
                qkv[..., : 2 * w] += F.linear(pos, self.qkv.weight[: 2 * w]).to(qkv.dtype)
            qk, v = qkv[..., : 2 * w], qkv[..., 2 * w :]
        qk = qk.reshape(b, n, 2, self.heads, hd).permute(2, 0, 3, 1, 4)
        v = v.reshape(b, n, self.heads, hd).transpose(1, 2)
        p = self.dropout if self.training else 0.0
        y = attention(qk[0], qk[1], v, dropout_p=p)
        return self.proj_drop(self.proj(y.transpose(1, 2).reshape(b, n, w)))


class SkipLayer(nn.Module):
    """One pre-norm layer: self-attention (+pos), optional cross-attention (+pos on queries), MLP."""

    def __init__(self, width: int, heads: int, ff_dim: int, dropout: float, cross_attention: bool) -> None:
        super().__init__()
        self.norm1 = nn.LayerNorm(width, eps=LN_EPS)
        self.attn = PosSelfAttention(width, heads, dropout)
        if cross_attention:
            self.norm_cross = nn.LayerNorm(width, eps=LN_EPS)
            self.cross = CrossAttention(width, heads, dropout)
        else:
            self.norm_cross = self.cross = None
        self.norm2 = nn.LayerNorm(width, eps=LN_EPS)
        self.mlp = Mlp(width, ff_dim, dropout)

    def forward(
        self, x: torch.Tensor, pos: torch.Tensor | None = None, memory: torch.Tensor | None = None
    ) -> torch.Tensor:
        """``x [B, N, W]``, ``pos [1 or B, N, W]``, ``memory [B, M, W]`` ``-> [B, N, W]``."""
        x = x + self.attn(self.norm1(x), pos)
        if self.cross is not None:
            if memory is None:
                raise ValueError("this skip transformer has cross-attention: pass a memory [B, M, W]")
            q = self.norm_cross(x)
            x = x + self.cross(q if pos is None else q + pos, memory)
        return x + self.mlp(self.norm2(x))


class SkipTransformer(nn.Module):
    """U-Net-like transformer: ``k`` input blocks, a middle block, ``k`` output blocks with skip fusion."""

    def __init__(self, config: SkipTransformerConfig) -> None:
        super().__init__()
        self.config = config
        c = config

        def layer() -> SkipLayer:
            return SkipLayer(c.width, c.heads, c.ff_dim, c.dropout, c.cross_attention)

        self.input_blocks = nn.ModuleList(layer() for _ in range(c.num_skips))
        self.middle_block = layer()
        self.output_blocks = nn.ModuleList(layer() for _ in range(c.num_skips))
        self.fuse = nn.ModuleList(nn.Linear(2 * c.width, c.width) for _ in range(c.num_skips))
        self.norm = nn.LayerNorm(c.width, eps=LN_EPS)
        self.apply(init_transformer_weights)

    def forward(
        self, x: torch.Tensor, pos: torch.Tensor | None = None, memory: torch.Tensor | None = None
    ) -> torch.Tensor:
        """Args: tokens ``x [B, N, W]``; positional embedding ``pos [1 or B, N, W]`` added to the
        queries and keys of every attention layer; ``memory [B, M, W]`` for cross-attention (required
        iff the config has ``cross_attention``).

        Returns: ``[B, N, W]`` after the final LayerNorm.
        """
        if x.dim() != 3 or x.shape[-1] != self.config.width:
            raise ValueError(f"skip transformer expects [B, N, {self.config.width}], got {tuple(x.shape)}")
        if pos is not None and pos.shape[-2:] != x.shape[-2:]:
            raise ValueError(f"positional embedding {tuple(pos.shape)} does not match tokens {tuple(x.shape)}")
        skips = []
        for block in self.input_blocks:
            x = block(x, pos, memory)
            skips.append(x)
        x = self.middle_block(x, pos, memory)
        for block, fuse in zip(self.output_blocks, self.fuse):
            x = block(fuse(torch.cat([x, skips.pop()], dim=-1)), pos, memory)
        return self.norm(x)


def sinusoidal_embedding(t: torch.Tensor, dim: int, max_period: float = 10000.0) -> torch.Tensor:
    """Sinusoidal embedding of (diffusion) timesteps, as in DDPM/Transformer: ``t [B] -> [B, dim]``.

    The first half holds ``cos(t * f_i)``, the second ``sin(t * f_i)`` with
    ``f_i = max_period ** (-i / (dim // 2))``; an odd ``dim`` gets one zero column at the end.
    """
    half = dim // 2
    freqs = torch.exp(-torch.log(torch.tensor(max_period)) * torch.arange(half, dtype=torch.float32) / half)
    args = t.to(torch.float32)[:, None] * freqs.to(t.device)[None]
    emb = torch.cat([torch.cos(args), torch.sin(args)], dim=-1)
    if dim % 2:
        emb = F.pad(emb, (0, 1))
    return emb
