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

import sys
from dataclasses import dataclass

import torch
import torch.nn.functional as F
from torch import nn

from emogesture.errors import ConfigError
from emogesture.runtime import acceleration_enabled, amx_bf16, linear_gelu

LN_EPS = 1e-6
#: :func:`attention`'s blocked path computes at most about this many scores at a time (12 heads x 128
#: queries x 1214 keys in bf16: they stay within a core's cache), from this many tokens on.
ATTENTION_BLOCK_SCORES = 12 * 128 * 1214
ATTENTION_QUERY_BLOCK = 128
BLOCKED_ATTENTION_MIN_TOKENS = 256
#: Under autograd on a CPU, bf16 attention runs in float32 for fewer queries or narrower heads than
#: these (queries, head width): torch's bf16 backward is the slower one there. Measured on
#: self-attention (the paper decoder's cross-attention of few queries over many keys goes to float32
#: too), forward and backward, bf16 against float32, on a 2-core Xeon with AMX: 130 tokens x 32 wide
#: 104 / 31 ms (the tiny speech encoders: their bf16 training ran at 28 windows/s against 94 in
#: float32, 90 with this), 300 x 16 41 / 18 (the tiny gesture model's), 300 x 32 42 / 27, 130 x 64
#: 171 / 93; but 300 x 64 47 / 50, 600 x 64 134 / 132, 1214 x 64 169 / 240 (the paper encoders',
#: whose training stays bf16).
FLOAT32_TRAINING_ATTENTION = (256, 64)


def attention(q: torch.Tensor, k: torch.Tensor, v: torch.Tensor, dropout_p: float = 0.0) -> torch.Tensor:
    """Scaled dot-product attention ``q [B, H, N, E]``, ``k, v [B, H, M, E] -> [B, H, N, E]``.

    On a CPU in bf16 without gradients and for sequences of :data:`BLOCKED_ATTENTION_MIN_TOKENS` or more,
    blocks of about :data:`ATTENTION_BLOCK_SCORES` scores go through two bf16 batched matrix products
    and a softmax: several whole samples at a time where a sample's scores are fewer (the tiny motion
    decoder's 4 heads x 300 x 300), else one sample's heads for :data:`ATTENTION_QUERY_BLOCK` queries
    at a time (the paper encoders' 1214 tokens). On a 2-core AVX-512-bf16 CPU this ran at about 180
    GFLOP/s against 130 for torch's fused CPU kernel in the paper encoders, and 9.5 against 11.6 ms
    for the tiny decoder's 32 x 4 x 300 tokens (bench/results/cpu.md). The probabilities are rounded to
    bf16 before the second product, as in any bf16 product of them. On a CPU with AMX tiles
    (:func:`~emogesture.runtime.amx_bf16`) torch's fused kernel is the faster one (3 paper-encoder
    windows: 21 against 43 ms a layer; the tiny decoder's: 5.3 against 8 ms), and everything else
    goes to :func:`torch.nn.functional.scaled_dot_product_attention` too. Under autograd, CPU bf16
    inputs of shapes below :data:`FLOAT32_TRAINING_ATTENTION` are attended in float32 (the result is
    returned in bf16), larger ones by torch's bf16 kernel. With the speed-ups switched off
    (:func:`~emogesture.runtime.acceleration_enabled`), always torch's kernel.
    """
    cpu_bf16 = q.device.type == "cpu" and q.dtype == torch.bfloat16
    training = torch.is_grad_enabled() and (q.requires_grad or k.requires_grad or v.requires_grad)
    if cpu_bf16 and training \
            and (q.shape[-2] < FLOAT32_TRAINING_ATTENTION[0] or q.shape[-1] < FLOAT32_TRAINING_ATTENTION[1]):
        with torch.autocast("cpu", enabled=False):
            return F.scaled_dot_product_attention(q.float(), k.float(), v.float(), dropout_p=dropout_p).to(q.dtype)
    blocked = (cpu_bf16 and not training and dropout_p == 0.0 and q.shape[-2] >= BLOCKED_ATTENTION_MIN_TOKENS
               and not amx_bf16() and acceleration_enabled())
    if not blocked:
        return F.scaled_dot_product_attention(q, k, v, dropout_p=dropout_p)
    *batch, n, e = q.shape
    q, k, v = (x.reshape(-1, *x.shape[-3:]) for x in (q, k, v))  # [B, H, N, E]; a view when 4-D already
    b, h, m = q.shape[0], q.shape[1], k.shape[-2]
    # keys and values are made contiguous once per block (a strided operand would be copied by every
    # product), and the output is written in [B, N, H, E] order, so the caller's
    # transpose(1, 2).reshape(B, N, H·E) before the output projection is a view, not a copy
    out = q.new_empty(b, n, h, e).transpose(1, 2)
    scale = e ** -0.5
    samples = ATTENTION_BLOCK_SCORES // (h * n * m)
    if samples >= 1:  # whole samples
        for i in range(0, b, samples):
            block = slice(i, i + samples)
            scores = torch.matmul((q[block] * scale).contiguous(), k[block].transpose(-1, -2).contiguous())
            out[block] = torch.matmul(torch.softmax(scores, -1), v[block].contiguous())
        return out.reshape(*batch, n, e)
    heads = max(1, ATTENTION_BLOCK_SCORES // (ATTENTION_QUERY_BLOCK * m))
    for s in range(b):  # one sample at a time, blocks of heads and queries
        kt, vs = k[s].transpose(-1, -2).contiguous(), v[s].contiguous()
        for hb in range(0, h, heads):
            hs = slice(hb, hb + heads)
            for i in range(0, n, ATTENTION_QUERY_BLOCK):
                queries = slice(i, i + ATTENTION_QUERY_BLOCK)
                scores = torch.bmm((q[s, hs, queries] * scale).contiguous(), kt[hs])
                out[s, hs, queries] = torch.bmm(torch.softmax(scores, -1), vs[hs])
    return out.reshape(*batch, n, e)  # a view: same shape


class Dropout(nn.Dropout):
    """:class:`torch.nn.Dropout` whose CPU masks are cut from 64-bit random words, three 16-bit draws each.

    torch's CPU dropout draws one random number per element through ``bernoulli_``, and in the tiny
    gesture model's training (the denoiser's dropout, also inside the alignment's sampling) the masks
    cost about as much as the matrix products they follow; these take about half as long. An element is
    kept with probability ``1 − q``, ``q = round(p · 2¹⁶) / 2¹⁶`` (``p`` to 1e-5), and scaled by
    ``1 / (1 − q)``, so the expectation is kept exactly. Draws come from torch's default generator, as
    ``nn.Dropout``'s do; other devices, ``inplace`` and ``p ≥ 1`` use ``nn.Dropout`` itself.
    """

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if not self.training or self.p == 0.0:
            return x
        if x.device.type != "cpu" or self.inplace or self.p >= 1.0 or sys.byteorder != "little":
            return super().forward(x)
        drop = round(self.p * 65536)
        n = x.numel()
        words = torch.empty((n + 2) // 3, dtype=torch.int64).random_()  # 63 random bits: [0, 2^63)
        draws = words.view(torch.int16).view(-1, 4)[:, :3].reshape(-1)[:n].view(x.shape)  # 16 random bits each
        return x * (draws >= drop - 32768).to(x.dtype).mul_(65536 / (65536 - drop))


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
        where :func:`emogesture.runtime.linear_gelu` can (bf16 on a CPU), else in place on its output:
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
