"""Back faces in Blender: which bakes get a back transfer, where it is stored, what shade returns for each side, a failed write."""

import numpy as np
import pytest
from helpers.worlds import new_world


def _plane_and_cube(bpy, scene):
    new_world(bpy, scene)
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=4, y_subdivisions=4, size=2.0)
    plane = bpy.context.active_object
    bpy.ops.mesh.primitive_cube_add(location=(4.0, 0.0, 1.0))
    return plane, bpy.context.active_object


def _names(obj):
    return sorted(a.name for a in obj.data.attributes if a.name.startswith("prt_t"))


def test_open_mesh_gets_a_back_transfer_and_a_closed_one_does_not(bpy_module, empty_scene):
    from prt_addon import api

    plane, cube = _plane_and_cube(bpy_module, empty_scene)
    api.project_world(empty_scene, 4)
    report = api.bake([plane, cube], order=4, samples=512)
    assert _names(plane) == [f"prt_t{k:02d}" for k in range(4)] + [f"prt_tb{k:02d}" for k in range(4)]
    assert _names(cube) == [f"prt_t{k:02d}" for k in range(4)]
    assert plane.data["prt_bake"]["back"] == 1 and "back" not in cube.data["prt_bake"]
    assert plane.data["prt_bake"]["version"] == 1  # old readers draw the front transfer, as before
    assert not (plane.data.color_attributes.active_color_name or "").startswith("prt_tb")
    # Uniform white sky of radiance 1: the top sees it but for the cube, the underside sees it all.
    top, bottom = api.shade(plane), api.shade(plane, side="BACK")
    assert top.shape == bottom.shape == (25, 3)
    np.testing.assert_allclose(bottom, 1.0, atol=3e-3)
    assert 0.9 < top.min() < 0.999 and top.max() <= 1.003
    assert report.rays_traced > 0
    with pytest.raises(ValueError, match="no back-side transfer"):
        api.shade(cube, side="BACK")
    with pytest.raises(ValueError, match="side must be"):
        api.shade(plane, side="INSIDE")


def test_back_attributes_go_when_the_mesh_is_closed_or_baked_per_texel(bpy_module, empty_scene):
    import bmesh

    from prt_addon import api

    plane, _cube = _plane_and_cube(bpy_module, empty_scene)
    api.project_world(empty_scene, 4)
    api.bake([plane], order=3, samples=128)
    assert "prt_tb02" in plane.data.attributes
    api.bake([plane], order=2, samples=128)  # fewer coefficients: the extra back attributes go
    assert _names(plane) == ["prt_t00", "prt_tb00"]
    bm = bmesh.new()  # close the plane into a box: no boundary edge left
    bm.from_mesh(plane.data)
    bmesh.ops.extrude_face_region(bm, geom=bm.faces[:])
    bmesh.ops.contextual_create(bm, geom=[e for e in bm.edges if e.is_boundary])
    bm.to_mesh(plane.data)
    bm.free()
    api.bake([plane], order=2, samples=128)
    assert _names(plane) == ["prt_t00"] and "back" not in plane.data["prt_bake"]


def test_a_failed_write_leaves_the_back_attributes_as_they_were(bpy_module, empty_scene, monkeypatch):
    from prt_addon import api
    from prt_addon.blender.scene import back_storage

    plane, _cube = _plane_and_cube(bpy_module, empty_scene)
    api.project_world(empty_scene, 4)
    api.bake([plane], order=2, samples=128)
    before = {n: np.array(plane.data.attributes[n].data[0].color) for n in _names(plane)}

    def broken(mesh, values, domain):
        mesh.attributes[back_storage.back_attribute_name(0)].data[0].color = (9.0, 9.0, 9.0, 9.0)
        raise RuntimeError("disk full")

    monkeypatch.setattr(back_storage, "write_back", broken)
    with pytest.raises(RuntimeError, match="disk full"):
        api.bake([plane], order=3, samples=128)
    assert _names(plane) == sorted(before)
    for name, value in before.items():
        np.testing.assert_array_equal(np.array(plane.data.attributes[name].data[0].color), value)
    assert plane.data["prt_bake"]["order"] == 2 and plane.data["prt_bake"]["back"] == 1


def test_a_texel_bake_replaces_the_back_attributes_with_its_back_image(bpy_module, empty_scene):
    from prt_addon import api

    plane, cube = _plane_and_cube(bpy_module, empty_scene)
    api.project_world(empty_scene, 4)
    api.bake([plane], order=2, samples=128)
    api.bake([plane, cube], order=2, samples=64, target="TEXELS", uv_map="UVMap", resolution=8)
    assert _names(plane) == [] and plane.data["prt_bake"]["back_image"] == "PRT Grid (back)"
    assert api.shade(plane, side="BACK").shape == (8, 8, 3)
    with pytest.raises(ValueError, match="no back-side transfer"):
        api.shade(cube, side="BACK")
