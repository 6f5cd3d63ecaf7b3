"""Run by Blender, not imported: ``blender -b --factory-startup --python blender_fbx.py -- IN.glb OUT.fbx FPS``.

Imports IN.glb with Blender's glTF importer at FPS frames per second and writes OUT.fbx with Blender's FBX
exporter: the armature (no leaf bones added), the skinned mesh and the baked animation, Y up and -Z forward
(FBX's usual axes, as Unity and Unreal expect). Used by :func:`emogesture.export.fbx.save_fbx`.
"""


def main() -> None:
    import sys

    import bpy
    import numpy

    if not hasattr(numpy, "bool"):  # Blender 3.4's glTF importer still uses numpy.bool (gone in numpy 1.24)
        numpy.bool = bool
    src, dst, fps = sys.argv[sys.argv.index("--") + 1:][:3]
    for obj in list(bpy.data.objects):  # the factory scene's cube, camera and light
        bpy.data.objects.remove(obj)
    scene = bpy.context.scene
    scene.render.fps, scene.render.fps_base = round(float(fps)), round(float(fps)) / float(fps)
    bpy.ops.import_scene.gltf(filepath=src)
    armature = next(o for o in scene.objects if o.type == "ARMATURE")
    scene.frame_start, scene.frame_end = (int(f) for f in armature.animation_data.action.frame_range)
    for obj in scene.objects:  # the bake samples the skeleton only: no need to deform the mesh at every frame
        for modifier in obj.modifiers:
            if modifier.type == "ARMATURE":
                modifier.show_viewport = False
    bpy.ops.export_scene.fbx(filepath=dst, check_existing=False,
                             object_types={"ARMATURE", "MESH"}, add_leaf_bones=False, bake_anim=True,
                             bake_anim_use_all_actions=False, bake_anim_use_nla_strips=False,
                             bake_anim_simplify_factor=0.0, primary_bone_axis="Y", secondary_bone_axis="X",
                             axis_forward="-Z", axis_up="Y")


if __name__ == "__main__":
    main()
