"""Speech disentanglement model (docs/design.md, 'Speech disentanglement model'; paper supp. B): three ViT
encoders, a fusion, a filterbank decoder.

``fbank [B, 1024, 128]`` -> content, emotion, style latents ``[B, 256]`` each (plus emotion and speaker
logits) -> fusion of the three latents into one embedding -> decoder back to ``[B, 1024, 128]``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import torch
from torch import nn

from emogesture.errors import ConfigError
from emogesture.models.vit import LN_EPS, AudioViT, Block, CrossBlock, ViTConfig, init_transformer_weights

COMPONENTS = ("content_encoder", "emotion_encoder", "style_encoder", "fusion", "decoder")


@dataclass
class SpeechModelConfig:
    """Size of the speech disentanglement model. Defaults are the ``paper`` preset with 30 speakers.

    The decoder uses ``input_frames / decoder_time_stride`` learned time queries (128 for the paper
    preset), each cross-attending ``decoder_memory_tokens`` tokens made from the fused embedding and
    mapped by one Linear to ``decoder_time_stride`` frames × 128 bins.
    """

    encoder: ViTConfig = field(default_factory=ViTConfig)
    latent_dim: int = 256
    num_emotions: int = 8
    num_speakers: int = 30
    fusion_layers: int = 2
    fusion_heads: int = 4
    fusion_width: int = 768
    decoder_layers: int = 4
    decoder_heads: int = 4
    decoder_width: int = 512
    decoder_time_stride: int = 8
    decoder_memory_tokens: int = 8
    dropout: float = 0.1
    #: An extension (paper: off): the emotion encoder also reads the window's style latent (detached,
    #: LayerNorm + Linear, zero at initialisation, added to its [CLS] input), so it can judge emotion
    #: relative to the speaker's own voice.
    emotion_speaker_context: bool = False
    #: An extension (paper: 0, every bin): the encoders hear only the lowest ``heard_bins`` filterbank bins,
    #: the others held at the dataset mean (0 in the normalised domain). A recording's top octave says much
    #: about the microphone, the codec and the synthesiser and little about emotion: with the default 128
    #: HTK-mel bins from 20 Hz to 8 kHz, 96 hears up to 4 kHz, as a low-pass at 4 kHz would leave them.
    #: Not an architecture change: a trained model can be trained on with another value (``--init-from``).
    heard_bins: int = 0

    def __post_init__(self) -> None:
        if self.fusion_width % self.fusion_heads or self.decoder_width % self.decoder_heads:
            raise ConfigError("speech model: fusion/decoder width must be divisible by its heads")
        if self.encoder.input_frames % self.decoder_time_stride:
            raise ConfigError(
                f"speech model: decoder_time_stride {self.decoder_time_stride} does not divide "
                f"{self.encoder.input_frames} frames"
            )
        if not 0 <= self.heard_bins <= self.encoder.input_bins:
            raise ConfigError(f"speech model: heard_bins {self.heard_bins} must be 0 (all) to "
                              f"{self.encoder.input_bins}")
        if min(self.num_emotions, self.num_speakers, self.latent_dim, self.decoder_memory_tokens) < 1:
            raise ConfigError("speech model: num_emotions, num_speakers, latent_dim and memory tokens must be ≥ 1")

    @classmethod
    def preset(cls, name: str, num_speakers: int = 30) -> "SpeechModelConfig":
        """``paper``: three DeiT-B/16-384 encoders (≈86 M each), fusion width 768 (supp. B.5).

        ``tiny``: width-64 encoders on whole-spectrum 128×8 patches, small fusion and decoder, for CPU training: a
        step of 16 quadruples (64 windows, 256 decodes) takes about 0.7–1 s on two CPU cores.
        """
        if name == "paper":
            return cls(encoder=ViTConfig.preset("paper"), num_speakers=num_speakers)
        if name == "tiny":
            return cls(
                encoder=ViTConfig.preset("tiny"), num_speakers=num_speakers, fusion_width=64,
                fusion_layers=2, fusion_heads=4, decoder_width=32, decoder_layers=2, decoder_heads=4,
                decoder_time_stride=32, decoder_memory_tokens=4, dropout=0.0,
            )
        raise ConfigError(f"unknown speech model preset {name!r}; known: paper, tiny")


class AudioLatents(NamedTuple):
    """The three disentangled latents, each ``[B, latent_dim]``."""

    content: torch.Tensor
    emotion: torch.Tensor
    style: torch.Tensor


#: The three speech latents, in the order of :class:`SpeechEncoding`.
LATENT_PARTS = ("content", "emotion", "style")


class SpeechEncoding(NamedTuple):
    """Output of :meth:`SpeechDisentangler.encode`: latents ``[B, 256]`` and logits ``[B, 8]``/``[B, n]``."""

    content: torch.Tensor
    emotion: torch.Tensor
    style: torch.Tensor
    emotion_logits: torch.Tensor
    speaker_logits: torch.Tensor

    @property
    def latents(self) -> AudioLatents:
        return AudioLatents(self.content, self.emotion, self.style)


class SpeechOutput(NamedTuple):
    """Output of :meth:`SpeechDisentangler.forward`: the encoding plus ``reconstruction [B, 1024, 128]``."""

    content: torch.Tensor
    emotion: torch.Tensor
    style: torch.Tensor
    emotion_logits: torch.Tensor
    speaker_logits: torch.Tensor
    reconstruction: torch.Tensor


class SpeechEncoder(nn.Module):
    """One ViT, a latent head (LayerNorm + Linear on the mean patch token), an optional classifier."""

    def __init__(self, vit: ViTConfig, latent_dim: int, num_classes: int | None = None) -> None:
        super().__init__()
        self.vit = AudioViT(vit)
        self.latent_head = nn.Sequential(nn.LayerNorm(vit.width, eps=LN_EPS), nn.Linear(vit.width, latent_dim))
        self.classifier = nn.Linear(vit.width, num_classes) if num_classes else None
        self.latent_head.apply(init_transformer_weights)
        if self.classifier is not None:
            init_transformer_weights(self.classifier)

    def forward(self, fbank: torch.Tensor, context: torch.Tensor | None = None
                ) -> tuple[torch.Tensor, torch.Tensor | None]:
        """``fbank [B, 1024, 128] -> (latent [B, 256], logits [B, classes] or None)``.

        The logits come from the mean of the [CLS] and [DIST] outputs (only [CLS] if not distilled).
        ``context [B, W]``: see :meth:`AudioViT.forward`.
        """
        tokens = self.vit(fbank, context)
        k = self.vit.config.num_prefix
        latent = self.latent_head(tokens[:, k:].mean(dim=1))
        logits = self.classifier(tokens[:, :k].mean(dim=1)) if self.classifier is not None else None
        return latent, logits


class LatentFusion(nn.Module):
    """Three latents as three tokens (own projection + learned type embedding each) -> one embedding."""

    def __init__(self, config: SpeechModelConfig) -> None:
        super().__init__()
        w = config.fusion_width
        self.in_proj = nn.ModuleList(nn.Linear(config.latent_dim, w) for _ in range(3))
        self.type_embed = nn.Parameter(torch.zeros(1, 3, w))
        self.blocks = nn.ModuleList(
            Block(w, config.fusion_heads, 4.0, config.dropout) for _ in range(config.fusion_layers)
        )
        self.norm = nn.LayerNorm(w, eps=LN_EPS)
        self.apply(init_transformer_weights)
        nn.init.trunc_normal_(self.type_embed, std=0.02)

    def forward(self, content: torch.Tensor, emotion: torch.Tensor, style: torch.Tensor) -> torch.Tensor:
        """Three ``[B, 256]`` -> fused ``[B, fusion_width]``; attention runs over the 3 tokens of a sample."""
        x = torch.stack([p(v) for p, v in zip(self.in_proj, (content, emotion, style))], dim=1)
        x = x + self.type_embed
        for block in self.blocks:
            x = block(x)
        return self.norm(x).mean(dim=1)


class FilterbankDecoder(nn.Module):
    """Learned time queries cross-attending memory tokens made from the fused embedding."""

    def __init__(self, config: SpeechModelConfig) -> None:
        super().__init__()
        w = config.decoder_width
        self.frames = config.encoder.input_frames
        self.bins = config.encoder.input_bins
        self.stride = config.decoder_time_stride
        self.memory_tokens = config.decoder_memory_tokens
        self.memory_proj = nn.Linear(config.fusion_width, self.memory_tokens * w)
        self.queries = nn.Parameter(torch.zeros(1, self.frames // self.stride, w))
        self.blocks = nn.ModuleList(
            CrossBlock(w, config.decoder_heads, 4.0, config.dropout) for _ in range(config.decoder_layers)
        )
        self.norm = nn.LayerNorm(w, eps=LN_EPS)
        self.out = nn.Linear(w, self.stride * self.bins)
        self.apply(init_transformer_weights)
        nn.init.trunc_normal_(self.queries, std=0.02)

    def forward(self, fused: torch.Tensor) -> torch.Tensor:
        """``fused [B, fusion_width] -> filterbank [B, 1024, 128]``."""
        b = fused.shape[0]
        memory = self.memory_proj(fused).reshape(b, self.memory_tokens, -1)
        x = self.queries.expand(b, -1, -1)
        for block in self.blocks:
            x = block(x, memory)
        y = self.out(self.norm(x))  # [B, frames / stride, stride * bins]
        return y.reshape(b, self.frames, self.bins)


class SpeechDisentangler(nn.Module):
    """E_c, E_e, E_s + fusion + decoder (docs/design.md, 'Speech disentanglement model')."""

    def __init__(self, config: SpeechModelConfig) -> None:
        super().__init__()
        self.config = config
        self.content_encoder = SpeechEncoder(config.encoder, config.latent_dim, None)
        self.emotion_encoder = SpeechEncoder(config.encoder, config.latent_dim, config.num_emotions)
        self.style_encoder = SpeechEncoder(config.encoder, config.latent_dim, config.num_speakers)
        self.fusion = LatentFusion(config)
        self.decoder = FilterbankDecoder(config)
        # Linear heads of two extensions (trained only when their loss terms are on, see speech_losses):
        # adversaries reading the other factor, and classifiers reading each latent's own factor.
        self.speaker_adversary = nn.Linear(config.latent_dim, config.num_speakers)
        self.emotion_adversary = nn.Linear(config.latent_dim, config.num_emotions)
        self.emotion_from_latent = nn.Linear(config.latent_dim, config.num_emotions)
        self.speaker_from_latent = nn.Linear(config.latent_dim, config.num_speakers)
        self.emotion_context = None
        if config.emotion_speaker_context:
            self.emotion_context = nn.Sequential(nn.LayerNorm(config.latent_dim, eps=LN_EPS),
                                                 nn.Linear(config.latent_dim, config.encoder.width))
            nn.init.zeros_(self.emotion_context[1].weight)
            nn.init.zeros_(self.emotion_context[1].bias)

    def encode(self, fbank: torch.Tensor, emotion_fbank: torch.Tensor | None = None,
               parts: tuple[str, ...] = LATENT_PARTS) -> SpeechEncoding:
        """``fbank [B, 1024, 128]`` -> content, emotion, style ``[B, 256]``, logits ``[B, 8]``, ``[B, n]``.

        ``emotion_fbank [B, 1024, 128]``: another input for the emotion encoder alone (training-time
        augmentation); default ``fbank``. ``parts``: the latents wanted (a subset of ``content``,
        ``emotion``, ``style``); an encoder nobody needs is not run and its outputs are ``[B, 0]``
        (the style encoder also runs for ``emotion`` when the emotion encoder reads the speaker context).
        """
        unknown = set(parts) - set(LATENT_PARTS)
        if unknown:
            raise ValueError(f"unknown latent parts {sorted(unknown)}; known: {', '.join(LATENT_PARTS)}")
        fbank = self.heard(fbank)
        emotion_fbank = None if emotion_fbank is None else self.heard(emotion_fbank)
        empty = fbank.new_zeros(fbank.shape[0], 0)
        content = self.content_encoder(fbank)[0] if "content" in parts else empty
        style = speaker_logits = emotion = emotion_logits = empty
        if "style" in parts or ("emotion" in parts and self.emotion_context is not None):
            style, speaker_logits = self.style_encoder(fbank)
        if "emotion" in parts:
            context = None if self.emotion_context is None else self.emotion_context(style.detach())
            emotion, emotion_logits = self.emotion_encoder(fbank if emotion_fbank is None else emotion_fbank, context)
        return SpeechEncoding(content, emotion, style, emotion_logits, speaker_logits)

    def heard(self, fbank: torch.Tensor) -> torch.Tensor:
        """``fbank [B, T, bins]`` as the encoders hear it: the bins from ``config.heard_bins`` on set to 0 (the
        dataset mean); unchanged when every bin is heard."""
        k = self.config.heard_bins
        if k == 0 or k >= fbank.shape[-1]:
            return fbank
        return torch.cat([fbank[..., :k], fbank.new_zeros(*fbank.shape[:-1], fbank.shape[-1] - k)], dim=-1)

    def decode(self, content: torch.Tensor, emotion: torch.Tensor, style: torch.Tensor) -> torch.Tensor:
        """Latents ``[B, 256]`` ×3 -> reconstructed filterbank ``[B, 1024, 128]``."""
        return self.decoder(self.fusion(content, emotion, style))

    def forward(self, fbank: torch.Tensor) -> SpeechOutput:
        """``fbank [B, 1024, 128]`` -> encoding + self-reconstruction ``[B, 1024, 128]``."""
        enc = self.encode(fbank)
        return SpeechOutput(*enc, self.decode(enc.content, enc.emotion, enc.style))

    def count_parameters(self) -> dict[str, int]:
        """Parameter count per component (``content_encoder`` ... ``decoder``, the four linear
        ``latent_heads`` of the extension losses) and ``total``."""
        counts = {name: sum(p.numel() for p in getattr(self, name).parameters()) for name in COMPONENTS}
        heads = (self.speaker_adversary, self.emotion_adversary, self.emotion_from_latent, self.speaker_from_latent)
        counts["latent_heads"] = sum(p.numel() for m in heads for p in m.parameters())
        counts["total"] = sum(p.numel() for p in self.parameters())
        return counts

    def flops_per_window(self) -> dict[str, int]:
        """FLOPs of encoding and self-reconstructing one ``[1, 1024, 128]`` window, per component."""
        return flops_per_window(self.config)


def flops_per_window(config: SpeechModelConfig) -> dict[str, int]:
    """FLOPs (multiply-add = 2) of one window through encode + decode, counted on the meta device.

    Counts matmuls, convolutions and attention (torch's ``FlopCounterMode``); norms and activations
    are not counted. Uses a weightless copy of the model, so it is instant even for the paper preset.
    """
    from torch.utils.flop_counter import FlopCounterMode

    with torch.device("meta"):
        model = SpeechDisentangler(config).eval()
        x = torch.zeros(1, config.encoder.input_frames, config.encoder.input_bins)
    with FlopCounterMode(display=False) as counter:
        model(x)
    per_module = counter.get_flop_counts()
    out = {}
    for name in COMPONENTS:
        counts = per_module.get(f"{type(model).__name__}.{name}", {})
        out[name] = int(sum(counts.values()))
    out["total"] = int(counter.get_total_flops())
    return out
