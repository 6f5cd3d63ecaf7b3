"""The CPU kernels the models call: attention, dropout masks and the fused product with its GELU.

The model files hold the networks; how a product or an attention runs fastest on the machine at hand (a
blocked bf16 attention, cheaper dropout masks, oneDNN's fused product of :mod:`emogesture.runtime`) is here,
each with the measurements that chose it (bench/results/cpu.md).
"""

from __future__ import annotations

import sys

import torch
import torch.nn.functional as F
from torch import nn

from emogesture.runtime import acceleration_enabled, amx_bf16, linear_gelu

__all__ = ["attention", "Dropout", "linear_gelu", "ATTENTION_BLOCK_SCORES", "ATTENTION_QUERY_BLOCK",
           "BLOCKED_ATTENTION_MIN_TOKENS", "FLOAT32_TRAINING_ATTENTION"]

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
