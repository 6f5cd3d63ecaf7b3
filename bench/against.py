"""Whole-process ``emogesture generate`` of this checkout against another one, alternated, on the same speech.

A speed target written as "no slower than that code" cannot be read off two runs made hours apart on a shared
machine, whose speed drifts by a factor of two within a day. This runs fresh processes of both codes in turn
(which goes first alternates from round to round), each with its own bundled model, on the benchmark's
synthetic speech of each length, npz only; and reports, per code, the median wall time at each length and the
marginal real-time factor between the two lengths (of the medians, and the median of the rounds'), and their
ratios. The other checkout is any source tree of emogesture (a ``git worktree`` of an older commit), run by
this environment's Python with its ``src`` first on the path.

Usage: python bench/against.py OTHER_CHECKOUT [--rounds 14] [--lengths 10,600] [--json OUT]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import fixtures  # noqa: E402
import machine  # noqa: E402

HERE = Path(__file__).resolve().parents[1]
MODEL = Path("src/emogesture/assets/model/gesture.json")


def timed_generate(checkout: Path, speech: Path, out: Path) -> float:
    """Wall seconds of one fresh ``generate`` process of ``checkout`` on ``speech`` (npz only, its own bundled
    model); a failure stops the benchmark with its output."""
    args = [sys.executable, "-m", "emogesture.cli.main", "generate", "--model", str(checkout / MODEL), "--format",
            "npz", "--overwrite", "--quiet", "--precision", "auto", str(speech), "-o", str(out)]
    env = dict(os.environ, PYTHONPATH=str(checkout / "src"))
    t0 = time.perf_counter()
    done = subprocess.run(args, env=env, cwd=checkout, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if done.returncode:
        sys.exit(f"{checkout}: generate failed ({done.returncode}):\n{done.stderr[-2000:]}")
    return wall


def run(other: Path, rounds: int, lengths: tuple[float, float]) -> dict:
    """``rounds`` alternated rounds of both codes at both lengths -> their wall times and medians."""
    work = fixtures.scratch_folder()
    speech = {seconds: fixtures.speech_file(work, seconds) for seconds in lengths}
    codes = {"this": HERE, "other": other.resolve()}
    walls: dict[str, dict[float, list[float]]] = {name: {s: [] for s in lengths} for name in codes}
    for name, checkout in codes.items():  # untimed: torch's libraries into the file cache
        timed_generate(checkout, speech[lengths[0]], work / name)
    for r in range(rounds):
        order = list(codes) if r % 2 == 0 else list(codes)[::-1]
        for seconds in lengths:
            for name in order:
                walls[name][seconds].append(round(timed_generate(codes[name], speech[seconds], work / name), 3))
        print(f"round {r + 1}/{rounds}: " + ", ".join(
            f"{name} {walls[name][lengths[1]][-1]:.2f} / {walls[name][lengths[0]][-1]:.2f} s" for name in codes),
            flush=True)
    short, long = lengths
    result = {"other": str(other), "rounds": rounds, "lengths_s": list(lengths), "codes": {}}
    for name in codes:
        w = walls[name]
        per_round = [(a - b) / (long - short) for a, b in zip(w[long], w[short])]
        result["codes"][name] = {
            "wall_s": {str(s): w[s] for s in lengths},
            "median_s": {str(s): round(statistics.median(w[s]), 3) for s in lengths},
            "marginal_rtf_of_medians": round((statistics.median(w[long]) - statistics.median(w[short])) / (long - short), 5),
            "marginal_rtf_median_of_rounds": round(statistics.median(per_round), 5)}
    this, theirs = result["codes"]["this"], result["codes"]["other"]
    result["ratios"] = {
        "marginal_rtf_of_medians": round(this["marginal_rtf_of_medians"] / theirs["marginal_rtf_of_medians"], 3),
        "marginal_rtf_median_of_rounds": round(this["marginal_rtf_median_of_rounds"]
                                               / theirs["marginal_rtf_median_of_rounds"], 3),
        **{f"{s:g}_s_clip": round(this["median_s"][str(s)] / theirs["median_s"][str(s)], 3) for s in lengths}}
    return result


def table(result: dict) -> str:
    short, long = result["lengths_s"]
    lines = [f"| code | {short:g}-s clip (median) | {long:g}-s (median) | marginal RTF (of the medians; median of "
             f"the rounds) |", "|---|---|---|---|"]
    for name, c in result["codes"].items():
        label = "this checkout" if name == "this" else result["other"]
        lines.append(f"| {label} | {c['median_s'][str(short)]:.2f} s | {c['median_s'][str(long)]:.2f} s | "
                     f"{c['marginal_rtf_of_medians']:.5f}; {c['marginal_rtf_median_of_rounds']:.5f} |")
    r = result["ratios"]
    lines.append(f"\nthis / other, {result['rounds']} rounds: marginal RTF {r['marginal_rtf_of_medians']} × "
                 f"(median of the rounds: {r['marginal_rtf_median_of_rounds']} ×), the {short:g}-s clip "
                 f"{r[f'{short:g}_s_clip']} ×, {long:g} s {r[f'{long:g}_s_clip']} ×")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("other", type=Path, help="the other checkout's root (holding src/emogesture)")
    ap.add_argument("--rounds", type=int, default=14)
    ap.add_argument("--lengths", default="10,600", help="two audio lengths in seconds (default 10,600)")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    lengths = tuple(float(x) for x in args.lengths.split(","))
    if len(lengths) != 2 or not 0 < lengths[0] < lengths[1]:
        sys.exit("--lengths: two lengths, the shorter first (for instance 10,600)")
    if not (args.other / MODEL).is_file():
        sys.exit(f"{args.other}: no {MODEL} there; give the root of an emogesture checkout")
    if args.rounds < 1:
        sys.exit("--rounds must be at least 1")
    result = {"machine": machine.describe("cpu"), **run(args.other, args.rounds, lengths)}
    print(table(result))
    machine.write_json(args.json, result)


if __name__ == "__main__":
    main()
