"""A bundle: the models that work together (speech, gesture, extractor) in one folder, with a checksum list.

The package ships one (``emogesture/assets/model``); ``emogesture bundle`` makes others.
"""

from __future__ import annotations

from collections.abc import Sequence
from os import PathLike
from pathlib import Path

import torch

from emogesture.checkpoints import file_sha256, load_model, read_meta, save_model, write_text_atomic
from emogesture.provenance import trained_with
from emogesture.errors import InputFileError, OutputExistsError

CHECKSUMS = "SHA256SUMS"


def write_checksums(folder: str | PathLike[str]) -> Path:
    """Write ``SHA256SUMS`` (``sha256sum`` format) over every other file of ``folder``."""
    folder = Path(folder)
    lines = [f"{file_sha256(p)}  {p.name}" for p in sorted(folder.iterdir()) if p.is_file() and p.name != CHECKSUMS
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
        if file_sha256(path) != digest:
            raise InputFileError(path, f"checksum differs from {CHECKSUMS} (the file was changed or damaged)")
        names.append(name.strip())
    return names


def bundle_models(speech: str | PathLike[str], gesture: str | PathLike[str], extractor: str | PathLike[str] | None,
                  out: str | PathLike[str], overwrite: bool = False,
                  weights_dtype: torch.dtype | None = torch.float16, generation: Sequence[str] = ()) -> Path:
    """Copy a speech model, the gesture model trained on it and (optionally) an extractor into one folder
    as ``speech.*``, ``gesture.*``, ``extractor.*`` with ``weights_dtype`` weights; the gesture model then
    names its speech model by the relative path ``speech.json``. ``generation``: ``key=value`` changes
    of the gesture model's generation settings (:meth:`GenerationConfig.with_overrides`).
    Writes ``SHA256SUMS``; returns ``out``."""
    out = Path(out)
    if out.exists() and any(out.iterdir()) and not overwrite:
        raise OutputExistsError(out)
    out.mkdir(parents=True, exist_ok=True)
    s = load_model(speech, "speech")
    g = load_model(gesture, "gesture")
    if not g.metadata.speech_weights_sha256 or not trained_with(g, s):
        raise InputFileError(s.path, f"is not the speech model {g.path} was trained with")
    settings = g.generation.with_overrides(list(generation))
    save_model(out, "speech", s.model, s.config, s.metadata, name="speech", weights_dtype=weights_dtype,
               tensors=s.tensors)
    speech_sha = read_meta(out, "speech", "speech")["weights_sha256"]
    metadata = g.metadata.replace(speech_model="speech.json", speech_weights_sha256=speech_sha)
    save_model(out, "gesture", g.model, g.config, metadata, name="gesture", weights_dtype=weights_dtype,
               generation=settings)
    if extractor is not None:
        x = load_model(extractor, "extractor")
        save_model(out, "extractor", x.model, x.config, x.metadata, name="extractor", weights_dtype=weights_dtype)
    write_checksums(out)
    return out
