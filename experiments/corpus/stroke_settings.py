"""How fast the corpus's wrists travel with other stroke settings, before a corpus version is built.

Every N-th take of the experiments' 30-voice corpus (speech and motion, as ``emogesture corpus`` builds it) is
built again into OUT with some of the constants of ``emogesture.data.synthetic.gestures`` changed, and the
motion statistics of ``motion-stats`` are read from it (wrist speed, pooled onset coupling, torso yaw, ...), with
the fastest wrist speed in the body's own frame (the bound of ``tests/test_corpus.py``'s anatomy check). The
corpus checks that decide whether a setting can ship are ``tests/test_corpus.py`` with the same constants.

Usage: python experiments/corpus/stroke_settings.py OUT EVERY '{"STROKE_AMPLITUDE": 1.2, "STROKE_GAIN": {"elbow": 1.8}}'
"""

from __future__ import annotations

import json
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import torch

import emogesture.data.synthetic.gestures as gestures
from emogesture.data.synthetic.corpus import CorpusConfig, plan_takes
from emogesture.data.synthetic.takes import build_take
from emogesture.eval.motion_stats import file_statistics
from emogesture.motion import SkeletonBody, load_smplx_npz
from emogesture.motion.rotations import axis_angle_to_matrix


def changed(settings: dict) -> None:
    """The gesture module's constants set to ``settings`` (a dict constant is updated key by key)."""
    for name, value in settings.items():
        if not hasattr(gestures, name):
            raise SystemExit(f"{name}: not a constant of emogesture.data.synthetic.gestures")
        if isinstance(getattr(gestures, name), dict):
            getattr(gestures, name).update(value)
        else:
            setattr(gestures, name, value)


def build(job: tuple) -> str:
    out, plan, settings = job
    changed(settings)
    return build_take(out, plan)


def fastest_wrist(folder: Path) -> float:
    """The fastest wrist speed (m/s) over every take, in the body's own frame (the root's turn taken out)."""
    body, fastest = SkeletonBody(), 0.0
    for f in sorted(folder.glob("*.npz")):
        poses = load_smplx_npz(f).poses
        joints = body(torch.from_numpy(poses)).numpy()
        turn = axis_angle_to_matrix(torch.from_numpy(poses[:, 0]).double()).numpy()
        joints = np.einsum("tab,tja->tjb", turn, joints - joints[:, :1])
        fastest = max(fastest, float(np.linalg.norm(np.diff(joints[:, [20, 21]], axis=0), axis=-1).max() * 30))
    return fastest


def main() -> None:
    out, every = Path(sys.argv[1]), int(sys.argv[2])
    settings = json.loads(sys.argv[3]) if len(sys.argv) > 3 else {}
    plans = plan_takes(CorpusConfig(speakers=30))[0][::every]
    with ProcessPoolExecutor(2) as pool:
        list(pool.map(build, [(out, p, settings) for p in plans]))
    stats = file_statistics(sorted((out / "smplxflame_30").glob("*.npz")))
    result = {"settings": settings, "every": every, "fastest_wrist_body_frame": round(fastest_wrist(out / "smplxflame_30"), 3),
              **{k: v for k, v in stats.items() if isinstance(v, (int, float))}}
    (out / "stroke_settings.json").write_text(json.dumps(result, indent=1) + "\n")
    print(json.dumps({k: result[k] for k in ("settings", "wrist_speed_mean", "onset_coupling",
                                              "fastest_wrist_body_frame")}))


if __name__ == "__main__":
    main()
