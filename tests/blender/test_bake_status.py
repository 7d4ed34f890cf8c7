"""Bake staleness and refusals: topology edits, removed or converted attributes, bad input, modifiers, seeds."""

import pytest


def test_topology_edit_is_stale(empty_scene, bpy_module):
    import bmesh

    bpy = bpy_module
    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=2)
    obj = bpy.context.object
    from prt_addon import api

    assert api.bake_status(obj) == "none"
    api.bake([obj], order=2, samples=32)
    assert api.bake_status(obj) == "fresh"
    obj.data.vertices[0].co.x += 0.1  # moving a vertex keeps the topology
    assert api.bake_status(obj) == "fresh"
    bm = bmesh.new()
    bm.from_mesh(obj.data)
    bmesh.ops.triangulate(bm, faces=bm.faces[:])  # already triangles: no change
    bm.to_mesh(obj.data)
    assert api.bake_status(obj) == "fresh"
    # Rotating one edge keeps every count but changes which vertices the corners use.
    bm = bmesh.new()
    bm.from_mesh(obj.data)
    bm.edges.ensure_lookup_table()
    bmesh.ops.rotate_edges(bm, edges=[bm.edges[5]], use_ccw=True)
    bm.to_mesh(obj.data)
    bm.free()
    state, reason = api.bake_status(obj, reason=True)
    assert state == "stale"
    assert "topology" in reason
    api.bake([obj], order=2, samples=32)
    assert api.bake_status(obj) == "fresh"
    bm = bmesh.new()
    bm.from_mesh(obj.data)
    bm.verts.ensure_lookup_table()
    bmesh.ops.delete(bm, geom=[bm.verts[0]], context="VERTS")
    bm.to_mesh(obj.data)
    bm.free()
    assert api.bake_status(obj) == "stale"


def test_removed_or_converted_transfer_attribute_is_reported(empty_scene, bpy_module):
    """A user deleting or converting one prt_tKK attribute: the bake is stale (not 'fresh' with
    garbage), the display does not draw it, and storage.read_transfer returns None."""
    bpy = bpy_module
    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=2)
    obj = bpy.context.object
    from prt_addon import api
    from prt_addon.blender.display import gpu_cache
    from prt_addon.blender.scene import storage

    api.bake([obj], order=3, samples=32, shadows=False)  # 9 coefficients: prt_t00 .. prt_t02
    assert api.bake_status(obj) == "fresh"
    info, problem = storage.usable_bake(obj.data)
    assert info.order == 3
    assert info.count == 3
    assert problem == ""
    elements = len(obj.data.loops) if info.domain == "CORNER" else len(obj.data.vertices)
    assert gpu_cache.read_transfer(obj.data, info).shape == (elements, 12)
    assert storage.read_transfer(obj.data).shape == (elements, 9)

    obj.data.attributes.remove(obj.data.attributes["prt_t01"])
    state, reason = api.bake_status(obj, reason=True)
    assert state == "stale"
    assert "prt_t01" in reason
    assert storage.usable_bake(obj.data) == (None, "attribute prt_t01 is missing or changed")
    assert storage.read_transfer(obj.data) is None

    api.bake([obj], order=3, samples=32, shadows=False)
    assert api.bake_status(obj) == "fresh"
    obj.data.attributes.new("prt_t02_tmp", "BYTE_COLOR", info.domain)
    obj.data.attributes.remove(obj.data.attributes["prt_t02"])
    obj.data.attributes["prt_t02_tmp"].name = "prt_t02"  # same name, wrong type
    assert api.bake_status(obj) == "stale"
    assert storage.usable_bake(obj.data)[0] is None

    api.bake([obj], order=3, samples=32, shadows=False)
    del obj.data["prt_bake"]["fingerprint"]
    assert api.bake_status(obj, reason=True) == ("stale", "the bake record is incomplete: bake again")


def test_bad_inputs_give_clear_reports(empty_scene, bpy_module, bake_ops):
    from prt_addon.blender.bake import reports as bake_reports

    bpy = bpy_module
    from prt_addon import api

    with pytest.raises(ValueError, match="nothing selected"):
        api.bake([])
    bpy.ops.object.empty_add()
    empty = bpy.context.object
    with pytest.raises(ValueError, match="not a mesh"):
        api.bake([empty])
    mesh = bpy.data.meshes.new("points")
    mesh.from_pydata([(0, 0, 0), (1, 0, 0)], [(0, 1)], [])
    points = bpy.data.objects.new("points", mesh)
    empty_scene.collection.objects.link(points)
    with pytest.raises(ValueError, match="has no faces"):
        api.bake([points])
    with pytest.raises(ValueError, match="order"):
        api.bake([points], order=0)
    bpy.ops.mesh.primitive_cube_add(location=(5, 0, 0))
    cube = bpy.context.object
    report = api.bake([cube, empty, points], order=2, samples=16)
    assert report.objects == [cube.name]
    assert [name for name, _ in report.skipped] == [points.name]  # (explained: it is a mesh)
    assert [name for name, _ in report.left_out] == [empty.name]  # (no geometry: left out quietly)
    assert any("Skipped" in line for line in report.summary_lines())
    # The operator: empty selection, then a non-mesh only.
    bpy.ops.object.select_all(action="DESELECT")
    with pytest.raises(RuntimeError, match="nothing selected"):
        bpy.ops.prt.bake_transfer()
    assert "nothing selected" in bake_reports.last_report(empty_scene)["message"]
    empty.select_set(True)
    with pytest.raises(RuntimeError, match="not a mesh"):
        bpy.ops.prt.bake_transfer()
    assert "not a mesh" in bake_reports.last_report(empty_scene)["message"]


def test_modifiers_deform_is_used_topology_change_is_refused(empty_scene, bpy_module, mesh_io):
    bpy = bpy_module
    from prt_addon import api

    bpy.ops.mesh.primitive_grid_add(x_subdivisions=6, y_subdivisions=6, size=2)
    grid = bpy.context.object
    wave = grid.modifiers.new("Wave", "WAVE")  # moves vertices only: same topology
    wave.height, wave.width, wave.narrowness = 0.5, 0.5, 0.5
    report = api.bake([grid], order=2, samples=64)
    # The flat base mesh cannot shadow itself; the curved one (what the user sees) can.
    assert report.rays_traced > 0
    assert report.objects == [grid.name]
    grid.modifiers.new("Subdivision", "SUBSURF")
    with pytest.raises(ValueError, match="Apply"):
        api.bake([grid], order=2, samples=16)


def test_bad_seed_is_refused_before_any_ray(empty_scene, bpy_module, mesh_io, monkeypatch):
    bpy = bpy_module
    bpy.ops.mesh.primitive_plane_add()
    plane = bpy.context.object
    from prt_addon import api
    from prt_addon.blender.bake import job as bake_job

    monkeypatch.setattr(bake_job.BakeJob, "steps", lambda *a, **k: pytest.fail("traced before validating"))
    for seed in (None, -1, 2.5):
        with pytest.raises(ValueError, match="seed must be an integer >= 0"):
            api.bake([plane], seed=seed)
    assert "prt_bake" not in plane.data
