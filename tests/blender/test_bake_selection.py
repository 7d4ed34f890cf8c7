"""Selecting everything and baking: objects with no geometry are left out quietly, meshes that could not be baked are explained."""

import pytest


def test_cameras_and_lights_selected_with_the_meshes_are_left_out_quietly(bpy_module, empty_scene):
    from prt_addon import api

    bpy = bpy_module
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    plane = bpy.context.object
    bpy.ops.object.camera_add()
    bpy.ops.object.light_add(type="SUN")
    bpy.ops.curve.primitive_bezier_circle_add()
    curve = bpy.context.object
    report = api.bake(list(empty_scene.objects), order=2, samples=16)
    assert report.objects == [plane.name]
    assert [name for name, _why in report.skipped] == [curve.name]  # (it could be converted)
    assert sorted(name for name, _why in report.left_out) == ["Camera", "Sun"]
    assert "Left out 2 object(s) with no geometry to bake (cameras, lights, empties)" in report.report_lines()
    assert not any("Camera" in line for line in report.report_lines() if line.startswith("Skipped"))


def test_only_a_camera_selected_is_still_refused_with_its_reason(bpy_module, empty_scene):
    from prt_addon import api

    bpy_module.ops.object.camera_add()
    with pytest.raises(ValueError, match="nothing to bake: 'Camera' is a camera, not a mesh"):
        api.bake([bpy_module.context.object], order=2, samples=16)
