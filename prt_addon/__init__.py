"""PRT Lighting: precomputed radiance transfer with spherical harmonics for Blender.

`prt_addon.core` is pure numpy and imports without Blender; `prt_addon.blender` is the thin
Blender layer. register()/unregister() import the Blender layer only when called, so that
`import prt_addon.core` (and `prt_addon.api`'s maths functions) work in a plain Python.
"""


def register():
    from .blender import registration

    registration.register()


def unregister():
    from .blender import registration

    registration.unregister()
