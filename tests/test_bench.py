"""Smoke test of bench/training.py: the training step it times runs on the presets' current inputs.

(It crashed on the tiny gesture model from issue 18 on, whose conditions end with the timing stream,
and nothing noticed: `make bench` is not part of the test suite.)"""

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
