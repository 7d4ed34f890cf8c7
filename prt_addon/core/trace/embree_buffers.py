"""Zero-copy triangle geometry for an embreex scene, through Embree's C API (ctypes).

embreex's `TriangleMesh` constructor copies the vertices and indices into Embree's buffers one
element at a time through Python indexing, holding the GIL: ~0.08 s for 216k triangles, longer
than Embree's own BVH build. Embree can instead read the caller's arrays in place
(`rtcSetSharedGeometryBuffer`, Embree 4 API, rtcore_geometry.h); embreex does not expose it, so
this module calls it on the scene handle of an `EmbreeScene`, in the same libembree4 that
embreex's own calls are bound to (`_bind`).

The scene handle is the first field of the Cython object (`cdef RTCScene scene_i`, `cdef public
int is_committed`, `cdef EmbreeDevice device`; rtcore_scene.pxd). That layout is checked on
every call (the public `is_committed` and the device object must be found at their offsets), and
the whole path is checked once per process by tracing known rays. When anything does not match,
`available()` is False and the caller uses `TriangleMesh`. Enabled on Linux only, where it is
tested.
"""

from __future__ import annotations

import ctypes
import gc
import glob
import os
import sys
import threading
import types
from typing import Any

import numpy as np

# Embree 4 enums (rtcore_common.h, rtcore_buffer.h, rtcore_geometry.h).
_GEOMETRY_TYPE_TRIANGLE = 0
_BUFFER_TYPE_INDEX = 0
_BUFFER_TYPE_VERTEX = 1
_FORMAT_UINT3 = 0x5003
_FORMAT_FLOAT3 = 0x9003
_NO_ERROR = 0

_P = ctypes.c_void_p
_SIGNATURES = {
    "rtcGetSceneDevice": (_P, [_P]),
    "rtcReleaseDevice": (None, [_P]),
    "rtcGetDeviceError": (ctypes.c_int, [_P]),
    "rtcNewGeometry": (_P, [_P, ctypes.c_int]),
    "rtcSetSharedGeometryBuffer": (
        None,
        [_P, ctypes.c_int, ctypes.c_uint, ctypes.c_int, _P, ctypes.c_size_t, ctypes.c_size_t, ctypes.c_size_t],
    ),
    "rtcCommitGeometry": (None, [_P]),
    "rtcAttachGeometry": (ctypes.c_uint, [_P, _P]),
    "rtcReleaseGeometry": (None, [_P]),
}

_lock = threading.Lock()
_state: dict[str, Any] = {}


def _library_path():
    """embreex's own copy of libembree4 (the wheel's embreex.libs), or None."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        import embreex
    except (ImportError, OSError):
        return None
    package = os.path.dirname(os.path.abspath(embreex.__file__))
    found = sorted(glob.glob(os.path.join(os.path.dirname(package), "embreex.libs", "libembree4*.so*")))
    return found[0] if len(found) == 1 else None


def _bind(path):
    """The Embree functions embreex's extension modules call, and where they come from.

    The dynamic linker resolves a symbol of a dlopen()ed module in the global scope (the program,
    its libraries and RTLD_GLOBAL ones) before the module's own dependencies. A Blender program
    linked with its own libembree4 therefore makes embreex call that one; bpy imported as a
    Python module keeps it private, and embreex calls the copy in embreex.libs. Calling the
    other copy would mix the objects of two Embree libraries. PyDLL, not CDLL: the calls keep the
    GIL, because the error callback embreex installs on the device runs Python code.
    """
    source = ctypes.PyDLL(None)  # the global scope
    if not hasattr(source, "rtcNewScene"):
        source = ctypes.PyDLL(path)  # already loaded by embreex: the same handle
    functions = {}
    for name, (restype, argtypes) in _SIGNATURES.items():
        function = getattr(source, name)
        function.restype, function.argtypes = restype, argtypes
        functions[name] = function
    return types.SimpleNamespace(origin=source._name or "the program", **functions)


def _scene_handle(scene):
    """The RTCScene of an embreex EmbreeScene, after checking the object's layout."""
    from embreex.rtcore_scene import EmbreeScene

    address = id(scene)
    if type(scene) is not EmbreeScene or EmbreeScene.__basicsize__ != 40:
        raise RuntimeError("unexpected EmbreeScene layout")
    devices = [r for r in gc.get_referents(scene) if type(r).__name__ == "EmbreeDevice"]
    if len(devices) != 1 or ctypes.c_void_p.from_address(address + 32).value != id(devices[0]):
        raise RuntimeError("unexpected EmbreeScene layout")
    saved = scene.is_committed
    try:
        for probe in (0x5A5A1234, 0x12345A5A):
            scene.is_committed = probe
            if ctypes.c_int.from_address(address + 24).value != probe:
                raise RuntimeError("unexpected EmbreeScene layout")
    finally:
        scene.is_committed = saved
    handle = ctypes.c_void_p.from_address(address + 16).value
    if not handle:
        raise RuntimeError("the EmbreeScene has no Embree scene")
    return handle


def _attach(lib, scene, vertices, triangles):
    """Attach float32 (V, 3) vertices and int32 (T, 3) triangles (validated) to an uncommitted
    scene; returns the arrays Embree reads, which must live as long as the scene."""
    padded = np.zeros((len(vertices), 4), dtype=np.float32)  # 16-byte rows, as Embree prefers
    padded[:, :3] = vertices
    indices = np.array(triangles, dtype=np.uint32, order="C")  # a copy the caller cannot change
    handle = _scene_handle(scene)
    if scene.is_committed:
        raise RuntimeError("geometry must be attached before the scene's first run()")
    device = lib.rtcGetSceneDevice(handle)  # one more reference to the device, released below
    try:
        geometry = lib.rtcNewGeometry(device, _GEOMETRY_TYPE_TRIANGLE)
        if not geometry:
            raise RuntimeError(f"rtcNewGeometry failed (Embree error {lib.rtcGetDeviceError(device)})")
        try:
            lib.rtcSetSharedGeometryBuffer(
                geometry, _BUFFER_TYPE_VERTEX, 0, _FORMAT_FLOAT3, padded.ctypes.data, 0, 16, len(padded)
            )
            lib.rtcSetSharedGeometryBuffer(
                geometry, _BUFFER_TYPE_INDEX, 0, _FORMAT_UINT3, indices.ctypes.data, 0, 12, len(indices)
            )
            lib.rtcCommitGeometry(geometry)
            lib.rtcAttachGeometry(handle, geometry)
        finally:
            lib.rtcReleaseGeometry(geometry)  # the scene keeps its own reference
        error = lib.rtcGetDeviceError(device)
    finally:
        lib.rtcReleaseDevice(device)
    if error != _NO_ERROR:
        raise RuntimeError(f"Embree error {error} while attaching shared buffers")
    return padded, indices


def _self_test(lib, scene_type):
    """Trace known rays against one triangle attached this way: True when all answers are right."""
    scene = scene_type()
    keep = _attach(
        lib, scene, np.array([[-1, -1, 1], [1, -1, 1], [0, 1, 1]], np.float32), np.array([[0, 1, 2]], np.int32)
    )
    origins = np.zeros((3, 3), np.float32)
    directions = np.array([[0, 0, 1], [0, 0, -1], [5, 0, 1]], np.float32)
    hits = scene.run(origins, directions, query="OCCLUDED") == 0
    del scene, keep
    return hits.tolist() == [True, False, False]


def _ready():
    """The bound Embree functions (`_bind`) when the shared path works here, else None (decided
    once per process)."""
    with _lock:
        if "lib" not in _state:
            _state["lib"] = None
            path = _library_path()
            if path is not None:
                try:
                    from embreex import rtcore_scene

                    lib = _bind(path)
                    if _self_test(lib, rtcore_scene.EmbreeScene):
                        _state["lib"] = lib
                except Exception:
                    pass
        return _state["lib"]


def available() -> bool:
    """True when `attach_triangles` can be used with this embreex on this platform."""
    return _ready() is not None


def attach_triangles(scene: Any, vertices: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Attach validated float32 (V, 3) vertices and int32 (T, 3) triangles to an uncommitted
    embreex EmbreeScene without copying them element by element; returns the buffers Embree
    reads (keep them referenced for as long as the scene is used)."""
    lib = _ready()
    if lib is None:
        raise RuntimeError("shared Embree buffers are not available here")
    return _attach(lib, scene, vertices, triangles)
