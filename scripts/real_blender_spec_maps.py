"""Ad-hoc real-window look: a sphere whose Roughness and Metallic come from a metallic-roughness image, PRT overlay then Cycles.

blender --factory-startup --enable-event-simulate --python real_blender_spec_maps.py -- ZIP OUT_DIR (under Xvfb, as
real_blender_check.sh runs Blender, with real_blender_adhoc.py beside it): installs the zip, bakes the sphere under forest.exr, shows
the overlay in the 3D View's camera view (Solid shading), saves the X screen, then renders the same
camera with Cycles (direct light only) into OUT_DIR.
"""

import os
import sys

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import real_blender_adhoc as adhoc


def orm_image():
    image = bpy.data.images.new("orm", 64, 64)
    image.colorspace_settings.name = "Non-Color"
    px = np.ones((64, 64, 4), np.float32)
    px[:, :32, 1], px[:, 32:, 1] = 0.2, 0.8  # G roughness: u < 0.5 glossy
    px[:32, :, 2], px[32:, :, 2] = 0.0, 1.0  # B metallic: v >= 0.5 metal
    image.pixels.foreach_set(px.ravel())
    image.pack()
    return image


def scene_setup():
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    scene = bpy.context.scene
    scene.world = adhoc.hdri_world("forest")
    bpy.ops.mesh.primitive_uv_sphere_add(segments=64, ring_count=32, radius=1.0)
    sphere = bpy.context.active_object
    sphere.rotation_euler = (0.0, 0.0, np.radians(90.0))
    sphere.data.shade_smooth()
    mat = bpy.data.materials.new("mapped")
    mat.use_nodes = True
    tree = mat.node_tree
    bsdf = tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = orm_image()
    sep = tree.nodes.new("ShaderNodeSeparateColor")
    tree.links.new(tex.outputs["Color"], sep.inputs[0])
    tree.links.new(sep.outputs["Green"], bsdf.inputs["Roughness"])
    tree.links.new(sep.outputs["Blue"], bsdf.inputs["Metallic"])
    sphere.data.materials.append(mat)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    scene.collection.objects.link(cam)
    cam.location, cam.rotation_euler = (0.0, -4.5, 0.0), (np.pi / 2, 0.0, 0.0)
    scene.camera = cam
    scene.render.resolution_x, scene.render.resolution_y = 400, 400
    scene.view_settings.view_transform = "Standard"
    api = adhoc.api()
    api.project_world(order=8)
    api.bake([sphere], order=8, samples=128)
    scene.prt_display.specular = True
    adhoc.camera_view()


adhoc.run(scene_setup)
