"""Whole-process ``emogesture generate``: wall time and peak resident memory, per preset and audio length.

Each run is a fresh process (start-up, imports and model loading included), writing npz only (the
exports are timed by ``stages.py``): wall clock, and the child's peak resident memory (VmHWM). One
untimed run comes first, so that every timed run finds torch's libraries in the file cache, as a
user's second run does (the first run after a reboot reads about 1 GB of libraries from disk); each
length and setting is then run ``repeats`` times and the best wall time kept (single runs vary by
±10 % here, and the first timed run used to be the cold one).
Also reported: the marginal real-time factor (extra seconds per extra second of audio, between the two
longest clips), the scaling exponent between them (1 = linear), 4 samples against one, and an emotion
edit (``--emotion-from`` another recording of the same length; ``--emotion LABEL``) against plain generation.
The linearity is also measured without the start-up (:func:`in_process`): a 1.9-s start-up that varies
by ±0.1 s hides the 60-s clip's 0.3 s of work, so the whole-process ratio is mostly that noise for tiny.

Usage: python bench/whole.py [--preset tiny|paper] [--lengths 10,60,600] [--precision auto|fp32|bf16]
                             [--repeats N] [--in-process] [--real-speech] [--json OUT]
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import fixtures  # noqa: E402
import machine  # noqa: E402

EG = [sys.executable, "-m", "emogesture.cli.main"]


def peak_rss_kib(pid: int) -> int | None:
    """The high-water mark of a running process's resident memory (``VmHWM``, KiB), or None."""
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


def timed(args: list[str]) -> tuple[float, float]:
    """Run ``emogesture ARGS``: (wall seconds, peak RSS GiB); a failure stops the benchmark with its output.

    The peak is the child's ``VmHWM``, read every 20 ms until it exits (``wait4``'s ``ru_maxrss`` would
    count the benchmark's own memory, which the forked child holds until it execs)."""
    t0 = time.perf_counter()
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        proc = subprocess.Popen(EG + args, stdout=out, stderr=err)
        peak = 0
        while proc.poll() is None:
            hwm = peak_rss_kib(proc.pid)
            # the first reads may still see the forked copy of this process, before exec
            if hwm is not None and time.perf_counter() - t0 > 0.2:
                peak = max(peak, hwm)
            time.sleep(0.02)
        wall = time.perf_counter() - t0
        if proc.returncode:
            out.seek(0)
            err.seek(0)
            sys.exit(f"emogesture {' '.join(args)} failed ({proc.returncode}):\n{out.read().decode()}\n"
                     f"{err.read().decode()}")
    return wall, peak / 2**20


def run(preset: str, lengths: list[float], precision: str = "auto", device: str = "cpu",
        repeats: int = 2) -> dict:
    """``repeats``: runs per length and per setting of the ratios (the best wall time is kept, with the
    largest peak memory of those runs)."""
    work = fixtures.scratch_folder()
    model = fixtures.gesture_run(work, preset)
    base = ["generate", "--model", str(model), "--format", "npz", "--overwrite", "--quiet",
            "--precision", precision, "--device", device]
    rows = []
    timed([*base, str(fixtures.speech_file(work, lengths[0])), "-o", str(work / "out")])  # warm the file cache
    for seconds in lengths:
        speech = fixtures.speech_file(work, seconds)
        runs = [timed([*base, str(speech), "-o", str(work / "out")]) for _ in range(repeats)]
        wall, rss = min(r[0] for r in runs), max(r[1] for r in runs)
        rows.append({"seconds": seconds, "wall_s": round(wall, 2), "peak_rss_gib": round(rss, 3)})
        print(f"{preset} {seconds:g} s: {wall:.2f} s wall, {rss:.2f} GiB peak", flush=True)
    a, b = rows[-2], rows[-1]
    marginal = (b["wall_s"] - a["wall_s"]) / (b["seconds"] - a["seconds"])
    exponent = math.log(b["wall_s"] / a["wall_s"]) / math.log(b["seconds"] / a["seconds"])
    # linearity: time per second of audio beyond start-up (the shortest clip's time) at the longer lengths
    startup = rows[0]["wall_s"]
    per_s = [(r["wall_s"] - startup) / (r["seconds"] - rows[0]["seconds"]) for r in rows[1:]]
    mid = fixtures.speech_file(work, lengths[1] if len(lengths) > 2 else lengths[0])
    other = fixtures.speech_file(work, lengths[1] if len(lengths) > 2 else lengths[0])

    def best(extra: list[str], name: str) -> float:
        return min(timed([*base, str(mid), "-o", str(work / name), *extra])[0] for _ in range(repeats))

    plain = best([], "plain")
    four = best(["--samples", "4"], "four")
    label = best(["--emotion", "happiness"], "label")
    edit = best(["--emotion-from", str(other)], "edit")
    mid_s = lengths[1] if len(lengths) > 2 else lengths[0]
    return {"preset": preset, "precision": precision, "runs": rows,
            "marginal_rtf": round(marginal, 4), "scaling_exponent": round(exponent, 3),
            "seconds_per_audio_second": [round(x, 4) for x in per_s],
            "linearity": round(per_s[-1] / per_s[0], 3) if len(per_s) > 1 and per_s[0] > 0 else None,
            "clip_for_ratios_s": mid_s, "repeats": repeats, "one_sample_s": round(plain, 2), "four_samples_s": round(four, 2),
            "four_over_one": round(four / plain, 3), "emotion_label_s": round(label, 2),
            "emotion_label_over_plain": round(label / plain, 3), "emotion_from_s": round(edit, 2),
            "emotion_from_over_plain": round(edit / plain, 3)}


def in_process(preset: str, lengths: tuple[float, float] = (60.0, 600.0), precision: str = "auto",
               device: str = "cpu", repeats: int = 3) -> dict:
    """Linearity without the start-up: ``GesturePipeline.generate`` on each length in one process
    (models loaded once, one untimed run first), the lengths interleaved ``repeats`` times and the best
    kept: milliseconds per audio second at each length, and their ratio (long / short)."""
    from emogesture.audio import load_audio
    from emogesture.pipeline.generate import GesturePipeline

    work = fixtures.scratch_folder()
    pipe = GesturePipeline.from_run(fixtures.gesture_run(work, preset), precision=precision, device=device)
    waves = [load_audio(fixtures.speech_file(work, s))[0] for s in lengths]
    pipe.generate(waves[0][: 10 * 16000], seed=0)
    best = [math.inf] * len(lengths)
    for _ in range(repeats):
        for i, (seconds, wave) in enumerate(zip(lengths, waves)):
            t0 = time.perf_counter()
            pipe.generate(wave, seed=0)
            best[i] = min(best[i], (time.perf_counter() - t0) / seconds * 1000)
    return {"lengths_s": list(lengths), "ms_per_audio_second": [round(x, 2) for x in best],
            "ratio": round(best[-1] / best[0], 3), "repeats": repeats}


def real_speech(preset: str = "tiny", precision: str = "auto", device: str = "cpu", repeats: int = 2) -> dict:
    """``GesturePipeline.generate`` in one process on each real recording of
    :mod:`emogesture.data.real_speech` (voices the perception does not always trust, so the front end trained on
    real speech hears some of their windows): audio seconds, generation seconds (best of ``repeats``) and the
    front end's share (its ``voice features`` stage, the model loaded on first use and counted in the first,
    untimed run), summed over the recordings; their real-time factor."""
    from emogesture.data.real_speech import RECORDINGS, load_real_recording
    from emogesture.pipeline.generate import GesturePipeline
    from emogesture.runtime import StageTimes

    pipe = GesturePipeline.from_run(fixtures.gesture_run(fixtures.scratch_folder(), preset), precision=precision,
                                    device=device)
    audio = generation = heard = 0.0
    for recording in RECORDINGS:
        wave = load_real_recording(recording)
        pipe.generate(wave, seed=0)
        runs = []
        for _ in range(repeats):
            times = StageTimes()
            t0 = time.perf_counter()
            pipe.generate(wave, seed=0, times=times)
            runs.append((time.perf_counter() - t0, times.get("voice features", 0.0)))
        wall, front = min(runs)
        audio, generation, heard = audio + len(wave) / 16000, generation + wall, heard + front
    return {"recordings": [r.name for r in RECORDINGS], "audio_s": round(audio, 1), "generation_s": round(generation, 2),
            "front_end_s": round(heard, 2), "rtf": round(generation / audio, 4), "repeats": repeats}


def table(result: dict) -> str:
    lines = [f"**{result['preset']}** (precision {result['precision']}; whole process, npz only; best of "
             f"{result.get('repeats', 1)} after an untimed run)\n",
             "| audio | wall | peak RSS |", "|---|---|---|"]
    lines += [f"| {r['seconds']:g} s | {r['wall_s']:.2f} s | {r['peak_rss_gib']:.2f} GiB |" for r in result["runs"]]
    lines += ["", f"marginal RTF {result['marginal_rtf']}, scaling exponent {result['scaling_exponent']}, "
              f"time per audio second beyond start-up {result['seconds_per_audio_second']} "
              f"(ratio {result['linearity']}); on the {result['clip_for_ratios_s']:g}-s clip: 4 samples / 1 = "
              f"{result['four_over_one']}, --emotion LABEL / plain = {result['emotion_label_over_plain']}, "
              f"--emotion-from / plain = {result['emotion_from_over_plain']}"]
    if "in_process" in result:
        r = result["in_process"]
        lines += ["", f"in one process (no start-up; best of {r['repeats']}, interleaved): "
                  f"{' / '.join(f'{x} ms' for x in r['ms_per_audio_second'])} per audio second at "
                  f"{' / '.join(f'{s:g} s' for s in r['lengths_s'])} (ratio {r['ratio']})"]
    if "real_speech" in result:
        r = result["real_speech"]
        lines += ["", f"real speech ({', '.join(r['recordings'])}; {r['audio_s']:g} s, in one process, best of "
                  f"{r['repeats']}): {r['generation_s']} s, RTF {r['rtf']}, of which the front end trained on real "
                  f"speech {r['front_end_s']} s"]
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--preset", default="tiny", choices=["tiny", "paper"])
    ap.add_argument("--lengths", default="10,60,600", help="seconds of audio, comma-separated (default 10,60,600)")
    ap.add_argument("--precision", default="auto", choices=["auto", "fp32", "bf16"])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--repeats", type=int, default=2, help="runs per length and setting, the best kept (default 2)")
    ap.add_argument("--in-process", action="store_true",
                    help="also measure the linearity in one process (the two longest lengths)")
    ap.add_argument("--real-speech", action="store_true",
                    help="also generate for the packaged real recordings in one process (the front end's share)")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    lengths = [float(x) for x in args.lengths.split(",")]
    result = {"machine": machine.describe(args.device),
              **run(args.preset, lengths, args.precision, args.device, args.repeats)}
    if args.in_process:
        result["in_process"] = in_process(args.preset, tuple(lengths[-2:]), args.precision, args.device)
    if args.real_speech:
        result["real_speech"] = real_speech(args.preset, args.precision, args.device, args.repeats)
    print(table(result))
    machine.write_json(args.json, result)


if __name__ == "__main__":
    main()
