"""Run inside Blender: blender -b --factory-startup --python import_gltf.py -- FILE OUT.json FRAME...

Imports FILE (.glb with Blender's glTF importer, .fbx with its FBX importer, as File > Import does) with the
scene at 30 frames per second, and writes the armature's bone count and names, the frame range of its action,
the number of mesh vertices bound to it and the world position (Blender's Z-up frame, metres) of every bone's
head at the given frames (1-based scene frames) to OUT.json; for a mesh with shape keys (the face), their names
and values at those frames.
"""

import json
import sys

import bpy
import numpy

# Debian's Blender 3.4 glTF importer still uses numpy.bool, which numpy 1.24 (Debian's) removed.
if not hasattr(numpy, "bool"):
    numpy.bool = bool

argv = sys.argv[sys.argv.index("--") + 1:]
path, out, frames = argv[0], argv[1], [int(f) for f in argv[2:]]
for obj in list(bpy.data.objects):  # the factory scene's cube, camera and light
    bpy.data.objects.remove(obj)
scene = bpy.context.scene
scene.render.fps, scene.render.fps_base = 30, 1.0
if path.endswith(".fbx"):
    bpy.ops.import_scene.fbx(filepath=path)
else:
    bpy.ops.import_scene.gltf(filepath=path)
arm = next(o for o in scene.objects if o.type == "ARMATURE")
meshes = [o for o in scene.objects if o.type == "MESH"]
action = arm.animation_data.action
result = {"bones": len(arm.data.bones), "names": [b.name for b in arm.data.bones],
          "action_frame_range": list(action.frame_range), "fps": scene.render.fps / scene.render.fps_base,
          "vertices": sum(len(m.data.vertices) for m in meshes),
          "skinned": all(any(mod.type == "ARMATURE" for mod in m.modifiers) for m in meshes), "heads": {},
          "shape_keys": [], "shape_values": {}}
keyed = [m for m in meshes if m.data.shape_keys is not None]
if keyed:
    result["shape_keys"] = [k.name for k in keyed[0].data.shape_keys.key_blocks[1:]]  # after the Basis
for f in frames:
    scene.frame_set(f)
    result["heads"][str(f)] = {b.name: list(arm.matrix_world @ b.head) for b in arm.pose.bones}
    if keyed:
        result["shape_values"][str(f)] = {k.name: k.value for k in keyed[0].data.shape_keys.key_blocks[1:]}
with open(out, "w") as fh:
    json.dump(result, fh)
