"""A DeiT-style distilled Vision Transformer over a log-mel filterbank (docs/design.md, 'Speech disentanglement
model'; paper supp. B.2).

The filterbank ``[B, 1024 (time), 128 (freq)]`` is treated as a one-channel image of height = frequency
and width = time, i.e. ``[B, 1, 128, 1024]``. Overlapping 16×16 patches with stride 10 give a grid of
12 (freq) × 101 (time) = 1212 patches, flattened frequency-major (row ``f`` holds patches
``f * 101 ... f * 101 + 100``). Two prefix tokens, [CLS] then [DIST], come first.

Attribute names follow the timm DeiT layout (``patch_embed.proj``, ``cls_token``, ``dist_token``,
``pos_embed``, ``blocks.N.{norm1,attn.qkv,attn.proj,norm2,mlp.fc1,mlp.fc2}``, ``norm``) so a pretrained
state dict maps key for key (see :mod:`emogesture.models.pretrained`).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
import torch.nn.functional as F
from torch import nn

from emogesture.errors import ConfigError
from emogesture.kernels import Dropout, attention, linear_gelu

LN_EPS = 1e-6
@dataclass
class ViTConfig:
    """Size of one audio ViT. Defaults are the paper's DeiT-B/16-384 (``ViTConfig.preset('paper')``)."""

    input_frames: int = 1024
    input_bins: int = 128
    patch: int = 16
    stride: int = 10
    #: Patch height / stride along frequency when they differ from ``patch`` / ``stride`` (0 = the same).
    #: ``patch_freq = input_bins`` makes every token one whole short-time spectrum slice.
    patch_freq: int = 0
    stride_freq: int = 0
    width: int = 768
    depth: int = 12
    heads: int = 12
    mlp_ratio: float = 4.0
    dropout: float = 0.0
    distilled: bool = True

    def __post_init__(self) -> None:
        if self.width % self.heads:
            raise ConfigError(f"vit: width {self.width} is not divisible by heads {self.heads}")
        if self.stride < 1 or self.patch < 1 or self.depth < 1 or min(self.patch_freq, self.stride_freq) < 0:
            raise ConfigError("vit: patch, stride and depth must be positive")
        if self.input_frames < self.patch or self.input_bins < self.kernel[0]:
            raise ConfigError(f"vit: input {self.input_frames}x{self.input_bins} is smaller than a patch")

    @property
    def kernel(self) -> tuple[int, int]:
        """Patch size (frequency, time): (16, 16) for the paper."""
        return (self.patch_freq or self.patch, self.patch)

    @property
    def strides(self) -> tuple[int, int]:
        """Patch stride (frequency, time): (10, 10) for the paper."""
        return (self.stride_freq or self.stride, self.stride)

    @property
    def grid(self) -> tuple[int, int]:
        """Patch grid (frequency rows, time columns): (12, 101) for 128 bins × 1024 frames."""
        f = (self.input_bins - self.kernel[0]) // self.strides[0] + 1
        t = (self.input_frames - self.kernel[1]) // self.strides[1] + 1
        return f, t

    @property
    def num_patches(self) -> int:
        f, t = self.grid
        return f * t

    @property
    def num_prefix(self) -> int:
        """Number of prefix tokens: 2 ([CLS], [DIST]) when distilled, else 1 ([CLS])."""
        return 2 if self.distilled else 1

    @classmethod
    def preset(cls, name: str) -> "ViTConfig":
        """``paper``: DeiT-B/16-384 (depth 12, width 768, 12 heads). ``tiny``: a CPU-sized encoder.

        ``tiny`` uses non-overlapping full-height patches, each token one 80-ms slice of the whole
        spectrum (128 bins × 8 frames: 128 tokens instead of 1212), so a training step of 16 quadruples
        stays near a second on two CPU cores; otherwise it is the paper's design. Whole-spectrum tokens
        let a small encoder read pitch and spectral balance directly: with square 32×32 patches the
        emotion classifier of the same width learned about three times slower on the synthetic corpus
        (held-out accuracy 0.48 vs 0.71 after 100 steps, 0.70 after 300).
        """
        if name == "paper":
            return cls()
        if name == "tiny":
            return cls(patch=8, stride=8, patch_freq=128, stride_freq=128, width=64, depth=2, heads=2)
        raise ConfigError(f"unknown ViT preset {name!r}; known: paper, tiny")


class Attention(nn.Module):
    """Multi-head self-attention with q, k, v from one Linear (``qkv``) and an output ``proj``."""

    def __init__(self, width: int, heads: int, dropout: float = 0.0) -> None:
        super().__init__()
        self.heads = heads
        self.dropout = dropout
        self.qkv = nn.Linear(width, 3 * width)
        self.proj = nn.Linear(width, width)
        self.proj_drop = Dropout(dropout)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """``x [B, N, W] -> [B, N, W]``; tokens attend only within their own sample."""
        b, n, w = x.shape
        qkv = self.qkv(x).reshape(b, n, 3, self.heads, w // self.heads).permute(2, 0, 3, 1, 4)
        p = self.dropout if self.training else 0.0
        y = attention(qkv[0], qkv[1], qkv[2], dropout_p=p)
        return self.proj_drop(self.proj(y.transpose(1, 2).reshape(b, n, w)))


class CrossAttention(nn.Module):
    """Multi-head attention of queries ``x`` over a separate ``memory`` (``q`` and ``kv`` Linears)."""

    def __init__(self, width: int, heads: int, dropout: float = 0.0) -> None:
        super().__init__()
        self.heads = heads
        self.dropout = dropout
        self.q = nn.Linear(width, width)
        self.kv = nn.Linear(width, 2 * width)
        self.proj = nn.Linear(width, width)
        self.proj_drop = Dropout(dropout)

    def forward(self, x: torch.Tensor, memory: torch.Tensor) -> torch.Tensor:
        """``x [B, N, W]``, ``memory [B, M, W] -> [B, N, W]``."""
        b, n, w = x.shape
        m = memory.shape[1]
        hd = w // self.heads
        p = self.dropout if self.training else 0.0
        if m == 1 and p == 0.0:
            # one memory token: the softmax over one key is exactly 1, so every query reads that token's
            # value (the same numbers, without the queries' product and the attention; the motion
            # decoder's memory is one token)
            v = F.linear(memory, self.kv.weight[w:], self.kv.bias[w:])  # [B, 1, W]
            out = self.proj_drop(self.proj(v))
            if torch.is_grad_enabled():
                # the queries' true gradient is zero: one query's stand-in keeps x and the q Linear in the
                # graph with that gradient, so weight decay and DDP see their parameters as with the
                # attention computed in full (where they get rounding-level gradients)
                out = out + 0.0 * self.q(x[:, :1]).sum()
            return out.expand(b, n, w)
        q = self.q(x).reshape(b, n, self.heads, hd).transpose(1, 2)
        kv = self.kv(memory).reshape(b, m, 2, self.heads, hd).permute(2, 0, 3, 1, 4)
        y = attention(q, kv[0], kv[1], dropout_p=p)
        return self.proj_drop(self.proj(y.transpose(1, 2).reshape(b, n, w)))


class Mlp(nn.Module):
    """``fc1`` -> GELU -> ``fc2`` with dropout."""

    def __init__(self, width: int, hidden: int, dropout: float = 0.0) -> None:
        super().__init__()
        self.fc1 = nn.Linear(width, hidden)
        self.act = nn.GELU()
        self.fc2 = nn.Linear(hidden, width)
        self.drop = Dropout(dropout)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """``x [B, N, W] -> [B, N, W]``. Without autograd the GELU is applied inside ``fc1``'s product
        where :func:`emogesture.kernels.linear_gelu` can (bf16 on a CPU), else in place on its output:
        the paper encoder's hidden activation is 3 × 1214 × 3072 numbers per batch, and a fresh tensor
        for it cost 12 % of the MLP's time on a 2-core CPU in bf16 (the same numbers either way)."""
        h = linear_gelu(self.fc1, x, self.act.approximate)  # None where it cannot run
        if h is None:
            h = self.fc1(x)
            if h.requires_grad:  # never inside no_grad / inference_mode
                h = self.act(h)
            else:
                h = torch.ops.aten.gelu_(h, approximate=self.act.approximate)
        return self.drop(self.fc2(self.drop(h)))


class Block(nn.Module):
    """Pre-norm transformer block: ``x + attn(norm1(x))``, then ``x + mlp(norm2(x))``."""

    def __init__(self, width: int, heads: int, mlp_ratio: float = 4.0, dropout: float = 0.0) -> None:
        super().__init__()
        self.norm1 = nn.LayerNorm(width, eps=LN_EPS)
        self.attn = Attention(width, heads, dropout)
        self.norm2 = nn.LayerNorm(width, eps=LN_EPS)
        self.mlp = Mlp(width, int(width * mlp_ratio), dropout)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """``x [B, N, W] -> [B, N, W]``."""
        x = x + self.attn(self.norm1(x))
        return x + self.mlp(self.norm2(x))


class CrossBlock(nn.Module):
    """Pre-norm decoder block: self-attention, cross-attention to ``memory``, MLP."""

    def __init__(self, width: int, heads: int, mlp_ratio: float = 4.0, dropout: float = 0.0) -> None:
        super().__init__()
        self.norm1 = nn.LayerNorm(width, eps=LN_EPS)
        self.attn = Attention(width, heads, dropout)
        self.norm_cross = nn.LayerNorm(width, eps=LN_EPS)
        self.cross = CrossAttention(width, heads, dropout)
        self.norm2 = nn.LayerNorm(width, eps=LN_EPS)
        self.mlp = Mlp(width, int(width * mlp_ratio), dropout)

    def forward(self, x: torch.Tensor, memory: torch.Tensor) -> torch.Tensor:
        """``x [B, N, W]``, ``memory [B, M, W] -> [B, N, W]``."""
        x = x + self.attn(self.norm1(x))
        x = x + self.cross(self.norm_cross(x), memory)
        return x + self.mlp(self.norm2(x))


def init_transformer_weights(module: nn.Module) -> None:
    """ViT-style init (use with ``Module.apply``): truncated normal 0.02 for Linear, zero biases."""
    if isinstance(module, nn.Linear):
        nn.init.trunc_normal_(module.weight, std=0.02)
        if module.bias is not None:
            nn.init.zeros_(module.bias)
    elif isinstance(module, nn.LayerNorm):
        nn.init.ones_(module.weight)
        nn.init.zeros_(module.bias)


class PatchEmbed(nn.Module):
    """Conv2d(1 -> width, kernel ``kernel``, stride ``strides``) over the image ``[B, 1, bins, frames]``.

    ``proj.weight`` is ``[W, 1, patch (freq), patch (time)]`` (image height = frequency, as DeiT/AST
    kernels are read). The convolution runs on the time-major input with the kernel transposed, which
    gives the same numbers without copying the filterbank.
    """

    def __init__(self, config: ViTConfig) -> None:
        super().__init__()
        self.stride = config.strides[::-1]  # (time, freq) for the time-major input
        self.proj = nn.Conv2d(1, config.width, kernel_size=config.kernel, stride=config.strides)

    def forward(self, fbank: torch.Tensor) -> torch.Tensor:
        """``fbank [B, 1024, 128] -> patches [B, 12 * 101, W]`` (frequency-major).

        Training under CPU bf16 autocast runs this convolution in float32: the bf16 weight gradient of
        a convolution took a slow path on the CPU (585 ms of a 2.6-s tiny speech training step on a
        Xeon with AMX), float32 none."""
        x, weight, bias = fbank.unsqueeze(1), self.proj.weight.transpose(2, 3), self.proj.bias
        if x.device.type == "cpu" and torch.is_autocast_enabled("cpu") and torch.is_grad_enabled() \
                and weight.requires_grad:
            with torch.autocast("cpu", enabled=False):
                y = F.conv2d(x.float(), weight, bias, stride=self.stride)
        else:
            y = F.conv2d(x, weight, bias, stride=self.stride)
        b, w = y.shape[:2]  # y: [B, W, 101 (time), 12 (freq)]
        return y.permute(0, 3, 2, 1).reshape(b, -1, w)


class AudioViT(nn.Module):
    """DeiT-style distilled ViT over a filterbank; returns every output token after the final norm."""

    def __init__(self, config: ViTConfig) -> None:
        super().__init__()
        self.config = config
        w = config.width
        self.patch_embed = PatchEmbed(config)
        self.cls_token = nn.Parameter(torch.zeros(1, 1, w))
        self.dist_token = nn.Parameter(torch.zeros(1, 1, w)) if config.distilled else None
        self.pos_embed = nn.Parameter(torch.zeros(1, config.num_prefix + config.num_patches, w))
        self.pos_drop = Dropout(config.dropout)
        self.blocks = nn.ModuleList(
            Block(w, config.heads, config.mlp_ratio, config.dropout) for _ in range(config.depth)
        )
        self.norm = nn.LayerNorm(w, eps=LN_EPS)
        self.apply(init_transformer_weights)
        for p in (self.cls_token, self.dist_token, self.pos_embed):
            if p is not None:
                nn.init.trunc_normal_(p, std=0.02)

    def forward(self, fbank: torch.Tensor, context: torch.Tensor | None = None) -> torch.Tensor:
        """``fbank [B, 1024, 128] -> tokens [B, 2 + 1212, W]`` ([CLS], [DIST], then the patches).

        ``context [B, W]``: optional per-sample vector added to the [CLS] token's input, through which
        every token can attend to it.
        """
        c = self.config
        if fbank.dim() != 3 or fbank.shape[1:] != (c.input_frames, c.input_bins):
            raise ValueError(
                f"expected a filterbank [B, {c.input_frames}, {c.input_bins}], got {tuple(fbank.shape)}"
            )
        x = self.patch_embed(fbank)
        b = x.shape[0]
        prefix = [self.cls_token.expand(b, -1, -1) if context is None else self.cls_token + context[:, None]]
        if self.dist_token is not None:
            prefix.append(self.dist_token.expand(b, -1, -1))
        x = self.pos_drop(torch.cat(prefix + [x], dim=1) + self.pos_embed)
        for block in self.blocks:
            x = block(x)
        return self.norm(x)
