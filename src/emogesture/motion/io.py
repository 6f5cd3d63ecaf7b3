"""Reading and writing SMPL-X animations as BEAT2 ``.npz`` files, deterministically and atomically."""

from __future__ import annotations

import zipfile
import zlib
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np

from emogesture.errors import InputFileError, OutputExistsError  # OutputExistsError: emogesture.motion gives it
from emogesture.fileio import atomic_output
from emogesture.types import ARKIT_NAMES, FPS, NUM_JOINTS, SMPLXSequence

_ZIP_DATE = (1980, 1, 1, 0, 0, 0)


def write_npz_atomic(
    path: str | PathLike[str], arrays: dict[str, Any], overwrite: bool = False, compress: bool = False
) -> Path:
    """Write ``arrays`` as an ``.npz`` readable by ``np.load``, byte-identical for identical input.

    Entries are written in ``arrays``' order with a fixed 1980-01-01 timestamp (``np.savez``
    would embed the current time). The file is first written to a temporary file in the same
    folder and then moved into place with ``os.replace``, so readers never see a partial file.
    Missing parent folders are created.

    Raises:
        OutputExistsError: ``path`` exists and ``overwrite`` is False.
        EmogestureError: the file cannot be written (one line, naming it).
    """
    method = zipfile.ZIP_DEFLATED if compress else zipfile.ZIP_STORED
    with atomic_output(path, overwrite) as tmp, tmp.open("wb") as handle:
        with zipfile.ZipFile(handle, "w", compression=method) as archive:
            for name, value in arrays.items():
                info = zipfile.ZipInfo(f"{name}.npy", date_time=_ZIP_DATE)
                info.compress_type = method
                info.external_attr = 0o644 << 16
                with archive.open(info, "w", force_zip64=True) as entry:
                    np.lib.format.write_array(entry, np.asanyarray(value), allow_pickle=False)
    return Path(path)


def save_smplx_npz(seq: SMPLXSequence, path: str | PathLike[str], overwrite: bool = False) -> Path:
    """Write ``seq`` in the BEAT2 form: ``poses [T, 165]`` float32, ``trans [T, 3]``, ``betas [B]``,
    ``expressions [T, E]``, ``model``, ``gender``, ``mocap_frame_rate``; with a face track also ``arkit [T, 52]``
    and ``arkit_names [52]``.

    Deterministic (identical input -> identical bytes) and atomic; refuses to replace an
    existing file unless ``overwrite`` (raises ``OutputExistsError``).
    """
    fps = float(seq.fps)
    rate = np.asarray(int(fps)) if fps.is_integer() else np.asarray(fps)
    arrays = {
        "poses": np.ascontiguousarray(seq.poses.reshape(seq.num_frames, NUM_JOINTS * 3), np.float32),
        "trans": np.ascontiguousarray(seq.trans, np.float32),
        "betas": np.ascontiguousarray(seq.betas, np.float32),
        "expressions": np.ascontiguousarray(seq.expressions, np.float32),
        "model": np.asarray(str(seq.model)),
        "gender": np.asarray(str(seq.gender)),
        "mocap_frame_rate": rate,
    }
    if seq.arkit is not None:  # the face track: ARKit weights and their names
        arrays["arkit"] = np.ascontiguousarray(seq.arkit, np.float32)
        arrays["arkit_names"] = np.asarray(ARKIT_NAMES)
    return write_npz_atomic(path, arrays, overwrite=overwrite)


def _read(data: Any, key: str, path: Path) -> np.ndarray | None:
    if key not in data.files:
        return None
    try:
        return np.asarray(data[key])
    except (ValueError, OSError, EOFError, zipfile.BadZipFile, zlib.error) as err:
        raise InputFileError(path, f"cannot read '{key}' ({type(err).__name__}: {err})") from err


def _read_text(data: Any, key: str, default: str, path: Path) -> str:
    try:
        value = _read(data, key, path)
    except InputFileError:  # e.g. a pickled object array: ignore an unreadable label
        return default
    if value is None or value.size != 1:
        return default
    item = value.reshape(()).item()
    return item.decode("utf-8", "replace") if isinstance(item, bytes) else str(item)


def _numeric(value: np.ndarray, key: str, path: Path, dtype: type = np.float32) -> np.ndarray:
    if not (np.issubdtype(value.dtype, np.floating) or np.issubdtype(value.dtype, np.integer)):
        raise InputFileError(path, f"'{key}' must be numeric, got dtype {value.dtype}")
    if not np.all(np.isfinite(value)):
        raise InputFileError(path, f"'{key}' contains NaN or infinite values")
    return value.astype(dtype)


def load_smplx_npz(path: str | PathLike[str]) -> SMPLXSequence:
    """Read a BEAT2-style SMPL-X ``.npz`` into an ``SMPLXSequence`` (poses ``[T, 55, 3]`` float32).

    Accepts ``poses`` as ``(T, 165)`` or ``(T, 55, 3)``, float32 or float64; extra keys are
    ignored. Missing optional keys default to: ``trans`` zeros ``[T, 3]``, ``betas`` zeros
    ``[300]``, ``expressions`` zeros ``[T, 100]``, ``mocap_frame_rate`` 30, ``gender`` 'neutral',
    ``model`` 'smplx2020'.

    Raises:
        InputFileError: missing file, not an npz archive, no/ill-shaped ``poses``, mismatched
            frame counts, or NaN/inf values; the message names the file.
    """
    path = Path(path)
    if not path.exists():
        raise InputFileError(path, "file not found")
    if path.is_dir():
        raise InputFileError(path, "is a folder, expected an .npz file")
    try:
        data = np.load(path, allow_pickle=False)
    except (ValueError, OSError, EOFError, zipfile.BadZipFile) as err:
        raise InputFileError(path, f"not a readable .npz archive ({type(err).__name__})") from err
    if not isinstance(data, np.lib.npyio.NpzFile):
        raise InputFileError(path, "is a single .npy array, expected an .npz archive with 'poses'")
    with data:
        poses = _read(data, "poses", path)
        if poses is None:
            raise InputFileError(path, f"no 'poses' array (found: {', '.join(data.files) or 'nothing'})")
        poses = _numeric(poses, "poses", path)
        if poses.ndim == 2 and poses.shape[1] == NUM_JOINTS * 3:
            poses = poses.reshape(-1, NUM_JOINTS, 3)
        if poses.ndim != 3 or poses.shape[1:] != (NUM_JOINTS, 3):
            raise InputFileError(path, f"'poses' must be (T, 165) or (T, 55, 3), got {poses.shape}")
        frames = poses.shape[0]
        if frames == 0:
            raise InputFileError(path, "'poses' has no frames")

        trans = _read(data, "trans", path)
        trans = np.zeros((frames, 3), np.float32) if trans is None else _numeric(trans, "trans", path)
        if trans.shape != (frames, 3):
            raise InputFileError(path, f"'trans' must be ({frames}, 3) to match 'poses', got {trans.shape}")

        betas = _read(data, "betas", path)
        betas = np.zeros(300, np.float32) if betas is None else _numeric(betas, "betas", path).reshape(-1)

        expressions = _read(data, "expressions", path)
        if expressions is None:
            expressions = np.zeros((frames, 100), np.float32)
        expressions = _numeric(expressions, "expressions", path)
        if expressions.ndim != 2 or expressions.shape[0] != frames:
            raise InputFileError(
                path, f"'expressions' must be ({frames}, E) to match 'poses', got {expressions.shape}"
            )

        rate = _read(data, "mocap_frame_rate", path)
        fps = float(FPS)
        if rate is not None and rate.size != 1:
            raise InputFileError(path, f"'mocap_frame_rate' must be one number, got an array of shape {rate.shape}")
        if rate is not None:
            fps = float(_numeric(rate, "mocap_frame_rate", path, np.float64).item())
        if fps <= 0:
            raise InputFileError(path, f"'mocap_frame_rate' must be positive, got {fps}")
        gender = _read_text(data, "gender", "neutral", path)
        model = _read_text(data, "model", "smplx2020", path)
        arkit = _read(data, "arkit", path)
        if arkit is not None:
            arkit = _numeric(arkit, "arkit", path)
            if arkit.shape != (frames, len(ARKIT_NAMES)):
                raise InputFileError(path, f"'arkit' must be ({frames}, {len(ARKIT_NAMES)}) to match 'poses', "
                                           f"got {arkit.shape}")

    return SMPLXSequence(
        poses=poses, trans=trans, betas=betas, expressions=expressions, fps=fps, gender=gender, model=model,
        arkit=arkit,
    )
