"""Ad-hoc real-window look: a glossy metal floor baked per texel with a box on it under city.exr, PRT overlay then Cycles.

blender --factory-startup --enable-event-simulate --python real_blender_texel_specular.py -- ZIP OUT_DIR (under
Xvfb, as real_blender_check.sh runs Blender): installs the zip, bakes the floor per texel (32 x 32)
and the box per vertex under city.exr with the light split on, shows the overlay with Specular on
in the 3D View's camera view (Solid shading), saves the X screen, then renders the same camera with
Cycles (direct light only) into OUT_DIR: the floor before the box's foot mirrors the box, not the sky.
"""

import importlib
import json
import math
import os
import subprocess
import sys

import bpy

ZIP, OUT = sys.argv[sys.argv.index("--") + 1 :][:2]
MODULE = "bl_ext.user_default.prt_lighting"
state = {"step": 0}


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
    world = bpy.data.worlds.new("city")
    world.use_nodes = True
    env = world.node_tree.nodes.new("ShaderNodeTexEnvironment")
    folder = bpy.utils.system_resource("DATAFILES", path="studiolights/world")
    env.image = bpy.data.images.load(os.path.join(folder, "city.exr"))
    world.node_tree.links.new(env.outputs["Color"], world.node_tree.nodes["Background"].inputs["Color"])
    scene.world = world
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
    api = importlib.import_module(f"{MODULE}.prt_addon.api")
    api.project_world(order=8, split_lights=True)
    api.bake([floor], order=8, samples=256, target="TEXELS", uv_map="UVMap", resolution=32)
    api.bake([box], order=8, samples=256)
    scene.prt_display.specular = True
    scene.prt.show_display = True
    window = bpy.context.window_manager.windows[0]
    area = max((a for a in window.screen.areas if a.type == "VIEW_3D"), key=lambda a: a.width * a.height)
    space = area.spaces.active
    space.shading.type = "SOLID"
    space.region_3d.view_perspective = "CAMERA"
    space.overlay.show_overlays = False
    with bpy.context.temp_override(window=window, area=area, region=[r for r in area.regions if r.type == "WINDOW"][0]):
        bpy.ops.view3d.view_center_camera()
    area.tag_redraw()


def tick():
    step = state["step"]
    state["step"] += 1
    try:
        if step == 0:
            window = bpy.context.window_manager.windows[0]
            window.event_simulate(type="ESC", value="PRESS")  # closes the splash screen
            window.event_simulate(type="ESC", value="RELEASE")
            bpy.ops.extensions.package_install_files(filepath=ZIP, repo="user_default", enable_on_install=True)
        elif step == 1:
            scene_setup()
        elif step == 4:
            window = bpy.context.window_manager.windows[0]
            area = max((a for a in window.screen.areas if a.type == "VIEW_3D"), key=lambda a: a.width * a.height)
            region = [r for r in area.regions if r.type == "WINDOW"][0]
            box = [region.x, region.y, region.width, region.height, window.height]
            open(os.path.join(OUT, "region.json"), "w").write(json.dumps(box))
            subprocess.run(
                [
                    "import",
                    "-display",
                    os.environ.get("DISPLAY", ":99"),
                    "-window",
                    "root",
                    os.path.join(OUT, "screen.png"),
                ],
                check=True,
            )
        elif step == 5:
            scene = bpy.context.scene
            scene.render.engine = "CYCLES"
            scene.cycles.samples = 128
            scene.cycles.max_bounces = 0
            scene.cycles.use_denoising = False
            scene.render.filepath = os.path.join(OUT, "cycles.png")
            bpy.ops.render.render(write_still=True)
            bpy.ops.wm.quit_blender()
            return None
    except Exception as e:
        open(os.path.join(OUT, "error.txt"), "w").write(repr(e))
        bpy.ops.wm.quit_blender()
        return None
    return 2.0


bpy.app.timers.register(tick, first_interval=1.0)
