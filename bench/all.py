"""Every benchmark in one run (``make bench``): the machine and its floor, stages per preset and
precision, whole-process time and memory, training throughput. Writes ``bench/results/NAME.json`` and
``NAME.md`` (NAME: ``cpu`` by default, ``--name`` to keep another machine's results beside it).

Usage: python bench/all.py [--name cpu] [--device cpu|cuda] [--quick]
``--quick``: short clips and the tiny preset only (a check that the benchmarks run, not a result).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import torch

from emogesture.runtime import native_bf16

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import machine  # noqa: E402
import stages  # noqa: E402
import training  # noqa: E402
import whole  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--name", default=None, help="results file name (default: cpu, or gpu on --device cuda)")
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--skip", default="", help="comma-separated parts to skip: stages, drift, whole, training")
    args = ap.parse_args()
    name = args.name or ("gpu" if args.device.startswith("cuda") else "cpu")
    skip = set(filter(None, args.skip.split(",")))
    presets = ["tiny"] if args.quick else ["tiny", "paper"]
    precisions = ["fp32", "bf16"]
    started = time.time()
    floor = machine.floors(args.device)
    result = {"machine": machine.describe(args.device), "matmul_gflops": floor,
              "date": time.strftime("%Y-%m-%d"), "quick": args.quick}
    md = [f"# Benchmarks: {name}", "",
          f"{result['machine']['cpu']}, {result['machine']['cores']} cores "
          f"(torch {result['machine']['torch']} with {torch.get_num_threads()} threads; CPU flags "
          f"{', '.join(result['machine']['cpu_flags'])}"
          + (f"; GPU {result['machine']['gpu']}" if "gpu" in result["machine"] else "") + f"), {result['date']}.",
          "", f"Matrix throughput measured in this run (the floor): fp32 {floor['fp32']} GFLOP/s, "
          f"bf16 {floor['bf16']} GFLOP/s.", ""]
    if "stages" not in skip:
        result["stages"] = []
        md += ["## Stages of generation (per 10 s of audio)", ""]
        native = native_bf16(args.device)
        for preset in presets:
            for precision in precisions:
                # emulated bf16 runs the paper preset several times slower: a shorter clip
                seconds = 20.0 if args.quick or (preset == "paper" and precision == "bf16" and not native) else 60.0
                # the exports run on the CPU whatever the device: timed in the CPU runs only
                exports = preset == "tiny" and precision == "fp32" and not args.device.startswith("cuda")
                r = stages.run(preset, precision, seconds, exports=exports,
                               device=args.device, floor=floor, repeats=3 if preset == "tiny" else 2)
                result["stages"].append(r)
                md += [stages.table(r)]
                print(stages.table(r), flush=True)
    if "drift" not in skip:
        result["drift"] = [stages.drift(p, device=args.device) for p in presets]
        md += ["## bf16 drift (against fp32; same 20-s clip and seed, one seam candidate)", "",
               "| preset | speech latents, largest relative difference | joints, mean mm | joints, largest mm |",
               "|---|---|---|---|"]
        md += [f"| {d['preset']} | {d['latent_max_relative']} | {d['joint_mean_mm']} | {d['joint_max_mm']} |"
               for d in result["drift"]]
        md += [""]
        print(result["drift"], flush=True)
    if "whole" not in skip:
        result["whole"] = []
        md += ["## Whole process (`emogesture generate`, fresh process, npz only; precision auto)", ""]
        lengths = [10.0, 20.0, 40.0] if args.quick else [10.0, 60.0, 600.0]
        for preset in presets:
            r = whole.run(preset, lengths, "auto", args.device, repeats=5 if preset == "tiny" else 1)
            if preset == "tiny":  # the paper preset's long clips take minutes each; its start-up hides nothing
                r["in_process"] = whole.in_process(preset, tuple(lengths[-2:]), "auto", args.device)
                r["real_speech"] = whole.real_speech(preset, "auto", args.device, repeats=1 if args.quick else 2)
            result["whole"].append(r)
            md += [whole.table(r)]
            print(whole.table(r), flush=True)
    if "training" not in skip:
        md += ["## Training throughput (random inputs of the right shapes; gesture: the joint phase)", ""]
        rows = []
        accelerator = "gpu" if args.device.startswith("cuda") else "cpu"
        on_cpu = accelerator == "cpu"
        for model in ("speech", "gesture"):
            for preset in presets:
                for precision in precisions:
                    if on_cpu and preset == "paper" and precision == "bf16" and not native_bf16(args.device):
                        rows.append({"model": model, "preset": preset, "precision": precision,
                                     "skipped": "bf16 is emulated on this CPU (no avx512_bf16/AMX)"})
                        continue
                    # the paper preset on a CPU: small batches (minutes per step at its own)
                    batch = ({"speech": 1, "gesture": 8}[model] if on_cpu and preset == "paper" else None)
                    steps = 2 if args.quick or batch else 6
                    rows.append(training.throughput(model, preset, precision, steps, accelerator, batch))
                    print(rows[-1], flush=True)
        result["training"] = rows
        md += [training.table(rows)]
    result["bench_seconds"] = round(time.time() - started, 1)
    out = HERE / "results"
    out.mkdir(exist_ok=True)
    (out / f"{name}.json").write_text(json.dumps(result, indent=1))
    (out / f"{name}.md").write_text("\n".join(md) + f"\nBenchmarks took {result['bench_seconds']:.0f} s.\n")
    print(f"wrote {out / (name + '.json')} and {out / (name + '.md')}")


if __name__ == "__main__":
    main()
