"""Ad-hoc real-window look: a glossy metal floor baked per texel with a box on it under city.exr, PRT overlay then Cycles.

blender --factory-startup --enable-event-simulate --python real_blender_texel_specular.py -- ZIP OUT_DIR (under
Xvfb, as real_blender_check.sh runs Blender): installs the zip, bakes the floor per texel (32 x 32)
and the box per vertex under city.exr with the light split on, shows the overlay with Specular on
in the 3D View's camera view (Solid shading), saves the X screen, then renders the same camera with
Cycles (direct light only) into OUT_DIR: the floor before the box's foot mirrors the box, not the sky.
The steps are real_blender_adhoc.py's, which must be beside it.
"""

import math
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import real_blender_adhoc as adhoc


def principled(name, base, roughness, metallic):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*base, 1.0)
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["Metallic"].default_value = metallic
    return mat


def scene_setup():
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    scene = bpy.context.scene
    scene.world = adhoc.hdri_world("city")
    bpy.ops.mesh.primitive_plane_add(size=4.0)
    floor = bpy.context.active_object
    floor.data.materials.append(principled("floor", (0.8, 0.8, 0.8), 0.2, 1.0))
    bpy.ops.mesh.primitive_cube_add(size=0.8, location=(0.0, 0.3, 0.4))
    box = bpy.context.active_object
    box.data.materials.append(principled("box", (0.5, 0.5, 0.5), 1.0, 0.0))
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    scene.collection.objects.link(cam)
    pitch = math.atan2(1.1, 3.0)
    cam.location, cam.rotation_euler = (0.0, -3.0, 1.1), (math.pi / 2 - pitch, 0.0, 0.0)
    cam.data.lens = 35.0
    scene.camera = cam
    scene.render.resolution_x, scene.render.resolution_y = 480, 288
    scene.view_settings.view_transform = "Standard"
    api = adhoc.api()
    api.project_world(order=8, split_lights=True)
    api.bake([floor], order=8, samples=256, target="TEXELS", uv_map="UVMap", resolution=32)
    api.bake([box], order=8, samples=256)
    scene.prt_display.specular = True
    adhoc.camera_view()


adhoc.run(scene_setup)
