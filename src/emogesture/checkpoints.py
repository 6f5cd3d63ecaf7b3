"""Model files: safetensors weights + a JSON of config, statistics and version (SPEC §9).

A model is stored as two files side by side, ``<name>.safetensors`` and ``<name>.json``; both are
written atomically (temporary file + rename), weights first, so a JSON always describes complete
weights. Loading never unpickles anything and checks the model kind, the format version and the
weights' checksum, with one-line errors naming the file.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from os import PathLike
from pathlib import Path
from typing import Any

from safetensors import SafetensorError
import torch
from safetensors.torch import load_file, save_file
from torch import nn

from emogesture import __version__
from emogesture.config import from_dict, to_dict
from emogesture.errors import ConfigError, InputFileError, OutputExistsError

FORMAT = "emogesture-model"
FORMAT_VERSION = 1


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
    extra: dict
    meta: dict
    path: Path


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _atomic_write(path: Path, write: Callable[[Path], None]) -> None:
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        write(Path(tmp))
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


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


def save_model(
    path: str | PathLike[str],
    kind: str,
    model: nn.Module,
    config: Any,
    extra: dict | None = None,
    *,
    name: str = "model",
    overwrite: bool = True,
    weights_dtype: torch.dtype | None = None,
) -> Path:
    """Write ``model``'s weights and ``{kind, config, extra, version}``; returns the JSON path.

    ``extra`` holds JSON-safe data stored with the model (normalisation statistics, label names,
    per-class mean latents, ...). ``weights_dtype`` (e.g. ``torch.float16``) stores floating-point
    tensors in that type (they are cast back to the model's type when loaded).
    """
    weights, meta_path = model_paths(path, name)
    weights.parent.mkdir(parents=True, exist_ok=True)
    if not overwrite and (weights.exists() or meta_path.exists()):
        raise OutputExistsError(meta_path)
    state = {k: v.detach().contiguous().cpu() for k, v in model.state_dict().items()}
    if weights_dtype is not None:
        state = {k: v.to(weights_dtype) if v.is_floating_point() else v for k, v in state.items()}
    _atomic_write(weights, lambda tmp: save_file(state, str(tmp), metadata={"format": FORMAT, "kind": kind}))
    meta = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "kind": kind,
        "emogesture_version": __version__,
        "config": to_dict(config),
        "extra": extra or {},
        "weights": weights.name,
        "weights_sha256": _sha256(weights),
    }
    _atomic_write(meta_path, lambda tmp: tmp.write_text(json.dumps(meta, indent=1)))
    return meta_path


def read_meta(path: str | PathLike[str], kind: str | None = None, name: str = "model") -> dict:
    """The JSON of a model file, checked for format, version and (if given) kind."""
    weights, meta_path = model_paths(path, name)
    if not meta_path.is_file():
        raise InputFileError(meta_path, "model file not found")
    try:
        meta = json.loads(meta_path.read_text())
    except (OSError, ValueError) as e:
        raise InputFileError(meta_path, f"not a readable model description ({e.__class__.__name__})")
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise InputFileError(meta_path, "not an emogesture model file")
    if meta.get("format_version") != FORMAT_VERSION:
        raise InputFileError(
            meta_path,
            f"model format version {meta.get('format_version')} is not supported by this emogesture "
            f"{__version__} (expects {FORMAT_VERSION})",
        )
    if kind is not None and meta.get("kind") != kind:
        raise InputFileError(meta_path, f"holds a {meta.get('kind')!r} model, but a {kind!r} model is needed")
    return meta


def load_model(path: str | PathLike[str], kind: str, *, name: str = "model", device: str = "cpu") -> LoadedModel:
    """Rebuild a model of ``kind`` from its files and load its weights (eval mode)."""
    _builtin_kinds()
    if kind not in _KINDS:
        raise ValueError(f"unknown model kind {kind!r}")
    weights, meta_path = model_paths(path, name)
    meta = read_meta(path, kind, name)
    if not weights.is_file():
        raise InputFileError(weights, "model weights not found next to its .json")
    if _sha256(weights) != meta.get("weights_sha256"):
        raise InputFileError(weights, "weights do not match their .json (checksum differs); the files are from different saves")
    try:
        config = from_dict(_KINDS[kind].config_cls, meta["config"])
    except ConfigError as e:
        raise InputFileError(meta_path, f"invalid stored config ({e})")
    model = _KINDS[kind].build(config)
    try:
        state = load_file(str(weights), device=device)
    except (SafetensorError, OSError) as e:
        raise InputFileError(weights, f"corrupt weights file ({e})")
    missing, unexpected = model.load_state_dict(state, strict=False)
    missing = [k for k in missing if k not in getattr(model, "optional_state_keys", ())]
    if missing or unexpected:
        raise InputFileError(
            weights, f"weights do not fit the stored config (missing {list(missing)[:3]}, unexpected {list(unexpected)[:3]})"
        )
    model.to(device).eval()
    return LoadedModel(model, config, meta.get("extra", {}), meta, meta_path)


CHECKSUMS = "SHA256SUMS"


def write_checksums(folder: str | PathLike[str]) -> Path:
    """Write ``SHA256SUMS`` (``sha256sum`` format) over every other file of ``folder``."""
    folder = Path(folder)
    lines = [f"{_sha256(p)}  {p.name}" for p in sorted(folder.iterdir()) if p.is_file() and p.name != CHECKSUMS
             and not p.name.startswith(".")]
    return write_text_atomic(folder / CHECKSUMS, "\n".join(lines) + "\n")


def verify_checksums(folder: str | PathLike[str]) -> list[str]:
    """Check every file listed in ``folder/SHA256SUMS``; returns the names checked, raises on a mismatch."""
    folder = Path(folder)
    sums = folder / CHECKSUMS
    if not sums.is_file():
        raise InputFileError(sums, "checksum list not found")
    names = []
    for line in sums.read_text().splitlines():
        if not line.strip():
            continue
        digest, name = line.split(maxsplit=1)
        path = folder / name.strip()
        if not path.is_file():
            raise InputFileError(path, f"listed in {CHECKSUMS} but missing")
        if _sha256(path) != digest:
            raise InputFileError(path, f"checksum differs from {CHECKSUMS} (the file was changed or damaged)")
        names.append(name.strip())
    return names


def bundle_models(speech: str | PathLike[str], gesture: str | PathLike[str], extractor: str | PathLike[str] | None,
                  out: str | PathLike[str], overwrite: bool = False,
                  weights_dtype: torch.dtype | None = torch.float16) -> Path:
    """Copy a speech model, the gesture model trained on it and (optionally) an extractor into one folder
    as ``speech.*``, ``gesture.*``, ``extractor.*`` with ``weights_dtype`` weights; the gesture model then
    names its speech model by the relative path ``speech.json``. Writes ``SHA256SUMS``; returns ``out``."""
    out = Path(out)
    if out.exists() and any(out.iterdir()) and not overwrite:
        raise OutputExistsError(out)
    out.mkdir(parents=True, exist_ok=True)
    s = load_model(speech, "speech")
    g = load_model(gesture, "gesture")
    if g.extra.get("speech_weights_sha256") != s.meta["weights_sha256"]:
        raise InputFileError(s.path, f"is not the speech model {g.path} was trained with")
    save_model(out, "speech", s.model, s.config, s.extra, name="speech", weights_dtype=weights_dtype)
    speech_sha = read_meta(out, "speech", "speech")["weights_sha256"]
    extra = {**g.extra, "speech_model": "speech.json", "speech_weights_sha256": speech_sha}
    save_model(out, "gesture", g.model, g.config, extra, name="gesture", weights_dtype=weights_dtype)
    if extractor is not None:
        x = load_model(extractor, "extractor")
        save_model(out, "extractor", x.model, x.config, x.extra, name="extractor", weights_dtype=weights_dtype)
    write_checksums(out)
    return out
