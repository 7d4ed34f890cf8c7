// The specular occlusion of the full transfer per vertex, drawn into a float texture when the view or the node moves; the frame reads one value a vertex.
//
// The lobe-weighted visibility at the vertex's reflection direction (docs/specular.md: sum_lm
// k_l t_lm y_lm(R) over the open transfer's sum_l k_l z_l sqrt((2l + 1) / 4 pi) P_l(n.R), the real
// SH basis by its recurrences, as shader_specular.py's occlusion_lines) depends on the view, so it
// cannot be relit once per lighting change; and in the frame's vertex stage SwiftShader runs it
// for more than the mesh's vertices (1M triangles hold 3M indices: docs/export.md, "Speed").
// Here the mesh's vertices are drawn once as points, one per texel of a float target in the
// relight's layout (vertex v at (v % perRow, v / perRow)), each point's vertex shader evaluating
// its vertex's occlusion; it runs again only when the eye point (the camera's position, or its
// direction for an orthographic camera) or the node's matrix changed.
import * as THREE from 'three';
import { renderInto } from './relight.js';

/** GLSL lines setting `float occ` from the transfer's vec4s `fetch(k)` at the world point `wp`
 * with the world normal `sn` and the direction to the viewer `sv` (uniforms prtFrame, prtBands,
 * prtOpen), the full transfer of order `n`; `paired`: `float occ2` too, the second lobe's
 * (prtBands2, prtOpen2: a roughness image's largest value, as Blender's display/material_maps.py). */
export function occlusionLines(fetch, n, paired = false) {
  const lines = [];
  const vec4s = Math.ceil((n * n) / 4);
  for (let k = 0; k < vec4s; k++) lines.push(`  vec4 q${k} = ${fetch(k)};`);
  const coeff = (i) => `q${i >> 2}[${i & 3}]`;
  const band = (l) => `prtBands[${l >> 2}][${l & 3}]`;
  lines.push(
    '  vec3 sr = reflect(-sv, sn);',
    '  vec3 d = transpose(prtFrame) * sr;',
    '  float seen = 0.0;',
    '  float c0 = 1.0;',
    '  float s0 = 0.0;',
  );
  let factorial = 1;
  for (let m = 0; m < n; m++) {
    if (m > 0) {
      lines.push(`  float c${m} = d.x * c${m - 1} - d.y * s${m - 1};`);
      lines.push(`  float s${m} = d.x * s${m - 1} + d.y * c${m - 1};`);
      factorial *= 2 * m - 1;
    }
    for (let l = m; l < n; l++) {
      let q;
      if (l === m) q = `${factorial.toFixed(1)}`;
      else if (l === m + 1) q = `${2 * m + 1}.0 * d.z * Q${l - 1}_${m}`;
      else q = `(${2 * l - 1}.0 * d.z * Q${l - 1}_${m} - ${l + m - 1}.0 * Q${l - 2}_${m}) / ${l - m}.0`;
      lines.push(`  float Q${l}_${m} = ${q};`);
      let ratio = 1;
      for (let j = l - m + 1; j <= l + m; j++) ratio *= j;
      let k = Math.sqrt((2 * l + 1) / (4 * Math.PI) / ratio);
      if (m === 0) lines.push(`  seen += ${band(l)} * ${coeff(l * l + l)} * (${k.toExponential(16)} * Q${l}_0);`);
      else {
        k *= Math.SQRT2;
        lines.push(
          `  seen += ${band(l)} * (${k.toExponential(16)} * Q${l}_${m}) * (${coeff(l * l + l + m)} * c${m} + ${coeff(l * l + l - m)} * s${m});`,
        );
      }
    }
  }
  lines.push('  float mu = dot(sn, sr);', '  float p0 = 1.0;', '  float p1 = mu;');
  const terms = ['prtOpen[0][0]'];
  if (n > 1) terms.push('prtOpen[0][1] * mu');
  for (let l = 2; l < n; l++) {
    lines.push(`  float p${l} = (${2 * l - 1}.0 * mu * p${l - 1} - ${l - 1}.0 * p${l - 2}) / ${l}.0;`);
    terms.push(`prtOpen[${l >> 2}][${l & 3}] * p${l}`);
  }
  lines.push(`  float open_ = ${terms.join(' + ')};`, '  float occ = open_ > 1e-8 ? seen / open_ : 1.0;');
  return (paired ? secondLobe(lines) : lines).join('\n');
}

// The same sums over the second lobe's bands (each `seen +=` and the open transfer's line again
// with prtBands2 and prtOpen2), and occ2 from them.
function secondLobe(lines) {
  const out = [];
  for (const line of lines) {
    out.push(line);
    if (line.startsWith('  seen += ') || line.startsWith('  float open_ = '))
      out.push(
        line
          .replace('seen +=', 'seen2 +=')
          .replace('open_ =', 'open2 =')
          .replace(/prtBands\[/g, 'prtBands2[')
          .replace(/prtOpen\[/g, 'prtOpen2['),
      );
    else if (line === '  float seen = 0.0;') out.push('  float seen2 = 0.0;');
    else if (line.startsWith('  float occ = ')) out.push('  float occ2 = open2 > 1e-8 ? seen2 / open2 : 1.0;');
  }
  return out;
}

const VERTEX = (source, n, paired) => `
${source.glsl}
uniform mat4 prtModel;
uniform mat3 nrmMatrix;
uniform mat3 prtFrame;
uniform vec4 prtBands[8];
uniform vec4 prtOpen[8];
${paired ? 'uniform vec4 prtBands2[8];\nuniform vec4 prtOpen2[8];' : ''}
uniform vec4 prtEye;
uniform vec2 prtTargetSize;
flat varying vec2 prtOcc;
void main() {
  vec2 texel = vec2(float(gl_VertexID % prtPerRow), float(gl_VertexID / prtPerRow)) + 0.5;
  gl_Position = vec4(texel / prtTargetSize * 2.0 - 1.0, 0.0, 1.0);
  gl_PointSize = 1.0;
  vec3 wp = (prtModel * vec4(position, 1.0)).xyz;
  vec3 sn = normalize(nrmMatrix * normal);
  vec3 sv = normalize(prtEye.xyz - wp * prtEye.w);
${occlusionLines(source.fetch, n, paired)}
  prtOcc = vec2(occ, ${paired ? 'occ2' : '0.0'});
}
`;

const FRAGMENT = `
flat varying vec2 prtOcc;
void main() {
  gl_FragColor = vec4(prtOcc, 0.0, 1.0);
}
`;

/** The eye point of a camera in world space, homogeneous: its position (w 1), or for an
 * orthographic camera the direction toward the viewer (w 0), as shader_specular.eye_point. */
function eyePoint(camera, out) {
  const e = camera.matrixWorld.elements;
  if (camera.isOrthographicCamera) {
    const n = Math.hypot(e[8], e[9], e[10]) || 1;
    return out.set(e[8] / n, e[9] / n, e[10] / n, 0);
  }
  return out.set(e[12], e[13], e[14], 1);
}

/** The occlusion texture of one baked mesh (a node: its own matrix) whose transfer `source`
 * decodes at the vertex (transfer_source.js, kind 'texture'); the material's uniforms nrmMatrix,
 * prtFrame, prtBands and prtOpen are shared with it. update(renderer, camera, object) redraws it
 * when needed. */
export class OcclusionPass {
  constructor(geometry, source, material, order) {
    const [width, height] = source.relightSize;
    const u = material.uniforms;
    const paired = Boolean(u.prtBands2 && u.prtOpen2); // (a roughness image: its two lobes, red and green)
    this.target = new THREE.WebGLRenderTarget(width, height, {
      type: THREE.FloatType,
      format: paired ? THREE.RGFormat : THREE.RedFormat,
      minFilter: THREE.NearestFilter,
      magFilter: THREE.NearestFilter,
      depthBuffer: false,
      generateMipmaps: false,
    });
    // The mesh's own position and normal buffers, drawn without the index: one point a vertex.
    const points = new THREE.BufferGeometry();
    points.setAttribute('position', geometry.attributes.position);
    points.setAttribute('normal', geometry.attributes.normal);
    points.setDrawRange(0, geometry.attributes.position.count);
    this.material = new THREE.ShaderMaterial({
      uniforms: {
        ...source.uniforms,
        nrmMatrix: u.nrmMatrix,
        prtFrame: u.prtFrame,
        prtBands: u.prtBands,
        prtOpen: u.prtOpen,
        ...(paired ? { prtBands2: u.prtBands2, prtOpen2: u.prtOpen2 } : {}),
        prtModel: { value: new THREE.Matrix4() },
        prtEye: { value: new THREE.Vector4() },
        prtTargetSize: { value: new THREE.Vector2(width, height) },
      },
      vertexShader: VERTEX(source, order, paired),
      fragmentShader: FRAGMENT,
      depthTest: false,
      depthWrite: false,
    });
    this.points = new THREE.Points(points, this.material);
    this.points.frustumCulled = false;
    this.scene = new THREE.Scene();
    this.scene.add(this.points);
    this.camera = new THREE.Camera();
    this.texture = this.target.texture;
    this.eye = new THREE.Vector4();
    this.model = null;
  }

  /** Draw the target again if the camera's eye point or the node's matrix changed since the last time. */
  update(renderer, camera, object) {
    const eye = eyePoint(camera, this.eye);
    const u = this.material.uniforms;
    if (this.model && this.model.equals(object.matrixWorld) && u.prtEye.value.equals(eye)) return false;
    u.prtEye.value.copy(eye);
    u.prtModel.value.copy(object.matrixWorld);
    this.model = object.matrixWorld.clone();
    renderInto(renderer, this.scene, this.camera, this.target);
    return true;
  }

  dispose() {
    this.target.dispose();
    this.material.dispose();
    // The points' geometry holds the mesh's own position and normal buffers: let go of them first,
    // so its dispose frees only its own state (its vertex-array objects), not the mesh's buffers.
    const points = this.points.geometry;
    points.deleteAttribute('position');
    points.deleteAttribute('normal');
    points.dispose();
  }
}
