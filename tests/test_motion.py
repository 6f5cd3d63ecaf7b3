"""Motion package: rotations, skeleton, features, forward kinematics and npz files."""

import json
import math
import zipfile

import numpy as np
import pytest
import torch

from emogesture.errors import EmogestureError, InputFileError
from emogesture.motion import (
    JOINT_NAMES, LOWER_BODY_JOINTS, PARENTS, UPPER_BODY_JOINTS, FeatureStats, MotionFeatureSpec,
    OutputExistsError, SkeletonBody, axis_angle_to_matrix, axis_angle_to_rot6d,
    features_to_poses, interpolate_rotations, load_smplx_npz, matrix_to_axis_angle,
    matrix_to_rot6d, poses_to_features, rest_joints, rest_offsets, rot6d_to_axis_angle, rot6d_to_matrix,
    save_smplx_npz
)
from emogesture.motion.skeleton import MANNEQUIN_TO_SMPLX
from emogesture.types import SMPLXSequence


def random_axis_angle(shape, seed=0, max_angle=math.pi - 0.1, dtype=torch.float64):
    g = torch.Generator().manual_seed(seed)
    axis = torch.randn(*shape, 3, generator=g, dtype=dtype)
    axis = axis / axis.norm(dim=-1, keepdim=True)
    return axis * torch.rand(*shape, 1, generator=g, dtype=dtype) * max_angle


# --- rotations -------------------------------------------------------------------------------


def test_axis_angle_round_trips():
    aa = random_axis_angle((64, 7))
    assert torch.allclose(matrix_to_axis_angle(axis_angle_to_matrix(aa)), aa, atol=1e-5)
    assert torch.allclose(rot6d_to_axis_angle(axis_angle_to_rot6d(aa)), aa, atol=1e-5)
    aa32 = aa.float()
    assert rot6d_to_axis_angle(axis_angle_to_rot6d(aa32)).dtype == torch.float32
    assert torch.allclose(rot6d_to_axis_angle(axis_angle_to_rot6d(aa32)), aa32, atol=1e-4)


def test_rot6d_is_first_two_columns():
    quarter_turn_z = torch.tensor([0.0, 0.0, math.pi / 2])
    six = axis_angle_to_rot6d(quarter_turn_z)
    # R = [[0,-1,0],[1,0,0],[0,0,1]]: column 0 = (0,1,0), column 1 = (-1,0,0)
    assert torch.allclose(six, torch.tensor([0.0, 1.0, 0.0, -1.0, 0.0, 0.0]), atol=1e-6)
    m = axis_angle_to_matrix(random_axis_angle((5,)))
    assert torch.allclose(rot6d_to_matrix(matrix_to_rot6d(m)), m, atol=1e-10)


def test_rot6d_gram_schmidt_gives_rotations_and_gradients():
    g = torch.Generator().manual_seed(1)
    raw = torch.randn(32, 6, generator=g, requires_grad=True)
    m = rot6d_to_matrix(raw)
    eye = torch.eye(3).expand(32, 3, 3)
    assert torch.allclose(m.transpose(-1, -2) @ m, eye, atol=1e-5)
    assert torch.allclose(torch.linalg.det(m), torch.ones(32), atol=1e-5)
    (m[..., 0, 2] + m[..., 1, 1]).sum().backward()
    assert torch.isfinite(raw.grad).all() and raw.grad.abs().sum() > 0


def test_interpolate_rotations():
    a = axis_angle_to_matrix(random_axis_angle((10, 4), seed=2))
    b = axis_angle_to_matrix(random_axis_angle((10, 4), seed=3))
    assert torch.allclose(interpolate_rotations(a, b, 0.0), a, atol=1e-6)
    assert torch.allclose(interpolate_rotations(a, b, 1.0), b, atol=1e-6)
    mid = interpolate_rotations(a, b, 0.5)
    # geodesic midpoint: equal angle to both ends, half the total
    total = matrix_to_axis_angle(a.transpose(-1, -2) @ b).norm(dim=-1)
    to_a = matrix_to_axis_angle(a.transpose(-1, -2) @ mid).norm(dim=-1)
    to_b = matrix_to_axis_angle(mid.transpose(-1, -2) @ b).norm(dim=-1)
    assert torch.allclose(to_a, total / 2, atol=1e-6) and torch.allclose(to_b, total / 2, atol=1e-6)
    # per-frame ramp on 6D input [T, J, 6] with weights [T, 1]
    w = torch.linspace(0, 1, 10, dtype=a.dtype)[:, None]
    ramp = interpolate_rotations(matrix_to_rot6d(a), matrix_to_rot6d(b), w)
    assert ramp.shape == (10, 4, 6)
    assert torch.allclose(ramp[0], matrix_to_rot6d(a[0]), atol=1e-6)
    assert torch.allclose(ramp[-1], matrix_to_rot6d(b[-1]), atol=1e-6)


def test_guide_features_extrapolates_but_never_turns_a_column_round():
    from emogesture.motion import GUIDANCE_FLOOR, guide_features

    spec = MotionFeatureSpec(joints=(16, 18), include_translation=True)
    plain = torch.cat([matrix_to_rot6d(axis_angle_to_matrix(random_axis_angle((40, 2), seed=6))).reshape(40, 12),
                       torch.randn(40, 3, dtype=torch.float64)], -1)
    heard = plain + 0.02 * torch.randn(40, 15, dtype=torch.float64)  # a small timing part: plain extrapolation
    torch.testing.assert_close(guide_features(plain, heard, 3.0, spec), plain + 3 * (heard - plain))
    torch.testing.assert_close(guide_features(plain, heard, 0.5, spec), plain + 0.5 * (heard - plain))
    # an elbow whose heard decoding is the plain one shortened to 0.6 and turned a little: extrapolated as
    # numbers by 3, its first column points backwards (a half-turn flip); guided, it stays ahead
    turn = axis_angle_to_matrix(torch.tensor([[0.0, 0.05, 0.0]], dtype=torch.float64))[0]
    short = heard.clone()
    short[:, 6:9] = 0.6 * plain[:, 6:9] @ turn.T
    linear = plain + 3 * (short - plain)
    guided = guide_features(plain, short, 3.0, spec)
    ahead = lambda x: (x[:, 6:9] * plain[:, 6:9]).sum(-1) / (plain[:, 6:9] ** 2).sum(-1)
    assert (ahead(linear) < 0).all()
    # never shorter along p than the floor, or than the heard column itself where that is shorter (w >= 1)
    assert (ahead(guided) >= torch.clamp(ahead(short), max=GUIDANCE_FLOOR) - 1e-9).all() and (ahead(guided) > 0).all()
    torch.testing.assert_close(guided[:, :6], linear[:, :6])  # the other joint keeps its full guidance
    # the lowered guidance changes continuously: a slightly shorter column moves the output slightly
    shorter = short.clone()
    shorter[:, 6:9] *= 0.999
    assert (guide_features(plain, shorter, 3.0, spec) - guided).abs().max() < 0.01
    with pytest.raises(ValueError, match="features must both be"):
        guide_features(plain, heard[:, :14], 2.0, spec)


# --- skeleton and features -------------------------------------------------------------------


def test_skeleton_tables():
    assert len(JOINT_NAMES) == len(PARENTS) == 55
    assert JOINT_NAMES[22] == "jaw" and JOINT_NAMES[25] == "left_index1" and JOINT_NAMES[54] == "right_thumb3"
    assert all(PARENTS[j] < j for j in range(1, 55))
    assert PARENTS[20] == 18 and PARENTS[25] == 20 and PARENTS[40] == 21 and PARENTS[52] == 21
    assert len(UPPER_BODY_JOINTS) == 47 and not set(UPPER_BODY_JOINTS) & set(LOWER_BODY_JOINTS)


def test_rest_joints_shape_and_cache():
    joints = rest_joints()
    assert joints.shape == (55, 3) and joints.dtype == np.float32
    joints[0] = 99.0  # callers get a copy, the cache is untouched
    assert rest_joints()[0, 0] != 99.0
    tall = rest_joints(np.array([3.0] + [0.0] * 9))
    assert not np.allclose(tall, rest_joints(), atol=1e-3)
    assert np.array_equal(rest_joints(np.zeros(300)), rest_joints())
    offsets = rest_offsets()
    head = rest_joints()[15]
    assert np.allclose(offsets[23] + head, rest_joints()[23]) and offsets[23][2] > 0  # eyes face +Z
    assert rest_joints()[23][0] > 0 > rest_joints()[24][0]


def test_features_round_trips():
    spec = MotionFeatureSpec()
    assert spec.dim == 282 and MotionFeatureSpec.all_joints().dim == 333
    poses = random_axis_angle((2, 6, 55), seed=4).float()
    feats = poses_to_features(poses, spec)
    assert feats.shape == (2, 6, 282)
    back, trans = features_to_poses(feats, spec)
    assert trans is None and back.shape == poses.shape
    upper = list(UPPER_BODY_JOINTS)
    assert torch.allclose(back[..., upper, :], poses[..., upper, :], atol=1e-4)
    assert torch.all(back[..., list(LOWER_BODY_JOINTS), :] == 0)
    assert torch.allclose(poses_to_features(back, spec), feats, atol=1e-5)


def test_all_joint_features_with_translation_and_gradients():
    spec = MotionFeatureSpec.all_joints()
    poses = random_axis_angle((5, 55), seed=5).float()
    trans = torch.randn(5, 3, generator=torch.Generator().manual_seed(0))
    feats = poses_to_features(poses, spec, trans).requires_grad_(True)
    back, back_trans = features_to_poses(feats, spec)
    assert torch.allclose(back, poses, atol=1e-4) and torch.equal(back_trans, trans)
    back.sum().backward()
    assert torch.isfinite(feats.grad).all() and feats.grad.abs().sum() > 0
    with pytest.raises(ValueError, match="translation"):
        poses_to_features(poses, spec)


def test_feature_stats():
    rng = np.random.default_rng(0)
    x = rng.normal(3.0, 2.0, size=(500, 4)).astype(np.float32)
    x[:, 2] = 7.0  # constant feature
    stats = FeatureStats.compute(x, eps=1e-4)
    assert stats.std[2] == pytest.approx(1e-4) and abs(stats.mean[0] - 3.0) < 0.3
    z = stats.normalise(x)
    assert np.isfinite(z).all() and abs(z[:, 0].std() - 1.0) < 1e-3
    assert np.allclose(stats.denormalise(z), x, atol=1e-4)
    zt = stats.normalise(torch.from_numpy(x))
    assert isinstance(zt, torch.Tensor) and np.allclose(zt.numpy(), z, atol=1e-6)
    again = FeatureStats.from_dict(json.loads(json.dumps(stats.to_dict())))
    assert np.array_equal(again.mean, stats.mean) and np.array_equal(again.std, stats.std)
    with pytest.raises(ValueError):
        stats.normalise(np.zeros((2, 5)))


# --- bodies ----------------------------------------------------------------------------------


def test_fk_rest_pose_is_a_plausible_t_pose():
    joints = SkeletonBody()(torch.zeros(1, 1, 55, 3))[0, 0].numpy()
    assert np.allclose(joints, rest_joints(), atol=1e-6)
    pelvis, neck, head = joints[0], joints[12], joints[15]
    assert head[1] > neck[1] > pelvis[1]
    assert joints[10][1] < pelvis[1] - 0.7 and joints[11][1] < pelvis[1] - 0.7
    span = float(np.linalg.norm(joints[20] - joints[21]))
    print(f"rest wrist-to-wrist distance: {span:.3f} m")
    assert 1.2 < span < 1.8


def test_fk_batching_translation_and_gradients():
    body = SkeletonBody()
    poses = random_axis_angle((2, 3, 55), seed=6).float().requires_grad_(True)
    trans = torch.tensor([0.5, -1.0, 2.0]).expand(2, 3, 3)
    joints = body(poses, trans)
    assert joints.shape == (2, 3, 55, 3)
    assert torch.allclose(body(poses[1]), joints[1] - trans[1][:, None], atol=1e-5)  # [T, 55, 3] input
    assert torch.allclose(body.forward_matrices(axis_angle_to_matrix(poses), trans), joints, atol=1e-6)
    joints[..., 20, :].sum().backward()
    assert torch.isfinite(poses.grad).all()
    assert poses.grad[..., 18, :].abs().sum() > 0 and poses.grad[..., 5, :].abs().sum() == 0


def test_fk_matches_mannequin_x():
    from mannequin import Mannequin

    model = Mannequin("wooden", shape=np.zeros(10), flat_hand_mean=True)
    rng = np.random.default_rng(7)
    poses = (rng.normal(size=(6, 55, 3)) * 0.6).astype(np.float32)
    trans = rng.normal(size=(6, 3)).astype(np.float32)
    params = model.rest_pose(batch_dims=(6,))
    # SMPL-X's global orientation turns about the pelvis joint: that is mannequin-x's pelvis_rotation
    # (its global_rotation turns about the origin instead).
    params.update(body_pose=poses[:, 1:22], hand_pose=poses[:, 25:55], pelvis_rotation=poses[:, 0])
    params.update(global_translation=trans)
    reference = model.joint_transforms(params)[..., :3, 3]
    ours = SkeletonBody()(torch.from_numpy(poses), torch.from_numpy(trans)).numpy()
    m_index = [model.joint_names.index(name) for name in MANNEQUIN_TO_SMPLX]
    s_index = list(MANNEQUIN_TO_SMPLX.values())
    error = float(np.abs(reference[:, m_index] - ours[:, s_index]).max())
    print(f"max FK difference vs mannequin-x over 52 joints: {error:.2e} m")
    assert len(s_index) == 52 and error < 1e-5


# --- npz files -------------------------------------------------------------------------------


def make_seq(frames=12, seed=0):
    rng = np.random.default_rng(seed)
    return SMPLXSequence(
        poses=rng.normal(size=(frames, 55, 3)) * 0.3,
        trans=rng.normal(size=(frames, 3)),
        betas=rng.normal(size=300),
        expressions=rng.normal(size=(frames, 100)),
    )


def test_npz_round_trip_and_beat2_layout(tmp_path):
    seq = make_seq()
    path = save_smplx_npz(seq, tmp_path / "take.npz")
    with np.load(path) as raw:
        assert raw["poses"].shape == (12, 165) and raw["poses"].dtype == np.float32
        assert str(raw["model"]) == "smplx2020" and str(raw["gender"]) == "neutral"
        assert int(raw["mocap_frame_rate"]) == 30
    back = load_smplx_npz(path)
    for name in ("poses", "trans", "betas", "expressions"):
        assert np.array_equal(getattr(back, name), getattr(seq, name)), name
    assert (back.fps, back.gender, back.model) == (30.0, "neutral", "smplx2020")


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("layout", ["flat", "joints"])
def test_npz_reads_beat2_variants(tmp_path, dtype, layout):
    seq = make_seq(frames=5)
    poses = seq.poses.reshape(5, 165) if layout == "flat" else seq.poses
    path = tmp_path / "beat2.npz"
    np.savez(
        path, poses=poses.astype(dtype), trans=seq.trans.astype(dtype), betas=seq.betas[:10].astype(dtype),
        mocap_frame_rate=np.array(30.0), gender=np.array("female"), surprise=np.arange(3),
    )  # fmt: skip
    back = load_smplx_npz(path)
    assert back.poses.dtype == np.float32 and np.allclose(back.poses, seq.poses, atol=1e-6)
    assert back.betas.shape == (10,) and back.gender == "female" and back.model == "smplx2020"
    assert np.array_equal(back.expressions, np.zeros((5, 100), np.float32))
    np.savez(path, poses=poses)  # only poses: the rest take BEAT2 defaults
    back = load_smplx_npz(path)
    assert back.trans.shape == (5, 3) and back.betas.shape == (300,) and back.fps == 30


def test_npz_saves_are_byte_identical(tmp_path):
    seq = make_seq(seed=3)
    a = save_smplx_npz(seq, tmp_path / "a.npz").read_bytes()
    b = save_smplx_npz(seq, tmp_path / "b.npz").read_bytes()
    assert a == b
    with zipfile.ZipFile(tmp_path / "a.npz") as archive:
        assert {info.date_time for info in archive.infolist()} == {(1980, 1, 1, 0, 0, 0)}


def test_npz_overwrite_protection(tmp_path):
    path = tmp_path / "out.npz"
    save_smplx_npz(make_seq(seed=1), path)
    before = path.read_bytes()
    with pytest.raises(OutputExistsError, match=r"out\.npz.*--overwrite") as info:
        save_smplx_npz(make_seq(seed=2), path)
    assert isinstance(info.value, EmogestureError) and isinstance(info.value, FileExistsError)
    assert path.read_bytes() == before
    save_smplx_npz(make_seq(seed=2), path, overwrite=True)
    assert path.read_bytes() != before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.npz"]  # no temp files left


def _write_bad(tmp_path, kind):
    path = tmp_path / f"{kind}.npz"
    good = make_seq(frames=4)
    if kind == "no_poses":
        np.savez(path, trans=good.trans)
    elif kind == "corrupt":
        path.write_bytes(b"PK\x03\x04 this is not really a zip file")
    elif kind == "bad_shape":
        np.savez(path, poses=np.zeros((4, 156)))
    elif kind == "trans_mismatch":
        np.savez(path, poses=good.poses, trans=good.trans[:3])
    elif kind == "nan":
        poses = good.poses.copy()
        poses[1, 3, 0] = np.nan
        np.savez(path, poses=poses)
    elif kind == "npy":
        np.save(tmp_path / "npy.npy", good.poses)
        (tmp_path / "npy.npy").rename(path)
    return path


@pytest.mark.parametrize(
    "kind, problem",
    [
        ("no_poses", "no 'poses'"),
        ("corrupt", "not a readable .npz"),
        ("bad_shape", r"\(T, 165\)"),
        ("trans_mismatch", "'trans' must be"),
        ("nan", "NaN"),
        ("npy", "single .npy"),
        ("missing", "file not found"),
    ],
)
def test_npz_errors_name_the_file(tmp_path, kind, problem):
    path = _write_bad(tmp_path, kind)
    with pytest.raises(InputFileError, match=problem) as info:
        load_smplx_npz(path)
    assert str(info.value).startswith(f"{path}: ") and "\n" not in str(info.value)


def test_features_to_matrices_gives_the_same_joints_as_poses():
    from emogesture.motion import SkeletonBody, features_to_matrices

    body = SkeletonBody()
    for spec in (MotionFeatureSpec(), MotionFeatureSpec.all_joints()):
        x = torch.randn(2, 5, spec.dim, generator=torch.Generator().manual_seed(4))
        poses, trans = features_to_poses(x, spec)
        rotations, trans2 = features_to_matrices(x, spec)
        assert rotations.shape == (2, 5, 55, 3, 3)
        assert torch.allclose(body(poses, trans), body.forward_matrices(rotations, trans2), atol=1e-5)


def test_fk_from_features_matches_fk_from_all_rotations_with_gradients():
    # forward_features skips the rest rotations of the joints the features leave out and the world
    # rotations of leaves; it must give the same joints and gradients as the full 55-joint path
    from emogesture.motion import SkeletonBody, features_to_matrices

    body = SkeletonBody()
    specs = (MotionFeatureSpec(), MotionFeatureSpec.all_joints(), MotionFeatureSpec(joints=(0, 3, 6, 9, 13, 16, 18)))
    for spec in specs:
        x = torch.randn(2, 7, spec.dim, generator=torch.Generator().manual_seed(5))
        a, b = x.clone().requires_grad_(True), x.clone().requires_grad_(True)
        joints = body.forward_features(a, spec)
        reference = body.forward_matrices(*features_to_matrices(b, spec))
        assert joints.shape == (2, 7, 55, 3)
        assert torch.allclose(joints, reference, atol=1e-6)
        weights = torch.randn(joints.shape, generator=torch.Generator().manual_seed(6))
        (joints * weights).sum().backward()
        (reference * weights).sum().backward()
        assert torch.allclose(a.grad, b.grad, atol=1e-5, rtol=1e-5)
        assert a.grad.abs().sum() > 0
    # and the gradients are the joints' own (finite differences, float64)
    spec = specs[-1]
    x = torch.randn(1, 2, spec.dim, generator=torch.Generator().manual_seed(7), dtype=torch.float64)
    assert torch.autograd.gradcheck(lambda f: body.forward_features(f, spec), (x.requires_grad_(True),))
    with pytest.raises(ValueError, match="pelvis"):
        body.forward_features(torch.zeros(3, 12), MotionFeatureSpec(joints=(3, 6)))


def test_frame_rate_must_be_one_number(tmp_path):
    from emogesture.motion import load_smplx_npz

    path = tmp_path / "rates.npz"
    np.savez(path, poses=np.zeros((4, 165), np.float32), trans=np.zeros((4, 3), np.float32),
             mocap_frame_rate=np.array([30.0, 60.0]))
    with pytest.raises(InputFileError, match="mocap_frame_rate.*one number"):
        load_smplx_npz(path)
