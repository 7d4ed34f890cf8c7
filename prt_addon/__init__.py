"""PRT Lighting: precomputed radiance transfer with spherical harmonics for Blender.

`prt_addon.core` is pure numpy and imports without Blender; `prt_addon.blender` is the thin
Blender layer. register()/unregister() import the Blender layer only when called, so that
`import prt_addon.core` (and `prt_addon.api`'s maths functions) work in a plain Python.
"""

NUMPY_MISSING = (
    "PRT Lighting needs numpy, which this Blender's Python does not have. Blender's own builds "
    "include it; a Blender from a Linux distribution may need its numpy package installed "
    "(for example python3-numpy on Debian and Ubuntu)"
)


def register():
    try:
        import numpy  # noqa: F401
    except ImportError as error:
        raise ImportError(NUMPY_MISSING) from error
    from .blender import registration

    registration.register()


def unregister():
    from .blender import registration

    registration.unregister()
