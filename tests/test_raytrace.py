"""The Embree occluder's two ways of giving Embree the triangles: shared buffers (read in place,
core.embree_buffers) and embreex's own copying TriangleMesh."""

import sys

import numpy as np
import pytest

from prt_addon.core import embree_buffers, raytrace

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
        assert inside[clear].sum() > 1000 and (~inside[clear]).sum() > 1000


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
