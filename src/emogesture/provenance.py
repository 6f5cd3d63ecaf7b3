"""Which cache splits a model touched: the splits its weights were fitted on, the calibrations measured on a
split, and whether a gesture model was trained on a given speech model; evaluations refuse a split a model
trained on and say which calibrations used it."""

from __future__ import annotations

import json
from pathlib import Path

from emogesture.checkpoints import LoadedModel
from emogesture.errors import InputFileError


def trained_splits(loaded: LoadedModel) -> list[str]:
    """The cache splits a model's weights were fitted on: stored in its file (``metadata.train_splits``);
    for files written before that was stored, a speech model's ``run.json``, and ``train`` for gesture
    models and extractors (which only ever trained on it)."""
    if loaded.metadata.train_splits is not None:
        return list(loaded.metadata.train_splits)
    if loaded.kind in ("gesture", "extractor"):
        return ["train"]
    try:
        blob = json.loads((Path(loaded.path).parent / "run.json").read_text())
        return list(blob["config"]["train_splits"])
    except (OSError, ValueError, KeyError, TypeError):
        raise InputFileError(loaded.path, "does not record the splits it was trained on (no train_splits, no "
                             "run.json beside it)") from None


def refuse_trained_split(split: str, *models: LoadedModel, purpose: str = "evaluate") -> None:
    """A one-line error when any of ``models`` trained on ``split`` (numbers there would not be held out)."""
    for m in models:
        used = trained_splits(m)
        if split in used:
            raise InputFileError(m.path, f"was trained on the {split} split ({'+'.join(used)}); {purpose} on "
                                 "windows no part of the model saw")


def trained_with(gesture: LoadedModel, speech: LoadedModel) -> bool:
    """Whether ``gesture`` was trained on ``speech``'s network: it names the checksum of ``speech``'s weights file,
    or of the file a perception calibration copied ``speech`` from (the calibration adds its arrays to the file);
    True for a gesture model that names none."""
    want = gesture.metadata.speech_weights_sha256
    info = (speech.metadata.emotion_perception or {}).get("info") or {}
    # (and of the file a front end's read-out was added to: emogesture.train.heard_readout)
    return not want or want in (speech.weights_sha256, info.get("calibrated_from"), info.get("read_out_added_to"))


def calibration_splits(loaded: LoadedModel) -> dict[str, str]:
    """Calibrations stored in a model file and the split each was measured on (its windows are not
    held out for numbers of this model): e.g. ``{"residual_calibration": "val"}``."""
    found = {}
    for key in ("residual_calibration", "emotion_perception", "fallback_style"):
        blob = getattr(loaded.metadata, key, None)
        if isinstance(blob, dict):
            split = blob.get("split", (blob.get("info") or {}).get("split"))
            if split:
                found[key] = str(split)
    return found


def split_use(split: str, models: dict[str, LoadedModel]) -> dict:
    """What the models (name -> loaded) did with ``split``; refuses a split any of them trained on.
    ``held_out`` is True only when no model trained or calibrated on it."""
    for m in models.values():
        refuse_trained_split(split, m)
    calibrated = {f"{name}: {key}": s for name, m in models.items() for key, s in calibration_splits(m).items()
                  if s == split}
    return {"split": split, "trained_on": {name: trained_splits(m) for name, m in models.items()},
            "calibrated_on_it": sorted(calibrated), "held_out": not calibrated}
