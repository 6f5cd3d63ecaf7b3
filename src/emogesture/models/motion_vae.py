"""Motion prior: a transformer VAE in the style of MLD (docs/design.md, 'Gesture generation model'; paper §3.3,
supp. Fig. A.7).

Encoder P_E: ``motion [B, T, 282]`` -> Linear(282 -> d) -> two learnable distribution tokens (μ, log σ²)
prepended -> skip transformer (learnable positional embedding in every attention layer) -> the first two
output tokens give μ and log σ² (each projected to ``latent_dim`` when ``d != latent_dim``) ->
``z = μ + σ·ε``.

Decoder P_D: T zero queries plus the positional embedding -> skip transformer with cross-attention to the
single memory token ``Linear(z)`` (identity when ``d == latent_dim``) in every layer -> Linear(d -> 282).
With one memory token the cross-attention softmax is identically 1, so each cross-attention adds
``proj(v(z))`` to every frame and its query path (``norm_cross``, ``cross.q``) never receives a gradient
(as in MLD with ``latent_size = 1``). The queries carry the positional embedding both as their input
(values must differ per frame, or attention could not tell frames apart) and inside every attention.

Windows may be shorter than ``frames`` (the maximum; the positional tables are sized to it).

Options beside MLD's design (each off in the ``paper`` preset; measurements behind them:
``experiments/motion_prior/README.md`` and ``experiments/rhythm/README.md``):

* ``low_frequency_path = F > 0`` (tiny): a linear path beside the transformers. The encoder adds
  ``Linear(DCT_F(frame embeddings))`` to μ, where ``DCT_F`` takes the first F DCT-II coefficients over
  time (coefficient 0 is the time mean); the decoder adds ``Σ_f cos_f(t) · Linear(z)_f`` to every frame.
  The transformers then only model what is left: the gesture strokes. The path's output Linear starts
  at zero (random cosines would only add noise).
* ``detail_path = F'`` with ``detail_columns`` (tiny, with the timing stream): the same kind of path for
  a few feature columns only, reading their own features (not the frame embeddings) and writing only
  them, so that those columns get more cosines than the rest (the wrists' turns, which the timing stream
  cannot place). Output Linear at zero, as above.
* ``timing_features = F > 0`` (tiny, for the variants that hear speech): the decoder also reads the
  speech's timing stream (:func:`emogesture.audio.timing.timing_stream`, ``[B, T, F]``), smoothed over
  ``timing_smoothing`` frames: every query token gets ``Linear(the stream of the frames it covers)``
  added, so each frame knows when the speech around it moves without that passing through z. The Linear
  starts at zero (the prior begins as MLD's). :meth:`MotionVAE.decode_pair` decodes with and without the
  stream, for timing guidance at generation (:class:`~emogesture.models.generation.GenerationConfig`).

Tried and not adopted: several frames per token, several latent tokens (``experiments/motion_prior/``), a
smoothing that ends the decoder (``experiments/rhythm/``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import torch
from torch import nn

from emogesture.errors import ConfigError
from emogesture.models.skip_transformer import SkipTransformer, SkipTransformerConfig
from emogesture.motion.features import MotionFeatureSpec
from emogesture.motion.filters import gaussian_smooth
from emogesture.motion.skeleton import WRIST_JOINTS


@dataclass
class MotionVAEConfig:
    """Size of the motion VAE. Defaults are the ``paper`` preset (MLD's VAE: 9 layers, 4 heads, d 256)."""

    RETIRED: ClassVar[dict] = {"frames_per_token": 1, "latent_tokens": 1, "decoder_smoothing": 0.0}

    feature_dim: int = 282
    frames: int = 300
    latent_dim: int = 256
    width: int = 256
    layers: int = 9
    heads: int = 4
    ff_dim: int = 1024
    dropout: float = 0.1
    low_frequency_path: int = 0
    #: A second linear cosine path, for some feature columns only (not in MLD; 0 = off): the encoder adds
    #: ``Linear(DCT_F(the columns' own features))`` to μ, the decoder adds ``Σ_f cos_f(t) · Linear(z)_f``
    #: to those columns, with F = ``detail_path`` cosines. Meant for motion the timing stream cannot
    #: place (a wrist turning in each stroke's own direction) while the other columns keep a short path.
    detail_path: int = 0
    detail_columns: tuple[int, ...] = ()
    timing_features: int = 0
    #: σ, in frames, of a Gaussian smoothing of the timing stream before the decoder reads it (0 = none):
    #: the fbank's frame-to-frame onset strength is jittery, and read raw it comes out as jitter.
    timing_smoothing: float = 0.0

    def __post_init__(self) -> None:
        if min(self.feature_dim, self.frames, self.latent_dim) < 1:
            raise ConfigError("motion VAE: feature_dim, frames and latent_dim must be positive")
        if not 0 <= self.low_frequency_path <= self.frames:
            raise ConfigError(f"motion VAE: low_frequency_path must be in 0..{self.frames}, "
                              f"got {self.low_frequency_path}")
        if self.detail_path:
            cols = self.detail_columns
            if not cols or len(set(cols)) != len(cols) or min(cols) < 0 or max(cols) >= self.feature_dim:
                raise ConfigError(f"motion VAE: detail_columns must be distinct feature columns in "
                                  f"0..{self.feature_dim - 1}, got {list(cols)}")
            if not 0 < self.detail_path <= self.frames:
                raise ConfigError(f"motion VAE: detail_path must be in 0..{self.frames}, got {self.detail_path}")
        if min(self.timing_features, self.timing_smoothing) < 0:
            raise ConfigError(f"motion VAE: timing_features and timing_smoothing must be ≥ 0, "
                              f"got {self.timing_features}, {self.timing_smoothing}")
        self.transformer(cross_attention=False)  # validates width/heads/layers/dropout

    def transformer(self, cross_attention: bool) -> SkipTransformerConfig:
        return SkipTransformerConfig(self.width, self.layers, self.heads, self.ff_dim, self.dropout, cross_attention)

    @classmethod
    def preset(cls, name: str, feature_dim: int = 282, frames: int = 300, timing: bool = False) -> "MotionVAEConfig":
        """``paper``: width 256, 9 layers, 4 heads, ff 1024, dropout 0.1 (≈17.9 M parameters).

        ``tiny``: width 64, 3 layers (1 + 1 + 1), 4 heads, ff 256, no dropout (attention then runs in
        torch's fused CPU kernel), and a low-frequency path of 48 cosines (2.4 Hz over a 10-s window, so
        the path also carries the strokes; ≈4.76 M parameters, 4.27 M of them in the path's Linears).

        ``tiny`` with ``timing=True`` (the gesture model's, for the variants that hear speech): 16 cosines
        only (0.75 Hz over 10 s), so the latent carries posture and slow motion and the decoder places the
        strokes from the speech's timing stream (2 numbers a frame, smoothed over 2 frames); the wrists'
        12 feature columns (in the default 282-number layout) get a path of their own of 24 cosines
        (1.15 Hz), for the direction each stroke turns a wrist, which the stream cannot say. The reasons
        and measurements: ``experiments/motion_prior/README.md``.
        """
        if name == "paper":
            return cls(feature_dim=feature_dim, frames=frames)
        if name == "tiny":
            spec = MotionFeatureSpec()  # the wrists' columns, in the default feature layout
            wrists = tuple(spec.columns(WRIST_JOINTS)) if feature_dim == spec.dim else ()
            hears = dict(timing_features=2, timing_smoothing=2.0,
                         detail_path=min(24, frames) if wrists else 0, detail_columns=wrists)
            return cls(feature_dim=feature_dim, frames=frames, width=64, layers=3, heads=4, ff_dim=256, dropout=0.0,
                       low_frequency_path=min(16 if timing else 48, frames), **(hears if timing else {}))
        raise ConfigError(f"unknown motion VAE preset {name!r}; known: paper, tiny")


def kl_loss(mu: torch.Tensor, logvar: torch.Tensor) -> torch.Tensor:
    """KL(N(μ, σ²) ‖ N(0, I)) summed over latent dimensions, averaged over the batch: ``[B, Z] -> []``.

    ``½ Σ (μ² + σ² − log σ² − 1)``, the paper's L_KL (its weight, 1e-4, is a training setting).
    """
    return 0.5 * (mu.pow(2) + logvar.exp() - logvar - 1.0).sum(dim=-1).mean()


def dct_basis(n: int, count: int) -> torch.Tensor:
    """The first ``count`` DCT-II cosines over ``n`` samples, unnormalised: ``[n, count]``, column f is
    ``cos(π f (j + ½) / n)``.

    :func:`emogesture.audio.mfcc.dct_matrix` is the same basis scaled to be orthonormal, but computed in
    float64 with another operation order: rescaled, it differs from this one in the last float32 bits (up
    to about 1e-5 at 300 frames). Models are trained and generate with these exact values, so each keeps
    its own."""
    j = torch.arange(n, dtype=torch.float32, device="cpu")[:, None] + 0.5  # on the CPU even while a model
    return torch.cos(torch.pi * j * torch.arange(count, device="cpu") / n)  # is built on the meta device


class MotionVAE(nn.Module):
    """Transformer VAE over motion-feature windows; see the module docstring."""

    def __init__(self, config: MotionVAEConfig) -> None:
        super().__init__()
        config.__post_init__()  # fields may have been changed after construction
        self.config = config
        c = config
        d = c.width
        # Encoder P_E.
        tokens, part = c.frames, c.latent_dim
        self.encoder_input = nn.Linear(c.feature_dim, d)
        self.dist_tokens = nn.Parameter(torch.zeros(1, 2, d))  # [μ token, log σ² token]
        self.encoder_pos = nn.Parameter(torch.zeros(1, 2 + tokens, d))
        self.encoder = SkipTransformer(c.transformer(cross_attention=False))
        self.to_mu = nn.Linear(d, part) if d != part else nn.Identity()
        self.to_logvar = nn.Linear(d, part) if d != part else nn.Identity()
        # Decoder P_D.
        self.decoder_pos = nn.Parameter(torch.zeros(1, tokens, d))
        self.latent_to_memory = nn.Linear(part, d) if d != part else nn.Identity()
        # Low-frequency path (not in MLD, off in the paper preset); see the module docstring.
        f = c.low_frequency_path
        if f:
            self.register_buffer("dct_basis", dct_basis(tokens, f), persistent=False)
            self.low_frequency_mu = nn.Linear(f * d, c.latent_dim)
            self.low_frequency_out = nn.Linear(c.latent_dim, f * c.feature_dim)
            nn.init.zeros_(self.low_frequency_out.weight)  # starts as a no-op: random cosines would only add noise
            nn.init.zeros_(self.low_frequency_out.bias)
        else:
            self.dct_basis = self.low_frequency_mu = self.low_frequency_out = None
        if c.detail_path:  # the detail path
            self.register_buffer("detail_basis", dct_basis(c.frames, c.detail_path), persistent=False)
            self.register_buffer("detail_index", torch.tensor(c.detail_columns, dtype=torch.long, device="cpu"),
                                 persistent=False)
            self.detail_mu = nn.Linear(c.detail_path * len(c.detail_columns), c.latent_dim)
            self.detail_out = nn.Linear(c.latent_dim, c.detail_path * len(c.detail_columns))
            nn.init.zeros_(self.detail_out.weight)
            nn.init.zeros_(self.detail_out.bias)
        else:
            self.detail_basis = self.detail_index = self.detail_mu = self.detail_out = None
        if c.timing_features:  # the speech's timing stream added to the queries
            self.timing_to_query = nn.Linear(c.timing_features, d)
            nn.init.zeros_(self.timing_to_query.weight)
            nn.init.zeros_(self.timing_to_query.bias)
        else:
            self.timing_to_query = None
        self.decoder = SkipTransformer(c.transformer(cross_attention=True))
        self.decoder_output = nn.Linear(d, c.feature_dim)
        for p in (self.dist_tokens, self.encoder_pos, self.decoder_pos):
            nn.init.trunc_normal_(p, std=0.02)

    def _check_motion(self, motion: torch.Tensor) -> None:
        c = self.config
        if motion.dim() != 3 or motion.shape[-1] != c.feature_dim or not 1 <= motion.shape[1] <= c.frames:
            raise ValueError(f"motion VAE expects [B, T<={c.frames}, {c.feature_dim}], got {tuple(motion.shape)}")

    def encode(
        self, motion: torch.Tensor, generator: torch.Generator | None = None, sample: bool = True
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Args: normalised features ``motion [B, T, 282]`` (``T <= frames``); ``generator`` for ε
        (required when ``sample`` and the result must be reproducible); ``sample=False`` returns ``z = μ``.

        Returns: ``z [B, 256]``, ``mu [B, 256]``, ``logvar [B, 256]``.
        """
        self._check_motion(motion)
        b, n, _ = motion.shape  # a token per frame
        frames = self.encoder_input(motion)
        x = torch.cat([self.dist_tokens.expand(b, -1, -1), frames], dim=1)
        y = self.encoder(x, self.encoder_pos[:, : n + 2])
        mu, logvar = self.to_mu(y[:, :1]).reshape(b, -1), self.to_logvar(y[:, 1:2]).reshape(b, -1)
        if self.low_frequency_mu is not None:  # DCT-II coefficients of the frame embeddings over time
            coefficients = torch.einsum("nf,bnd->bfd", self.dct_basis[:n], frames) / n
            mu = mu + self.low_frequency_mu(coefficients.reshape(b, -1))
        if self.detail_mu is not None:  # DCT-II coefficients of the detail columns over time
            detail = motion[:, :, self.detail_index]
            coefficients = torch.einsum("tf,btc->bfc", self.detail_basis[:n], detail) / n
            mu = mu + self.detail_mu(coefficients.reshape(b, -1))
        if not sample:
            return mu, mu, logvar
        # drawn on the generator's own device, then moved: a CPU generator cannot draw on a GPU, and the
        # noise does not depend on where the model runs
        eps = torch.randn(mu.shape, generator=generator, dtype=mu.dtype,
                          device=mu.device if generator is None else generator.device).to(mu.device)
        return mu + torch.exp(0.5 * logvar) * eps, mu, logvar

    def decode(self, z: torch.Tensor, frames: int | None = None, timing: torch.Tensor | None = None) -> torch.Tensor:
        """``z [B, 256] -> motion [B, T, 282]`` with ``T = frames`` (default: the configured maximum);
        ``timing [B, T', timing_features]`` (``T' >= T``), required when ``timing_features > 0``."""
        return self._decode(z, frames, timing)

    def decode_pair(self, z: torch.Tensor, frames: int | None = None, timing: torch.Tensor | None = None,
                    keep: tuple[int, ...] = ()) -> tuple[torch.Tensor, torch.Tensor]:
        """The decoding with the timing stream ``[B, T, F]`` and with a zero stream (what a silent window
        gives) but for its columns ``keep``, run as one batch: ``(heard [B, T, 282], deaf [B, T, 282])``.
        Timing guidance (``timing_guidance``) extrapolates from ``deaf`` through ``heard``; the pipeline
        does it in raw feature units, where the 6D columns live (:func:`emogesture.motion.guide_features`).
        """
        if timing is None:
            raise ValueError("decode_pair needs the timing stream")
        if any(not 0 <= k < timing.shape[-1] for k in keep):
            raise ValueError(f"decode_pair: keep {list(keep)} names columns beyond the stream's {timing.shape[-1]}")
        deaf = torch.zeros_like(timing)
        deaf[..., list(keep)] = timing[..., list(keep)]
        both = self._decode(torch.cat([z, z]), frames, torch.cat([timing, deaf]))
        return both[: len(z)], both[len(z):]

    def _decode(self, z: torch.Tensor, frames: int | None, timing: torch.Tensor | None) -> torch.Tensor:
        c = self.config
        t = c.frames if frames is None else int(frames)
        if not 1 <= t <= c.frames:
            raise ValueError(f"motion VAE decodes 1..{c.frames} frames, asked for {t}")
        if z.dim() != 2 or z.shape[-1] != c.latent_dim:
            raise ValueError(f"motion VAE expects z [B, {c.latent_dim}], got {tuple(z.shape)}")
        memory = self.latent_to_memory(z.reshape(z.shape[0], 1, -1))  # [B, 1, d]
        n = t  # a token per frame
        pos = self.decoder_pos[:, :n]
        queries = torch.zeros(z.shape[0], n, c.width, device=z.device, dtype=z.dtype) + pos
        if self.timing_to_query is not None:
            queries = queries + self.timing_to_query(self._timing_tokens(timing, z.shape[0], n))
        out = self.decoder_output(self.decoder(queries, pos, memory))  # [B, T, D]
        if self.low_frequency_out is not None:  # the same cosines, weighted by a Linear of z
            coefficients = self.low_frequency_out(z).reshape(z.shape[0], c.low_frequency_path, -1)
            out = out + torch.einsum("nf,bfe->bne", self.dct_basis[:n], coefficients)
        if self.detail_out is not None:
            coefficients = self.detail_out(z).reshape(z.shape[0], c.detail_path, -1)
            detail = torch.einsum("tf,bfc->btc", self.detail_basis[:t], coefficients)
            out = out.index_add(2, self.detail_index, detail)
        return out

    def _timing_tokens(self, timing: torch.Tensor | None, b: int, n: int) -> torch.Tensor:
        """The timing stream ``[B, >= n, F]`` of the ``n`` query tokens (frames): ``[B, n, F]``, smoothed."""
        c = self.config
        if timing is None or timing.dim() != 3 or timing.shape[0] != b or timing.shape[2] != c.timing_features \
                or timing.shape[1] < n:
            got = None if timing is None else tuple(timing.shape)
            raise ValueError(f"this motion decoder reads a timing stream [B={b}, >={n}, {c.timing_features}], got {got}")
        timing = timing[:, :n]
        if c.timing_smoothing > 0:
            timing = gaussian_smooth(timing, c.timing_smoothing)
        return timing

    def forward(
        self, motion: torch.Tensor, generator: torch.Generator | None = None, sample: bool = True,
        timing: torch.Tensor | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """``motion [B, T, 282]`` (and the timing stream ``[B, T, F]`` when the decoder reads one) ->
        ``reconstruction [B, T, 282]``, ``z``, ``mu``, ``logvar`` ``[B, 256]``."""
        z, mu, logvar = self.encode(motion, generator=generator, sample=sample)
        return self.decode(z, frames=motion.shape[1], timing=timing), z, mu, logvar

    @staticmethod
    def kl_loss(mu: torch.Tensor, logvar: torch.Tensor) -> torch.Tensor:
        """See :func:`kl_loss`."""
        return kl_loss(mu, logvar)
