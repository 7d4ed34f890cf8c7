"""Pure numpy core: SH maths (sh/), ray tracing (trace/), transfer (transfer/), split lights (lights/), IBL (ibl/).

Nothing in this package may import bpy, mathutils or gpu.
"""
