"""The accuracy report's scenes and references: Suzanne or a torus on a ground grid, the HDRI
worlds, Cycles' vertex bake, the PRT bake read back, the float64 transfer and the traced cap.

Used by benchmarks/accuracy_report.py and benchmarks/accuracy_split.py (docstring of the former).
"""

import math
import os
import time

import numpy as np

CAP_AXIS = np.array(
    [
        math.cos(math.radians(35)) * math.cos(math.radians(40)),
        math.cos(math.radians(35)) * math.sin(math.radians(40)),
        math.sin(math.radians(35)),
    ]
)
BACKGROUND = 1.0


# --- scenes ------------------------------------------------------------------------------------


def _material(bpy):
    mat = bpy.data.materials.get("white") or bpy.data.materials.new("white")
    return mat


def _link(bpy, scene, name, mesh):
    mesh.shade_smooth()
    mesh.materials.append(_material(bpy))
    obj = bpy.data.objects.new(name, mesh)
    scene.collection.objects.link(obj)
    return obj


def _sit_on_ground(mesh):
    from mathutils import Matrix

    co = np.empty(len(mesh.vertices) * 3, np.float32)
    mesh.vertices.foreach_get("co", co)
    mesh.transform(Matrix.Translation((0.0, 0.0, -float(co.reshape(-1, 3)[:, 2].min()))))


def build_scene(bpy, name):
    """Empty file with the shape and the ground; returns [shape, ground]."""
    import bmesh
    from mathutils import Matrix

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    if name == "suzanne":
        bm = bmesh.new()
        bmesh.ops.create_monkey(bm)
        base = bpy.data.meshes.new("suzanne0")
        bm.to_mesh(base)
        bm.free()
        tmp = bpy.data.objects.new("tmp", base)
        scene.collection.objects.link(tmp)
        tmp.modifiers.new("subdiv", "SUBSURF").levels = 1
        dg = bpy.context.evaluated_depsgraph_get()
        mesh = bpy.data.meshes.new_from_object(tmp.evaluated_get(dg))
        bpy.data.objects.remove(tmp)
    elif name == "torus":
        big, small, nu, nv = 1.0, 0.4, 48, 24
        u = np.arange(nu) * 2 * np.pi / nu
        v = np.arange(nv) * 2 * np.pi / nv
        uu, vv = np.meshgrid(u, v, indexing="ij")
        verts = np.stack(
            [(big + small * np.cos(vv)) * np.cos(uu), (big + small * np.cos(vv)) * np.sin(uu), small * np.sin(vv)], -1
        ).reshape(-1, 3)
        faces = []
        for i in range(nu):
            for j in range(nv):
                a, b = i * nv + j, ((i + 1) % nu) * nv + j
                c, d = ((i + 1) % nu) * nv + (j + 1) % nv, i * nv + (j + 1) % nv
                faces.append((a, b, c, d))
        mesh = bpy.data.meshes.new("torus")
        mesh.from_pydata(verts.tolist(), [], faces)
        mesh.transform(Matrix.Rotation(math.radians(50.0), 4, "X"))
    else:
        raise ValueError(name)
    _sit_on_ground(mesh)
    shape = _link(bpy, scene, name, mesh)
    bm = bmesh.new()
    bmesh.ops.create_grid(bm, x_segments=32, y_segments=32, size=4.0)
    gmesh = bpy.data.meshes.new("ground")
    bm.to_mesh(gmesh)
    bm.free()
    ground = _link(bpy, scene, "ground", gmesh)
    for obj in (shape, ground):
        obj.select_set(True)
        attr = obj.data.color_attributes.new("cycles_bake", "FLOAT_COLOR", "POINT")
        obj.data.color_attributes.active_color = obj.data.color_attributes[attr.name]
    bpy.context.view_layer.objects.active = shape
    return [shape, ground]


def set_world(bpy, scene, name):
    world = bpy.data.worlds.get(name)
    if world is None:
        folder = bpy.utils.system_resource("DATAFILES", path="studiolights/world")
        world = bpy.data.worlds.new(name)
        tree = world.node_tree
        env = tree.nodes.new("ShaderNodeTexEnvironment")
        env.image = bpy.data.images.load(os.path.join(folder, f"{name}.exr"))
        tree.links.new(env.outputs["Color"], tree.nodes["Background"].inputs["Color"])
    scene.world = world
    return world


def read_cycles(objs):
    out = []
    for obj in objs:
        mesh = obj.data
        buf = np.empty(len(mesh.vertices) * 4, np.float32)
        mesh.color_attributes["cycles_bake"].data.foreach_get("color", buf)
        out.append(buf.reshape(-1, 4)[:, :3].astype(np.float64))
    return np.concatenate(out)


def cycles_bake(bpy, scene, objs, samples, seed):
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.seed = seed
    for obj in objs:
        obj.data.color_attributes.active_color = obj.data.color_attributes["cycles_bake"]
    t0 = time.perf_counter()
    bpy.ops.object.bake(type="DIFFUSE", pass_filter={"DIRECT"}, target="VERTEX_COLORS", use_clear=True)
    return time.perf_counter() - t0, read_cycles(objs)


def read_prt(objs):
    from prt_addon.blender.display import gpu_cache
    from prt_addon.blender.scene import storage

    out = []
    for obj in objs:
        info, problem = storage.usable_bake(obj.data)
        assert info is not None and info.domain == "POINT", problem
        out.append(gpu_cache.read_transfer(obj.data, info)[:, : info.order**2])
    return np.concatenate(out)


def prt_bake(objs, order, samples, kind):
    from prt_addon import api

    t0 = time.perf_counter()
    report = api.bake(objs, order=order, samples=samples, direction_set=kind, seed=0)
    seconds = time.perf_counter() - t0
    return seconds, report, read_prt(objs)


def radiance(transfer, light):
    n2 = light.shape[0]
    return np.maximum(transfer[:, :n2].astype(np.float64) @ light, 0.0)


# --- float64 transfer (bypassing the float32 storage) ------------------------------------------


def scene_points(bpy, objs):
    """World positions, normals, offsets, an Embree occluder and the triangles of the whole scene
    (each object's points are its vertices: the report's meshes are smooth, one normal each)."""
    from prt_addon.blender.scene import mesh_read, parts as scene_parts
    from prt_addon.core.trace import raytrace
    from prt_addon.core.transfer import mesh as core_mesh

    pos, nrm, off, verts, tris = [], [], [], [], []
    base = 0
    for obj in objs:
        m4 = core_mesh.matrix_to_numpy(obj.matrix_world)
        pts = mesh_read.bake_points(obj.data, m4)
        pos.append(pts.positions)
        nrm.append(pts.normals)
        v = core_mesh.transform_points(m4, mesh_read.read_positions(obj.data))
        box = raytrace.bounding_box(v)
        diag = float(np.linalg.norm(box[1] - box[0]))
        off.append(
            np.full(
                len(pts.positions),
                max(scene_parts.OFFSET_REL * diag, scene_parts.OFFSET_ULP * float(np.abs(v).max())),
            )
        )
        verts.append(v)
        tris.append(mesh_read.read_triangles(obj.data) + base)
        base += len(v)
    verts, tris = np.concatenate(verts), np.concatenate(tris)
    occ = raytrace.EmbreeOccluder(verts, tris)
    return np.concatenate(pos), np.concatenate(nrm), np.concatenate(off), occ, (verts, tris)


def transfer_float64(points, order, samples):
    """The bake's transfer in float64: the same rays (offset along the normal and into the point's
    own surface, as api.bake does; the objects share no vertex, so one surface serves all)."""
    from prt_addon.core.sh import directions
    from prt_addon.core.transfer import quadrature as transfer

    pos, nrm, off, occ, surface = points
    comp = transfer.TransferComputation(
        pos, nrm, directions.make_directions("FIBONACCI", samples, 0), order, occ, offset=off, surface=surface
    )
    comp.coeffs = np.zeros(comp.coeffs.shape, dtype=np.float64)  # keep the float64 sums
    return comp.run().coeffs


def cap_truth(points, t0_conv, half_angle, value, k=400):
    """E/pi of background BACKGROUND + a cap of `value` around CAP_AXIS, by tracing the cap."""
    pos, nrm, off, occ, _surface = points
    # k directions evenly spread over the cap (Fibonacci spiral in cos(theta), phi).
    i = np.arange(k) + 0.5
    z = 1.0 - (1.0 - math.cos(half_angle)) * i / k
    phi = i * math.pi * (3.0 - math.sqrt(5.0))
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    local = np.stack([r * np.cos(phi), r * np.sin(phi), z], -1)
    a = CAP_AXIS / np.linalg.norm(CAP_AXIS)
    t = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
    t /= np.linalg.norm(t)
    b = np.cross(a, t)
    dirs = local @ np.stack([t, b, a])
    solid = 2 * math.pi * (1.0 - math.cos(half_angle))
    out = np.empty(len(pos))
    origins = (pos + off[:, None] * nrm).astype(np.float32)
    d32 = dirs.astype(np.float32)
    for s in range(0, len(pos), 256):
        o = np.repeat(origins[s : s + 256], k, axis=0)
        d = np.tile(d32, (len(o) // k, 1))
        free = ~occ.occluded(o, d).reshape(-1, k)
        cos = np.maximum(nrm[s : s + 256] @ dirs.T, 0.0)
        out[s : s + 256] = value * solid / k * np.sum(cos * free, axis=1) / math.pi
    return out + BACKGROUND * math.sqrt(4 * math.pi) * t0_conv
