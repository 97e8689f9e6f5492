import bpy

bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.wm.usd_import(filepath="out/bench/stage.usda")

bpy.data.objects["p1"].location.x += 1.0  # the person 1 m east (to the right in the image)

bpy.ops.mesh.primitive_cube_add(size=0.6, location=(1.5, 1.0, 0.3))  # a new crate
crate = bpy.context.active_object
crate.name = "crate"
crate.data.materials.append(bpy.data.materials.new("wood"))  # named like a library material
crate["humv_class"] = "prop"
crate["humv_temperature_k"] = 320.0

bpy.ops.wm.usd_export(filepath="out/edited.usd", export_animation=True)
