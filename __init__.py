# Extension root: Blender loads this package (the repository root) and calls register().
# Everything lives in prt_addon/; its core imports without bpy.
from .prt_addon import register, unregister  # noqa: F401
