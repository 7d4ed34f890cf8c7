"""Ad-hoc real-window look: two spheres whose IOR comes from an image (1.2 / 2.0 by halves; 0.5, clamped), PRT overlay then Cycles.

blender --factory-startup --enable-event-simulate --python real_blender_ior_maps.py -- ZIP OUT_DIR (under Xvfb, as
real_blender_check.sh runs Blender, with real_blender_adhoc.py beside it): installs the zip, bakes the spheres under forest.exr, shows
the overlay in the 3D View's camera view (Solid shading) with the sidebar's PRT tab (the Display
panel's clamp note), saves the X screen, then renders the same camera with Cycles (direct light
only) into OUT_DIR.
"""

import os
import sys

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import real_blender_adhoc as adhoc


def halves(name, left, right):
    image = bpy.data.images.new(name, 64, 64, float_buffer=True)
    image.colorspace_settings.name = "Non-Color"
    px = np.ones((64, 64, 4), np.float32)
    px[:, :32, :3], px[:, 32:, :3] = left, right
    image.pixels.foreach_set(px.ravel())
    image.pack()
    return image


def material(name, image):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    tree = mat.node_tree
    bsdf = tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.2
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = image
    tree.links.new(tex.outputs["Color"], bsdf.inputs["IOR"])
    return mat


def scene_setup():
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    scene = bpy.context.scene
    scene.world = adhoc.hdri_world("forest")
    spheres = []
    for x, mat in (
        (-1.1, material("ior_map", halves("iors", 1.2, 2.0))),
        (1.1, material("below", halves("below", 0.5, 0.5))),
    ):
        bpy.ops.mesh.primitive_uv_sphere_add(segments=64, ring_count=32, radius=1.0, location=(x, 0.0, 0.0))
        sphere = bpy.context.active_object
        sphere.rotation_euler = (0.0, 0.0, np.radians(90.0))
        sphere.data.shade_smooth()
        sphere.data.materials.append(mat)
        spheres.append(sphere)
    sphere = spheres[1]
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    scene.collection.objects.link(cam)
    cam.location, cam.rotation_euler = (0.0, -7.0, 0.0), (np.pi / 2, 0.0, 0.0)
    scene.camera = cam
    scene.render.resolution_x, scene.render.resolution_y = 600, 300
    scene.view_settings.view_transform = "Standard"
    api = adhoc.api()
    api.project_world(order=8)
    api.bake(spheres, order=8, samples=128)
    scene.prt_display.specular = True
    bpy.context.view_layer.objects.active = sphere
    sphere.select_set(True)
    adhoc.camera_view(sidebar=True)


adhoc.run(scene_setup, prt_tab=True)
