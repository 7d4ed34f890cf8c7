"""The full transfer's specular occlusion per vertex, drawn into a texture once per view change; the frame reads it.

The lobe-weighted visibility at a vertex's reflection direction (shader_specular.occlusion_lines;
docs/specular.md) depends on the eye, the object's matrix and the slot's roughness, not on the
lighting. Here the mesh's vertices are drawn once as points, one per texel of an RG32F target
4096 texels wide (vertex v at (v % 4096, v / 4096)), each point's vertex shader evaluating its vertex's
occlusion (r) and, for a roughness image, its second lobe's (g, material_maps); again only when
one of those changed. Turning the lighting draws none of it; the frame's vertex shader reads
one texel instead of summing the transfer a second time (as web/src/occlusion.js).
"""

import gpu
import numpy as np

from .. import caches
from . import material_maps, shader_specular

WIDTH_BITS = shader_specular.OCC_WIDTH_BITS  # 4096 texels a row: a vertex's texel by shifts

_VERTEX = f"""
void main()
{{
  vec2 texel = vec2(float(gl_VertexID & {(1 << WIDTH_BITS) - 1}), float(gl_VertexID >> {WIDTH_BITS})) + 0.5;
  gl_Position = vec4(texel / vec2(occ_size) * 2.0 - 1.0, 0.0, 1.0);
  float spec_occ;
  float spec_occ2;
COLUMNS
LINES  occ_value = vec2(spec_occ, SECOND);
}}
"""

_FRAGMENT = """
void main()
{
  FragColor = vec4(occ_value, 0.0, 1.0);
}
"""

_programs = {}  # (mode, count, vec4s per element, two lobes) -> shader


@caches.on_clear
def clear_programs():
    _programs.clear()


def _program(mode, count, total, paired):
    """The points shader for a transfer in `mode` ("ATTR" or "TEXTURE") of `count` direct vec4s
    among `total` per element; paired: a roughness image's two lobes (material_maps)."""
    key = (mode, count, total, paired)
    if key in _programs:
        return _programs[key]
    info = gpu.types.GPUShaderCreateInfo()
    info.typedef_source(material_maps.ubo_source() if paired else shader_specular.UBO_SOURCE)
    info.uniform_buf(2, "PRTSpec", "spec")
    info.push_constant("IVEC2", "occ_size")
    info.vertex_in(0, "VEC3", "prt_pos")
    info.vertex_in(1, "VEC3", "prt_nrm")
    columns = ""
    if mode == "ATTR":
        for k in range(count):
            info.vertex_in(2 + k, "VEC4", f"prt_t{k}")
    else:
        info.push_constant("INT", "per_row")
        info.sampler(0, "FLOAT_2D", "transfer_tx")
        columns = f"  int col = (gl_VertexID % per_row) * {total};\n  int row = gl_VertexID / per_row;\n"
    iface = gpu.types.GPUStageInterfaceInfo("prt_occ_iface")
    iface.flat("VEC2", "occ_value")
    info.vertex_out(iface)
    info.fragment_out(0, "VEC4", "FragColor")
    lines = shader_specular.occlusion_lines(mode, count)
    source = _VERTEX.replace("COLUMNS\n", columns).replace("LINES", lines)
    source = source.replace("SECOND", "spec_occ2" if paired else "0.0")
    info.vertex_source(material_maps.second_lobe(source) if paired else source)
    info.fragment_source(_FRAGMENT)
    _programs[key] = gpu.shader.create_from_info(info)
    return _programs[key]


class Occlusion:
    """One material slot's occlusion texture, and what it was drawn for."""

    __slots__ = ("texture", "key")

    def __init__(self, vertices):
        max_size = min(16384, gpu.capabilities.max_texture_size_get())
        height = max(1, -(-vertices >> WIDTH_BITS))
        if height > max_size:
            raise RuntimeError(f"{vertices} vertices exceed one {1 << WIDTH_BITS}x{max_size} texture")
        self.texture = gpu.types.GPUTexture((1 << WIDTH_BITS, height), format="RG32F")
        self.key = None


def update(state, slot, entry, ubo, key, layout):
    """Slot `slot`'s occlusion texture of `entry` (gpu_cache.MeshEntry), drawn with the slot's
    PRTSpec block `ubo` when `key` (the eye, the object's matrix, the lobes: what it depends on)
    differs from the last draw's; layout: (mode, direct vec4s, vec4s per element, two lobes)."""
    if state.spec_occ is None:
        state.spec_occ = {}
    occ = state.spec_occ.get(slot)
    key = (entry, layout, key)  # (a MeshEntry compares by identity: a rebuilt mesh draws again)
    if occ is None or occ.texture.width * occ.texture.height < entry.vertices:
        occ = state.spec_occ[slot] = Occlusion(entry.vertices)
    if occ.key == key:
        return occ.texture
    mode, count, total, paired = layout
    shader = _program(mode, count, total, paired)
    viewport = gpu.state.viewport_get()
    depth_test = gpu.state.depth_test_get()
    try:
        # A new framebuffer at each use, as texel_relight's (one binds only in its first GPU context).
        with gpu.types.GPUFrameBuffer(color_slots=(occ.texture,)).bind():
            gpu.state.depth_test_set("NONE")
            gpu.state.viewport_set(0, 0, occ.texture.width, occ.texture.height)
            gpu.state.point_size_set(1.0)
            shader.bind()
            shader.uniform_block("spec", ubo)
            shader.uniform_int("occ_size", (occ.texture.width, occ.texture.height))
            if mode == "TEXTURE":
                shader.uniform_int("per_row", entry.per_row)
                shader.uniform_sampler("transfer_tx", entry.texture)
            entry.points.draw(shader)
    finally:
        gpu.state.depth_test_set(depth_test)
        gpu.state.viewport_set(*viewport)
    occ.key = key
    return occ.texture


def view_key(spec_frame, matrix_world, params, extra):
    """What a slot's occlusion depends on: the eye, the object's matrix, the lobes' parameters."""
    return (np.asarray(spec_frame[0]).tobytes(), np.asarray(matrix_world).tobytes(), params, extra)
