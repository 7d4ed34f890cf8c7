"""The ad-hoc real-window looks' common steps: the zip installed, the scene set up and shown in the 3D View's camera view, the X screen saved, Cycles' render.

A look's script (real_blender_spec_maps.py, real_blender_texel_specular.py,
real_blender_ior_maps.py), with this file beside it, is run as
`blender --factory-startup --enable-event-simulate --python SCRIPT -- ZIP OUT_DIR` under Xvfb (as
real_blender_check.sh runs Blender): it defines its scene and calls `run`.
"""

import importlib
import json
import os
import subprocess
import sys

import bpy

MODULE = "bl_ext.user_default.prt_lighting"
ZIP, OUT = sys.argv[sys.argv.index("--") + 1 :][:2]


def api():
    """The installed extension's prt_addon.api."""
    return importlib.import_module(f"{MODULE}.prt_addon.api")


def hdri_world(name):
    """A new world lit by one of Blender's bundled studio-light HDRIs (forest, city, ...)."""
    world = bpy.data.worlds.new(name)
    world.use_nodes = True
    env = world.node_tree.nodes.new("ShaderNodeTexEnvironment")
    folder = bpy.utils.system_resource("DATAFILES", path="studiolights/world")
    env.image = bpy.data.images.load(os.path.join(folder, f"{name}.exr"))
    world.node_tree.links.new(env.outputs["Color"], world.node_tree.nodes["Background"].inputs["Color"])
    return world


def view_3d():
    """(window, the largest 3D View area, its WINDOW region)."""
    window = bpy.context.window_manager.windows[0]
    area = max((a for a in window.screen.areas if a.type == "VIEW_3D"), key=lambda a: a.width * a.height)
    return window, area, [r for r in area.regions if r.type == "WINDOW"][0]


def camera_view(sidebar=False):
    """The 3D View in Solid shading through the scene's camera, without overlays (with the
    sidebar open when asked), the PRT display on."""
    bpy.context.scene.prt.show_display = True
    window, area, region = view_3d()
    space = area.spaces.active
    space.shading.type = "SOLID"
    space.region_3d.view_perspective = "CAMERA"
    space.overlay.show_overlays = False
    if sidebar:
        space.show_region_ui = True
    with bpy.context.temp_override(window=window, area=area, region=region):
        bpy.ops.view3d.view_center_camera()
    area.tag_redraw()


def _screenshot():
    window, _area, region = view_3d()
    box = [region.x, region.y, region.width, region.height, window.height]
    with open(os.path.join(OUT, "region.json"), "w") as f:
        f.write(json.dumps(box))
    display = os.environ.get("DISPLAY", ":99")
    subprocess.run(["import", "-display", display, "-window", "root", os.path.join(OUT, "screen.png")], check=True)


def _cycles_render():
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 128
    scene.cycles.max_bounces = 0
    scene.cycles.use_denoising = False
    scene.render.filepath = os.path.join(OUT, "cycles.png")
    bpy.ops.render.render(write_still=True)


def _prt_tab():
    _window, area, _region = view_3d()
    for region in area.regions:
        if region.type == "UI":
            region.active_panel_category = "PRT"  # (the sidebar's PRT tab: read-only during set-up, not here)
    area.tag_redraw()


def run(scene_setup, prt_tab=False):
    """Every 2 s one step: install ZIP (the splash closed), scene_setup(), the sidebar's PRT tab
    (with prt_tab), the X screen into OUT/screen.png (and the view's region in OUT/region.json),
    Cycles with direct light only into OUT/cycles.png, quit; an exception goes to OUT/error.txt."""
    steps = {1: scene_setup, 2: _prt_tab if prt_tab else None, 4: _screenshot, 5: _cycles_render}
    state = {"step": 0}

    def tick():
        step = state["step"]
        state["step"] += 1
        try:
            if step == 0:
                window = bpy.context.window_manager.windows[0]
                window.event_simulate(type="ESC", value="PRESS")  # closes the splash screen
                window.event_simulate(type="ESC", value="RELEASE")
                bpy.ops.extensions.package_install_files(filepath=ZIP, repo="user_default", enable_on_install=True)
            elif steps.get(step):
                steps[step]()
            if step == 5:
                bpy.ops.wm.quit_blender()
                return None
        except Exception as e:
            with open(os.path.join(OUT, "error.txt"), "w") as f:
                f.write(repr(e))
            bpy.ops.wm.quit_blender()
            return None
        return 2.0

    bpy.app.timers.register(tick, first_interval=1.0)
