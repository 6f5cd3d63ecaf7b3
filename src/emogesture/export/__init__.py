"""Exporters: an :class:`~emogesture.types.SMPLXSequence` to files people open (never a model).

- ``npz``: BEAT2's SMPL-X format (:func:`emogesture.motion.save_smplx_npz`), for the SMPL-X Blender
  add-on and BEAT2 tools;
- ``bvh``: the SMPL-X skeleton as motion capture (:mod:`emogesture.export.bvh`), for Blender, Unity,
  Maya, MotionBuilder;
- ``mp4``: a rendered preview with the speech (:mod:`emogesture.export.video`), for any player;
- ``glb``: binary glTF, a skinned mannequin with the SMPL-X skeleton and the animation
  (:mod:`emogesture.export.gltf`), for Blender, three.js, Godot, Unity and Unreal;
- ``fbx``: the same character and animation as FBX, written by Blender (:mod:`emogesture.export.fbx`;
  needs Blender), for Unity, Unreal, Maya and MotionBuilder;
- ``arkit``: the face track as a Live Link Face CSV (:mod:`emogesture.export.arkit_csv`; ``name.arkit.csv``), for
  Unreal's Live Link and the Maya and Blender CSV importers (a sequence with a face only).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from os import PathLike
from pathlib import Path

import numpy as np

from emogesture.errors import EmogestureError
from emogesture.export.arkit_csv import save_arkit_csv
from emogesture.export.bvh import save_bvh, sequence_to_bvh
from emogesture.export.fbx import save_fbx
from emogesture.export.gltf import save_glb
from emogesture.export.video import MannequinRenderer, save_mp4
from emogesture.fileio import check_output
from emogesture.motion import save_smplx_npz
from emogesture.motion.rigs import rig_named
from emogesture.types import SMPLXSequence

FORMATS = ("npz", "bvh", "mp4", "glb", "fbx", "arkit")
#: the file name ending of each format where it is not ``.<format>``
SUFFIXES = {"arkit": ".arkit.csv"}
#: what ``generate`` writes unless told otherwise
DEFAULT_FORMATS = ("npz", "bvh", "mp4")

__all__ = ["DEFAULT_FORMATS", "FORMATS", "MannequinRenderer", "export_paths", "export_sequence", "parse_formats",
           "save_arkit_csv", "save_bvh", "save_fbx", "save_glb", "save_mp4", "sequence_to_bvh"]


def parse_formats(text: str) -> tuple[str, ...]:
    """``"npz,bvh"`` -> ``("npz", "bvh")`` in the order given; unknown or empty names are errors."""
    names = [t.strip().lower().lstrip(".") for t in text.split(",") if t.strip()]
    unknown = [n for n in names if n not in FORMATS]
    if unknown or not names:
        raise EmogestureError(f"--format {text!r}: choose one or more of {', '.join(FORMATS)}, comma-separated")
    return tuple(dict.fromkeys(names))


def export_paths(stem: str | PathLike[str], formats: tuple[str, ...]) -> dict[str, Path]:
    """``out/name`` and formats -> ``{format: out/name.<format>}`` (``out/name.arkit.csv`` for ``arkit``)."""
    stem = Path(stem)
    return {f: stem.with_name(stem.name + SUFFIXES.get(f, f".{f}")) for f in formats}


def export_sequence(seq: SMPLXSequence, stem: str | PathLike[str], formats: tuple[str, ...] = DEFAULT_FORMATS, *,
                    audio: tuple[np.ndarray, int] | None = None, label: str | Sequence[tuple[float, str]] = "",
                    overwrite: bool = False, progress: bool = False, written: Callable[[Path], None] | None = None,
                    skeleton: str = "smplx") -> list[Path]:
    """Write ``seq`` as ``<stem>.<format>`` for each format; every target is checked before the first
    is written (so an existing file without ``overwrite`` leaves nothing new behind), and each file
    appears whole or not at all. ``audio = (waveform, rate)`` and ``label`` (a text, or ``(from seconds, text)``
    pairs) go into the video;
    ``written(path)`` is called after each file. ``skeleton``: the bones of the bvh, glb and fbx files,
    ``smplx`` or ``mixamo`` (:mod:`emogesture.motion.rigs`)."""
    paths = export_paths(stem, formats)
    rig_named(skeleton)  # an unknown name is an error before anything is written
    for path in paths.values():
        check_output(path, overwrite)
    out = []
    for fmt, path in paths.items():
        if fmt == "npz":
            save_smplx_npz(seq, path, overwrite=overwrite)
        elif fmt == "bvh":
            save_bvh(seq, path, overwrite=overwrite, skeleton=skeleton)
        elif fmt == "glb":
            save_glb(seq, path, overwrite=overwrite, skeleton=skeleton)
        elif fmt == "fbx":
            save_fbx(seq, path, overwrite=overwrite, skeleton=skeleton)
        elif fmt == "arkit":
            save_arkit_csv(seq, path, overwrite=overwrite)
        else:
            save_mp4(seq, path, audio=audio, label=label, overwrite=overwrite, progress=progress)
        out.append(path)
        if written is not None:
            written(path)
    return out
