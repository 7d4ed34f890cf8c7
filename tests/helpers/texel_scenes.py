"""The low-poly room of the texel bakes' tests: single-quad floor, walls and ceiling, a table of five boxes and a box, lightmap UVs; and Cycles' image bake of it."""

import math

import numpy as np

LIGHTMAP = "Lightmap"


def _quad(bpy, name, corners):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(c) for c in corners], [], [(0, 1, 2, 3)])
    mesh.uv_layers.new(name="UVMap")
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def _box(bpy, name, centre, size):
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=centre)
    obj = bpy.context.object
    obj.name = obj.data.name = name
    obj.scale = size
    bpy.ops.object.transform_apply(location=False, rotation=False, scale=True)
    return obj


def lightmap_unwrap(bpy, obj, margin=0.05):
    """A UV map LIGHTMAP made by Smart UV Project on obj (as an artist's lightmap UVs)."""
    layer = obj.data.uv_layers.new(name=LIGHTMAP)
    obj.data.uv_layers.active = layer
    bpy.ops.object.select_all(action="DESELECT")
    obj.select_set(True)
    bpy.context.view_layer.objects.active = obj
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.select_all(action="SELECT")
    bpy.ops.uv.smart_project(angle_limit=math.radians(66.0), island_margin=margin, area_weight=0.0)
    bpy.ops.object.mode_set(mode="OBJECT")


def low_poly_room(bpy, ceiling=True):
    """Floor 4 x 4 m, back and left walls 2.5 m high (and a ceiling), single quads (the open
    sides let the sky and the sun in); a table of five boxes and a box on the floor."""
    w, h = 2.0, 2.5
    objs = [
        _quad(bpy, "Floor", [(-w, -w, 0), (w, -w, 0), (w, w, 0), (-w, w, 0)]),
        _quad(bpy, "Back", [(-w, w, 0), (w, w, 0), (w, w, h), (-w, w, h)]),
        _quad(bpy, "Left", [(-w, -w, 0), (-w, w, 0), (-w, w, h), (-w, -w, h)]),
    ]
    if ceiling:
        objs.append(_quad(bpy, "Ceiling", [(-w, -w, h), (-w, w, h), (w, w, h), (w, -w, h)]))
    objs.append(_box(bpy, "Top", (0.3, 0.6, 0.75), (1.2, 0.8, 0.06)))
    for i, (x, y) in enumerate([(-0.25, 0.25), (0.85, 0.25), (-0.25, 0.95), (0.85, 0.95)]):
        objs.append(_box(bpy, f"Leg{i}", (x, y, 0.36), (0.06, 0.06, 0.72)))
    objs.append(_box(bpy, "Box", (-1.0, -0.6, 0.25), (0.5, 0.5, 0.5)))
    for obj in objs:
        lightmap_unwrap(bpy, obj)
    return objs


def cycles_texel_bake(bpy, scene, objects, resolution, samples, uv_name=LIGHTMAP, passes=("DIRECT",), seed=0):
    """{name: (res, res, 3)} E/pi per texel (white albedo) from Cycles' DIFFUSE image bake of
    each object through its UV map `uv_name`, each with a material of its own; removed again."""
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.seed = seed
    scene.cycles.use_denoising = False
    made = []
    bpy.ops.object.select_all(action="DESELECT")
    for obj in objects:
        image = bpy.data.images.new(f"cy {obj.name}", resolution, resolution, float_buffer=True, is_data=True)
        mat = bpy.data.materials.new(f"cy {obj.name}")
        mat.use_nodes = True
        node = mat.node_tree.nodes.new("ShaderNodeTexImage")
        node.image = image
        mat.node_tree.nodes.active = node
        old = list(obj.data.materials)
        obj.data.materials.clear()
        obj.data.materials.append(mat)
        uv_active = obj.data.uv_layers.active_index
        obj.data.uv_layers.active = obj.data.uv_layers[uv_name]
        made.append((obj, image, mat, old, uv_active))
        obj.select_set(True)
    bpy.context.view_layer.objects.active = objects[0]
    bpy.ops.object.bake(type="DIFFUSE", pass_filter=set(passes), target="IMAGE_TEXTURES", margin=0, use_clear=True)
    out = {}
    for obj, image, mat, old, uv_active in made:
        buf = np.empty(resolution * resolution * 4, np.float32)
        image.pixels.foreach_get(buf)
        out[obj.name] = buf.reshape(resolution, resolution, 4)[..., :3].astype(np.float64)
        obj.data.materials.clear()
        for m in old:
            obj.data.materials.append(m)
        obj.data.uv_layers.active_index = uv_active
        bpy.data.images.remove(image)
        bpy.data.materials.remove(mat)
    return out


def interior_texels(obj, resolution, uv_name=LIGHTMAP):
    """(res, res) bool: texels whose centre and a ring of 8 points half a texel out lie inside one
    of the object's UV triangles (texels both bakes cover fully, away from chart edges)."""
    mesh = obj.data
    mesh.calc_loop_triangles()
    uv = np.empty(len(mesh.loops) * 2, np.float32)
    mesh.uv_layers[uv_name].uv.foreach_get("vector", uv)
    uv = uv.reshape(-1, 2).astype(np.float64)
    loops = np.empty(len(mesh.loop_triangles) * 3, np.int32)
    mesh.loop_triangles.foreach_get("loops", loops)
    tris = uv[loops.reshape(-1, 3)] * resolution
    ys, xs = np.mgrid[0:resolution, 0:resolution] + 0.5
    inside = np.zeros((resolution, resolution), bool)
    ring = [(0, 0)] + [(0.5 * math.cos(a), 0.5 * math.sin(a)) for a in np.linspace(0, 2 * math.pi, 8, endpoint=False)]
    for a, b, c in tris:
        det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])
        if abs(det) < 1e-12:
            continue
        ok = np.ones_like(inside)
        for dx, dy in ring:
            px, py = xs + dx, ys + dy
            w1 = ((px - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (py - a[1])) / det
            w2 = ((b[0] - a[0]) * (py - a[1]) - (px - a[0]) * (b[1] - a[1])) / det
            ok &= (w1 >= 0) & (w2 >= 0) & (1 - w1 - w2 >= 0)
        inside |= ok
    return inside


LUMA = np.array([0.2126, 0.7152, 0.0722])


def relative_rmse(ours, theirs, masks):
    """Relative RMSE of luminance over the masked texels of every object."""
    a = np.concatenate([(ours[n] @ LUMA)[masks[n]] for n in masks])
    b = np.concatenate([(theirs[n] @ LUMA)[masks[n]] for n in masks])
    return float(np.sqrt(np.mean((a - b) ** 2)) / np.sqrt(np.mean(b**2)))
