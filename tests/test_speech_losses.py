"""The speech model's loss terms: the fused L1, the swap terms and their partners, switched-off terms, weights and presets, the adversaries."""

from __future__ import annotations

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from emogesture.models import speech_losses as sl
from emogesture.models.speech import SpeechDisentangler, SpeechEncoding, SpeechModelConfig
from emogesture.models.speech_losses import SpeechLossConfig, speech_losses
from emogesture.models.vit import ViTConfig


def _gen(seed: int) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


class StubModel:
    """encode reads rows 0/1/2 of a window as content/emotion/style; decode writes them back.

    Emotion logits are the first 8 entries of the emotion row, speaker logits the first 5 of the style row.
    """

    def __init__(self, noise: float = 0.0):
        self.noise = noise
        self.decoded: list[int] = []

    def encode(self, x):
        e, s = x[:, 1], x[:, 2]
        return SpeechEncoding(x[:, 0], e, s, e[:, :8], s[:, :5])

    def decode(self, c, e, s):
        self.decoded.append(c.shape[0])
        y = torch.stack([c, e, s], dim=1)
        return y * (1 + self.noise) + self.noise  # imperfect, and independent of the batch layout


def _toy_quadruples(b: int = 3):
    """fbank [B, 4, 3, 16] consistent with (c1 s1, c2 s1, c1 s2, c2 s2), one emotion per quadruple."""
    g = _gen(4)
    emotion = torch.randint(0, 8, (b,), generator=g)
    speaker = torch.randint(0, 5, (b, 2), generator=g)
    content = torch.randn(b, 2, 16, generator=g)
    # each speaker voices the shared emotion in its own way (entries 8:), so swapping emotion latents is
    # only harmless between windows of the same speaker: a wrong partner map shows up as a positive loss
    emo_vec = torch.cat([50 * F.one_hot(emotion, 8).float()[:, None].expand(b, 2, 8),
                         torch.randn(b, 2, 8, generator=g)], 2)
    sty_vec = torch.cat([50 * F.one_hot(speaker, 5).float(), torch.randn(b, 2, 11, generator=g)], 2)
    rows = []
    for ci, si in ((0, 0), (1, 0), (0, 1), (1, 1)):
        rows.append(torch.stack([content[:, ci], emo_vec[:, si], sty_vec[:, si]], dim=1))
    fbank = torch.stack(rows, dim=1)
    return fbank, emotion, speaker[:, [0, 0, 1, 1]]


TERMS = ("self_recon", "content", "emotion", "style", "cross_emotion", "cross_style", "cross_content")


def _zero_terms(out):
    return {k for k in TERMS if float(out[k]) < 1e-6}


def test_fused_l1_matches_autograd_reference():
    g = _gen(10)
    pred = torch.randn(2, 3, 4, 5, 6, generator=g, requires_grad=True)
    target = torch.randn(2, 1, 4, 5, 6, generator=g)
    w = torch.tensor([1.0, 2.0, 0.5])
    ref = (pred - target).abs().mean(dim=(0, 2, 3, 4))
    (ref_grad,) = torch.autograd.grad((ref * w).sum(), pred)
    got = sl._MeanAbsError.apply(pred, target)
    (got_grad,) = torch.autograd.grad((got * w).sum(), pred)
    assert torch.allclose(got, ref) and torch.allclose(got_grad, ref_grad)


def test_losses_vanish_for_a_perfect_model():
    fbank, emotion, speaker = _toy_quadruples()
    out = speech_losses(StubModel(), fbank, emotion, speaker)
    assert set(out) == set(TERMS) | {"total"}
    assert _zero_terms(out) == set(TERMS) and float(out["total"]) < 1e-5


@pytest.mark.parametrize(
    "row, window, positive",
    [
        (1, 1, {"cross_emotion"}),  # a2's emotion latent differs from a1's: only the emotion swap notices
        (2, 1, {"cross_style"}),  # a2's style latent differs from a1's (same speaker): only the style swap
        (0, 2, {"content", "cross_content"}),  # a3's content differs from a1's
    ],
)
def test_each_swap_term_uses_its_partner(row, window, positive):
    fbank, emotion, speaker = _toy_quadruples()
    fbank[:, window, row, 8:] += 1.0  # outside the logit entries: labels stay right
    out = speech_losses(StubModel(), fbank, emotion, speaker)
    assert set(TERMS) - _zero_terms(out) == positive


def test_terms_are_positive_for_imperfect_models():
    fbank, emotion, speaker = _toy_quadruples()
    out = speech_losses(StubModel(noise=0.1), fbank, emotion, speaker)
    assert set(TERMS) - _zero_terms(out) == {"self_recon", "cross_emotion", "cross_style", "cross_content"}
    out = speech_losses(StubModel(), fbank, (emotion + 1) % 8, speaker)
    assert set(TERMS) - _zero_terms(out) == {"emotion"}
    out = speech_losses(StubModel(), fbank, emotion, (speaker + 1) % 5)
    assert set(TERMS) - _zero_terms(out) == {"style"}


@pytest.mark.parametrize("term", TERMS)
def test_a_switched_off_term_is_absent_and_not_computed(term, monkeypatch):
    fbank, emotion, speaker = _toy_quadruples()
    fbank[:, 2, 0] += 0.5  # make L_con and L_xcon positive too
    ce_calls = []
    real_ce = F.cross_entropy
    monkeypatch.setattr(F, "cross_entropy", lambda *a, **k: ce_calls.append(1) or real_ce(*a, **k))
    stub = StubModel(noise=0.1)
    full = speech_losses(stub, fbank, (emotion + 1) % 8, (speaker + 1) % 5)
    assert all(float(full[t]) > 1e-3 for t in TERMS)
    ce_calls.clear()
    stub.decoded.clear()
    out = speech_losses(stub, fbank, (emotion + 1) % 8, (speaker + 1) % 5, SpeechLossConfig(**{term: 0.0}))
    assert term not in out
    expected = sum(float(full[t]) for t in TERMS if t != term)
    assert float(out["total"]) == pytest.approx(expected, rel=1e-5)
    n_recon = sum(t in sl.RECONSTRUCTIONS for t in TERMS if t != term)
    assert stub.decoded == [n_recon * 4 * fbank.shape[0]]  # one batched decode of the active swaps
    assert len(ce_calls) == (1 if term in ("emotion", "style") else 2)


def test_configs_round_trip_and_reject_unknown_keys():
    from emogesture.config import from_dict, to_dict
    from emogesture.errors import ConfigError

    for name in ("paper", "tiny"):
        cfg = SpeechModelConfig.preset(name, num_speakers=7)
        assert from_dict(SpeechModelConfig, to_dict(cfg)) == cfg
    with pytest.raises(ConfigError, match="unknown key"):
        from_dict(SpeechModelConfig, {"encoder": {"widht": 3}})
    with pytest.raises(ConfigError, match="divisible"):
        ViTConfig(width=100, heads=3)
    assert from_dict(SpeechLossConfig, {"style": 0}).active() == [t for t in TERMS if t != "style"]


def test_loss_weights_and_presets():
    fbank, emotion, speaker = _toy_quadruples()
    stub = StubModel(noise=0.1)
    ref = speech_losses(stub, fbank, emotion, speaker)
    out = speech_losses(stub, fbank, emotion, speaker, SpeechLossConfig(self_recon=2.0, cross_style=0.5))
    expected = sum(float(ref[t]) for t in TERMS) + float(ref["self_recon"]) - 0.5 * float(ref["cross_style"])
    assert float(out["total"]) == pytest.approx(expected, rel=1e-5)
    assert set(SpeechLossConfig.preset("emotion_only").active()) == set(TERMS) - {"style", "cross_style"}
    assert set(SpeechLossConfig.preset("style_only").active()) == set(TERMS) - {"emotion", "cross_emotion"}
    assert SpeechLossConfig.preset("full").active() == list(TERMS)
    assert SpeechLossConfig.preset("adversarial").active() == list(TERMS) + ["latent_classes", "adversarial"]


def test_latent_classes_read_each_latent_own_factor():
    torch.manual_seed(3)
    model = SpeechDisentangler(SpeechModelConfig.preset("tiny", num_speakers=5))
    fbank = torch.randn(2, 4, 1024, 128, generator=_gen(7)) * 0.5
    emotion, speaker = torch.tensor([3, 5]), torch.tensor([[0, 0, 4, 4], [1, 1, 2, 2]])
    out = speech_losses(model, fbank, emotion, speaker, SpeechLossConfig(**{t: 0.0 for t in TERMS}, latent_classes=1.0))
    assert set(out) == {"latent_classes", "total"}
    enc = model.encode(fbank.reshape(8, 1024, 128))
    expected = (F.cross_entropy(model.emotion_from_latent(sl._standardise(enc.emotion)), emotion.repeat_interleave(4))
                + F.cross_entropy(model.speaker_from_latent(sl._standardise(enc.style)), speaker.reshape(-1)))
    assert float(out["latent_classes"].detach()) == pytest.approx(float(expected.detach()), rel=1e-5)
    out["total"].backward()
    assert model.emotion_encoder.latent_head[1].weight.grad.abs().sum() > 0
    assert model.style_encoder.latent_head[1].weight.grad.abs().sum() > 0
    assert model.content_encoder.latent_head[1].weight.grad is None
    standard = sl._standardise(torch.randn(16, 4) * 3 + 2)
    assert torch.allclose(standard.mean(0), torch.zeros(4), atol=1e-5)
    assert torch.allclose(standard.std(0), torch.ones(4), atol=1e-3)


def test_adversaries_learn_to_read_and_encoders_learn_to_hide():
    """The adversaries' heads get gradient only from their own cross-entropy (on detached latents); the
    encoders only from the confusion term, which is smallest when the adversaries' output is uniform."""
    torch.manual_seed(2)
    model = SpeechDisentangler(SpeechModelConfig.preset("tiny", num_speakers=5))
    fbank = torch.randn(2, 4, 1024, 128, generator=_gen(6)) * 0.5
    emotion, speaker = torch.tensor([3, 5]), torch.tensor([[0, 0, 4, 4], [1, 1, 2, 2]])
    only = SpeechLossConfig(**{t: 0.0 for t in TERMS}, adversarial=1.0)
    out = speech_losses(model, fbank, emotion, speaker, only)
    assert set(out) == {"adversarial", "adversary_ce", "total"}
    # untrained adversaries guess near chance: CE ≈ log 5 + log 8
    assert float(out["adversary_ce"]) == pytest.approx(np.log(5) + np.log(8), rel=0.2)
    model.zero_grad()
    out["total"].backward()
    head = model.speaker_adversary.weight.grad
    enc = model.emotion_encoder.latent_head[1].weight.grad
    assert head is not None and head.abs().sum() > 0 and enc is not None and enc.abs().sum() > 0
    assert model.emotion_encoder.classifier.weight.grad is None or model.emotion_encoder.classifier.weight.grad.abs().sum() == 0
    # the heads' gradient equals that of their cross-entropy alone
    latent = sl._standardise(model.encode(fbank.reshape(8, 1024, 128)).emotion.detach())
    model.speaker_adversary.zero_grad()
    torch.nn.functional.cross_entropy(model.speaker_adversary(latent), speaker.reshape(-1)).backward()
    assert torch.allclose(head, model.speaker_adversary.weight.grad, atol=1e-6)
    # the confusion part is minimal (log K) for uniform predictions
    from emogesture.models.speech_losses import _adversarial_terms

    zero = torch.nn.Linear(256, 8)
    torch.nn.init.zeros_(zero.weight), torch.nn.init.zeros_(zero.bias)
    _, confusion = _adversarial_terms([(zero, torch.randn(4, 256), torch.tensor([0, 1, 2, 3]))])
    assert float(confusion) == pytest.approx(np.log(8), abs=1e-6)


def test_gradients_reach_all_three_encoders():
    torch.manual_seed(1)
    model = SpeechDisentangler(SpeechModelConfig.preset("tiny", num_speakers=5))
    g = _gen(5)
    fbank = torch.randn(1, 4, 1024, 128, generator=g) * 0.5
    out = speech_losses(model, fbank, torch.tensor([3]), torch.tensor([[0, 0, 4, 4]]))
    out["total"].backward()
    for name in ("content_encoder", "emotion_encoder", "style_encoder", "fusion", "decoder"):
        for pname, p in getattr(model, name).named_parameters():
            assert p.grad is not None and p.grad.abs().sum() > 0, f"{name}.{pname} gets no gradient"
