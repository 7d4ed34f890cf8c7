"""Pure numpy core: SH maths, direction sets, projection, rotation, windows, transfer.

Nothing in this package may import bpy, mathutils or gpu.
"""
