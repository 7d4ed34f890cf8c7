"""The back side of open texel-baked meshes: its image, record and staleness, shade of each side, the front untouched, all or nothing."""

import hashlib

import numpy as np
import pytest
from helpers.worlds import new_world

BACK = "PRT Plane (back)"


def _plane_and_cube(bpy, scene):
    new_world(bpy, scene)
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    plane = bpy.context.active_object
    bpy.ops.mesh.primitive_cube_add(location=(4.0, 0.0, 1.0))
    return plane, bpy.context.active_object


def _texels(objects, **options):
    from prt_addon import api

    settings = dict(order=3, samples=256, target="TEXELS", uv_map="UVMap", resolution=8)
    settings.update(options)
    return api.bake(objects, **settings)


def _digest(image):
    buf = np.empty(len(image.pixels), np.float32)
    image.pixels.foreach_get(buf)
    return hashlib.sha256(buf.tobytes()).hexdigest()


def test_a_plane_alone_under_a_uniform_sky_is_one_on_each_side(bpy_module, empty_scene):
    """Radiance 1 from every direction, nothing else in the scene: E/pi = 1 on both sides of
    every covered texel. The closed cube gets no back side and says so."""
    from prt_addon import api

    bpy = bpy_module
    plane, cube = _plane_and_cube(bpy, empty_scene)
    bpy.data.objects.remove(cube)
    api.project_world(empty_scene, 4)
    _texels([plane], samples=512)
    record = plane.data["prt_bake"]
    assert record["back"] == 1 and record["back_image"] == BACK and record["image"] == "PRT Plane"
    assert bpy.data.images[BACK].size[:] == bpy.data.images["PRT Plane"].size[:]
    assert bpy.data.images[BACK].packed_file is not None
    front, back = api.shade(plane), api.shade(plane, side="BACK")
    assert front.shape == back.shape == (8, 8, 3)
    np.testing.assert_allclose(front, 1.0, atol=3e-3)
    np.testing.assert_allclose(back, 1.0, atol=3e-3)
    assert api.bake_status(plane) == "fresh"


def test_the_back_sees_what_is_under_the_plane_and_the_closed_cube_has_none(bpy_module, empty_scene):
    """A cube under the plane's middle shadows its underside there, not its top (uniform sky)."""
    from prt_addon import api

    bpy = bpy_module
    plane, cube = _plane_and_cube(bpy, empty_scene)
    cube.location = (0.0, 0.0, -0.6)
    cube.scale = (0.5, 0.5, 0.5)
    api.project_world(empty_scene, 4)
    _texels([plane, cube], samples=512)
    front, back = api.shade(plane), api.shade(plane, side="BACK")
    middle, rim = back[3:5, 3:5].mean(), back[[0, -1]].mean()
    assert front.min() > 0.99
    assert middle < 0.75 * rim  # the cube covers the back's view down there
    assert "back" not in cube.data["prt_bake"] and "PRT Cube (back)" not in bpy.data.images
    with pytest.raises(ValueError, match="no back-side transfer"):
        api.shade(cube, side="BACK")


def test_the_front_image_is_bit_for_bit_the_one_without_a_back_side(bpy_module, empty_scene, monkeypatch):
    """The back side is baked after the front and adds nothing to it: the same bake with the back
    side turned off (the plane taken for closed) writes the same front image."""
    from prt_addon import api
    from prt_addon.blender.bake import texels

    bpy = bpy_module
    plane, cube = _plane_and_cube(bpy, empty_scene)
    api.project_world(empty_scene, 4)
    for adaptive in (0.05, 0.0):
        _texels([plane, cube], adaptive=adaptive)
        with_back = _digest(bpy.data.images["PRT Plane"])
        assert BACK in bpy.data.images
        with monkeypatch.context() as patch:
            patch.setattr(texels.back_side, "is_open", lambda triangles: False)
            _texels([plane, cube], adaptive=adaptive)
        assert BACK not in bpy.data.images and "back" not in plane.data["prt_bake"]  # (the old one went)
        assert _digest(bpy.data.images["PRT Plane"]) == with_back


def test_with_bounces_the_back_gets_direct_light_only(bpy_module, empty_scene):
    """The back image of a bake with bounces is the one without, bit for bit (docs/bake.md)."""
    from prt_addon import api

    bpy = bpy_module
    plane, cube = _plane_and_cube(bpy, empty_scene)
    cube.location = (0.0, 0.0, -0.6)
    api.project_world(empty_scene, 4)
    _texels([plane, cube])
    direct = _digest(bpy.data.images[BACK])
    _texels([plane, cube], bounces=2)
    assert plane.data["prt_bake"]["bounce_channels"] == 1
    assert _digest(bpy.data.images[BACK]) == direct
    assert api.shade(plane, side="BACK").shape == (8, 8, 3)


def test_stale_without_its_back_image_and_gone_with_a_vertex_bake(bpy_module, empty_scene):
    from prt_addon import api

    bpy = bpy_module
    plane, _cube = _plane_and_cube(bpy, empty_scene)
    api.project_world(empty_scene, 4)
    _texels([plane])
    bpy.data.images.remove(bpy.data.images[BACK])
    state, reason = api.bake_status(plane, reason=True)
    assert state == "stale" and "back-side image" in reason
    _texels([plane])
    assert api.bake_status(plane) == "fresh"
    api.bake([plane], order=2, samples=64)  # per vertex: its back side is attributes again
    assert BACK not in bpy.data.images and "PRT Plane" not in bpy.data.images
    assert "prt_tb00" in plane.data.attributes and plane.data["prt_bake"]["back"] == 1


def test_a_failed_write_of_the_back_image_leaves_everything_as_it_was(bpy_module, empty_scene, monkeypatch):
    from prt_addon import api
    from prt_addon.blender.scene import texel_storage

    bpy = bpy_module
    plane, _cube = _plane_and_cube(bpy, empty_scene)
    api.project_world(empty_scene, 4)
    _texels([plane])
    before = {image.name: _digest(image) for image in bpy.data.images}
    record = plane.data["prt_bake"].to_dict()
    stage = texel_storage.stage_image

    def broken(name, image):
        if name.endswith(texel_storage.BACK_SUFFIX):
            raise RuntimeError("disk full")
        return stage(name, image)

    monkeypatch.setattr(texel_storage, "stage_image", broken)
    with pytest.raises(RuntimeError, match="disk full"):
        _texels([plane], order=2)
    assert {image.name: _digest(image) for image in bpy.data.images} == before
    assert plane.data["prt_bake"].to_dict() == record


def test_cancelled_while_the_back_side_bakes_writes_nothing(bpy_module, empty_scene):
    from prt_addon import api
    from prt_addon.blender.bake.job import BakeJob
    from prt_addon.blender.bake.settings import BakeSettings
    from prt_addon.core.transfer import quadrature

    bpy = bpy_module
    plane, _cube = _plane_and_cube(bpy_module, empty_scene)
    api.project_world(empty_scene, 4)
    settings = BakeSettings(order=3, samples=256, target="TEXELS", uv_map="UVMap", resolution=16, chunk_rays=4096)
    job = BakeJob([plane], settings)
    labels = []
    with pytest.raises(quadrature.Cancelled):  # noqa: PT012 (the steps run until the back side)
        for _fraction, text in job.steps():
            labels.append(text)
            if text.startswith("Baking the back"):
                job.cancel()
        job.finish()
    assert any(t.startswith("Baking the back") for t in labels)
    assert "prt_bake" not in plane.data and not [i for i in bpy.data.images if i.name.startswith("PRT")]


def test_the_estimate_counts_the_back_side_of_an_open_mesh(bpy_module, empty_scene, monkeypatch):
    """An open quad's texel bake traces its texels twice and holds texel_memory's back part."""
    from prt_addon.blender.bake import estimate
    from prt_addon.blender.bake.settings import BakeSettings, texel_memory

    plane, _cube = _plane_and_cube(bpy_module, empty_scene)
    settings = BakeSettings(order=8, samples=256, target="TEXELS", resolution=64, shadows=False)
    both = estimate.estimate([plane], settings)
    monkeypatch.setattr(estimate, "mesh_is_open", lambda mesh: False)
    front = estimate.estimate([plane], settings)
    assert both.rays == 2 * front.rays == 2 * 64 * 64 * 256
    assert both.bytes - front.bytes == texel_memory(64, 8, back=True) - texel_memory(64, 8) > 0


def test_the_back_of_a_rug_on_the_floor_is_baked_as_shadowed(bpy_module, empty_scene):
    """Contacts as the front's, turned over: a quad lying on a larger floor quad has its back on
    the floor, facing it. Rays offset to the back would start under the floor and see the sky
    below it (1 under the uniform sky); found by the contact ray, those samples are shadowed."""
    from prt_addon import api

    bpy = bpy_module
    new_world(bpy, empty_scene)
    bpy.ops.mesh.primitive_plane_add(size=8.0)  # the floor
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    rug = bpy.context.active_object
    api.project_world(empty_scene, 4)
    report = _texels([rug], samples=512)
    assert any("under another surface on their back" in note for note in report.texel_notes)
    assert not any("under another surface and" in note for note in report.texel_notes)
    np.testing.assert_allclose(api.shade(rug), 1.0, atol=3e-3)
    assert np.abs(api.shade(rug, side="BACK")).max() < 1e-6
