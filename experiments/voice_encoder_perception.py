"""Emotion heard through a speaker encoder trained on real speech: held-out voices and real read speech.

The speech model's perception has heard synthetic voices only, and a real voice lands outside them (the
`real` report). This experiment asks whether a part trained on thousands of real voices places real and
synthetic speech in one space where the corpus's emotions can be read: resemblyzer's speaker encoder
(Apache-2.0; its weights ship inside the package, ``pip install --no-deps resemblyzer``; the package itself
is not imported, only its weights are read). The encoder's input is rebuilt here with the project's own
signal code: a 40-band Slaney mel power spectrogram (25-ms Hann window, 10-ms hop, centred), 1.6-s partial
utterances 1.3 times a second, each through the 3-layer LSTM and a rectified linear layer, L2-normalised,
averaged and normalised again. Each 10-s window (the pipeline's windows, every 5 s) is first brought to
-30 dBFS, so the recording's level cannot decide the emotion.

The emotion is read by linear discriminant analysis (shrinkage covariance) fitted on the **train** texts of
the train speakers, and scored on the **val** texts of the val speakers (voices never heard in training),
as recorded and through the changes of :func:`emogesture.audio.wave_augment.recording_changes`; a window
is trusted when its Mahalanobis distance to the nearest class mean lies within the 0.99 quantile of those
val windows'. The real read
speech of :mod:`emogesture.data.real_speech` is a check, never used for a choice.

With ``--real-voices N`` the fit also takes, from each of the real training voices
(:data:`emogesture.data.real_speech.TRAINING_VOICES`, other people than the checks'), N windows per
emotion given that emotion's corpus prosody (:func:`emogesture.data.synthetic.speech.give_prosody`, the
factor table plus a take's random deviation; neutral: only the deviation), labelled with it. The report
then also reads the check recordings given each emotion's prosody (as ``real_voice_emotions.py`` does):
the share heard as the emotion given.

Usage: python experiments/voice_encoder_perception.py CACHE OUT_DIR [--every N] [--augment K] [--real-voices N]
"""

from __future__ import annotations

import argparse
import importlib.util
import json
from pathlib import Path

import numpy as np
import torch
from sklearn.discriminant_analysis import LinearDiscriminantAnalysis
from tqdm import tqdm

from emogesture.audio import TARGET_SAMPLE_RATE, load_audio
from emogesture.audio.mel import librosa_mel_banks
from emogesture.audio.stft import stft_power
from emogesture.audio.wave_augment import augment_waveform, recording_changes
from emogesture.audio.windows import WINDOW_SECONDS, window_starts
from emogesture.data.beat import EMOTIONS
from emogesture.data.cache import open_cache
from emogesture.data.real_speech import RECORDINGS, TRAINING_VOICES, load_real_recording, load_training_voice
from emogesture.data.synthetic.corpus import CorpusConfig
from emogesture.data.synthetic.factors import emotion_prosody
from emogesture.data.synthetic.speech import give_prosody
from emogesture.pipeline.speech import SpeechLatentEncoder

PARTIAL_FRAMES, PARTIAL_RATE, MIN_COVERAGE = 160, 1.3, 0.75
TARGET_DBFS = -30.0
TRUST_QUANTILE = 0.99


class SpeakerEncoder(torch.nn.Module):
    """mel frames ``[B, 160, 40]`` -> embeddings ``[B, 256]`` (non-negative, unit length)."""

    def __init__(self) -> None:
        super().__init__()
        self.lstm = torch.nn.LSTM(40, 256, 3, batch_first=True)
        self.linear = torch.nn.Linear(256, 256)

    def forward(self, mels: torch.Tensor) -> torch.Tensor:
        _, (hidden, _) = self.lstm(mels)
        out = torch.relu(self.linear(hidden[-1]))
        return out / out.norm(dim=1, keepdim=True).clamp_min(1e-12)


def load_speaker_encoder() -> SpeakerEncoder:
    """The encoder with resemblyzer's shipped weights (found without importing the package)."""
    spec = importlib.util.find_spec("resemblyzer")
    if spec is None or not spec.submodule_search_locations:
        raise SystemExit("resemblyzer is not installed: pip install --no-deps resemblyzer==0.1.4")
    weights = Path(next(iter(spec.submodule_search_locations))) / "pretrained.pt"
    state = torch.load(weights, map_location="cpu", weights_only=True)["model_state"]
    model = SpeakerEncoder()
    model.load_state_dict({k: v for k, v in state.items() if k.startswith(("lstm.", "linear."))})
    return model.eval()


def mel_frames(wave: np.ndarray) -> np.ndarray:
    """16-kHz waveform ``[N]`` -> mel power frames ``[F, 40]`` (no log: the encoder was trained on power)."""
    power = stft_power(torch.from_numpy(np.asarray(wave, np.float64)), n_fft=400, hop_length=160).numpy()
    return (power @ librosa_mel_banks(TARGET_SAMPLE_RATE, 400, 40).T).astype(np.float32)


def at_level(wave: np.ndarray, dbfs: float = TARGET_DBFS) -> np.ndarray:
    """``wave`` scaled so that its RMS is ``dbfs`` (silence stays silence)."""
    rms = float(np.sqrt(np.mean(np.square(wave, dtype=np.float64))))
    return wave if rms < 1e-6 else wave * (10 ** (dbfs / 20) / rms)


@torch.no_grad()
def embed(model: SpeakerEncoder, wave: np.ndarray) -> np.ndarray:
    """One window's embedding ``[256]``: the normalised mean of its partial utterances'."""
    mels = mel_frames(at_level(wave))
    step = max(1, int(round(TARGET_SAMPLE_RATE / PARTIAL_RATE / 160)))
    starts = list(range(0, max(1, len(mels) - PARTIAL_FRAMES + step + 1), step))
    last = len(mels) - starts[-1]
    if last < MIN_COVERAGE * PARTIAL_FRAMES and len(starts) > 1:
        starts.pop()
    padded = np.pad(mels, ((0, max(0, starts[-1] + PARTIAL_FRAMES - len(mels))), (0, 0)))
    batch = torch.from_numpy(np.stack([padded[s: s + PARTIAL_FRAMES] for s in starts]))
    mean = model(batch).mean(0)
    return (mean / mean.norm().clamp_min(1e-12)).numpy()


def windows(wave: np.ndarray) -> list[np.ndarray]:
    """The pipeline's 10-s windows of a recording, every 5 s (the last aligned with its end)."""
    n = int(WINDOW_SECONDS * TARGET_SAMPLE_RATE)
    return [wave[int(round(s * TARGET_SAMPLE_RATE)):][:n] for s in window_starts(len(wave) / TARGET_SAMPLE_RATE)]


def real_voice_windows(embed_window, per_emotion: int, rng: np.random.Generator):
    """Embeddings ``[V * 8 * per_emotion, 256]`` and emotions of the real training voices' windows, each given
    an emotion's corpus prosody plus a take's deviation (drawn from ``rng``)."""
    n = int(WINDOW_SECONDS * TARGET_SAMPLE_RATE)
    scale = CorpusConfig().emotion_prosody_scale
    xs, ys = [], []
    for voice in TRAINING_VOICES:
        wave = load_training_voice(voice)
        for k, emotion in enumerate(tqdm(EMOTIONS, desc=voice, leave=False)):
            for _ in range(per_emotion):
                start = int(rng.integers(len(wave) - 3 * n // 2))
                prosody = emotion_prosody(emotion, scale, rng)
                xs.append(embed_window(give_prosody(wave[start: start + 3 * n // 2], prosody, rng)[:n].astype(np.float64)))
                ys.append(k)
    return np.array(xs), np.array(ys)


def takes_of(cache, split: str, held_out_voices: bool) -> list[tuple[str, int]]:
    """(take, emotion) of a split: the train speakers' takes for train, else the voices never trained on."""
    train_speakers = set(cache.split("train").speaker_id.tolist())
    part = cache.split(split)
    keep = {}
    for take, speaker, emotion in zip(part.takes, part.speaker_id.tolist(), part.emotion.tolist()):
        if (speaker not in train_speakers) == held_out_voices:
            keep[take] = int(emotion)
    return sorted(keep.items())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("cache", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--every", type=int, default=1, help="every N-th take of each split (1: all)")
    ap.add_argument("--augment", type=int, default=0,
                    help="also fit on this many copies of each train window through wave_augment's random "
                         "recording conditions (seeded; 0: clean windows only)")
    ap.add_argument("--with-speech", default="",
                    help="a speech model: read the emotion from its emotion latent beside the embedding (each "
                         "feature standardised on the fitting windows)")
    ap.add_argument("--real-voices", type=int, default=0,
                    help="also fit on this many windows per emotion of each real training voice, given that "
                         "emotion's corpus prosody (0: none)")
    args = ap.parse_args()
    model = load_speaker_encoder()
    speech = SpeechLatentEncoder.from_run(args.with_speech) if args.with_speech else None

    def features(wave: np.ndarray) -> np.ndarray:
        """One window's features: the speaker embedding, and the speech model's emotion latent if asked."""
        x = embed(model, wave)
        if speech is not None:
            enc, _ = speech.encode(wave.astype(np.float32), TARGET_SAMPLE_RATE, 10.0, parts=("emotion",))
            x = np.concatenate([x, enc.emotion[0]])
        return x
    cache = open_cache(args.cache)
    root = Path(cache.manifest["root"])
    rng, augment_rng = np.random.default_rng(0), np.random.default_rng(1)

    def load(takes: list[tuple[str, int]]) -> list[tuple[np.ndarray, int]]:
        """(waveform float32, emotion) of each take, read once for every change below."""
        return [(load_audio(root / "wave16k" / f"{take}.wav")[0], emotion) for take, emotion in takes]

    def encode(recordings, change=lambda w: w, copies=0):
        xs, ys = [], []
        for wave, emotion in tqdm(recordings, unit="take", leave=False):
            for w in windows(change(wave.astype(np.float64))):
                for k in range(1 + copies):
                    xs.append(features(w if k == 0 else augment_waveform(w, augment_rng)[0].astype(np.float64)))
                    ys.append(emotion)
        return np.array(xs), np.array(ys)

    train = takes_of(cache, "train", held_out_voices=False)[:: args.every]
    val = takes_of(cache, "val", held_out_voices=True)[:: args.every]
    if not train or not val:
        raise SystemExit(f"{args.cache}: needs train takes of train speakers and val takes of voices never trained on "
                         "(prepare --set split_source=csv+actor)")
    x_train, y_train = encode(load(train), copies=args.augment)
    if args.real_voices:
        x_real, y_real = real_voice_windows(features, args.real_voices, np.random.default_rng(2))
        x_train, y_train = np.concatenate([x_train, x_real]), np.concatenate([y_train, y_real])
    centre, spread = (x_train.mean(0), x_train.std(0) + 1e-8) if speech is not None else (0.0, 1.0)
    lda = LinearDiscriminantAnalysis(solver="lsqr", shrinkage="auto").fit((x_train - centre) / spread, y_train)
    precision = np.linalg.inv(lda.covariance_)

    def heard_as(x: np.ndarray) -> np.ndarray:
        return lda.predict((x - centre) / spread)

    def distance(x: np.ndarray) -> np.ndarray:
        d = (x - centre)[:, None, :] / spread - lda.means_[None]
        return np.sqrt(np.einsum("wkd,de,wke->wk", d, precision, d).min(1))

    rows, threshold, val_waves = {}, None, load(val)
    for name, change in {"as recorded": lambda w: w, **recording_changes(rng)}.items():
        x, y = encode(val_waves, lambda w, c=change: np.asarray(c(w), np.float64))
        heard = heard_as(x)
        dist = distance(x)
        if threshold is None:  # the trust threshold: the as-recorded val windows' quantile
            threshold = float(np.quantile(dist, TRUST_QUANTILE))
        rows[name] = {"windows": len(y), "perceived_correctly": float(np.mean(heard == y)),
                      "trusted": float(np.mean(dist <= threshold)),
                      "perceived": {EMOTIONS[k]: float(np.mean(heard == k)) for k in np.unique(heard)}}
    real, real_waves = {}, {rec.name: load_real_recording(rec).astype(np.float64) for rec in RECORDINGS}
    for rec in RECORDINGS:
        x = np.array([features(w) for w in windows(real_waves[rec.name])])
        heard, dist = [EMOTIONS[k] for k in heard_as(x)], distance(x)
        real[rec.name] = {"windows": len(x), "heard": heard, "trusted": (dist <= threshold).tolist(),
                          "distance_over_threshold": np.round(dist / threshold, 2).tolist()}
    given = {}
    if args.real_voices:
        scale = CorpusConfig().emotion_prosody_scale
        for k, emotion in enumerate(EMOTIONS):
            x = np.array([features(w) for i, wave in enumerate(real_waves.values())
                          for w in windows(give_prosody(wave, emotion_prosody(emotion, scale),
                                                        np.random.default_rng([k, i])).astype(np.float64))])
            given[emotion] = float(np.mean(heard_as(x) == k))
    heard_all = [h for r in real.values() for h in r["heard"]]
    trusted_all = [t for r in real.values() for t in r["trusted"]]
    result = {"train_windows": len(y_train), "augmented_copies": args.augment, "val_takes": len(val),
              "trust_threshold": threshold, "rows": rows,
              "real": real, "real_heard_as_neutral": float(np.mean([h == "neutral" for h in heard_all])),
              "real_trusted": float(np.mean(trusted_all)), "real_voices": args.real_voices,
              "real_given_emotion_heard": given}
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "voice_encoder_perception.json").write_text(json.dumps(result, indent=1) + "\n")
    augmented = f"; each window also through {args.augment} random recording conditions" if args.augment else ""
    if args.real_voices:
        augmented += (f"; and {args.real_voices} windows per emotion of each of the {len(TRAINING_VOICES)} real training "
                      "voices, given that emotion's corpus prosody")
    lines = ["# Emotion read from a speaker encoder trained on real speech (val, voices never trained on)", "",
             f"Linear discriminant analysis on the embeddings of {len(y_train)} train windows (train texts, train "
             f"speakers{augmented}); val: {len(val)} takes of the val texts spoken by the val speakers. "
             "Trusted: the distance to "
             "the nearest emotion mean within the 0.99 quantile of the as-recorded val windows'.", "",
             "| audio | windows | perceived emotion correct | trusted | most perceived |", "|---|---|---|---|---|"]
    for name, r in rows.items():
        top = ", ".join(f"{k} {v:.2f}" for k, v in sorted(r["perceived"].items(), key=lambda kv: -kv[1])[:3])
        lines.append(f"| {name} | {r['windows']} | {r['perceived_correctly']:.3f} | {r['trusted']:.3f} | {top} |")
    lines += ["", "| real read speech | windows | heard | trusted | distance / threshold |", "|---|---|---|---|---|"]
    for name, r in real.items():
        lines.append(f"| {name} | {r['windows']} | {', '.join(r['heard'])} | {sum(r['trusted'])} | "
                     f"{', '.join(f'{d:.2f}' for d in r['distance_over_threshold'])} |")
    lines.append(f"| **all** | {len(heard_all)} | neutral {result['real_heard_as_neutral']:.0%} | "
                 f"{result['real_trusted']:.0%} | |")
    if given:
        lines += ["", "The real read speech given each emotion's corpus prosody (neutral: as given, level included), "
                  "share heard as that emotion:", "", "| " + " | ".join(EMOTIONS) + " | mean of the seven |",
                  "|" + "---|" * (len(EMOTIONS) + 1),
                  "| " + " | ".join(f"{given[e]:.2f}" for e in EMOTIONS)
                  + f" | {np.mean([given[e] for e in EMOTIONS if e != 'neutral']):.2f} |"]
    (args.out / "voice_encoder_perception.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
