"""Scoring trained gesture models: paper Table 1 with the ablations, plus the checks of a trained model.

Each model generates motion for every window of the evaluated split from that window's own audio (its
cached speech latents, or MFCCs for the ``no_audio`` ablation), with one seeded noise draw per window.
The edit model also generates every window with its emotion replaced by another label's mean latent
(a seeded, always different target), scored by GA against the target. On top of Table 1 this writes:

- **prior reconstruction**: ground truth through each model's motion prior (encoder mean, decoder),
  as the mean upper-body joint position error next to the error of predicting the mean pose;
- **long audio**: the edit model animates a long recording made of the split's cached windows, take
  after take; the frame-to-frame joint jumps inside the cross-faded overlaps of neighbouring windows
  (seams) are compared with those inside windows (99th percentiles, several seeds pooled; jumps near a
  take change left out), next to the ground truth of the same stretch cut into the same windows;
- **checks**: every threshold of the CPU experiment, computed from the numbers above.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from emogesture.checkpoints import load_model, write_text_atomic
from emogesture.provenance import split_use
from emogesture.data.beat import EMOTIONS
from emogesture.data.cache import open_cache
from emogesture.errors import EmogestureError, OutputExistsError
from emogesture.eval.gesture import GestureEvaluator, evaluate_gesture, gesture_markdown
from emogesture.eval.metrics import UPPER_BODY_JOINTS
from emogesture.eval.rhythm import (
    RHYTHM_CONSTANTS, other_window_pairs, within_noise,
)
from emogesture.eval import sources as src
from emogesture.eval.seams import (BOUNDARY_MARGIN_S, SEAM_CANDIDATES, long_audio_check, long_audio_ground_truth,
                                   long_audio_stretches, whole_take_seams)
from emogesture.eval.split_latents import model_conditions
from emogesture.pipeline.sampling import emotion_label_edit, generate_from_conditions, reconstruct_motion, window_seeds
from emogesture.pipeline.generate import GesturePipeline
from emogesture.pipeline.perception import auto_emotion, auto_style, fallback_style_of, perception_of
from emogesture.pipeline.speech import SpeechLatentEncoder


def edit_targets(emotion: np.ndarray, seed: int = 0, available: list[int] | None = None) -> np.ndarray:
    """A target emotion per window, uniform over the ``available`` classes (default: all eight) other
    than its own (seeded)."""
    classes = np.asarray(sorted(range(len(EMOTIONS)) if available is None else available))
    rng = np.random.default_rng([seed, 11])
    out = np.empty(len(emotion), np.int64)
    for i, e in enumerate(np.asarray(emotion).tolist()):
        choices = classes[classes != e]
        if not len(choices):
            raise EmogestureError("no other emotion to edit to")
        out[i] = choices[rng.integers(len(choices))]
    return out


def mean_joint_error(pred_joints: np.ndarray, gt_joints: np.ndarray) -> float:
    """Mean L2 distance (m) over windows, frames and the upper-body joints: ``[W, T, 55, 3]`` twice."""
    j = list(UPPER_BODY_JOINTS)
    return float(np.linalg.norm(pred_joints[:, :, j] - gt_joints[:, :, j], axis=-1).mean())


def _ratio(v: dict) -> float:
    return v["max_seam_jump_m"] / v["p99_inside_jump_m"]


def _tail_ratio(v: dict) -> float:
    return v["p99_seam_jump_m"] / v["p99_inside_jump_m"]


def _seam_cells(v: dict) -> str:
    """The seam statistics' markdown cells: jumps, max, p99 seam, p99 inside (mm), both ratios, share."""
    return (f"{v['seam_jumps']} | {v['max_seam_jump_m'] * 1000:.1f} | {v['p99_seam_jump_m'] * 1000:.1f} | "
            f"{v['p99_inside_jump_m'] * 1000:.1f} | {_ratio(v):.2f} | {_tail_ratio(v):.2f} | "
            f"{100 * v['seam_share_above_p99']:.2f} %")


#: The largest frame-to-frame joint jump anywhere in the takes generated whole may be at most this many
#: times the ground truth's over the same takes: a joint that flips for a frame (a 6D column turning
#: round) jumps 0.5-0.8 m, 3-5 times what real motion reaches, while the seam checks read percentiles.
MAX_JUMP_RATIO = 1.5


def gesture_checks(rows: dict, model: str, ablations: list[str], edit_row: str | None, recon: dict,
                   long: dict | None, edit_control: float | None = None) -> dict:
    """The experiment's thresholds as ``{name: {value, threshold, pass}}`` (pure function).

    Every row with a threshold can fail for a bad model (``tests/test_report_checks.py`` feeds bad
    rows); numbers that cannot (BA, which mismatched audio matches; Div, which any real-looking motion
    matches; the chooser-selected seam ratio) are reported without a threshold. ``edit_control``: GA of
    the unedited output against the edit targets (what an edit that changes nothing scores).
    """
    gt, ours = rows["GT"], rows[model]
    checks = {}

    def check(name: str, value: float, threshold: float, higher_is_better: bool = True, strict: bool = False) -> None:
        if higher_is_better:
            ok = value > threshold if strict else value >= threshold
        else:
            ok = value < threshold if strict else value <= threshold
        checks[name] = {"value": float(value), "threshold": float(threshold), "pass": bool(ok)}

    def report(name: str, value: float) -> None:
        checks[f"{name} (reported)"] = {"value": float(value), "threshold": None, "pass": None}

    if model in recon:
        check("prior error / mean-pose error <= 0.25", recon[model]["joint_error_m"] / recon["mean pose"]["joint_error_m"],
              0.25, higher_is_better=False)
    check("GA / GA(GT) >= 0.7", ours["GA"] / gt["GA"], 0.7)
    if edit_row is not None:
        check("GA(emotion edit) / GA(GT) >= 0.5", rows[edit_row]["GA"] / gt["GA"], 0.5)
        if edit_control is not None:
            report("the unedited output scored against the edit targets, / GA(GT)", edit_control / gt["GA"])
    if f"{model}, emotion auto" in rows:
        check("|GA(emotion auto) - GA| <= 0.03", abs(rows[f"{model}, emotion auto"]["GA"] - ours["GA"]), 0.03,
              higher_is_better=False)
    for name in ablations:
        check(f"FGD / FGD({name}) < 1", ours["FGD"] / rows[name]["FGD"], 1.0, higher_is_better=False, strict=True)
    if "GT, mismatched audio" in rows:
        report("FGD / FGD(GT, mismatched audio)", ours["FGD"] / max(rows["GT, mismatched audio"]["FGD"], 1e-12))
    if np.isfinite(gt["BA"]):
        report("BA / BA(GT) (no check: mismatched audio scores alike, see the rhythm gain)", ours["BA"] / gt["BA"])
        if "GT, mismatched audio" in rows:
            report("BA(GT, mismatched audio) / BA(GT)", rows["GT, mismatched audio"]["BA"] / gt["BA"])
    report("Div / Div(GT) (no check: every source but the mean pose lies within 20 %)", ours["Div"] / gt["Div"])
    if "rhythm" in gt:  # rhythm: a measure that can fail, and a model that follows the speech's timing
        factor, noise = RHYTHM_CONSTANTS["discrimination_factor"], RHYTHM_CONSTANTS["noise_factor"]
        g = gt["rhythm"]
        check(f"rhythm: the ground truth's gain / its spread >= {factor:g}", g["gain_over_spread"], factor)
        for name in ("mean pose", "no audio model", f"{model}, timing stream of another window"):
            r = rows.get(name, {}).get("rhythm")
            if r is not None:
                checks[f"rhythm: {name}, |gain| within {noise:g} spreads of 0"] = {
                    "value": abs(r["gain_over_spread"]),
                    "threshold": noise, "pass": bool(within_noise(r, noise))}
        if "rhythm" in ours:
            check("rhythm: gain / the ground truth's gain >= 0.6", ours["rhythm"]["gain"] / g["gain"], 0.6)
            report("rhythm: gain / its spread", ours["rhythm"]["gain_over_spread"])
    if long is not None:
        one, chosen = long.get("candidates_1"), long.get("candidates_4")
        if one is not None:
            pooled = f"{one['stretches']} stretches x " if one.get("stretches", 1) > 1 else ""
            check(f"long audio, 1 candidate per window, {pooled}{one.get('seeds', 1)} seeds: p99 seam jump / "
                  "p99 inside <= 1", _tail_ratio(one), 1.0, higher_is_better=False)
            report("long audio, 1 candidate per window: largest seam jump / p99 inside", _ratio(one))
            if "p99_windows_own_seam_jump_m" in one:  # the same frames, each window's own jumps, no cross-fade
                check("long audio, 1 candidate per window: p99 seam jump / the windows' own p99 there <= 1",
                      one["p99_seam_jump_m"] / one["p99_windows_own_seam_jump_m"], 1.0, higher_is_better=False)
        if "ground_truth" in long:
            stretches = "stretches" if long["ground_truth"].get("stretches", 1) > 1 else "stretch"
            report(f"long audio, ground truth of the same {stretches}: p99 seam jump / p99 inside",
                   _tail_ratio(long["ground_truth"]))
        if chosen is not None:
            report("long audio, 4 candidates chosen on the largest seam jump: its ratio", _ratio(chosen))
        if "every_take" in long:
            every = long["every_take"]
            check(f"every take whole, {every.get('seam_candidates', 1)} candidate: p99 seam jump / p99 inside <= 1",
                  _tail_ratio(every), 1.0, higher_is_better=False)
            if "max_jump_m" in every and "max_jump_m" in every["ground_truth"]:
                check(f"every take whole: largest jump anywhere / the ground truth's <= {MAX_JUMP_RATIO:g}",
                      every["max_jump_m"] / every["ground_truth"]["max_jump_m"], MAX_JUMP_RATIO, higher_is_better=False)
            for name, v in (("ours", every), ("ground truth", every["ground_truth"])):
                if name == "ground truth":
                    report("every take whole, ground truth: p99 seam jump / p99 inside", _tail_ratio(v))
                report(f"every take whole, {name}: largest seam jump / p99 inside", _ratio(v))
                report(f"every take whole, {name}: share of seam jumps above p99 inside", v["seam_share_above_p99"])
            if "rhythm" in every:
                for name, v in every["rhythm"].items():
                    report(f"every take whole, {name}: rhythm gain", v["gain"])
    return checks


def evaluate_gesture_models(cache_dir: Path, extractor_run: Path, models: dict[str, Path], out_dir: Path,
                            split: str = "test", edit_model: str | None = None, seed: int = 0,
                            long_audio_seconds: float = 65.0, overwrite: bool = False) -> dict:
    """Generate with every model (name -> run folder; the first is "ours"), score them with the
    baselines, and write ``gesture_models_<split>.{json,md}`` beside the Table-1 report."""
    out_dir = Path(out_dir)
    json_path, md_path = out_dir / f"gesture_models_{split}.json", out_dir / f"gesture_models_{split}.md"
    for p in (json_path, md_path):
        if p.exists() and not overwrite:
            raise OutputExistsError(p)
    if not models:
        raise EmogestureError("no gesture model to evaluate")
    cache = open_cache(cache_dir)
    windows = cache.split(split)
    main = next(iter(models))
    edit_model = edit_model or main
    sources: dict = {}
    auto_trust: dict = {}
    loaded: dict = {}
    parts: dict = {}  # every model behind the numbers, for the report's split use
    streams: dict = {}  # each model's timing stream of the split's windows (None: it reads none)
    for name, run in models.items():
        gesture = load_model(run, "gesture")
        loaded[name] = gesture
        variant = gesture.metadata.variant or gesture.config.variant
        speech = None if variant == "no_audio" else SpeechLatentEncoder.of_gesture_model(gesture)
        parts[name] = gesture
        if speech is not None:
            parts[f"{name}: speech model"] = speech.loaded
        split_use(split, parts)  # refuses a split any part trained on, before the work
        conds = model_conditions(gesture, cache, split, speech)
        streams[name] = conds[-1] if gesture.config.hears_timing else None
        seeds = window_seeds(seed, len(windows))
        sources[name] = generate_from_conditions(gesture, conds, seeds)
        perception = perception_of(speech) if name == main and speech is not None else None
        if perception is not None:  # `generate --emotion auto`: untrusted emotion latents blended toward neutral,
            # an unfamiliar voice's style toward the model's fallback style
            trust = perception.trust(conds[1], conds[2])
            auto_trust[f"{name}, emotion auto"] = {"windows": int(len(trust)), "trusted": int((trust >= 1).sum()),
                                                   "mean_trust": float(trust.mean())}
            sources[f"{name}, emotion auto"] = generate_from_conditions(
                gesture, [conds[0], auto_emotion(conds[1], conds[2], perception), auto_style(conds[2], perception, fallback_style_of(gesture)),
                          *conds[3:]], seeds)
        if gesture.config.hears_timing:  # the control: the stream of another window, all else its own
            other = other_window_pairs(windows.text, seed, 1)[0]
            sources[f"{name}, timing stream of another window"] = generate_from_conditions(
                gesture, [*conds[:-1], conds[-1][other]], seeds)
        if name == edit_model:
            known = [EMOTIONS.index(k) for k in gesture.metadata.emotion_latent_means or {}]
            targets = edit_targets(windows.emotion, seed, known)
            edited = generate_from_conditions(gesture, emotion_label_edit(gesture, conds, targets), seeds)
            sources[f"{name}, emotion edit"] = (edited, targets)
            sources[f"{name}, unedited, against the edit targets"] = (sources[name], targets)  # the control
    ev = GestureEvaluator(cache, split, load_model(extractor_run, "extractor"))
    table = evaluate_gesture(cache_dir, extractor_run, sources, out_dir, split, seed=seed, overwrite=overwrite,
                             evaluator=ev, models=parts)
    recon = {"mean pose": {"joint_error_m": mean_joint_error(ev.embed(src.mean_pose(windows, cache)).joints,
                                                             ev.gt.joints)}}
    for name, gesture in loaded.items():
        if gesture.config.variant != "no_prior":
            rec = reconstruct_motion(gesture, np.asarray(windows.motion, np.float32), timing=streams[name])
            recon[name] = {"joint_error_m": mean_joint_error(ev.embed(rec).joints, ev.gt.joints)}
    long = None
    if long_audio_seconds > 0:
        stretches = long_audio_stretches(cache, split, long_audio_seconds)
        recording = stretches[0]
        pipe = GesturePipeline.from_run(models[edit_model])
        long = {**long_audio_check(pipe, stretches, seed), "takes": recording.takes}
        long["ground_truth"] = long_audio_ground_truth(stretches, cache, long["hop_seconds"])
        long["emotions"] = [EMOTIONS[int(np.asarray(windows.emotion)[list(windows.takes).index(t)])]
                            for t in recording.takes]
        long["every_take"] = whole_take_seams(pipe, cache, split, seed, long["hop_seconds"])
    result = {
        "split": split, "models": {k: str(v) for k, v in models.items()}, "ours": main, "edit_model": edit_model,
        "steps": {k: g.metadata.step for k, g in loaded.items()},
        "variants": {k: g.config.variant for k, g in loaded.items()},
        "table": table, "prior_reconstruction": recon, "long_audio": long, "emotion_auto_trust": auto_trust,
    }
    result["checks"] = report_checks(result)
    write_text_atomic(json_path, json.dumps(result, indent=1))
    write_text_atomic(md_path, gesture_models_markdown(result))
    return result


def report_checks(r: dict) -> dict:
    """The checks (:func:`gesture_checks`) of a report's numbers (the dict written as JSON)."""
    main, edit = r["ours"], r["edit_model"]
    rows = r["table"]["rows"]
    return gesture_checks(rows, main, [n for n in r["models"] if n != main], f"{edit}, emotion edit",
                          r["prior_reconstruction"], r["long_audio"],
                          rows[f"{edit}, unedited, against the edit targets"]["GA"])


def gesture_models_markdown(r: dict) -> str:
    lines = [gesture_markdown(r["table"]).rstrip(), "",
             "Models: " + ", ".join(f"{k} = {r['variants'][k]} (step {r['steps'][k]})" for k in r["models"]),
             f"Emotion edit: every window of `{r['edit_model']}` re-generated with another emotion's mean latent "
             "(seeded target, never its own); its GA is against the target.",
             "Generation: each window drawn by the engine `generate` runs (residual noise, timing guidance, filters, "
             "the model's own settings), alone: no seams (a recording's windows are joined in the long-audio check "
             "below), and no quiet-window settling (every window of the corpus holds speech).", "",
             "## Motion prior reconstruction (upper-body joint error, m)", "", "| source | error | / mean pose |",
             "|---|---|---|"]
    base = r["prior_reconstruction"]["mean pose"]["joint_error_m"]
    for name, v in r["prior_reconstruction"].items():
        lines.append(f"| {name} | {v['joint_error_m']:.4f} | {v['joint_error_m'] / base:.3f} |")
    if r["long_audio"]:
        la = r["long_audio"]
        emotions = f" ({', '.join(la['emotions'])}: a window across a take boundary mixes two)" if "emotions" in la else ""
        bounds = ", ".join(f"{b:.1f}" for b in la.get("boundaries_s", []))
        k = la["candidates_1"].get("stretches", 1)
        pooled = (f" Unselected windows are also drawn for {k - 1} more stretches of the same length, starting at "
                  "other takes spread over the split, and the seam jumps of all are pooled (one stretch is too "
                  "little motion for a 99th percentile: the ground truth's own ratio varies from stretch to "
                  "stretch, below).") if k > 1 else ""
        lines += ["", "## Long audio", "",
                  f"{la['seconds']:.1f} s of the split's cached windows, take after take{emotions} (expected "
                  f"{la['expected_frames']} frames; takes change at {bounds or 'no point'} s), windows every "
                  f"{la['hop_seconds']} s. Frame-to-frame joint jumps touching the cross-faded overlaps (seams) "
                  "against those inside windows; jumps within "
                  f"{BOUNDARY_MARGIN_S:g} s of a take change are left out (the speech itself changes there). "
                  "With 1 candidate per window nothing is selected, and the seam jumps of "
                  f"{la['candidates_1'].get('seeds', 1)} sampling seeds are pooled; with 4 candidates (seed "
                  "only) the kept draws are chosen to make the largest seam jump small, so that row is selected "
                  "on a statistic it reports. The ground truth of the same frames, cut into the same windows, "
                  f"has no seams: its ratios are what real motion reaches by chance.{pooled}", "",
                  "| motion | seeds | frames | seam jumps | max seam jump (mm) | p99 seam (mm) | p99 inside (mm) | "
                  "max / p99 inside | p99 seam / p99 inside | share above p99 |",
                  "|---|---|---|---|---|---|---|---|---|---|"]
        where = {1: f", {k} stretches" if k > 1 else "", 4: ", the first stretch" if k > 1 else ""}
        rows = [(f"ours, {c} candidate{'s' if c > 1 else ''} per window{where[c]}", la.get(f"candidates_{c}"))
                for c in SEAM_CANDIDATES] + [(f"ground truth, same frames{where[1]}", la.get("ground_truth"))]
        for name, v in rows:
            if v is not None:
                lines.append(f"| {name} | {v.get('seeds', '-')} | {v.get('frames', la['expected_frames'])} | "
                             f"{_seam_cells(v)} |")
        if "stretches" in la and "per_stretch" in la.get("ground_truth", {}):
            lines += ["", "Each stretch on its own (p99 seam jump / p99 inside; ours with 1 candidate per window, "
                      f"{la['candidates_1'].get('seeds', 1)} seeds pooled):", "",
                      "| stretch | takes | ours | ground truth |", "|---|---|---|---|"]
            for i, (v, g) in enumerate(zip(la["stretches"], la["ground_truth"]["per_stretch"])):
                lines.append(f"| {i + 1} | {v['takes'][0]} to {v['takes'][-1]} | {_tail_ratio(v):.2f} | "
                             f"{_tail_ratio(g):.2f} |")
        if "every_take" in la:
            lines += ["", f"Every take of the split generated whole (each its own audio; pooled jumps; ours with "
                      f"{la['every_take'].get('seam_candidates', 4)} candidate per window, unselected):", "",
                      "| motion | takes | seam jumps | max seam jump (mm) | p99 seam (mm) | p99 inside (mm) | "
                      "max / p99 inside | p99 seam / p99 inside | share above p99 |",
                      "|---|---|---|---|---|---|---|---|---|"]
            for name, v in (("ours", la["every_take"]), ("ground truth", la["every_take"]["ground_truth"])):
                lines.append(f"| {name} | {v['takes']} | {_seam_cells(v)} |")
        if "rhythm" in la.get("every_take", {}):
            lines += ["", "Rhythm of the takes generated whole (consecutive 10-s windows of each take; mismatched "
                      "audio as in the rhythm table):", "", "| motion | windows | score | gain | spread | gain / spread |",
                      "|---|---|---|---|---|---|"]
            for name, v in la["every_take"]["rhythm"].items():
                lines.append(f"| {name} | {v['windows']} | {v['score']:.4f} | {v['gain']:.4f} | {v['spread']:.4f} | "
                             f"{v['gain_over_spread']:.1f} |")
    lines += ["", "## Checks", "", "| check | value | threshold | pass |", "|---|---|---|---|"]
    for name, c in r["checks"].items():
        thr = "-" if c["threshold"] is None else f"{c['threshold']:g}"
        ok = "-" if c["pass"] is None else ("yes" if c["pass"] else "**no**")
        lines.append(f"| {name} | {c['value']:.3f} | {thr} | {ok} |")
    return "\n".join(lines) + "\n"
