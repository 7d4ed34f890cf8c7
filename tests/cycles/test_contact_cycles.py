"""Surfaces in contact in Blender against Cycles: a box on the ground, a wall on a floor, touching boxes, the bake.

The Cycles tests bake DIFFUSE / DIRECT to a FLOAT_COLOR CORNER attribute: E/pi per corner
(white albedo excluded), sampled at the corner's vertex with its face's normal. The PRT side
is the core run on the same corners (vertex position, corner normal) with the scene's
triangles in Embree, under a uniform world of radiance 1, where E/pi = sqrt(4 pi) t_0. Values
are compared as row means (the rows of a box side at one height); Cycles at 256 samples and
the 1024-direction quadrature differ by at most 0.009 per row on these scenes (measured), so
the tolerance is ROW_TOLERANCE = 0.025 (E/pi is 0.5 - 1 here). Before the change the bottom
rows were 1.00 against Cycles' 0.50. The BVHTree fallback gets the same fix at the seam.
"""

import numpy as np
import pytest
from helpers.contact import DIRECTIONS, _add, _grid, _prt, _read, _wall, embree

ROW_TOLERANCE = 0.025
SAMPLES = 256  # Cycles


# --- against Cycles ------------------------------------------------------------------------


def _white_world(bpy, scene):
    world = bpy.data.worlds.new("World")
    if world.node_tree is None:
        world.use_nodes = True
    background = world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    background.inputs["Strength"].default_value = 1.0
    scene.world = world


def _box(size, cuts):
    def build(bmesh, bm):
        bmesh.ops.create_cube(bm, size=size)
        bmesh.ops.subdivide_edges(bm, edges=bm.edges[:], cuts=cuts, use_grid_fill=True)

    return build


def _cycles(bpy, scene, obj):
    """E/pi per corner of obj from Cycles."""
    mesh = obj.data
    attr = mesh.color_attributes.new("bake", "FLOAT_COLOR", "CORNER")
    mesh.color_attributes.active_color = attr
    for other in scene.objects:
        other.select_set(other == obj)
    bpy.context.view_layer.objects.active = obj
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = SAMPLES
    bpy.ops.object.bake(type="DIFFUSE", pass_filter={"DIRECT"}, target="VERTEX_COLORS", use_clear=True)
    out = np.empty(len(mesh.loops) * 4, np.float32)
    mesh.color_attributes["bake"].data.foreach_get("color", out)
    return out.reshape(-1, 4)[:, :3].mean(axis=1).astype(np.float64)


def _rows(values, key, select):
    """{rounded key: mean of values over the selected corners with that key}."""
    keys = np.round(key, 4)
    return {k: float(values[select & (keys == k)].mean()) for k in np.unique(keys[select])}


def _compare(label, cycles, new, old, key, select):
    rc, rn, ro = _rows(cycles, key, select), _rows(new, key, select), _rows(old, key, select)
    for k in rc:
        print(f"{label} {k:+.3f}: cycles {rc[k]:.4f}  prt {rn[k]:.4f}  before {ro[k]:.4f}")
    return rc, rn, ro


def _assert_rows_agree(rc, rn):
    worst = max(abs(rn[k] - rc[k]) for k in rc)
    assert worst <= ROW_TOLERANCE, (worst, rc, rn)


@embree
def test_box_on_ground_bottom_row_like_cycles(empty_scene, bpy_module):
    bpy, scene = bpy_module, empty_scene
    _white_world(bpy, scene)
    ground = _add(bpy, scene, "ground", _grid(4.0, 16))
    box = _add(bpy, scene, "box", _box(1.0, 3), (0.0, 0.0, 0.5))  # standing on z = 0
    cycles = _cycles(bpy, scene, box)
    new, old, pos, normals = _prt([box, ground], 0)
    side = np.abs(normals[:, 2]) < 0.5
    rc, rn, _ro = _compare("box side z", cycles, new, old, pos[:, 2], side)
    z = sorted(rc)
    # Not brighter than the row above beyond what Cycles shows (Cycles: 0.50 and 0.59).
    assert rn[z[0]] - rn[z[1]] <= rc[z[0]] - rc[z[1]] + ROW_TOLERANCE
    _assert_rows_agree(rc, rn)


@embree
def test_wall_on_floor_bottom_row_like_cycles(empty_scene, bpy_module):
    bpy, scene = bpy_module, empty_scene
    _white_world(bpy, scene)
    floor = _add(bpy, scene, "floor", _grid(4.0, 16))
    wall = _add(bpy, scene, "wall", _wall(2.0, 1.0, 8))
    cycles = _cycles(bpy, scene, wall)
    new, old, pos, normals = _prt([wall, floor], 0)
    assert np.allclose(normals, [1.0, 0.0, 0.0], atol=1e-6)
    rc, rn, _ro = _compare("wall z", cycles, new, old, pos[:, 2], np.ones(len(pos), bool))
    _assert_rows_agree(rc, rn)


@embree
def test_box_hovering_above_the_ground_not_darkened(empty_scene, bpy_module):
    """A gap of 1 % of the box's size: the rays pass under the box, as in Cycles."""
    bpy, scene = bpy_module, empty_scene
    _white_world(bpy, scene)
    ground = _add(bpy, scene, "ground", _grid(4.0, 16))
    box = _add(bpy, scene, "box", _box(1.0, 3), (0.0, 0.0, 0.51))
    cycles = _cycles(bpy, scene, box)
    new, old, pos, normals = _prt([box, ground], 0)
    rc, rn, _ro = _compare("hovering side z", cycles, new, old, pos[:, 2], np.abs(normals[:, 2]) < 0.5)
    _assert_rows_agree(rc, rn)
    bottom = normals[:, 2] < -0.5  # facing the ground 0.01 below: dark in both
    assert new[bottom].mean() < 0.01
    assert cycles[bottom].mean() < 0.01


@embree
@pytest.mark.parametrize("where", ["edge", "corner"])
def test_boxes_touching_at_an_edge_or_corner_not_darkened(empty_scene, bpy_module, where):
    """Box B touches box A along A's vertical edge (x, y) = (1/2, 1/2), or only at its corner
    (1/2, 1/2, 1/2). A's +x face, by rows across y (the touching edge is the last row), and
    the corners at the contact point, as in Cycles."""
    bpy, scene = bpy_module, empty_scene
    _white_world(bpy, scene)
    a = _add(bpy, scene, "A", _box(1.0, 3))
    b = _add(bpy, scene, "B", _box(1.0, 3), (1.0, 1.0, 0.0 if where == "edge" else 1.0))
    cycles = _cycles(bpy, scene, a)
    new, old, pos, normals = _prt([a, b], 0)
    face = normals[:, 0] > 0.5
    rc, rn, _ro = _compare(f"{where}: A's +x face, y", cycles, new, old, pos[:, 1], face)
    _assert_rows_agree(rc, rn)
    assert min(rn[k] - rc[k] for k in rc) >= -ROW_TOLERANCE
    # The corners at (1/2, 1/2, 1/2): Cycles itself gives 0.62 - 1.0 there (its +x and +y
    # corners differ by 0.07 at the edge contact, the point being on B's edge).
    at = np.all(np.abs(pos - 0.5) < 1e-6, axis=1)
    print("corners at the contact point: cycles", cycles[at], "prt", new[at], "before", old[at])
    assert np.all(new[at] >= cycles[at] - 0.1)


@embree
def test_the_bake_job_passes_the_surface(empty_scene, bpy_module):
    """The whole bake (api.bake, its own offsets, CORNER points of the flat box) has the fix:
    the box's bottom row agrees with Cycles as the core does above."""
    from prt_addon import api
    from prt_addon.blender.scene import storage

    bpy, scene = bpy_module, empty_scene
    _white_world(bpy, scene)
    ground = _add(bpy, scene, "ground", _grid(4.0, 16))
    box = _add(bpy, scene, "box", _box(1.0, 3), (0.0, 0.0, 0.5))
    cycles = _cycles(bpy, scene, box)
    api.bake([box, ground], order=1, samples=DIRECTIONS)
    assert box.data["prt_bake"]["domain"] == "CORNER"
    baked = storage.read_transfer(box.data)[:, 0].astype(np.float64) * np.sqrt(4.0 * np.pi)
    _v, _t, corner_verts, normals = _read(box)
    positions = _read(box)[0][corner_verts]
    side = np.abs(normals[:, 2]) < 0.5
    rc, rn = _rows(cycles, positions[:, 2], side), _rows(baked, positions[:, 2], side)
    _assert_rows_agree(rc, rn)
