// Principled specular in the PRT material: the file's residual sky levels and split-sum table, the GLSL of Blender's display's.
//
// The port of prt_addon/blender/display/shader_specular.py (docs/specular.md): per pixel
//   out = k_d diffuse + scale (S(R) E_spec occ + sum_v P_v f_GGX(n, v, l_v) n.l_v V_v share_v)
// with S the sky level at the roughness (the file's GGX-prefiltered residual sky, in its image
// frame: looked up at rows * d, rows the file's glTF -> image rows times the lighting turn's
// inverse) at Frostbite's dominant direction, E_spec the multiple-scattering albedo from the
// split-sum table, occ the specular occlusion from the transfer (the cones of bands 0 and 1 below
// roughness 0.3, the lobe-weighted visibility of the full transfer above 0.6, per vertex:
// occlusion.js; a texel bake's full transfer at every roughness, per pixel: texel_occlusion.js), the
// split lights' GGX at the representative point of each view's disc with its shadow map's
// visibility, each view weighted by its share of its light's power.
import * as THREE from 'three';

const Y0 = 0.28209479177387814;
const ROUGH_FROM = 0.3;
const ROUGH_SPAN = 0.3;
export const BAND_COUNT = 32;

// The levels (half RGB, level k's rows above level k - 1's) as one half RGBA 2D texture, each
// level's rows with its last texel copied before its first and its first after its last, and its
// first and last rows copied below and above it: one clamp-to-edge bilinear fetch per level then
// wraps in longitude and clamps in latitude within its level (two 2D fetches cost less than one 3D
// trilinear fetch in SwiftShader).
function wrappedLevels(bytes, levels, width, height) {
  const rgb = new Uint16Array(bytes.buffer, bytes.byteOffset, levels * width * height * 3);
  const [w, h] = [width + 2, height + 2];
  const out = new Uint16Array(levels * h * w * 4);
  for (let row = 0; row < levels * h; row++) {
    const level = Math.floor(row / h);
    const source = level * height + Math.min(Math.max((row % h) - 1, 0), height - 1);
    for (let x = 0; x < w; x++) {
      const i = 3 * (source * width + ((x + width - 1) % width));
      const o = 4 * (row * w + x);
      out[o] = rgb[i];
      out[o + 1] = rgb[i + 1];
      out[o + 2] = rgb[i + 2];
      out[o + 3] = 0x3c00; // 1.0
    }
  }
  return filtered(new THREE.DataTexture(out, w, levels * h, THREE.RGBAFormat, THREE.HalfFloatType));
}

function filtered(texture) {
  texture.minFilter = texture.magFilter = THREE.LinearFilter;
  texture.generateMipmaps = false;
  texture.unpackAlignment = 1;
  texture.needsUpdate = true;
  return texture;
}

/** The file's specular data (the scene extras' `specular`, docs/export.md) as textures: the sky
 * levels (one 2D texture, wrappedLevels), the table (RG), the rows; null without. */
export async function loadSpecular(parser, block) {
  if (!block || !block.sky || !block.brdf || !Array.isArray(block.sky_rows)) return null;
  const { levels, width, height } = block.sky;
  const sky = await parser.getDependency('bufferView', block.sky.bufferView);
  const table = await parser.getDependency('bufferView', block.brdf.bufferView);
  const texels = levels * width * height;
  if (sky.byteLength < texels * 6) throw new Error('the specular sky is truncated');
  const size = block.brdf.size;
  if (table.byteLength < size * size * 8) throw new Error('the split-sum table is truncated');
  // The table as half floats: WebGL2 filters those everywhere (32-bit floats need an extension).
  const rg = new Float32Array(table.slice(0, size * size * 8));
  const rgba = new Uint16Array(size * size * 4);
  for (let i = 0; i < size * size; i++) {
    rgba[4 * i] = THREE.DataUtils.toHalfFloat(rg[2 * i]);
    rgba[4 * i + 1] = THREE.DataUtils.toHalfFloat(rg[2 * i + 1]);
  }
  return {
    sky: wrappedLevels(new Uint8Array(sky), levels, width, height),
    table: filtered(new THREE.DataTexture(rgba, size, size, THREE.RGBAFormat, THREE.HalfFloatType)),
    levels,
    width,
    height,
    rows: block.sky_rows.flat().map(Number),
  };
}

const WRAPS = { REPEAT: THREE.RepeatWrapping, MIRROR: THREE.MirroredRepeatWrapping };

/** The per-pixel dielectric F0 of a material whose Specular IOR Level or IOR Blender reads from an
 * image (its extras' `f0_map`, docs/export.md: float16 texels, row 0 at v = 0) as a red half-float
 * texture on its TEXCOORD (`channel`), filtered and wrapped as the image's node samples it (Clip
 * as Extend); null without. */
export async function loadF0Map(parser, block) {
  if (!block) return null;
  const { width, height } = block;
  const data = await parser.getDependency('bufferView', block.bufferView);
  if (block.format !== 'float16_r' || !(width > 0 && height > 0) || data.byteLength < width * height * 2)
    throw new Error('the dielectric F0 map is not float16 texels of its size');
  const texels = new Uint16Array(data.slice(0, width * height * 2));
  const texture = new THREE.DataTexture(texels, width, height, THREE.RedFormat, THREE.HalfFloatType);
  texture.minFilter = texture.magFilter = block.interpolation === 'CLOSEST' ? THREE.NearestFilter : THREE.LinearFilter;
  texture.wrapS = texture.wrapT = WRAPS[block.extension] ?? THREE.ClampToEdgeWrapping;
  texture.generateMipmaps = false;
  texture.unpackAlignment = 2;
  texture.channel = Number(block.texCoord) || 0;
  texture.needsUpdate = true;
  return texture;
}

/** A material's constants (its PRT_lighting extras) or null: {roughness, metallic, f0, bands, open,
 * maps: the inputs Blender reads from an image ('roughness', 'metallic'), f0Block: the extras'
 * `f0_map` when its Specular IOR Level or IOR comes from an image (loadF0Map makes it f0Map), and
 * with either range (the roughness image's smallest and largest value), bands2 and open2 (the lobe
 * at the largest; bands and open are at the smallest)}. */
export function readMaterial(extras) {
  if (!extras || !Array.isArray(extras.lobe_bands) || !Array.isArray(extras.lobe_open)) return null;
  const vec4s = (values) =>
    Array.from(
      { length: BAND_COUNT / 4 },
      (_v, k) => new THREE.Vector4(...[0, 1, 2, 3].map((j) => Number(values[4 * k + j] || 0))),
    );
  const maps = Array.isArray(extras.maps) ? extras.maps.filter((m) => m === 'roughness' || m === 'metallic') : [];
  const f0Block = extras.f0_map && typeof extras.f0_map === 'object' ? extras.f0_map : null;
  const paired =
    Boolean(maps.length || f0Block) && Array.isArray(extras.lobe_bands2) && Array.isArray(extras.lobe_open2);
  const range = Array.isArray(extras.roughness_range) ? extras.roughness_range.map(Number) : [0, 0];
  return {
    roughness: Number(extras.roughness),
    metallic: Number(extras.metallic),
    f0: Number(extras.f0),
    bands: vec4s(extras.lobe_bands),
    open: vec4s(extras.lobe_open),
    maps: paired ? maps : [],
    f0Block: paired ? f0Block : null,
    f0Map: null,
    range: new THREE.Vector2(range[0] || 0, range[1] || 0),
    bands2: paired ? vec4s(extras.lobe_bands2) : null,
    open2: paired ? vec4s(extras.lobe_open2) : null,
  };
}

/** Vertex GLSL: the first transfer vec4 (bands 0 and 1) and the full transfer's occlusion at the
 * vertex's reflection direction, read from the occlusion pass's texture (occlusion.js) at the
 * vertex; a source without decoded values at the vertex (packed, texel) is open. `paired`: the
 * second lobe's occlusion too (prtSpecOcc2, the texture's second channel), as Blender's
 * display/material_maps.py: the two are mixed per pixel by the roughness between the image's range. */
export function specularVertex(source, paired = false) {
  const decoded = source.kind === 'texture';
  if (source.stage === 'texel')
    return 'uniform mat3 nrmMatrix;\nvarying vec3 prtSpecPos;\nvarying vec3 prtSpecNrm;\nvoid prtSpecularVertex(vec3 wp) {\n  prtSpecPos = wp;\n  prtSpecNrm = nrmMatrix * normal;\n}'; // (its occlusion per pixel: texel_occlusion.js)
  const lines = [
    'uniform mat3 nrmMatrix;',
    decoded ? 'uniform sampler2D prtOcclusionTx;' : '',
    'varying vec3 prtSpecPos;',
    'varying vec3 prtSpecNrm;',
    'varying vec4 prtSpecVis;',
    'varying float prtSpecOcc;',
    paired ? 'varying float prtSpecOcc2;' : '',
    'void prtSpecularVertex(vec3 wp) {',
    '  prtSpecPos = wp;',
    '  prtSpecNrm = nrmMatrix * normal;',
  ];
  if (!decoded)
    lines.push(
      `  prtSpecVis = vec4(${Y0}, 0.0, 0.0, 0.0);`,
      '  prtSpecOcc = 1.0;',
      paired ? '  prtSpecOcc2 = 1.0;' : '',
      '}',
    );
  else
    lines.push(
      `  prtSpecVis = ${source.fetch(0)};`,
      '  vec4 occlusion = texelFetch(prtOcclusionTx, ivec2(gl_VertexID % prtPerRow, gl_VertexID / prtPerRow), 0);',
      '  prtSpecOcc = occlusion.r;',
      paired ? '  prtSpecOcc2 = occlusion.g;' : '',
      '}',
    );
  return lines.join('\n');
}

/** SPECULAR_FRAGMENT with the roughness, metallic and dielectric F0 per pixel (prtRoughness,
 * prtMetallic, prtF0d, set before prtSpecularSetup) and the two lobes' occlusion mixed by the roughness. */
export function mappedFragment() {
  const occ = 'clamp(prtSpecOcc, 0.0, 1.0)';
  return (
    'float prtRoughness;\nfloat prtMetallic;\nfloat prtF0d;\nuniform vec2 prtRoughRange;\nvarying float prtSpecOcc2;\n' +
    SPECULAR_FRAGMENT.replace(
      occ,
      'clamp(mix(prtSpecOcc, prtSpecOcc2, clamp((prtRoughness - prtRoughRange.x) / max(prtRoughRange.y - prtRoughRange.x, 1e-6), 0.0, 1.0)), 0.0, 1.0)',
    )
      .replace(/prtSurface\.x/g, 'prtRoughness')
      .replace(/prtSurface\.y/g, 'prtMetallic')
      .replace(/prtSurface\.z/g, 'prtF0d')
  );
}

// Per pixel the glossy material's roughness and metallic: its maps' G and B times the glTF
// factors (three.js's roughness and metalness), or the file's constants; its dielectric F0 the
// F0 map's red, or the file's constant.
export function surfaceSpecular(surface) {
  const lines = [];
  if (surface.f0Map) lines.push('uniform sampler2D prtF0Map;', 'varying vec2 prtF0Uv;');
  if (surface.roughMap)
    lines.push('uniform sampler2D prtRoughMap;', 'uniform float prtRoughFactor;', 'varying vec2 prtRoughUv;');
  if (surface.metalMap)
    lines.push('uniform sampler2D prtMetalMap;', 'uniform float prtMetalFactor;', 'varying vec2 prtMetalUv;');
  lines.push('void prtSurfaceInputs() {');
  lines.push(
    surface.roughMap
      ? '  prtRoughness = clamp(prtRoughFactor * texture2D(prtRoughMap, prtRoughUv).g, 0.0, 1.0);'
      : '  prtRoughness = prtSurface.x;',
  );
  lines.push(
    surface.metalMap
      ? '  prtMetallic = clamp(prtMetalFactor * texture2D(prtMetalMap, prtMetalUv).b, 0.0, 1.0);'
      : '  prtMetallic = prtSurface.y;',
  );
  lines.push(surface.f0Map ? '  prtF0d = texture2D(prtF0Map, prtF0Uv).r;' : '  prtF0d = prtSurface.z;');
  lines.push('}');
  return lines.join('\n');
}

/** Fragment GLSL: the sky, the table, the lobe's albedo, the occlusion, the shading (spec_shade). */
export const SPECULAR_FRAGMENT = `
uniform sampler2D prtSkyTx;
uniform sampler2D prtBrdfTx;
uniform mat3 prtSkyRows;
uniform vec3 prtSkySize;
uniform vec4 prtSurface;
uniform mat3 prtFrame;
varying vec3 prtSpecPos;
varying vec3 prtSpecNrm;
varying vec4 prtSpecVis;
varying float prtSpecOcc;
vec3 spec_n;
vec3 spec_v;
vec3 spec_r;
float spec_nv;
float spec_alpha;
vec3 spec_f0;
vec2 spec_ab;

vec3 skyRadiance(vec3 d, float roughness) {
  // Bilinear in the two nearest levels (x past the wrapped column, y past the level's copied row), then linear between them.
  vec3 q = prtSkyRows * d;
  vec2 uv = vec2(-atan(q.y, q.x) / (2.0 * 3.14159265) + 0.5, atan(q.z, length(q.xy)) / 3.14159265 + 0.5);
  float x = (1.0 + uv.x * prtSkySize.y) / (prtSkySize.y + 2.0);
  float rows = prtSkySize.z + 2.0;
  float y = 1.0 + uv.y * prtSkySize.z;
  float level = roughness * (prtSkySize.x - 1.0);
  float l0 = floor(level);
  float l1 = min(l0 + 1.0, prtSkySize.x - 1.0);
  vec3 a = texture(prtSkyTx, vec2(x, (l0 * rows + y) / (prtSkySize.x * rows))).rgb;
  vec3 b = texture(prtSkyTx, vec2(x, (l1 * rows + y) / (prtSkySize.x * rows))).rgb;
  return mix(a, b, level - l0);
}

vec2 brdfAB(float nv, float roughness) {
  return texture(prtBrdfTx, vec2(nv, roughness)).rg; // (bilinear, clamped to the edge)
}

vec3 lobeAlbedo(vec3 f0) {
  // Fdez-Aguera 2019: single scattering plus the compensated multiple scattering.
  vec3 single = f0 * spec_ab.x + spec_ab.y;
  float e_ms = 1.0 - spec_ab.x - spec_ab.y;
  vec3 f_avg = f0 + (1.0 - f0) / 21.0;
  return single + single * f_avg / (1.0 - e_ms * f_avg) * e_ms;
}

// The caps' shared solid angle (Mazonka 2012), the containment tests on cosines: shader_specular.py's CAP_GLSL.
float capIntersection(float ca, float cb, float cg) {
  ca = clamp(ca, -1.0, 1.0);
  cb = clamp(cb, -1.0, 1.0);
  cg = clamp(cg, -1.0, 1.0);
  float sa = sqrt(1.0 - ca * ca);
  float sb = sqrt(1.0 - cb * cb);
  float sg = max(sqrt(1.0 - cg * cg), 1e-6);
  float smaller = 2.0 * 3.14159265 * (1.0 - max(ca, cb));
  if (cg >= ca * cb + sa * sb) return smaller;
  if (ca + cb >= 0.0 && cg <= ca * cb - sa * sb) return 0.0;
  sa = max(sa, 1e-6);
  sb = max(sb, 1e-6);
  float gap = acos(clamp((cg - ca * cb) / (sa * sb), -1.0, 1.0));
  float x = acos(clamp((cb - cg * ca) / (sg * sa), -1.0, 1.0));
  float y = acos(clamp((ca - cg * cb) / (sg * sb), -1.0, 1.0));
  return clamp(2.0 * (3.14159265 - gap - ca * x - cb * y), 0.0, smaller);
}

float specularOcclusion() {
  float ao = clamp(prtSpecVis.x / ${Y0}, 0.0, 1.0);
  vec3 b = prtFrame * vec3(prtSpecVis.w, prtSpecVis.y, prtSpecVis.z);
  float len = length(b);
  b = len > 1e-8 ? b / len : spec_n;
  float cos_s = exp2(-3.32193 * spec_alpha * spec_alpha);
  float open_ = capIntersection(0.0, cos_s, dot(spec_n, spec_r));
  float cones = open_ <= 1e-7 ? 1.0 : clamp(capIntersection(sqrt(1.0 - ao), cos_s, dot(b, spec_r)) / open_, 0.0, 1.0);
  return mix(cones, clamp(prtSpecOcc, 0.0, 1.0), clamp((prtSurface.x - ${ROUGH_FROM}) / ${ROUGH_SPAN}, 0.0, 1.0));
}

void prtSpecularSetup(vec3 base) {
  spec_n = normalize(prtSpecNrm);
  spec_v = isOrthographic ? vec3(viewMatrix[0][2], viewMatrix[1][2], viewMatrix[2][2]) : normalize(cameraPosition - prtSpecPos);
  spec_nv = clamp(dot(spec_n, spec_v), 1e-4, 1.0);
  spec_r = reflect(-spec_v, spec_n);
  spec_alpha = max(prtSurface.x * prtSurface.x, 1e-3);
  spec_f0 = mix(vec3(prtSurface.z), base, prtSurface.y);
  spec_ab = brdfAB(spec_nv, prtSurface.x);
}

vec3 prtSpecularShade(vec3 diffuse, vec3 sunSpec, vec3 base, float scale) {
  vec3 dielectric = lobeAlbedo(vec3(prtSurface.z));
  vec3 e_spec = mix(dielectric, lobeAlbedo(base), prtSurface.y);
  vec3 kd = (1.0 - prtSurface.y) * (1.0 - dielectric);
  float s = (1.0 - spec_alpha) * (sqrt(1.0 - spec_alpha) + spec_alpha);  // Frostbite's dominant direction
  vec3 env = skyRadiance(normalize(mix(spec_n, spec_r, s)), prtSurface.x);
  return kd * diffuse + scale * (env * e_spec * specularOcclusion() + sunSpec);
}

// GGX at the representative point of a view's disc (Karis 2013), widened and normalised; times
// pi (the lights' power uniform is P / pi).
vec3 sunSpecular(vec3 c, float angle) {
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
  if (nl <= 0.0) return vec3(0.0);
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
  return 3.14159265 * d * vis * nl * f * comp;
}
`;

/** The material's specular uniforms (sky, table and rows shared, the surface's own). */
export function specularUniforms(shared, surface) {
  return {
    prtSkyTx: shared.skyTx,
    prtBrdfTx: shared.brdfTx,
    prtSkyRows: shared.skyRows,
    prtSkySize: shared.skySize,
    prtSurface: { value: new THREE.Vector4(surface.roughness, surface.metallic, surface.f0, 1.0) },
    prtFrame: { value: new THREE.Matrix3() },
    prtBands: { value: surface.bands },
    prtOpen: { value: surface.open },
    ...(surface.bands2
      ? {
          prtBands2: { value: surface.bands2 },
          prtOpen2: { value: surface.open2 },
          prtRoughRange: { value: surface.range },
        }
      : {}),
    prtOcclusionTx: { value: null }, // (occlusion.js's texture, for a source decoded at the vertex)
    prtTilesTx: { value: null }, // (a texel bake's decoded tiles: texel_occlusion.js)
  };
}
