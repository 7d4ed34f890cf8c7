"""Principled specular: the split-sum BRDF table, its energy compensation, specular occlusion."""
