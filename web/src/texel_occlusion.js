// A texel bake's specular occlusion: its direct transfer tiles decoded once into a float texture, the full transfer summed per pixel at the lightmap UV.
//
// As Blender's display/texel_occlusion.py: the lobe-weighted visibility of the full transfer
// (occlusion.js's occlusionLines) at the pixel's reflection direction, from the coefficients
// looked up bilinearly (clamp to edge within each tile, texel centres at (i + 0.5) / res) at the
// pixel's lightmap UV, at every roughness (texel bakes do not use the cones). The PNG planes are
// decoded by a pass drawn once (a texel source's prtTexel0(k, p), transfer_source.js) into a
// float target of the planes' tile layout (tile k at column k % tiles_x, row k / tiles_x); the
// frame reads four texels a tile.
import * as THREE from 'three';
import { SCREEN_VERTEX, renderInto, screenPass } from './relight.js';
import { occlusionLines } from './occlusion.js';
import { BAND_COUNT } from './specular.js';

const DECODE = (source) => `
${source.relightGlsl}
void main() {
  ivec2 p = ivec2(gl_FragCoord.xy);
  ivec2 tile = p / ${source.resolution};
  int k = tile.x + tile.y * ${source.tiles[0]};
  gl_FragColor = k < ${source.count} ? prtTexel0(k, p - tile * ${source.resolution}) : vec4(0.0);
}
`;

/** The decoded direct tiles of a texel source (transfer_source.js, stage 'texel') in a float
 * target; update(renderer) draws it the first time. */
export class TexelTiles {
  constructor(source) {
    const [columns, rows] = source.tiles;
    this.target = new THREE.WebGLRenderTarget(columns * source.resolution, rows * source.resolution, {
      type: THREE.FloatType,
      format: THREE.RGBAFormat,
      minFilter: THREE.NearestFilter,
      magFilter: THREE.NearestFilter,
      depthBuffer: false,
      generateMipmaps: false,
    });
    this.material = new THREE.ShaderMaterial({
      uniforms: source.uniforms,
      vertexShader: SCREEN_VERTEX,
      fragmentShader: DECODE(source),
      depthTest: false,
      depthWrite: false,
    });
    Object.assign(this, screenPass(this.material));
    this.texture = this.target.texture;
    this.drawn = false;
  }

  update(renderer) {
    if (this.drawn) return false;
    renderInto(renderer, this.scene, this.camera, this.target);
    this.drawn = true;
    return true;
  }

  dispose() {
    this.target.dispose();
    this.material.dispose();
    this.mesh.geometry.dispose();
  }
}

/** Fragment GLSL of a glossy texel bake (`source` a texel source, `glossy` prt_material.js's;
 * otherwise ''): prtTexelOcclusion() sets prtSpecOcc (and prtSpecOcc2, `paired`: a roughness
 * image's second lobe) from prtTilesTx at prtUv, with spec_n and spec_v (prtSpecularSetup's). */
export function texelOcclusionFragment(source, glossy, paired) {
  if (!glossy || source.stage !== 'texel') return '';
  const n = Math.min(glossy.order, BAND_COUNT);
  const [columns, resolution] = [source.tiles[0], source.resolution];
  return `
uniform sampler2D prtTilesTx;
uniform vec4 prtBands[8];
uniform vec4 prtOpen[8];
${paired ? 'uniform vec4 prtBands2[8];\nuniform vec4 prtOpen2[8];' : ''}
ivec2 prtTileA;
ivec2 prtTileB;
vec2 prtTileF;
vec4 prtTile(int k) {
  ivec2 o = ivec2(k % ${columns}, k / ${columns}) * ${resolution};
  vec4 t00 = texelFetch(prtTilesTx, prtTileA + o, 0);
  vec4 t10 = texelFetch(prtTilesTx, ivec2(prtTileB.x, prtTileA.y) + o, 0);
  vec4 t01 = texelFetch(prtTilesTx, ivec2(prtTileA.x, prtTileB.y) + o, 0);
  vec4 t11 = texelFetch(prtTilesTx, prtTileB + o, 0);
  return mix(mix(t00, t10, prtTileF.x), mix(t01, t11, prtTileF.x), prtTileF.y);
}
void prtTexelOcclusion() {
  vec2 x = prtUv * ${resolution.toFixed(1)} - 0.5;
  vec2 f0 = floor(x);
  prtTileF = x - f0;
  prtTileA = clamp(ivec2(f0), ivec2(0), ivec2(${resolution - 1}));
  prtTileB = clamp(ivec2(f0) + 1, ivec2(0), ivec2(${resolution - 1}));
  vec3 sn = spec_n;
  vec3 sv = spec_v;
${occlusionLines((k) => `prtTile(${k})`, n, paired)}
  prtSpecOcc = occ;
${paired ? '  prtSpecOcc2 = occ2;' : ''}
}
`;
}

/** The specular fragment (specular.js's SPECULAR_FRAGMENT or mappedFragment), for a glossy
 * texel bake (texelOcclusion: its texelOcclusionFragment, else '' and the fragment as it is) with
 * its occlusion inputs set per pixel (prtTexelOcclusion), the full transfer's at every roughness. */
export function texelSpecular(fragment, texelOcclusion) {
  if (!texelOcclusion) return fragment;
  const out = fragment
    .replace('varying vec4 prtSpecVis;', 'vec4 prtSpecVis = vec4(0.28209479177387814, 0.0, 0.0, 0.0);')
    .replace('varying float prtSpecOcc;', 'float prtSpecOcc = 1.0;')
    .replace('varying float prtSpecOcc2;', 'float prtSpecOcc2 = 1.0;')
    .replace(/clamp\(\((prtSurface\.x|prtRoughness) - 0\.3\) \/ 0\.3, 0\.0, 1\.0\)\);/, '1.0);')
    .replace('void prtSpecularSetup(vec3 base) {', 'void prtTexelOcclusion();\nvoid prtSpecularSetup(vec3 base) {')
    .replace(/(\n {2}spec_ab = brdfAB\(spec_nv, [a-zA-Z.]+\);\n)\}/, '$1  prtTexelOcclusion();\n}');
  if (
    !out.includes('  prtTexelOcclusion();\n}') ||
    out.includes('varying float prtSpecOcc') ||
    !out.includes('1.0);\n}')
  )
    throw new Error('unexpected specular GLSL');
  return out;
}
