"""The PRT shader: per-vertex radiance sum_i L_i t_i from vertex attributes or a texture.

The transfer t comes as vertex attributes while they fit in the 16 vertex-attribute limit
(orders <= 7), otherwise from an RGBA32F texture read with texelFetch at gl_VertexID; the light
is a uniform buffer (std140, vec4-padded). The vertex shader computes max(sum_i L_i t_i, 0) per
colour channel times the albedo; the fragment shader writes it through the scene's display
transform (colour.GLSL: display_transform, one 3D-table lookup; display_mode 0 leaves it linear).
With sun lights (shadows.py) a variant adds per pixel albedo * sum_l P_l/pi * max(0, n.s_l) * V_l
(shader_suns.py) before that transform.
"""

import gpu
import numpy as np

from . import colour


# GL guarantees (and llvmpipe offers) 16 vertex attributes; position and albedo use two.
MAX_VERTEX_ATTRIBUTES = 16


MAX_ATTRIBUTE_TRANSFER = MAX_VERTEX_ATTRIBUTES - 2  # 14 vec4 = 56 coefficients: orders <= 7


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
  FragColor = vec4(display_transform(radiance), 1.0);
}
"""


def _dot_line(tex, k, count):
    return (
        f"  r += vec3(dot({tex}, light.c[{k}]), dot({tex}, light.c[{count + k}]), "
        f"dot({tex}, light.c[{2 * count + k}]));"
    )


def shader_mode(count):
    return "ATTR" if count <= MAX_ATTRIBUTE_TRANSFER else "TEXTURE"


def get_shader(count, lights=0):
    """Compiled shader for `count` transfer vec4s and `lights` suns (cached). Raises RuntimeError
    on failure. lights = 0 is the plain PRT shader."""
    mode = shader_mode(count)
    key = (mode, count) if not lights else (mode, count, lights)
    shader = _shaders.get(key)
    if shader is not None:
        return shader
    info = gpu.types.GPUShaderCreateInfo()
    typedefs = f"struct PRTLight {{ vec4 c[{3 * count}]; }};\n"
    if lights:
        from .shader_suns import UBO_SOURCE

        typedefs += UBO_SOURCE  # (typedef_source keeps only its last call)
    info.typedef_source(typedefs)
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
    if lights:
        from .shader_suns import add_suns

        vertex, fragment = add_suns(info, lights, _VERTEX_COMMON % body, 2 + count if mode == "ATTR" else 2)
    else:
        iface = gpu.types.GPUStageInterfaceInfo("prt_iface")
        iface.smooth("VEC3", "radiance")
        info.vertex_out(iface)
        vertex, fragment = _VERTEX_COMMON % body, _FRAGMENT
    colour.declare(info)
    info.fragment_out(0, "VEC4", "FragColor")
    info.vertex_source(vertex)
    info.fragment_source(colour.GLSL + fragment)
    shader = gpu.shader.create_from_info(info)
    _shaders[key] = shader
    return shader


def light_ubo_bytes(light_local, count):
    """std140 bytes of PRTLight: c[ch * count + k] = (L_{4k..4k+3}, channel ch), zero-padded."""
    padded = np.zeros((4 * count, 3), dtype=np.float32)
    n = min(len(light_local), 4 * count)
    padded[:n] = light_local[:n]
    return np.ascontiguousarray(padded.T.reshape(3, count, 4)).tobytes()
