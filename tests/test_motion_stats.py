"""Motion statistics (docs/design.md, 'Metrics'): angular speed, wrist speed and posture on motion with known answers."""

import json
import subprocess

import numpy as np
import pytest
import torch

from emogesture.eval.motion_stats import elbow_angles_deg, joint_angular_speed, motion_statistics
from emogesture.motion import JOINT_NAMES, SkeletonBody

from helpers import cli, make_root

J = {n: i for i, n in enumerate(JOINT_NAMES)}


def _pose(poses: np.ndarray):
    joints = SkeletonBody()(torch.from_numpy(poses.astype(np.float32))).numpy()
    return poses, joints, 30.0


def test_angular_speed_is_the_rotation_per_frame():
    poses = np.zeros((31, 55, 3))
    poses[:, J["neck"], 1] = 0.02 * np.arange(31)  # 0.02 rad per frame about y
    poses[:, J["left_elbow"], :] = 0.3  # turned, but still
    speed = joint_angular_speed(poses)
    assert speed.shape == (30, 55)
    assert np.allclose(speed[:, J["neck"]], 0.02, atol=1e-6)
    assert np.allclose(np.delete(speed, J["neck"], axis=1), 0.0, atol=1e-6)


def test_posture_and_hand_speed_follow_the_pose():
    still = np.zeros((60, 55, 3))  # the rest pose: arms straight out
    r = motion_statistics([_pose(still)])
    assert r["elbow_open_share"] == 1.0 and r["wrist_below_pelvis_share"] == 0.0
    assert r["wrist_still_share"] == 1.0 and r["wrist_speed_mean"] == 0.0
    rest = elbow_angles_deg(_pose(still)[1])  # the mannequin's rest arms are nearly straight (not exactly)
    assert rest.shape == (60, 2) and np.all(rest > 150.0)

    down = np.zeros((60, 55, 3))
    down[:, J["left_shoulder"], 2] = -1.3  # arms hanging by the sides
    down[:, J["right_shoulder"], 2] = 1.3
    down[:, J["left_elbow"], 1] = -np.linspace(0.0, 1.5, 60)  # the left forearm comes up over 2 s
    r = motion_statistics([_pose(down)])
    assert r["wrist_below_pelvis_share"] > 0.5
    assert 0.5 < r["elbow_open_share"] < 0.75  # the right arm stays straight, the left bends early on
    assert r["angular_speed"]["left_elbow"] == pytest.approx(1.5 / 59, rel=1e-3)
    assert r["angular_speed"]["right_elbow"] == 0.0 and 0.0 < r["wrist_still_share"] < 1.0
    assert r["wrist_speed_mean"] > 0.05 and r["frames"] == 60 and r["seconds"] == 2.0
    pooled = motion_statistics([_pose(still), _pose(down)])  # frame-weighted pool of both
    assert pooled["elbow_open_share"] == pytest.approx((1.0 + r["elbow_open_share"]) / 2, abs=0.01)


def test_motion_stats_command(tmp_path, capsys):
    make_root(tmp_path / "root", speakers=(1,), takes=(1, 2))
    files = sorted((tmp_path / "root" / "smplxflame_30").glob("*.npz"))
    out = subprocess.run(cli("motion-stats", f"mocap={tmp_path / 'root'}", files[0], "--json", tmp_path / "s.json"),
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "| statistic | mocap | npz files |" in out.stdout and "left_wrist angular speed" in out.stdout
    blob = json.loads((tmp_path / "s.json").read_text())
    assert blob["mocap"]["sequences"] == 2 and blob["npz files"]["sequences"] == 1
    assert blob["mocap"]["angular_speed"]["neck"] > 0  # the fixture's random walk moves every joint
    from emogesture.cli.main import main

    capsys.readouterr()
    assert main(["motion-stats", str(files[0]), "--json", str(tmp_path / "s.json")]) == 2
    assert "already exists" in capsys.readouterr().err
    assert main(["motion-stats", str(tmp_path / "nothing")]) == 2
    err = capsys.readouterr().err
    assert "nothing: not found" in err and len(err.strip().splitlines()) == 1


def test_gesture_space_reads_the_body_frame():
    """A hand in front of the chest and the wrists' distance, in the body's own frame: the same pose
    turned about the vertical axis reads the same, and bending the forearms forward moves both numbers."""
    from emogesture.eval.motion_stats import body_frame, hands_in_front, wrist_distance

    down = np.zeros((30, 55, 3))
    down[:, J["left_shoulder"], 2] = -1.3  # arms hanging by the sides
    down[:, J["right_shoulder"], 2] = 1.3
    r = motion_statistics([_pose(down)])
    assert r["hand_in_front_share"] == 0.0 and r["constants"]["front_m"] == 0.15
    front = down.copy()
    front[:, J["left_elbow"], 1] = -1.5  # forearms raised forward (elbows bent 90 degrees)
    front[:, J["right_elbow"], 1] = 1.5
    f = motion_statistics([_pose(front)])
    assert f["hand_in_front_share"] == 1.0
    assert f["wrist_distance_median"] < r["wrist_distance_median"]
    turned = front.copy()
    turned[:, J["pelvis"], 1] = 1.0  # the whole body turned by a radian: its own frame turns with it
    joints = _pose(turned)[1]
    x, up, forward = body_frame(joints)
    straight = body_frame(_pose(front)[1])[2]  # facing +z, turned by a radian about y
    c, s = np.cos(1.0), np.sin(1.0)
    assert np.allclose(forward, straight @ np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]]), atol=1e-5)
    assert straight[0] @ np.array([0.0, 0.0, 1.0]) > 0.99
    assert hands_in_front(joints).all()
    assert np.allclose(wrist_distance(joints), wrist_distance(_pose(front)[1]), atol=1e-5)
    half = np.concatenate([down, front])
    assert motion_statistics([_pose(half)])["hand_in_front_share"] == pytest.approx(0.5)


def test_fingers_body_turn_and_hand_height_have_known_answers():
    from emogesture.eval.motion_stats import FINGER_JOINTS, root_turn_deg, torso_yaw_pitch_deg

    t = np.arange(90)
    poses = np.zeros((90, 55, 3))
    poses[:, list(FINGER_JOINTS["left"]), 2] = np.radians(20.0)  # every left finger joint curled by 20 degrees
    r = motion_statistics([_pose(poses)])
    assert r["finger_curl_left_deg"] == pytest.approx(20.0) and r["finger_curl_right_deg"] == 0.0
    assert r["finger_curl_deg"] == pytest.approx(10.0) and r["finger_change_deg"] == pytest.approx(0.0, abs=1e-9)
    assert r["root_turn_deg"] == pytest.approx(0.0, abs=1e-5) and r["onset_coupling"] is None
    moving = poses.copy()
    moving[:, list(FINGER_JOINTS["right"]), 2] = np.radians(30.0) * (t % 30 < 15)[:, None]  # a fist that opens
    assert motion_statistics([_pose(moving)])["finger_change_deg"] == pytest.approx(15.0 / 2, abs=0.5)

    turning = np.zeros((90, 55, 3))
    turning[:, J["pelvis"], 1] = 0.5 + np.radians(6.0) * np.sin(2 * np.pi * t / 45)  # turned, swaying ±6 degrees
    assert root_turn_deg(turning) == pytest.approx(6.0 / np.sqrt(2), rel=0.02)
    yaw, pitch = torso_yaw_pitch_deg(turning)
    assert yaw.std() == pytest.approx(6.0 / np.sqrt(2), rel=0.02) and pitch.std() == pytest.approx(0.0, abs=1e-6)
    twist = np.zeros((90, 55, 3))
    twist[:, J["spine2"], 1] = np.radians(5.0) * np.sin(2 * np.pi * t / 45)  # the chest turns, the root does not
    twist[:, J["spine1"], 0] = np.radians(8.0) * np.sin(2 * np.pi * t / 30)  # and leans forward and back
    twist[:, J["left_shoulder"], 1] = np.sin(t)  # the arms move: not the chest
    r = motion_statistics([_pose(twist)])
    assert r["root_turn_deg"] == pytest.approx(0.0, abs=1e-5)
    assert r["torso_yaw_std_deg"] == pytest.approx(5.0 / np.sqrt(2), rel=0.05)
    assert r["torso_pitch_std_deg"] == pytest.approx(8.0 / np.sqrt(2), rel=0.05)

    down = np.zeros((30, 55, 3))
    down[:, J["left_shoulder"], 2] = -1.3
    down[:, J["right_shoulder"], 2] = 1.3
    together = down.copy()
    together[:, J["left_shoulder"], 1] = -0.9  # both arms brought forward and in
    together[:, J["right_shoulder"], 1] = 0.9
    together[:, J["left_elbow"], 1] = -1.2
    together[:, J["right_elbow"], 1] = 1.2
    a, b = motion_statistics([_pose(down)]), motion_statistics([_pose(together)])
    assert a["hands_together_share"] == 0.0 and b["hands_together_share"] == 1.0
    assert a["wrist_height_median"] < 0.0 < b["wrist_height_median"]  # hanging below the pelvis / raised
    assert a["wrist_height_p10"] <= a["wrist_height_median"] <= a["wrist_height_p90"]


def test_onset_coupling_follows_the_strokes(tmp_path):
    """Arms that move on the speech's onsets couple far more than the same motion moved 0.6 s late."""
    from emogesture.eval.motion_stats import file_statistics, onset_coupling, onset_coupling_curve, speech_of

    rng = np.random.default_rng(0)
    fps, sr, seconds = 30.0, 16000, 12
    onsets = np.sort(rng.choice(np.arange(1, seconds - 1, 0.25), 18, replace=False))
    wave = 0.002 * rng.normal(size=seconds * sr)
    for o in onsets:  # a 150-ms vowel-like burst at each onset
        n = np.arange(int(0.15 * sr))
        wave[int(o * sr): int(o * sr) + len(n)] += 0.3 * np.sin(2 * np.pi * 200 * n / sr) * np.hanning(len(n))
    frames = np.arange(int(seconds * fps)) / fps

    def strokes(delay: float) -> np.ndarray:
        lift = sum(np.exp(-0.5 * ((frames - o - delay) / 0.08) ** 2) for o in onsets)
        poses = np.zeros((len(frames), 55, 3))
        poses[:, J["right_shoulder"], 2] = 1.3
        poses[:, J["right_elbow"], 1] = 0.8 * lift
        return poses

    on = _pose(strokes(0.05))[1]
    late = _pose(strokes(0.6))[1]
    c_on, c_late = onset_coupling(on, wave, sr, fps), onset_coupling(late, wave, sr, fps)
    assert c_on > 0.4 and c_late < c_on - 0.3
    # the curve over lags finds each motion's delay: its peak lies where the strokes follow the onsets
    for delay, joints in ((0.05, on), (0.6, late), (-0.5, _pose(strokes(-0.5))[1])):
        curve = onset_coupling_curve(joints, wave, sr, fps, 1.0)
        assert len(curve) == 61 and (np.argmax(curve) - 30) / fps == pytest.approx(delay, abs=0.1)
    assert onset_coupling_curve(on, wave, sr, fps, 0.2).max() == pytest.approx(c_on)
    r = motion_statistics([(*_pose(strokes(0.05))[:2], fps, (wave, sr)), _pose(strokes(0.6))])
    assert r["onset_coupling"] == pytest.approx(c_on) and r["sequences_with_audio"] == 1

    import soundfile as sf

    from emogesture.motion.io import save_smplx_npz
    from emogesture.types import SMPLXSequence

    (tmp_path / "smplxflame_30").mkdir()
    (tmp_path / "wave16k").mkdir()
    seq = SMPLXSequence(poses=strokes(0.05).astype(np.float32), trans=np.zeros((len(frames), 3), np.float32),
                        betas=np.zeros(10, np.float32), expressions=np.zeros((len(frames), 0), np.float32), fps=fps)
    save_smplx_npz(seq, tmp_path / "smplxflame_30" / "a.npz")
    save_smplx_npz(seq, tmp_path / "smplxflame_30" / "b.npz")
    sf.write(tmp_path / "wave16k" / "a.wav", wave.astype(np.float32), sr)
    assert speech_of(tmp_path / "smplxflame_30" / "a.npz") == tmp_path / "wave16k" / "a.wav"
    assert speech_of(tmp_path / "smplxflame_30" / "b.npz") is None
    r = file_statistics(sorted((tmp_path / "smplxflame_30").glob("*.npz")))
    assert r["sequences_with_audio"] == 1 and r["onset_coupling"] == pytest.approx(c_on, abs=0.02)


def test_onset_coupling_of_many_short_sequences_is_not_raised_by_chance():
    """Over many short sequences the curves are pooled before the best lag is taken: motion that has nothing
    to do with its speech reads near zero (the best of each sequence's own curve reads clearly above it),
    motion on the onsets reads high, and sequences at two frame rates pool at the same lags."""
    rng = np.random.default_rng(1)
    sr, seconds = 16000, 8

    def take(fps: float, follow: bool) -> tuple:
        onsets = np.sort(rng.uniform(0.0, seconds - 0.15, 16))
        wave = 0.002 * rng.normal(size=seconds * sr)
        for o in onsets:
            n = np.arange(int(0.15 * sr))
            wave[int(o * sr): int(o * sr) + len(n)] += 0.3 * np.sin(2 * np.pi * 200 * n / sr) * np.hanning(len(n))
        frames = np.arange(int(seconds * fps)) / fps
        times = onsets + 0.05 if follow else rng.uniform(0.0, seconds - 0.15, 16)
        poses = np.zeros((len(frames), 55, 3))
        poses[:, J["right_shoulder"], 2] = 1.3
        poses[:, J["right_elbow"], 1] = 0.8 * sum(np.exp(-0.5 * ((frames - t) / 0.08) ** 2) for t in times)
        poses, joints = _pose(poses)[:2]
        return poses, joints, fps, (wave, sr)

    from emogesture.eval.motion_stats import onset_coupling

    unrelated = [take(30.0 if i % 2 else 60.0, follow=False) for i in range(24)]
    r = motion_statistics(unrelated)
    by_sequence = np.mean([onset_coupling(j, w, s, f) for _, j, f, (w, s) in unrelated])
    assert abs(r["onset_coupling"]) < 0.04 < by_sequence
    following = motion_statistics([take(30.0 if i % 2 else 60.0, follow=True) for i in range(6)])
    assert following["onset_coupling"] > 0.3 and following["onset_coupling_lag_s"] == pytest.approx(0.05, abs=0.1)


def test_rhythm_lag_curve_script_writes_its_report(tmp_path):
    """The short version of experiments/rhythm/rhythm_lag_curve.py: the bundled model on two takes of a small
    corpus, two settings; the report's curves are real correlations at every lag and differ by setting."""
    import sys
    from pathlib import Path

    names = make_root(tmp_path / "root", speakers=(1,), takes=(2, 66))
    script = Path(__file__).resolve().parents[1] / "experiments" / "rhythm" / "rhythm_lag_curve.py"
    from emogesture.assets import bundled_model_file

    subprocess.run([sys.executable, str(script), str(tmp_path / "root"), str(bundled_model_file("gesture")),
                    str(tmp_path / "out"), "--split", "test", "--every", "1", "--settings", "shipped:",
                    "no guidance:timing_guidance=1"], check=True, capture_output=True, timeout=300)
    report = json.loads((tmp_path / "out" / "lag_curve_test.json").read_text())
    assert report["takes"] == sorted(names) and len(report["lags_s"]) == 121
    curves = {k: np.array(v) for k, v in report["curves"].items()}
    assert set(curves) == {"ground truth", "shipped", "no guidance"}
    assert all(np.all(np.abs(c) <= 1) and np.ptp(c) > 0 for c in curves.values())
    assert not np.allclose(curves["shipped"], curves["no guidance"])
    assert (tmp_path / "out" / "lag_curve_test.png").stat().st_size > 5000
    assert "lag of the peak" in (tmp_path / "out" / "lag_curve_test.md").read_text()
