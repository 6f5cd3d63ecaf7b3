"""The glb and fbx exports: a valid binary glTF 2.0 file (Khronos' glTF-Validator), a skinned mannequin whose
skin is the mannequin-x package's own, and in Blender's glTF and FBX importers the right bones, frames and
joint positions; without Blender, fbx says what to install."""

import json
import os
import shutil
import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest
import torch

from emogesture.errors import EmogestureError
from emogesture.export import export_sequence, save_fbx, save_glb
from emogesture.export.gltf import mannequin_skin, sequence_to_gltf
from emogesture.motion import JOINT_NAMES, SkeletonBody
from emogesture.motion.rigs import RIGS
from emogesture.motion.rotations import axis_angle_to_matrix

from helpers import fk, gesture_like

ROOT = Path(__file__).resolve().parents[1]
VALIDATOR = ROOT / "build" / "node" / "node_modules" / "gltf-validator"


def test_the_file_holds_the_skeleton_the_mesh_and_the_animation(tmp_path):
    seq = gesture_like(frames=45, seed=2)
    seq.trans[:] = np.linspace(0, 0.3, 45)[:, None] * [1.0, 0.0, 0.5]
    path = save_glb(seq, tmp_path / "a.glb")
    data = path.read_bytes()
    magic, version, length = struct.unpack("<4sII", data[:12])
    assert (magic, version, length) == (b"glTF", 2, len(data))
    size, kind = struct.unpack("<I4s", data[12:20])
    gltf = json.loads(data[20:20 + size])
    assert kind == b"JSON" and data[20 + size + 4:20 + size + 8] == b"BIN\0"
    assert [n["name"] for n in gltf["nodes"][:55]] == list(JOINT_NAMES)
    assert gltf["skins"][0]["joints"] == list(range(55))
    channels = gltf["animations"][0]["channels"]
    assert len(channels) == 56 and channels[-1]["target"] == {"node": 0, "path": "translation"}
    times = gltf["accessors"][gltf["animations"][0]["samplers"][0]["input"]]
    assert times["count"] == 45 and times["max"] == pytest.approx([44 / 30])
    with pytest.raises(Exception, match="already exists"):
        save_glb(seq, path)


def test_the_skin_moves_the_mesh_as_mannequin_x_does():
    """Linear blend skinning with the file's skin and our forward kinematics puts every vertex where
    mannequin-x's own posed mannequin has it (so the joint mapping, left and right, is right)."""
    from mannequin import Mannequin

    skin = mannequin_skin()
    rng = np.random.default_rng(0)
    poses = np.zeros((1, 55, 3), np.float32)
    poses[0, 1:22] = rng.normal(0, 0.3, (21, 3))
    poses[0, 25:] = rng.normal(0, 0.2, (30, 3))
    body = SkeletonBody()
    rotations = axis_angle_to_matrix(torch.from_numpy(poses))[0].numpy()
    world = [None] * 55
    for j, parent in enumerate(body_parents()):
        world[j] = rotations[j] if parent < 0 else world[parent] @ rotations[j]
    with torch.no_grad():
        joints = body(torch.from_numpy(poses))[0].numpy()
    rest = body.rest.numpy()
    moved = np.zeros_like(skin["positions"])
    for k in range(4):
        j = skin["joints"][:, k]
        local = skin["positions"] - rest[j]
        moved += skin["weights"][:, k:k + 1] * (np.einsum("vij,vj->vi", np.stack(world)[j], local) + joints[j])
    model = Mannequin("wooden", flat_hand_mean=True)
    pose = model.rest_pose()
    pose["body_pose"] = poses[0, 1:22]
    pose["hand_pose"] = poses[0, 25:]
    theirs = np.asarray(model.vertices(pose))
    assert np.abs(moved - theirs).max() < 1e-3


def body_parents():
    from emogesture.motion import PARENTS

    return PARENTS


def _validator():
    node = shutil.which("node")
    if node is None or not VALIDATOR.is_dir():
        if os.environ.get("CI"):
            pytest.fail("node or the glTF-Validator is missing (make test installs them into build/node)")
        pytest.skip("node or the glTF-Validator is missing (make test installs them)")
    return node


def validated(path):
    """The Khronos glTF-Validator's issues with the file at ``path`` (errors, warnings, infos) and its first
    messages."""
    node = _validator()
    proc = subprocess.run([node, str(ROOT / "tests" / "node" / "validate_gltf.js"), str(VALIDATOR), str(path)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    issues = json.loads(proc.stdout)["issues"]
    return (issues["numErrors"], issues["numWarnings"], issues["numInfos"]), issues["messages"][:5]


def test_khronos_validator_finds_nothing(tmp_path):
    counts, messages = validated(save_glb(gesture_like(frames=60, seed=4), tmp_path / "v.glb"))
    assert counts == (0, 0, 0), messages


def read_in_blender(path, frames, first, tmp_path, seq, skeleton="smplx", script="import_gltf.py"):
    """Import ``path`` into Debian's Blender (``tests/blender/<script>``) and check its armature: the bones of
    ``skeleton`` by their names, an action from scene frame ``first`` over every frame of ``seq``, and every
    bone's head where our forward kinematics puts its joint (within 1 cm) at the scene ``frames``, so that
    every limb points where ours does."""
    blender = shutil.which("blender")
    if blender is None:
        if os.environ.get("CI"):
            pytest.fail("blender is not installed (make test installs Debian's package)")
        pytest.skip("blender not installed (make test installs it)")
    out = tmp_path / f"{path.name}.json"
    proc = subprocess.run([blender, "-b", "--factory-startup", "--python", str(ROOT / "tests" / "blender" / script),
                           "--", str(path), str(out), *map(str, frames)], capture_output=True, text=True, timeout=300)
    assert out.is_file(), proc.stdout[-2000:] + proc.stderr[-2000:]
    got = json.loads(out.read_text())
    rig = RIGS[skeleton]
    assert got["bones"] == len(rig.joints) and set(got["names"]) == set(rig.names)
    assert got["action_frame_range"] == [first, first + seq.num_frames - 1]
    ours = fk(seq)[:, :, [0, 2, 1]] * [1, -1, 1]  # Blender: Z up; ours: Y up -> (x, -z, y)
    for f in frames:
        heads = np.array([got["heads"][str(f)][name] for name in rig.names])
        mine = ours[f - first, list(rig.joints)]
        assert np.linalg.norm(heads - mine, axis=1).max() < 0.01, f
        for b, p in enumerate(rig.parents):  # every limb (parent -> child) points where ours does: within 3 deg
            theirs, limb = heads[b] - heads[p], mine[b] - mine[p]
            if p >= 0 and np.linalg.norm(limb) > 0.01:
                cos = theirs @ limb / np.linalg.norm(theirs) / np.linalg.norm(limb)
                assert np.degrees(np.arccos(np.clip(cos, -1, 1))) < 3.0, (f, rig.names[b])
    return got


@pytest.mark.training
def test_glb_in_real_blender(tmp_path):
    seq = gesture_like(frames=40, seed=3)
    got = read_in_blender(save_glb(seq, tmp_path / "g.glb"), [0, 9, 24, 39], 0, tmp_path, seq)
    assert got["skinned"] and got["vertices"] == len(mannequin_skin(seq.betas)["positions"])


def test_three_js_plays_it_with_every_joint_where_ours_is(tmp_path):
    """three.js's GLTFLoader and AnimationMixer (what a web page uses) put every bone where our forward
    kinematics puts its joint (within 1 mm), at the first, a middle and the last frame."""
    node = _validator()
    three = ROOT / "build" / "node" / "node_modules" / "three"
    if not three.is_dir():
        if os.environ.get("CI"):
            pytest.fail("three.js is missing (make test installs it into build/node)")
        pytest.skip("three.js is missing (make test installs it)")
    seq = gesture_like(frames=45, seed=7)
    path = save_glb(seq, tmp_path / "t.glb")
    times = ["0", "0.5", "1.4666667"]  # frames 0, 15 and 44
    proc = subprocess.run([node, str(ROOT / "tests" / "node" / "three_pose.mjs"), str(three.parent), str(path), *times],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    got = json.loads(proc.stdout)
    assert got["bones"] == 55 and got["skinned"] == 1 and got["duration"] == pytest.approx(44 / 30, abs=1e-4)
    ours = fk(seq)
    for t in times:
        frame = round(float(t) * 30)
        for name, position in got["poses"][t].items():
            assert np.linalg.norm(np.array(position) - ours[frame, JOINT_NAMES.index(name)]) < 1e-3, (t, name)


def test_glb_bytes_are_reproducible():
    seq = gesture_like(frames=10, seed=1)
    assert sequence_to_gltf(seq)[1] == sequence_to_gltf(seq)[1]


@pytest.mark.training
def test_fbx_written_by_blender_reads_back_with_the_bones_frames_and_joints(tmp_path):
    seq = gesture_like(frames=40, seed=5)
    got = read_in_blender(save_fbx(seq, tmp_path / "f.fbx"), [1, 10, 25, 40], 1, tmp_path, seq)  # FBX: from 1
    assert got["skinned"]


@pytest.mark.training
@pytest.mark.parametrize("fmt", ["bvh", "glb", "fbx"])
def test_the_mixamo_rig_has_mixamo_bones_pointing_where_ours_do(tmp_path, fmt):
    """Mixamo's 52 bones by Mixamo's names, each limb (elbow -> wrist, say) pointing where ours does: every bone's
    head within 1 cm of our joint, in the file as Blender imports it."""
    seq = gesture_like(frames=30, seed=6)
    path = export_sequence(seq, tmp_path / "m", (fmt,), skeleton="mixamo")[0]
    first = 0 if fmt == "glb" else 1
    script = "import_bvh.py" if fmt == "bvh" else "import_gltf.py"
    got = read_in_blender(path, [first, first + 13, first + 29], first, tmp_path, seq, "mixamo", script)
    assert "mixamorig:LeftForeArm" in got["names"] and "mixamorig:RightHandThumb3" in got["names"]


def test_mixamo_names_and_hierarchy():
    rig = RIGS["mixamo"]
    parent = {rig.names[b]: rig.names[p] if p >= 0 else None for b, p in enumerate(rig.parents)}
    m = "mixamorig:"
    chains = [["Hips", "Spine", "Spine1", "Spine2", "Neck", "Head"],
              ["Spine2", "LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand", "LeftHandIndex1", "LeftHandIndex2"],
              ["Spine2", "RightShoulder", "RightArm", "RightForeArm", "RightHand", "RightHandThumb1"],
              ["Hips", "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase"]]
    for chain in chains:
        for up, down in zip(chain, chain[1:]):
            assert parent[m + down] == m + up
    assert len(rig.names) == 52 and parent[m + "Hips"] is None
    with pytest.raises(EmogestureError, match="--skeleton 'unreal': choose smplx or mixamo"):
        export_sequence(gesture_like(frames=3), Path("/nonexistent/x"), ("bvh",), skeleton="unreal")
    assert not Path("/nonexistent").exists()


def test_fbx_without_blender_says_what_to_install(tmp_path, monkeypatch):
    monkeypatch.setenv("EMOGESTURE_BLENDER", str(tmp_path / "no-blender"))
    with pytest.raises(EmogestureError, match="fbx export runs Blender.*apt-get install blender") as err:
        save_fbx(gesture_like(frames=5), tmp_path / "x.fbx")
    assert "\n" not in str(err.value) and not (tmp_path / "x.fbx").exists()


def with_face(seq, seed=0):
    """``seq`` with a random face track."""
    seq.arkit = np.random.default_rng(seed).uniform(0, 1, (seq.num_frames, 52)).astype(np.float32)
    return seq


def test_the_face_rig_moves_each_blendshape_where_its_name_says():
    """Every one of the 52 targets moves some of the face, by at most a few centimetres; the lower lip drops
    for jawOpen and mouthClose lifts it back, the upper lid comes down over the iris for a blink, the left
    lip corner (+X) rises for mouthSmileLeft and the left iris turns up for eyeLookUpLeft."""
    from emogesture.export.face_rig import face_rig
    from emogesture.types import ARKIT_NAMES

    skin = mannequin_skin()
    on_head = (skin["weights"] * (skin["joints"] == 15)).sum(1) > 0.5
    triangles = skin["indices"].reshape(-1, 3).astype(np.int64)
    face = face_rig(skin["positions"], triangles[on_head[triangles].all(1)])
    head = skin["positions"][on_head]
    targets, rest = face["targets"], face["positions"]
    index = {name: i for i, name in enumerate(ARKIT_NAMES)}
    size = np.linalg.norm(targets, axis=2).max(1)
    assert targets.shape == (52,) + rest.shape and (size > 0.002).all() and (size < 0.05).all()
    front = rest[:, 2] > np.quantile(rest[:, 2], 0.5)  # the face lies on the front of the head, not behind it
    assert rest[front, 2].min() > head[:, 2].max() - 0.03 and np.isfinite(face["normals"]).all()
    jaw, close = targets[index["jawOpen"]], targets[index["mouthClose"]]
    dropped = jaw[:, 1] < -0.01
    assert dropped.sum() > 50 and np.allclose(jaw[dropped] + close[dropped], 0)
    blink = targets[index["eyeBlinkLeft"]]
    assert blink[:, 1].min() < -0.01 and (blink[rest[:, 0] < 0] == 0).all()  # the left eye only
    smile = targets[index["mouthSmileLeft"]]
    assert smile[rest[:, 0] > 0.015, 1].max() > 0.008 and (smile[rest[:, 0] < 0, 1] <= 1e-9).all()
    look = targets[index["eyeLookUpLeft"]]
    assert look[:, 1].max() > 0.004 and (look[rest[:, 0] < 0] == 0).all()


def test_a_face_track_makes_a_head_with_52_arkit_morph_targets_that_validates(tmp_path):
    """With ``arkit`` the glb has a second skinned mesh named face with 52 morph targets named by ARKit
    (``extras.targetNames``) and a weights channel of 52 values a frame; the Khronos validator finds nothing."""
    from emogesture.types import ARKIT_NAMES

    seq = with_face(gesture_like(frames=40, seed=8))
    gltf, _ = sequence_to_gltf(seq)
    face = next(m for m in gltf["meshes"] if m["name"] == "face")
    assert face["extras"]["targetNames"] == list(ARKIT_NAMES) and len(face["primitives"][0]["targets"]) == 52
    node = next(i for i, n in enumerate(gltf["nodes"]) if n.get("mesh") == gltf["meshes"].index(face))
    channel = next(c for c in gltf["animations"][0]["channels"] if c["target"] == {"node": node, "path": "weights"})
    output = gltf["accessors"][gltf["animations"][0]["samplers"][channel["sampler"]]["output"]]
    assert output["count"] == 40 * 52 and node in gltf["scenes"][0]["nodes"]
    assert all(m["name"] != "face" for m in sequence_to_gltf(gesture_like(frames=40, seed=8))[0]["meshes"])
    counts, messages = validated(save_glb(seq, tmp_path / "face.glb"))
    assert counts == (0, 0, 0), messages


def test_three_js_plays_the_face_weights_of_the_npz(tmp_path):
    """three.js's morphTargetInfluences, by the ARKit names of its morphTargetDictionary, equal the face track
    at the first, a middle and the last frame."""
    from emogesture.types import ARKIT_NAMES

    node = _validator()
    three = ROOT / "build" / "node" / "node_modules" / "three"
    if not three.is_dir():
        pytest.skip("three.js is missing (make test installs it)")
    seq = with_face(gesture_like(frames=45, seed=9), seed=1)
    path = save_glb(seq, tmp_path / "f.glb")
    times = ["0", "0.5", "1.4666667"]
    proc = subprocess.run([node, str(ROOT / "tests" / "node" / "three_pose.mjs"), str(three.parent), str(path), *times],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    got = json.loads(proc.stdout)
    assert got["morph_mesh"] == "face" and got["skinned"] == 2
    for t in times:
        influences = np.array([got["morphs"][t][name] for name in ARKIT_NAMES])
        assert np.abs(influences - seq.arkit[round(float(t) * 30)]).max() < 1e-5, t


@pytest.mark.training
@pytest.mark.parametrize("fmt", ["glb", "fbx"])
def test_blender_imports_52_shape_keys_that_play_the_face_track(tmp_path, fmt):
    """Blender's importer (glb) and the fbx written through Blender read back: the skeleton as before, and 52
    shape keys by ARKit's names whose animated values equal the npz's weights within 1e-3."""
    from emogesture.types import ARKIT_NAMES

    seq = with_face(gesture_like(frames=30, seed=10), seed=2)
    path = export_sequence(seq, tmp_path / "face", (fmt,))[0]
    first = 0 if fmt == "glb" else 1
    got = read_in_blender(path, [first, first + 11, first + 29], first, tmp_path, seq)
    assert got["shape_keys"] == list(ARKIT_NAMES)
    for frame, values in got["shape_values"].items():
        assert np.abs(np.array([values[n] for n in ARKIT_NAMES]) - seq.arkit[int(frame) - first]).max() < 1e-3
