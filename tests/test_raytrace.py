"""The Embree occluder's two ways of giving Embree the triangles: shared buffers (read in place,
core.trace.embree_buffers) and embreex's own copying TriangleMesh."""

import glob
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from prt_addon.core.trace import embree_buffers, raytrace

pytestmark = pytest.mark.skipif(not raytrace.EMBREE_AVAILABLE, reason="embreex not installed")


def wavy_grid(n=120):
    x, y = np.meshgrid(np.linspace(-1, 1, n), np.linspace(-1, 1, n))
    vertices = np.stack([x.ravel(), y.ravel(), 0.3 * np.sin(5 * x.ravel()) * np.cos(3 * y.ravel())], 1)
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    return vertices, np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)])


def random_rays(count, seed):
    rng = np.random.default_rng(seed)
    origins = rng.uniform(-1.2, 1.2, (count, 3)).astype(np.float32)
    origins[:, 2] = rng.uniform(-0.5, 0.5, count)
    return origins, rng.normal(size=(count, 3)).astype(np.float32)


def test_linux_uses_shared_buffers():
    if not sys.platform.startswith("linux"):
        pytest.skip("shared buffers are enabled on Linux only")
    assert embree_buffers.available()
    vertices, triangles = wavy_grid(8)
    assert raytrace.EmbreeOccluder(vertices, triangles).geometry == "SHARED"
    assert raytrace.EmbreeOccluder(vertices, triangles, shared=False).geometry == "COPIED"


def test_square_occludes_exactly_the_rays_through_it():
    """Two triangles forming the square [-1, 1]^2 at z = 1, rays from below: occluded exactly
    when the ray meets the plane z = 1 inside the square (rays within 1e-4 of an edge skipped)."""
    vertices = np.array([[-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], np.float64)
    triangles = np.array([[0, 1, 2], [0, 2, 3]])
    rng = np.random.default_rng(3)
    origins = np.column_stack([rng.uniform(-2, 2, (20000, 2)), rng.uniform(-1, 0.5, 20000)])
    directions = rng.normal(size=(20000, 3))
    up = directions[:, 2] > 0.05
    origins, directions = origins[up], directions[up]
    reach = (1.0 - origins[:, 2]) / directions[:, 2]
    meet = origins[:, :2] + reach[:, None] * directions[:, :2]
    inside = np.all(np.abs(meet) < 1.0, axis=1)
    clear = np.all(np.abs(np.abs(meet) - 1.0) > 1e-4, axis=1)
    for shared in (True, False):
        occluder = raytrace.EmbreeOccluder(vertices, triangles, shared=shared)
        hit = occluder.occluded(origins.astype(np.float32), directions.astype(np.float32))
        np.testing.assert_array_equal(hit[clear], inside[clear])
        assert inside[clear].sum() > 1000
        assert (~inside[clear]).sum() > 1000


def test_shared_and_copied_geometry_trace_identically():
    vertices, triangles = wavy_grid()
    origins, directions = random_rays(200_000, 1)
    shared = raytrace.EmbreeOccluder(vertices, triangles).occluded(origins, directions)
    copied = raytrace.EmbreeOccluder(vertices, triangles, shared=False).occluded(origins, directions)
    np.testing.assert_array_equal(shared, copied)
    assert 0.1 < shared.mean() < 0.9


def test_shared_buffers_do_not_alias_the_callers_arrays():
    vertices, triangles = wavy_grid(40)
    vertices = vertices.astype(np.float32)
    triangles = triangles.astype(np.int32)  # already in the dtypes Embree reads
    origins, directions = random_rays(50_000, 2)
    occluder = raytrace.EmbreeOccluder(vertices, triangles)
    before = occluder.occluded(origins, directions)
    vertices += 100.0
    triangles[:] = 0
    np.testing.assert_array_equal(occluder.occluded(origins, directions), before)


def test_attach_refuses_a_committed_scene_and_other_objects():
    if not embree_buffers.available():
        pytest.skip("shared buffers are not available here")
    from embreex import rtcore_scene

    vertices, triangles = wavy_grid(4)
    scene = rtcore_scene.EmbreeScene()
    scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32), query="OCCLUDED")
    with pytest.raises(RuntimeError, match="before the scene's first run"):
        embree_buffers.attach_triangles(scene, vertices, triangles)
    assert scene.is_committed == 1
    with pytest.raises(RuntimeError, match="layout"):
        embree_buffers.attach_triangles(object(), vertices, triangles)


def test_an_attach_error_falls_back_to_the_copy(monkeypatch):
    def failing(scene, vertices, triangles):
        raise RuntimeError("Embree error 3 while attaching shared buffers")

    monkeypatch.setattr(embree_buffers, "attach_triangles", failing)
    vertices, triangles = wavy_grid(40)
    origins, directions = random_rays(20_000, 4)
    occluder = raytrace.EmbreeOccluder(vertices, triangles)
    assert occluder.geometry == "COPIED"
    expected = raytrace.EmbreeOccluder(vertices, triangles, shared=False).occluded(origins, directions)
    np.testing.assert_array_equal(occluder.occluded(origins, directions), expected)


ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def run_python(code):
    """Run code in a fresh interpreter of this venv (a crash there fails the test, not pytest)."""
    env = dict(os.environ, PYTHONPATH=ROOT)
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True, env=env, cwd=ROOT, timeout=120
    )


def blender_embrees():
    """bpy's own libembree4 in each of this checkout's venvs (looked up when the test runs: the
    venvs of bpy 4.2 and 4.5 are made by tests/test_install.py, earlier in the same run)."""
    return sorted(
        glob.glob(os.path.join(ROOT, ".venv*", "lib", "python3*", "site-packages", "bpy", "lib", "libembree4.so*"))
    )


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="shared buffers are Linux only")
def test_shared_buffers_use_the_embree_embreex_is_bound_to():
    """When the program links its own libembree4 (as a Blender program may: Blender ships one),
    it comes first in the global symbol scope and embreex's calls go to it, not to embreex.libs:
    the shared buffers must be attached through that same library (two copies of Embree must
    never see each other's objects). Simulated by loading bpy's libembree4 with RTLD_GLOBAL
    before embreex; bpy 4.2 ships Embree 4.3, a different version from embreex's 4.4."""
    libraries = blender_embrees()
    if not libraries:
        pytest.skip("no bpy libembree4 in this checkout's venvs")
    for library in libraries:
        check_bound_to(library)


def check_bound_to(library):
    out = run_python(f"""
        import ctypes
        program = ctypes.CDLL({library!r}, mode=ctypes.RTLD_GLOBAL)
        import numpy as np
        from prt_addon.core.trace import embree_buffers, raytrace
        from tests.test_raytrace import random_rays, wavy_grid
        bound = embree_buffers._ready()
        address = lambda f: ctypes.cast(f, ctypes.c_void_p).value
        assert bound is not None and bound.origin == "the program", bound
        assert address(bound.rtcNewGeometry) == address(program.rtcNewGeometry)
        vertices, triangles = wavy_grid()
        origins, directions = random_rays(100_000, 5)
        shared = raytrace.EmbreeOccluder(vertices, triangles)
        assert shared.geometry == "SHARED"
        copied = raytrace.EmbreeOccluder(vertices, triangles, shared=False)
        assert np.array_equal(shared.occluded(origins, directions), copied.occluded(origins, directions))
        print("ok")
    """)
    assert out.returncode == 0 and out.stdout.strip().endswith("ok"), (
        library,
        out.returncode,
        out.stdout,
        out.stderr[-3000:],
    )


def test_an_embree_error_is_reported_not_a_crash():
    """embreex's error callback runs Python: the ctypes calls must hold the GIL (PyDLL), else an
    Embree error (here a misaligned shared buffer) crashes the process."""
    if not embree_buffers.available():
        pytest.skip("shared buffers are not available here")
    out = run_python("""
        import numpy as np
        from embreex import rtcore_scene
        from prt_addon.core.trace import embree_buffers
        lib = embree_buffers._ready()
        scene = rtcore_scene.EmbreeScene()
        device = lib.rtcGetSceneDevice(embree_buffers._scene_handle(scene))
        geometry = lib.rtcNewGeometry(device, 0)
        data = np.zeros(64, np.uint8)
        lib.rtcSetSharedGeometryBuffer(geometry, 1, 0, 0x9003, data.ctypes.data + 1, 0, 16, 3)
        error = lib.rtcGetDeviceError(device)
        lib.rtcReleaseGeometry(geometry)
        lib.rtcReleaseDevice(device)
        print("error", error)
    """)
    assert out.returncode == 0, (out.returncode, out.stderr[-3000:])
    assert out.stdout.split()[-1] != "0", out.stdout
