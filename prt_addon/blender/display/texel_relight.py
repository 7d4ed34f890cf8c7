"""Texel bakes relit once per lighting change: each texel's max(sum_i L_i t_i, 0) into a texture the frame reads.

A frame then reads one bilinear radiance per pixel instead of every coefficient tile's four
texels (the per-pixel sum cost 6.8 times the vertex bake's frame on llvmpipe; docs/texels.md).
The bilinear lookup of the clamped radiance is what `shade` gives per texel, looked up. With
bounces the bounced tiles (scene.texel_storage) add against light.b, the sky plus the split
lights' SH, before the clamp, as `shade` does. An open mesh's back side is relit beside the front, in
the same texture from column res, from its own image (direct only).
"""

import gpu

from .. import caches

_VERTEX = """
void main()
{
  gl_Position = vec4(pos, 0.0, 1.0);
}
"""

_FRAGMENT = """
void main()
{
  ivec2 p = ivec2(gl_FragCoord.xy) - ivec2(x0, 0);
  vec3 r = vec3(0.0);
  for (int k = 0; k < %(count)d; k++) {
    vec4 t = texelFetch(transfer_tx, ivec2(k %% tiles, k / tiles) * res + p, 0);
    r += vec3(dot(t, light.c[k]), dot(t, light.c[%(count)d + k]), dot(t, light.c[%(twice)d + k]));
%(bounce)s  }
  FragColor = vec4(max(r, vec3(0.0)), 1.0);
}
"""

_programs = {}  # (coefficient groups, bounce channels) -> (shader, quad batch)


@caches.on_clear
def clear():
    _programs.clear()


def _bounce_source(count, channels):
    """Fragment lines adding the bounced tiles' k-th vec4s (one per channel, or one for all)."""
    if not channels:
        return ""
    fetch = []
    for c in range(3):
        g = f"{count * (1 + (c if channels == 3 else 0))} + k"
        fetch.append(f"texelFetch(transfer_tx, ivec2(({g}) % tiles, ({g}) / tiles) * res + p, 0)")
    return (
        f"    r += vec3(dot({fetch[0]}, light.b[k]), dot({fetch[1]}, light.b[{count} + k]),\n"
        f"              dot({fetch[2]}, light.b[{2 * count} + k]));\n"
    )


def _program(count, channels=0):
    key = (count, channels)
    if key not in _programs:
        from gpu_extras.batch import batch_for_shader

        info = gpu.types.GPUShaderCreateInfo()
        bounce_block = f" vec4 b[{3 * count}];" if channels else ""
        info.typedef_source(f"struct PRTLight {{ vec4 c[{3 * count}];{bounce_block} }};\n")
        info.uniform_buf(0, "PRTLight", "light")
        info.push_constant("INT", "res")
        info.push_constant("INT", "tiles")
        info.push_constant("INT", "x0")  # the first column drawn: 0, or res for a back side
        info.sampler(0, "FLOAT_2D", "transfer_tx")
        info.vertex_in(0, "VEC2", "pos")
        info.fragment_out(0, "VEC4", "FragColor")
        info.vertex_source(_VERTEX)
        bounce = _bounce_source(count, channels)
        info.fragment_source(_FRAGMENT % {"count": count, "twice": 2 * count, "bounce": bounce})
        shader = gpu.shader.create_from_info(info)
        quad = batch_for_shader(shader, "TRI_STRIP", {"pos": ((-1, -1), (1, -1), (-1, 1), (1, 1))})
        _programs[key] = (shader, quad)
    return _programs[key]


class Relit:
    """One object's relit radiance: an RGBA32F texture of res x res texels, or for an open mesh
    2 res x res, its back side's beside the front's (from column res)."""

    __slots__ = ("texture", "back", "resolution")

    def __init__(self, resolution, back=False):
        self.resolution = resolution
        self.back = bool(back)
        self.texture = gpu.types.GPUTexture((resolution * (1 + self.back), resolution), format="RGBA32F")


def relight(relit, transfer, grid, count, light_ubo, channels=0, back=None):
    """Draw max(sum_i L_i t_i, 0) of every texel of `transfer` (the bake's tiles; grid: (res,
    tiles per row)) with the light of `light_ubo` (shader.light_ubo_bytes) into relit.texture;
    channels: the bounce channels of the tiles (0: direct only); back: (the back side's tiles,
    their tiles per row), drawn into the texture's back half with the same light (direct only)."""
    parts = [(0, transfer, grid[1], channels)]
    if back is not None:
        parts.append((relit.resolution, back[0], back[1], 0))
    viewport = gpu.state.viewport_get()
    depth_test = gpu.state.depth_test_get()
    try:
        # A new framebuffer at each use (as shadow_atlas.Atlas's: one binds only in the GPU
        # context of its first bind).
        with gpu.types.GPUFrameBuffer(color_slots=(relit.texture,)).bind():
            gpu.state.depth_test_set("NONE")
            for x0, tiles, per_row, part_channels in parts:
                shader, quad = _program(count, part_channels)
                gpu.state.viewport_set(x0, 0, relit.resolution, relit.resolution)
                shader.bind()
                shader.uniform_block("light", light_ubo)
                shader.uniform_int("res", grid[0])
                shader.uniform_int("tiles", per_row)
                shader.uniform_int("x0", x0)
                shader.uniform_sampler("transfer_tx", tiles)
                quad.draw(shader)
    finally:
        gpu.state.depth_test_set(depth_test)
        gpu.state.viewport_set(*viewport)
