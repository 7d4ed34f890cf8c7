// The PRT material: per-vertex (or per-texel) max(0, sum_i L_i t_i) x albedo, plus the split lights per pixel, times the base colour map per pixel.
//
// The same shading as Blender's display (prt_addon/blender/display/shader.py, shader_suns.py):
// the transfer comes from a transfer source (transfer_source.js: fetch(k), the k-th vec4 from
// packed integer attributes or a texture read at gl_VertexID), the light is a uniform array of 3 * count vec4s
// (light[ch * count + k] = L_{4k..4k+3} of channel ch, in the node's local frame). The split
// lights add albedo * sum_v P_v/pi * C_v * V_v per pixel over their shadow views (shadows.js):
// C_v = sum_j w_j max(0, n.s_j) over the view's samples, V_v PCSS on the view's map over
// Vogel-disc taps, the same filter as Blender's (other tap counts for a wide light's views). Output is
// linear radiance times exposureScale (2^stops), then three.js's own tone mapping and output
// colour space (renderer.toneMapping, outputColorSpace; none when drawing into a render target):
// NoToneMapping and sRGB output is Blender's "Standard" view.
import * as THREE from 'three';
import {
  BLOCKER_TAPS,
  CONTACT_SHIFT,
  MAX_RADIUS,
  MAX_SLOPE,
  MIN_COSINE,
  PCF_TAPS,
  WIDE_BLOCKER_TAPS,
  WIDE_FIRST_TAPS,
  WIDE_MAX_RADIUS,
  WIDE_PCF_TAPS,
} from './shadows.js';
import { SPECULAR_FRAGMENT, mappedFragment, specularUniforms, specularVertex, surfaceSpecular } from './specular.js';
import { TEXEL_LOOKUP } from './relight.js';
import { texelOcclusionFragment, texelSpecular } from './texel_occlusion.js';

// The sum unrolled (k constant, so a source's fetch(k) can name an attribute). A bounced bake
// (Blender's bake.md, "Interreflection") has `channels` more blocks of `count` vec4s after the
// direct one, lit by bounceLight: the sky plus the split lights' SH. lightConstant and
// bounceConstant are the parts of the sums a source folds out of the transfer (its decoding's
// offsets, transfer_source.js; 0 for the texture source).
function transferSum(count, channels, source) {
  const lines = [];
  const block = [0, 1, 2].map((c) => count * (1 + (channels === 3 ? c : 0)));
  for (let k = 0; k < count; k++) {
    lines.push(`  t = ${source.fetch(k)};`);
    lines.push(`  r += vec3(dot(t, light[${k}]), dot(t, light[${count + k}]), dot(t, light[${2 * count + k}]));`);
    if (!channels) continue;
    const b = block.map((first) => (channels === 3 ? source.fetch(first + k) : 't1'));
    if (channels === 1) lines.push(`  t1 = ${source.fetch(block[0] + k)};`);
    lines.push(
      `  r += vec3(dot(${b[0]}, bounceLight[${k}]), dot(${b[1]}, bounceLight[${count + k}]), dot(${b[2]}, bounceLight[${2 * count + k}]));`,
    );
  }
  return lines.join('\n');
}

// The radiance of a vertex: the sum here, or (a relit source, relight.js) read from the texture
// the sum was drawn into once per lighting change; a texel source's is read per pixel instead.
function vertexRadiance(count, channels, source) {
  if (source.stage === 'texel') return `  prtUv = ${source.uvAttribute};`;
  if (source.radianceVertex) return `  radiance = ${source.radianceVertex} * albedo * scale;`;
  return `  vec3 r = lightConstant${channels ? ' + bounceConstant' : ''};
  vec4 t;
  ${channels === 1 ? 'vec4 t1;' : ''}
${transferSum(count, channels, source)}
  radiance = max(r, vec3(0.0)) * albedo * scale;`;
}

// The source material's base colour per pixel, as MeshStandardMaterial takes it: its map (on the
// map's UV channel, through its texture transform; an sRGB map decoded by the GPU as three.js
// uploads it) and its vertex colours, multiplying the diffuse and the split lights' light.
// The glossy material's roughness and metalness maps (three.js's convention for glTF's
// metallicRoughnessTexture: roughness in G, metalness in B), each on its own UV channel and transform,
// and the file's dielectric F0 map (specular.js's loadF0Map) on its TEXCOORD.
const SURFACE_MAPS = [
  ['map', 'prtMap'],
  ['roughMap', 'prtRough'],
  ['metalMap', 'prtMetal'],
  ['f0Map', 'prtF0'],
];

function surfaceVertex(surface, source) {
  const lines = [];
  const declared = new Set(['uv', source.uvAttribute]);
  for (const [key, name] of SURFACE_MAPS) {
    if (!surface[key]) continue;
    const channel = surface[key].channel || 0;
    const uv = channel ? `uv${channel}` : 'uv';
    if (!declared.has(uv)) lines.push(`attribute vec2 ${uv};`);
    declared.add(uv);
    lines.push(`uniform mat3 ${name}Transform;`, `varying vec2 ${name}Uv;`);
    lines.push(`#define ${name.toUpperCase()}_UV (${name}Transform * vec3(${uv}, 1.0)).xy`);
  }
  if (surface.vertexColors) lines.push('attribute vec3 color;', 'varying vec3 prtVertexColor;');
  return lines.join('\n');
}

function surfaceUvs(surface) {
  return SURFACE_MAPS.filter(([key]) => surface[key])
    .map(([, name]) => `  ${name}Uv = ${name.toUpperCase()}_UV;`)
    .join('\n');
}

function surfaceFragment(surface) {
  const lines = [];
  if (surface.map) lines.push('uniform sampler2D prtMap;', 'varying vec2 prtMapUv;');
  if (surface.vertexColors) lines.push('varying vec3 prtVertexColor;');
  lines.push('vec3 prtBaseColor() {', '  vec3 c = vec3(1.0);');
  if (surface.map) lines.push('  c *= texture2D(prtMap, prtMapUv).rgb;');
  if (surface.vertexColors) lines.push('  c *= prtVertexColor;');
  lines.push('  return c;', '}');
  return lines.join('\n');
}

const VERTEX = (count, views, channels, source, surface, glossy, contact) => `
${source.glsl}
${glossy ? specularVertex(source, surface.paired) : ''}
${source.stage === 'texel' ? `attribute vec2 ${source.uvAttribute};\nvarying vec2 prtUv;` : ''}
${surfaceVertex(surface, source)}
${source.radianceVertex ? 'uniform sampler2D prtRadianceTx;' : ''}
uniform vec4 light[${3 * count}];
uniform vec3 lightConstant;
${channels ? `uniform vec4 bounceLight[${3 * count}];\nuniform vec3 bounceConstant;` : ''}
uniform vec3 albedo;
uniform float scale;
varying vec3 radiance;
${views ? 'varying vec3 surfaceAlbedo;\nvarying vec3 worldPos;\nvarying vec3 localNrm;' : ''}
${views && contact ? 'attribute vec3 prtContact;\nvarying vec3 localTan;' : ''}
void main() {
${vertexRadiance(count, channels, source)}
${surfaceUvs(surface)}
${surface.vertexColors ? '  prtVertexColor = color;' : ''}
  vec4 wp = modelMatrix * vec4(position, 1.0);
${glossy ? '  prtSpecularVertex(wp.xyz);' : ''}
${views ? '  surfaceAlbedo = albedo * scale;\n  worldPos = wp.xyz;\n  localNrm = normal;' : ''}
${views && contact ? '  localTan = prtContact;' : ''}
  gl_Position = projectionMatrix * viewMatrix * wp;
}
`;

// Blender's view_cosine and view_visibility (shader_suns.py) for `views` views holding `samples`
// samples in all, on maps that store depth > 0, and 0 where empty. Per view v: sunRows[3v..3v+2]
// world -> (texel x, texel y, depth), sunDir its direction, sunPower P/pi of its light, sunParams
// (texel size, tan filter angle, resolution), sunRange (first sample, sample count, layer, wide).
const SUN_FUNCTIONS = (views, samples, contact) => `
uniform vec4 sunRows[${3 * views}];
uniform vec4 sunDir[${views}];
uniform vec4 sunPower[${views}];
uniform vec4 sunParams[${views}];
uniform vec4 sunRange[${views}];
uniform vec4 sunSamples[${samples}];
uniform sampler2DArray sharpMaps;
uniform sampler2DArray wideMaps;
uniform mat3 nrmMatrix;
uniform bool useShadows;
${contact ? 'uniform mat3 tanMatrix;\nvarying vec3 localTan;' : ''}

float sunDepth(sampler2DArray maps, vec2 xy, float layer, float res) {
  ivec2 t = ivec2(floor(xy));
  if (t.x < 0 || t.y < 0 || t.x >= int(res) || t.y >= int(res)) return 1.0e30;
  float d = texelFetch(maps, ivec3(t, int(layer)), 0).r;
  return d > 0.0 ? d : 1.0e30;
}

vec2 vogel(int i, int n) {
  float a = float(i) * 2.3999632;
  return sqrt((float(i) + 0.5) / float(n)) * vec2(cos(a), sin(a));
}

// (weight x lit, weight) of the PCF tap at o; 2 biases behind the receiver's plane (past a join): its mirror tap.
vec2 pcfTap(sampler2DArray maps, float layer, float res, vec3 q, vec2 grad, float bias, vec2 o, float facing, vec2 tilt) {
  float w = max(facing + dot(tilt, o), 0.0);
  float d = sunDepth(maps, q.xy + o, layer, res);
  if (d > q.z + dot(grad, floor(q.xy + o) + 0.5 - q.xy) + 2.0 * bias) { o = -o; d = sunDepth(maps, q.xy + o, layer, res); }
  return w * vec2(step(q.z + dot(grad, floor(q.xy + o) + 0.5 - q.xy) - bias, d), 1.0);
}

float viewVisibility(sampler2DArray maps, int v, vec3 n, int blockerTaps, int pcfTaps, int firstTaps, float maxRadius) {
  vec4 p = vec4(worldPos, 1.0);
  vec3 q = vec3(dot(sunRows[3 * v], p), dot(sunRows[3 * v + 1], p), dot(sunRows[3 * v + 2], p));
  // A view whose direction is below the receiver's horizon looks through it: no light.
  float facing = dot(n, sunDir[v].xyz);
  if (facing <= 0.0) return 0.0;
  float texel = sunParams[v].x;
  float tanA = sunParams[v].y;
  float res = sunParams[v].z;
  float layer = sunRange[v].z;
  // The receiver's plane in the map (receiver-plane depth bias): depth changes by
  // texel (n.t, n.b) / n.s per texel; sunRows[3v], [3v+1] are t, b over the texel size.
  vec2 grad = vec2(dot(n, sunRows[3 * v].xyz), dot(n, sunRows[3 * v + 1].xyz)) * texel
              / max(dot(n, sunDir[v].xyz), ${MIN_COSINE.toFixed(2)});
  float slope = length(grad);
  if (slope > ${MAX_SLOPE.toFixed(1)}) {
    grad *= ${MAX_SLOPE.toFixed(1)} / slope;
    slope = ${MAX_SLOPE.toFixed(1)};
  }
  grad *= texel;
  float bias = texel * (1.0 + slope);
${contact ? CONTACT_LINES : ''}  float search = clamp(q.z * tanA / texel, 1.0, maxRadius);
  float sum = 0.0;
  float found = 0.0;
  for (int i = 0; i < blockerTaps; i++) {
    vec2 xy = q.xy + search * vogel(i, blockerTaps);
    float d = sunDepth(maps, xy, layer, res);
    if (d < q.z + dot(grad, floor(xy) + 0.5 - q.xy) - bias) {
      sum += d;
      found += 1.0;
    }
  }
  if (found == 0.0) return 1.0;
  float radius = clamp((q.z - sum / found) * tanA / texel, 0.5, maxRadius);
  // Tap o is the disc's direction s + tanA (o / radius) . (t, b): weighted by its cosine, none below the horizon.
  vec2 tilt = vec2(dot(n, sunRows[3 * v].xyz), dot(n, sunRows[3 * v + 1].xyz)) * (texel * tanA / radius);
  // Every stride-th tap first, the others only where those disagree (display/shader_suns.py).
  int stride = pcfTaps / firstTaps;
  vec2 lit = vec2(0.0);
  for (int i = 0; i < pcfTaps; i += stride) lit += pcfTap(maps, layer, res, q, grad, bias, radius * vogel(i, pcfTaps), facing, tilt);
  if (stride > 1 && lit.x > 0.0 && lit.x < lit.y) {
    for (int i = 0; i < pcfTaps; i++) if (i % stride != 0) lit += pcfTap(maps, layer, res, q, grad, bias, radius * vogel(i, pcfTaps), facing, tilt);
  }
  return lit.y > 0.0 ? lit.x / lit.y : 0.0;
}
`;

// Where another surface touches this one (a wall under a ceiling) the map holds that surface at
// the receiver's own depth: the lookup moves into the receiver's own surface along its contact
// tangent, by CONTACT_SHIFT biases in world units times its length (display/shader_suns.py,
// docs/display.md "Joins"); the tangent is the node's (glTF local), taken to world space by tanMatrix.
const CONTACT_LINES = `  vec3 along = tanMatrix * localTan;
  vec3 dq = vec3(dot(sunRows[3 * v].xyz, along), dot(sunRows[3 * v + 1].xyz, along), dot(sunRows[3 * v + 2].xyz, along));
  float moved = length(vec3(dq.xy * texel, dq.z));
  if (moved > 0.0) q += dq * (${CONTACT_SHIFT.toFixed(1)} * bias * length(localTan) / moved);
`;

// The views written out one by one (layout: per view {count of samples, wide}, fixed per file), so
// that every uniform index is a constant: software WebGL (SwiftShader) indexes uniform arrays by
// a variable slowly. The same sums as Blender's view_cosine over each view's own samples.
function sunLoop(layout, glossy) {
  const lines = [
    '  vec3 n = normalize(nrmMatrix * localNrm);',
    '  vec3 sun = vec3(0.0);',
    '  float c;',
    '  float vis;',
  ];
  let first = 0;
  layout.forEach(({ count, wide, share }, v) => {
    lines.push('  c = 0.0;');
    for (let j = first; j < first + count; j++)
      lines.push(`  c += sunSamples[${j}].w * max(dot(n, sunSamples[${j}].xyz), 0.0);`);
    first += count;
    const visibility = wide
      ? `viewVisibility(wideMaps, ${v}, n, ${WIDE_BLOCKER_TAPS}, ${WIDE_PCF_TAPS}, ${WIDE_FIRST_TAPS}, ${WIDE_MAX_RADIUS.toFixed(1)})`
      : `viewVisibility(sharpMaps, ${v}, n, ${BLOCKER_TAPS}, ${PCF_TAPS}, ${PCF_TAPS}, ${MAX_RADIUS.toFixed(1)})`;
    lines.push(
      `  if (c > 0.0) {`,
      `    vis = useShadows ? ${visibility} : 1.0;`,
      `    sun += sunPower[${v}].rgb * (c * vis);`,
    );
    // (a view's highlight weighted by its share of its light's power: a wide light's views sum to 1)
    if (glossy) {
      const highlight = `sunSpecular(sunDir[${v}].xyz, atan(sunParams[${v}].y))`;
      lines.push(`    sunSpec += sunPower[${v}].rgb * (${highlight} * (vis * ${(share ?? 1).toFixed(9)}));`);
    }
    lines.push('  }');
  });
  lines.push('  color += surfaceAlbedo * sun;');
  return lines.join('\n');
}

// The end of the fragment shader: the base colour per pixel, and with specular Principled's weights.
function shade(glossy) {
  if (!glossy) return '  gl_FragColor = vec4(color * prtBaseColor() * exposureScale, 1.0);';
  return `  gl_FragColor = vec4(prtSpecularShade(color * prtBaseColor(), sunSpec, base, scale) * exposureScale, 1.0);`;
}

const FRAGMENT = (views, samples, layout, texel, surface, glossy, contact, texelOcclusion = '') => `
uniform float exposureScale;
varying vec3 radiance;
${glossy && !texel ? 'uniform vec3 albedo;\nuniform float scale;' : ''}
${surfaceFragment(surface)}
${glossy ? texelSpecular(surface.paired ? mappedFragment() + surfaceSpecular(surface) : SPECULAR_FRAGMENT, texelOcclusion) : ''}
${texel ? TEXEL_LOOKUP + texelOcclusion : ''}
${views ? 'varying vec3 surfaceAlbedo;\nvarying vec3 worldPos;\nvarying vec3 localNrm;' : ''}
${views ? SUN_FUNCTIONS(views, samples, contact) : ''}
void main() {
  vec3 color = ${texel ? 'prtTexelRadiance() * albedo * scale' : 'radiance'};
${glossy ? `  vec3 sunSpec = vec3(0.0);\n  vec3 base = albedo * prtBaseColor();\n${surface.paired ? '  prtSurfaceInputs();\n' : ''}  prtSpecularSetup(base);` : ''}
${views ? sunLoop(layout, glossy) : ''}
${shade(glossy)}
  #include <tonemapping_fragment>
  #include <colorspace_fragment>
}
`;

/** A ShaderMaterial for a transfer source (transfer_source.js: `count` vec4s per block, 1 + `channels`
 * blocks), `views` shadow views holding `samples` samples in all (0: no split lights), a bounced
 * transfer of `channels` channels (0: none), shared uniforms passed in; `layout` per view {count
 * of its samples, wide} (in the order of the shared uniforms); `side` as three.js's
 * (the plugin passes the glTF material's: doubleSided or not); `surface` the source material's
 * per-pixel base colour: {map (a THREE.Texture, its `channel` and `matrix` used), vertexColors};
 * `glossy` the Principled specular (specular.js: {order, constants: readMaterial's}; null: diffuse
 * only), its shared uniforms (skyTx, brdfTx, skyRows, skySize) in `shared`; `contact` whether the
 * geometry has the contact tangent `prtContact` (plugin.js), which the shadow lookups move along. */
export function prtMaterial({
  source,
  views = 0,
  samples = 0,
  layout = [],
  albedo,
  shared,
  channels = 0,
  side = THREE.DoubleSide,
  surface = {},
  glossy = null,
  contact = false,
}) {
  const mapped = glossy ? glossy.constants.maps || [] : [];
  const base = {
    map: surface.map || null,
    roughMap: (mapped.includes('roughness') && surface.roughnessMap) || null,
    metalMap: (mapped.includes('metallic') && surface.metalnessMap) || null,
    f0Map: (glossy && glossy.constants.f0Map) || null,
    vertexColors: Boolean(surface.vertexColors),
  };
  base.paired = Boolean(glossy && glossy.constants.bands2 && (base.roughMap || base.metalMap || base.f0Map));
  if (source.stage !== 'vertex' && source.stage !== 'texel')
    throw new Error(`a '${source.stage}' transfer source is not supported`);
  const count = source.count;
  const vec4s = () => ({ value: Array.from({ length: 3 * count }, () => new THREE.Vector4()) });
  const uniforms = {
    ...source.uniforms,
    light: vec4s(),
    lightConstant: { value: new THREE.Vector3() },
    ...(channels ? { bounceLight: vec4s(), bounceConstant: { value: new THREE.Vector3() } } : {}),
    albedo: { value: new THREE.Vector3(...albedo) },
    scale: { value: 1.0 },
    nrmMatrix: { value: new THREE.Matrix3() },
    tanMatrix: { value: new THREE.Matrix3() },
    exposureScale: shared.exposureScale,
    prtRadianceTx: { value: null }, // (a relit or texel source: relight.js's texture)
    prtResolution: { value: source.resolution || 0 },
    ...(base.map ? { prtMap: { value: base.map }, prtMapTransform: { value: base.map.matrix } } : {}),
    ...(base.roughMap
      ? {
          prtRoughMap: { value: base.roughMap },
          prtRoughTransform: { value: base.roughMap.matrix },
          prtRoughFactor: { value: surface.roughness ?? 1 },
        }
      : {}),
    ...(base.metalMap
      ? {
          prtMetalMap: { value: base.metalMap },
          prtMetalTransform: { value: base.metalMap.matrix },
          prtMetalFactor: { value: surface.metalness ?? 1 },
        }
      : {}),
    ...(base.f0Map ? { prtF0Map: { value: base.f0Map }, prtF0Transform: { value: base.f0Map.matrix } } : {}),
    ...(glossy ? specularUniforms(shared, glossy.constants) : {}),
  };
  if (views) {
    for (const name of ['sunRows', 'sunDir', 'sunPower', 'sunParams', 'sunRange', 'sunSamples']) {
      uniforms[name] = shared[name];
    }
    Object.assign(uniforms, { sharpMaps: shared.sharpMaps, wideMaps: shared.wideMaps, useShadows: shared.useShadows });
  }
  const texelOcc = texelOcclusionFragment(source, glossy, base.paired); // ('' unless a glossy texel bake)
  return new THREE.ShaderMaterial({
    uniforms,
    vertexShader: VERTEX(count, views, channels, source, base, glossy, contact),
    fragmentShader: FRAGMENT(views, samples, layout, source.stage === 'texel', base, glossy, contact, texelOcc),
    side,
  });
}

/** Write a local-frame RGB light ((order^2) rows of [r, g, b]) into the material's uniform
 * (`name`: light, or bounceLight for a bounced bake's sky plus lights). */
export function setLight(material, local, count, name = 'light') {
  const light = material.uniforms[name].value;
  for (let ch = 0; ch < 3; ch++) {
    for (let k = 0; k < count; k++) {
      const v = [0, 1, 2, 3].map((j) => (local[4 * k + j] ? local[4 * k + j][ch] : 0));
      light[ch * count + k].set(v[0], v[1], v[2], v[3]);
    }
  }
}
