"""Preparation recipe: a BEAT2-layout root -> a windows cache of aligned fbank and motion windows.

An explicit, idempotent step (docs/design.md, 'Data'): re-running on a complete cache does nothing, and an
interrupted run resumes. Work happens in two stages:

1. per take (resumable): decode audio, Kaldi fbank, motion features, semantic scores ->
   ``<cache>/takes/<take>.npz``, each written atomically, so a file that exists is complete;
2. assembly: statistics over the training split, then per-split window arrays (see
   :mod:`emogesture.data.cache`), written under temporary names and renamed; ``manifest.json`` last.

The settings are recorded in ``prepare_config.json`` when a cache is started; re-running with other
settings into the same directory is refused rather than mixing two preparations. Each prepared take
records the size and modification time of its source files: a take whose files changed since (a
rebuilt corpus, an edited take) is processed again, and a changed take list or split file
re-assembles the windows.
"""

from __future__ import annotations

import csv
import hashlib
import json
import os
import shutil
import sys
import time
import zipfile
from dataclasses import dataclass, field
from os import PathLike
from pathlib import Path

import numpy as np
import torch
from tqdm.auto import tqdm

from emogesture.version import __version__
from emogesture.config import to_dict
from emogesture.audio import RECORDING_NORMS, FbankConfig, kaldi_fbank, load_audio, normalise_recording
from emogesture.data.beat import SPLITS, actor_split, parse_take_name, read_sem, read_split_csv, sem_frame_scores
from emogesture.data.cache import CACHE_VERSION, WINDOW_COLUMNS
from emogesture.errors import EmogestureError, InputFileError
from emogesture.fileio import read_json
from emogesture.motion import MotionFeatureSpec, load_smplx_npz, poses_to_features, write_npz_atomic

FBANK_RATE = 100  # fbank frames per second (10 ms shift)


def bar_interval() -> float:
    """Seconds between progress-bar updates: lively on a terminal, sparse in a log file."""
    return 0.1 if sys.stderr.isatty() else 15.0


@dataclass
class PrepareConfig:
    """Settings of one preparation; stored in the cache and compared on re-runs."""

    window_seconds: float = 10.0
    fbank_frames: int = 1024
    hop_seconds: float = 5.0  # between training windows
    eval_hop_seconds: float = 10.0  # between val/test windows (non-overlapping)
    fps: int = 30
    take_types: tuple[int, ...] = (0, 1)
    #: "csv", "actor", "csv+actor" (held out by either: a take is test when its csv split or its actor is,
    #: else val when either is; the synthetic corpus's csv splits by text) or "auto" (csv when present, else actor)
    split_source: str = "auto"
    fbank: FbankConfig = field(default_factory=FbankConfig)
    #: each take's fbank measured against the take itself before the statistics (``none``, ``level`` or
    #: ``spectrum``: :func:`emogesture.audio.normalise_recording`); a speech model trained on the cache
    #: does the same to every recording it hears
    recording_norm: str = "none"
    features: MotionFeatureSpec = field(default_factory=MotionFeatureSpec)

    def to_dict(self) -> dict:
        return to_dict(self)

    def digest(self) -> str:
        d = self.to_dict()
        if d["recording_norm"] == "none":  # caches prepared before the setting existed keep their digest
            del d["recording_norm"]
        return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:16]


@dataclass
class PrepareResult:
    cache: Path
    takes_total: int
    takes_processed: int  # this run; 0 when everything was already there
    windows: dict[str, int]
    skipped: list[str]
    assembled: bool  # False when the cache was already complete
    seconds: float

    def format(self) -> str:
        w = ", ".join(f"{k} {v}" for k, v in self.windows.items())
        state = "assembled" if self.assembled else "already complete, nothing to do"
        lines = [
            f"cache {self.cache}: {state}",
            f"  takes: {self.takes_total} ({self.takes_processed} processed this run, {len(self.skipped)} skipped)",
            f"  windows: {w}",
            f"  time: {self.seconds:.1f} s",
        ]
        return "\n".join(lines)


def find_takes(root: Path, take_types: tuple[int, ...]) -> tuple[list[str], list[str]]:
    """Takes with both motion and audio under a BEAT2 root; returns (takes, skipped-with-reason)."""
    motion_dir, wave_dir = root / "smplxflame_30", root / "wave16k"
    for d in (motion_dir, wave_dir):
        if not d.is_dir():
            raise InputFileError(d, "missing folder; expected the BEAT2 layout <root>/smplxflame_30, <root>/wave16k")
    takes, skipped = [], []
    for p in sorted(motion_dir.glob("*.npz")):
        try:
            info = parse_take_name(p.stem)
        except ValueError:
            skipped.append(f"{p.name}: not a BEAT take name")
            continue
        if info.take_type not in take_types:
            continue
        if not (wave_dir / f"{p.stem}.wav").is_file():
            skipped.append(f"{p.name}: no wave16k/{p.stem}.wav")
            continue
        takes.append(p.stem)
    if not takes:
        raise InputFileError(root, "no takes with both smplxflame_30/*.npz and wave16k/*.wav")
    return takes, skipped


def assign_splits(root: Path, takes: list[str], source: str) -> dict[str, str]:
    csv_path = root / "train_test_split.csv"
    if source == "csv" or (source == "auto" and csv_path.is_file()):
        table = read_split_csv(csv_path)
        return {t: table.get(t, "additional") for t in takes}
    if source in ("actor", "auto"):
        return {t: actor_split(t) for t in takes}
    if source == "csv+actor":
        table = read_split_csv(csv_path)
        out = {}
        for t in takes:
            both = (table.get(t, "additional"), actor_split(t))
            out[t] = "additional" if both[0] == "additional" else next(s for s in ("test", "val", "train") if s in both)
        return out
    raise EmogestureError(f"unknown split source {source!r} (use csv, actor, csv+actor or auto)")


def process_take(root: Path, take: str, config: PrepareConfig) -> dict[str, np.ndarray]:
    """One take -> ``fbank [F, n_mels]`` (log-mel, measured against the take as ``config.recording_norm`` says), ``motion [T, D]``, ``sem [T]``."""
    wave, sr = load_audio(root / "wave16k" / f"{take}.wav", target_sr=config.fbank.sample_rate)
    fbank = normalise_recording(kaldi_fbank(wave, config.fbank).numpy(), config.recording_norm).astype(np.float32)
    seq = load_smplx_npz(root / "smplxflame_30" / f"{take}.npz")
    if abs(seq.fps - config.fps) > 1e-3:
        raise InputFileError(root / "smplxflame_30" / f"{take}.npz", f"frame rate {seq.fps} is not {config.fps}")
    with torch.no_grad():
        motion = poses_to_features(
            torch.from_numpy(seq.poses), config.features, trans=torch.from_numpy(seq.trans)
        ).numpy()
    sem_path = root / "sem" / f"{take}.txt"
    sem = (
        sem_frame_scores(read_sem(sem_path), seq.num_frames, config.fps)
        if sem_path.is_file()
        else np.zeros(seq.num_frames, np.float32)
    )
    return {"fbank": fbank, "motion": motion.astype(np.float32), "sem": sem}


SOURCE_FILES = (("wave16k", ".wav"), ("smplxflame_30", ".npz"), ("sem", ".txt"))


def _file_stamp(path: Path) -> str:
    """Size and modification time of ``path`` ('-' when missing): a rewritten file gets a new stamp."""
    try:
        st = path.stat()
    except OSError:
        return "-"
    return f"{st.st_size}:{st.st_mtime_ns}"


def source_stamp(root: Path, take: str) -> str:
    """Stamp of the source files a take is prepared from (audio, motion, semantic scores)."""
    return ";".join(f"{sub}={_file_stamp(root / sub / f'{take}{suffix}')}" for sub, suffix in SOURCE_FILES)


def _prepared_stamp(path: Path) -> str | None:
    """The source stamp a prepared take was made from (None: missing, unreadable or from an older cache)."""
    try:
        with np.load(path) as z:
            return str(z["source"]) if "source" in z.files else None
    except (OSError, ValueError, EOFError, zipfile.BadZipFile):
        return None


def full_window_starts(seconds: float, window: float, hop: float) -> list[float]:
    """Start times of full windows inside ``seconds``, every ``hop`` from 0."""
    n = int(np.floor((seconds - window) / hop + 1e-9)) + 1 if seconds >= window else 0
    return [round(i * hop, 6) for i in range(max(n, 0))]


def _text_group(take: str) -> int:
    info = parse_take_name(take)
    return info.take_type * 1000 + info.take


def _compute_stats(take_dir: Path, train_takes: list[str]) -> dict:
    """Scalar fbank mean/std (as AST) and per-feature motion mean/std over the training takes."""
    s = ss = 0.0
    n = 0
    m_sum = m_sq = None
    m_n = 0
    for take in train_takes:
        with np.load(take_dir / f"{take}.npz") as z:
            fb = z["fbank"].astype(np.float64)
            mo = z["motion"].astype(np.float64)
        s, ss, n = s + fb.sum(), ss + (fb**2).sum(), n + fb.size
        m_sum = mo.sum(0) if m_sum is None else m_sum + mo.sum(0)
        m_sq = (mo**2).sum(0) if m_sq is None else m_sq + (mo**2).sum(0)
        m_n += mo.shape[0]
    f_mean = s / n
    f_std = float(np.sqrt(max(ss / n - f_mean**2, 1e-12)))
    mean = m_sum / m_n
    std = np.sqrt(np.maximum(m_sq / m_n - mean**2, 0.0))
    return {
        "fbank_mean": float(f_mean),
        "fbank_std": f_std,
        "motion_mean": mean.astype(np.float32).tolist(),
        "motion_std": np.maximum(std, 1e-4).astype(np.float32).tolist(),
        "train_takes": len(train_takes),
        "train_frames": int(m_n),
    }


def _assemble_split(
    out: Path, take_dir: Path, takes: list[str], hop: float, config: PrepareConfig, stats: dict
) -> int:
    """Write one split's window arrays (temp names, then rename); returns the window count."""
    win_frames = int(round(config.window_seconds * config.fps))
    rows = []
    for take in takes:
        with np.load(take_dir / f"{take}.npz") as z:
            seconds = min(z["fbank"].shape[0] / FBANK_RATE, z["motion"].shape[0] / config.fps)
        rows += [(take, s) for s in full_window_starts(seconds, config.window_seconds, hop)]
    split_dir = out / "tmp_split"
    if split_dir.exists():
        shutil.rmtree(split_dir)
    split_dir.mkdir(parents=True)
    n_mels = config.fbank.num_mel_bins
    dim = config.features.dim
    W = len(rows)
    fb_arr = np.lib.format.open_memmap(split_dir / "fbank.npy", "w+", np.float16, (W, config.fbank_frames, n_mels))
    mo_arr = np.lib.format.open_memmap(split_dir / "motion.npy", "w+", np.float32, (W, win_frames, dim))
    se_arr = np.lib.format.open_memmap(split_dir / "sem.npy", "w+", np.float32, (W, win_frames))
    mean, two_std = stats["fbank_mean"], 2.0 * stats["fbank_std"]
    current, z = None, None
    with (split_dir / "windows.csv").open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(WINDOW_COLUMNS)
        for i, (take, start) in enumerate(rows):
            if take != current:
                with np.load(take_dir / f"{take}.npz") as zz:
                    z = {k: zz[k] for k in zz.files}
                current = take
            a0 = int(round(start * FBANK_RATE))
            fb = (z["fbank"][a0 : a0 + config.fbank_frames] - mean) / two_std
            fb_arr[i] = 0.0  # zero in the normalised domain past the end of the audio
            fb_arr[i, : fb.shape[0]] = fb
            m0 = int(round(start * config.fps))
            mo_arr[i] = z["motion"][m0 : m0 + win_frames]
            se_arr[i] = z["sem"][m0 : m0 + win_frames]
            info = parse_take_name(take)
            writer.writerow([take, info.speaker_id, info.emotion, _text_group(take), f"{start:.6f}"])
    for arr in (fb_arr, mo_arr, se_arr):
        arr.flush()
    del fb_arr, mo_arr, se_arr
    return W


def prepare(
    root: str | PathLike[str],
    out: str | PathLike[str],
    config: PrepareConfig | None = None,
    *,
    progress: bool = True,
) -> PrepareResult:
    """Prepare (or finish preparing) the windows cache of a BEAT2-layout ``root`` into ``out``.

    Safe to re-run: a complete cache with the same settings is left as it is; an interrupted one
    resumes from the takes already processed.
    """
    t0 = time.monotonic()
    root, out = Path(root), Path(out)
    config = config or PrepareConfig()
    if config.recording_norm not in RECORDING_NORMS:
        raise EmogestureError(f"recording_norm {config.recording_norm!r}: use one of {', '.join(RECORDING_NORMS)}")
    if not root.is_dir():
        raise InputFileError(root, "data root not found")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:  # a file there, a link to nowhere, no permission
        raise EmogestureError(f"{out}: cannot create the cache folder ({err.strerror})") from None
    cfg_path = out / "prepare_config.json"
    cfg = {"digest": config.digest(), "config": config.to_dict(), "root": str(root.resolve())}
    if cfg_path.is_file():
        try:
            old = read_json(cfg_path, "cache settings file")
        except InputFileError as err:
            raise EmogestureError(f"{err}; delete the cache folder or use another --out") from None
        if old.get("digest") != cfg["digest"]:
            raise EmogestureError(
                f"{out}: this cache was started with other settings; use another --out or delete it"
            )
    else:
        tmp = cfg_path.with_suffix(".json.tmp")
        tmp.write_text(json.dumps(cfg, indent=1))
        os.replace(tmp, cfg_path)

    takes, skipped = find_takes(root, config.take_types)
    stamps = {t: source_stamp(root, t) for t in takes}
    sources = hashlib.sha1(json.dumps([stamps, _file_stamp(root / "train_test_split.csv")],
                                      sort_keys=True).encode()).hexdigest()
    manifest_path = out / "manifest.json"
    if manifest_path.is_file():
        try:
            manifest = read_json(manifest_path, "cache manifest")
        except InputFileError as err:  # derived data: assembled again from the prepared takes
            print(f"note: {err}; assembling it again", file=sys.stderr)
            manifest = {}
        if (manifest.get("takes") == takes and manifest.get("digest") == cfg["digest"]
                and manifest.get("sources") == sources):
            return PrepareResult(out, len(takes), 0, manifest["windows"], skipped, False, time.monotonic() - t0)
        manifest_path.unlink()  # the root changed: re-assemble

    take_dir = out / "takes"
    take_dir.mkdir(exist_ok=True)
    # a take is (re)processed when it is missing or its source files changed since it was prepared
    todo = [t for t in takes if _prepared_stamp(take_dir / f"{t}.npz") != stamps[t]]
    for take in tqdm(todo, desc="prepare takes", unit="take", disable=not progress, mininterval=bar_interval()):
        arrays = process_take(root, take, config)
        arrays["source"] = np.array(stamps[take])
        write_npz_atomic(take_dir / f"{take}.npz", arrays, overwrite=True)

    splits = assign_splits(root, takes, config.split_source)
    train = [t for t in takes if splits[t] == "train"]
    if not train:
        raise InputFileError(root, "no training takes (check train_test_split.csv or the actor split)")
    stats = _compute_stats(take_dir, train)
    windows = {}
    for split in SPLITS:
        members = [t for t in takes if splits[t] == split]
        hop = config.hop_seconds if split == "train" else config.eval_hop_seconds
        n = _assemble_split(out, take_dir, members, hop, config, stats) if members else 0
        windows[split] = n
        final = out / split
        if final.exists():
            shutil.rmtree(final)
        if members:
            os.replace(out / "tmp_split", final)
    (out / "stats.json").write_text(json.dumps(stats))
    manifest = {
        "cache_version": CACHE_VERSION,
        "emogesture_version": __version__,
        "digest": cfg["digest"],
        "config": cfg["config"],
        "root": cfg["root"],
        "takes": takes,
        "sources": sources,
        "splits": {s: sum(1 for t in takes if splits[t] == s) for s in SPLITS},
        "windows": windows,
        "skipped": skipped,
    }
    tmp = manifest_path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(manifest, indent=1))
    os.replace(tmp, manifest_path)
    return PrepareResult(out, len(takes), len(todo), windows, skipped, True, time.monotonic() - t0)
