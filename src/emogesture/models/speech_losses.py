"""Quadruple losses of the speech disentanglement model (docs/design.md, 'Speech disentanglement model';
paper supp. B.4).

A training sample is a quadruple ``(a1, a2, a3, a4) = (c1 s1, c2 s1, c1 s2, c2 s2)``: one emotion, two
texts (contents) c1, c2 and two speakers s1, s2. Indices below are 0-based: window ``k`` of a quadruple.

Terms (paper notation -> key here), each a mean absolute error or a mean cross-entropy:

- L_self  -> ``self_recon``:    D(c_k, e_k, s_k) vs a_k
- L_con   -> ``content``:       |E_c(a1) - E_c(a3)| + |E_c(a2) - E_c(a4)|
- L_emo   -> ``emotion``:       cross-entropy of E_e's logits against the quadruple's emotion
- L_sty   -> ``style``:         cross-entropy of E_s's logits against each window's speaker
- L_xemo  -> ``cross_emotion``: D(c_k, e_j(k), s_k) vs a_k, j = EMOTION_STYLE_PARTNER
- L_xsty  -> ``cross_style``:   D(c_k, e_k, s_j(k)) vs a_k, j = EMOTION_STYLE_PARTNER
- L_xcon  -> ``cross_content``: D(c_j(k), e_k, s_k) vs a_k, j = CONTENT_PARTNER

Beyond the paper, off unless their weights are set (``SpeechLossConfig.preset('adversarial')``). The
paper's seven terms never penalise a factor leaking into the wrong latent (every swap pairs windows that
share it), and with a weak decoder nothing makes a latent carry its own factor either: on the synthetic
corpus both the emotion and the style latent then carry both factors. Both extensions look at
batch-standardised latents (zero mean, unit variance per dimension), as a linear probe does:

- ``latent_classes``: cross-entropy of a linear emotion classifier on the emotion latent and a linear
  speaker classifier on the style latent (each latent carries its own factor, linearly);
- ``adversarial``: two linear adversaries, speaker from the emotion latent and emotion from the style
  latent. The adversaries learn to read the other factor (cross-entropy on detached latents); the
  encoders learn to leave them guessing (cross-entropy of the frozen adversaries' predictions against
  the uniform distribution, a "confusion" loss, which unlike a gradient reversal cannot be satisfied by
  making the adversary confidently wrong). The logged value is the adversaries' cross-entropy plus the
  confusion term; the adversaries' part alone is logged as ``adversary_ce`` (log 8 + log n at chance).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import torch
import torch.nn.functional as F

from emogesture.errors import ConfigError

#: Same speaker, other text: a1 <-> a2, a3 <-> a4 (1-based j(k) = 2, 1, 4, 3). Emotion and style swaps.
EMOTION_STYLE_PARTNER: tuple[int, int, int, int] = (1, 0, 3, 2)
#: Same text, other speaker: a1 <-> a3, a2 <-> a4 (1-based j(k) = 3, 4, 1, 2). Content swaps.
CONTENT_PARTNER: tuple[int, int, int, int] = (2, 3, 0, 1)

_SELF = (0, 1, 2, 3)
#: For each reconstruction term, the window index of (content, emotion, style) decoded for target a_k.
RECONSTRUCTIONS: dict[str, tuple[tuple[int, ...], tuple[int, ...], tuple[int, ...]]] = {
    "self_recon": (_SELF, _SELF, _SELF),
    "cross_emotion": (_SELF, EMOTION_STYLE_PARTNER, _SELF),
    "cross_style": (_SELF, _SELF, EMOTION_STYLE_PARTNER),
    "cross_content": (CONTENT_PARTNER, _SELF, _SELF),
}


LOSS_PRESETS = ("full", "emotion_only", "style_only", "adversarial")


@dataclass
class SpeechLossConfig:
    """Weight of each term (all 1 in the paper). A weight of 0 switches the term off: it is not computed."""

    self_recon: float = 1.0
    content: float = 1.0
    emotion: float = 1.0
    style: float = 1.0
    cross_emotion: float = 1.0
    cross_style: float = 1.0
    cross_content: float = 1.0
    latent_classes: float = 0.0  # not in the paper; see the module docstring
    adversarial: float = 0.0  # not in the paper; see the module docstring

    def __post_init__(self) -> None:
        for f in fields(self):
            if getattr(self, f.name) < 0:
                raise ConfigError(f"speech loss weight {f.name} must be ≥ 0, got {getattr(self, f.name)}")

    @classmethod
    def preset(cls, name: str) -> "SpeechLossConfig":
        """``full`` (the paper's seven terms), ``emotion_only`` (no L_sty, L_xsty), ``style_only`` (no L_emo,
        L_xemo), ``adversarial`` (the seven terms plus the two extensions: latent classes at weight 1,
        adversaries at 0.5)."""
        if name == "full":
            return cls()
        if name == "adversarial":
            return cls(latent_classes=1.0, adversarial=0.5)
        if name == "emotion_only":
            return cls(style=0.0, cross_style=0.0)
        if name == "style_only":
            return cls(emotion=0.0, cross_emotion=0.0)
        raise ConfigError(f"unknown speech loss preset {name!r}; known: {', '.join(LOSS_PRESETS)}")

    def active(self) -> list[str]:
        """Names of the switched-on terms."""
        return [f.name for f in fields(self) if getattr(self, f.name) > 0]


class _MeanAbsError(torch.autograd.Function):
    """``mean |pred - target|`` per index of dim 1 of ``pred [B, n, 4, T, F]`` vs ``target [B, 1, 4, T, F]``.

    Same value and gradient as ``(pred - target).abs().mean(dim=(0, 2, 3, 4))`` with fewer passes over
    the (large) reconstructions: saves only the sign. ``target`` gets no gradient.
    """

    @staticmethod
    def forward(ctx, pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        diff = pred - target
        sign = diff.sign()
        ctx.count = diff.numel() // diff.shape[1]
        ctx.save_for_backward(sign)
        return diff.abs_().mean(dim=(0, 2, 3, 4))

    @staticmethod
    def backward(ctx, grad: torch.Tensor):
        (sign,) = ctx.saved_tensors
        return sign * (grad / ctx.count).view(1, -1, 1, 1, 1), None


def speech_losses(
    model, fbank: torch.Tensor, emotion: torch.Tensor, speaker: torch.Tensor,
    config: SpeechLossConfig | None = None, target: torch.Tensor | None = None,
    emotion_fbank: torch.Tensor | None = None,
) -> dict[str, torch.Tensor]:
    """Disentanglement losses of a batch of quadruples.

    Args:
        model: exposes ``encode`` and ``decode`` (see the module docstring).
        fbank: ``[B, 4, T, F]`` (``[B, 4, 1024, 128]``) windows in quadruple order (c1 s1, c2 s1, c1 s2, c2 s2).
        emotion: ``[B]`` emotion class of each quadruple (shared by its four windows).
        speaker: ``[B, 4]`` speaker class of each window.
        config: term weights; ``None`` means :meth:`SpeechLossConfig.preset` ``"full"``.
        target: ``[B, 4, T, F]`` reconstruction targets when ``fbank`` is augmented (the clean
            windows); ``None`` reconstructs ``fbank`` itself.
        emotion_fbank: ``[B, 4, T, F]`` input of the emotion encoder alone (e.g. word-order scrambled
            windows); ``None`` gives it ``fbank``.

    Returns:
        A dict with a scalar per switched-on term (unweighted) and ``total`` (the weighted sum).
        All 4·B windows are encoded in one pass and all requested reconstructions decoded in one pass.
    """
    config = config or SpeechLossConfig()
    if fbank.dim() != 4 or fbank.shape[1] != 4:
        raise ValueError(f"fbank must be [B, 4, T, F] quadruples, got {tuple(fbank.shape)}")
    b, _, t, f = fbank.shape
    if emotion.shape != (b,) or speaker.shape != (b, 4):
        raise ValueError(
            f"expected emotion [{b}] and speaker [{b}, 4], got {tuple(emotion.shape)}, {tuple(speaker.shape)}"
        )
    active = config.active()
    flat = fbank.reshape(b * 4, t, f)
    enc = model.encode(flat) if emotion_fbank is None else model.encode(
        flat, emotion_fbank=emotion_fbank.reshape(b * 4, t, f))
    lat = [v.reshape(b, 4, -1) for v in (enc.content, enc.emotion, enc.style)]
    out: dict[str, torch.Tensor] = {}
    extras: dict[str, torch.Tensor] = {}  # logged, not part of the total

    recon = [name for name in RECONSTRUCTIONS if name in active]
    if recon:
        idx = [torch.tensor([i for name in recon for i in RECONSTRUCTIONS[name][part]], device=fbank.device)
               for part in range(3)]
        picked = [v[:, ix].reshape(b * len(ix), -1) for v, ix in zip(lat, idx)]
        decoded = model.decode(*picked).reshape(b, len(recon), 4, t, f)
        errors = _MeanAbsError.apply(decoded, (fbank if target is None else target).unsqueeze(1))
        out.update({name: errors[i] for i, name in enumerate(recon)})
    if "content" in active:
        out["content"] = (lat[0][:, :2] - lat[0][:, 2:]).abs().mean()
    if "emotion" in active:
        out["emotion"] = F.cross_entropy(enc.emotion_logits, emotion.repeat_interleave(4))
    if "style" in active:
        out["style"] = F.cross_entropy(enc.speaker_logits, speaker.reshape(-1))
    if "latent_classes" in active:
        out["latent_classes"] = (
            F.cross_entropy(model.emotion_from_latent(_standardise(enc.emotion)), emotion.repeat_interleave(4))
            + F.cross_entropy(model.speaker_from_latent(_standardise(enc.style)), speaker.reshape(-1)))
    if "adversarial" in active:
        adversary_ce, confusion = _adversarial_terms(
            ((model.speaker_adversary, _standardise(enc.emotion), speaker.reshape(-1)),
             (model.emotion_adversary, _standardise(enc.style), emotion.repeat_interleave(4))))
        out["adversarial"] = adversary_ce + confusion
        extras["adversary_ce"] = adversary_ce.detach()

    total = fbank.new_zeros(())
    for name, value in out.items():
        total = total + getattr(config, name) * value
    out.update(extras)
    out["total"] = total
    return out


def _standardise(x: torch.Tensor) -> torch.Tensor:
    """Per-dimension zero mean, unit variance over the batch: ``[N, D] -> [N, D]``."""
    return (x - x.mean(0)) / (x.std(0) + 1e-5)


def _adversarial_terms(heads) -> tuple[torch.Tensor, torch.Tensor]:
    """``heads``: (linear adversary, latent ``[N, 256]``, labels ``[N]``) triples -> (the adversaries'
    cross-entropy on detached latents, the encoders' confusion loss through frozen adversaries)."""
    ce, confusion = 0.0, 0.0
    for head, latent, labels in heads:
        ce = ce + F.cross_entropy(head(latent.detach()), labels)
        logp = F.log_softmax(F.linear(latent, head.weight.detach(), head.bias.detach()), dim=-1)
        confusion = confusion - logp.mean()
    return ce, confusion
