"""The exported file's shading rule (docs/export.md, "Shading") against api.shade, and its basis table."""

import numpy as np
import pytest
from helpers.gltf import _assert_rows_match, _read_glb, _transfer, _world


def _node_matrix(node):
    if "matrix" in node:
        return np.array(node["matrix"], dtype=np.float64).reshape(4, 4).T[:3, :3]
    x, y, z, w = node.get("rotation", [0.0, 0.0, 0.0, 1.0])
    rot = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    return rot @ np.diag(node.get("scale", [1.0, 1.0, 1.0]))


@pytest.mark.parametrize("scale", [(1.0, 1.0, 1.0), (-1.0, 0.7, 1.3)])
def test_shading_from_the_file_as_docs_say(empty_scene, bpy_module, tmp_path, scale):
    """docs/export.md's shading steps on the file's data give api.shade's radiance (SH part)."""
    from prt_addon import api
    from prt_addon.core.sh import basis as sh, rotation

    bpy = bpy_module
    _world(bpy)
    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=2, location=(0.3, 0.2, 1.0), rotation=(0.4, -0.6, 1.1))
    obj = bpy.context.object
    obj.scale = scale
    obj.data.shade_smooth()
    bpy.ops.mesh.primitive_plane_add(size=6.0)
    api.project_world(order=3)
    # A directional light (not only the constant colour), through the test override.
    from prt_addon.blender.scene import lighting

    light = np.zeros((16, 3))
    light[0], light[1], light[2], light[3], light[6] = 1.0, (0.3, 0.1, 0.0), (0.8, 0.5, 0.2), -0.4, 0.2
    lighting.set_light_override(empty_scene, light)
    try:
        api.bake([obj], order=4, samples=64)
        expected = api.shade(obj)
        # The exported lighting comes from the world's SH: write the override's into it for the test.
        from prt_addon.blender.export import gltf

        real = gltf.world_extras

        def with_override(scene):
            data = real(scene)
            data["coefficients"] = gltf.to_gltf_frame(lighting.world_light(scene)).tolist()
            data["order"] = 4
            return data

        gltf.world_extras = with_override
        try:
            path = api.export_gltf(str(tmp_path / "s.glb"), [obj])
        finally:
            gltf.world_extras = real
    finally:
        lighting.clear_light_overrides()
    document, accessor = _read_glb(path)
    node = next(n for n in document["nodes"] if n["name"] == obj.name)
    mesh = document["meshes"][node["mesh"]]
    prim = mesh["primitives"][0]
    t = _transfer(document, accessor, mesh, prim)  # (decoded as docs/export.md says: snorm16 by default)
    world = np.array(document["scenes"][0]["extras"]["PRT_lighting"]["coefficients"])
    u, _s, vt = np.linalg.svd(_node_matrix(node))
    q = u @ vt
    mirrored = np.linalg.det(q) < 0
    r = -q if mirrored else q
    local = rotation.rotation_matrix(r.T, 4) @ world
    if mirrored:
        local *= ((-1.0) ** sh.band_of_index(4))[:, None]
    radiance = np.maximum(t @ local, 0.0)
    p = accessor(prim["attributes"]["POSITION"]).astype(np.float64)
    pos = np.stack([p[:, 0], -p[:, 2], p[:, 1]], axis=1)
    co = np.empty(len(obj.data.vertices) * 3, np.float32)
    obj.data.vertices.foreach_get("co", co)
    _assert_rows_match(co.reshape(-1, 3).astype(np.float64), expected, pos, radiance, tol=1e-4)
