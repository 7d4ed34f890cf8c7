// Relighting once per lighting change: each vertex's or texel's max(0, sum_i L_i t_i) drawn into a float texture the frame reads.
//
// As Blender's display does for texel bakes (prt_addon/blender/display/texel_relight.py): the sum
// over the n*n coefficients runs once per change of the light (a turn, a moved node), one
// fragment per vertex or texel of a float render target, and every frame reads one RGBA value: a
// vertex at gl_VertexID (so the vertex stage costs the same at every order), a texel by one
// clamp-to-edge bilinear lookup per pixel (4 texelFetch, the lookup of core.transfer.lightmap).
// The light uniforms are the material's own (prt_material.js), so PRTLighting sets them as
// before; run(renderer) redraws the target.
import * as THREE from 'three';

// A texel source's radiance: the bilinear lookup (clamp to edge, texel centres at (i + 0.5) / res)
// of the relit texture at the lightmap UV, as core.transfer.lightmap.bilinear and Blender's display.
export const TEXEL_LOOKUP = `
uniform sampler2D prtRadianceTx;
uniform int prtResolution;
uniform vec3 albedo;
uniform float scale;
varying vec2 prtUv;
vec3 prtTexelRadiance() {
  vec2 x = prtUv * float(prtResolution) - 0.5;
  vec2 f0 = floor(x);
  vec2 f = x - f0;
  ivec2 top = ivec2(prtResolution - 1);
  ivec2 a = clamp(ivec2(f0), ivec2(0), top);
  ivec2 b = clamp(ivec2(f0) + 1, ivec2(0), top);
  vec3 r00 = texelFetch(prtRadianceTx, a, 0).rgb;
  vec3 r10 = texelFetch(prtRadianceTx, ivec2(b.x, a.y), 0).rgb;
  vec3 r01 = texelFetch(prtRadianceTx, ivec2(a.x, b.y), 0).rgb;
  vec3 r11 = texelFetch(prtRadianceTx, b, 0).rgb;
  return mix(mix(r00, r10, f.x), mix(r01, r11, f.x), f.y);
}`;

/** The vertex shader of a full-screen pass: screenPass's triangle, as it is in clip space. */
export const SCREEN_VERTEX = `
void main() {
  gl_Position = vec4(position.xy, 0.0, 1.0);
}
`;

/** A full-screen triangle drawing `material` into a target: {mesh, scene, camera} for renderInto
 * (its geometry is the pass's own: dispose mesh.geometry with it). */
export function screenPass(material) {
  const quad = new THREE.BufferGeometry();
  quad.setAttribute('position', new THREE.Float32BufferAttribute([-1, -1, 0, 3, -1, 0, -1, 3, 0], 3));
  const mesh = new THREE.Mesh(quad, material);
  mesh.frustumCulled = false;
  const scene = new THREE.Scene();
  scene.add(mesh);
  return { mesh, scene, camera: new THREE.Camera() };
}

// The sum of prt_material.js's transferSum, `fetch(k)` a source's (with p the target's texel).
function sum(count, channels, source) {
  const lines = [];
  const block = [0, 1, 2].map((c) => count * (1 + (channels === 3 ? c : 0)));
  for (let k = 0; k < count; k++) {
    lines.push(`  t = ${source.relightFetch(k)};`);
    lines.push(`  r += vec3(dot(t, light[${k}]), dot(t, light[${count + k}]), dot(t, light[${2 * count + k}]));`);
    if (!channels) continue;
    const b = [0, 1, 2].map((c) => `b${c}`);
    lines.push(`  b0 = ${source.relightFetch(block[0] + k)};`);
    lines.push(channels === 3 ? `  b1 = ${source.relightFetch(block[1] + k)};` : '  b1 = b0;');
    lines.push(channels === 3 ? `  b2 = ${source.relightFetch(block[2] + k)};` : '  b2 = b0;');
    lines.push(
      `  r += vec3(dot(${b[0]}, bounceLight[${k}]), dot(${b[1]}, bounceLight[${count + k}]), dot(${b[2]}, bounceLight[${2 * count + k}]));`,
    );
  }
  return lines.join('\n');
}

const FRAGMENT = (count, channels, source) => `
${source.relightGlsl}
uniform vec4 light[${3 * count}];
uniform vec3 lightConstant;
${channels ? `uniform vec4 bounceLight[${3 * count}];\nuniform vec3 bounceConstant;` : ''}
void main() {
  ivec2 p = ivec2(gl_FragCoord.xy);
  vec3 r = lightConstant${channels ? ' + bounceConstant' : ''};
  vec4 t;
  ${channels ? 'vec4 b0, b1, b2;' : ''}
${sum(count, channels, source)}
  gl_FragColor = vec4(max(r, vec3(0.0)), 1.0);
}
`;

/** Render `scene` into `target` as a nested render: the renderer's target and auto-clear are restored. */
export function renderInto(renderer, scene, camera, target) {
  const previous = renderer.getRenderTarget();
  const autoClear = renderer.autoClear;
  try {
    renderer.autoClear = false;
    renderer.setRenderTarget(target);
    renderer.render(scene, camera);
  } finally {
    renderer.setRenderTarget(previous);
    renderer.autoClear = autoClear;
  }
}

/** The relit radiance of one baked mesh: a float target of source.relightSize, drawn by run(renderer)
 * with the light uniforms of `material` (prt_material.js). */
export class Relight {
  constructor(source, material, channels) {
    const [width, height] = source.relightSize;
    this.target = new THREE.WebGLRenderTarget(width, height, {
      type: THREE.FloatType,
      format: THREE.RGBAFormat,
      minFilter: THREE.NearestFilter,
      magFilter: THREE.NearestFilter,
      depthBuffer: false,
      generateMipmaps: false,
    });
    const uniforms = { ...source.uniforms };
    for (const name of ['light', 'lightConstant', 'bounceLight', 'bounceConstant']) {
      if (material.uniforms[name]) uniforms[name] = material.uniforms[name];
    }
    this.material = new THREE.ShaderMaterial({
      uniforms,
      vertexShader: SCREEN_VERTEX,
      fragmentShader: FRAGMENT(source.count, channels, source),
      depthTest: false,
      depthWrite: false,
    });
    Object.assign(this, screenPass(this.material));
    this.texture = this.target.texture;
    this.dirty = true;
  }

  /** Draw the target now (a nested render: the renderer's target and clear colour are restored). */
  run(renderer) {
    renderInto(renderer, this.scene, this.camera, this.target);
    this.dirty = false;
  }

  dispose() {
    this.target.dispose();
    this.material.dispose();
    this.mesh.geometry.dispose();
  }
}
