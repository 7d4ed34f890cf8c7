"""Shadow maps of the split lights: one orthographic depth map per shadow view over all visible meshes.

The views come from core.lights.shadow_views (one per compact light, one per sample group of a wide
light). Every visible mesh casts (baked or not), from its evaluated world-space triangles. Each
map is a tile of an R32F atlas (shadow_atlas.py) holding the depth from the view's near plane in
world units (cleared to FAR), drawn with a depth buffer from the view's direction and fitted to the
bounding box of the casters: the compact lights' maps at RESOLUTION, the wide lights' at
WIDE_RESOLUTION. The caster batch is rebuilt only when the geometry signature changes (objects,
transforms, element counts, and a generation counter the depsgraph handler bumps on geometry
updates); a map is drawn again only when its view's direction or the geometry changed.
"""

import bpy
import gpu
import numpy as np

from ...core.lights.shadow_views import shadow_views, wide_view_budget
from .. import caches
from ..scene import mesh_read
from . import shadow_atlas

RESOLUTION = 2048  # the compact lights' maps
WIDE_RESOLUTION = 1024  # a wide light's maps (core.lights.shadow_views): softer, and many of them
FAR = 1.0e30
PAD = 0.01  # fraction of the box diagonal added around the casters


_DEPTH_VERTEX = """
void main()
{
  depth = dot(depth_row, vec4(pos, 1.0));
  gl_Position = clip * vec4(pos, 1.0);
}
"""

_DEPTH_FRAGMENT = """
void main()
{
  FragColor = vec4(depth, 0.0, 0.0, 1.0);
}
"""

_depth_shader = []
_generation = [0]
_states = {}  # scene pointer -> ShadowState


class ViewMap:
    """Where one view's map is: world -> (texel x, texel y, depth) rows within its tile, texel
    size, resolution, its tile's first texel in the atlas and whether it is a wide light's."""

    __slots__ = ("rows", "texel", "resolution", "origin", "wide")

    def __init__(self, rows, texel, resolution, origin, wide):
        self.rows, self.texel, self.resolution, self.origin, self.wide = rows, texel, resolution, origin, wide


class ShadowSet:
    """The maps of a frame: the lights' views (core.lights.shadow_views.ShadowView), one ViewMap per view
    (same order) and the two atlas textures (the compact lights' tiles at RESOLUTION, the wide
    lights' views' at WIDE_RESOLUTION; a 1-texel texture stands in for an empty one, as a sampler
    is bound even when it is not read)."""

    __slots__ = ("views", "maps", "sharp", "wide")

    def __init__(self, views, maps, sharp, wide):
        self.views, self.maps, self.sharp, self.wide = views, maps, sharp, wide


class ShadowState:
    __slots__ = ("geometry_key", "batch", "box", "triangles", "atlases")

    def __init__(self):
        self.geometry_key = None
        self.batch = None
        self.box = None
        self.triangles = 0
        self.atlases = {}  # wide flag -> shadow_atlas.Atlas


@caches.on_geometry
def geometry_changed(_mesh=None):
    """Any mesh's geometry changed: the casters are read again."""
    _generation[0] += 1


@caches.on_clear
def clear_shadows():
    _states.clear()
    _depth_shader.clear()


def _shader():
    if not _depth_shader:
        info = gpu.types.GPUShaderCreateInfo()
        info.push_constant("MAT4", "clip")
        info.push_constant("VEC4", "depth_row")
        info.vertex_in(0, "VEC3", "pos")
        iface = gpu.types.GPUStageInterfaceInfo("prt_shadow_iface")
        iface.smooth("FLOAT", "depth")
        info.vertex_out(iface)
        info.fragment_out(0, "VEC4", "FragColor")
        info.vertex_source(_DEPTH_VERTEX)
        info.fragment_source(_DEPTH_FRAGMENT)
        _depth_shader.append(gpu.shader.create_from_info(info))
    return _depth_shader[0]


def caster_objects(scene, view_layer=None):
    """Visible mesh objects of the view layer: all of them cast, baked or not."""
    view_layer = view_layer or scene.view_layers[0]
    out = []
    for obj in view_layer.objects:
        if obj.type != "MESH":
            continue
        try:
            visible = obj.visible_get(view_layer=view_layer)
        except TypeError:
            visible = obj.visible_get()
        if visible:
            out.append(obj)
    return out


def _evaluated(obj, depsgraph):
    return obj.data if depsgraph is None else obj.evaluated_get(depsgraph).data


def geometry_signature(objects, depsgraph):
    """Cheap per-frame key of the casters: pointers, transforms, element counts, generation."""
    parts = [_generation[0]]
    for obj in objects:
        mesh = _evaluated(obj, depsgraph)
        parts.append(
            (
                obj.as_pointer(),
                np.array(obj.matrix_world, dtype=np.float32).tobytes(),
                len(mesh.vertices),
                len(mesh.polygons),
            )
        )
    return tuple(parts)


def caster_triangles(objects, depsgraph):
    """(V, 3) float32 world positions and (T, 3) int32 triangles of the evaluated casters."""
    positions, triangles, offset = [], [], 0
    for obj in objects:
        mesh = _evaluated(obj, depsgraph)
        local = mesh_read.read_positions(mesh)
        tris = mesh_read.read_triangles(mesh, local)
        if not len(tris):
            continue
        mw = np.array(obj.matrix_world, dtype=np.float64)
        positions.append((local @ mw[:3, :3].T + mw[:3, 3]).astype(np.float32))
        triangles.append(tris.astype(np.int32) + offset)
        offset += len(local)
    if not positions:
        return np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32)
    return np.concatenate(positions), np.concatenate(triangles)


def _frame(direction):
    """Unit t, b completing the unit light direction s to an orthonormal basis."""
    s = np.asarray(direction, dtype=np.float64)
    s = s / np.linalg.norm(s)
    helper = np.array([1.0, 0.0, 0.0]) if abs(s[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t = np.cross(helper, s)
    t /= np.linalg.norm(t)
    return t, np.cross(s, t), s


def light_rows(direction, box, resolution=RESOLUTION):
    """((3, 4) world -> (texel x, texel y, depth) rows, (4, 4) clip matrix, texel size).

    Orthographic along -s: depth = w_top - p.s in world units (0 at the casters' side nearest the
    light), the square footprint fitted to the box's eight corners.
    """
    t, b, s = _frame(direction)
    lo, hi = box
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    pad = PAD * float(np.linalg.norm(hi - lo)) + 1e-6
    u, v, w = corners @ t, corners @ b, corners @ s
    size = max(np.ptp(u), np.ptp(v)) + 2.0 * pad
    u0 = 0.5 * (u.min() + u.max()) - 0.5 * size
    v0 = 0.5 * (v.min() + v.max()) - 0.5 * size
    w_top = w.max() + pad
    depth_range = np.ptp(w) + 2.0 * pad
    k = resolution / size
    rows = np.array([np.r_[k * t, -k * u0], np.r_[k * b, -k * v0], np.r_[-s, w_top]])
    clip = np.zeros((4, 4))
    clip[0] = rows[0] * 2.0 / resolution - np.array([0, 0, 0, 1.0])
    clip[1] = rows[1] * 2.0 / resolution - np.array([0, 0, 0, 1.0])
    clip[2] = rows[2] * 2.0 / depth_range - np.array([0, 0, 0, 1.0])
    clip[3, 3] = 1.0
    return rows, clip, size / resolution


def _build_batch(positions, triangles):
    fmt = gpu.types.GPUVertFormat()
    fmt.attr_add(id="pos", comp_type="F32", len=3, fetch_mode="FLOAT")
    vbo = gpu.types.GPUVertBuf(fmt, len(positions))
    vbo.attr_fill("pos", positions)
    ibo = gpu.types.GPUIndexBuf(type="TRIS", seq=triangles)
    return gpu.types.GPUBatch(type="TRIS", buf=vbo, elem=ibo)


def _render(framebuffer, batch, clip, rows, resolution):
    import mathutils

    viewport = gpu.state.viewport_get()
    depth_test = gpu.state.depth_test_get()
    depth_mask = gpu.state.depth_mask_get()
    try:
        with framebuffer.bind():
            gpu.state.viewport_set(0, 0, resolution, resolution)
            framebuffer.clear(color=(FAR, 0.0, 0.0, 1.0), depth=1.0)
            gpu.state.depth_test_set("LESS_EQUAL")
            gpu.state.depth_mask_set(True)
            gpu.state.face_culling_set("NONE")
            shader = _shader()
            shader.bind()
            shader.uniform_float("clip", mathutils.Matrix(clip.tolist()))
            shader.uniform_float("depth_row", tuple(float(x) for x in rows[2]))
            batch.draw(shader)
    finally:
        gpu.state.depth_test_set(depth_test)
        gpu.state.depth_mask_set(depth_mask)
        gpu.state.viewport_set(*viewport)


def scene_view_layer(scene):
    return bpy.context.view_layer if scene == bpy.context.scene else scene.view_layers[0]


def _atlas(state, wide, tiles, resolution):
    """The state's atlas for `wide`, made again when its tile count or resolution changed."""
    atlas = state.atlases.get(wide)
    if tiles == 0:
        state.atlases.pop(wide, None)
        return None
    if atlas is None or atlas.tiles != tiles or atlas.resolution != resolution:
        atlas = state.atlases[wide] = shadow_atlas.Atlas(resolution, tiles)
    return atlas


def update_shadow_maps(scene, lights, depsgraph=None, view_layer=None, resolution=None, wide_resolution=None):
    """The scene's ShadowSet for `lights` (core.lights.extraction.Light list): their views
    (core.lights.shadow_views, as many wide maps as the casters' triangles allow), each map drawn again
    only when its direction or the geometry changed."""
    sizes = {False: resolution or RESOLUTION, True: wide_resolution or WIDE_RESOLUTION}
    state = _states.setdefault(scene.as_pointer(), ShadowState())
    objects = caster_objects(scene, view_layer or scene_view_layer(scene))
    key = geometry_signature(objects, depsgraph)
    if key != state.geometry_key:
        positions, triangles = caster_triangles(objects, depsgraph)
        state.batch = _build_batch(positions, triangles) if len(triangles) else None
        state.box = (
            (positions.min(axis=0).astype(np.float64), positions.max(axis=0).astype(np.float64))
            if len(positions)
            else None
        )
        state.triangles = len(triangles)
        state.geometry_key = key
    views = shadow_views(lights, max_wide_views=wide_view_budget(state.triangles))
    atlases = {}
    for wide in (False, True):
        atlases[wide] = _atlas(state, wide, sum(1 for v in views if v.wide == wide), sizes[wide])
    placed, next_tile = [], {False: 0, True: 0}
    for view in views:
        wide = bool(view.wide)
        atlas, tile = atlases[wide], next_tile[wide]
        next_tile[wide] += 1
        size = atlas.resolution
        if state.box is None:
            rows, texel, clip = np.array([[0, 0, 0, -1.0], [0, 0, 0, -1.0], [0, 0, 0, 0.0]]), 1.0, None
        else:
            rows, clip, texel = light_rows(view.direction, state.box, size)
        map_key = (key, np.asarray(view.direction, dtype=np.float64).tobytes())
        if clip is not None and atlas.keys[tile] != map_key:
            target = shadow_atlas.scratch(size)
            _render(target.framebuffer, state.batch, clip, rows, size)
            shadow_atlas.copy_into(atlas, tile, target.color)
        atlas.keys[tile] = map_key
        placed.append(ViewMap(rows, texel, size, atlas.origin(tile), wide))
    textures = {w: (a.color if a is not None else shadow_atlas.empty_texture()) for w, a in atlases.items()}
    return ShadowSet(views, placed, textures[False], textures[True])
