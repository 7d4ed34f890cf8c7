"""Spherical harmonics: the basis, rotation, projection of images, closed forms, direction sets, frames."""
