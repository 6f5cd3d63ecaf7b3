"""Time per stage of generation, per 10 s of audio, against the floor measured in the same run.

For one preset and one precision, a clip of SECONDS of speech (default 60) goes through
``GesturePipeline.generate`` (default settings: 7-s hops, 4 seam candidates, one sample) with its
stage timer on; the three audio encoders are timed apart by hooks on the speech model; the exports
(npz, bvh, glb, fbx, mp4) are timed on the generated sequence. Each row gives seconds per 10 s of audio, the
real-time factor, the FLOPs counted for the stage (torch's FlopCounter on a weightless copy) and
the ratio of the time to its floor (FLOPs ÷ the matrix throughput of the precision, measured here).
The first of REPEATS generations is a warm-up; the best of the others is kept.

Usage: python bench/stages.py [--preset tiny|paper] [--precision fp32|bf16] [--seconds 60]
                              [--exports] [--json OUT]
"""

from __future__ import annotations

from dataclasses import replace

import argparse
import sys
import time
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
import fixtures  # noqa: E402
import machine  # noqa: E402

from emogesture.audio import window_starts  # noqa: E402
from emogesture.models.gesture import gesture_flops  # noqa: E402
from emogesture.models.speech import flops_per_window  # noqa: E402
from emogesture.pipeline.generate import HOP_SECONDS, WINDOW_SECONDS, GesturePipeline  # noqa: E402
from emogesture.pipeline.postprocess import candidates_drawn  # noqa: E402
from emogesture.runtime import StageTimes  # noqa: E402

ENCODERS = ("content_encoder", "emotion_encoder", "style_encoder")


def encoder_hooks(model: torch.nn.Module, times: StageTimes) -> list:
    """Add each audio encoder's forward time to ``times`` under its name."""
    handles, started = [], {}
    for name in ENCODERS:
        module = getattr(model, name)
        handles.append(module.register_forward_pre_hook(lambda m, a, n=name: started.__setitem__(n, time.perf_counter())))
        handles.append(module.register_forward_hook(
            lambda m, a, o, n=name: times.__setitem__(n, times.get(n, 0.0) + time.perf_counter() - started[n])))
    return handles


def run(preset: str, precision: str, seconds: float, exports: bool, repeats: int = 3, device: str = "cpu",
        floor: dict | None = None) -> dict:
    floor = floor or machine.floors(device)
    work = fixtures.scratch_folder()
    pipe = GesturePipeline.from_run(fixtures.gesture_run(work, preset), device=device, precision=precision)
    path = fixtures.speech_file(work, seconds)
    best: StageTimes | None = None
    for r in range(repeats):
        times = StageTimes(device)
        handles = encoder_hooks(pipe.speech.model, times)
        with times.stage("decode audio"):
            wave = pipe.load_speech(path)
        seq = pipe.generate(wave, times=times)[0]
        for h in handles:
            h.remove()
        if r and (best is None or sum(times.values()) < sum(best.values())):
            best = times
    times = best if best is not None else times
    if exports:
        from emogesture.export import export_sequence

        for fmt in ("npz", "bvh", "glb", "fbx", "mp4"):
            with times.stage(f"export {fmt}"):
                export_sequence(seq, work / f"out_{fmt}", (fmt,), audio=(wave, 16000), overwrite=True)
    windows = len(window_starts(seconds, WINDOW_SECONDS, HOP_SECONDS))
    draws = windows * candidates_drawn(windows, 4)
    sflops = flops_per_window(pipe.speech.loaded.config)
    gflops = gesture_flops(pipe.loaded.config)
    steps = pipe.generation.num_inference_steps
    flops = {name: sflops[name] * windows for name in ENCODERS}
    flops["sampling"] = gflops["denoiser"] * steps * draws
    flops["motion decoder"] = gflops["decode"] * draws
    per10 = 10.0 / seconds
    rate = floor["bf16" if precision == "bf16" else "fp32"] * 1e9
    rows = []
    order = ["decode audio", "fbank", *ENCODERS, "speech encoders", "sampling", "motion decoder", "seams and poses",
             "export npz", "export bvh", "export glb", "export fbx", "export mp4"]
    for name in order:
        if name not in times:
            continue
        t = times[name] * per10
        f = flops.get(name)
        if name == "speech encoders":
            f = sum(flops[n] for n in ENCODERS)
        row = {"stage": name, "seconds_per_10s": round(t, 4), "rtf": round(t / 10.0, 5)}
        if f:
            row["gflop_per_10s"] = round(f * per10 / 1e9, 2)
            row["floor_s_per_10s"] = round(f * per10 / rate, 4)
            row["ratio_to_floor"] = round(t / (f * per10 / rate), 2)
        rows.append(row)
    pipeline_stages = ["decode audio", "fbank", "speech encoders", "sampling", "motion decoder", "seams and poses"]
    total = sum(times[n] for n in pipeline_stages if n in times) * per10
    total_flops = sum(flops.values()) * per10
    return {"preset": preset, "precision": pipe.precision, "seconds": seconds, "windows": windows,
            "seam_candidates": 4, "ddim_steps": steps, "matmul_gflops": floor, "stages": rows,
            "generation_seconds_per_10s": round(total, 4), "generation_rtf": round(total / 10, 5),
            "generation_floor_s_per_10s": round(total_flops / rate, 4),
            "generation_ratio_to_floor": round(total / (total_flops / rate), 2)}


def drift(preset: str, seconds: float = 20.0, device: str = "cpu") -> dict:
    """bf16 autocast against float32 on the same clip and seed: the speech latents' largest relative
    difference, and the joint positions' mean and largest difference in mm (licence-free skeleton)."""
    import numpy as np

    from emogesture.motion import SkeletonBody

    work = fixtures.scratch_folder()
    model = fixtures.gesture_run(work, preset)
    out = {}
    for precision in ("fp32", "bf16"):
        pipe = GesturePipeline.from_run(model, device=device, precision=precision)
        wave = pipe.load_speech(fixtures.speech_file(work, seconds))
        enc, starts = pipe.encode(wave)
        seq = pipe.generate(wave, encoded=(enc, starts), generation=replace(pipe.generation, seam_candidates=1))[0]  # no discrete choice
        with torch.no_grad():
            joints = SkeletonBody()(torch.from_numpy(seq.poses), torch.from_numpy(seq.trans)).numpy()
        out[precision] = (np.concatenate([enc.content, enc.emotion, enc.style], 1), joints)
    (la, ja), (lb, jb) = out["fp32"], out["bf16"]
    rel = np.abs(lb - la).max() / np.abs(la).max()
    mm = np.linalg.norm(jb - ja, axis=-1) * 1000
    return {"preset": preset, "seconds": seconds, "latent_max_relative": round(float(rel), 5),
            "joint_mean_mm": round(float(mm.mean()), 3), "joint_max_mm": round(float(mm.max()), 3)}


def table(result: dict) -> str:
    head = (f"**{result['preset']}, {result['precision']}** ({result['seconds']:g}-s clip, {result['windows']} windows, "
            f"{result['seam_candidates']} seam candidates, {result['ddim_steps']} DDIM steps)\n\n"
            "| stage | s per 10 s | RTF | GFLOP per 10 s | floor, s | time / floor |\n|---|---|---|---|---|---|\n")
    lines = [f"| {r['stage']} | {r['seconds_per_10s']:.3f} | {r['rtf']:.4f} | {r.get('gflop_per_10s', '')} | "
             f"{r.get('floor_s_per_10s', '')} | {r.get('ratio_to_floor', '')} |" for r in result["stages"]]
    lines.append(f"| **generation (all but exports)** | {result['generation_seconds_per_10s']:.3f} | "
                 f"{result['generation_rtf']:.4f} | | {result['generation_floor_s_per_10s']} | "
                 f"{result['generation_ratio_to_floor']} |")
    return head + "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--preset", default="tiny", choices=["tiny", "paper"])
    ap.add_argument("--precision", default="fp32", choices=["fp32", "bf16"])
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--exports", action="store_true", help="also time the npz, bvh, glb, fbx and mp4 exports")
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--json", type=Path, help="write the result here")
    args = ap.parse_args()
    result = {"machine": machine.describe(args.device),
              **run(args.preset, args.precision, args.seconds, args.exports, device=args.device)}
    print(table(result))
    machine.write_json(args.json, result)


if __name__ == "__main__":
    main()
