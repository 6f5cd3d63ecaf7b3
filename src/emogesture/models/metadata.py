"""What a model file stores beside its weights and architecture: one typed record per model kind.

A model's JSON keeps these under ``extra`` (the name of the section in every file written so far). Each
field is optional, since a file holds what its training knew (a gesture model trained without a speech
model names none); :meth:`ModelMetadata.require` gives a one-line error naming the file when a reader needs a
field the file lacks. Keys a file holds that this version does not know are kept in ``other`` and written
back unchanged, so a file of a newer version survives a round trip through this one.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, ClassVar

from emogesture.config import from_dict
from emogesture.errors import ConfigError


@dataclass
class ModelMetadata:
    """Fields every kind may hold."""

    kind: ClassVar[str] = ""
    #: optimiser steps the weights have had
    step: int | None = None
    #: the cache splits the weights were fitted on (held-out numbers never come from these)
    train_splits: list[str] | None = None
    #: the emotion names of the label indices
    emotions: list[str] | None = None
    #: keys of the stored section this version does not know, kept as they are
    other: dict[str, Any] = field(default_factory=dict)

    def require(self, name: str, where: object = "model file") -> Any:
        """The value of field ``name``; a :class:`ConfigError` naming ``where`` when the file lacks it."""
        value = getattr(self, name)
        if value is None:
            raise ConfigError(f"{where}: the {self.kind} model file holds no {name!r} (it was written without it)")
        return value

    def to_dict(self) -> dict[str, Any]:
        """The JSON section: set fields only, then the unknown keys as read."""
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)
               if f.name != "other" and getattr(self, f.name) is not None}
        return {**out, **self.other}

    @classmethod
    def from_dict(cls, stored: dict[str, Any]) -> "ModelMetadata":
        if not isinstance(stored, dict):
            raise ConfigError("the stored 'extra' section is not a mapping")
        names = {f.name for f in dataclasses.fields(cls)} - {"other"}
        known = from_dict(cls, {k: v for k, v in stored.items() if k in names}, "extra")
        return dataclasses.replace(known, other={k: v for k, v in stored.items() if k not in names})

    def replace(self, **changes: Any) -> "ModelMetadata":
        return dataclasses.replace(self, **changes)


@dataclass
class SpeechMetadata(ModelMetadata):
    """A speech model's: its training speakers, the fbank normalisation, how its cache was prepared and,
    once calibrated, its emotion perception (:class:`emogesture.models.perception.EmotionPerception`; its arrays are tensors of the weights file)."""

    kind: ClassVar[str] = "speech"
    speakers: list[int] | None = None
    fbank_mean: float | None = None
    fbank_std: float | None = None
    prepare_config: dict[str, Any] | None = None
    emotion_perception: dict[str, Any] | None = None


@dataclass
class GestureMetadata(ModelMetadata):
    """A gesture model's: motion normalisation and features, the speech model it trained on (path and
    weights' checksum), the mean emotion latent of each emotion, the residual-noise calibration and the
    style an unfamiliar voice takes (``fallback_style``, :mod:`emogesture.train.fallback_style`)."""

    kind: ClassVar[str] = "gesture"
    motion_mean: list[float] | None = None
    motion_std: list[float] | None = None
    features: dict[str, Any] | None = None
    variant: str | None = None
    fps: int | None = None
    speech_model: str | None = None
    speech_weights_sha256: str | None = None
    emotion_latent_means: dict[str, list[float]] | None = None
    residual_calibration: dict[str, Any] | None = None
    fallback_style: dict[str, Any] | None = None


@dataclass
class ExtractorMetadata(ModelMetadata):
    """The motion feature extractor's: the motion normalisation and features it reads."""

    kind: ClassVar[str] = "extractor"
    motion_mean: list[float] | None = None
    motion_std: list[float] | None = None
    features: dict[str, Any] | None = None


METADATA: dict[str, type[ModelMetadata]] = {m.kind: m for m in (SpeechMetadata, GestureMetadata, ExtractorMetadata)}


def metadata_of(kind: str, stored: dict[str, Any] | ModelMetadata | None) -> ModelMetadata:
    """The typed record of ``kind`` from a stored section (or a record of the right kind, returned as is)."""
    cls = METADATA.get(kind, ModelMetadata)
    if isinstance(stored, ModelMetadata):
        if not isinstance(stored, cls):
            raise ConfigError(f"{type(stored).__name__} given for a {kind} model")
        return stored
    return cls.from_dict(stored or {})
