"""Run in a fresh interpreter with BLENDER_USER_RESOURCES set: install the zip as a user would.

    python tests/e2e_install_script.py ZIP RESULT_JSON

Installs the zip with Blender's extension installer, enables it, uses it, disables and removes
it, and writes what it observed to RESULT_JSON (the pytest side asserts on it).
"""

import json
import os
import sys

import bpy

MODULE = "bl_ext.user_default.prt_lighting"


def our_handlers():
    found = []
    for name in dir(bpy.app.handlers):
        handlers = getattr(bpy.app.handlers, name)
        if isinstance(handlers, list):
            found += [f"{name}:{h.__name__}" for h in handlers if getattr(h, "__module__", "").startswith(MODULE)]
    return found


def main(zip_path, result_path):
    import addon_utils
    import numpy as np

    result = {}
    repos = [r.module for r in bpy.context.preferences.extensions.repos]
    result["install"] = list(bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=True))
    result["enabled"] = list(addon_utils.check(MODULE))
    site = os.path.join(bpy.utils.user_resource("EXTENSIONS"), ".local", "lib", "python3.11", "site-packages")
    result["bundled_embreex"] = os.path.isdir(os.path.join(site, "embreex"))
    result["scene_property"] = hasattr(bpy.types.Scene, "prt")
    result["panel"] = hasattr(bpy.types, "VIEW3D_PT_prt")

    api = sys.modules[MODULE + ".prt_addon.api"] if MODULE + ".prt_addon.api" in sys.modules else __import__(MODULE + ".prt_addon.api", fromlist=["api"])
    result["basis_north_pole"] = api.sh_basis(np.array([[0.0, 0.0, 1.0]]), 2)[0].tolist()

    result["handlers_while_enabled"] = our_handlers()
    result["disable"] = list(bpy.ops.preferences.addon_disable(module=MODULE))
    result["scene_property_after_disable"] = hasattr(bpy.types.Scene, "prt")
    result["panel_after_disable"] = hasattr(bpy.types, "VIEW3D_PT_prt")
    result["handlers_after_disable"] = our_handlers()
    result["uninstall"] = list(bpy.ops.extensions.package_uninstall(repo_index=repos.index("user_default"), pkg_id="prt_lighting"))
    result["files_left"] = os.path.exists(os.path.join(bpy.utils.user_resource("EXTENSIONS"), "user_default", "prt_lighting"))
    with open(result_path, "w") as f:
        json.dump(result, f, indent=1)


if __name__ == "__main__":
    main(sys.argv[-2], sys.argv[-1])
