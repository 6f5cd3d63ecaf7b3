"""Smoke test of bench/training.py: the training step it times runs on the presets' current inputs.

(It once crashed on the tiny gesture model, whose conditions end with the timing stream, and nothing
noticed: `make bench` is not part of the test suite.)"""

import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench"


@pytest.mark.parametrize("model", ["gesture", "speech"])
def test_training_throughput_runs_a_tiny_step(model, monkeypatch):
    monkeypatch.syspath_prepend(str(BENCH))
    sys.modules.pop("training", None)
    import training

    row = training.throughput(model, "tiny", "fp32", steps=1, batch=2)
    assert row["windows_per_second"] > 0 and row["windows_per_step"] == 2 * (4 if model == "speech" else 1)


def test_whole_process_benchmark_runs_and_leaves_no_scratch_folder(tmp_path):
    """bench/whole.py on two short clips, one run each after its untimed one, in a child process so that
    its scratch folder's removal at exit is seen (the benchmarks used to leave ~55 MB in /tmp)."""
    import json
    import os
    import subprocess

    env = {**os.environ, "TMPDIR": str(tmp_path), "OMP_NUM_THREADS": "1"}
    code = ("import sys, json; sys.path.insert(0, sys.argv[1]); import whole; "
            "r = whole.run('tiny', [1.0, 2.0], repeats=1); r['in_process'] = whole.in_process('tiny', (1.0, 2.0), "
            "repeats=1); r['real_speech'] = whole.real_speech('tiny', repeats=1); print(json.dumps(r)); "
            "print(whole.table(r))")
    out = subprocess.run([sys.executable, "-c", code, str(BENCH)], env=env, capture_output=True, text=True,
                         check=True).stdout
    result = json.loads(next(line for line in out.splitlines() if line.startswith("{")))
    assert [r["seconds"] for r in result["runs"]] == [1.0, 2.0]
    assert all(r["wall_s"] > 0 and r["peak_rss_gib"] > 0 for r in result["runs"])
    assert result["repeats"] == 1 and result["four_samples_s"] > 0 and "best of 1 after an untimed run" in out
    inner = result["in_process"]
    assert inner["lengths_s"] == [1.0, 2.0] and all(x > 0 for x in inner["ms_per_audio_second"]) and inner["ratio"] > 0
    assert "in one process (no start-up; best of 1, interleaved)" in out
    real = result["real_speech"]
    assert real["audio_s"] > 60 and 0 < real["front_end_s"] < real["generation_s"] and "real speech (" in out
    assert not list(tmp_path.glob("emogesture-bench-*"))


def test_the_comparison_with_another_checkout_alternates_fresh_processes(tmp_path):
    """bench/against.py with this checkout as the other one, one round on 1-s and 2-s clips: both codes timed
    at both lengths, the ratios made of their medians, the scratch folder gone."""
    import json
    import os
    import subprocess

    env = {**os.environ, "TMPDIR": str(tmp_path), "OMP_NUM_THREADS": "1"}
    out = tmp_path / "against.json"
    done = subprocess.run([sys.executable, str(BENCH / "against.py"), str(BENCH.parent), "--rounds", "1", "--lengths",
                           "1,2", "--json", str(out)], env=env, capture_output=True, text=True, check=True)
    result = json.loads(out.read_text())
    assert set(result["codes"]) == {"this", "other"} and result["lengths_s"] == [1.0, 2.0]
    for code in result["codes"].values():
        assert all(len(walls) == 1 and walls[0] > 0 for walls in code["wall_s"].values())
        assert code["marginal_rtf_of_medians"] == round(code["median_s"]["2.0"] - code["median_s"]["1.0"], 5)
    this, other = result["codes"]["this"], result["codes"]["other"]
    assert result["ratios"]["1_s_clip"] == round(this["median_s"]["1.0"] / other["median_s"]["1.0"], 3)
    assert "this / other, 1 rounds" in done.stdout
    assert not list(tmp_path.glob("emogesture-bench-*"))
    bad = subprocess.run([sys.executable, str(BENCH / "against.py"), str(tmp_path)], capture_output=True, text=True)
    assert bad.returncode != 0 and "give the root of an emogesture checkout" in bad.stderr


def test_augmentation_benchmark_times_every_transform_and_both_recipe_stages(monkeypatch):
    monkeypatch.syspath_prepend(str(BENCH))
    sys.modules.pop("augment", None)
    import augment

    result = augment.measure(repeats=1)
    assert set(result["stages"]) == set(augment.STAGES) and len(result["transforms_ms"]) == 9
    assert all(v > 0 for v in result["transforms_ms"].values())
    # the second stage augments more windows, and more heavily, than the first
    first, second = (result["stages"][k] for k in augment.STAGES)
    assert second["augmented_share"] > first["augmented_share"] and second["core_s_per_step"] > 0
    assert "| recipe stage |" in augment.markdown(result)
