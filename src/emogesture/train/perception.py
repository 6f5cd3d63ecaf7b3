"""Calibrating a speech model's emotion perception (:mod:`emogesture.models.perception`): class means and spread
on the training windows, trust thresholds and the read-out's temperature on held-out windows, optionally the
means of real voices given the corpus's emotions and of training takes heard through recording conditions (a
telephone band, quieter, in noise; ``emogesture calibrate speech``)."""

from __future__ import annotations

from os import PathLike
from pathlib import Path

import numpy as np
from tqdm import tqdm

from emogesture.audio import load_audio
from emogesture.audio.wave_augment import add_noise, telephone
from emogesture.checkpoints import check_model_output, load_model, save_model, stored_weights_dtype
from emogesture.provenance import refuse_trained_split, trained_splits
from emogesture.data.cache import open_cache
from emogesture.data.real_speech import TRAINING_VOICES, training_voice_emotions
from emogesture.data.synthetic.corpus import corpus_emotion_prosody_scale
from emogesture.errors import EmogestureError
from emogesture.eval.split_latents import encode_split
from emogesture.models.perception import EmotionPerception, LatentRange, class_means, log_softmax
from emogesture.pipeline.speech import EncodedWindows, SpeechLatentEncoder
from emogesture.types import EMOTIONS

TRUST_QUANTILE = 0.99
REAL_STRETCHES = 10  # per real voice, when the perception learns real voices' emotions
#: the recording conditions the train takes can be heard through for the read-out's condition means
#: (:func:`condition_latents`): a telephone band (300-3400 Hz, 8 kHz, mu-law), a recording quieter by
#: :data:`QUIETER_DB` and one in white noise at :data:`NOISE_SNR_DB` (each take's level and SNR drawn)
CONDITIONS = ("telephone", "quieter", "noisy")
QUIETER_DB = (6.0, 14.0)  # dB below the take's own level, drawn uniformly
NOISE_SNR_DB = (8.0, 16.0)  # white noise's signal-to-noise ratio, drawn uniformly


def fit_perception(train: EncodedWindows, emotions: np.ndarray, speakers: np.ndarray, held_out: EncodedWindows,
                   quantile: float = TRUST_QUANTILE, held_out_emotions: np.ndarray | None = None,
                   real: EncodedWindows | None = None, real_emotions: np.ndarray | None = None,
                   band: EncodedWindows | None = None,
                   band_emotions: np.ndarray | None = None) -> EmotionPerception:
    """Emotion means (by ``emotions`` ``[N]``, indices into ``EMOTIONS``) and speaker means (by
    ``speakers`` ``[N]``) with their within-class spread from training windows; each threshold is the
    ``quantile`` of the held-out windows' distances; with the held-out windows' emotions ``[M]``, the
    read-out's temperature is fitted on those within the range (:func:`fit_temperature`). With ``real``
    windows of real voices given the corpus's emotions (``real_emotions`` ``[R]``), each of their emotions
    gets a second mean beside the corpus's (the spread stays the training windows'). With ``band`` windows
    (training speech heard through a telephone band, emotions ``band_emotions`` ``[B]``), each of their
    emotions gets a mean that only the read-out uses (:meth:`EmotionPerception.read_range`)."""
    emotions, speakers = np.asarray(emotions), np.asarray(speakers)
    present = sorted(set(emotions.tolist()))
    if EMOTIONS.index("neutral") not in present:
        raise EmogestureError("emotion perception needs neutral training windows")
    labels = [EMOTIONS[k] for k in present]
    emotion = LatentRange.fit(train.emotion, emotions)
    if real is not None:
        heard, real_means = class_means(real.emotion, real_emotions)
        emotion.means = np.concatenate([emotion.means, real_means])
        labels += [EMOTIONS[k] for k in heard]
    voice = LatentRange.fit(train.style, speakers)
    d_emotion, d_voice = emotion.nearest(held_out.emotion), voice.nearest(held_out.style)
    emotion.threshold = float(np.quantile(d_emotion, quantile))
    voice.threshold = float(np.quantile(d_voice, quantile))
    info = {"train_windows": int(len(emotions)), "held_out_windows": int(len(d_emotion)), "quantile": float(quantile),
            "held_out_distance_median": {"emotion": float(np.median(d_emotion)), "voice": float(np.median(d_voice))}}
    if real is not None:
        info["real_windows"] = int(len(real_emotions))
    perception = EmotionPerception(labels, emotion, voice, info)
    if band is not None:
        heard, perception.band_means = class_means(np.asarray(band.emotion, np.float64), band_emotions)
        perception.band_labels = [EMOTIONS[k] for k in heard]
        info["band_windows"] = int(len(band_emotions))
    if held_out_emotions is not None:
        inside = d_emotion <= emotion.threshold
        perception.temperature = fit_temperature(perception, held_out.emotion[inside], held_out.emotion_logits[inside],
                                                 np.asarray(held_out_emotions)[inside])
        info["temperature_windows"] = int(inside.sum())
    return perception


def fit_temperature(perception: EmotionPerception, emotion: np.ndarray, logits: np.ndarray,
                    labels: np.ndarray) -> float:
    """The temperature (0.5-1000) that minimises the mean negative log-likelihood of ``labels`` ``[M]``
    (indices into ``EMOTIONS``) under the read-out's summed log-probabilities of windows within the range
    (emotion latents ``[M, D]``, head logits ``[M, 8]``); 1 without windows."""
    from scipy.optimize import minimize_scalar

    if len(labels) == 0:
        return 1.0
    summed = perception.summed(emotion, logits)
    rows = np.arange(len(labels))

    def nll(log_t: float) -> float:
        lp = log_softmax(summed / np.exp(log_t))[rows, labels]
        return float(-np.maximum(lp, -1e3).mean())  # a label the means never saw: a bounded penalty

    best = minimize_scalar(nll, bounds=(np.log(0.5), np.log(1000.0)), method="bounded")
    return float(np.exp(best.x))


def calibrate_perception_run(run: str | PathLike[str], cache_dir: str | PathLike[str], out: str | PathLike[str],
                             split: str = "val", quantile: float = TRUST_QUANTILE, overwrite: bool = False,
                             real_voices: list[str] | tuple[str, ...] = (),
                             real_stretches: int = REAL_STRETCHES,
                             condition_means: list[str] | tuple[str, ...] = ()) -> EmotionPerception:
    """Write a copy of the speech model of ``run`` to ``out`` with its emotion perception: means and
    spread from the cache's ``train`` windows, the threshold from ``split`` (which the model must not
    have trained on; its run records the training splits). With ``real_voices`` (names of
    :data:`emogesture.data.real_speech.TRAINING_VOICES`), also means of those real voices given each of the
    synthetic corpus's emotions (``real_stretches`` 10-s stretches of each; module docstring). With
    ``condition_means`` (names of :data:`CONDITIONS`), also each emotion's mean of the ``train`` takes heard
    through each of those recording conditions, for the read-out only (:func:`condition_latents`)."""
    if not 0.5 <= quantile < 1.0:
        raise EmogestureError(f"quantile {quantile}: must be in [0.5, 1)")
    if split in ("train", "test"):
        raise EmogestureError(f"--split {split}: calibrate on held-out windows that are not the test split (e.g. val)")
    unknown = [v for v in real_voices if v not in TRAINING_VOICES]
    if unknown:
        raise EmogestureError(f"real voice {unknown[0]!r}: unknown; known: {', '.join(TRAINING_VOICES)}")
    unknown = [c for c in condition_means if c not in CONDITIONS]
    if unknown:
        raise EmogestureError(f"condition {unknown[0]!r}: unknown; known: {', '.join(CONDITIONS)}")
    check_model_output(out, overwrite)
    loaded = load_model(run, "speech")
    trained_on = trained_splits(loaded)
    refuse_trained_split(split, loaded, purpose="calibrate")
    encoder = SpeechLatentEncoder(loaded)
    cache = open_cache(cache_dir)
    train = encode_split(encoder, cache, "train")
    held = encode_split(encoder, cache, split)
    windows = cache.split("train")
    held_emotions = cache.split(split).emotion
    real = real_emotions = None
    if real_voices:
        root = Path(cache.manifest["root"])
        try:
            scale = corpus_emotion_prosody_scale(root)
        except (OSError, KeyError, ValueError) as e:
            raise EmogestureError(f"{root}: real voices are given the emotions of a synthetic corpus, and this "
                                  f"cache's corpus is not one ({e})") from None
        real, real_emotions = real_voice_latents(encoder, list(real_voices), real_stretches, scale)
    band = band_emotions = None
    if condition_means:
        band, band_emotions = condition_latents(encoder, cache, tuple(condition_means))
    perception = fit_perception(train, windows.emotion, windows.speaker_id, held, quantile,
                                held_out_emotions=held_emotions, real=real, real_emotions=real_emotions,
                                band=band, band_emotions=band_emotions)
    perception.info.update(split=split, trained_on=trained_on)
    if real_voices:
        perception.info.update(real_voices=list(real_voices), real_stretches=int(real_stretches))
    if condition_means:
        perception.info["condition_means"] = list(condition_means)
    # the weights file a gesture model trained on this network names (the file's checksum changes here)
    before = (loaded.metadata.emotion_perception or {}).get("info") or {}
    perception.info["calibrated_from"] = before.get("calibrated_from", loaded.weights_sha256)
    record, tensors = perception.to_state()
    metadata = loaded.metadata.replace(train_splits=trained_on, emotion_perception=record)
    save_model(out, "speech", loaded.model, loaded.config, metadata, weights_dtype=stored_weights_dtype(loaded),
               tensors=tensors)
    return perception


def condition_latents(encoder: SpeechLatentEncoder, cache, conditions: tuple[str, ...] = ("telephone",),
                      split: str = "train", hop_seconds: float = 8.0,
                      seed: int = 0) -> tuple[EncodedWindows, np.ndarray]:
    """Every take of a cache's ``split`` heard through each of ``conditions`` (:data:`CONDITIONS`; a quieter or
    noisy take's level or SNR drawn from ``seed``), in 10-s windows every ``hop_seconds`` -> their windows'
    emotion latents and logits, and each window's emotion ``[N]``."""
    root = Path(cache.manifest["root"])
    rng = np.random.default_rng(seed)
    change = {"telephone": telephone,
              "quieter": lambda w: w * 10 ** (-rng.uniform(*QUIETER_DB) / 20),
              "noisy": lambda w: add_noise(w, rng, rng.uniform(*NOISE_SNR_DB), "white")}
    encoded, emotions = [], []
    takes = cache.split(split).take_emotions()
    for condition in conditions:
        for take, emotion in tqdm(takes.items(), total=len(takes), desc=f"train takes heard {condition}",
                                  unit="take", disable=None):
            wave, _ = load_audio(root / "wave16k" / f"{take}.wav")  # a clear one-line error when it is missing
            heard = np.asarray(change[condition](wave), np.float32)
            enc = encoder.encode(heard, hop_seconds=hop_seconds, parts=("emotion",))[0]
            encoded.append(enc)
            emotions += [emotion] * len(enc.emotion)
    return concat_windows(encoded), np.asarray(emotions)


def concat_windows(parts: list[EncodedWindows]) -> EncodedWindows:
    """The windows of several :class:`EncodedWindows` one after another (their stored latents and logits)."""
    return EncodedWindows(*(np.concatenate([getattr(e, k) for e in parts]) for k in EncodedWindows.stored))


def real_voice_latents(encoder: SpeechLatentEncoder, names: list[str], stretches: int,
                       prosody_scale: float) -> tuple[EncodedWindows, np.ndarray]:
    """The real training voices ``names`` given each emotion at the corpus's ``prosody_scale``
    (:func:`emogesture.data.real_speech.training_voice_emotions`) -> their encoded windows (emotion latents and
    logits; one 10-s window each) and emotions ``[N]``."""
    waves, emotions = training_voice_emotions(names, stretches, prosody_scale)
    encoded = [encoder.encode(w, parts=("emotion",))[0] for w in waves]
    first = EncodedWindows(*(np.concatenate([getattr(e, k)[:1] for e in encoded]) for k in EncodedWindows.stored))
    return first, emotions
