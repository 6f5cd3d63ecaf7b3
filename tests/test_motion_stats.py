"""Motion statistics (issue 17): angular speed, wrist speed and posture on motion with known answers."""

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


def test_motion_stats_command(tmp_path):
    make_root(tmp_path / "root", speakers=(1,), takes=(1, 2))
    files = sorted((tmp_path / "root" / "smplxflame_30").glob("*.npz"))
    out = subprocess.run(cli("motion-stats", f"mocap={tmp_path / 'root'}", files[0], "--json", tmp_path / "s.json"),
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "| statistic | mocap | npz files |" in out.stdout and "left_wrist angular speed" in out.stdout
    blob = json.loads((tmp_path / "s.json").read_text())
    assert blob["mocap"]["sequences"] == 2 and blob["npz files"]["sequences"] == 1
    assert blob["mocap"]["angular_speed"]["neck"] > 0  # the fixture's random walk moves every joint
    again = subprocess.run(cli("motion-stats", files[0], "--json", tmp_path / "s.json"), capture_output=True, text=True)
    assert again.returncode == 2 and "already exists" in again.stderr
    bad = subprocess.run(cli("motion-stats", tmp_path / "nothing"), capture_output=True, text=True)
    assert bad.returncode == 2 and "nothing: not found" in bad.stderr and len(bad.stderr.strip().splitlines()) == 1


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
