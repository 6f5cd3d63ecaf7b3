"""``emogesture evaluate gesture``: paper Table 1 (SRGR, BA, FGD, Div, GA) plus wrist jerk and speed,
and the rhythm gain (:mod:`emogesture.eval.rhythm`).

Every source is a set of motion windows aligned with one split of a windows cache. The extractor M
embeds them (FGD, Div) and classifies their emotion (GA); forward kinematics on the licence-free
skeleton gives joint positions for BA, SRGR, jerk and rhythm; audio onsets and onset envelopes come from
the cache's source audio.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from emogesture.audio import detect_onsets, load_audio, onset_strength
from emogesture.eval.rhythm import RHYTHM_CONSTANTS, arm_speed, envelope_at_frames, mismatched_envelopes, rhythm_gain
from emogesture.eval.motion_stats import motion_statistics, motion_stats_markdown
from emogesture.eval.report import split_use_line
from emogesture.checkpoints import LoadedModel, load_model, write_text_atomic
from emogesture.provenance import split_use
from emogesture.config import from_dict
from emogesture.data.beat import EMOTIONS
from emogesture.data.cache import SplitWindows, WindowsCache, open_cache
from emogesture.errors import EmogestureError, OutputExistsError
from emogesture.eval.classification import classification_report
from emogesture.eval.metrics import (
    METRIC_CONSTANTS, beat_align, diversity, frechet_distance, motion_beats, srgr, wrist_jerk, wrist_speed,
)
from emogesture.eval.plots import save_confusion_matrix
from emogesture.motion import MotionFeatureSpec, SkeletonBody, canonical_features, features_to_poses

COLUMNS = ("SRGR", "BA", "FGD", "Div", "GA", "Jerk", "Speed", "Rhythm")


@dataclass
class Embedded:
    features: np.ndarray  # [W, width] extractor features
    logits: np.ndarray  # [W, 8]
    joints: np.ndarray  # [W, T, 55, 3] metres


class GestureEvaluator:
    """Holds what every source is compared with: the split's ground truth, audio onsets, extractor."""

    def __init__(self, cache: WindowsCache, split: str, extractor: LoadedModel, fps: int = 30) -> None:
        self.cache, self.split, self.extractor, self.fps = cache, split, extractor, fps
        self.windows: SplitWindows = cache.split(split)
        self.spec = from_dict(MotionFeatureSpec, cache.manifest["config"]["features"])
        stored = extractor.metadata.features
        if stored is not None and from_dict(MotionFeatureSpec, stored) != self.spec:
            raise EmogestureError(f"{extractor.path}: the extractor was trained on other motion features than {cache.root}")
        self.mean = torch.tensor(extractor.metadata.require("motion_mean", extractor.path), dtype=torch.float32)
        self.std = torch.tensor(extractor.metadata.require("motion_std", extractor.path), dtype=torch.float32)
        self.body = SkeletonBody()
        self.onsets, self.envelopes = self._window_onsets()
        self.rhythm_audio = None  # (own [W, T], mismatched name -> [W, T]) onset envelopes
        if self.envelopes is not None:
            frames = self.windows.motion.shape[1]
            starts = [int(round(s * fps)) for s in self.windows.start_s]
            self.rhythm_audio = mismatched_envelopes(self.envelopes, self.windows.takes, starts, self.windows.text,
                                                     frames, seed=RHYTHM_CONSTANTS["seed"], fps=fps)
        self.gt = self.embed(np.asarray(self.windows.motion, np.float32))

    def _window_onsets(self) -> tuple[list[np.ndarray] | None, dict[str, np.ndarray] | None]:
        """Audio onset times (s, relative to each window's start) for every window, and each take's
        onset envelope at the motion's frame rate; ``(None, None)`` without audio."""
        root = Path(self.cache.manifest["root"])
        per_take: dict[str, np.ndarray] = {}
        envelopes: dict[str, np.ndarray] = {}
        out = []
        window_s = self.windows.motion.shape[1] / self.fps
        for take, start in zip(self.windows.takes, self.windows.start_s):
            if take not in per_take:
                wav = root / "wave16k" / f"{take}.wav"
                if not wav.is_file():
                    return None, None
                wave, sr = load_audio(wav)
                envelope = onset_strength(wave, sr)
                per_take[take] = detect_onsets(wave, sr, envelope=envelope)
                envelopes[take] = envelope_at_frames(envelope, sr, int(round(len(wave) / sr * self.fps)), self.fps)
            on = per_take[take]
            out.append(on[(on >= start) & (on < start + window_s)] - start)
        return out, envelopes

    @torch.no_grad()
    def embed(self, motion: np.ndarray, batch_size: int = 64) -> Embedded:
        """Raw features ``[W, T, D]`` -> extractor features, logits and joint positions. The extractor
        reads the rotations the body shows (:func:`~emogesture.motion.canonical_features`), never 6D
        numbers off the rotation manifold that a decoder may output and no body displays."""
        feats, logits, joints = [], [], []
        for i in range(0, len(motion), batch_size):
            x = canonical_features(torch.from_numpy(np.array(motion[i : i + batch_size], np.float32)), self.spec)
            f, lg = self.extractor.model((x - self.mean) / self.std)
            feats.append(f.numpy())
            logits.append(lg.numpy())
            joints.append(self.body.forward_features(x, self.spec).numpy())
        return Embedded(np.concatenate(feats), np.concatenate(logits), np.concatenate(joints))

    def score(self, motion: np.ndarray, labels: np.ndarray | None = None, seed: int = 0) -> tuple[dict, np.ndarray]:
        """Table-1 metrics of one source; returns ``(row, emotion confusion matrix)``."""
        if motion.shape != self.windows.motion.shape:
            raise EmogestureError(f"a source has shape {motion.shape}, expected {self.windows.motion.shape}")
        e = self.embed(motion)
        labels = self.windows.emotion if labels is None else labels
        rep = classification_report(labels, e.logits.argmax(1), len(EMOTIONS))
        ba = np.nan
        if self.onsets is not None:
            scores = np.array([beat_align(motion_beats(j, fps=self.fps), on) for j, on in zip(e.joints, self.onsets)])
            ba = float(np.mean(scores[np.isfinite(scores)])) if np.isfinite(scores).any() else np.nan
        row = {
            "SRGR": float(np.mean([srgr(p, g, s) for p, g, s in zip(e.joints, self.gt.joints, self.windows.sem)])),
            "BA": ba,
            "FGD": frechet_distance(e.features, self.gt.features),
            "Div": diversity(e.features, seed=seed),
            "GA": rep["accuracy"],
            "Jerk": float(np.mean([wrist_jerk(j, fps=self.fps) for j in e.joints])),
            "Speed": float(np.mean([wrist_speed(j, fps=self.fps) for j in e.joints])),
            "Rhythm": np.nan,
        }
        if self.rhythm_audio is not None:
            own, mismatched = self.rhythm_audio
            rhythm = rhythm_gain(arm_speed(e.joints, fps=self.fps), own, mismatched, fps=self.fps)
            row["Rhythm"], row["rhythm"] = rhythm["gain"], rhythm
        return row, rep["confusion"]

    @torch.no_grad()
    def motion_stats(self, motion: np.ndarray) -> dict:
        """:func:`~emogesture.eval.motion_stats.motion_statistics` of a source's windows ``[W, T, D]``."""
        x = torch.from_numpy(np.array(motion, np.float32))  # a copy: sources may be read-only memory maps
        poses, _ = features_to_poses(x, self.spec)
        joints = self.body.forward_features(x, self.spec)
        return motion_statistics([(p, j, float(self.fps)) for p, j in zip(poses.numpy(), joints.numpy())])

    def split_half_fgd(self, seed: int = 0) -> float:
        """FGD between the ground truth of two disjoint halves of the takes: the noise floor of FGD."""
        takes = sorted(set(self.windows.takes))
        rng = np.random.default_rng(seed)
        half = set(rng.permutation(takes)[: len(takes) // 2].tolist())
        mask = np.array([t in half for t in self.windows.takes])
        return frechet_distance(self.gt.features[mask], self.gt.features[~mask])


def gesture_markdown(result: dict) -> str:
    lines = [f"# Gesture evaluation: {result['split']} split, {result['windows']} windows", "",
             split_use_line(result.get("split_use")), "",
             "| source | " + " | ".join(COLUMNS) + " |", "|---|" + "---|" * len(COLUMNS)]
    for name, row in result["rows"].items():
        lines.append(f"| {name} | " + " | ".join(_fmt(row[c]) for c in COLUMNS) + " |")
    lines += ["", f"FGD between two disjoint halves of the ground-truth takes: {result['gt_split_half_fgd']:.3f} "
              "(the noise floor of FGD on this split).",
              "SRGR, BA, GA, Div: higher is better (Div: closer to GT); FGD, Jerk: lower is better (Jerk: m/s³, "
              "closer to GT). Speed: mean wrist speed, m/s (closer to GT). Rhythm: rhythm gain (below).",
              "BA here does not measure whether motion follows the speech: the corpus's speech has onsets every "
              "few tenths of a second, so with σ = 0.3 s any motion's beats lie near one (compare the mismatched "
              "and shifted ground truth); the rhythm gain does.", "",
              f"Extractor: {result['extractor']}", ""]
    if any("rhythm" in row for row in result["rows"].values()):
        lines += [rhythm_markdown(result).rstrip(), ""]
    if result.get("motion_stats"):
        lines += ["## Motion statistics (`emogesture motion-stats`: per-window, pooled)", "",
                  motion_stats_markdown(result["motion_stats"]).rstrip(), ""]
    lines += ["Constants: " + json.dumps(result["constants"]), ""]
    return "\n".join(lines)


def rhythm_markdown(result: dict) -> str:
    """The rhythm section of a gesture report (sources with audio envelopes only)."""
    rc = result["constants"].get("rhythm", RHYTHM_CONSTANTS)
    lines = ["## Rhythm (arm speed against the speech's onset envelope)", "",
             f"Pearson correlation of the arm joints' mean speed with the audio's onset-strength envelope inside "
             f"each window (both smoothed, σ {rc['smooth_s']} s), at lags up to ±{rc['max_lag_s']} s, averaged over "
             "windows; score = the best lag's. Gain = score against the window's own audio minus the mean score of "
             f"the same motion against mismatched audio ({rc['other_window_draws']} draws of another text's window, "
             f"the same take shifted by {', '.join(f'{s:g}' for s in rc['shifts_s'])} s); spread = the standard "
             "deviation of those mismatched scores. Follows the speech: gain ≥ "
             f"{rc['discrimination_factor']:g} × spread; within noise: |gain| ≤ {rc['noise_factor']:g} × spread.", "",
             "| source | score (own audio) | best lag (s) | mismatched, mean | gain | spread | gain / spread |",
             "|---|---|---|---|---|---|---|"]
    for name, row in result["rows"].items():
        r = row.get("rhythm")
        if r is None:
            continue
        mis = float(np.mean(list(r["mismatched"].values())))
        lines.append(f"| {name} | {r['score']:.4f} | {r['lag_s']:+.2f} | {mis:.4f} | {r['gain']:.4f} | "
                     f"{r['spread']:.4f} | {r['gain_over_spread']:.1f} |")
    return "\n".join(lines) + "\n"


def _fmt(v: float) -> str:
    return "n/a" if v is None or (isinstance(v, float) and np.isnan(v)) else f"{v:.3f}"


def evaluate_gesture(cache_dir: Path, extractor_run: Path, sources: dict, out_dir: Path, split: str = "test",
                     baselines: bool = True, seed: int = 0, overwrite: bool = False,
                     evaluator: GestureEvaluator | None = None, models: dict | None = None) -> dict:
    """Score ``sources`` (name -> raw features ``[W, T, D]``, or ``(features, target labels)``, or a
    folder of npz files) and the built-in baselines; writes JSON, markdown and confusion PNGs.
    ``evaluator``: an already built :class:`GestureEvaluator` of the same cache, split and extractor;
    ``models``: the loaded models behind ``sources`` (name -> LoadedModel), whose use of ``split`` (trained
    on it: refused; calibrated on it: noted) the report records."""
    from emogesture.eval import sources as src

    t0 = time.monotonic()
    out_dir = Path(out_dir)
    json_path, md_path = out_dir / f"gesture_{split}.json", out_dir / f"gesture_{split}.md"
    for p in (json_path, md_path):
        if p.exists() and not overwrite:
            raise OutputExistsError(p)
    cache = open_cache(cache_dir)
    ev = evaluator or GestureEvaluator(cache, split, load_model(extractor_run, "extractor"))
    use = split_use(split, {"extractor": ev.extractor, **(models or {})})
    w = ev.windows
    todo: dict = {"GT": src.ground_truth(w)}
    if baselines:
        todo["mean pose"] = src.mean_pose(w, cache)
        todo["GT, mismatched audio"] = src.mismatched(w, seed)
        todo["GT, shifted 1 s"] = src.time_shifted(w, cache, 1.0)
    for name, value in sources.items():
        todo[name] = src.npz_folder(value, w, ev.spec) if isinstance(value, (str, Path)) else value
    rows, stats, out_dir_made = {}, {}, False
    for name, value in todo.items():
        motion, labels = value if isinstance(value, tuple) else (value, None)
        rows[name], cm = ev.score(motion, labels, seed)
        if labels is None:  # the same motion scored against other labels has the same statistics
            stats[name] = ev.motion_stats(motion)
        if not out_dir_made:
            out_dir.mkdir(parents=True, exist_ok=True)
            out_dir_made = True
        slug = "".join(c if c.isalnum() else "_" for c in name.lower()).strip("_")
        save_confusion_matrix(cm, list(EMOTIONS), out_dir / f"gesture_{split}_{slug}_emotion_confusion.png",
                              title=f"{name}: GA {rows[name]['GA']:.3f}", overwrite=True)
    result = {
        "split": split, "windows": len(w), "cache": str(cache_dir), "extractor": str(extractor_run), "split_use": use,
        "rows": rows, "motion_stats": stats, "gt_split_half_fgd": ev.split_half_fgd(seed),
        "audio_onsets": ev.onsets is not None,
        "constants": {**{k: (list(v) if isinstance(v, tuple) else v) for k, v in METRIC_CONSTANTS.items()},
                      "div_seed": seed, "seed": seed, "body": "licence-free mannequin-x skeleton",
                      "rhythm": {k: (list(v) if isinstance(v, tuple) else v) for k, v in RHYTHM_CONSTANTS.items()}},
        "seconds": round(time.monotonic() - t0, 1),
    }
    for path, text in ((json_path, json.dumps(result, indent=1)), (md_path, gesture_markdown(result))):
        write_text_atomic(path, text)
    return result
