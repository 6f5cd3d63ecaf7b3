"""Many recordings in one `generate`: a bad file does not stop the others, a killed batch resumes with
--skip-existing and gives the files an uninterrupted run gives, and generation is bit-reproducible across
processes at two threads (the bundled model, short clips of the demo speech)."""

import os
import subprocess

import pytest
import soundfile as sf

from emogesture.assets import DEMO_CLIPS
from emogesture.errors import EmogestureError, InputFileError
from emogesture.pipeline.animate import AnimationRequest
from emogesture.pipeline.batch import animate_files, batch_summary, speech_files

from helpers import cli, cli_here


@pytest.fixture(scope="module")
def talks(tmp_path_factory):
    """A folder with two 5-s clips of the demo speech and a file that is not audio."""
    d = tmp_path_factory.mktemp("talks")
    wave, sr = sf.read(DEMO_CLIPS / "talk.flac", dtype="float32")
    sf.write(d / "a.wav", wave[: 5 * sr], sr)
    sf.write(d / "b.flac", wave[5 * sr: 10 * sr], sr)
    (d / "c.wav").write_bytes(b"not audio at all")
    (d / "notes.txt").write_text("not a recording")
    return d


def generate(*args, threads=2):
    env = {**os.environ, "OMP_NUM_THREADS": str(threads)}
    return subprocess.run(cli("generate", *args, "--format", "npz,bvh", "--quiet"), capture_output=True, text=True,
                          env=env)


def generate_here(capsys, *args) -> tuple[int, str, str]:
    """``generate`` in this process (no start-up of its own): exit status, stdout, stderr."""
    return cli_here(capsys, "generate", *args, "--format", "npz,bvh", "--quiet")


def test_a_batch_goes_on_past_a_bad_file_and_a_killed_one_resumes(talks, tmp_path, capsys):
    out = generate(talks, "-o", tmp_path / "o")
    assert out.returncode == 2
    assert out.stderr.strip().splitlines() == [out.stderr.strip()] and "c.wav" in out.stderr  # one line
    assert "Traceback" not in out.stderr and "2 of 3 recordings animated, 1 failed" in out.stdout
    files = {p.name: p.read_bytes() for p in (tmp_path / "o").iterdir()}
    assert sorted(files) == ["a_seed0_0.bvh", "a_seed0_0.npz", "a_seed0_perception.json",
                             "b_seed0_0.bvh", "b_seed0_0.npz", "b_seed0_perception.json"]

    # a batch killed part-way: one recording's npz and another's report are missing; the rest in this process
    (tmp_path / "o" / "a_seed0_0.npz").unlink()
    (tmp_path / "o" / "b_seed0_perception.json").unlink()
    kept = (tmp_path / "o" / "a_seed0_0.bvh").stat().st_mtime_ns
    code, stdout, stderr = generate_here(capsys, talks / "a.wav", talks / "b.flac", "-o", tmp_path / "o",
                                         "--skip-existing")
    assert code == 0, stderr
    assert {p.name: p.read_bytes() for p in (tmp_path / "o").iterdir()} == files  # as the uninterrupted run
    assert (tmp_path / "o" / "a_seed0_0.bvh").stat().st_mtime_ns == kept  # what existed was left alone
    code, stdout, _ = generate_here(capsys, talks / "a.wav", talks / "b.flac", "-o", tmp_path / "o", "--skip-existing")
    assert code == 0 and "0 of 2 recordings animated, 2 already done (skipped)" in stdout

    # neither flag: nothing replaced
    code, stdout, stderr = generate_here(capsys, talks / "a.wav", talks / "b.flac", "-o", tmp_path / "o")
    assert code == 2 and stderr.count("already exists") == 2 and "0 of 2" in stdout
    assert {p.name: p.read_bytes() for p in (tmp_path / "o").iterdir()} == files
    code, _, stderr = generate_here(capsys, talks / "a.wav", "-o", tmp_path / "o", "--skip-existing", "--overwrite")
    assert code == 2 and "choose one" in stderr


def test_generation_is_bit_reproducible_in_fresh_processes_at_two_threads(talks, tmp_path):
    for k in range(3):
        out = generate(talks / "b.flac", "-o", tmp_path / str(k), "--emotion", "anger", "--seed", "3")
        assert out.returncode == 0, out.stderr
    runs = [(tmp_path / str(k) / "b_emotion-anger_seed3_0.npz").read_bytes() for k in range(3)]
    assert runs[0] == runs[1] == runs[2]


def test_inputs_are_expanded_and_clashing_outputs_refused(talks, tmp_path):
    assert [p.name for p in speech_files([talks, talks / "a.wav"])] == ["a.wav", "b.flac", "c.wav"]
    with pytest.raises(InputFileError, match="none.wav: not found"):
        speech_files([talks / "none.wav"])
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputFileError, match="empty: holds no audio files"):
        speech_files([tmp_path / "empty"])
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "a.flac").write_bytes((talks / "b.flac").read_bytes())
    with pytest.raises(EmogestureError, match="a.wav and .*a.flac would both write a_seed0_0.npz"):
        animate_files(None, [talks / "a.wav", tmp_path / "other" / "a.flac"],
                      AnimationRequest("", tmp_path / "o", formats="npz"))


def test_batch_summary_counts():
    from emogesture.pipeline.animate import AnimationResult
    from emogesture.pipeline.batch import BatchItem

    skipped = AnimationResult([], None, [], [], [], skipped=True)
    items = [BatchItem("a", error="a: broken"), BatchItem("b", result=skipped), BatchItem("c", result=skipped),
             BatchItem("d", result=AnimationResult([], None, [], [], []))]
    assert batch_summary(items) == "1 of 4 recordings animated, 2 already done (skipped), 1 failed"
