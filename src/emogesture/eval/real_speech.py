"""How a model does on real recorded speech, against the same model on held-out corpus voices.

Real read speech carries no acted emotion, so a model should hear it as neutral, trust what it hears
(``--emotion auto`` blends untrusted windows toward neutral), and animate it as it animates held-out
corpus speech of the same emotion: the hands working in front of the chest as often, the wrists as
far apart. The report reads, per recording and pooled:

- **perception**: each 10-s window's emotion (the speech model's classifier, as ``--emotion own``
  hears it), the share heard as the recording's emotion, and the share of windows ``auto`` trusts
  (trust 1: within the calibrated range of both the emotion and the voice);
- **motion**, generated as ``emogesture generate`` does by default (``--emotion auto``, 4 seam
  candidates), over several sampling seeds: :func:`~emogesture.eval.motion_stats.motion_statistics`,
  above all the share of frames with a hand in front of the chest and the wrists' median distance (pooled,
  and for each recording).

Checks (each can fail): heard as its emotion in at least :data:`HEARD_SHARE` of the windows; trusted in
at least :data:`TRUSTED_SHARE`; the hand-in-front share within :data:`FRONT_SHARE_TOLERANCE` and the
wrists' median distance within :data:`WRIST_DISTANCE_TOLERANCE` (relative) of the reference's.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence

import numpy as np

from emogesture.audio import TARGET_SAMPLE_RATE
from emogesture.data.beat import EMOTIONS
from emogesture.eval.seams import sequence_joints
from emogesture.eval.motion_stats import motion_statistics
from emogesture.pipeline.generate import GesturePipeline

HEARD_SHARE = 0.70
TRUSTED_SHARE = 0.70
FRONT_SHARE_TOLERANCE = 0.10
WRIST_DISTANCE_TOLERANCE = 0.10
REAL_SPEECH_CONSTANTS = {"heard_share": HEARD_SHARE, "trusted_share": TRUSTED_SHARE,
                         "front_share_tolerance": FRONT_SHARE_TOLERANCE,
                         "wrist_distance_tolerance": WRIST_DISTANCE_TOLERANCE}


def _perception(pipe: GesturePipeline, wave: np.ndarray, emotion: str, name: str,
                neutral: np.ndarray | None = None) -> tuple[dict, object]:
    encoded = pipe.encode(wave)
    reference = None if neutral is None else pipe.neutral_reference(neutral, f"{name}, neutral reference")
    heard, encoded = pipe.perceive_against(encoded, name, reference)  # as `generate --neutral-from` does
    trusted = None if heard.trust is None else [bool(t >= 1.0) for t in heard.trust]
    return {"seconds": round(len(wave) / TARGET_SAMPLE_RATE, 2), "windows": len(heard.labels), "heard": heard.labels,
            "heard_counts": dict(Counter(heard.labels)),
            "heard_as_emotion": [label == emotion for label in heard.labels],
            "trusted": trusted, "trust": None if heard.trust is None else [round(float(t), 3) for t in heard.trust],
            "distance": None if heard.distance is None else np.round(heard.distance, 3).tolist()}, encoded


def _motion(pipe: GesturePipeline, wave: np.ndarray, encoded, seeds: Sequence[int]) -> list:
    return [(seq.poses.reshape(len(seq.poses), -1, 3), sequence_joints(pipe, seq), float(pipe.fps))
            for seed in seeds for seq in pipe.generate(wave, seed=seed, encoded=encoded)]


def _pooled(rows: dict[str, dict]) -> dict:
    heard = [h for r in rows.values() for h in r["heard_as_emotion"]]
    trusted = [t for r in rows.values() for t in (r["trusted"] or [])]
    return {"windows": len(heard), "heard_share": float(np.mean(heard)) if heard else float("nan"),
            "trusted_share": float(np.mean(trusted)) if trusted else float("nan")}


def real_speech_report(pipe: GesturePipeline, recordings: dict[str, tuple[np.ndarray, str]],
                       reference: dict[str, tuple[np.ndarray, str]], seeds: Sequence[int] = (0, 1, 2, 3),
                       progress: bool = False, neutral_references: dict[str, np.ndarray] | None = None) -> dict:
    """Perception and motion of real ``recordings`` (name -> 16-kHz waveform, the emotion it is spoken
    with) beside ``reference`` recordings (held-out corpus takes, same form), generated with ``seeds``;
    a recording named in ``neutral_references`` (name -> 16-kHz waveform of the same speaker without
    emotion) is heard and generated against it, as ``generate --neutral-from`` does.

    Returns ``{"real": {name: row}, "reference": {name: row}, "pooled": {"real", "reference"}, "motion":
    {"real", "reference"} (motion_statistics), "checks": {name: {value, bar, pass}}, "seeds", "constants"}``.
    """
    from tqdm import tqdm

    out: dict = {"real": {}, "reference": {}, "seeds": list(seeds), "constants": dict(REAL_SPEECH_CONSTANTS)}
    motion: dict[str, list] = {"real": [], "reference": []}
    items = [("real", k, v) for k, v in recordings.items()] + [("reference", k, v) for k, v in reference.items()]
    for group, name, (wave, emotion) in tqdm(items, desc="real speech report", unit="recording", disable=not progress):
        if emotion not in EMOTIONS:
            raise ValueError(f"{name}: unknown emotion {emotion!r}")
        row, encoded = _perception(pipe, wave, emotion, name,
                                   (neutral_references or {}).get(name) if group == "real" else None)
        sequences = _motion(pipe, wave, encoded, seeds)
        own = motion_statistics(sequences)
        out[group][name] = row | {"emotion": emotion, "hand_in_front_share": own["hand_in_front_share"],
                                  "wrist_distance_median": own["wrist_distance_median"]}
        motion[group] += sequences
    out["pooled"] = {g: _pooled(out[g]) for g in ("real", "reference")}
    out["motion"] = {g: motion_statistics(motion[g]) for g in ("real", "reference")}
    out["checks"] = real_speech_checks(out)
    return out


def real_speech_checks(r: dict) -> dict:
    """The report's pass/fail lines (module docstring) from a :func:`real_speech_report` result."""
    real, ref = r["motion"]["real"], r["motion"]["reference"]
    front = real["hand_in_front_share"] - ref["hand_in_front_share"]
    distance = real["wrist_distance_median"] / ref["wrist_distance_median"] - 1.0
    checks = {
        "real speech heard as its emotion (share of windows)": (r["pooled"]["real"]["heard_share"], f">= {HEARD_SHARE}",
                                                                r["pooled"]["real"]["heard_share"] >= HEARD_SHARE),
        "windows of real speech that auto trusts": (r["pooled"]["real"]["trusted_share"], f">= {TRUSTED_SHARE}",
                                                    r["pooled"]["real"]["trusted_share"] >= TRUSTED_SHARE),
        "hand in front of the chest, real - reference": (front, f"within +-{FRONT_SHARE_TOLERANCE}",
                                                         abs(front) <= FRONT_SHARE_TOLERANCE),
        "wrists' median distance, real / reference - 1": (distance, f"within +-{WRIST_DISTANCE_TOLERANCE}",
                                                          abs(distance) <= WRIST_DISTANCE_TOLERANCE),
    }
    return {k: {"value": float(v), "bar": bar, "pass": bool(ok)} for k, (v, bar, ok) in checks.items()}


def heard_text(counts: dict[str, int]) -> str:
    """``{"contempt": 3, "neutral": 1}`` -> ``"contempt 3, neutral 1"``, the most heard first."""
    return ", ".join(f"{k} {n}" for k, n in sorted(counts.items(), key=lambda kv: -kv[1]))


def real_speech_markdown(r: dict, title: str = "Real speech") -> str:
    """The report as markdown: checks, per-recording perception, motion side by side."""
    lines = [f"# {title}", "", r.get("header", ""), "", "| check | value | bar | |", "|---|---|---|---|"]
    for name, c in r["checks"].items():
        lines.append(f"| {name} | {c['value']:.3f} | {c['bar']} | {'pass' if c['pass'] else 'FAIL'} |")
    lines += ["", "| recording | group | seconds | windows | heard (--emotion own) | as its emotion | trusted by auto | "
              "a hand in front | wrists apart (m) |", "|---|---|---|---|---|---|---|---|---|"]
    for group in ("real", "reference"):
        for name, row in r[group].items():
            heard = heard_text(row["heard_counts"])
            trusted = "n/a" if row["trusted"] is None else f"{np.mean(row['trusted']):.0%}"
            front = f"{row['hand_in_front_share']:.0%}" if "hand_in_front_share" in row else ""
            apart = f"{row['wrist_distance_median']:.2f}" if "wrist_distance_median" in row else ""
            lines.append(f"| {name} | {group} | {row['seconds']:.1f} | {row['windows']} | {heard} | "
                         f"{np.mean(row['heard_as_emotion']):.0%} | {trusted} | {front} | {apart} |")
    for group in ("real", "reference"):
        p, m = r["pooled"][group], r["motion"][group]
        lines.append(f"| **pooled** | {group} | | {p['windows']} | | {p['heard_share']:.0%} | {p['trusted_share']:.0%} | "
                     f"{m['hand_in_front_share']:.0%} | {m['wrist_distance_median']:.2f} |")
    m = r["motion"]
    lines += ["", f"Motion generated with `--emotion auto`, seeds {', '.join(map(str, r['seeds']))}:", "",
              "| statistic | real | reference |", "|---|---|---|"]
    for label, key, fmt in (("a hand >= 0.15 m in front of the chest", "hand_in_front_share", "{:.1%}"),
                            ("wrists' median distance (m)", "wrist_distance_median", "{:.3f}"),
                            ("wrist speed mean (m/s)", "wrist_speed_mean", "{:.3f}"),
                            ("a wrist below the pelvis", "wrist_below_pelvis_share", "{:.1%}"),
                            ("elbow opened beyond 150°", "elbow_open_share", "{:.1%}"),
                            ("seconds", "seconds", "{:.0f}")):
        lines.append(f"| {label} | {fmt.format(m['real'][key])} | {fmt.format(m['reference'][key])} |")
    return "\n".join(lines) + "\n"


def reference_recordings(cache, split: str, emotions: set[str]) -> dict[str, tuple[np.ndarray, str]]:
    """The takes of a prepared cache's ``split`` spoken with one of ``emotions``, whole, from the corpus
    root the cache was prepared from: take -> (16-kHz waveform, emotion)."""
    from pathlib import Path

    from emogesture.audio import load_audio

    windows = cache.split(split)
    root = Path(cache.manifest["root"])
    out = {}
    for take, emotion in zip(windows.takes, np.asarray(windows.emotion).tolist()):
        if EMOTIONS[emotion] in emotions and take not in out:
            out[take] = (load_audio(root / "wave16k" / f"{take}.wav")[0], EMOTIONS[emotion])
    if not out:
        raise ValueError(f"the {split} split holds no take spoken with {', '.join(sorted(emotions))}")
    return out


def evaluate_real_speech(model, cache_dir, out_dir, split: str = "test", real_root=None, seeds: int = 4,
                         overwrite: bool = False, progress: bool = True, labelled=None,
                         labelled_split: str = "val") -> dict:
    """Score a gesture model (run folder or model JSON; None = the bundled model) on the real recordings
    of :mod:`emogesture.data.real_speech` (or, with ``labelled``, a labelled-speech manifest's
    ``labelled_split`` speakers, each speaker's clips of an emotion one recording;
    :mod:`emogesture.data.labelled_speech`) beside the held-out ``split`` takes of the windows cache
    ``cache_dir`` spoken with the same emotions; writes ``real_speech.{json,md}`` to ``out_dir``."""
    import json
    from pathlib import Path

    from emogesture.checkpoints import write_text_atomic
    from emogesture.provenance import split_use
    from emogesture.data.cache import open_cache
    from emogesture.data.labelled_speech import labelled_recordings, read_manifest
    from emogesture.data.real_speech import load_real_recording, real_recordings
    from emogesture.errors import EmogestureError, OutputExistsError

    out_dir = Path(out_dir)
    paths = [out_dir / "real_speech.json", out_dir / "real_speech.md"]
    for p in paths:
        if p.exists() and not overwrite:
            raise OutputExistsError(p)
    if seeds < 1:
        raise EmogestureError(f"--seeds {seeds}: must be at least 1")
    if labelled is not None:
        recordings = labelled_recordings(read_manifest(labelled), labelled_split)
        heard = ", whom a model trained on this manifest has heard" if labelled_split == "train" else ", never trained on"
        source = f"Labelled real speech ({labelled}, its {labelled_split} speakers{heard})"
    else:
        found = real_recordings(real_root)
        recordings = {r.name: (load_real_recording(r, real_root), r.emotion) for r in found}
        folders = [str(real_root)] if real_root is not None else list(dict.fromkeys(str(r.folder) for r in found))
        source = f"Real recordings ({', '.join(folders)})"
    pipe = GesturePipeline.from_run(model)
    use = split_use(split, {"gesture": pipe.loaded, "speech": pipe.speech.loaded})
    reference = reference_recordings(open_cache(cache_dir), split, {e for _, e in recordings.values()})
    result = real_speech_report(pipe, recordings, reference, list(range(seeds)), progress)
    held = "held out (no part trained or calibrated on it)" if use["held_out"] else \
        f"not held out: calibrated on it ({', '.join(use['calibrated_on_it'])})"
    if labelled is not None:
        result["labelled"] = {"manifest": str(labelled), "split": labelled_split}
    result["header"] = (f"{source} against the {split} split's takes of the same emotion: {held}; "
                        f"model {pipe.loaded.path}.")
    result["split_use"] = use
    result["model"] = str(pipe.loaded.path)
    out_dir.mkdir(parents=True, exist_ok=True)
    write_text_atomic(paths[0], json.dumps(result, indent=1))
    write_text_atomic(paths[1], real_speech_markdown(result))
    return result
