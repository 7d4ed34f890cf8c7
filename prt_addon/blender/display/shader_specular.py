"""GLSL of the Principled specular: the prefiltered sky times the split-sum table and the specular
occlusion, GGX for the split lights, the diffuse weighted as Principled weights it.

Added to the PRT shader (shader.get_shader(specular=True)) for objects with a Principled
material. Per pixel (docs/specular.md):

    out = k_d (diffuse) + scale (S_env(R) E_spec occ + sum_v P_v f(n, v, l_v) n.l_v V_v)

with E_spec the multiple-scattering albedo of the lobe (core.specular.brdf, Fdez-Aguera 2019;
metallic mixes a conductor of F0 = base colour with the dielectric of the IOR's F0), k_d =
(1 - metallic) (1 - E_spec,dielectric), S_env the sky level at the roughness (sky_texture,
looked up at Q^T of Frostbite's dominant direction, linear between the two nearest levels: one
trilinear fetch of sky_texture's 3D texture),
occ the cones' occlusion of core.specular.occlusion from the transfer's bands 0 and 1 (per
vertex; a texel bake's is the full transfer's, per pixel: texel_occlusion), and for each split
light's shadow view its GGX at Karis's representative point of its disc with the widened
alpha' = min(1, alpha + angle / 2) and the (alpha / alpha')^2 normalisation,
times Turquin's compensation 1 + F0 (1 / E_ss - 1), its visibility V_v the shadow maps' one.
"""

import functools

import gpu
import numpy as np

from ...core.sh import analytic, frames
from ...core.specular import occlusion

SKY_SLOT = 3
BRDF_SLOT = 4
OCC_SLOT = 12  # the full transfer's occlusion per vertex (spec_occlusion; 9 colour table, 10 IOR map, 11 texel tiles)
Y0 = 0.28209479177387814
ROUGH_FROM, ROUGH_SPAN = 0.3, 0.3  # cones below roughness 0.3, the full transfer above 0.6
MAX_BAND_ORDER = 32

UBO_SOURCE = (
    "struct PRTSpec { vec4 model[3]; vec4 nrm[3]; vec4 frame[3]; vec4 eye; vec4 sky[3]; vec4 params; "
    "vec4 material; vec4 bands[8]; };\n"
)

# The sky's and the table's lookups (also compiled alone by their test): spec.sky (rows), spec.params.
LOOKUP_GLSL = """
vec3 sky_radiance(vec3 d, float roughness)
{
  // One trilinear fetch: bilinear in the level (x past the wrapped column), linear between levels.
  vec3 q = vec3(dot(spec.sky[0].xyz, d), dot(spec.sky[1].xyz, d), dot(spec.sky[2].xyz, d));
  vec2 uv = vec2(-atan(q.y, q.x) / (2.0 * 3.14159265) + 0.5, atan(q.z, length(q.xy)) / 3.14159265 + 0.5);
  float x = (1.0 + uv.x * spec.params.y) / (spec.params.y + 2.0);
  float z = (roughness * (spec.params.x - 1.0) + 0.5) / spec.params.x;
  return texture(sky_tx, vec3(x, uv.y, z)).rgb;
}

vec2 brdf_ab(float nv, float roughness)
{
  return texture(brdf_tx, vec2(nv, roughness)).rg;  // (bilinear, clamped to the edge)
}
"""

# The solid angle shared by two caps (Mazonka 2012) of half-angle cosines ca, cb whose axes make
# cos g = cg, with the angles' sines as sqrt(1 - c^2) and the containment tests on cosines: g <= |a - b|
# when cg >= cos(a - b) = ca cb + sa sb, g >= a + b when a + b <= pi (ca + cb >= 0) and
# cg <= cos(a + b) = ca cb - sa sb; three acos in all (also compiled alone by its test).
CAP_GLSL = """
float cap_intersection(float ca, float cb, float cg)
{
  ca = clamp(ca, -1.0, 1.0);
  cb = clamp(cb, -1.0, 1.0);
  cg = clamp(cg, -1.0, 1.0);
  float sa = sqrt(1.0 - ca * ca);
  float sb = sqrt(1.0 - cb * cb);
  float sg = max(sqrt(1.0 - cg * cg), 1e-6);
  float smaller = 2.0 * 3.14159265 * (1.0 - max(ca, cb));
  if (cg >= ca * cb + sa * sb) {
    return smaller;
  }
  if (ca + cb >= 0.0 && cg <= ca * cb - sa * sb) {
    return 0.0;
  }
  sa = max(sa, 1e-6);
  sb = max(sb, 1e-6);
  float gap = acos(clamp((cg - ca * cb) / (sa * sb), -1.0, 1.0));
  float x = acos(clamp((cb - cg * ca) / (sg * sa), -1.0, 1.0));
  float y = acos(clamp((ca - cg * cb) / (sg * sb), -1.0, 1.0));
  return clamp(2.0 * (3.14159265 - gap - ca * x - cb * y), 0.0, smaller);
}
"""

_FUNCTIONS = f"""
vec3 spec_n;
vec3 spec_v;
vec3 spec_r;
float spec_nv;
float spec_alpha;
vec3 spec_f0;
vec2 spec_ab;

{LOOKUP_GLSL}
vec3 lobe_albedo(vec3 f0)
{{
  // Fdez-Aguera 2019: single scattering plus the compensated multiple scattering.
  vec3 single = f0 * spec_ab.x + spec_ab.y;
  float e_ms = 1.0 - spec_ab.x - spec_ab.y;
  vec3 f_avg = f0 + (1.0 - f0) / 21.0;
  return single + single * f_avg / (1.0 - e_ms * f_avg) * e_ms;
}}

{CAP_GLSL}
float specular_occlusion()
{{
  float ao = clamp(spec_vis.x / {Y0}, 0.0, 1.0);
  vec3 b = vec3(spec_vis.w, spec_vis.y, spec_vis.z);
  b = vec3(dot(spec.frame[0].xyz, b), dot(spec.frame[1].xyz, b), dot(spec.frame[2].xyz, b));
  float len = length(b);
  b = len > 1e-8 ? b / len : spec_n;
  float cos_s = exp2(-3.32193 * spec_alpha * spec_alpha);
  float open_ = cap_intersection(0.0, cos_s, dot(spec_n, spec_r));
  float cones = open_ <= 1e-7 ? 1.0 : clamp(cap_intersection(sqrt(1.0 - ao), cos_s, dot(b, spec_r)) / open_, 0.0, 1.0);
  // Rough lobes: the lobe-weighted visibility from the full transfer (per vertex), more exact there.
  return mix(cones, clamp(spec_occ, 0.0, 1.0), clamp((spec.material.x - {ROUGH_FROM}) / {ROUGH_SPAN}, 0.0, 1.0));
}}

void spec_setup()
{{
  vec4 p = vec4(spec_pos, 1.0);
  vec3 w = vec3(dot(spec.model[0], p), dot(spec.model[1], p), dot(spec.model[2], p));
  vec3 m = spec_nrm;
  spec_n = normalize(vec3(dot(spec.nrm[0].xyz, m), dot(spec.nrm[1].xyz, m), dot(spec.nrm[2].xyz, m)));
  spec_v = normalize(spec.eye.xyz - w * spec.eye.w);
  spec_nv = clamp(dot(spec_n, spec_v), 1e-4, 1.0);
  spec_r = reflect(-spec_v, spec_n);
  spec_alpha = max(spec.material.x * spec.material.x, 1e-3);
  vec3 base = spec_albedo / max(scale, 1e-20);
  spec_f0 = mix(vec3(spec.material.z), base, spec.material.y);
  spec_ab = brdf_ab(spec_nv, spec.material.x);
}}

vec3 spec_shade(vec3 diffuse, vec3 sun_spec)
{{
  if (spec.material.w <= 0.0) {{
    return diffuse;
  }}
  vec3 dielectric = lobe_albedo(vec3(spec.material.z));
  vec3 e_spec = mix(dielectric, lobe_albedo(spec_albedo / max(scale, 1e-20)), spec.material.y);
  vec3 kd = (1.0 - spec.material.y) * (1.0 - dielectric);
  float s = (1.0 - spec_alpha) * (sqrt(1.0 - spec_alpha) + spec_alpha);  // Frostbite's dominant direction
  vec3 env = sky_radiance(normalize(mix(spec_n, spec_r, s)), spec.material.x);
  return kd * diffuse + scale * (env * e_spec * specular_occlusion() + sun_spec);
}}
"""


_SUN_FUNCTION = """
vec3 sun_specular(int v)
{
  // GGX at the representative point of the view's disc (Karis 2013), widened and normalised.
  vec3 c = suns.dir[v].xyz;
  float angle = atan(suns.params[v].y);
  float cr = dot(c, spec_r);
  vec3 l = c;
  if (cr < cos(angle)) {
    vec3 t = spec_r - cr * c;
    float tl = length(t);
    l = tl > 1e-6 ? normalize(c * cos(angle) + (t / tl) * sin(angle)) : c;
  } else {
    l = spec_r;
  }
  float nl = dot(spec_n, l);
  if (nl <= 0.0) {
    return vec3(0.0);
  }
  float a2 = spec_alpha * spec_alpha;
  float wide = min(1.0, spec_alpha + 0.5 * angle);
  vec3 h = normalize(spec_v + l);
  float nh = max(dot(spec_n, h), 0.0);
  float q = nh * nh * (wide * wide - 1.0) + 1.0;
  float d = wide * wide / (3.14159265 * q * q) * (a2 / (wide * wide));
  float lv = 0.5 * (sqrt(1.0 + a2 * (1.0 / (spec_nv * spec_nv) - 1.0)) - 1.0);
  float ll = 0.5 * (sqrt(1.0 + a2 * (1.0 / (nl * nl) - 1.0)) - 1.0);
  float vis = 1.0 / ((1.0 + lv + ll) * 4.0 * spec_nv * nl);
  vec3 f = spec_f0 + (1.0 - spec_f0) * pow(1.0 - max(dot(spec_v, h), 0.0), 5.0);
  vec3 comp = 1.0 + spec_f0 * (1.0 / max(spec_ab.x + spec_ab.y, 1e-4) - 1.0);
  return 3.14159265 * d * vis * nl * f * comp;  // (suns.power is P / pi)
}

"""


def transfer_vec4(mode):
    """GLSL of the element's first transfer vec4 (bands 0 and 1) in the vertex shader."""
    if mode == "ATTR":
        return "prt_t0"
    return "texelFetch(transfer_tx, ivec2(col, row), 0)"  # (a texel bake's is per pixel: texel_occlusion)


def occlusion_lines(mode, count):
    """GLSL (vertex shader) of spec_occ: core.specular.occlusion.transfer_occlusion at the
    vertex's reflection direction, the real SH basis written out by its recurrences (core.sh.basis:
    Q_mm = (2m - 1)!!, Q_{m+1,m} = (2m + 1) z Q_mm, Q_lm = ((2l - 1) z Q_{l-1,m} - (l + m - 1)
    Q_{l-2,m}) / (l - m); y_lm = K_lm Q_lm Re/Im (x + i y)^m), the open transfer's part by the
    addition theorem: sum_l k_l z_l sqrt((2l + 1) / 4 pi) P_l(n.R)."""
    order = min(int(np.floor(np.sqrt(4 * count))), MAX_BAND_ORDER)
    if mode == "ATTR":
        coeff = lambda i: f"prt_t{i // 4}[{i % 4}]"
        lines = []
    else:
        coeff = lambda i: f"q{i // 4}[{i % 4}]"
        lines = [
            f"  vec4 q{k} = texelFetch(transfer_tx, ivec2(col + {k}, row), 0);" for k in range(-(-order * order // 4))
        ]
    lines += [
        "  vec4 sp = vec4(prt_pos, 1.0);",
        "  vec3 sw = vec3(dot(spec.model[0], sp), dot(spec.model[1], sp), dot(spec.model[2], sp));",
        "  vec3 sn = normalize(vec3(dot(spec.nrm[0].xyz, prt_nrm), dot(spec.nrm[1].xyz, prt_nrm), "
        "dot(spec.nrm[2].xyz, prt_nrm)));",
        "  vec3 sr = reflect(-normalize(spec.eye.xyz - sw * spec.eye.w), sn);",
        "  vec3 d = spec.frame[0].xyz * sr.x + spec.frame[1].xyz * sr.y + spec.frame[2].xyz * sr.z;",
        "  float seen = 0.0;",
        "  float c0 = 1.0;",
        "  float s0 = 0.0;",
    ]
    zonal = analytic.clamped_cosine_zonal(order)
    band = lambda l: f"spec.bands[{l // 4}][{l % 4}]"
    for m in range(order):
        if m > 0:
            lines.append(f"  float c{m} = d.x * c{m - 1} - d.y * s{m - 1};")
            lines.append(f"  float s{m} = d.x * s{m - 1} + d.y * c{m - 1};")
        double_factorial = float(np.prod(np.arange(2 * m - 1, 0, -2))) if m > 0 else 1.0
        for l in range(m, order):
            if l == m:
                q = f"{float(double_factorial)!r}"
            elif l == m + 1:
                q = f"{2 * m + 1}.0 * d.z * Q{l - 1}_{m}"
            else:
                q = f"({2 * l - 1}.0 * d.z * Q{l - 1}_{m} - {l + m - 1}.0 * Q{l - 2}_{m}) / {l - m}.0"
            lines.append(f"  float Q{l}_{m} = {q};")
            k = np.sqrt((2 * l + 1) / (4 * np.pi) / np.prod(np.arange(l - m + 1, l + m + 1, dtype=np.float64)))
            if m == 0:
                lines.append(f"  seen += {band(l)} * {coeff(l * l + l)} * ({float(k)!r} * Q{l}_0);")
            else:
                k *= np.sqrt(2.0)
                lines.append(
                    f"  seen += {band(l)} * ({float(k)!r} * Q{l}_{m}) * ({coeff(l * l + l + m)} * c{m} + "
                    f"{coeff(l * l + l - m)} * s{m});"
                )
    lines += ["  float mu = dot(sn, sr);", "  float p0 = 1.0;", "  float p1 = mu;"]
    open_terms = [f"{band(0)} * {float(zonal[0] * np.sqrt(1 / (4 * np.pi)))!r}"]
    if order > 1:
        open_terms.append(f"{band(1)} * {float(zonal[1] * np.sqrt(3 / (4 * np.pi)))!r} * mu")
    for l in range(2, order):
        lines.append(f"  float p{l} = ({2 * l - 1}.0 * mu * p{l - 1} - {l - 1}.0 * p{l - 2}) / {l}.0;")
        if zonal[l] != 0.0:
            open_terms.append(f"{band(l)} * {float(zonal[l] * np.sqrt((2 * l + 1) / (4 * np.pi)))!r} * p{l}")
    lines.append("  float open_ = " + " + ".join(open_terms) + ";")
    lines.append("  spec_occ = open_ > 1e-8 ? seen / open_ : 1.0;")
    return "\n".join(lines) + "\n"


# The frame's vertex shader: its vertex's texel of the occlusion drawn by spec_occlusion's pass.
# (2^OCC_WIDTH_BITS texels a row: shifts, where an integer division is lane by lane on llvmpipe)
OCC_WIDTH_BITS = 12
OCCLUSION_READ = (
    f"  spec_occ = texelFetch(occ_tx, ivec2(gl_VertexID & {(1 << OCC_WIDTH_BITS) - 1}, "
    f"gl_VertexID >> {OCC_WIDTH_BITS}), 0).r;\n"
)

# With split lights the sun shader's own varyings hold the same position, normal and albedo.
_SUN_VARYINGS = "#define spec_pos local_pos\n#define spec_nrm local_nrm\n#define spec_albedo surface_albedo\n"


def add_specular(info, vertex, fragment, mode, nrm_index, has_suns, count=1, inline=False):
    """Declare the specular inputs on `info`; -> (vertex, fragment) sources. nrm_index: the
    attribute slot of prt_nrm (declared here unless the suns declared it). A vertex or corner
    bake reads its full-transfer occlusion from occ_tx (spec_occlusion), or with `inline` sums it
    in the vertex shader (while the view moves)."""
    info.uniform_buf(2, "PRTSpec", "spec")
    info.sampler(SKY_SLOT, "FLOAT_3D", "sky_tx")
    info.sampler(BRDF_SLOT, "FLOAT_2D", "brdf_tx")
    inline = inline or mode == "TEXEL"
    if not inline:
        info.sampler(OCC_SLOT, "FLOAT_2D", "occ_tx")
    if not has_suns:
        info.vertex_in(nrm_index, "VEC3", "prt_nrm")
    iface = gpu.types.GPUStageInterfaceInfo("prt_spec_iface")
    own = "" if has_suns else "  spec_pos = prt_pos;\n  spec_nrm = prt_nrm;\n"
    if not has_suns:
        iface.smooth("VEC3", "spec_pos")
        iface.smooth("VEC3", "spec_nrm")
        iface.smooth("VEC3", "spec_albedo")
        own += "  spec_albedo = prt_albedo.rgb * tint.rgb * scale;\n"
    occluded = ""
    if mode != "TEXEL":  # (a texel bake reads them per pixel: texel_occlusion)
        iface.smooth("VEC4", "spec_vis")
        iface.smooth("FLOAT", "spec_occ")
        occ = occlusion_lines(mode, count) if inline else OCCLUSION_READ
        occluded = f"  spec_vis = {transfer_vec4(mode)};\n{occ}"
    if not (has_suns and mode == "TEXEL"):  # (else it has no member: an empty block does not compile)
        info.vertex_out(iface)
    vertex = vertex.replace("  gl_Position = mvp", f"{own}{occluded}  gl_Position = mvp", 1)
    main = "void main()\n{\n"
    assert main in fragment and "FragColor = vec4(display_transform(" in fragment
    fragment = fragment.replace(
        main, main + "  spec_setup();\n" + ("" if has_suns else "  vec3 sun_spec = vec3(0.0);\n"), 1
    )
    head, tail = fragment.split("FragColor = vec4(display_transform(", 1)
    expr, rest = tail.rsplit("), 1.0);", 1)
    fragment = head + f"FragColor = vec4(display_transform(spec_shade({expr}, sun_spec)), 1.0);" + rest
    return vertex, (_SUN_VARYINGS if has_suns else "") + _FUNCTIONS + (_SUN_FUNCTION if has_suns else "") + fragment


def spec_ubo_bytes(matrix_world, frame, eye, sky_rows, sky, material):
    """std140 bytes of PRTSpec: the object's local -> world rows, normal matrix, the transfer
    frame's rotation (local SH -> world, core.sh.frames), the eye (world, homogeneous: w 0 for
    an orthographic view), the world -> sky image rows, (levels, width, height, 0), and the
    slot's (roughness, metallic, dielectric F0, 1) (principled_specular; 0 in w: diffuse only)."""
    mw = np.asarray(matrix_world, dtype=np.float64)
    data = np.zeros((23, 4))
    data[0:3] = mw[:3]
    data[3:6, :3] = np.linalg.inv(mw[:3, :3]).T
    data[6:9, :3] = frame
    data[9] = eye
    data[10:13, :3] = sky_rows
    data[13, :3] = (sky.levels, sky.width, sky.height)
    data[14] = material
    data[15:23] = _bands(material[0]).reshape(8, 4)
    return data.astype(np.float32).tobytes()


@functools.lru_cache(maxsize=64)
def _bands(roughness):
    """(32,) k_l of the slot's lobe (core.specular.occlusion.lobe_bands), for every order."""
    return occlusion.lobe_bands(float(max(roughness * roughness, 1e-3)), MAX_BAND_ORDER)


def eye_point(view_projection):
    """(4,) the eye in world space, homogeneous: the clip-space point (0, 0, -1, 0) taken back
    (the camera's position for a perspective view, w > 0; the direction toward the viewer, w = 0,
    for an orthographic one)."""
    e = np.linalg.solve(np.asarray(view_projection, dtype=np.float64), np.array([0.0, 0.0, -1.0, 0.0]))
    if abs(e[3]) > 1e-12:
        return e / e[3]
    return e / max(np.linalg.norm(e[:3]), 1e-30)


def bind_textures(shader, spec_frame):
    """Bind the sky and table textures; spec_frame: (eye, sky rows, sky_texture.SkyTexture, the
    table's texture) of this redraw."""
    _eye, _rows, sky, table = spec_frame
    shader.uniform_sampler("sky_tx", sky.texture)
    shader.uniform_sampler("brdf_tx", table)


def slot_ubo(state, slot, matrix_world, spec_frame, params, extra=b""):
    """Material slot `slot`'s PRTSpec block (one uniform buffer per object and slot, updated
    when it changed); params: principled_specular's triple or None (diffuse only); extra: bytes
    of the members after the block's own (material_maps)."""
    eye, rows, sky, _table = spec_frame
    r, mirrored = frames.frame_rotation(np.asarray(matrix_world, dtype=np.float64)[:3, :3])
    material = (0.5, 0.0, 0.04, 0.0) if params is None else (*params, 1.0)
    data = spec_ubo_bytes(matrix_world, -r if mirrored else r, eye, rows, sky, material) + extra
    if state.spec_ubo is None:
        state.spec_ubo, state.spec_bytes = {}, {}
    ubo = state.spec_ubo.get(slot)
    if ubo is not None and len(state.spec_bytes.get(slot, b"")) != len(data):
        ubo = None  # (the slot gained or lost its maps: another size)
    if ubo is None:
        ubo = state.spec_ubo[slot] = gpu.types.GPUUniformBuf(data)
    elif state.spec_bytes.get(slot) != data:
        ubo.update(data)
    state.spec_bytes[slot] = data
    return ubo
