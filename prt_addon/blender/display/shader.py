"""The PRT shader: radiance sum_i L_i t_i per vertex (attributes or a texture) or per pixel (texel bakes).

The transfer t comes as vertex attributes while they fit in the 16 vertex-attribute limit
(orders <= 6), otherwise from an RGBA32F texture read with texelFetch at gl_VertexID; the light
is a uniform buffer (std140, vec4-padded). The vertex shader computes max(sum_i L_i t_i, 0) per
colour channel times the albedo; the fragment shader writes it through the scene's display
transform (colour.GLSL: display_transform, one 3D-table lookup; display_mode 0 leaves it linear).
With sun lights (shadows.py) a variant adds per pixel albedo * sum_l P_l/pi * max(0, n.s_l) * V_l
(shader_suns.py) before that transform. An open mesh's back side: a second sum, drawn on the
faces seen from behind (_back_side).
"""

import gpu
import numpy as np

from .. import caches
from . import albedo_texture, colour, material_maps, shader_specular, texel_occlusion
from .shader_suns import UBO_SOURCE, add_suns

# GL guarantees (and llvmpipe offers) 16 vertex attributes; position, albedo, and for the suns
# the normal and the contact tangent (shader_suns.py) use four.
MAX_VERTEX_ATTRIBUTES = 16


MAX_ATTRIBUTE_TRANSFER = MAX_VERTEX_ATTRIBUTES - 4  # 12 vec4 = 48 coefficients: orders <= 6


_shaders = {}


@caches.on_clear
def clear_shaders():
    _shaders.clear()


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
  FragColor = vec4(display_transform(radiance), 1.0);
}
"""


def _dot_line(tex, k, count):
    return (
        f"  r += vec3(dot({tex}, light.c[{k}]), dot({tex}, light.c[{count + k}]), "
        f"dot({tex}, light.c[{2 * count + k}]));"
    )


def shader_mode(count, domain="POINT", textured=False):
    """textured: the albedo's UV map takes one more vertex attribute."""
    if domain == "TEXEL":
        return "TEXEL"
    return "ATTR" if count <= MAX_ATTRIBUTE_TRANSFER - int(textured) else "TEXTURE"


def _albedo_diffuse(fragment):
    """`fragment` with the diffuse it writes multiplied by the albedo image (albedo_texture)."""
    head, tail = fragment.split("FragColor = vec4(display_transform(", 1)
    expr, rest = tail.rsplit("), 1.0);", 1)
    return head + f"FragColor = vec4(display_transform(albedo_px * ({expr})), 1.0);" + rest


# A texel bake: the relit radiance texture (texel_relight: max(sum_i L_i t_i, 0) per texel, made
# once per lighting change) read per pixel with the bilinear weights of a GPU's clamp-to-edge
# filter (texel centres at (i + 0.5) / res), as core's lightmap.bilinear does; x0: the first
# column of the side read (an open mesh's back side is relit beside its front, from column res).
_TEXEL_FUNCTION = """
vec3 texel_transfer(int x0)
{
  int res = texel_grid.x;
  vec2 p = clamp(texel_uv * float(res) - 0.5, vec2(0.0), vec2(float(res - 1)));
  ivec2 a = ivec2(floor(p));
  ivec2 b = min(a + 1, ivec2(res - 1));
  vec2 f = p - vec2(a);
  a.x += x0;
  b.x += x0;
  vec3 low = mix(texelFetch(transfer_tx, a, 0).rgb, texelFetch(transfer_tx, ivec2(b.x, a.y), 0).rgb, f.x);
  vec3 high = mix(texelFetch(transfer_tx, ivec2(a.x, b.y), 0).rgb, texelFetch(transfer_tx, b, 0).rgb, f.x);
  return mix(low, high, f.y);
}
"""


def _texel_back(info, vertex, fragment):
    """(vertex, fragment) of a texel bake with a back side: faces seen from behind read the relit
    texture's back half (texel_relight), with the suns' normal flipped there (as _back_side)."""
    iface = gpu.types.GPUStageInterfaceInfo("prt_back_iface")
    iface.flat("FLOAT", "prt_facing")
    info.vertex_out(iface)
    front = "vec3 prt_texel = texel_transfer(0);"
    back = "vec3 prt_texel = texel_transfer(prt_front() ? 0 : texel_grid.x);"
    assert "  radiance = max(r," in vertex and front in fragment
    facing = "  prt_facing = determinant(mvp) < 0.0 ? 1.0 : -1.0;\n"
    vertex = vertex.replace("  radiance = max(r,", facing + "  radiance = max(r,", 1)
    fragment = fragment.replace(front, back, 1)
    fragment = fragment.replace("local_nrm)));\n", "local_nrm)));\n  n = prt_front() ? n : -n;\n", 1)
    return vertex, _BACK_FUNCTION + fragment


def _texel_fragment(fragment, count):
    """`fragment` with the radiance multiplied per pixel by the texel bake's transfer."""
    main = "void main()\n{\n"
    assert main in fragment and "display_transform(radiance" in fragment
    fragment = fragment.replace(main, main + "  vec3 prt_texel = texel_transfer(0);\n", 1)
    fragment = fragment.replace("display_transform(radiance", "display_transform(radiance * prt_texel", 1)
    return _TEXEL_FUNCTION + fragment


def _bounce_lines(fetch, k, count, channels):
    """Lines adding the bounced transfer's k-th vec4s (one per channel, or one for all when
    channels == 1) against light.b, the sky plus the split lights' SH (core.lights.light_sh)."""
    t = [fetch(count * (1 + (c if channels == 3 else 0)) + k) for c in range(3)]
    return (
        f"  r += vec3(dot({t[0]}, light.b[{k}]), dot({t[1]}, light.b[{count + k}]), "
        f"dot({t[2]}, light.b[{2 * count + k}]));"
    )


def transfer_vec4s(count, bounce_channels=0, back=False):
    """vec4s per element: the direct transfer's `count`, then `count` per bounce channel, then
    `count` of the back side's transfer when `back`."""
    return count * (1 + bounce_channels + bool(back))


# The back side of an open mesh (docs/display.md, "Back faces"): a fragment whose face looks away
# from the camera takes radiance_back. gl_FrontFacing follows the winding on screen, which a
# mirrored object turns over: det(mvp) is negative for an unmirrored one (a GL projection's is).
_BACK_FUNCTION = """
bool prt_front()
{
  return gl_FrontFacing == (prt_facing > 0.0);
}
"""


def _back_side(info, vertex, fragment, first, count, mode):
    """(vertex, fragment) that also sum the back transfer (its vec4s from `first`) into
    radiance_back and draw it on back faces, with the suns' normal flipped there."""
    iface = gpu.types.GPUStageInterfaceInfo("prt_back_iface")
    iface.smooth("VEC3", "radiance_back")
    iface.flat("FLOAT", "prt_facing")
    info.vertex_out(iface)
    if mode == "ATTR":
        lines = [_dot_line(f"prt_t{first + k}", k, count).replace("r +=", "rb +=", 1) for k in range(count)]
    else:
        t = f"texelFetch(transfer_tx, ivec2(col + {first} + k, row), 0)"
        lines = [
            f"  for (int k = 0; k < {count}; k++) {{\n"
            f"    rb += vec3(dot({t}, light.c[k]), dot({t}, light.c[{count} + k]),\n"
            f"               dot({t}, light.c[{2 * count} + k]));\n"
            "  }"
        ]
    body = "  vec3 rb = vec3(0.0);\n" + "\n".join(lines)
    body += "\n  radiance_back = max(rb, vec3(0.0)) * prt_albedo.rgb * tint.rgb * scale;"
    body += "\n  prt_facing = determinant(mvp) < 0.0 ? 1.0 : -1.0;\n"
    assert "  radiance = max(r," in vertex and "display_transform(radiance" in fragment
    vertex = vertex.replace("  radiance = max(r,", body + "  radiance = max(r,", 1)
    fragment = fragment.replace(
        "display_transform(radiance", "display_transform((prt_front() ? radiance : radiance_back)"
    )
    fragment = fragment.replace("local_nrm)));\n", "local_nrm)));\n  n = prt_front() ? n : -n;\n", 1)
    return vertex, _BACK_FUNCTION + fragment


def get_shader(
    count,
    lights=None,
    bounce_channels=0,
    domain="POINT",
    specular=False,
    textured=False,
    back=False,
    spec_maps=False,
    spec_inline=False,
):
    """Compiled shader for `count` transfer vec4s per part, with the suns' shadow views when `lights`
    is a (compact views, wide views) pair (shader_suns.view_layout; None or (0, 0): no suns) and a bounced transfer
    of `bounce_channels` channels (0: none), with the Principled specular when `specular`
    (shader_specular), with an albedo image per pixel when `textured` (albedo_texture), with the back
    side's transfer drawn on back faces when `back` (a texel bake: its relit texture's back half),
    with the Principled inputs' images per pixel when `spec_maps` (material_maps; specular and
    textured only), with the specular's full-transfer occlusion summed in the vertex shader when
    `spec_inline`, else read from spec_occlusion's texture (cached).
    Raises RuntimeError on failure."""
    back = bool(back)
    total = transfer_vec4s(count, bounce_channels, back and domain != "TEXEL")
    mode = shader_mode(total, domain, textured)
    lights = tuple(lights) if lights and any(lights) else None
    spec_maps = bool(spec_maps and specular and textured)
    spec_inline = bool(spec_inline and specular and mode != "TEXEL")
    key = (mode, count, lights, bounce_channels, bool(specular), bool(textured), back, spec_maps, spec_inline)
    shader = _shaders.get(key)
    if shader is not None:
        return shader
    info = gpu.types.GPUShaderCreateInfo()
    bounce_block = f" vec4 b[{3 * count}];" if bounce_channels else ""
    typedefs = f"struct PRTLight {{ vec4 c[{3 * count}];{bounce_block} }};\n"
    if lights:
        typedefs += UBO_SOURCE  # (typedef_source keeps only its last call)
    if specular:
        typedefs += material_maps.ubo_source() if spec_maps else shader_specular.UBO_SOURCE
    info.typedef_source(typedefs)
    info.uniform_buf(0, "PRTLight", "light")
    info.push_constant("MAT4", "mvp")
    info.push_constant("VEC4", "tint")
    info.vertex_in(0, "VEC3", "prt_pos")
    info.vertex_in(1, "VEC4", "prt_albedo")
    if mode == "TEXEL":
        info.vertex_in(2, "VEC2", "prt_uv")
        info.push_constant("IVEC2", "texel_grid")  # (texels per side, tiles per row)
        info.sampler(0, "FLOAT_2D", "transfer_tx")
        texel_iface = gpu.types.GPUStageInterfaceInfo("prt_texel_iface")
        texel_iface.smooth("VEC2", "texel_uv")
        info.vertex_out(texel_iface)
        body = "  r = vec3(1.0);\n  texel_uv = prt_uv;"
    elif mode == "ATTR":
        for k in range(total):
            info.vertex_in(2 + k, "VEC4", f"prt_t{k}")
        lines = [_dot_line(f"prt_t{k}", k, count) for k in range(count)]
        if bounce_channels:
            lines += [_bounce_lines(lambda j: f"prt_t{j}", k, count, bounce_channels) for k in range(count)]
        body = "\n".join(lines)
    else:
        info.push_constant("INT", "per_row")
        info.sampler(0, "FLOAT_2D", "transfer_tx")
        bounce = ""
        if bounce_channels:
            part = [count * (1 + (c if bounce_channels == 3 else 0)) for c in range(3)]
            fetch = [f"texelFetch(transfer_tx, ivec2(col + {p} + k, row), 0)" for p in part]
            bounce = (
                f"    r += vec3(dot({fetch[0]}, light.b[k]), dot({fetch[1]}, light.b[{count} + k]),\n"
                f"              dot({fetch[2]}, light.b[{2 * count} + k]));\n"
            )
        body = (
            "  int col = (gl_VertexID % per_row) * " + str(total) + ";\n"
            "  int row = gl_VertexID / per_row;\n"
            f"  for (int k = 0; k < {count}; k++) {{\n"
            "    vec4 t = texelFetch(transfer_tx, ivec2(col + k, row), 0);\n"
            f"    r += vec3(dot(t, light.c[k]), dot(t, light.c[{count} + k]), "
            f"dot(t, light.c[{2 * count} + k]));\n"
            f"{bounce}"
            "  }"
        )
    first = {"ATTR": 2 + total, "TEXEL": 3}.get(mode, 2)
    if textured:
        info.vertex_in(first, "VEC2", "prt_albedo_uv")
        info.sampler(albedo_texture.ALBEDO_SLOT, "FLOAT_2D", "albedo_tx")
        info.push_constant("IVEC2", "albedo_mode")  # (interpolation, extension): albedo_texture
        albedo_iface = gpu.types.GPUStageInterfaceInfo("prt_albedo_iface")
        albedo_iface.smooth("VEC2", "albedo_uv")
        info.vertex_out(albedo_iface)
        body += "\n  albedo_uv = prt_albedo_uv;"
        first += 1
    # The floats after the ivec2s: Blender's push-constant layout counts 136 bytes (over the 128 every
    # backend guarantees) for a texel bake with an albedo image when they come first, within it after.
    info.push_constant("FLOAT", "scale")
    info.push_constant("FLOAT", "depth_bias")
    if lights:
        vertex, fragment = add_suns(info, lights, _VERTEX_COMMON % body, first, specular)
    else:
        iface = gpu.types.GPUStageInterfaceInfo("prt_iface")
        iface.smooth("VEC3", "radiance")
        info.vertex_out(iface)
        vertex, fragment = _VERTEX_COMMON % body, _FRAGMENT
    if back and mode != "TEXEL":
        vertex, fragment = _back_side(info, vertex, fragment, count * (1 + bounce_channels), count, mode)
    if mode == "TEXEL":
        fragment = _texel_fragment(fragment, count)
        if back:
            vertex, fragment = _texel_back(info, vertex, fragment)
    if textured:
        fragment = _albedo_diffuse(fragment)
    if specular:
        vertex, fragment = shader_specular.add_specular(
            info, vertex, fragment, mode, first, bool(lights), count, spec_inline
        )
        if mode == "TEXEL":
            fragment = texel_occlusion.GLOBALS + texel_occlusion.add_occlusion(info, fragment, count, back)
    if textured:  # read first (the specular's set-up takes it as the base colour of metals and Fresnel)
        base, main = "spec_albedo / max(scale", "void main()\n{\n"
        assert fragment.count(base) == (2 if specular else 0) and main in fragment
        fragment = fragment.replace(base, "albedo_px * " + base).replace(
            main, main + "  albedo_px = albedo_at(albedo_uv);\n", 1
        )
        fragment = albedo_texture.GLSL + fragment
    if spec_maps:
        vertex, fragment = material_maps.add_maps(info, vertex, fragment, texel=mode == "TEXEL")
    colour.declare(info)
    info.fragment_out(0, "VEC4", "FragColor")
    info.vertex_source(vertex)
    info.fragment_source(colour.GLSL + fragment)
    shader = gpu.shader.create_from_info(info)
    _shaders[key] = shader
    return shader


def light_ubo_bytes(light_local, count, bounce_light=None):
    """std140 bytes of PRTLight: c[ch * count + k] = (L_{4k..4k+3}, channel ch), zero-padded;
    then, for a bounced bake, b laid out the same from bounce_light (the sky plus the split
    lights' SH, what the bounced transfer sees)."""
    blocks = []
    for values in (light_local,) if bounce_light is None else (light_local, bounce_light):
        padded = np.zeros((4 * count, 3), dtype=np.float32)
        n = min(len(values), 4 * count)
        padded[:n] = values[:n]
        blocks.append(np.ascontiguousarray(padded.T.reshape(3, count, 4)).tobytes())
    return b"".join(blocks)
