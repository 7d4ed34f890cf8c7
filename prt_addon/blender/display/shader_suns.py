"""GLSL of the sun lights: per-pixel cosine term and shadow-map visibility, summed over the lights' shadow views.

Added to the PRT shader when the scene has split lights. The SH part (per vertex, clamped) is left
as it is; the fragment shader adds albedo * sum_v P_v/pi * C_v * V_v over the shadow views
(core.lights.shadow_views): a compact light is one view holding all its samples, a wide light one view
per group of its samples. C_v is the view's cosine term as core.lights.visibility.light_cosines
defines it, over its own samples: sum_j w_j max(0, n.s_j). V_v is PCSS on the view's orthographic
depth map (shadows.py; a tile of the compact or of the wide maps' atlas): a blocker search over
the widest penumbra the view's disc can throw, then percentage-closer filtering with the penumbra
radius (d_receiver - d_blocker) * tan(angle), both over Vogel-disc taps. Each tap is compared with
the receiver's own plane at that texel's centre (receiver-plane depth bias: the plane's depth
slope in the map follows from the normal), less a bias of one texel plus that slope, so the bias
does not grow with the filter's radius. A PCF tap stands for one direction of the view's disc and
counts with its cosine to the receiver, none below the receiver's horizon (where a map seeing the
receiver edge-on holds nothing); a view whose own direction is below that horizon gives 0. A PCF
tap whose map depth is far behind the receiver's plane (past a join, where that plane is no
surface) reads the tap mirrored through the centre instead. A wide light's view reads every
sixth of its PCF taps first and the rest only where those disagree (its penumbra).
"""

import gpu
import numpy as np

from ...core.lights.shadow_views import MAX_SAMPLES, MAX_WIDE_VIEWS

MAX_SUNS = 8
MAX_VIEWS = MAX_SUNS + MAX_WIDE_VIEWS
MIN_COSINE = 0.05  # the slope bias's cosine when the view's direction is at or below the horizon
SHARP_SLOT = 1  # the compact lights' maps (slot 0 is the transfer texture)
WIDE_SLOT = 2  # the wide lights' views' maps
BLOCKER_TAPS = 12
PCF_TAPS = 16
WIDE_BLOCKER_TAPS = 6  # a wide light's views: many maps average out, each one filters less
WIDE_PCF_TAPS = 48  # in a penumbra: 8 left faint streaks (docs/display.md, "Streaks")
WIDE_FIRST_TAPS = 8  # the wide PCF taps read first; the rest only where these disagree
MAX_RADIUS = 64.0  # texels: widest penumbra filtered (a compact light's map, at 2048)
WIDE_MAX_RADIUS = 24.0  # texels: a wide light's view's (1024): wider reaches past joins and edges
MAX_SLOPE = 20.0  # tan of the receiver's angle to the light, capped for the bias
MIRROR_BEHIND = 2.0  # biases behind the receiver's plane past which a PCF tap reads its mirror tap
CONTACT_SHIFT = 3.0  # lookups move this many biases along the contact tangent (docs/display.md, "Joins")

UBO_SOURCE = (
    f"struct PRTSuns {{ vec4 nrm[3]; vec4 to_light[{3 * MAX_VIEWS}]; vec4 dir[{MAX_VIEWS}]; "
    f"vec4 axes[{2 * MAX_VIEWS}]; vec4 power[{MAX_VIEWS}]; vec4 params[{MAX_VIEWS}]; vec4 range[{MAX_VIEWS}]; "
    f"vec4 samples[{2 * MAX_SUNS * MAX_SAMPLES}]; }};\n"
)

_FUNCTIONS = f"""
float sun_depth(sampler2D maps, vec2 xy, ivec2 origin, float res)
{{
  ivec2 t = ivec2(floor(xy));
  if (t.x < 0 || t.y < 0 || t.x >= int(res) || t.y >= int(res)) {{
    return 1.0e30;
  }}
  return texelFetch(maps, origin + t, 0).r;
}}

vec2 vogel(int i, int n)
{{
  float r = sqrt((float(i) + 0.5) / float(n));
  float a = float(i) * 2.3999632;
  return r * vec2(cos(a), sin(a));
}}

float compact_cosine(vec3 n, int v)
{{
  float sum = 0.0;
  for (int j = 0; j < {MAX_SAMPLES}; j++) {{
    vec4 s = suns.samples[{MAX_SAMPLES} * v + j];
    sum += s.w * max(dot(n, s.xyz), 0.0);
  }}
  return sum;
}}

float view_cosine(vec3 n, int v)
{{
  int first = int(suns.range[v].x);
  int count = int(suns.range[v].y);
  float sum = 0.0;
  for (int j = first; j < first + count; j++) {{
    vec4 s = suns.samples[j];
    sum += s.w * max(dot(n, s.xyz), 0.0);
  }}
  return sum;
}}

vec2 pcf_tap(sampler2D maps, ivec2 origin, float res, vec3 q, vec2 grad, float bias, vec2 o, float facing, vec2 tilt)
{{
  // (weight x lit, weight) of the PCF tap at offset o: its direction's cosine, 0 below the horizon.
  float w = max(facing + dot(tilt, o), 0.0);
  // A tap whose column holds nothing at or near the receiver's plane, only far behind it (past
  // a join, where that plane goes outside a closed room or under the floor; past the map),
  // reads its mirror tap instead: lit only if that one is.
  vec2 xy = q.xy + o;
  float plane = q.z + dot(grad, floor(xy) + 0.5 - q.xy);
  float d = sun_depth(maps, xy, origin, res);
  if (d > plane + {MIRROR_BEHIND} * bias) {{
    xy = q.xy - o;
    plane = q.z + dot(grad, floor(xy) + 0.5 - q.xy);
    d = sun_depth(maps, xy, origin, res);
  }}
  return vec2(w * step(plane - bias, d), w);
}}

float view_visibility(sampler2D maps, int v, vec3 n, int blocker_taps, int pcf_taps, int first_taps,
                      float max_radius)
{{
  vec4 p = vec4(local_pos, 1.0);
  vec3 q = vec3(dot(suns.to_light[3 * v], p), dot(suns.to_light[3 * v + 1], p),
                dot(suns.to_light[3 * v + 2], p));
  vec3 dq = vec3(dot(suns.to_light[3 * v].xyz, local_tan), dot(suns.to_light[3 * v + 1].xyz, local_tan),
                 dot(suns.to_light[3 * v + 2].xyz, local_tan));
  // A view whose direction is below the receiver's horizon (a group of a wide light's samples
  // straddling it) has a map that looks through the receiver: its samples above get no light.
  float facing = dot(n, suns.dir[v].xyz);
  if (facing <= 0.0) {{
    return 0.0;
  }}
  float texel = suns.params[v].x;
  float tan_a = suns.params[v].y;
  float res = suns.params[v].z;
  ivec2 origin = ivec2(suns.range[v].zw);
  // The receiver's plane in the map: depth changes by texel (n.t, n.b) / n.s per texel.
  vec2 grad = vec2(dot(n, suns.axes[2 * v].xyz), dot(n, suns.axes[2 * v + 1].xyz))
              / max(dot(n, suns.dir[v].xyz), {MIN_COSINE});
  float slope = length(grad);
  if (slope > {MAX_SLOPE}) {{
    grad *= {MAX_SLOPE} / slope;
    slope = {MAX_SLOPE};
  }}
  grad *= texel;
  float bias = texel * (1.0 + slope);
  // Where another surface touches this one (a wall under a ceiling), the map holds that surface
  // at the receiver's own depth and the bias lets it through: the lookup moves into the
  // receiver's own surface along its contact tangent (core.transfer.contact.inward_tangents,
  // as the bake's ray origins do), by CONTACT_SHIFT biases in world units times its length.
  float moved = length(vec3(dq.xy * texel, dq.z));
  if (moved > 0.0) {{
    q += dq * ({CONTACT_SHIFT} * bias * length(local_tan) / moved);
  }}
  float search = clamp(q.z * tan_a / texel, 1.0, max_radius);
  float sum = 0.0;
  float found = 0.0;
  for (int i = 0; i < blocker_taps; i++) {{
    vec2 xy = q.xy + search * vogel(i, blocker_taps);
    float d = sun_depth(maps, xy, origin, res);
    if (d < q.z + dot(grad, floor(xy) + 0.5 - q.xy) - bias) {{
      sum += d;
      found += 1.0;
    }}
  }}
  if (found == 0.0) {{
    return 1.0;
  }}
  float gap = q.z - sum / found;
  float radius = clamp(gap * tan_a / texel, 0.5, max_radius);
  // Tap o stands for the direction s + tan(angle) (o / radius) . (t, b) of the view's disc: it
  // counts with that direction's cosine n . s', and not at all below the receiver's horizon.
  vec2 tilt = vec2(dot(n, suns.axes[2 * v].xyz), dot(n, suns.axes[2 * v + 1].xyz)) * (tan_a / radius);
  // Every stride-th tap first (spread over the whole disc); the others only where those disagree
  // (a penumbra), as the light is all seen or all hidden where they agree.
  int stride = pcf_taps / first_taps;
  vec2 sum_lit = vec2(0.0);
  for (int i = 0; i < pcf_taps; i += stride) {{
    sum_lit += pcf_tap(maps, origin, res, q, grad, bias, radius * vogel(i, pcf_taps), facing, tilt);
  }}
  if (stride > 1 && sum_lit.x > 0.0 && sum_lit.x < sum_lit.y) {{
    for (int i = 0; i < pcf_taps; i++) {{
      if (i % stride != 0) {{
        sum_lit += pcf_tap(maps, origin, res, q, grad, bias, radius * vogel(i, pcf_taps), facing, tilt);
      }}
    }}
  }}
  float lit = sum_lit.x;
  float weight = sum_lit.y;
  return weight > 0.0 ? lit / weight : 0.0;
}}
"""


def view_layout(shadow_set):
    """(compact views, wide views) of a ShadowSet: the shader is compiled for these counts (the
    compact views written out, the wide views in a loop of constant bound)."""
    wide = sum(1 for m in shadow_set.maps if m.wide)
    return len(shadow_set.maps) - wide, wide


def _view_lines(v, maps, cosine, taps, max_radius, specular=False):
    """GLSL adding view `v`'s light (a literal index, or a loop variable's name) to `sun`, and
    with `specular` its GGX (shader_specular.sun_specular) to `sun_spec`; taps: (blocker, PCF,
    first PCF) tap counts."""
    blocker_taps, pcf_taps, first_taps = taps
    if specular:
        return (
            f"  c = {cosine}(n, {v});\n"
            "  if (c > 0.0) {\n"
            f"    float vis = view_visibility({maps}, {v}, n, {blocker_taps}, {pcf_taps}, {first_taps}, "
            f"{max_radius:.1f});\n"
            f"    sun += suns.power[{v}].rgb * (c * vis);\n"
            "    if (spec.material.w > 0.0) {\n"
            f"      sun_spec += suns.power[{v}].rgb * (sun_specular({v}) * (vis * suns.params[{v}].w));\n"
            "    }\n"
            "  }\n"
        )
    return (
        f"  c = {cosine}(n, {v});\n"
        "  if (c > 0.0) {\n"
        f"    sun += suns.power[{v}].rgb * (c * view_visibility({maps}, {v}, n, {blocker_taps}, {pcf_taps}, "
        f"{first_taps}, {max_radius:.1f}));\n"
        "  }\n"
    )


def add_suns(info, layout, vertex_source, attr_index, specular=False):
    """Declare the sun inputs on `info` for `layout` (compact views, wide views); -> (vertex
    source, fragment source). specular: also sum the lights' GGX into `sun_spec`."""
    compact, wide = layout
    info.uniform_buf(1, "PRTSuns", "suns")
    info.vertex_in(attr_index, "VEC3", "prt_nrm")
    info.vertex_in(attr_index + 1, "VEC3", "prt_tan")
    info.sampler(SHARP_SLOT, "FLOAT_2D", "sharp_maps")
    info.sampler(WIDE_SLOT, "FLOAT_2D", "wide_maps")
    iface = gpu.types.GPUStageInterfaceInfo("prt_sun_iface")
    iface.smooth("VEC3", "radiance")
    iface.smooth("VEC3", "surface_albedo")
    iface.smooth("VEC3", "local_pos")
    iface.smooth("VEC3", "local_nrm")
    iface.smooth("VEC3", "local_tan")
    info.vertex_out(iface)
    vertex = vertex_source.replace(
        "  gl_Position = mvp",
        "  surface_albedo = prt_albedo.rgb * tint.rgb * scale;\n"
        "  local_pos = prt_pos;\n"
        "  local_nrm = prt_nrm;\n"
        "  local_tan = prt_tan;\n"
        "  gl_Position = mvp",
    )
    # Compact views written out one by one: on llvmpipe the same code in a loop of constant
    # bound (not unrolled, as its body is large) made the frame slower (docs/display.md).
    # Wide views stay in one loop: written out they were no faster and compile to far more code.
    views = [
        _view_lines(v, "sharp_maps", "compact_cosine", (BLOCKER_TAPS, PCF_TAPS, PCF_TAPS), MAX_RADIUS, specular)
        for v in range(compact)
    ]
    if wide:
        views.append(
            f"  for (int v = {compact}; v < {compact + wide}; v++) {{\n"
            + _view_lines(
                "v",
                "wide_maps",
                "view_cosine",
                (WIDE_BLOCKER_TAPS, WIDE_PCF_TAPS, WIDE_FIRST_TAPS),
                WIDE_MAX_RADIUS,
                specular,
            )
            + "  }\n"
        )
    fragment = _FUNCTIONS + (
        "void main()\n{\n"
        "  vec3 n = normalize(vec3(dot(suns.nrm[0].xyz, local_nrm), dot(suns.nrm[1].xyz, local_nrm),\n"
        "                          dot(suns.nrm[2].xyz, local_nrm)));\n"
        "  vec3 sun = vec3(0.0);\n"
        + ("  vec3 sun_spec = vec3(0.0);\n" if specular else "")
        + "  float c;\n"
        + "".join(views)
        + "  FragColor = vec4(display_transform(radiance + surface_albedo * sun), 1.0);\n}\n"
    )
    return vertex, fragment


def suns_ubo_bytes(lights, shadow_set, matrix_world):
    """std140 bytes of PRTSuns for one object: its normal matrix, and per view
    (core.lights.shadow_views; the compact lights' views first, as view_layout counts them) the local ->
    (texel x, texel y, depth) rows of its map, its direction, the map's world axes t and b, P / pi
    of its light, (texel size, tan filter angle, resolution, the view's share of the light's power:
    its highlight is weighted by it, the cosine term by its samples' weights), (first sample, sample count,
    the first texel of its tile in the atlas) and the samples (direction, weight)."""
    mw = np.asarray(matrix_world, dtype=np.float64)
    order = sorted(range(len(shadow_set.views)), key=lambda i: shadow_set.maps[i].wide)  # compact first
    views = [shadow_set.views[i] for i in order]
    maps = [shadow_set.maps[i] for i in order]
    rows_at, dir_at = 3, 3 + 3 * MAX_VIEWS
    axes_at = dir_at + MAX_VIEWS
    power_at = axes_at + 2 * MAX_VIEWS
    params_at, range_at = power_at + MAX_VIEWS, power_at + 2 * MAX_VIEWS
    samples_at = power_at + 3 * MAX_VIEWS
    data = np.zeros((samples_at + 2 * MAX_SUNS * MAX_SAMPLES, 4))
    data[0:3, :3] = np.linalg.inv(mw[:3, :3]).T
    first = MAX_SUNS * MAX_SAMPLES  # a wide view's samples, after the compact views' 16 slots each
    for v, (view, placed) in enumerate(zip(views, maps)):
        data[rows_at + 3 * v : rows_at + 3 * v + 3] = placed.rows @ mw
        data[dir_at + v, :3] = view.direction
        data[axes_at + 2 * v : axes_at + 2 * v + 2, :3] = placed.rows[:2, :3] * placed.texel  # unit t, b
        data[power_at + v, :3] = lights[view.light].power / np.pi
        share = float(np.sum(view.weights))  # the view's share of its light's power: a light's views sum to 1
        data[params_at + v] = (placed.texel, np.tan(min(view.angle, 1.5)), placed.resolution, share)
        count = len(view.weights)
        at = MAX_SAMPLES * v if not placed.wide else first
        data[range_at + v] = (at, count, *placed.origin)
        data[samples_at + at : samples_at + at + count] = np.c_[view.samples, view.weights]
        first += count if placed.wide else 0
    return data.astype(np.float32).tobytes()
