"""Public Python API of PRT Lighting (stable names; documented in docs/api.md).

The maths functions are pure numpy and work without Blender. Functions that take Blender data
import the Blender layer only when called.
"""

import numpy as np

from .core import projection as _projection
from .core import rotation as _rotation
from .core import sh as _sh
from .core.directions import make_directions  # noqa: F401  (re-exported)


def sh_basis(directions, order):
    """Real orthonormal SH basis (no Condon-Shortley phase, Z up) at directions: (N, order**2)."""
    return _sh.sh_basis(directions, order)


def project_equirect(pixels, order):
    """(H, W, C) equirectangular image, row 0 at the bottom as Image.pixels -> (order**2, 3).

    NaN/Inf values are set to 0 and negative values clamped to 0; use
    prt_addon.core.projection.project_equirect to also get the counts.
    """
    coeffs, _report = _projection.project_equirect(pixels, order)
    return coeffs


def rotation_matrix(rotation, order):
    """(order**2, order**2) matrix M such that M @ c are the coefficients of f(R^-1 w).

    `rotation` is a 3x3 rotation matrix (anything np.asarray turns into one, e.g. a
    mathutils.Matrix.to_3x3()).
    """
    return _rotation.rotation_matrix(np.asarray(rotation, dtype=np.float64), order)


def project_world(scene=None, order=None):
    """Project scene.world (default: the context scene) into SH, store it on the scene and
    return the world-space coefficients (order**2, 3). order=None uses scene.prt_world.order.

    Raises ValueError (prt_addon.blender.world.WorldError) with a clear message when the world
    cannot be projected; the stored lighting is then left unchanged.
    """
    import bpy

    from .blender import world as _world

    scene = bpy.context.scene if scene is None else scene
    return _world.project_and_store(scene, order).coeffs.copy()


def world_lighting(scene=None):
    """World-space SH lighting (n*n, 3) stored on the scene for its current Mapping rotation,
    or None if nothing was projected."""
    import bpy

    from .blender import world as _world

    return _world.current_world_coeffs(bpy.context.scene if scene is None else scene)
