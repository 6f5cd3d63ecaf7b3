"""Model files: safetensors weights + a JSON of config, statistics and version (docs/design.md, 'Conventions').

A model is stored as two files side by side, ``<name>.safetensors`` and ``<name>.json``, saved as one
(see :func:`save_model`: a save killed at any point leaves the old model or the new one). The JSON
holds the weights' checksum and a checksum of its own content. Loading never unpickles anything and
checks the model kind, the format version and both checksums, with one-line errors naming the file.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np
import torch
from safetensors import SafetensorError
from safetensors import safe_open
from safetensors.torch import save_file
from torch import nn

from emogesture.version import __version__
from emogesture.config import from_dict, to_dict
from emogesture.errors import ConfigError, EmogestureError, InputFileError, OutputExistsError
from emogesture.fileio import atomic_output, fsync_dir
from emogesture.models.generation import GenerationConfig, split_legacy_settings
from emogesture.models.metadata import ModelMetadata, metadata_of

FORMAT = "emogesture-model"
FORMAT_VERSION = 2
READABLE_VERSIONS = (1, 2)  # 1: before the content checksum (read without it)
#: names of the arrays a weights file may store beside the network's (save_model's ``tensors``)
STORED_ARRAY_PREFIXES = ("emotion_perception.",)


@dataclass
class ModelKind:
    """How to rebuild one kind of model from its stored config."""

    config_cls: type
    build: Callable[[Any], nn.Module]


_KINDS: dict[str, ModelKind] = {}


def register_kind(name: str, config_cls: type, build: Callable[[Any], nn.Module]) -> None:
    _KINDS[name] = ModelKind(config_cls, build)


def _builtin_kinds() -> None:
    if _KINDS:
        return
    from emogesture.models.extractor import ExtractorConfig, MotionFeatureExtractor
    from emogesture.models.speech import SpeechDisentangler, SpeechModelConfig

    register_kind("speech", SpeechModelConfig, SpeechDisentangler)
    register_kind("extractor", ExtractorConfig, MotionFeatureExtractor)
    from emogesture.models.gesture import GestureModel, GestureModelConfig

    register_kind("gesture", GestureModelConfig, GestureModel)


@dataclass
class LoadedModel:
    model: nn.Module
    config: Any
    #: what the file stores beside weights and config (a :class:`ModelMetadata` of the model's kind)
    metadata: ModelMetadata
    path: Path
    #: what the file says it holds: ``speech``, ``gesture`` or ``extractor`` ("" for a model not read from a file)
    kind: str = ""
    #: the SHA-256 of the weights file, as its JSON records it ("" for a model not read from a file)
    weights_sha256: str = ""
    #: how a gesture model generates (the ``generation`` section of its JSON); None for other kinds
    generation: GenerationConfig | None = None
    #: arrays the weights file stores beside the network's (a calibration's, by name: :func:`save_model`)
    tensors: dict[str, np.ndarray] = field(default_factory=dict)


def file_sha256(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _atomic_write(path: Path, write: Callable[[Path], None]) -> None:
    """Write through :func:`emogesture.fileio.atomic_output` (replacing ``path``): temporary file, fsync, rename."""
    with atomic_output(path, overwrite=True) as tmp:
        write(tmp)


def check_model_output(path: str | PathLike[str], overwrite: bool = False, name: str = "model") -> None:
    """Refuse to write a model where one exists (either file of the pair), unless ``overwrite``."""
    if not overwrite:
        for p in model_paths(path, name):
            if p.exists():
                raise OutputExistsError(p)


def write_text_atomic(path: str | PathLike[str], text: str) -> Path:
    """Write a text file (a report, a JSON) through a temporary file and a rename."""
    path = Path(path)
    _atomic_write(path, lambda tmp: tmp.write_text(text))
    return path


def model_paths(path: str | PathLike[str], name: str = "model") -> tuple[Path, Path]:
    """``(weights, meta)`` paths for a run folder, a ``.json`` or a ``.safetensors`` path."""
    p = Path(path)
    if p.suffix in (".json", ".safetensors"):
        return p.with_suffix(".safetensors"), p.with_suffix(".json")
    return p / f"{name}.safetensors", p / f"{name}.json"


_FLOAT_TYPES = {"F16": torch.float16, "BF16": torch.bfloat16, "F32": torch.float32, "F64": torch.float64}


def stored_weights_dtype(loaded: LoadedModel) -> torch.dtype | None:
    """The floating-point type ``loaded``'s file stores its weights in where it is not the model's own (a
    bundle's ``torch.float16``), else None. A calibration saves its copy in it, so that the weights keep their
    bytes and checksum, and a gesture model trained on them still names them."""
    weights = model_paths(loaded.path)[0]
    if not weights.is_file():
        weights = pending_weights(weights)
    own = loaded.model.state_dict()
    with safe_open(str(weights), framework="pt", device="cpu") as f:
        for key in f.keys():
            stored = _FLOAT_TYPES.get(f.get_slice(key).get_dtype())
            if stored is not None and key in own:
                return None if stored == own[key].dtype else stored
    return None


def pending_weights(weights: Path) -> Path:
    """Where a save keeps the new weights until its JSON is in place (see :func:`save_model`)."""
    return weights.with_name(f".{weights.name}.pending")


def content_checksum(meta: dict) -> str:
    """SHA-256 of what a model file means: its kind, config, stored data (``extra``) and the weights'
    own checksum, as canonical JSON. Stored as ``checksum_sha256``; any edit of the JSON is refused."""
    blob = {k: meta.get(k) for k in ("kind", "config", "extra", "weights_sha256")}
    if "generation" in meta:  # files written before the section existed keep their checksum
        blob["generation"] = meta["generation"]
    return hashlib.sha256(json.dumps(blob, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def save_model(
    path: str | PathLike[str],
    kind: str,
    model: nn.Module,
    config: Any,
    metadata: ModelMetadata | dict | None = None,
    *,
    name: str = "model",
    overwrite: bool = True,
    weights_dtype: torch.dtype | None = None,
    generation: GenerationConfig | None = None,
    tensors: dict[str, np.ndarray] | None = None,
) -> Path:
    """Write ``model``'s weights and ``{kind, config, extra, version}``; returns the JSON path.

    ``metadata`` (a :class:`ModelMetadata` of ``kind``, or its fields as a mapping: normalisation
    statistics, label names, per-class mean latents, ...) is stored as the ``extra`` section; ``generation``, a gesture model's generation
    settings. ``weights_dtype`` (e.g. ``torch.float16``) stores floating-point
    tensors in that type (they are cast back to the model's type when loaded). ``tensors``: arrays stored
    in the weights file beside the network's, as they are (a calibration's, e.g. the emotion perception's
    ``emotion_perception.*``; their names must begin with a prefix of :data:`STORED_ARRAY_PREFIXES`); a
    load gives them back in :attr:`LoadedModel.tensors`.

    The pair is replaced as one: the new weights go to a hidden pending file first, then the JSON (which
    names their checksum) replaces the old one — the moment the new model exists — and only then do the
    weights take their place. A save killed before the JSON's rename leaves the old model; one killed
    after it leaves the new one, whose weights :func:`load_model` finds in the pending file.
    """
    if any(p.dtype == torch.bfloat16 for p in model.parameters()):
        # models train with float32 weights; bf16 ones are an inference pipeline's rounded copies
        raise ValueError(f"{type(model).__name__} holds bf16 weights (runtime.hold_bf16_weights): save the "
                         "float32 model it was loaded from")
    weights, meta_path = model_paths(path, name)
    weights.parent.mkdir(parents=True, exist_ok=True)
    check_model_output(path, overwrite, name)
    state = {k: v.detach().contiguous().cpu() for k, v in model.state_dict().items()}
    if weights_dtype is not None:
        state = {k: v.to(weights_dtype) if v.is_floating_point() else v for k, v in state.items()}
    for key, array in (tensors or {}).items():
        if not key.startswith(STORED_ARRAY_PREFIXES) or key in state:
            raise ValueError(f"stored array {key!r}: its name must begin with one of {STORED_ARRAY_PREFIXES}")
        state[key] = torch.from_numpy(np.ascontiguousarray(array))
    pending = pending_weights(weights)
    # one metadata key only: safetensors writes a dict's keys in an order that changes from run to run,
    # and the same weights must give the same bytes (and checksum)
    for stale in [*weights.parent.glob(f".{meta_path.name}.*.tmp"), *weights.parent.glob(f".{pending.name}.*.tmp")]:
        stale.unlink(missing_ok=True)  # left by a save that was killed (one save per model at a time)
    _atomic_write(pending, lambda tmp: save_file(state, str(tmp), metadata={"format": FORMAT}))
    meta = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "kind": kind,
        "emogesture_version": __version__,
        "config": to_dict(config),
        "extra": metadata_of(kind, metadata).to_dict(),
        "weights": weights.name,
        "weights_sha256": file_sha256(pending),
    }
    if generation is not None:
        meta["generation"] = to_dict(generation)
    meta["checksum_sha256"] = content_checksum(meta)
    _atomic_write(meta_path, lambda tmp: tmp.write_text(json.dumps(meta, indent=1)))
    _commit_pending(pending, weights)
    return meta_path


def _commit_pending(pending: Path, weights: Path) -> None:
    os.replace(pending, weights)
    fsync_dir(weights.parent)


def read_meta(path: str | PathLike[str], kind: str | None = None, name: str = "model") -> dict:
    """The JSON of a model file, checked for format, version, content checksum and (if given) kind."""
    weights, meta_path = model_paths(path, name)
    if not meta_path.is_file():
        raise InputFileError(meta_path, "model file not found")
    try:
        meta = json.loads(meta_path.read_text())
    except UnicodeDecodeError:
        raise InputFileError(meta_path, "not a readable model description (not text)") from None
    except OSError as e:
        raise InputFileError(meta_path, f"cannot read it ({e.strerror or e})") from None
    except ValueError as e:
        raise InputFileError(meta_path, f"not a readable model description ({e.__class__.__name__})") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise InputFileError(meta_path, "not an emogesture model file")
    version = meta.get("format_version")
    if version not in READABLE_VERSIONS:
        raise InputFileError(
            meta_path,
            f"model format version {version} is not supported by this emogesture "
            f"{__version__} (reads {', '.join(map(str, READABLE_VERSIONS))})",
        )
    for key, tp in (("kind", str), ("config", dict), ("extra", dict), ("weights_sha256", str)):
        if not isinstance(meta.get(key), tp):
            raise InputFileError(meta_path, f"model description has no valid {key!r}")
    if version >= 2 and meta.get("checksum_sha256") != content_checksum(meta):
        raise InputFileError(meta_path, "its content does not match its checksum (the JSON was edited or damaged)")
    if kind is not None and meta.get("kind") != kind:
        raise InputFileError(meta_path, f"holds a {meta.get('kind')!r} model, but a {kind!r} model is needed")
    return meta


def _weights_file(weights: Path, want: str) -> Path:
    """The weights that match the JSON: in place, or left pending by a save interrupted after its JSON
    was written (then moved into place when the folder is writable)."""
    try:
        if weights.exists() and file_sha256(weights) == want:
            return weights
        pending = pending_weights(weights)
        if pending.is_file() and file_sha256(pending) == want:
            try:
                _commit_pending(pending, weights)
                return weights
            except OSError:
                return pending
    except OSError as e:
        raise InputFileError(weights, f"cannot read the weights ({e.strerror or e})") from None
    if not weights.is_file():
        raise InputFileError(weights, "model weights not found next to its .json")
    raise InputFileError(weights, "weights do not match their .json (checksum differs); the files are from different saves")


def load_model(path: str | PathLike[str], kind: str, *, name: str = "model", device: str = "cpu") -> LoadedModel:
    """Rebuild a model of ``kind`` from its files and load its weights (eval mode).

    Every problem with the files is an :class:`InputFileError` naming the file: missing, unreadable or
    corrupt JSON or weights, an edited JSON, weights from another save, a stored config that does not
    build or does not fit the weights.
    """
    _builtin_kinds()
    if kind not in _KINDS:
        raise ValueError(f"unknown model kind {kind!r}")
    weights, meta_path = model_paths(path, name)
    meta = read_meta(path, kind, name)
    weights = _weights_file(weights, meta["weights_sha256"])
    try:
        metadata = metadata_of(kind, meta["extra"])
    except ConfigError as e:
        raise InputFileError(meta_path, f"invalid stored data ({e})") from None
    try:
        config, generation = _stored_configs(kind, meta)
        model = _built_empty(_KINDS[kind].build, config)
    except ConfigError as e:
        raise InputFileError(meta_path, f"invalid stored config ({e})") from None
    except (RuntimeError, ValueError, TypeError, AttributeError) as e:
        raise InputFileError(meta_path, f"invalid stored config: the model cannot be built from it "
                             f"({str(e).splitlines()[0] if str(e) else e.__class__.__name__})") from None
    missing, unexpected, tensors = _load_weights(model, weights)
    optional = getattr(model, "optional_state_keys", ())
    if [k for k in missing if k not in optional] or unexpected:
        missing = [k for k in missing if k not in optional]
        raise InputFileError(
            weights, f"weights do not fit the stored config (missing {list(missing)[:3]}, unexpected {list(unexpected)[:3]})"
        )
    if missing:  # optional entries a file from before they existed lacks: their default, zeros
        model.load_state_dict({k: torch.zeros_like(model.get_buffer(k) if k in dict(model.named_buffers())
                                                   else model.get_parameter(k), device="cpu") for k in missing},
                              strict=False, assign=True)
    if empty := _left_empty(model):
        raise EmogestureError(f"{meta_path}: {type(model).__name__} built {empty[0]} from its config on the meta "
                              "device (compute such buffers with device='cpu')")
    try:
        model.to(device).eval()
    except torch.cuda.OutOfMemoryError:
        raise EmogestureError(f"{meta_path}: the model does not fit in the memory of {device}") from None
    return LoadedModel(model, config, metadata, meta_path, kind=str(meta.get("kind", kind)),
                       weights_sha256=str(meta.get("weights_sha256", "")), generation=generation, tensors=tensors)


def _stored_configs(kind: str, meta: dict) -> tuple[Any, GenerationConfig | None]:
    """The architecture config of a model file and, for a gesture model, its generation settings: the
    ``generation`` section, or for files saved before it existed, the settings their config held."""
    if kind != "gesture":
        return from_dict(_KINDS[kind].config_cls, meta["config"]), None
    config, legacy = split_legacy_settings(meta["config"])
    if not isinstance(meta.get("generation", {}), dict):
        raise ConfigError("'generation' is not a mapping")
    return from_dict(_KINDS[kind].config_cls, config), from_dict(GenerationConfig, {**legacy, **meta.get("generation", {})})


def _built_empty(build: Callable[[Any], nn.Module], config: Any) -> nn.Module:
    """``build(config)`` on the meta device: parameters and persistent buffers get a shape and no memory
    and draw nothing at random (the file sets them). A model built to be loaded thus skips its random
    initialisation, which took 2.7 s of the paper speech model's 4.5-s load. Buffers computed from the config
    (``persistent=False``: DCT bases, column indices) are built on the CPU explicitly by their modules, since
    the file does not hold them."""
    with torch.device("meta"):
        return build(config)


def _left_empty(model: nn.Module) -> list[str]:
    """Names of the parameters and buffers still on the meta device (none once a file has set them)."""
    return [name for name, t in [*model.named_parameters(), *model.named_buffers()] if t.is_meta]


def _load_weights(model: nn.Module, weights: Path) -> tuple[list[str], list[str], dict[str, np.ndarray]]:
    """Load a safetensors file into ``model`` (built on the meta device: the file's tensors, cast to the
    model's types, become its parameters and buffers) one top-level part at a time (the speech model's three
    encoders one after another), so that loading holds the model plus one part, not the model twice:
    loading the paper speech model peaked at 2.1 GiB instead of 2.8. Returns the keys missing from the
    file and those it has that the model lacks; a corrupt file or one that does not fit is an
    :class:`InputFileError`. The model is still on the CPU here (``load_model`` moves it afterwards), so
    a device's own errors (a GPU out of memory, a missing ``cuda:N``) are never read as a bad file. The
    arrays stored beside the network's (:data:`STORED_ARRAY_PREFIXES`) come back as a third value."""
    parts: dict[str, list[str]] = {}
    stored: dict[str, np.ndarray] = {}
    dtypes = {k: v.dtype for k, v in model.state_dict().items()}
    missing: set[str] | None = None
    unexpected: list[str] = []
    try:
        stamp = _file_stamp(weights)
        with safe_open(str(weights), framework="pt", device="cpu") as f:
            for key in f.keys():
                if key.startswith(STORED_ARRAY_PREFIXES):
                    stored[key] = f.get_tensor(key).numpy()
                else:
                    parts.setdefault(key.split(".", 1)[0], []).append(key)
        for keys in parts.values() or [[]]:
            # the file is mapped into memory while open, and the pages read count as the process's
            # own: opened again for each part, only one part's pages are mapped at a time
            with safe_open(str(weights), framework="pt", device="cpu") as f:
                if _file_stamp(weights) != stamp:
                    raise InputFileError(weights, "changed while it was being loaded (saved again?); load it again")
                part = {k: f.get_tensor(k) for k in keys}
            # the tensors become the model's own (assign): cast to its types (float16 files to float32)
            part = {k: t.to(dtypes[k]) if k in dtypes else t for k, t in part.items()}
            absent, extra = model.load_state_dict(part, strict=False, assign=True)
            del part
            missing = set(absent) if missing is None else missing & set(absent)
            unexpected += extra
    except InputFileError:
        raise
    except (SafetensorError, OSError, ValueError) as e:
        raise InputFileError(weights, f"corrupt weights file ({str(e).splitlines()[0] if str(e) else e.__class__.__name__})") from None
    except RuntimeError as e:
        detail = next((ln.strip() for ln in str(e).splitlines() if "size mismatch" in ln), "shapes differ")
        raise InputFileError(weights, f"weights do not fit the stored config ({detail.rstrip('.')})") from None
    return sorted(missing or ()), unexpected, stored


def _file_stamp(path: Path) -> tuple[int, int, int]:
    st = os.stat(path)
    return st.st_ino, st.st_size, st.st_mtime_ns
