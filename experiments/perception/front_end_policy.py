"""Who decides the emotion heard in a window, the speech model's read-out or the front end's: measured on val.

The policy shipped before let the front end trained on real speech (Whisper tiny.en and its read-out) decide in
every window whose trust is below 1 and the speech model's own read-out in the rest. This script hears every
window both ways once and stores what each says, so that policies and read-outs can be compared without
hearing again, on the synthetic val split's held-out voices (as recorded and through the nine recording changes
of ``perception_shift.py``), RAVDESS's val actors, the real read speech of the `real` checks and the
validation voices (KTuberling's word readers, real people reading without acted emotion):

- ``switch``: the front end where trust < 1, the speech model elsewhere;
- ``pool λ``: where trust < 1, the front end's log-probabilities plus λ times the speech model's;
- ``trusted: speech + μ front; others: pool λ``: the trusted windows too, the speech model's plus μ times the
  front end's;
- each with the shipped read-out and with read-outs refitted as the recipe fits them (regularisation chosen on
  the val actors): on the same windows, with an augmented copy of each (the training augmentation), and with
  real voices read without acted emotion as neutral (the training voices of ``emogesture.data.real_speech``).

Every window here is heard by the front end (``generate`` hears one every 20 s and interpolates the rest); the
chosen policy is then scored as ``generate`` hears by ``experiments/perception_shift.py`` and
``experiments/ravdess/perception_val.py``.

Usage:
  front_end_policy.py dump SPEECH_MODEL CACHE RAVDESS_MANIFEST OUT_DIR   # val conditions, val actors, real speech
  front_end_policy.py dump-train CACHE RAVDESS_TRAIN_MANIFEST OUT_DIR [COPIES]   # the read-out's train windows
  front_end_policy.py dump-voices SPEECH_MODEL OUT_DIR [COPIES] [MOST]   # training voices (train), word readers (val)
  front_end_policy.py score OUT_DIR                                       # the table (policies.md)
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from emogesture.audio import load_audio
from emogesture.audio.wave_augment import recording_changes
from emogesture.data.cache import open_cache
from emogesture.data.labelled_speech import labelled_recordings, read_manifest
from emogesture.data.real_speech import RECORDINGS, load_real_recording
from emogesture.pipeline.speech import SpeechLatentEncoder
from emogesture.pipeline.voice_features import whisper_features
from emogesture.types import EMOTIONS

CALM_AS = "neutral"


def heard_both_ways(encoder: SpeechLatentEncoder, hearer, wave: np.ndarray, hop_s: float) -> dict:
    """One recording's windows: the speech model's log-probabilities, trust and the front end's features."""
    perception = encoder.perception
    enc, starts = encoder.encode(wave, 16000, hop_s)
    speech = perception.read(enc.emotion, enc.emotion_logits)
    features = hearer(wave, starts)
    return {"speech": speech, "trust": perception.trust(enc.emotion, enc.style), "features": features,
            "front": perception.heard.log_probs(features)}


def dump(speech_model: str, cache_dir: str, manifest: str, out_dir: str) -> None:
    from tqdm import tqdm

    encoder = SpeechLatentEncoder.from_run(speech_model)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    cache = open_cache(cache_dir)
    val = cache.split("val")
    root = Path(cache.manifest["root"])
    emotion_of = val.take_emotions(leave_out_speakers=encoder.speakers)
    rng = np.random.default_rng(0)
    conditions = {"as recorded": lambda w: w, **recording_changes(rng)}
    sets: dict[str, tuple[list, list[str]]] = {}
    with whisper_features() as hearer:
        for name, change in conditions.items():
            parts, labels = [], []
            for take in tqdm(list(emotion_of), desc=name, leave=False):
                wave, _ = load_audio(root / "wave16k" / f"{take}.wav")
                h = heard_both_ways(encoder, hearer, np.asarray(change(wave), np.float32), 8.0)
                parts.append(h)
                labels += [EMOTIONS[emotion_of[take]]] * len(h["trust"])
            sets[f"synthetic val: {name}"] = (parts, labels)
        parts, labels = [], []
        for name, (wave, emotion) in tqdm(labelled_recordings(read_manifest(manifest), "val", 10.0).items(),
                                          desc="RAVDESS val", leave=False):
            h = heard_both_ways(encoder, hearer, wave, 7.0)
            parts.append(h)
            labels += [CALM_AS if emotion == "calm" else emotion] * len(h["trust"])
        sets["RAVDESS val actors"] = (parts, labels)
        parts, labels = [], []
        for recording in RECORDINGS:
            h = heard_both_ways(encoder, hearer, load_real_recording(recording), 8.0)
            parts.append(h)
            labels += ["neutral"] * len(h["trust"])
        sets["real read speech"] = (parts, labels)
    arrays = {}
    for i, (name, (parts, labels)) in enumerate(sets.items()):
        for key in ("speech", "trust", "features", "front"):
            arrays[f"{i}.{key}"] = np.concatenate([p[key] for p in parts])
        arrays[f"{i}.labels"] = np.asarray([EMOTIONS.index(lab) for lab in labels])
    np.savez_compressed(out / "heard.npz", **arrays)
    (out / "sets.json").write_text(json.dumps(list(sets), indent=1) + "\n")


def dump_train(cache_dir: str, manifest: str, out_dir: str, copies: str = "1") -> None:
    """The front end's features of what its read-out is fitted on (the cache's train takes every 10 s, the
    manifest's train speakers every 3 s, as the recipe fits it), as recorded and ``copies`` times through the
    training augmentation (:func:`emogesture.audio.wave_augment.augment_waveform`, seeded)."""
    from emogesture.audio.wave_augment import augment_waveform
    from emogesture.audio.windows import window_starts
    from emogesture.train.heard_readout import CORPUS_HOP_S, LABELLED_HOP_S
    from tqdm import tqdm

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    cache = open_cache(cache_dir)
    root = Path(cache.manifest["root"])
    recordings = [(take, root / "wave16k" / f"{take}.wav", emotion, CORPUS_HOP_S, "corpus")
                  for take, emotion in cache.split("train").take_emotions().items()]
    real = labelled_recordings(read_manifest(manifest), "train", 10.0)
    rng = np.random.default_rng(0)
    arrays: dict[str, list] = {}
    with whisper_features() as hearer:
        for item in tqdm(recordings + list(real.items()), desc="train recordings, front end"):
            if len(item) == 5:
                _, path, emotion, hop, source = item
                wave = load_audio(path)[0]
            else:
                _, (wave, name) = item
                emotion, hop, source = EMOTIONS.index(name), LABELLED_HOP_S, "real"
            starts = window_starts(len(wave) / 16000, 10.0, hop).tolist()
            for copy in range(1 + int(copies)):
                heard = wave if copy == 0 else augment_waveform(wave, rng)[0]
                x = hearer(heard, starts)
                arrays.setdefault(f"{source}.{copy}.features", []).append(x)
                arrays.setdefault(f"{source}.{copy}.labels", []).append(np.full(len(x), emotion))
    np.savez_compressed(out / "train_heard.npz", **{k: np.concatenate(v) for k, v in arrays.items()})


def dump_voices(speech_model: str, out_dir: str, copies: str = "1", most: str = "40") -> None:
    """Real voices read without acted emotion: the training voices (:data:`TRAINING_VOICES`, as neutral windows
    the read-out may be fitted on: at most ``most`` 10-s windows of each, spread over it, as recorded and
    ``copies`` times augmented) and the validation voices (:data:`WORD_READERS`, heard both ways like the val
    sets, every window every 8 s)."""
    from emogesture.audio.wave_augment import augment_waveform
    from emogesture.audio.windows import window_starts
    from emogesture.data.real_speech import TRAINING_VOICES, WORD_READERS, load_voice
    from tqdm import tqdm

    out = Path(out_dir)
    encoder = SpeechLatentEncoder.from_run(speech_model)
    rng = np.random.default_rng(1)
    train: dict[str, list] = {}
    val: list[dict] = []
    with whisper_features() as hearer:
        for voice in tqdm(list(TRAINING_VOICES.values()), desc="training voices"):
            wave = load_voice(voice)
            starts = window_starts(len(wave) / 16000, 10.0, 10.0)
            starts = starts[np.unique(np.linspace(0, len(starts) - 1, min(len(starts), int(most))).round().astype(int))]
            for copy in range(1 + int(copies)):
                heard = wave if copy == 0 else augment_waveform(wave, rng)[0]
                x = hearer(heard, starts.tolist())
                train.setdefault(f"voices.{copy}.features", []).append(x)
                train.setdefault(f"voices.{copy}.labels", []).append(np.full(len(x), EMOTIONS.index("neutral")))
        for voice in tqdm(list(WORD_READERS.values()), desc="validation voices"):
            val.append(heard_both_ways(encoder, hearer, load_voice(voice), 8.0))
    np.savez_compressed(out / "voices_train.npz", **{k: np.concatenate(v) for k, v in train.items()})
    np.savez_compressed(out / "voices_val.npz", **{k: np.concatenate([h[k] for h in val])
                                                  for k in ("speech", "trust", "features", "front")})


def policies(speech: np.ndarray, front: np.ndarray, trust: np.ndarray) -> dict[str, np.ndarray]:
    """The label each policy hears in each window ``[W]``."""
    known = trust >= 1.0
    out = {"speech model alone": speech.argmax(1), "front end alone": front.argmax(1),
           "switch (shipped)": np.where(known, speech.argmax(1), front.argmax(1))}
    for lam in (0.1, 0.25, 0.5, 1.0):
        pooled = front + lam * speech
        out[f"pool {lam:g}"] = np.where(known, speech.argmax(1), pooled.argmax(1))
    for mu in (0.25, 0.5, 1.0, 2.0):  # the trusted windows: the speech model's log-probabilities plus mu times the front end's
        for lam in (0.25, 0.5):
            out[f"trusted: speech + {mu:g} front; others: pool {lam:g}"] = np.where(
                known, (speech + mu * front).argmax(1), (front + lam * speech).argmax(1))
    return out


def readouts(out: Path, names: list[str], data) -> dict[str, list[np.ndarray]]:
    """The front end's log-probabilities ``[W, 8]`` on each set, by read-out: the shipped one, and where the train
    features were dumped, refitted as the recipe fits it (the regularisation chosen on the val actors) on the
    train windows as recorded, and with their augmented copies as well."""
    out_sets = {"shipped read-out": [data[f"{i}.front"] for i in range(len(names))]}
    if not (out / "train_heard.npz").exists():
        return out_sets
    from emogesture.train.heard_readout import C_GRID, accuracy, fit_readout

    train = np.load(out / "train_heard.npz")
    val = names.index("RAVDESS val actors")
    val_x, val_y = data[f"{val}.features"], data[f"{val}.labels"]
    copies = sorted({int(k.split(".")[1]) for k in train.files})
    if (out / "voices_train.npz").exists():
        train = {**train, **np.load(out / "voices_train.npz")}
    fits = [("refitted, as recorded", [0], ("corpus", "real")),
            ("refitted, with augmented copies", copies, ("corpus", "real"))]
    if "voices.0.features" in train:
        fits += [("refitted + real neutral voices", [0], ("corpus", "real", "voices")),
                 ("refitted + real neutral voices, augmented", copies, ("corpus", "real", "voices"))]
    for label, use, sources in fits:
        x = np.concatenate([train[f"{src}.{c}.features"] for src in sources for c in use])
        y = np.concatenate([train[f"{src}.{c}.labels"] for src in sources for c in use])
        best = max(C_GRID, key=lambda c: (accuracy(fit_readout(x, y, c), val_x, val_y), -c))
        readout = fit_readout(x, y, best)
        out_sets[f"{label} (C {best:g})"] = [readout.log_probs(data[f"{i}.features"]) for i in range(len(names))]
    return out_sets


def score(out_dir: str) -> None:
    out = Path(out_dir)
    names = json.loads((out / "sets.json").read_text())
    data = dict(np.load(out / "heard.npz"))
    if (out / "voices_val.npz").exists():  # the validation voices: neutral
        i = len(names)
        names.append("word readers (val voices)")
        for k, v in np.load(out / "voices_val.npz").items():
            data[f"{i}.{k}"] = v
        data[f"{i}.labels"] = np.full(len(data[f"{i}.trust"]), EMOTIONS.index("neutral"))
    table: dict[str, dict[str, float]] = {}
    for readout, fronts in readouts(out, names, data).items():
        for i, name in enumerate(names):
            speech, trust, labels = data[f"{i}.speech"], data[f"{i}.trust"], data[f"{i}.labels"]
            for policy, heard in policies(speech, fronts[i], trust).items():
                table.setdefault(f"{readout}: {policy}", {})[name] = float(np.mean(heard == labels))
    for i, name in enumerate(names):
        table.setdefault("trusted by auto", {})[name] = float(np.mean(data[f"{i}.trust"] >= 1.0))
    short = [n.replace("synthetic val: ", "") for n in names]
    lines = ["| read-out: policy | " + " | ".join(short) + " | lowest synthetic |", "|---|" + "---|" * (len(names) + 1)]
    synthetic = [i for i, n in enumerate(names) if n.startswith("synthetic")]
    for policy, row in table.items():
        low = min(row[names[i]] for i in synthetic)
        lines.append(f"| {policy} | " + " | ".join(f"{row[n]:.3f}" for n in names) + f" | {low:.3f} |")
    (out / "policies.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    {"dump": dump, "dump-train": dump_train, "dump-voices": dump_voices, "score": score}[sys.argv[1]](*sys.argv[2:])
