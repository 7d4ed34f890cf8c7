"""Mesh reading for the bake: triangles as Blender's own loop triangles, and the per-vertex or
per-corner choice of bake points."""

import numpy as np


def _loop_triangles(mesh):
    """Blender's own triangulation, read element by element (the reference)."""
    mesh.calc_loop_triangles()
    out = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int32)
    mesh.loop_triangles.foreach_get("vertices", out)
    return out.reshape(-1, 3)


def _mesh(bpy, name, vertices, faces):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(map(float, v)) for v in vertices], [], [tuple(map(int, f)) for f in faces])
    mesh.update()
    return mesh


def _flips(mesh):
    """Per quad of the mesh: whether Blender's first split (0-2 diagonal) was replaced."""
    from prt_addon.blender.scene import mesh_read

    triangles = _loop_triangles(mesh)
    corner_verts = mesh_read.read_corner_verts(mesh)
    starts = mesh_read.read_face_starts(mesh)
    sizes = np.diff(starts, append=len(corner_verts))
    first = np.cumsum(sizes - 2) - (sizes - 2)
    quads = np.flatnonzero(sizes == 4)
    return triangles[first[quads], 2] != corner_verts[starts[quads] + 2]


def test_read_triangles_matches_loop_triangles_on_quads_and_triangles(empty_scene, bpy_module, addon):
    """Random non-planar quads (about half of them take Blender's flipped split), darts concave
    at either corner, degenerate quads (a repeated point, collinear points, all one point) and
    triangles, mixed in one mesh: the same triangles in the same order as mesh.loop_triangles."""
    from prt_addon.blender.scene import mesh_read

    bpy = bpy_module
    rng = np.random.default_rng(7)
    vertices, faces = [], []

    def add(points):
        faces.append(range(len(vertices), len(vertices) + len(points)))
        vertices.extend(points)

    for _ in range(300):
        add(rng.normal(size=(4, 3)))
        add(rng.normal(size=(3, 3)))
    add([(0, 0, 0), (1, 1, 0), (2, 0, 0), (1, 0.5, 0)])  # dart, concave at the 4th corner
    add([(0, 0, 0), (1, 0.5, 0), (2, 0, 0), (1, 1, 0)])  # concave at the 2nd corner
    add([(0, 0, 0), (1, 0, 0), (1, 0, 0), (0, 1, 0)])  # a repeated point
    add([(0, 0, 0), (1, 0, 0), (2, 0, 0), (3, 0, 0)])  # collinear
    add([(1, 2, 3)] * 4)  # one point
    mesh = _mesh(bpy, "mixed", vertices, faces)
    flips = _flips(mesh)
    assert 0.2 < flips.mean() < 0.8
    assert flips[-5:-3].all()
    np.testing.assert_array_equal(mesh_read.read_triangles(mesh), _loop_triangles(mesh))

    # Shared vertices: a subdivided, noisy grid (quads only) and a subdivided Suzanne.
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=30, y_subdivisions=20)
    grid = bpy.context.object.data
    co = mesh_read.read_positions(grid) + rng.normal(0, 0.2, (len(grid.vertices), 3)).astype(np.float32)
    grid.attributes["position"].data.foreach_set("vector", co.ravel())
    grid.update()
    bpy.ops.mesh.primitive_monkey_add()
    monkey = bpy.context.object
    monkey.modifiers.new("s", "SUBSURF").levels = 1
    bpy.ops.object.modifier_apply(modifier="s")
    assert _flips(grid).any()  # (Suzanne has none)
    for shape in (grid, monkey.data):
        np.testing.assert_array_equal(mesh_read.read_triangles(shape), _loop_triangles(shape))


def test_read_triangles_with_ngons_and_without_faces(empty_scene, bpy_module, addon):
    """N-gons (here a concave hexagon and a cylinder's caps) are read from loop_triangles; a mesh
    without faces has no triangles."""
    from prt_addon.blender.scene import mesh_read

    bpy = bpy_module
    hexagon = [(0, 0, 0), (2, 0, 0), (2, 2, 0), (1, 0.5, 0), (0, 2, 0), (-0.5, 1, 0)]
    mesh = _mesh(bpy, "ngon", hexagon + [(0, 0, 1), (1, 0, 1), (0, 1, 1)], [range(6), (6, 7, 8)])
    np.testing.assert_array_equal(mesh_read.read_triangles(mesh), _loop_triangles(mesh))
    assert len(mesh_read.read_triangles(mesh)) == 5
    bpy.ops.mesh.primitive_cylinder_add(vertices=12)
    cylinder = bpy.context.object.data
    np.testing.assert_array_equal(mesh_read.read_triangles(cylinder), _loop_triangles(cylinder))
    points = _mesh(bpy, "points", [(0, 0, 0), (1, 0, 0)], [])
    assert mesh_read.read_triangles(points).shape == (0, 3)


def test_flat_grid_with_rounded_normals_bakes_per_vertex(empty_scene, bpy_module, addon):
    """A flat-shaded grid's face normals come out as (0, 0, 1) or (0, 0, 0.99999994) depending
    on the face; still one normal per vertex, so one bake point per vertex (POINT)."""
    from prt_addon.blender.scene import mesh_read

    bpy = bpy_module
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=150, y_subdivisions=150, size=8)
    mesh = bpy.context.object.data
    assert mesh.normals_domain != "POINT"
    normals = mesh_read.read_corner_normals(mesh)
    assert len(np.unique(normals, axis=0)) > 1  # not bit-identical: the case under test
    points = mesh_read.bake_points(mesh, np.eye(4))
    assert points.domain == "POINT"
    assert len(points.positions) == len(mesh.vertices)
    np.testing.assert_allclose(points.normals, np.tile([0.0, 0.0, 1.0], (len(mesh.vertices), 1)), atol=1e-6)


def test_read_face_materials_from_the_attribute_and_without_it(empty_scene, bpy_module, addon):
    """The faces' material slots read from the material_index attribute equal mesh.polygons';
    a mesh that never had slots assigned (no attribute) reads slot 0 everywhere."""
    from prt_addon.blender.scene import mesh_read as mesh_io

    bpy = bpy_module
    mesh = _mesh(bpy, "slots", [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (2, 0, 0)], [(0, 1, 2, 3), (1, 4, 2)])
    assert mesh.attributes.get("material_index") is None
    assert mesh_io.read_face_materials(mesh).tolist() == [0, 0]
    for name in ("a", "b", "c"):
        mesh.materials.append(bpy.data.materials.new(name))
    mesh.polygons.foreach_set("material_index", [2, 1])
    expected = np.zeros(2, dtype=np.int32)
    mesh.polygons.foreach_get("material_index", expected)
    assert mesh_io.read_face_materials(mesh).tolist() == expected.tolist() == [2, 1]
