"""Gesture evaluation end to end on a small fixture: extractor training, baselines, foreign npz files."""

import json
import subprocess

import numpy as np
import pytest

from emogesture.data.beat import write_split_csv
from emogesture.data.prepare import prepare

from helpers import cli, cli_here, make_root


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    d = tmp_path_factory.mktemp("geval")
    names = make_root(d / "root", speakers=(1, 2), takes=(1, 2, 65, 66))
    write_split_csv(d / "root" / "train_test_split.csv",
                    {n: "test" if n.split("_")[3] in ("2", "66") else "train" for n in names})
    prepare(d / "root", d / "cache", progress=False)
    out = subprocess.run(cli("train", "extractor", "--data", d / "cache", "--out", d / "ext", "--steps", 10, "--quiet"),
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-2000:]
    return d


def test_foreign_npz_files_score_like_the_ground_truth(trained, tmp_path, capsys):
    d = trained
    foreign = tmp_path / "other_tool"
    foreign.mkdir()
    for src in sorted((d / "root" / "smplxflame_30").glob("*.npz")):
        with np.load(src) as z:
            poses = z["poses"].astype(np.float64)
            trans = z["trans"].astype(np.float64)
        # another tool's file: float64, (T, 55, 3) poses, extra keys, np.savez
        np.savez(foreign / src.name, poses=poses.reshape(-1, 55, 3), trans=trans, betas=np.zeros(10),
                 mocap_frame_rate=np.array(30.0), exporter=np.array("other-tool 1.0"), fps=np.array(30))
    out = cli_here(capsys, "evaluate", "gesture", "--data", d / "cache", "--extractor", d / "ext",
                   "--source", f"other={foreign}", "--out", tmp_path / "report")
    assert out.returncode == 0, out.stderr[-2000:]
    r = json.loads((tmp_path / "report" / "gesture_test.json").read_text())
    rows = r["rows"]
    assert set(rows) == {"GT", "mean pose", "GT, mismatched audio", "GT, shifted 1 s", "other"}
    assert rows["other"]["FGD"] < 1e-3 and rows["other"]["SRGR"] == pytest.approx(rows["GT"]["SRGR"], abs=1e-6)
    assert rows["mean pose"]["FGD"] > 10 * max(rows["other"]["FGD"], 1e-3)
    assert rows["mean pose"]["Div"] < 1e-6 < rows["GT"]["Div"]
    assert rows["mean pose"]["Jerk"] < 1e-6 and rows["mean pose"]["Speed"] < 1e-6
    assert rows["GT"]["Speed"] > 0.01
    # the baselines order as they must: real motion of the wrong moment is farther from the take's own
    # motion (SRGR) the farther it comes from (1 s later < another text), and nearer than the mean pose (FGD)
    shifted, mismatched = rows["GT, shifted 1 s"], rows["GT, mismatched audio"]
    assert rows["GT"]["FGD"] < 1e-3 < min(shifted["FGD"], mismatched["FGD"])
    assert max(shifted["FGD"], mismatched["FGD"]) < rows["mean pose"]["FGD"]
    assert rows["GT"]["SRGR"] > shifted["SRGR"] > mismatched["SRGR"]
    assert r["split_use"]["held_out"] and r["split_use"]["trained_on"] == {"extractor": ["train"]}
    stats = r["motion_stats"]  # motion-stats of every source: the foreign copy moves like the ground truth
    assert stats["other"]["wrist_speed_mean"] == pytest.approx(stats["GT"]["wrist_speed_mean"], rel=1e-4)
    assert stats["mean pose"]["wrist_speed_mean"] == 0.0 < stats["GT"]["wrist_speed_mean"]
    assert "## Motion statistics" in (tmp_path / "report" / "gesture_test.md").read_text()
    md = (tmp_path / "report" / "gesture_test.md").read_text()
    assert "| other |" in md and "beat_sigma_s" in md
    assert (tmp_path / "report" / "gesture_test_other_emotion_confusion.png").read_bytes()[:4] == b"\x89PNG"
    again = cli_here(capsys, "evaluate", "gesture", "--data", d / "cache", "--extractor", d / "ext",
                     "--out", tmp_path / "report")
    assert again.returncode == 2 and "--overwrite" in again.stderr


def test_missing_take_in_a_source_names_the_file(trained, tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    out = cli_here(capsys, "evaluate", "gesture", "--data", trained / "cache", "--extractor", trained / "ext",
                   "--source", f"x={tmp_path / 'empty'}", "--out", tmp_path / "r")
    assert out.returncode == 2 and "missing" in out.stderr and ".npz" in out.stderr
    assert len(out.stderr.strip().splitlines()) == 1


def test_the_extractor_reads_the_rotations_the_body_shows(trained):
    """A decoder's 6D output need not be orthonormal; what is scored is the rotation it stands for."""
    from emogesture.checkpoints import load_model
    from emogesture.data.cache import open_cache
    from emogesture.eval.gesture import GestureEvaluator

    ev = GestureEvaluator(open_cache(trained / "cache"), "test", load_model(trained / "ext", "extractor"))
    gt = np.asarray(ev.windows.motion, np.float32)
    n = gt.shape[-1] // 6
    six = gt.reshape(*gt.shape[:-1], n, 2, 3)
    rng = np.random.default_rng(0)
    scale = rng.uniform(0.5, 2.0, size=(*six.shape[:-1], 1)).astype(np.float32)  # each column's own length
    skewed = six * scale
    skewed[..., 1, :] += 0.3 * skewed[..., 0, :]  # and the second column leaning on the first
    skewed = skewed.reshape(gt.shape)
    row, _ = ev.score(skewed)
    own, _ = ev.score(gt)
    assert row["FGD"] < 1e-3 and row["GA"] == own["GA"] and row["Speed"] == pytest.approx(own["Speed"], rel=1e-4)
