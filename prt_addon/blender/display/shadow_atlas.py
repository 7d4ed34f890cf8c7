"""Where the shadow maps live: one R32F atlas texture per kind of view, each map a tile copied in from a scratch map.

A map is drawn into a scratch framebuffer of its own size (R32F colour and a 32-bit depth buffer,
one per resolution, shared by every map of that size) and then copied into its tile of the atlas
by a full-tile draw. Layered framebuffer attachments would avoid the copy, but the `gpu` module of
Blender 4.2 to 4.5 parses the attachment dict's keys the wrong way round and 4.2 then draws
nothing into the layer, so plain 2D textures are used. The atlas is at most ATLAS_WIDTH texels
wide: ATLAS_WIDTH // resolution tiles to a row.
"""

import gpu

from .. import caches

ATLAS_WIDTH = 8192

_COPY_VERTEX = """
void main()
{
  gl_Position = vec4(pos, 0.0, 1.0);
}
"""

_COPY_FRAGMENT = """
void main()
{
  FragColor = texelFetch(source, ivec2(gl_FragCoord.xy - origin), 0);
}
"""

_copy = []  # (shader, batch)
_empty = []  # the 1-texel texture bound for an empty set of maps
_scratch = {}  # resolution -> Scratch


class Scratch:
    """One map's worth of framebuffer: R32F colour and a 32-bit depth buffer."""

    __slots__ = ("color", "depth")

    def __init__(self, resolution):
        self.color = gpu.types.GPUTexture((resolution, resolution), format="R32F")
        self.depth = gpu.types.GPUTexture((resolution, resolution), format="DEPTH_COMPONENT32F")

    @property
    def framebuffer(self):
        return gpu.types.GPUFrameBuffer(depth_slot=self.depth, color_slots=(self.color,))  # (see Atlas)


class Atlas:
    """`tiles` maps of `resolution` texels in one R32F texture, and per tile the key it holds."""

    __slots__ = ("resolution", "tiles", "cols", "color", "keys")

    def __init__(self, resolution, tiles):
        self.resolution = resolution
        self.tiles = tiles
        self.cols, rows = atlas_shape(tiles, resolution)
        self.color = gpu.types.GPUTexture((self.cols * resolution, rows * resolution), format="R32F")
        self.keys = [None] * tiles

    @property
    def framebuffer(self):
        """A new framebuffer over the texture at each use: a framebuffer binds only in the GPU
        context of its first bind (each window has its own, and render_view may run in another),
        while textures are shared between contexts."""
        return gpu.types.GPUFrameBuffer(color_slots=(self.color,))

    def origin(self, tile):
        """(x, y) texel of the tile's first texel in the atlas."""
        return (tile % self.cols) * self.resolution, (tile // self.cols) * self.resolution


def atlas_shape(tiles, resolution):
    """(columns, rows) of tiles: rows of at most ATLAS_WIDTH // resolution tiles."""
    cols = max(1, min(tiles, ATLAS_WIDTH // resolution))
    return cols, -(-tiles // cols)


def scratch(resolution):
    if resolution not in _scratch:
        _scratch[resolution] = Scratch(resolution)
    return _scratch[resolution]


def empty_texture():
    if not _empty:
        _empty.append(gpu.types.GPUTexture((1, 1), format="R32F", data=gpu.types.Buffer("FLOAT", 1, [0.0])))
    return _empty[0]


def _copy_program():
    if not _copy:
        from gpu_extras.batch import batch_for_shader

        info = gpu.types.GPUShaderCreateInfo()
        info.push_constant("VEC2", "origin")
        info.sampler(0, "FLOAT_2D", "source")
        info.vertex_in(0, "VEC2", "pos")
        info.fragment_out(0, "VEC4", "FragColor")
        info.vertex_source(_COPY_VERTEX)
        info.fragment_source(_COPY_FRAGMENT)
        shader = gpu.shader.create_from_info(info)
        quad = batch_for_shader(shader, "TRI_STRIP", {"pos": ((-1, -1), (1, -1), (-1, 1), (1, 1))})
        _copy.append((shader, quad))
    return _copy[0]


def copy_into(atlas, tile, source):
    """Copy the scratch texture `source` (one map) into the atlas's tile."""
    shader, quad = _copy_program()
    x, y = atlas.origin(tile)
    viewport = gpu.state.viewport_get()
    depth_test = gpu.state.depth_test_get()
    try:
        with atlas.framebuffer.bind():
            gpu.state.viewport_set(x, y, atlas.resolution, atlas.resolution)
            gpu.state.depth_test_set("NONE")
            shader.bind()
            shader.uniform_float("origin", (float(x), float(y)))
            shader.uniform_sampler("source", source)
            quad.draw(shader)
    finally:
        gpu.state.depth_test_set(depth_test)
        gpu.state.viewport_set(*viewport)


@caches.on_clear
def clear():
    _copy.clear()
    _empty.clear()
    _scratch.clear()
