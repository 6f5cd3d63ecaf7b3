"""Exports of an SMPLXSequence: BVH (checked with an independent reader and with real Blender) and MP4."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import torch

from emogesture.cli.main import main
from emogesture.errors import EmogestureError, OutputExistsError
from emogesture.export import export_sequence, parse_formats, save_bvh, save_mp4
from emogesture.export.video import Camera, MannequinRenderer
from emogesture.motion import JOINT_NAMES, axis_angle_to_matrix, save_smplx_npz
from emogesture.types import SMPLXSequence

from helpers import fk, gesture_like

RIGHT_WRIST = JOINT_NAMES.index("right_wrist")


def test_bvh_read_by_bvhio_matches_channels_and_forward_kinematics(tmp_path):
    bvhio = pytest.importorskip("bvhio")
    import glm

    seq = gesture_like()
    path = save_bvh(seq, tmp_path / "a.bvh")
    bvh = bvhio.readAsBvh(str(path))
    assert bvh.FrameCount == seq.num_frames
    assert bvh.FrameTime == pytest.approx(1 / 30, abs=1e-6)
    joints = {j.Name: j for j, _, _ in bvh.Root.layout()}
    assert set(joints) == set(JOINT_NAMES)
    local = axis_angle_to_matrix(torch.from_numpy(seq.poses).double()).numpy()
    worst = 0.0
    for i, name in enumerate(JOINT_NAMES):
        for f in range(seq.num_frames):
            m = np.array(glm.mat3_cast(joints[name].Keyframes[f].Rotation).to_list()).T  # glm is column-major
            worst = max(worst, np.abs(m - local[f, i]).max())
    assert worst < 1e-4
    root_pos = np.array([list(k.Position) for k in joints["pelvis"].Keyframes])
    assert np.abs(root_pos - (fk(seq)[:, 0])).max() < 1e-4

    hierarchy = bvhio.readAsHierarchy(str(path))
    layout = {j.Name: j for j, _, _ in hierarchy.layout()}
    ours = fk(seq)
    errors = []
    for f in range(seq.num_frames):
        hierarchy.loadPose(f)
        pos = np.array([list(layout[n].PositionWorld) for n in JOINT_NAMES])
        errors.append(np.linalg.norm(pos - ours[f], axis=-1).max())
    assert max(errors) < 1e-3  # 1 mm


def test_bvh_text_layout(tmp_path):
    seq = gesture_like(frames=3)
    text = save_bvh(seq, tmp_path / "b.bvh").read_text()
    assert text.startswith("HIERARCHY\nROOT pelvis\n")
    assert "CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation" in text
    assert text.count("CHANNELS 3 Zrotation Yrotation Xrotation") == 54
    motion = text.split("MOTION\n")[1].splitlines()
    assert motion[0] == "Frames: 3" and motion[1].startswith("Frame Time: 0.0333")
    assert all(len(line.split()) == 3 + 3 * 55 for line in motion[2:]) and len(motion) == 5


def _blender() -> str | None:
    found = shutil.which("blender")
    if found is None and os.environ.get("CI"):
        pytest.fail("blender is not installed (make test installs Debian's package)")
    return found


@pytest.mark.training
def test_bvh_in_real_blender(tmp_path):
    blender = _blender()
    if blender is None:
        pytest.skip("blender not installed (make test installs it)")
    seq = gesture_like(frames=40, seed=3)
    path = save_bvh(seq, tmp_path / "c.bvh")
    out = tmp_path / "blender.json"
    frames = [1, 10, 25, 40]
    script = Path(__file__).parent / "blender" / "import_bvh.py"
    proc = subprocess.run([blender, "-b", "--factory-startup", "--python", str(script), "--", str(path), str(out),
                           *map(str, frames)], capture_output=True, text=True, timeout=300)
    assert out.is_file(), proc.stdout[-2000:] + proc.stderr[-2000:]
    got = json.loads(out.read_text())
    assert got["bones"] == 55
    assert got["action_frame_range"] == [1.0, 40.0]
    assert got["fps"] == pytest.approx(30, abs=1e-3)
    ours = fk(seq)
    for f in frames:
        b = np.array(got["heads"][str(f)]["right_wrist"])  # Blender: Z up; ours: Y up -> (x, -z, y)
        o = ours[f - 1, RIGHT_WRIST]
        assert np.linalg.norm(b - np.array([o[0], -o[2], o[1]])) < 0.01


def _probe(path: Path) -> dict:
    proc = subprocess.run(["ffprobe", "-v", "error", "-count_frames", "-show_streams", "-of", "json", str(path)],
                          capture_output=True, text=True, check=True)
    return {s["codec_type"]: s for s in json.loads(proc.stdout)["streams"]}


def _decode_frame(path: Path, index: int, width: int, height: int) -> np.ndarray:
    proc = subprocess.run(["ffmpeg", "-v", "error", "-i", str(path), "-vf", f"select=eq(n\\,{index})", "-vframes", "1",
                           "-f", "rawvideo", "-pix_fmt", "rgb24", "pipe:1"], capture_output=True, check=True)
    return np.frombuffer(proc.stdout, np.uint8).reshape(height, width, 3)


@pytest.mark.training
def test_mp4_stream_and_known_pose(tmp_path):
    rng = np.random.default_rng(1)
    duration = 2.5
    audio = (0.1 * rng.normal(size=int(16000 * duration))).astype(np.float32)
    frames = int(round(duration * 30))
    seq = gesture_like(frames=frames)
    seq.poses[10] = 0.0  # the rest pose at frame 10
    seq.poses[10, 17] = [0.0, 0.0, 1.2]  # right shoulder raised: the arm up and out
    path = save_mp4(seq, tmp_path / "v.mp4", audio=(audio, 16000), label="v.wav\nseed 0")
    streams = _probe(path)
    video, sound = streams["video"], streams["audio"]
    assert video["codec_name"] == "h264" and video["pix_fmt"] == "yuv420p"
    assert video["r_frame_rate"] == "30/1"
    assert int(video["nb_read_frames"]) == frames
    assert sound["codec_name"] == "aac"
    assert float(sound["duration"]) == pytest.approx(duration, abs=0.1)

    renderer = MannequinRenderer()
    camera = Camera.upper_body(seq)
    reference = renderer.draw(fk(seq)[10].astype(np.float64), camera)
    decoded = _decode_frame(path, 10, 640, 480).astype(np.float64)
    assert np.abs(decoded[200:] - reference[200:]).mean() < 4.0  # below the label; H.264 at crf 20
    # the right wrist is drawn where it projects, the background stays background
    (u, v), _ = camera.project(fk(seq)[10, RIGHT_WRIST].astype(np.float64))
    u, v = int(round(u)), int(round(v))
    background = renderer.background[v, u].astype(np.float64)
    assert np.abs(decoded[v, u] - background).sum() > 60
    assert np.abs(decoded[470, 10] - renderer.background[470, 10]).sum() < 12
    # and the same frame of another pose differs there
    other = _decode_frame(path, 30, 640, 480).astype(np.float64)
    assert np.abs(other - decoded).mean() > 0.5


def test_exports_refuse_existing_files_and_leave_nothing(tmp_path):
    seq = gesture_like(frames=5)
    stem = tmp_path / "out" / "take"
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "take.bvh").write_text("mine")
    with pytest.raises(OutputExistsError):
        export_sequence(seq, stem, ("npz", "bvh"))
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["take.bvh"]
    assert (tmp_path / "out" / "take.bvh").read_text() == "mine"
    written = export_sequence(seq, stem, ("npz", "bvh"), overwrite=True)
    assert [p.name for p in written] == ["take.npz", "take.bvh"]
    assert (tmp_path / "out" / "take.bvh").read_text().startswith("HIERARCHY")
    (tmp_path / "file").write_text("x")
    with pytest.raises(EmogestureError, match="is a file"):
        save_bvh(seq, tmp_path / "file" / "a.bvh")
    assert not list(tmp_path.glob("**/.*.tmp"))


def test_parse_formats():
    assert parse_formats("npz, BVH,.mp4,npz") == ("npz", "bvh", "mp4")
    for bad in ("", "gif", "npz,obj"):
        with pytest.raises(EmogestureError, match="--format"):
            parse_formats(bad)


@pytest.mark.training
def test_export_command_on_a_beat2_npz(tmp_path, capsys):
    seq = gesture_like(frames=30)
    npz = save_smplx_npz(seq, tmp_path / "mocap.npz")
    wav = tmp_path / "speech.wav"
    import soundfile as sf

    sf.write(wav, 0.1 * np.random.default_rng(0).normal(size=16000).astype(np.float32), 16000)
    assert main(["export", str(npz), "--format", "bvh,mp4", "--audio", str(wav), "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "mocap.bvh" in printed and "mocap.mp4" in printed
    assert _probe(tmp_path / "mocap.mp4")["video"]["nb_read_frames"] == "30"
    assert main(["export", str(npz), "--format", "bvh"]) == 2  # exists, no --overwrite
    assert "already exists" in capsys.readouterr().err
    assert main(["export", str(tmp_path / "missing.npz")]) == 2


def test_a_label_that_changes_along_the_video_shows_each_text_from_its_time():
    from emogesture.export.video import MannequinRenderer, label_overlays

    overlays, which = label_overlays([(0.0, "emotion: anger"), (1.0, "emotion: sadness")], 320, 30.0, 60)
    assert which.tolist() == [0] * 30 + [1] * 30 and len(overlays) == 2
    seq = SMPLXSequence(poses=np.zeros((60, 55, 3), np.float32), trans=np.zeros((60, 3), np.float32))
    frames = list(MannequinRenderer(320, 240).frames(seq, overlay=overlays, which=which))
    corner = np.s_[8:30, 8:150]  # the label; the body does not move
    assert np.array_equal(frames[0][corner], frames[29][corner])
    assert not np.array_equal(frames[29][corner], frames[30][corner])
    assert np.array_equal(frames[0][100:], frames[30][100:])


def test_the_video_draws_the_face_from_its_arkit_weights():
    """With a face track the head shows it: the mouth's dark inside only when the jaw is open (not when
    mouthClose shuts the lips over it), white eyes that a blink closes, lip corners above the mouth's middle
    for a smile and below it for a frown; without one the head keeps its two dark eyes."""
    from emogesture.types import ARKIT_NAMES
    from emogesture.types import SMPLXSequence

    index = {name: i for i, name in enumerate(ARKIT_NAMES)}
    shapes = [{}, {"jawOpen": 0.8}, {"jawOpen": 0.8, "mouthClose": 0.8}, {"eyeBlinkLeft": 1, "eyeBlinkRight": 1},
              {"mouthSmileLeft": 1, "mouthSmileRight": 1}, {"mouthFrownLeft": 1, "mouthFrownRight": 1}]
    seq = SMPLXSequence(poses=np.zeros((len(shapes), 55, 3), np.float32), trans=np.zeros((len(shapes), 3), np.float32))
    seq.arkit = np.zeros((len(shapes), 52), np.float32)
    for f, shape in enumerate(shapes):
        for name, weight in shape.items():
            seq.arkit[f, index[name]] = weight
    renderer = MannequinRenderer()
    frames = np.stack(list(renderer.frames(seq))).astype(int)
    drawn = np.abs(frames - renderer.background.astype(int)).sum(-1) > 10
    dark_red = (frames[..., 0] < 120) & (frames[..., 1] < 45) & (frames[..., 0] > frames[..., 1] + 20)  # the inside
    white = (frames.min(-1) > 225) & drawn
    head = (slice(40, 200), slice(250, 390))
    closed = dark_red[0][head].sum()  # a few pixels of the lips' dark rims
    assert dark_red[1][head].sum() > 40 + 5 * closed and dark_red[2][head].sum() <= closed + 5
    eyes = (slice(60, 140), slice(270, 370))
    assert white[0][eyes].sum() > 30 and white[3][eyes].sum() < white[0][eyes].sum() / 4  # (the highlight stays)
    lips = (frames[..., 0] > 150) & (frames[..., 0] - frames[..., 1] > 60)
    rows = [np.nonzero(lips[f][head])[0] for f in (4, 5)]  # image rows grow downward
    assert rows[0].min() < rows[1].min() - 2  # the smile's corners rise above the frown's
    no_face = seq.slice(0, 1) if hasattr(seq, "slice") else seq
    no_face.arkit = None
    plain = next(renderer.frames(no_face)).astype(int)
    assert ((plain.min(-1) > 225) & drawn[0])[eyes].sum() < white[0][eyes].sum() / 4
