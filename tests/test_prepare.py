"""`emogesture prepare`: cache layout, idempotence, resume after a kill, bad input."""

import signal
import subprocess
import sys

import numpy as np
import pytest
import soundfile as sf

from emogesture.data.cache import open_cache
from emogesture.data.prepare import PrepareConfig, prepare
from emogesture.errors import EmogestureError, InputFileError
from helpers import cli, make_root


def test_layout_and_contents(tmp_path):
    names = make_root(tmp_path / "root")
    res = prepare(tmp_path / "root", tmp_path / "cache", progress=False)
    assert res.assembled and res.takes_processed == len(names) == res.takes_total
    cache = open_cache(tmp_path / "cache")
    assert set(cache.splits) == {"train", "test"}
    train, test = cache.split("train"), cache.split("test")
    # 21 s takes: training windows every 5 s (0, 5, 10), evaluation windows every 10 s (0, 10)
    assert len(train) == 4 * 3 and len(test) == 4 * 2
    assert train.fbank.shape == (12, 1024, 128) and train.fbank.dtype == np.float16
    assert train.motion.shape == (12, 300, 282) and train.sem.shape == (12, 300)
    # the normalised fbank has roughly zero mean / half unit std on the training split (mean/(2 std))
    fb = np.asarray(train.fbank, np.float32)
    assert abs(fb.mean()) < 0.1 and 0.35 < fb.std() < 0.65
    assert sorted(set(train.emotion.tolist())) == [0, 1]  # takes 1 (neutral) and 65 (happiness)
    assert set(train.speaker_id.tolist()) == {1, 2}
    # motion windows are the right slices of the take's features
    from emogesture.motion import MotionFeatureSpec, load_smplx_npz, poses_to_features
    import torch
    i = train.takes.index(names[0]) + 1  # second window of the first take starts at 5 s
    assert train.start_s[i] == 5.0
    seq = load_smplx_npz(tmp_path / "root" / "smplxflame_30" / f"{names[0]}.npz")
    feats = poses_to_features(torch.from_numpy(seq.poses), MotionFeatureSpec()).numpy()
    np.testing.assert_allclose(train.motion[i], feats[150:450], atol=1e-6)
    # semantic scores: 1.0-2.0 s at 0.5 in the first window, nothing in the second
    assert train.sem[i - 1][30:60].min() == pytest.approx(0.5) and train.sem[i].max() == 0
    assert len(cache.stats["motion_mean"]) == 282


def test_second_run_does_nothing(tmp_path):
    make_root(tmp_path / "root")
    prepare(tmp_path / "root", tmp_path / "cache", progress=False)
    stamp = {p: p.stat().st_mtime_ns for p in (tmp_path / "cache").rglob("*") if p.is_file()}
    res = prepare(tmp_path / "root", tmp_path / "cache", progress=False)
    assert res.takes_processed == 0 and not res.assembled
    assert {p: p.stat().st_mtime_ns for p in (tmp_path / "cache").rglob("*") if p.is_file()} == stamp


def test_changed_source_takes_are_prepared_again(tmp_path):
    make_root(tmp_path / "root")
    prepare(tmp_path / "root", tmp_path / "cache", progress=False)
    before = open_cache(tmp_path / "cache").split("train")
    wav = tmp_path / "root" / "wave16k" / f"{before.takes[0]}.wav"
    wave, sr = sf.read(wav, dtype="float32")
    sf.write(wav, 0.5 * wave, sr)  # the same take, rewritten 6 dB quieter
    res = prepare(tmp_path / "root", tmp_path / "cache", progress=False)
    assert res.takes_processed == 1 and res.assembled
    after = open_cache(tmp_path / "cache").split("train")
    first = [i for i, t in enumerate(after.takes) if t == before.takes[0]]
    assert not np.array_equal(after.fbank[first], before.fbank[first])
    assert np.array_equal(after.motion, before.motion)
    split = tmp_path / "root" / "train_test_split.csv"
    split.write_text(split.read_text().replace(",test", ",train"))  # every take now trains
    res = prepare(tmp_path / "root", tmp_path / "cache", progress=False)
    assert res.takes_processed == 0 and res.assembled
    assert open_cache(tmp_path / "cache").manifest["splits"]["test"] == 0


def test_other_settings_into_the_same_cache_are_refused(tmp_path):
    make_root(tmp_path / "root")
    prepare(tmp_path / "root", tmp_path / "cache", progress=False)
    with pytest.raises(EmogestureError, match="other settings"):
        prepare(tmp_path / "root", tmp_path / "cache", PrepareConfig(hop_seconds=2.5), progress=False)


# `emogesture prepare` that SIGKILLs itself as soon as its third take file is in place: a kill midway at a
# fixed point, with no clean-up of any kind, instead of a race between the command and a watcher
KILLED_AFTER_THREE_TAKES = """
import os, signal, sys
import emogesture.data.prepare as prepare_module
from emogesture.cli.main import main

write = prepare_module.write_npz_atomic
written = []

def write_then_die(path, *args, **kwargs):
    out = write(path, *args, **kwargs)
    written.append(path)
    if len(written) == 3:
        os.kill(os.getpid(), signal.SIGKILL)
    return out

prepare_module.write_npz_atomic = write_then_die
sys.exit(main(sys.argv[1:]))
"""


def test_killed_midway_resumes_to_the_same_result(tmp_path):
    make_root(tmp_path / "root", speakers=(1, 2, 3, 4, 5), takes=(1, 2, 3, 65, 66, 67))
    prepare(tmp_path / "root", tmp_path / "clean", progress=False)

    command = [sys.executable, "-c", KILLED_AFTER_THREE_TAKES, "prepare", str(tmp_path / "root"),
               "--out", str(tmp_path / "cache"), "--quiet"]
    proc = subprocess.run(command, capture_output=True, text=True, timeout=600)
    assert proc.returncode == -signal.SIGKILL, f"prepare was not killed midway: {proc.stderr[-2000:]}"
    takes = tmp_path / "cache" / "takes"
    done = len(list(takes.glob("*.npz")))
    assert done == 3 and not (tmp_path / "cache" / "manifest.json").exists()

    res = prepare(tmp_path / "root", tmp_path / "cache", progress=False)
    assert res.takes_processed == 30 - done  # resumed, not restarted
    a, b = open_cache(tmp_path / "clean"), open_cache(tmp_path / "cache")
    for split in ("train", "test"):
        sa, sb = a.split(split), b.split(split)
        assert sa.takes == sb.takes
        for key in ("fbank", "motion", "sem"):
            assert np.array_equal(getattr(sa, key), getattr(sb, key)), (split, key)
    assert a.stats == b.stats


def test_bad_roots_are_one_line_errors(tmp_path):
    with pytest.raises(InputFileError, match="nowhere"):
        prepare(tmp_path / "nowhere", tmp_path / "cache", progress=False)
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputFileError, match="smplxflame_30"):
        prepare(tmp_path / "empty", tmp_path / "cache2", progress=False)
    proc = subprocess.run(cli("prepare", tmp_path / "empty", "--out", tmp_path / "cache3"),
                          capture_output=True, text=True)
    assert proc.returncode == 2
    assert len(proc.stderr.strip().splitlines()) == 1 and "smplxflame_30" in proc.stderr


def test_corrupt_take_names_the_file(tmp_path):
    names = make_root(tmp_path / "root", speakers=(1,), takes=(1, 65))
    (tmp_path / "root" / "wave16k" / f"{names[0]}.wav").write_bytes(b"RIFF garbage")
    with pytest.raises(InputFileError, match=names[0]):
        prepare(tmp_path / "root", tmp_path / "cache", progress=False)


def test_a_cache_folder_that_cannot_be_made_is_one_line(tmp_path):
    (tmp_path / "link").symlink_to(tmp_path / "nowhere")
    with pytest.raises(EmogestureError, match="link: cannot create the cache folder"):
        prepare(tmp_path, tmp_path / "link", PrepareConfig())
