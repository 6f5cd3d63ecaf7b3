"""How human the motion looks, in numbers: the synthetic corpus, a model's output on held-out corpus
speech and on real read speech, beside a real conversational take.

`emogesture motion-stats`'s statistics (:func:`emogesture.eval.motion_stats.motion_statistics`) with the
onset coupling, for:

- **corpus**: every ``EVERY``-th take of the corpus (its motion and its own speech), and of its test split
  (the ground truth of the next column), the takes ordered by text and then speaker, so that every
  emotion and every speaker is sampled alike (a text carries one emotion; in the order of the file
  names, a stride of 4 over 8 test texts a speaker would pick the same two emotions from every speaker);
- **model, test takes**: the model's motion (``--emotion auto``, seed 0) for the test split's takes of the
  corpus (every ``EVERY``-th), with their speech;
- **model, real speech**: the same for the real read speech of :mod:`emogesture.data.real_speech`;
- **anger against sadness**: each real recording animated twice with the same seed, ``--emotion anger`` and
  ``--emotion sadness``: the wrists' mean speed and median height above the pelvis of each, with the checks
  that anger moves the wrists at least 1.3 times as fast and holds them at least 5 cm higher.

Besides `motion-stats`'s statistics, the wrists' mean jerk (m/s^3, :func:`emogesture.eval.metrics.wrist_jerk`,
pooled over frames) is reported: the model's on real speech must not be higher than the corpus's.

The onset coupling of several sequences is their pooled lag curve's best value (its lag beside it), so
chance does not add to it (:mod:`emogesture.eval.motion_stats`). The real take's column is quoted, not
measured here: BEAT speaker 2, 64 s of SMPL-X motion capture, measured with the same definitions outside
the project (BEAT is CC BY-NC and is not part of it; one take, so pooling does not change its coupling).

Usage: python experiments/motion_realism.py CORPUS OUT_DIR [GESTURE_MODEL] [EVERY]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from emogesture.audio import load_audio
from emogesture.data.beat import read_split_csv
from emogesture.data.real_speech import RECORDINGS, load_real_recording
from emogesture.eval.seams import sequence_joints
from emogesture.eval.metrics import wrist_jerk
from emogesture.eval.motion_stats import file_statistics, motion_statistics, npz_files, wrist_heights
from emogesture.motion.body import SkeletonBody
from emogesture.motion.io import load_smplx_npz
from emogesture.pipeline.generate import EditRequest, GesturePipeline

#: a real conversational take (BEAT speaker 2, 64 s), the same definitions; quoted
REAL_TAKE = {"finger_curl_deg": 23.0, "root_turn_deg": 5.3, "wrist_distance_median": 0.53,
             "hand_in_front_share": 0.45, "onset_coupling": 0.05}
ROWS = (("finger curl, mean joint angle (deg)", "finger_curl_deg", "{:.1f}"),
        ("hand shape change, joint angle std (deg)", "finger_change_deg", "{:.1f}"),
        ("body turn: root rotation about its mean (deg)", "root_turn_deg", "{:.2f}"),
        ("chest yaw std (deg)", "torso_yaw_std_deg", "{:.2f}"),
        ("chest pitch std (deg)", "torso_pitch_std_deg", "{:.2f}"),
        ("wrists' median distance (m)", "wrist_distance_median", "{:.3f}"),
        ("a hand >= 0.15 m in front of the chest", "hand_in_front_share", "{:.1%}"),
        ("wrist height above the pelvis, median (m)", "wrist_height_median", "{:.2f}"),
        ("hands together (wrists < 0.2 m apart)", "hands_together_share", "{:.1%}"),
        ("wrist speed mean (m/s)", "wrist_speed_mean", "{:.3f}"),
        ("wrist jerk mean (m/s^3)", "wrist_jerk", "{:.1f}"),
        ("onset coupling", "onset_coupling", "{:.3f}"),
        ("its lag (s; negative: the arms move first)", "onset_coupling_lag_s", "{:+.2f}"),
        ("seconds", "seconds", "{:.0f}"))


#: anger against sadness on the same real recording: wrists at least this many times as fast ...
ANGER_SPEED_RATIO = 1.3
#: ... and at least this many metres higher (median height above the pelvis)
ANGER_HEIGHT_M = 0.05


def pooled_jerk(joint_sequences: list) -> float:
    """The wrists' jerk pooled over the frames of several sequences ``[T, 55, 3]`` (m/s^3)."""
    frames = [max(len(j) - 3, 0) for j in joint_sequences]
    return float(sum(wrist_jerk(j) * f for j, f in zip(joint_sequences, frames) if f) / max(sum(frames), 1))


def generated(pipe: GesturePipeline, waves: list, seed: int = 0, edit: EditRequest | None = None) -> dict:
    sequences = []
    for wave in waves:
        seq = pipe.generate(wave, seed=seed, edit=edit)[0]
        sequences.append((seq.poses, sequence_joints(pipe, seq), float(pipe.fps), (wave, 16000)))
    return {**motion_statistics(sequences), "wrist_jerk": pooled_jerk([s[1] for s in sequences])}


def file_jerk(files: list) -> float:
    """:func:`pooled_jerk` of npz files, each posed on the licence-free skeleton with its own shape."""
    import torch

    joints = []
    for f in files:
        seq = load_smplx_npz(f)
        body = SkeletonBody(np.asarray(seq.betas[:10], np.float32) if len(seq.betas) else None)
        with torch.no_grad():
            joints.append(body(torch.from_numpy(seq.poses), torch.from_numpy(seq.trans)).numpy())
    return pooled_jerk(joints)


def anger_against_sadness(pipe: GesturePipeline, waves: list, seed: int = 0) -> dict:
    """Each real recording animated as anger and as sadness (same seed): the wrists' mean speed and median
    height above the pelvis, per recording and pooled, with the checks."""
    out = {}
    for label in ("anger", "sadness"):
        speeds, heights = [], []
        for wave in waves:
            seq = pipe.generate(wave, seed=seed, edit=EditRequest(emotion_label=label))[0]
            joints = sequence_joints(pipe, seq)
            speeds.append(motion_statistics([(seq.poses, joints, float(pipe.fps))])["wrist_speed_mean"])
            heights.append(float(np.median(wrist_heights(joints))))
        out[label] = {"wrist_speed_mean": speeds, "wrist_height_median": heights}
    ratio = [a / s for a, s in zip(out["anger"]["wrist_speed_mean"], out["sadness"]["wrist_speed_mean"])]
    higher = [a - s for a, s in zip(out["anger"]["wrist_height_median"], out["sadness"]["wrist_height_median"])]
    out.update(speed_ratio=ratio, height_difference_m=higher,
               speed_check=bool(min(ratio) >= ANGER_SPEED_RATIO), height_check=bool(min(higher) >= ANGER_HEIGHT_M))
    return out


def by_text(takes: list[str]) -> list[str]:
    """Take names (``SPEAKER_NAME_EMOTION-STYLE_TEXT_TEXT``) ordered by text, then speaker."""
    def key(take: str) -> tuple:
        parts = take.split("_")
        return int(parts[-1]), int(parts[0]), take
    return sorted(takes, key=key)


def main(corpus: str, out_dir: str, model: str | None = None, every: str = "4") -> None:
    step = int(every)
    root = Path(corpus)
    files = {f.stem: f for f in npz_files(root)}
    ordered = [files[t] for t in by_text(list(files))]
    results = {"corpus": {**file_statistics(ordered, step, progress=True), "wrist_jerk": file_jerk(ordered[::step])}}
    split = read_split_csv(root / "train_test_split.csv")
    test = by_text([t for t in split if split[t] == "test"])[::step]
    test_files = [root / "smplxflame_30" / f"{t}.npz" for t in test]
    results["corpus, test takes"] = {**file_statistics(test_files), "wrist_jerk": file_jerk(test_files)}
    pipe = GesturePipeline.from_run(model or None)
    results["model, test takes"] = generated(pipe, [load_audio(root / "wave16k" / f"{t}.wav")[0] for t in test])
    real = [load_real_recording(r) for r in RECORDINGS]
    results["model, real speech"] = generated(pipe, real)
    emotions = anger_against_sadness(pipe, real)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / "motion_realism.json").write_text(json.dumps({"real_take_quoted": REAL_TAKE, **results,
                                                         "anger_against_sadness": emotions}, indent=1) + "\n")
    names = list(results)
    lines = ["| statistic | real take (quoted) | " + " | ".join(names) + " |", "|---|---|" + "---|" * len(names)]
    for label, key, fmt in ROWS:
        real = fmt.format(REAL_TAKE[key]) if key in REAL_TAKE else ""
        cells = ["–" if results[n].get(key) is None else fmt.format(results[n][key]) for n in names]
        lines.append(f"| {label} | {real} | " + " | ".join(cells) + " |")
    lines += ["", "## Anger against sadness on the same real recording (`--emotion anger` / `sadness`, seed 0)", "",
              "| recording | anger wrist speed (m/s) | sadness | ratio | anger wrist height (m) | sadness | difference |",
              "|---|---|---|---|---|---|---|"]
    for i, r in enumerate(RECORDINGS):
        a, sd = emotions["anger"], emotions["sadness"]
        lines.append(f"| {r.name} | {a['wrist_speed_mean'][i]:.3f} | {sd['wrist_speed_mean'][i]:.3f} | "
                     f"{emotions['speed_ratio'][i]:.2f} | {a['wrist_height_median'][i]:.3f} | "
                     f"{sd['wrist_height_median'][i]:.3f} | {emotions['height_difference_m'][i]:+.3f} |")
    ok = {True: "holds", False: "FAILS"}
    jerk_ok = results["model, real speech"]["wrist_jerk"] <= results["corpus"]["wrist_jerk"]
    lines += ["", f"- anger's wrists at least {ANGER_SPEED_RATIO}x as fast as sadness's on every recording: "
              f"{ok[emotions['speed_check']]}",
              f"- and at least {ANGER_HEIGHT_M * 100:.0f} cm higher: {ok[emotions['height_check']]}",
              f"- the model's wrist jerk on real speech no higher than the corpus's: {ok[jerk_ok]}"]
    text = "\n".join(lines) + "\n"
    (out / "motion_realism.md").write_text(text)
    print(text, end="")


if __name__ == "__main__":
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    main(*sys.argv[1:5])
