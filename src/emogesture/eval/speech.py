"""``emogesture evaluate speech``: supp. Tables A.1 (EA, EF1, SA, SF1) and A.2 (reconstruction errors).

Also linear probes of each latent for emotion and speaker, the disentanglement check: emotion should
be readable from the emotion latent and not from the style latent, and the reverse for speaker.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import torch

from emogesture.eval.report import split_use_line
from emogesture.checkpoints import write_text_atomic
from emogesture.provenance import split_use
from emogesture.data.beat import EMOTIONS
from emogesture.data.cache import open_cache
from emogesture.data.quadruples import QuadrupleIndex, WindowLabels
from emogesture.errors import EmogestureError, OutputExistsError
from emogesture.eval.classification import classification_report
from emogesture.eval.plots import save_confusion_matrix
from emogesture.eval.probes import linear_probe_accuracy
from emogesture.models.speech_losses import SpeechLossConfig, speech_losses
from emogesture.pipeline.perception import perception_of
from emogesture.eval.split_latents import encode_split
from emogesture.pipeline.speech import SpeechLatentEncoder

RECON_COLUMNS = {"Self": "self_recon", "XCon": "cross_content", "XEmo": "cross_emotion", "XSty": "cross_style"}
ACCURACY_BAR = 0.9  # EA and SA: the bar the speech experiment set itself (experiments/speech_model/README.md)
NEAR_CHANCE = 0.25  # a probe of the other factor "near chance": within this share of the way from chance to 1
CONTENT_USE_BAR = 1.05  # swapping the content latent must raise the reconstruction error by at least 5 %


def speech_checks(r: dict) -> dict:
    """The speech model's thresholds as ``{name: {value, threshold, pass}}`` (pure function of a report).

    Each can fail for a bad model: an untrained model fails EA/SA; adversaries that leave the other
    factor readable fail the probe rows; a decoder that ignores the content latent fails content use.
    XCon/XEmo/XSty against Self are reported only: with such a decoder they equal Self for any model.
    """
    checks: dict = {}

    def check(name: str, value: float, threshold: float, higher_is_better: bool = True) -> None:
        ok = value >= threshold if higher_is_better else value <= threshold
        checks[name] = {"value": float(value), "threshold": float(threshold), "pass": bool(ok)}

    check(f"EA >= {ACCURACY_BAR}", r["EA"], ACCURACY_BAR)
    check(f"SA >= {ACCURACY_BAR}", r["SA"], ACCURACY_BAR)
    probes, chance = r["linear_probes"], r["chance"]
    for target, latent in (("emotion", "style"), ("speaker", "emotion")):
        bar = chance[target] + NEAR_CHANCE * (1.0 - chance[target])
        check(f"{target} read from the {latent} latent: near chance ({chance[target]:.3f})",
              probes[f"{target}_from_{latent}"], bar, higher_is_better=False)
    use = r["content_use"]
    check("content use: L1 with the content latent shuffled / own", use["content_shuffled"] / use["self"],
          CONTENT_USE_BAR)
    for col, rel in r["reconstruction_relative_to_self"].items():
        if col != "Self" and rel is not None:
            checks[f"{col} / Self (reported)"] = {"value": float(rel), "threshold": None, "pass": None}
    return checks


@torch.no_grad()
def reconstruction_errors(encoder: SpeechLatentEncoder, windows, partner, num_quadruples: int, seed: int,
                          batch_size: int = 8) -> dict[str, float]:
    """Mean L1 filterbank errors Self, XCon, XEmo, XSty over seeded held-out quadruples.

    The first text ``c1`` of every quadruple is one of the evaluated split's; ``c2`` is another text of
    the same emotion from that split or from ``partner``, windows of another split the model never
    trained on (each split of the synthetic corpus has one text per emotion).
    """
    labels = WindowLabels.concat(windows, partner)
    n = len(windows)
    index = QuadrupleIndex(labels, first_texts=set(windows.text.tolist()))

    def fbank(j: int) -> np.ndarray:
        return np.asarray(windows.fbank[j] if j < n else partner.fbank[j - n], np.float32)

    rng = np.random.default_rng(seed)
    speakers = {s: i for i, s in enumerate(encoder.speakers)}
    sums = {k: 0.0 for k in RECON_COLUMNS}
    done = 0
    cfg = SpeechLossConfig(content=0.0, emotion=0.0, style=0.0)
    while done < num_quadruples:
        qs = [index.draw(rng) for _ in range(min(batch_size, num_quadruples - done))]
        fb = torch.from_numpy(np.stack([[fbank(j) for j in q.indices] for q in qs]))
        emo = torch.tensor([q.emotion for q in qs])
        spk = torch.tensor([[speakers.get(s, 0) for s in q.speakers] for q in qs])
        out = speech_losses(encoder.model, fb.to(encoder.device), emo, spk, cfg)
        for col, key in RECON_COLUMNS.items():
            sums[col] += float(out[key]) * len(qs)
        done += len(qs)
    return {k: v / done for k, v in sums.items()}


@torch.no_grad()
def content_use(encoder: SpeechLatentEncoder, windows, seed: int, batch_size: int = 32) -> dict[str, float]:
    """Does the decoder use the content latent, and does it reconstruct any timing?

    Over every window of the split (mean L1 on the normalised filterbank): ``self`` (own three latents),
    ``content_shuffled`` (the content latent of a seeded random other window, own emotion and style) and
    ``time_mean`` (each window's own spectrum averaged over time: the best a reconstruction without any
    timing can do, up to the per-bin median). A content latent the decoder ignores gives
    ``content_shuffled == self``; a decoder that reconstructs no timing gives ``self ≈ time_mean``.
    """
    model = encoder.model
    n = len(windows.fbank)
    perm = np.random.default_rng(seed).permutation(n)
    perm = np.where(perm == np.arange(n), np.roll(perm, 1), perm)  # never a window's own content

    def batches():
        for i in range(0, n, batch_size):
            yield i, torch.from_numpy(np.asarray(windows.fbank[i : i + batch_size], np.float32)).to(encoder.device)

    def l1(x: torch.Tensor, target: torch.Tensor) -> float:
        return float((x - target).abs().sum())

    sums = {"self": 0.0, "content_shuffled": 0.0, "time_mean": 0.0}
    contents, others = [], []
    for _, fb in batches():  # first pass: latents, own reconstruction, time-averaged spectrum
        enc = model.encode(fb)
        contents.append(enc.content)
        others.append((enc.emotion, enc.style))
        sums["self"] += l1(model.decode(enc.content, enc.emotion, enc.style), fb)
        sums["time_mean"] += l1(fb.mean(dim=1, keepdim=True), fb)
    content = torch.cat(contents)
    for (i, fb), (e, s) in zip(batches(), others):  # second pass: another window's content latent
        sums["content_shuffled"] += l1(model.decode(content[torch.from_numpy(perm[i : i + len(fb)])], e, s), fb)
    size = n * windows.fbank.shape[1] * windows.fbank.shape[2]
    return {k: v / size for k, v in sums.items()}


def evaluate_speech(run: Path, cache_dir: Path, split: str = "test", out_dir: Path | None = None,
                    num_quadruples: int = 128, seed: int = 0, probe_train_windows: int = 4000,
                    overwrite: bool = False) -> dict:
    """Evaluate a speech model run on a cache split; writes JSON, markdown and confusion PNGs."""
    t0 = time.monotonic()
    out_dir = Path(out_dir) if out_dir else Path(run) / "eval"
    stem = f"speech_{split}"
    outputs = [out_dir / f"{stem}.json", out_dir / f"{stem}.md"]
    if not overwrite:
        for p in outputs:
            if p.exists():
                raise OutputExistsError(p)
    encoder = SpeechLatentEncoder.from_run(run)
    split_info = split_use(split, {"speech": encoder.loaded})
    cache = open_cache(cache_dir)
    test = cache.split(split)
    enc = encode_split(encoder, cache, split)
    emo_rep = classification_report(test.emotion, enc.emotion_logits.argmax(1), len(EMOTIONS))
    perception = perception_of(encoder)  # a calibrated model: the emotion as generate hears it, beside the head's
    heard = (None if perception is None else
             float((perception.read(enc.emotion, enc.emotion_logits).argmax(1) == test.emotion).mean()))
    spk_class = {s: i for i, s in enumerate(encoder.speakers)}
    known = np.array([s in spk_class for s in test.speaker_id.tolist()])
    if not known.any():
        raise EmogestureError(f"{cache_dir}: none of the {split} speakers were seen in training; no speaker accuracy")
    spk_true = np.array([spk_class[s] for s in test.speaker_id[known].tolist()])
    spk_rep = classification_report(spk_true, enc.speaker_logits[known].argmax(1), len(spk_class))

    # linear probes: fit on (a seeded subset of) training windows, score on the split
    train = cache.split("train")
    tr_enc = encode_split(encoder, cache, "train")
    rng = np.random.default_rng(seed)
    sub = np.sort(rng.permutation(len(train))[:probe_train_windows])
    probes = {}
    for latent in ("content", "emotion", "style"):
        x_tr, x_te = getattr(tr_enc, latent)[sub], getattr(enc, latent)
        probes[f"emotion_from_{latent}"] = linear_probe_accuracy(x_tr, train.emotion[sub], x_te, test.emotion)
        probes[f"speaker_from_{latent}"] = linear_probe_accuracy(x_tr, train.speaker_id[sub], x_te, test.speaker_id)

    # quadruples of held-out texts only: their second text from another split no part trained on (and
    # never from test when another split is scored: test is read only when it is the split scored)
    unseen = [s for s in cache.splits
              if s not in (split, "test") and s not in split_info["trained_on"]["speech"]]
    recon = (reconstruction_errors(encoder, test, cache.split(unseen[0]), num_quadruples, seed) if unseen
             else dict.fromkeys(RECON_COLUMNS))
    use = content_use(encoder, test, seed)
    result = {
        "run": str(run), "cache": str(cache_dir), "split": split, "windows": len(test), "split_use": split_info,
        "step": encoder.loaded.metadata.step,
        "EA": emo_rep["accuracy"], "EF1": emo_rep["macro_f1"], "EA_perceived": heard,
        "SA": spk_rep["accuracy"], "SF1": spk_rep["macro_f1"], "speaker_windows": int(known.sum()),
        "reconstruction_l1": recon,
        "reconstruction_relative_to_self": {k: (v / recon["Self"] if v is not None else None)
                                            for k, v in recon.items()},
        "reconstruction_partner_split": unseen[0] if unseen else None,
        "linear_probes": probes,
        "content_use": use,
        "chance": {"emotion": _majority_share(test.emotion), "speaker": _majority_share(test.speaker_id)},
        "constants": {"num_quadruples": num_quadruples, "seed": seed, "probe_train_windows": int(len(sub)),
                      "probe": "standardised multinomial logistic regression, C=1"},
        "seconds": round(time.monotonic() - t0, 1),
    }
    out_dir.mkdir(parents=True, exist_ok=True)
    save_confusion_matrix(emo_rep["confusion"], list(EMOTIONS), out_dir / f"{stem}_emotion_confusion.png",
                          title=f"emotion ({split}), EA {result['EA']:.3f}", overwrite=overwrite)
    save_confusion_matrix(spk_rep["confusion"], [str(s) for s in encoder.speakers],
                          out_dir / f"{stem}_speaker_confusion.png", title=f"speaker ({split}), SA {result['SA']:.3f}",
                          overwrite=overwrite)
    result["checks"] = speech_checks(result)
    write_text_atomic(outputs[0], json.dumps(result, indent=1, default=_jsonable))
    write_text_atomic(outputs[1], speech_markdown(result))
    return result


def speech_markdown(r: dict) -> str:
    rec, rel, pr = r["reconstruction_l1"], r["reconstruction_relative_to_self"], r["linear_probes"]
    use = r["content_use"]
    lines = [
        f"# Speech disentanglement: {r['split']} split ({r['windows']} windows, step {r['step']})", "",
        split_use_line(r.get("split_use")), "",
        "Classification (supp. Table A.1 layout)", "",
        "| EA | EF1 | SA | SF1 |", "|---|---|---|---|",
        f"| {r['EA']:.3f} | {r['EF1']:.3f} | {r['SA']:.3f} | {r['SF1']:.3f} |", "",
        *([f"EA of the emotion perception (the classifier head and the nearest emotion mean within the calibrated "
           f"range, as `generate` reports it): {r['EA_perceived']:.3f}", ""]
          if r.get("EA_perceived") is not None else []),
        "Reconstruction L1 on the normalised filterbank (supp. Table A.2 layout; ratio to Self below); "
        + (f"quadruples of {r['split']} texts paired with {r['reconstruction_partner_split']} texts of the same "
           "emotion, neither trained on" if r.get("reconstruction_partner_split") else
           "not measured: no second split of texts the model never trained on to pair with"), "",
        "| Self | XCon | XEmo | XSty |", "|---|---|---|---|",
        "| " + " | ".join(_num(rec[k], 4) for k in RECON_COLUMNS) + " |",
        "| " + " | ".join(_num(rel[k], 3) for k in RECON_COLUMNS) + " |", "",
        "Content use: reconstruction L1 over every window with its own latents, with the content latent of "
        "another window, and each window's own time-averaged spectrum (about what a reconstruction without any "
        "timing reaches)", "",
        "| self | content shuffled | time-averaged spectrum |", "|---|---|---|",
        "| " + " | ".join(f"{use[k]:.4f}" for k in ("self", "content_shuffled", "time_mean")) + " |", "",
        "Linear probes (held-out accuracy; chance = 1/classes)", "",
        "| latent | emotion | speaker |", "|---|---|---|",
    ]
    for latent in ("content", "emotion", "style"):
        lines.append(f"| {latent} | {pr[f'emotion_from_{latent}']:.3f} | {pr[f'speaker_from_{latent}']:.3f} |")
    if "checks" in r:
        lines += ["", "## Checks", "", "| check | value | threshold | pass |", "|---|---|---|---|"]
        for name, c in r["checks"].items():
            thr = "-" if c["threshold"] is None else f"{c['threshold']:.3f}"
            ok = "-" if c["pass"] is None else ("yes" if c["pass"] else "**no**")
            lines.append(f"| {name} | {c['value']:.3f} | {thr} | {ok} |")
    lines += ["", f"Constants: {json.dumps(r['constants'])}", ""]
    return "\n".join(lines)


def _majority_share(labels: np.ndarray) -> float:
    """Accuracy of always answering the most frequent label (chance for a classifier)."""
    _, counts = np.unique(np.asarray(labels), return_counts=True)
    return float(counts.max() / counts.sum())


def _num(v: float | None, digits: int) -> str:
    return "n/a" if v is None else f"{v:.{digits}f}"


def _jsonable(x):
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    raise TypeError(type(x))
