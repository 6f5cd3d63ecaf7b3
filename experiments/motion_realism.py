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
- **model, real speech**: the same for the real read speech of :mod:`emogesture.data.real_speech`.

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

from emogesture.audio import load_audio
from emogesture.data.beat import read_split_csv
from emogesture.data.real_speech import RECORDINGS, load_real_recording
from emogesture.eval.seams import sequence_joints
from emogesture.eval.motion_stats import file_statistics, motion_statistics, npz_files
from emogesture.pipeline.generate import GesturePipeline

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
        ("onset coupling", "onset_coupling", "{:.3f}"),
        ("its lag (s; negative: the arms move first)", "onset_coupling_lag_s", "{:+.2f}"),
        ("seconds", "seconds", "{:.0f}"))


def generated(pipe: GesturePipeline, waves: list, seed: int = 0) -> dict:
    sequences = []
    for wave in waves:
        seq = pipe.generate(wave, seed=seed)[0]
        sequences.append((seq.poses, sequence_joints(pipe, seq), float(pipe.fps), (wave, 16000)))
    return motion_statistics(sequences)


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
    results = {"corpus": file_statistics([files[t] for t in by_text(list(files))], step, progress=True)}
    split = read_split_csv(root / "train_test_split.csv")
    test = by_text([t for t in split if split[t] == "test"])[::step]
    results["corpus, test takes"] = file_statistics([root / "smplxflame_30" / f"{t}.npz" for t in test])
    pipe = GesturePipeline.from_run(model or None)
    results["model, test takes"] = generated(pipe, [load_audio(root / "wave16k" / f"{t}.wav")[0] for t in test])
    results["model, real speech"] = generated(pipe, [load_real_recording(r) for r in RECORDINGS])
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / "motion_realism.json").write_text(json.dumps({"real_take_quoted": REAL_TAKE, **results}, indent=1) + "\n")
    names = list(results)
    lines = ["| statistic | real take (quoted) | " + " | ".join(names) + " |", "|---|---|" + "---|" * len(names)]
    for label, key, fmt in ROWS:
        real = fmt.format(REAL_TAKE[key]) if key in REAL_TAKE else ""
        cells = ["–" if results[n].get(key) is None else fmt.format(results[n][key]) for n in names]
        lines.append(f"| {label} | {real} | " + " | ".join(cells) + " |")
    text = "\n".join(lines) + "\n"
    (out / "motion_realism.md").write_text(text)
    print(text, end="")


if __name__ == "__main__":
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    main(*sys.argv[1:5])
