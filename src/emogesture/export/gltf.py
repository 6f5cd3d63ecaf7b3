"""Binary glTF 2.0 (``.glb``): a skinned mannequin playing the animation, for Blender, three.js, Godot,
Unity (with a glTF importer such as glTFast) and Unreal (glTF import).

The file holds one scene:

- the SMPL-X skeleton, one node per joint named as in :data:`~emogesture.motion.JOINT_NAMES` (or with
  ``skeleton="mixamo"`` Mixamo's 52 bones by Mixamo's names, :mod:`emogesture.motion.rigs`), each at its
  rest offset from its parent (the rest skeleton of :class:`~emogesture.motion.SkeletonBody`, so the file's
  joints are where our forward kinematics puts them), with no rest rotation;
- the ``mannequin-x`` wooden mannequin (Apache-2.0; 24 k vertices) skinned to it, four joints per vertex
  (its hand joints are our wrists; no vertex follows the jaw or the eyes);
- with a face track (``seq.arkit``), a face on the mannequin's head (:mod:`emogesture.export.face_rig`, built
  here): a second skinned mesh, bound to the head, with Apple's 52 ARKit blendshapes as morph targets named in
  ``mesh.extras.targetNames`` (as three.js and Blender read them; sparse accessors), coloured by vertex;
- one animation at the sequence's frame rate: every joint's rotation and the pelvis's translation (and the
  face's 52 morph weights), with linear interpolation. Joints the model does not animate keep their rest
  (identity) rotation.

Units are metres, +Y is up and the character faces +Z, as in SMPL-X and glTF.
"""

from __future__ import annotations

import json
import struct
from functools import lru_cache
from os import PathLike
from pathlib import Path

import numpy as np
import torch

from emogesture.errors import EmogestureError
from emogesture.export.face_rig import HEAD, face_rig
from emogesture.fileio import atomic_output
from emogesture.motion import JOINT_NAMES, rest_joints, rest_offsets
from emogesture.motion.rigs import rig_named
from emogesture.motion.rotations import axis_angle_to_matrix, matrix_to_quaternion
from emogesture.motion.skeleton import MANNEQUIN_TO_SMPLX, shape_key
from emogesture.types import ARKIT_NAMES, SMPLXSequence

# glTF constants: component types, buffer-view targets, primitive mode
_FLOAT, _UBYTE, _USHORT = 5126, 5121, 5123
_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963
_TRIANGLES = 4
#: the mannequin's hand joints sit on the wrists and turn with them
_HAND_TO_WRIST = {"L_Hand": JOINT_NAMES.index("left_wrist"), "R_Hand": JOINT_NAMES.index("right_wrist")}
WOOD = (0.78, 0.60, 0.42, 1.0)


def mannequin_skin(shape: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """The wooden mannequin at rest for SMPL-X shape coefficients ``shape`` (None = the mean body):
    ``positions [V, 3]`` float32, ``normals [V, 3]``, ``indices [F * 3]`` uint16, ``joints [V, 4]`` uint8
    (SMPL-X joint indices) and ``weights [V, 4]`` float32 (rows sum to 1). Cached per shape."""
    return _mannequin_skin(shape_key(shape))


@lru_cache(maxsize=4)
def _mannequin_skin(key: tuple[float, ...]) -> dict[str, np.ndarray]:
    try:
        from mannequin import Mannequin
    except ImportError:
        raise EmogestureError("glb export needs the mannequin-x package (pip install mannequin-x)") from None
    model = Mannequin("wooden", shape=np.asarray(key, np.float32), flat_hand_mean=True)
    positions = np.asarray(model.vertices(model.rest_pose()), np.float32)
    try:  # the skin as the package binds it (its four strongest joints per vertex)
        index, weights = np.asarray(model._skin_joint_indices), np.asarray(model._skin_weights, np.float32)
    except AttributeError:
        raise EmogestureError("this mannequin-x release keeps its skin elsewhere; glb export needs mannequin-x "
                              "0.3 (pip install 'mannequin-x>=0.3,<0.4')") from None
    to_smplx = np.array([MANNEQUIN_TO_SMPLX.get(name, _HAND_TO_WRIST.get(name, -1)) for name in model.joint_names])
    joints = np.where(weights > 0, to_smplx[index], 0)  # an unused slot names joint 0, as glTF asks
    if (joints < 0).any():
        raise EmogestureError(f"mannequin-x skins joints this exporter does not know: "
                              f"{sorted({model.joint_names[i] for i in index[joints < 0]})}")
    joints = joints.astype(np.int64)
    faces = np.asarray(model.faces, np.int64)
    if positions.shape[0] > 65535:
        raise EmogestureError("the mannequin has more vertices than 16-bit indices address")
    normals = np.zeros_like(positions, np.float64)
    corner = positions[faces].astype(np.float64)
    area = np.cross(corner[:, 1] - corner[:, 0], corner[:, 2] - corner[:, 0])  # |n| = twice the area
    for k in range(3):
        np.add.at(normals, faces[:, k], area)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True).clip(1e-12)
    return {"positions": positions, "normals": normals.astype(np.float32),
            "indices": faces.reshape(-1).astype(np.uint16), "joints": joints.astype(np.uint8),
            "weights": weights / weights.sum(1, keepdims=True)}


def sequence_rotations(seq: SMPLXSequence) -> np.ndarray:
    """Local joint rotations as unit quaternions ``[T, 55, 4]`` (x, y, z, w), each joint's kept on one
    side of the sphere from frame to frame (so interpolation between frames takes the short way)."""
    q = matrix_to_quaternion(axis_angle_to_matrix(torch.from_numpy(np.asarray(seq.poses, np.float32)))).numpy()
    flips = np.cumsum(np.concatenate([np.zeros((1, q.shape[1])), (q[1:] * q[:-1]).sum(-1) < 0]), 0) % 2
    return np.where(flips[..., None] == 1, -q, q).astype(np.float32)


class _Buffer:
    """The binary chunk: buffer views and accessors appended one after another, 4-byte aligned."""

    def __init__(self) -> None:
        self.data = bytearray()
        self.views: list[dict] = []
        self.accessors: list[dict] = []

    def add(self, array: np.ndarray, kind: str, component: int, target: int | None = None,
            bounds: bool = False, normalized: bool = False) -> int:
        array = np.ascontiguousarray(array)
        self.data += b"\0" * (-len(self.data) % 4)
        view = {"buffer": 0, "byteOffset": len(self.data), "byteLength": array.nbytes}
        if target is not None:
            view["target"] = target
        self.data += array.tobytes()
        self.views.append(view)
        count = array.shape[0] if array.ndim else 1
        accessor = {"bufferView": len(self.views) - 1, "componentType": component, "count": count, "type": kind}
        if normalized:
            accessor["normalized"] = True
        if bounds:
            flat = array.reshape(count, -1)
            accessor["min"], accessor["max"] = flat.min(0).tolist(), flat.max(0).tolist()
        self.accessors.append(accessor)
        return len(self.accessors) - 1

    def add_sparse(self, array: np.ndarray) -> int:
        """A float ``VEC3`` accessor for ``array [N, 3]`` holding only its nonzero rows (a sparse accessor over
        zeros), with the bounds glTF asks of morph-target positions."""
        rows = np.flatnonzero(np.abs(array).sum(1) > 0).astype(np.uint16 if len(array) < 65536 else np.uint32)
        views = []
        for part in (rows, np.ascontiguousarray(array[rows], np.float32)):
            self.data += b"\0" * (-len(self.data) % 4)
            self.views.append({"buffer": 0, "byteOffset": len(self.data), "byteLength": part.nbytes})
            self.data += part.tobytes()
            views.append(len(self.views) - 1)
        self.accessors.append({
            "componentType": _FLOAT, "count": len(array), "type": "VEC3",
            "min": array.min(0).astype(float).tolist(), "max": array.max(0).astype(float).tolist(),
            "sparse": {"count": len(rows), "indices": {"bufferView": views[0],
                                                      "componentType": _USHORT if rows.dtype == np.uint16 else 5125},
                       "values": {"bufferView": views[1]}}})
        return len(self.accessors) - 1


def _face_mesh(buf: _Buffer, skin: dict[str, np.ndarray], head_bone: int) -> dict:
    """The face's mesh (module docstring) in ``buf``, bound to bone ``head_bone``, on the mannequin ``skin``."""
    on_head = (skin["weights"] * (skin["joints"] == HEAD)).sum(1) > 0.5
    triangles = skin["indices"].reshape(-1, 3).astype(np.int64)
    face = face_rig(skin["positions"], triangles[on_head[triangles].all(1)])
    count = len(face["positions"])
    attributes = {
        "POSITION": buf.add(face["positions"], "VEC3", _FLOAT, _ARRAY_BUFFER, bounds=True),
        "NORMAL": buf.add(face["normals"], "VEC3", _FLOAT, _ARRAY_BUFFER),
        "COLOR_0": buf.add(face["colors"], "VEC3", _FLOAT, _ARRAY_BUFFER),
        "JOINTS_0": buf.add(np.tile(np.array([head_bone, 0, 0, 0], np.uint8), (count, 1)), "VEC4", _UBYTE,
                            _ARRAY_BUFFER),
        "WEIGHTS_0": buf.add(np.tile(np.array([1, 0, 0, 0], np.float32), (count, 1)), "VEC4", _FLOAT, _ARRAY_BUFFER),
    }
    targets = [{"POSITION": buf.add_sparse(t)} for t in face["targets"]]
    indices = buf.add(face["indices"].astype(np.uint16), "SCALAR", _USHORT, _ELEMENT_ARRAY_BUFFER)
    return {"name": "face", "primitives": [{"attributes": attributes, "indices": indices, "material": 1,
                                            "mode": _TRIANGLES, "targets": targets}],
            "weights": [0.0] * len(ARKIT_NAMES), "extras": {"targetNames": list(ARKIT_NAMES)}}


def sequence_to_gltf(seq: SMPLXSequence, name: str = "emogesture", skeleton: str = "smplx") -> tuple[dict, bytes]:
    """The glTF JSON and its binary buffer for ``seq`` with the bones of ``skeleton`` (module docstring)."""
    rig = rig_named(skeleton)
    bone_of = np.full(len(JOINT_NAMES), -1)
    bone_of[list(rig.joints)] = np.arange(len(rig.joints))
    skin = mannequin_skin(seq.betas)
    offsets, rest = rest_offsets(seq.betas), rest_joints(seq.betas)
    buf = _Buffer()
    mesh_attributes = {
        "POSITION": buf.add(skin["positions"], "VEC3", _FLOAT, _ARRAY_BUFFER, bounds=True),
        "NORMAL": buf.add(skin["normals"], "VEC3", _FLOAT, _ARRAY_BUFFER),
        "JOINTS_0": buf.add(bone_of[skin["joints"]].astype(np.uint8), "VEC4", _UBYTE, _ARRAY_BUFFER),
        "WEIGHTS_0": buf.add(skin["weights"], "VEC4", _FLOAT, _ARRAY_BUFFER),
    }
    indices = buf.add(skin["indices"], "SCALAR", _USHORT, _ELEMENT_ARRAY_BUFFER)
    # joint j's rest world transform is a translation to rest[j]; its inverse, column-major
    bones = len(rig.joints)
    inverse_bind = np.tile(np.eye(4, dtype=np.float32), (bones, 1, 1))
    inverse_bind[:, :3, 3] = -rest[list(rig.joints)]
    ibm = buf.add(inverse_bind.transpose(0, 2, 1).reshape(bones, 16), "MAT4", _FLOAT)

    frames = seq.num_frames
    times = buf.add((np.arange(frames) / float(seq.fps)).astype(np.float32), "SCALAR", _FLOAT, bounds=True)
    rotations = sequence_rotations(seq)
    channels, samplers = [], []
    for b, j in enumerate(rig.joints):
        samplers.append({"input": times, "output": buf.add(rotations[:, j], "VEC4", _FLOAT),
                         "interpolation": "LINEAR"})
        channels.append({"sampler": len(samplers) - 1, "target": {"node": b, "path": "rotation"}})
    root = (rest[0][None] + np.asarray(seq.trans, np.float32)).astype(np.float32)
    samplers.append({"input": times, "output": buf.add(root, "VEC3", _FLOAT), "interpolation": "LINEAR"})
    channels.append({"sampler": len(samplers) - 1, "target": {"node": 0, "path": "translation"}})

    nodes = []
    for b, j in enumerate(rig.joints):
        node = {"name": rig.names[b], "translation": offsets[j].astype(float).tolist()}
        children = rig.children(b)
        if children:
            node["children"] = children
        nodes.append(node)
    nodes.append({"name": "mannequin", "mesh": 0, "skin": 0})  # a root node: the skin alone places it
    meshes = [{"name": "mannequin", "primitives": [{"attributes": mesh_attributes, "indices": indices,
                                                    "material": 0, "mode": _TRIANGLES}]}]
    materials = [{"name": "wood", "pbrMetallicRoughness": {"baseColorFactor": list(WOOD), "metallicFactor": 0.0,
                                                           "roughnessFactor": 0.7}}]
    if seq.arkit is not None:
        if bone_of[HEAD] < 0:
            raise EmogestureError(f"the {rig.name} skeleton has no head bone to carry the face")
        meshes.append(_face_mesh(buf, skin, int(bone_of[HEAD])))
        materials.append({"name": "face", "doubleSided": True,
                          "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0,
                                                   "roughnessFactor": 0.6}})
        nodes.append({"name": "face", "mesh": 1, "skin": 0})
        weights = np.clip(np.asarray(seq.arkit, np.float32), 0.0, 1.0).reshape(-1)
        samplers.append({"input": times, "output": buf.add(weights, "SCALAR", _FLOAT), "interpolation": "LINEAR"})
        channels.append({"sampler": len(samplers) - 1, "target": {"node": len(nodes) - 1, "path": "weights"}})
    gltf = {
        "asset": {"version": "2.0", "generator": "emogesture"},
        "scene": 0,
        "scenes": [{"name": name, "nodes": [0, *range(len(rig.joints), len(nodes))]}],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "skins": [{"name": rig.name, "joints": list(range(bones)), "skeleton": 0,
                   "inverseBindMatrices": ibm}],
        "animations": [{"name": name, "channels": channels, "samplers": samplers}],
        "accessors": buf.accessors,
        "bufferViews": buf.views,
        "buffers": [{"byteLength": len(buf.data)}],
    }
    return gltf, bytes(buf.data)


def glb_bytes(gltf: dict, binary: bytes) -> bytes:
    """A GLB container: the 12-byte header, the JSON chunk (space-padded) and the BIN chunk (zero-padded)."""
    text = json.dumps(gltf, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    binary = binary + b"\0" * (-len(binary) % 4)
    total = 12 + 8 + len(text) + 8 + len(binary)
    return (struct.pack("<4sII", b"glTF", 2, total) + struct.pack("<I4s", len(text), b"JSON") + text
            + struct.pack("<I4s", len(binary), b"BIN\0") + binary)


def save_glb(seq: SMPLXSequence, path: str | PathLike[str], *, overwrite: bool = False,
             skeleton: str = "smplx") -> Path:
    """Write ``seq`` as a binary glTF file with the bones of ``skeleton`` (module docstring), atomically;
    refuses an existing file unless ``overwrite``."""
    data = glb_bytes(*sequence_to_gltf(seq, Path(path).stem, skeleton))
    with atomic_output(path, overwrite) as tmp:
        tmp.write_bytes(data)
    return Path(path)
