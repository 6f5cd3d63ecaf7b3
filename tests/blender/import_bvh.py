"""Run inside Blender: blender -b --factory-startup --python import_bvh.py -- FILE.bvh OUT.json FRAME...

Imports FILE.bvh with Blender's own BVH importer (as File > Import > Motion Capture does) and writes the
bone count, the frame range of the imported action and the world position (Blender's Z-up frame, metres) of every
bone's head at the given frames (1-based scene frames) to OUT.json.
"""

import builtins
import json
import sys

import bpy

# Debian's Blender 3.4 runs on Python 3.11, which rejects the importer's open(..., 'rU'); drop the 'U'.
_open = builtins.open


def _open_without_u(file, mode="r", *args, **kwargs):
    return _open(file, mode.replace("U", "") if isinstance(mode, str) else mode, *args, **kwargs)


builtins.open = _open_without_u

argv = sys.argv[sys.argv.index("--") + 1:]
path, out, frames = argv[0], argv[1], [int(f) for f in argv[2:]]
bpy.ops.import_anim.bvh(filepath=path, global_scale=1.0, frame_start=1, use_fps_scale=False,
                        update_scene_fps=True, update_scene_duration=True, rotate_mode="NATIVE",
                        axis_forward="-Z", axis_up="Y")
arm = next(o for o in bpy.context.scene.objects if o.type == "ARMATURE")
scene = bpy.context.scene
action = arm.animation_data.action
result = {"bones": len(arm.data.bones), "action_frame_range": list(action.frame_range),
          "fps": scene.render.fps / scene.render.fps_base, "names": [b.name for b in arm.data.bones], "heads": {}}
for f in frames:
    scene.frame_set(f)
    result["heads"][str(f)] = {b.name: list(arm.matrix_world @ b.head) for b in arm.pose.bones}
with _open(out, "w") as fh:
    json.dump(result, fh)
