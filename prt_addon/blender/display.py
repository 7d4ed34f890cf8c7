"""Live PRT display: per-vertex radiance sum_i L_i t_i drawn with `gpu` shaders.

Data flow per redraw (see docs/display.md):

* the world light L (world space, (n*n, 3)) comes from `world_light(scene)`: the one seam between
  the display and the world projection (issue 3), with an injectable override for tests/scripts;
* per object, L is rotated into the object's local frame by R^-1, R = rotation part of
  `matrix_world` (polar decomposition, reflections handled exactly by the SH parity (-1)^l), and
  written into that object's uniform buffer (std140, vec4-padded) only when it changed;
* the transfer t (stored per docs/storage.md in FLOAT_COLOR attributes prt_t00..) is uploaded
  into a cached batch once per mesh and bake, and again whenever the evaluated positions of an
  object deformed by modifiers or shape keys move (its batches are cached per object): as vertex
  attributes while they fit in the 16 vertex-attribute limit (orders <= 7), otherwise as an
  RGBA32F texture read with texelFetch at gl_VertexID (an indexed draw over the per-element
  vertex buffer, so gl_VertexID is the element);
* the vertex shader computes radiance = max(sum_i L_i t_i, 0) per colour channel, times the albedo
  (material base colour per material slot, or a colour attribute), and the fragment shader writes
  it linearly.

`shade()` computes the same radiance on the CPU from the same L_local and the same float32
transfer values, albedo excluded. Nothing here changes Blender data.
"""


import bpy
import gpu
import numpy as np
from bpy.app.handlers import persistent

from ..core import rotation as _rotation
from ..core import sh as _sh
from ..core import transfer as _transfer
from . import mesh_io as _mesh_io
from . import world as _world

ATTR_PREFIX = _mesh_io.PREFIX
RECORD_KEY = _mesh_io.RECORD
# GL guarantees (and llvmpipe offers) 16 vertex attributes; position and albedo use two.
MAX_VERTEX_ATTRIBUTES = 16
MAX_ATTRIBUTE_TRANSFER = MAX_VERTEX_ATTRIBUTES - 2  # 14 vec4 = 56 coefficients: orders <= 7
VIEWPORT_DEPTH_BIAS = 2e-5  # clip-space z bias so the overlay wins against the engine's own depth


# The storage layout belongs to the bake (docs/storage.md); the display only reads it.
attribute_name = _mesh_io.attribute_name
attribute_count = _mesh_io.attribute_count


# ---------------------------------------------------------------------------------------------
# Bake record (docs/storage.md)
# ---------------------------------------------------------------------------------------------


def bake_status(mesh, check_topology=True):
    """(mesh_io.BakeRecord or None, problem string or ""): whether the mesh holds a usable bake.

    A stale bake (topology changed) still returns its BakeRecord, with the problem set; the draw
    path skips the topology check (check_topology=False) to stay cheap per frame. The check uses
    the exact fingerprint, not the UI's cached one (an edit that keeps the element counts must
    still be caught); a record without a fingerprint is not stale here."""
    info, problem = _mesh_io.read_bake_record(mesh)
    if info is None:
        return None, problem
    stale = check_topology and _mesh_io.stale_topology(mesh, info.record, allow_missing=True)
    return info, ("topology changed since the bake: re-bake" if stale else "")


def element_count(mesh, domain):
    return len(mesh.vertices) if domain == "POINT" else len(mesh.loops)


def read_transfer(mesh, info):
    """(elements, 4 * count) float32: t_0 .. t_{4 count - 1} per element (padding channels 0)."""
    return _mesh_io.read_transfer(mesh, info, padded=True)


# ---------------------------------------------------------------------------------------------
# Lighting: the world light seam and the Mapping node
# ---------------------------------------------------------------------------------------------

_light_overrides = {}  # scene name -> (n*n, 3) float64 unrotated light


def set_light_override(scene, coeffs):
    """Use `coeffs` ((n*n, 3) or (n*n,)) as the scene's unrotated light instead of the world's.

    The world's Mapping node rotation still applies (`world_light`), exactly as it would to the
    projected world. Pass None to remove. Overrides are dropped when a file loads.
    """
    if coeffs is None:
        _light_overrides.pop(scene.name, None)
    else:
        c = np.asarray(coeffs, dtype=np.float64)
        if c.ndim == 1:
            c = np.repeat(c[:, None], 3, axis=1)
        _sh.order_of(c.shape[0])
        if c.ndim != 2 or c.shape[1] != 3:
            raise ValueError(f"light coefficients must have shape (n*n, 3), got {c.shape}")
        _light_overrides[scene.name] = c.copy()
    tag_redraw()


def clear_light_overrides():
    _light_overrides.clear()


def world_light(scene):
    """(n*n, 3) float64 world-space light SH of the scene, or None when there is none."""
    override = _light_overrides.get(scene.name)
    if override is not None:
        rot = mapping_light_rotation(scene)
        return override if rot is None else _rotation.rotate(override, rot)
    coeffs = _world.current_world_coeffs(scene)
    return None if coeffs is None else np.asarray(coeffs, dtype=np.float64)


def find_environment_node(world):
    if world is None or world.node_tree is None:
        return None
    for node in world.node_tree.nodes:
        if node.bl_idname == "ShaderNodeTexEnvironment":
            return node
    return None


def find_mapping_node(world):
    """The Mapping node feeding the Environment Texture's Vector input, or None."""
    env = find_environment_node(world)
    if env is None or not env.inputs["Vector"].is_linked:
        return None
    node = env.inputs["Vector"].links[0].from_node
    return node if node.bl_idname == "ShaderNodeMapping" else None


def ensure_mapping_node(world):
    """The Mapping node in front of the Environment Texture, created (Texture Coordinate
    Generated -> Mapping (Point) -> Vector) if needed. None when the world has no Environment
    Texture."""
    node = find_mapping_node(world)
    if node is not None:
        return node
    env = find_environment_node(world)
    if env is None:
        return None
    tree = world.node_tree
    coords = tree.nodes.new("ShaderNodeTexCoord")
    mapping = tree.nodes.new("ShaderNodeMapping")
    mapping.vector_type = "POINT"
    coords.location = (env.location.x - 500, env.location.y)
    mapping.location = (env.location.x - 300, env.location.y)
    tree.links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    tree.links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    # The world projection (issue 3) follows the Mapping node it saw at projection time; a node
    # created afterwards is identity now, so it is the same lighting: point the record at it.
    for scene in bpy.data.scenes:
        settings = getattr(scene, "prt_world", None)
        if (
            scene.world == world
            and settings is not None
            and getattr(settings, "source_kind", "") == "IMAGE"
            and not getattr(settings, "mapping_node", "x")
            and getattr(settings, "source_node", None) == env.name
        ):
            settings.mapping_node = mapping.name
            settings.mapping_type = mapping.vector_type
    return mapping


def mapping_rotation_euler(world):
    """The Mapping node's rotation (radians, XYZ Euler) or (0, 0, 0) without a node."""
    node = find_mapping_node(world)
    if node is None:
        return (0.0, 0.0, 0.0)
    return tuple(node.inputs["Rotation"].default_value)


def set_mapping_rotation_euler(world, euler):
    """The single place where the sidebar's lighting rotation is written into the world."""
    node = ensure_mapping_node(world)
    if node is None:
        return False
    node.inputs["Rotation"].default_value = tuple(float(a) for a in euler)
    tag_redraw()
    return True


def mapping_light_rotation(scene):
    """3x3 Q with world light = rotate(image light, Q), from the Mapping node; None if identity.

    The Environment Texture is looked up at mapping(d) for a world direction d. A POINT, VECTOR or
    NORMAL Mapping node gives mapping(d) = R d (R = Euler XYZ of its rotation), so
    world(d) = image(R d) and Q = R^-1 = R^T; a TEXTURE node applies the inverse, Q = R.
    Location and scale are ignored (a direction lookup; scale is assumed uniform).
    """
    node = find_mapping_node(scene.world)
    if node is None:
        return None
    euler = tuple(node.inputs["Rotation"].default_value)
    if not any(euler):
        return None
    r = _rotation.euler_xyz_matrix(euler)
    return r if node.vector_type == "TEXTURE" else r.T


# ---------------------------------------------------------------------------------------------
# Object frame
# ---------------------------------------------------------------------------------------------


def light_in_local_frame(light_world, matrix_world, order):
    """(order**2, 3) light in the object's local frame: rotated by the inverse of the rotation
    part of matrix_world, truncated or zero-padded to `order`. The same frame as the bake's
    core.transfer.to_local_frame, applied to the light instead of the transfer."""
    n2 = order * order
    light = np.zeros((n2, 3))
    m = min(n2, light_world.shape[0])
    light[:m] = light_world[:m]
    r, parity = _transfer.frame_rotation(np.asarray(matrix_world, dtype=np.float64)[:3, :3])
    if np.abs(r - np.eye(3)).max() > 1e-12:
        light = _rotation.rotate(light, r.T)
    if parity:
        light *= ((-1.0) ** _sh.band_of_index(order))[:, None]
    return light


def object_light(obj, scene, order=None):
    """The local-frame light used for obj ((order**2, 3) float64), or None without lighting."""
    light = world_light(scene)
    if light is None:
        return None
    if order is None:
        info, _ = bake_status(obj.data)
        order = info.order if info is not None else _sh.order_of(light.shape[0])
    return light_in_local_frame(light, obj.matrix_world, order)


def shade(obj, scene=None):
    """Per-element radiance (elements, 3) float64 that the display shader computes for a white
    surface: max(sum_i L_i t_i, 0) per channel, L in obj's local frame. One row per vertex for a
    POINT bake, per face corner for a CORNER bake."""
    scene = scene if scene is not None else bpy.context.scene
    bpy.context.evaluated_depsgraph_get()  # flush pending transform edits into matrix_world
    mesh = obj.data
    info, problem = bake_status(mesh)
    if info is None or problem:  # not baked, or stale (topology changed since the bake)
        raise ValueError(f"'{obj.name}': {problem}: bake it (PRT tab > Bake Transfer)")
    light = object_light(obj, scene, info.order)
    if light is None:
        raise ValueError("the scene has no PRT lighting (project the world first)")
    transfer = read_transfer(mesh, info).astype(np.float64)
    n2 = info.order * info.order
    return np.maximum(transfer[:, :n2] @ light, 0.0)


# ---------------------------------------------------------------------------------------------
# Shaders
# ---------------------------------------------------------------------------------------------

_shaders = {}

_VERTEX_COMMON = """
void main()
{
  vec3 r = vec3(0.0);
%s
  radiance = max(r, vec3(0.0)) * prt_albedo.rgb * tint.rgb * scale;
  gl_Position = mvp * vec4(prt_pos, 1.0);
  gl_Position.z -= depth_bias * gl_Position.w;
}
"""

_FRAGMENT = """
void main()
{
  FragColor = vec4(radiance, 1.0);
}
"""


def _dot_line(tex, k, count):
    return (
        f"  r += vec3(dot({tex}, light.c[{k}]), dot({tex}, light.c[{count + k}]), "
        f"dot({tex}, light.c[{2 * count + k}]));"
    )


def shader_mode(count):
    return "ATTR" if count <= MAX_ATTRIBUTE_TRANSFER else "TEXTURE"


def get_shader(count):
    """Compiled shader for `count` transfer vec4s (cached). Raises RuntimeError on failure."""
    mode = shader_mode(count)
    key = (mode, count)
    shader = _shaders.get(key)
    if shader is not None:
        return shader
    info = gpu.types.GPUShaderCreateInfo()
    info.typedef_source(f"struct PRTLight {{ vec4 c[{3 * count}]; }};\n")
    info.uniform_buf(0, "PRTLight", "light")
    info.push_constant("MAT4", "mvp")
    info.push_constant("VEC4", "tint")
    info.push_constant("FLOAT", "scale")
    info.push_constant("FLOAT", "depth_bias")
    info.vertex_in(0, "VEC3", "prt_pos")
    info.vertex_in(1, "VEC4", "prt_albedo")
    if mode == "ATTR":
        for k in range(count):
            info.vertex_in(2 + k, "VEC4", f"prt_t{k}")
        body = "\n".join(_dot_line(f"prt_t{k}", k, count) for k in range(count))
    else:
        info.push_constant("INT", "per_row")
        info.sampler(0, "FLOAT_2D", "transfer_tx")
        body = (
            "  int col = (gl_VertexID % per_row) * " + str(count) + ";\n"
            "  int row = gl_VertexID / per_row;\n"
            f"  for (int k = 0; k < {count}; k++) {{\n"
            "    vec4 t = texelFetch(transfer_tx, ivec2(col + k, row), 0);\n"
            f"    r += vec3(dot(t, light.c[k]), dot(t, light.c[{count} + k]), "
            f"dot(t, light.c[{2 * count} + k]));\n"
            "  }"
        )
    iface = gpu.types.GPUStageInterfaceInfo("prt_iface")
    iface.smooth("VEC3", "radiance")
    info.vertex_out(iface)
    info.fragment_out(0, "VEC4", "FragColor")
    info.vertex_source(_VERTEX_COMMON % body)
    info.fragment_source(_FRAGMENT)
    shader = gpu.shader.create_from_info(info)
    _shaders[key] = shader
    return shader


def light_ubo_bytes(light_local, count):
    """std140 bytes of PRTLight: c[ch * count + k] = (L_{4k..4k+3}, channel ch), zero-padded."""
    padded = np.zeros((4 * count, 3), dtype=np.float32)
    n = min(len(light_local), 4 * count)
    padded[:n] = light_local[:n]
    return np.ascontiguousarray(padded.T.reshape(3, count, 4)).tobytes()


# ---------------------------------------------------------------------------------------------
# Per-mesh GPU data
# ---------------------------------------------------------------------------------------------


class MeshEntry:
    """GPU data of one baked mesh: vertex buffer, one batch per material slot, transfer texture."""

    def __init__(self, key, batches, texture, per_row, evaluated):
        self.key = key
        self.batches = batches  # list of (material_index, GPUBatch)
        self.texture = texture
        self.per_row = per_row
        self.evaluated = evaluated  # the evaluated positions it was built for (deformed objects)


class ObjectState:
    __slots__ = ("ubo", "light_key")

    def __init__(self):
        self.ubo = None
        self.light_key = None


_mesh_cache = {}  # (mesh pointer, object pointer or 0 when undeformed) -> MeshEntry
_object_cache = {}  # object pointer -> ObjectState


def clear_caches():
    _mesh_cache.clear()
    _object_cache.clear()


def _cache_key(mesh, info, albedo_mode, albedo_attr):
    record = info.record
    rec = record.to_dict() if hasattr(record, "to_dict") else dict(record)
    return (
        repr(sorted((k, repr(v)) for k, v in rec.items())),
        len(mesh.vertices),
        len(mesh.loops),
        len(mesh.polygons),
        albedo_mode,
        albedo_attr,
    )


def _albedo_attribute(mesh, name):
    if name:
        attr = mesh.color_attributes.get(name)
        return attr
    active = mesh.color_attributes.active_color
    if active is not None and not active.name.startswith(ATTR_PREFIX):
        return active
    for attr in mesh.color_attributes:
        if not attr.name.startswith(ATTR_PREFIX):
            return attr
    return None


def element_albedo(mesh, domain, mode, attr_name):
    """(elements, 4) float32 per-element albedo factor: ones unless mode == 'ATTRIBUTE'."""
    n = element_count(mesh, domain)
    ones = np.ones((n, 4), dtype=np.float32)
    if mode != "ATTRIBUTE":
        return ones
    attr = _albedo_attribute(mesh, attr_name)
    if attr is None:
        return ones
    values = np.empty(element_count(mesh, attr.domain) * 4, dtype=np.float32)
    attr.data.foreach_get("color", values)
    values = values.reshape(-1, 4)
    if attr.domain == domain:
        return values
    corner_verts = _mesh_io.read_corner_verts(mesh)
    if domain == "CORNER":  # POINT colours onto corners
        return np.ascontiguousarray(values[corner_verts])
    # CORNER colours onto vertices: the mean of each vertex's corners.
    sums = np.zeros((n, 4))
    np.add.at(sums, corner_verts, values)
    counts = np.bincount(corner_verts, minlength=n)[:, None]
    return np.where(counts > 0, sums / np.maximum(counts, 1), 1.0).astype(np.float32)


def deformed_mesh(obj, depsgraph):
    """obj's evaluated mesh when its modifiers or shape keys may move its vertices and keep the
    element counts (what the viewport shows, and what the bake used), else None: the mesh's
    own positions are drawn (no deformation; no depsgraph; or other counts, which the bake
    refuses, e.g. a Subdivision added after baking). get_mesh_entry also compares the full
    topology before it draws these positions."""
    mesh = obj.data
    if depsgraph is None or not (mesh.shape_keys or any(m.show_viewport for m in obj.modifiers)):
        return None
    mesh_eval = obj.evaluated_get(depsgraph).data
    counts = (len(mesh.vertices), len(mesh.loops), len(mesh.polygons))
    if (len(mesh_eval.vertices), len(mesh_eval.loops), len(mesh_eval.polygons)) != counts:
        return None
    return mesh_eval


def build_mesh_entry(mesh, info, key, albedo_mode="MATERIAL", albedo_attr="", positions=None,
                     evaluated=None):
    """Upload a baked mesh: vertex buffer per element, index buffers per material, transfer.
    key: its _cache_key; positions: (vertices, 3) local positions to draw instead of the mesh's
    (deformed_mesh); evaluated: the evaluated positions the entry stands for (get_mesh_entry)."""
    n = element_count(mesh, info.domain)
    if positions is None:
        positions = _mesh_io.read_positions(mesh)
    mesh.calc_loop_triangles()
    ntri = len(mesh.loop_triangles)
    tris = np.empty(ntri * 3, dtype=np.int32)
    mesh.loop_triangles.foreach_get("loops" if info.domain == "CORNER" else "vertices", tris)
    tris = tris.reshape(-1, 3)
    mat_index = np.empty(ntri, dtype=np.int32)
    mesh.loop_triangles.foreach_get("material_index", mat_index)
    if info.domain == "CORNER":
        positions = np.ascontiguousarray(positions[_mesh_io.read_corner_verts(mesh)])
    transfer = read_transfer(mesh, info)
    albedo = element_albedo(mesh, info.domain, albedo_mode, albedo_attr)

    mode = shader_mode(info.count)
    fmt = gpu.types.GPUVertFormat()
    fmt.attr_add(id="prt_pos", comp_type="F32", len=3, fetch_mode="FLOAT")
    fmt.attr_add(id="prt_albedo", comp_type="F32", len=4, fetch_mode="FLOAT")
    if mode == "ATTR":
        for k in range(info.count):
            fmt.attr_add(id=f"prt_t{k}", comp_type="F32", len=4, fetch_mode="FLOAT")
    vbo = gpu.types.GPUVertBuf(fmt, n)
    vbo.attr_fill("prt_pos", positions)
    vbo.attr_fill("prt_albedo", albedo)
    texture, per_row = None, 0
    if mode == "ATTR":
        for k in range(info.count):
            vbo.attr_fill(f"prt_t{k}", np.ascontiguousarray(transfer[:, 4 * k : 4 * k + 4]))
    else:
        texture, per_row = _transfer_texture(transfer, info.count)

    batches = []
    if ntri:
        order_idx = np.argsort(mat_index, kind="stable")
        sorted_mat = mat_index[order_idx]
        starts = np.flatnonzero(np.r_[True, sorted_mat[1:] != sorted_mat[:-1]])
        ends = np.r_[starts[1:], ntri]
        for s, e in zip(starts, ends):
            seq = np.ascontiguousarray(tris[order_idx[s:e]])
            ibo = gpu.types.GPUIndexBuf(type="TRIS", seq=seq)
            batches.append((int(sorted_mat[s]), gpu.types.GPUBatch(type="TRIS", buf=vbo, elem=ibo)))
    return MeshEntry(key, batches, texture, per_row, evaluated)


def _transfer_texture(transfer, count):
    """RGBA32F texture, element e's k-th vec4 at texel ((e % per_row) * count + k, e // per_row)."""
    n = transfer.shape[0]
    max_size = min(16384, gpu.capabilities.max_texture_size_get())
    per_row = max(1, min(max_size // count, n))
    rows = max(1, -(-n // per_row))
    if rows > max_size:
        raise RuntimeError(
            f"{n} elements at {count} texels each exceed one {max_size}x{max_size} texture"
        )
    data = np.zeros((rows * per_row * count, 4), dtype=np.float32)
    data[: n * count] = transfer.reshape(n * count, 4)
    buf = gpu.types.Buffer("FLOAT", data.size, data.reshape(-1))
    tex = gpu.types.GPUTexture((per_row * count, rows), format="RGBA32F", data=buf)
    return tex, per_row


def get_mesh_entry(mesh, info, albedo_mode, albedo_attr, obj=None, depsgraph=None):
    """The cached batches of `mesh`, or of `obj` when its modifiers or shape keys deform it:
    those are drawn at their evaluated positions, read again at every draw; when they moved (an
    animated armature, a shape-key value being dragged) the whole entry is built again."""
    mesh_eval = None if obj is None else deformed_mesh(obj, depsgraph)
    positions = None if mesh_eval is None else _mesh_io.read_positions(mesh_eval)
    ptr = (mesh.as_pointer(), 0 if positions is None else obj.as_pointer())
    key = _cache_key(mesh, info, albedo_mode, albedo_attr)
    entry = _mesh_cache.get(ptr)
    if entry is None or entry.key != key or (
        positions is not None and not np.array_equal(entry.evaluated, positions)
    ):
        drawn = positions
        # Same counts but other connectivity (e.g. a Sort Elements node): the baked elements
        # are not these, so draw the undeformed mesh.
        if positions is not None and _mesh_io.topology_fingerprint(mesh_eval) != _mesh_io.topology_fingerprint(mesh):
            drawn = None
        entry = build_mesh_entry(mesh, info, key, albedo_mode, albedo_attr, drawn, positions)
        _mesh_cache[ptr] = entry
    return entry


def material_colour(material):
    """Linear RGBA base colour of a material: Principled/Diffuse BSDF input, else diffuse_color."""
    if material is None:
        return (0.8, 0.8, 0.8, 1.0)
    tree = getattr(material, "node_tree", None)
    if tree is not None:
        for node in tree.nodes:
            if node.bl_idname == "ShaderNodeOutputMaterial" and node.is_active_output:
                surface = node.inputs["Surface"]
                if surface.is_linked:
                    bsdf = surface.links[0].from_node
                    sock = bsdf.inputs.get("Base Color") or bsdf.inputs.get("Color")
                    if sock is not None and not sock.is_linked and hasattr(sock, "default_value"):
                        return tuple(sock.default_value)
                break
    return tuple(material.diffuse_color)


def _slot_tints(obj, albedo_mode):
    if albedo_mode != "MATERIAL":
        return None
    return [material_colour(slot.material) for slot in obj.material_slots]


# ---------------------------------------------------------------------------------------------
# Drawing
# ---------------------------------------------------------------------------------------------


def display_settings(scene):
    settings = getattr(scene, "prt_display", None)
    if settings is None:
        return "MATERIAL", ""
    return settings.albedo_source, settings.albedo_attribute


def baked_objects(scene, view_layer=None, viewport=None):
    """Visible mesh objects of the view layer whose mesh holds a usable bake (stale ones too)."""
    view_layer = view_layer or scene.view_layers[0]
    out = []
    for obj in view_layer.objects:
        if obj.type != "MESH" or RECORD_KEY not in obj.data:
            continue
        try:
            visible = obj.visible_get(view_layer=view_layer, viewport=viewport) if viewport else obj.visible_get(view_layer=view_layer)
        except TypeError:
            visible = obj.visible_get()
        if visible and obj.mode != "EDIT":
            out.append(obj)
    return out


def draw_objects(scene, view_projection, objects, *, scale=1.0, depth_bias=0.0, depsgraph=None):
    """Draw `objects` with the PRT shader into the bound framebuffer. Returns the number drawn.

    view_projection: 4x4 (mathutils.Matrix or array) world -> clip. The caller sets depth state.
    depsgraph: the evaluated depsgraph whose deformed meshes are drawn (deformed_mesh);
    None draws every mesh undeformed.
    """
    import mathutils

    light = world_light(scene)
    if light is None:
        return 0
    light_tag = (light.shape, light.tobytes())
    vp = mathutils.Matrix(np.asarray(view_projection, dtype=np.float64).tolist())
    albedo_mode, albedo_attr = display_settings(scene)
    drawn = 0
    for obj in objects:
        info, _problem = bake_status(obj.data, check_topology=False)
        if info is None:
            continue
        entry = get_mesh_entry(obj.data, info, albedo_mode, albedo_attr, obj, depsgraph)
        if not entry.batches:
            continue
        shader = get_shader(info.count)
        state = _object_cache.setdefault(obj.as_pointer(), ObjectState())
        mw = np.array(obj.matrix_world, dtype=np.float64)
        light_key = (light_tag, mw[:3, :3].tobytes(), info.order, info.count)
        if state.ubo is None or state.light_key != light_key:
            data = light_ubo_bytes(light_in_local_frame(light, mw, info.order), info.count)
            if state.ubo is None or state.light_key is None or state.light_key[3] != info.count:
                state.ubo = gpu.types.GPUUniformBuf(data)
            else:
                state.ubo.update(data)
            state.light_key = light_key
        shader.bind()
        shader.uniform_float("mvp", vp @ obj.matrix_world)
        shader.uniform_float("scale", float(scale))
        shader.uniform_float("depth_bias", float(depth_bias))
        shader.uniform_block("light", state.ubo)
        if entry.texture is not None:
            shader.uniform_int("per_row", entry.per_row)
            shader.uniform_sampler("transfer_tx", entry.texture)
        tints = _slot_tints(obj, albedo_mode)
        for mat_index, batch in entry.batches:
            tint = (1.0, 1.0, 1.0, 1.0)
            if tints:
                tint = tints[min(mat_index, len(tints) - 1)]
            elif albedo_mode == "MATERIAL":
                tint = material_colour(None)
            shader.uniform_float("tint", tint)
            batch.draw(shader)
        drawn += 1
    return drawn


def exposure_scale(scene):
    """2**exposure: the scene exposure the viewport applies before its view transform."""
    return 2.0 ** float(scene.view_settings.exposure)


def _draw_callback():
    context = bpy.context
    scene = context.scene
    settings = getattr(scene, "prt", None)
    if settings is None or not settings.show_display:
        return
    region_data = context.region_data
    if region_data is None:
        return
    objects = baked_objects(scene, context.view_layer, context.space_data)
    if not objects:
        return
    depth_mask = gpu.state.depth_mask_get()
    gpu.state.depth_test_set("LESS_EQUAL")
    gpu.state.depth_mask_set(True)
    try:
        draw_objects(
            scene,
            region_data.perspective_matrix,
            objects,
            scale=exposure_scale(scene),
            depth_bias=VIEWPORT_DEPTH_BIAS,
            depsgraph=context.evaluated_depsgraph_get(),
        )
    finally:
        gpu.state.depth_mask_set(depth_mask)
        gpu.state.depth_test_set("NONE")
    _prune(objects)


def _prune(objects, slack=8):
    """Drop cached GPU data of meshes and objects no longer drawn (deleted, undone, hidden)."""
    if len(_mesh_cache) + len(_object_cache) <= 2 * len(objects) + slack:
        return
    meshes = {obj.data.as_pointer() for obj in objects}
    objs = {obj.as_pointer() for obj in objects}
    for key in [k for k in _mesh_cache if k[0] not in meshes or (k[1] and k[1] not in objs)]:
        del _mesh_cache[key]
    for key in [k for k in _object_cache if k not in objs]:
        del _object_cache[key]


# ---------------------------------------------------------------------------------------------
# Handlers
# ---------------------------------------------------------------------------------------------

_draw_handle = None


def draw_handle():
    """The current draw-handler handle (None when not installed); tests use it."""
    return _draw_handle


def add_draw_handler():
    global _draw_handle
    if _draw_handle is None:
        _draw_handle = bpy.types.SpaceView3D.draw_handler_add(_draw_callback, (), "WINDOW", "POST_VIEW")
    return _draw_handle


def remove_draw_handler():
    global _draw_handle
    if _draw_handle is not None:
        try:
            bpy.types.SpaceView3D.draw_handler_remove(_draw_handle, "WINDOW")
        except ValueError:
            pass
        _draw_handle = None
    clear_caches()


@persistent
def _on_load_pre(*_args):
    remove_draw_handler()
    clear_light_overrides()


@persistent
def _on_load_post(*_args):
    add_draw_handler()


@persistent
def _on_depsgraph_update(_scene, depsgraph):
    for update in depsgraph.updates:
        if not update.is_updated_geometry:
            continue
        ident = update.id
        mesh = None
        if isinstance(ident, bpy.types.Mesh):
            mesh = ident.original
        elif isinstance(ident, bpy.types.Object) and ident.type == "MESH":
            mesh = ident.original.data
        if mesh is not None:
            ptr = mesh.as_pointer()
            for key in [k for k in _mesh_cache if k[0] == ptr]:
                del _mesh_cache[key]
            _mesh_io.forget_cached_fingerprints(mesh)


_APP_HANDLERS = (
    ("load_pre", _on_load_pre),
    ("load_post", _on_load_post),
    ("depsgraph_update_post", _on_depsgraph_update),
)


def register_handlers():
    for name, func in _APP_HANDLERS:
        handlers = getattr(bpy.app.handlers, name)
        if func not in handlers:
            handlers.append(func)
    add_draw_handler()


def unregister_handlers():
    remove_draw_handler()
    for name, func in _APP_HANDLERS:
        handlers = getattr(bpy.app.handlers, name)
        while func in handlers:
            handlers.remove(func)
    clear_light_overrides()
    _shaders.clear()


def tag_redraw():
    wm = getattr(bpy.context, "window_manager", None)
    if wm is None:
        return
    for window in wm.windows:
        for area in window.screen.areas:
            if area.type == "VIEW_3D":
                area.tag_redraw()
