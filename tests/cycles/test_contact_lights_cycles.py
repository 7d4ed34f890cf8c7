"""The split lights where surfaces touch, against Cycles under courtyard.exr: a box foot, a wall foot, a single-quad room's corners (api.shade).

PRT is baked at order 8 with 1024 directions and shaded with the lights split (their visibility
traced from the bake's contact-moved origins, core.lights.visibility) and without (the whole
world through the transfer); Cycles bakes DIFFUSE / DIRECT per corner at 512 samples. Before
the lights' rays got the contact move, the box's bottom row came out at 0.45 against Cycles'
0.69 and the room's corners up to 9x too bright (docs/lights.md, "Contacts").
"""

import numpy as np
from helpers import contact_lights as cl

ROW_TOLERANCE = 0.03  # + 3 % of the value: Cycles' noise and the split's own error on rows away from contacts


def _bake_and_shade(bpy, scene, objects, targets):
    from prt_addon import api

    cl.white(bpy, objects)
    bpy.context.view_layer.update()
    api.bake(objects, order=cl.ORDER, samples=cl.DIRECTIONS)
    api.project_world(scene, cl.ORDER, split_lights=True)
    assert api.world_lights(scene)
    split = {o.name: cl.shade_corners(api, o, scene) for o in targets}
    api.project_world(scene, cl.ORDER, split_lights=False)
    unsplit = {o.name: cl.shade_corners(api, o, scene) for o in targets}
    return split, unsplit, cl.cycles_corners(bpy, scene, targets)


def _assert_rows(label, split, unsplit, cycles, height, select):
    rows = [cl.row_means(v, height, select) for v in (split, unsplit, cycles)]
    for k in rows[2]:
        print(f"{label} z {k:.2f}: split {rows[0][k]:.3f}  unsplit {rows[1][k]:.3f}  cycles {rows[2][k]:.3f}")
    bottom = min(rows[2])
    for values in rows[:2]:
        assert abs(values[bottom] - rows[2][bottom]) <= ROW_TOLERANCE + 0.03 * rows[2][bottom], (label, rows)
    return rows


def test_box_foot_split_lights_like_cycles(bpy_module, empty_scene):
    bpy, scene = bpy_module, empty_scene
    cl.hdri_world(bpy, scene)
    ground = cl.mesh_object(bpy, scene, "ground", cl.grid(4.0, 16))
    box = cl.mesh_object(bpy, scene, "box", cl.box(1.0, 3), (0.0, 0.0, 0.5))
    split, unsplit, cycles = _bake_and_shade(bpy, scene, [box, ground], [box])
    position, normal = cl.corner_frame(box)
    for axis in (0, 1):
        for sign in (-1.0, 1.0):
            side = normal[:, axis] * sign > 0.99
            rows = _assert_rows(
                f"side {axis} {sign:+.0f}", split["box"], unsplit["box"], cycles["box"], position[:, 2], side
            )
            # Cycles orders the bottom row below the one above it; so must the split.
            heights = sorted(rows[2])
            assert rows[2][heights[0]] < rows[2][heights[1]]
            assert rows[0][heights[0]] < rows[0][heights[1]]


def test_wall_foot_split_lights_like_cycles(bpy_module, empty_scene):
    bpy, scene = bpy_module, empty_scene
    cl.hdri_world(bpy, scene)
    floor = cl.mesh_object(bpy, scene, "floor", cl.grid(4.0, 16))

    def wall(bmesh, bm):  # a 2 x 2 m grid standing on the floor, facing +x
        bmesh.ops.create_grid(bm, x_segments=8, y_segments=8, size=0.5)
        for v in bm.verts:
            x, y, _z = v.co
            v.co = (0.0, 2.0 * x, 2.0 * (y + 0.5))

    walls = [cl.mesh_object(bpy, scene, f"wall{k}", wall, (0.5 - k, 0.0, 0.0)) for k in range(2)]
    walls[1].rotation_euler = (0.0, 0.0, np.pi)  # facing -x
    split, unsplit, cycles = _bake_and_shade(bpy, scene, walls + [floor], walls)
    for obj in walls:
        position, _normal = cl.corner_frame(obj)
        select = position[:, 2] < 0.8  # the rows near the foot
        _assert_rows(obj.name, split[obj.name], unsplit[obj.name], cycles[obj.name], position[:, 2], select)


def test_room_corners_split_lights_like_cycles(bpy_module, empty_scene):
    """Five single quads, a floor, three walls and half a ceiling (open at the front and half the
    top): every vertex is a corner where two or three of them meet."""
    bpy, scene = bpy_module, empty_scene
    cl.hdri_world(bpy, scene)
    objects = [cl.mesh_object(bpy, scene, name, cl.quad(corners)) for name, corners in cl.room_quads().items()]
    split, unsplit, cycles = _bake_and_shade(bpy, scene, objects, objects)
    for obj in objects:
        a, b, c = (v[obj.name] @ cl.LUMA for v in (split, unsplit, cycles))
        print(obj.name, " ".join(f"{x:.3f}/{y:.3f}/{z:.3f}" for x, y, z in zip(a, b, c)))
        # The split lights add no error of their own at the corners: the split is as close to
        # Cycles as the unsplit shading is (which shares the bake's transfer), within the noise.
        tolerance = ROW_TOLERANCE + 0.1 * c
        assert np.all(np.abs(a - c) <= np.abs(b - c) + tolerance), obj.name
