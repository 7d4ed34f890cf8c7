"""The real-window check's Embree checks: embreex imports inside Blender, the shared-buffer path
answers as embreex's copy, and which Embree library the binding resolved to (dladdr)."""

import ctypes


class DlInfo(ctypes.Structure):  # dladdr's Dl_info
    _fields_ = [(n, ctypes.c_char_p if "name" in n else ctypes.c_void_p) for n in ("fname", "fbase", "sname", "saddr")]


def check(result, raytrace, buffers):
    """Records the Embree facts in result; raytrace and buffers are the extension's modules."""
    import numpy as np

    result["embree_available"] = bool(raytrace.EMBREE_AVAILABLE)
    result["embree_import_error"] = str(getattr(raytrace, "EMBREE_IMPORT_ERROR", ""))
    if not raytrace.EMBREE_AVAILABLE:
        return
    import embreex

    result["embreex_file"] = embreex.__file__
    result["shared_buffers_available"] = bool(buffers.available())
    with open("/proc/self/maps") as f:
        result["embree_libraries_mapped"] = sorted({line.split()[-1] for line in f if "embree" in line})
    # Shared against copied triangles on random rays through a random soup.
    rng = np.random.default_rng(0)
    v = rng.normal(size=(3000, 3)).astype(np.float32)
    t = rng.integers(0, 3000, size=(5000, 3)).astype(np.int32)
    o, d = rng.normal(size=(2, 20000, 3)).astype(np.float32)
    shared, copied = (raytrace.EmbreeOccluder(v, t, shared=s) for s in (True, False))
    result["geometry"] = [shared.geometry, copied.geometry]
    a, b = shared.occluded(o, d), copied.occluded(o, d)
    result["shared_vs_copied_equal"] = bool(np.array_equal(a, b))
    lib = buffers._bind(buffers._library_path())
    result["binding_origin"] = lib.origin
    address = ctypes.cast(lib.rtcGetSceneDevice, ctypes.c_void_p).value
    ctypes.CDLL(None).dladdr(ctypes.c_void_p(address), ctypes.byref(info := DlInfo()))
    result["binding_library"] = info.fname.decode()
    result["occluded_fraction"] = float(a.mean())
