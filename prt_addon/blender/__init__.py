"""Blender layer: moves data between Blender and prt_addon.core, and the UI around it."""
