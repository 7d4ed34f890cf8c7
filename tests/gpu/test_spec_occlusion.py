"""The full transfer's specular occlusion drawn per vertex into a texture: numpy's values, summed in the frame while the view moves and drawn again once it stands (viewport and render_view), not when the lighting turns, freed on file load."""

import math
import types

import numpy as np
import pytest
from helpers.display_scenes import add_camera, clamped_cosine_rows, make_sphere, write_bake
from helpers.specular_scenes import principled_material
from helpers.worlds import new_world

ORDER = 4
ROUGHNESS = 1.0
SIZE = 64


def _cone_transfer(normals, order):
    """(N, order^2): V(w) max(n.w, 0) / pi on SH with V 1 above z = 0.3 only (a sky seen through
    a round opening over the sphere), by quadrature over 20000 Fibonacci directions."""
    from prt_addon.core.sh import basis, directions

    dirs = directions.fibonacci_directions(20000)
    y = basis.sh_basis(dirs, order) * (4.0 * np.pi / len(dirs))
    weight = np.maximum(normals @ dirs.T, 0.0) / np.pi * (dirs[:, 2] > 0.3)
    return weight @ y


def _expected(obj, eye):
    """Per vertex: core.specular.occlusion.transfer_occlusion at the vertex's reflection
    direction seen from `eye` (the object at the origin, unrotated)."""
    from prt_addon.core.sh import basis
    from prt_addon.core.specular import occlusion

    mesh = obj.data
    p = np.array([v.co for v in mesh.vertices], dtype=np.float64)
    n = np.array([v.normal for v in mesh.vertices], dtype=np.float64)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    v = eye - p
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    r = 2.0 * np.sum(n * v, axis=1, keepdims=True) * n - v
    bands = occlusion.lobe_bands(ROUGHNESS**2, 32)[:ORDER]
    return occlusion.transfer_occlusion(
        _cone_transfer(n, ORDER), clamped_cosine_rows(n, ORDER), basis.sh_basis(r, ORDER), bands
    )


def _drawn(obj):
    """The first slot's occlusion texture as (vertices,) values, and the key it was drawn for."""
    from prt_addon.blender.display import gpu_cache

    occ = gpu_cache._object_cache[obj.as_pointer()].spec_occ[0]
    values = np.array(occ.texture.read().to_list(), dtype=np.float64).reshape(-1, 2)
    return values[: len(obj.data.vertices), 0], occ.key


@pytest.fixture
def occluded_sphere(bpy_module, empty_scene, gpu_ready):
    from prt_addon.blender.world import projection

    scene = empty_scene
    scene.prt_display.specular = True
    new_world(bpy_module, scene, (1.0, 1.0, 1.0), 1.0)
    projection.project_and_store(scene, ORDER)
    obj = make_sphere(bpy_module, segments=32, rings=16)
    normals = np.array([v.normal for v in obj.data.vertices], dtype=np.float64)
    write_bake(obj, _cone_transfer(normals, ORDER), ORDER)
    obj.data.materials.append(principled_material(bpy_module, "Rough", (0.8, 0.8, 0.8), ROUGHNESS, 1.0))
    cam = add_camera(bpy_module, scene, size=SIZE)
    return scene, obj, cam


def _viewport(bpy, scene):
    """The viewport's draw (draw_viewport) from the scene camera, into an offscreen."""
    import gpu
    import mathutils

    from prt_addon.blender.display import draw, offscreen

    view, proj = offscreen.camera_matrices(scene, SIZE, SIZE)
    context = types.SimpleNamespace(
        scene=scene,
        region_data=types.SimpleNamespace(perspective_matrix=mathutils.Matrix((proj @ view).tolist())),
        view_layer=bpy.context.view_layer,
        space_data=None,
        evaluated_depsgraph_get=bpy.context.evaluated_depsgraph_get,
    )
    off = gpu.types.GPUOffScreen(SIZE, SIZE, format="RGBA32F")
    with off.bind():
        gpu.state.active_framebuffer_get().clear(color=(0.0, 0.0, 0.0, 0.0), depth=1.0)
        draw.draw_viewport(context)
    off.free()


def test_moving_the_view_draws_the_occlusion_again(bpy_module, occluded_sphere):
    """A first draw from a new eye sums the occlusion in the frame (the texture left as it was);
    the next draw from it draws the texture, each vertex's texel numpy's transfer_occlusion at its
    reflection direction from that eye (1e-4), and the frame reading it equals the one that
    summed it; for two cameras in turn, through render_view and the viewport's draw. Turning the
    lighting draws nothing."""
    import prt_addon.api as api
    from prt_addon.blender.scene import lighting

    bpy = bpy_module
    scene, obj, cam = occluded_sphere
    poses = [((0.0, -6.0, 0.0), (math.pi / 2, 0.0, 0.0)), ((0.0, 0.0, -6.0), (math.pi, 0.0, 0.0))]
    expected = []
    for location, euler in poses:
        cam.location, cam.rotation_euler = location, euler
        bpy.context.view_layer.update()
        expected.append(_expected(obj, np.array(location)))
    assert np.mean(np.abs(expected[0] - expected[1]) > 0.1) > 0.2  # the two views differ
    key = None
    for draw in ("render_view", "viewport"):
        for (location, euler), want in zip(poses, expected):
            cam.location, cam.rotation_euler = location, euler
            bpy.context.view_layer.update()
            frame = (
                (lambda: api.render_view(scene, SIZE, SIZE))
                if draw == "render_view"
                else (lambda: _viewport(bpy, scene))
            )
            moving = frame()
            if key is not None:
                assert _drawn(obj)[1] is key, draw  # no pass while the view moves
            still = frame()
            got, key = _drawn(obj)
            np.testing.assert_allclose(np.clip(got, 0.0, 1.0), want, atol=1e-4, err_msg=draw)  # (clamped per pixel)
            if draw == "render_view":
                assert (moving[..., 3] > 0).sum() > 500
                np.testing.assert_allclose(still, moving, atol=1e-5)
    lighting.set_light_override(scene, np.eye(ORDER * ORDER, 3) * 0.7)
    _viewport(bpy, scene)
    assert _drawn(obj)[1] is key  # the lighting does not enter the occlusion


def test_file_load_frees_the_occlusion_textures(bpy_module, occluded_sphere):
    """The occlusion textures live in the objects' display state and the points shaders in their
    own cache: both are empty after a file load."""
    import prt_addon.api as api
    from prt_addon.blender.display import gpu_cache, spec_occlusion

    scene, obj, _cam = occluded_sphere
    api.render_view(scene, SIZE, SIZE)
    api.render_view(scene, SIZE, SIZE)  # (the second from the same eye draws the texture)
    assert _drawn(obj)[0].size == len(obj.data.vertices) and spec_occlusion._programs
    bpy_module.ops.wm.read_homefile(use_empty=True)
    assert gpu_cache._object_cache == {} and spec_occlusion._programs == {}
