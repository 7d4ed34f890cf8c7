"""Run in a fresh interpreter with BLENDER_USER_RESOURCES set: install the zip as a user would.

    python tests/blender/e2e_install_script.py ZIP RESULT_JSON [embree|no-embree]

Installs the zip with Blender's extension installer, enables it, uses it (projects a world with a
bundled HDRI, bakes a sphere on a plane, shades it, rotates the lighting), disables and removes
it, and writes what it observed to RESULT_JSON (the pytest side asserts on it).

no-embree: embreex is made unimportable before the extension is enabled, as on a platform with
no embreex wheel (Linux or Windows on ARM): the bake must fall back to the BVH tree and say so.
"""

import json
import os
import sys
import types

import bpy

MODULE = "bl_ext.user_default.prt_lighting"


def our_handlers():
    found = []
    for name in dir(bpy.app.handlers):
        handlers = getattr(bpy.app.handlers, name)
        if isinstance(handlers, list):
            found += [f"{name}:{h.__name__}" for h in handlers if getattr(h, "__module__", "").startswith(MODULE)]
    return found


def our_functions():
    """Every function defined in the extension's modules (candidates for bpy.app.timers)."""
    funcs = []
    for name, module in list(sys.modules.items()):
        if not name.startswith(MODULE) or module is None:
            continue
        for value in vars(module).values():
            if isinstance(value, types.FunctionType) and value.__module__ == name:
                funcs.append(value)
            elif isinstance(value, type) and value.__module__ == name:
                funcs += [v for v in vars(value).values() if isinstance(v, types.FunctionType)]
    return funcs


def registered_timers(funcs):
    return sorted(f.__qualname__ for f in funcs if bpy.app.timers.is_registered(f))


def build_scene():
    """A UV sphere on a plane under a world with Blender's bundled forest.exr."""
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    bpy.ops.mesh.primitive_plane_add(size=6)
    plane = bpy.context.object
    bpy.ops.mesh.primitive_uv_sphere_add(segments=24, ring_count=12, location=(0, 0, 1))
    sphere = bpy.context.object
    sphere.data.shade_smooth()
    world = bpy.data.worlds.new("PRT World")
    if world.node_tree is None:  # Blender 4.x
        world.use_nodes = True
    bpy.context.scene.world = world
    tree = world.node_tree
    env = tree.nodes.new("ShaderNodeTexEnvironment")
    folder = bpy.utils.system_resource("DATAFILES", path="studiolights/world")
    env.image = bpy.data.images.load(os.path.join(folder, "forest.exr"))
    tree.links.new(env.outputs["Color"], tree.nodes["Background"].inputs["Color"])
    return plane, sphere


def use_it(result, api):
    import numpy as np

    scene = bpy.context.scene
    plane, sphere = build_scene()
    scene.prt_world.order = 4
    result["project"] = list(bpy.ops.prt.project_world())
    result["light_c0"] = api.world_lighting(scene)[0].tolist()
    bpy.ops.object.select_all(action="DESELECT")
    plane.select_set(True)
    sphere.select_set(True)
    scene.prt_bake.order, scene.prt_bake.samples = 4, 64
    result["bake"] = list(bpy.ops.prt.bake_transfer())
    bake_runner = sys.modules[MODULE + ".prt_addon.blender.bake.runner"]
    bake_reports = sys.modules[MODULE + ".prt_addon.blender.bake.reports"]
    result["bake_report"] = bake_reports.last_report(scene)
    result["backend"] = sphere.data["prt_bake"]["backend"]
    result["status"] = [api.bake_status(plane), api.bake_status(sphere)]
    radiance = api.shade(sphere)
    top = int(np.argmax([v.co.z for v in sphere.data.vertices]))
    bottom = int(np.argmin([v.co.z for v in sphere.data.vertices]))
    result["shade"] = {
        "shape": list(radiance.shape),
        "finite": bool(np.isfinite(radiance).all()),
        "min": float(radiance.min()),
        "max": float(radiance.max()),
        "mean": float(radiance.mean()),
        "top": radiance[top].tolist(),
        "bottom": radiance[bottom].tolist(),
    }
    result["rotate"] = list(bpy.ops.prt.set_light_rotation(rotation=(0.0, 0.0, 1.5)))
    rotated = api.shade(sphere)
    result["rotation_changes_shading"] = float(np.abs(rotated - radiance).max())
    display = sys.modules[MODULE + ".prt_addon.blender.display.draw"]
    result["draw_handler_while_enabled"] = display.draw_handle() is not None
    return display, bake_runner


def main(zip_path, result_path, mode="embree"):
    import addon_utils
    import numpy as np

    if mode == "no-embree":
        sys.modules["embreex"] = None  # `import embreex` now raises ImportError
    result = {"mode": mode}
    repos = [r.module for r in bpy.context.preferences.extensions.repos]
    result["install"] = list(
        bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=True)
    )
    result["enabled"] = list(addon_utils.check(MODULE))
    site = os.path.join(bpy.utils.user_resource("EXTENSIONS"), ".local", "lib", "python3.11", "site-packages")
    result["bundled_embreex"] = os.path.isdir(os.path.join(site, "embreex"))
    result["scene_property"] = hasattr(bpy.types.Scene, "prt")
    result["panel"] = hasattr(bpy.types, "VIEW3D_PT_prt")

    api = __import__(MODULE + ".prt_addon.api", fromlist=["api"])
    raytrace = sys.modules[MODULE + ".prt_addon.core.trace.raytrace"]
    result["embree_available"] = bool(raytrace.EMBREE_AVAILABLE)
    result["basis_north_pole"] = api.sh_basis(np.array([[0.0, 0.0, 1.0]]), 2)[0].tolist()

    display, bake_ops = use_it(result, api)
    funcs = our_functions()
    result["functions_checked_for_timers"] = len(funcs)
    result["timers_while_enabled"] = registered_timers(funcs)
    result["handlers_while_enabled"] = our_handlers()
    result["disable"] = list(bpy.ops.preferences.addon_disable(module=MODULE))
    result["scene_property_after_disable"] = hasattr(bpy.types.Scene, "prt")
    result["panel_after_disable"] = hasattr(bpy.types, "VIEW3D_PT_prt")
    result["operators_after_disable"] = [
        n for n in ("project_world", "bake_transfer", "set_light_rotation") if hasattr(bpy.types, f"PRT_OT_{n}")
    ]
    result["handlers_after_disable"] = our_handlers()
    result["timers_after_disable"] = registered_timers(funcs)
    result["draw_handler_after_disable"] = display.draw_handle() is not None
    result["running_bakes_after_disable"] = len(bake_ops._running)
    result["uninstall"] = list(
        bpy.ops.extensions.package_uninstall(repo_index=repos.index("user_default"), pkg_id="prt_lighting")
    )
    result["files_left"] = os.path.exists(
        os.path.join(bpy.utils.user_resource("EXTENSIONS"), "user_default", "prt_lighting")
    )
    with open(result_path, "w") as f:
        json.dump(result, f, indent=1)


if __name__ == "__main__":
    args = sys.argv[1:]
    main(*args[-3:]) if args and args[-1] in ("embree", "no-embree") else main(args[-2], args[-1])
