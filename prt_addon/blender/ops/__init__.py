"""Operators (prt.*): they move data between Blender and the rest and report to the user."""
