"""The core and the API's maths import in a Python where bpy, mathutils and gpu are blocked."""

import subprocess
import sys
import textwrap


def test_core_and_api_import_without_bpy():
    # bpy is blocked in a fresh interpreter: importing it would raise ImportError.
    code = textwrap.dedent(
        """
        import sys
        sys.modules["bpy"] = None
        sys.modules["mathutils"] = None
        sys.modules["gpu"] = None
        import prt_addon.core.sh, prt_addon.api
        import pkgutil, importlib, prt_addon.core as core
        for info in pkgutil.iter_modules(core.__path__):
            importlib.import_module("prt_addon.core." + info.name)
        import numpy as np
        print(prt_addon.api.sh_basis(np.array([[0.0, 0.0, 1.0]]), 2).shape)
        """
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=".")
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "(1, 4)"
