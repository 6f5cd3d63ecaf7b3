"""Mean ± standard deviation over sampling seeds of the gesture report's rows (the same models, split
and extractor, one `evaluate gesture --seed K` report per seed), as a markdown table on stdout.

Usage: python experiments/gesture_model/seed_summary.py SEED0.json SEED1.json ...   (gesture_models_<split>.json files)
"""

from __future__ import annotations

import json
import sys

import numpy as np

COLUMNS = ("GA", "FGD", "Div", "Speed", "Jerk", "Rhythm")


def main(paths: list[str]) -> None:
    reports = [json.load(open(p)) for p in paths]
    splits = {r["split"] for r in reports}
    if len(splits) != 1:
        sys.exit(f"seed_summary: the reports are of different splits {sorted(splits)}")
    seeds = [r["table"]["constants"]["seed"] for r in reports]
    if len(set(seeds)) != len(seeds):
        sys.exit(f"seed_summary: two reports share a seed ({seeds})")
    rows = [name for name in reports[0]["table"]["rows"] if all(name in r["table"]["rows"] for r in reports)]
    print(f"# Gesture report over {len(reports)} sampling seeds ({', '.join(map(str, seeds))}), "
          f"split {splits.pop()}\n")
    print("Mean ± standard deviation over the seeds (the seed changes the models' noise draws, the "
          "emotion-edit targets and the mismatched-audio draws of the rhythm gain).\n")
    print("| source | " + " | ".join(COLUMNS) + " |")
    print("|---|" + "---|" * len(COLUMNS))
    for name in rows:
        cells = []
        for col in COLUMNS:
            v = np.array([r["table"]["rows"][name].get(col, np.nan) for r in reports], float)
            cells.append("n/a" if np.isnan(v).all() else f"{np.nanmean(v):.3f} ± {np.nanstd(v, ddof=1):.3f}")
        print(f"| {name} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    main(sys.argv[1:])
