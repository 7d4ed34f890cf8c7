"""GLSL of the sun lights: per-pixel cosine term and a shadow-map visibility over the light's disc.

Added to the PRT shader when the scene has split lights. The SH part (per vertex, clamped) is left
as it is; the fragment shader adds albedo * sum_l P_l/pi * C_l * V_l. C_l is the light's cosine
term as core.light_visibility.light_cosines defines it: sum_j w_j max(0, n.s_j) over its samples
(up to MAX_SAMPLES; a light without samples is its direction, weight 1). V_l is PCSS on the
light's orthographic depth map (shadows.py): a blocker search over the widest penumbra the disc
can throw, then percentage-closer filtering with the penumbra radius (d_receiver - d_blocker) *
tan(angle), both over Vogel-disc taps, with a depth bias from the receiver's slope. It is one
map along the light's mean direction, filtered over a disc of the light's shadow angle
(core.light_samples.shadow_angle: the power-median radius of its texels, at most the moment
radius): for a wide light the shadow is that disc's, where api.shade traces each sample.
"""

import gpu
import numpy as np

from ...core.light_samples import shadow_angle

MAX_SUNS = 8
MAX_SAMPLES = 16  # samples per light in the cosine term (core.light_samples.SAMPLES_PER_LIGHT)
MIN_COSINE = 0.05  # the slope bias's cosine when the mean direction is at or below the horizon
SHADOW_SLOT = 1  # sampler slots 1..8 (slot 0 is the transfer texture)
BLOCKER_TAPS = 12
PCF_TAPS = 16
MAX_RADIUS = 16.0  # texels: widest penumbra filtered
MAX_SLOPE = 20.0  # tan of the receiver's angle to the light, capped for the bias

UBO_SOURCE = (
    f"struct PRTSuns {{ vec4 nrm[3]; vec4 to_light[{3 * MAX_SUNS}]; vec4 dir[{MAX_SUNS}]; "
    f"vec4 power[{MAX_SUNS}]; vec4 params[{MAX_SUNS}]; vec4 samples[{MAX_SUNS * MAX_SAMPLES}]; }};\n"
)

_FUNCTIONS = f"""
float sun_depth(sampler2D map, vec2 xy, float res)
{{
  ivec2 t = ivec2(floor(xy));
  if (t.x < 0 || t.y < 0 || t.x >= int(res) || t.y >= int(res)) {{
    return 1.0e30;
  }}
  return texelFetch(map, t, 0).r;
}}

vec2 vogel(int i, int n)
{{
  float r = sqrt((float(i) + 0.5) / float(n));
  float a = float(i) * 2.3999632;
  return r * vec2(cos(a), sin(a));
}}

float sun_cosine(vec3 n, int l)
{{
  float sum = 0.0;
  for (int j = 0; j < {MAX_SAMPLES}; j++) {{
    vec4 s = suns.samples[{MAX_SAMPLES} * l + j];
    sum += s.w * max(dot(n, s.xyz), 0.0);
  }}
  return sum;
}}

float sun_visibility(sampler2D map, int l, float c)
{{
  vec4 p = vec4(local_pos, 1.0);
  vec3 q = vec3(dot(suns.to_light[3 * l], p), dot(suns.to_light[3 * l + 1], p),
                dot(suns.to_light[3 * l + 2], p));
  float texel = suns.params[l].x;
  float tan_a = suns.params[l].y;
  float res = suns.params[l].z;
  float slope = min(sqrt(max(1.0 - c * c, 0.0)) / c, {MAX_SLOPE});
  float search = clamp(q.z * tan_a / texel, 1.0, {MAX_RADIUS});
  float limit = q.z - texel * (1.0 + (search + 1.0) * slope);
  float sum = 0.0;
  float found = 0.0;
  for (int i = 0; i < {BLOCKER_TAPS}; i++) {{
    float d = sun_depth(map, q.xy + search * vogel(i, {BLOCKER_TAPS}), res);
    if (d < limit) {{
      sum += d;
      found += 1.0;
    }}
  }}
  if (found == 0.0) {{
    return 1.0;
  }}
  float radius = clamp((q.z - sum / found) * tan_a / texel, 0.5, {MAX_RADIUS});
  limit = q.z - texel * (1.0 + (radius + 1.0) * slope);
  float lit = 0.0;
  for (int i = 0; i < {PCF_TAPS}; i++) {{
    lit += step(limit, sun_depth(map, q.xy + radius * vogel(i, {PCF_TAPS}), res));
  }}
  return lit / {float(PCF_TAPS)};
}}
"""


def add_suns(info, lights, vertex_source, attr_index):
    """Declare the sun inputs on `info`; -> (vertex source, fragment source)."""
    info.uniform_buf(1, "PRTSuns", "suns")
    info.vertex_in(attr_index, "VEC3", "prt_nrm")
    for l in range(lights):
        info.sampler(SHADOW_SLOT + l, "FLOAT_2D", f"shadow{l}")
    iface = gpu.types.GPUStageInterfaceInfo("prt_sun_iface")
    iface.smooth("VEC3", "radiance")
    iface.smooth("VEC3", "surface_albedo")
    iface.smooth("VEC3", "local_pos")
    iface.smooth("VEC3", "local_nrm")
    info.vertex_out(iface)
    vertex = vertex_source.replace(
        "  gl_Position = mvp",
        "  surface_albedo = prt_albedo.rgb * tint.rgb * scale;\n"
        "  local_pos = prt_pos;\n"
        "  local_nrm = prt_nrm;\n"
        "  gl_Position = mvp",
    )
    per_light = "\n".join(
        f"  c = sun_cosine(n, {l});\n"
        f"  if (c > 0.0) {{\n"
        f"    float v = sun_visibility(shadow{l}, {l}, max(dot(n, suns.dir[{l}].xyz), {MIN_COSINE}));\n"
        f"    sun += suns.power[{l}].rgb * (c * v);\n"
        f"  }}"
        for l in range(lights)
    )
    fragment = _FUNCTIONS + (
        "void main()\n{\n"
        "  vec3 n = normalize(vec3(dot(suns.nrm[0].xyz, local_nrm), dot(suns.nrm[1].xyz, local_nrm),\n"
        "                          dot(suns.nrm[2].xyz, local_nrm)));\n"
        "  vec3 sun = vec3(0.0);\n"
        "  float c;\n"
        f"{per_light}\n"
        "  FragColor = vec4(display_transform(radiance + surface_albedo * sun), 1.0);\n"
        "}\n"
    )
    return vertex, fragment


def suns_ubo_bytes(lights, maps, matrix_world):
    """std140 bytes of PRTSuns for one object: its normal matrix, and per light the local ->
    (texel x, texel y, depth) rows, the direction, P / pi, (texel size, tan shadow angle, resolution)
    and the samples (direction, weight; the first MAX_SAMPLES, their weights renormalised)."""
    mw = np.asarray(matrix_world, dtype=np.float64)
    data = np.zeros((3 + 6 * MAX_SUNS + MAX_SUNS * MAX_SAMPLES, 4))
    data[0:3, :3] = np.linalg.inv(mw[:3, :3]).T
    for l, (light, shadow) in enumerate(zip(lights, maps)):
        data[3 + 3 * l : 6 + 3 * l] = shadow.rows @ mw
        base = 3 + 3 * MAX_SUNS
        data[base + l, :3] = light.direction / np.linalg.norm(light.direction)
        data[base + MAX_SUNS + l, :3] = light.power / np.pi
        penumbra = min(shadow_angle(light), 1.5)
        data[base + 2 * MAX_SUNS + l, :3] = (shadow.texel, np.tan(penumbra), shadow.resolution)
        first = base + 3 * MAX_SUNS + MAX_SAMPLES * l
        if light.samples is None:
            data[first] = (*data[base + l, :3], 1.0)
        else:
            count = min(len(light.samples), MAX_SAMPLES)
            data[first : first + count, :3] = light.samples[:count]
            data[first : first + count, 3] = light.weights[:count] / light.weights[:count].sum()
    return data.astype(np.float32).tobytes()
