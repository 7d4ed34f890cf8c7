// Shadow maps of the split lights, as Blender's display draws them (prt_addon/blender/display/shadows.py).
//
// One orthographic map per light, 2048^2 R32F, holding the depth from the light's near plane in
// world units over every mesh of the scene, fitted to the bounding box of all vertices. Texels no
// caster covers hold 0 (read as "no blocker"). prt_material.js filters it (PCSS).
import * as THREE from 'three';

export const MAX_SUNS = 8;
export const RESOLUTION = 2048;
export const BLOCKER_TAPS = 12;
export const PCF_TAPS = 16;
export const MAX_RADIUS = 16.0;
export const MAX_SLOPE = 20.0;
export const MAX_SAMPLES = 16; // a light's samples in the cosine term (display/shader_suns.py)
export const MIN_COSINE = 0.05; // the slope bias's cosine when the mean direction is at or below the horizon
const PAD = 0.01;

const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const unit = (a) => {
  const n = Math.hypot(a[0], a[1], a[2]);
  return [a[0] / n, a[1] / n, a[2] / n];
};

/** Unit t, b completing the unit light direction s to an orthonormal basis (shadows._frame). */
function frame(direction) {
  const s = unit(direction);
  const helper = Math.abs(s[0]) < 0.9 ? [1, 0, 0] : [0, 1, 0];
  const t = unit(cross(helper, s));
  return [t, cross(s, t), s];
}

/** {rows (3 x vec4: world -> texel x, texel y, depth), clip (Matrix4), texel} (shadows.light_rows). */
export function lightRows(direction, box, resolution = RESOLUTION) {
  const [t, b, s] = frame(direction);
  const { min: lo, max: hi } = box;
  const corners = [];
  for (const x of [lo.x, hi.x]) for (const y of [lo.y, hi.y]) for (const z of [lo.z, hi.z]) corners.push([x, y, z]);
  const pad = PAD * Math.hypot(hi.x - lo.x, hi.y - lo.y, hi.z - lo.z) + 1e-6;
  const range = (axis) => {
    const values = corners.map((c) => dot(c, axis));
    return [Math.min(...values), Math.max(...values)];
  };
  const [u1, u2] = range(t);
  const [v1, v2] = range(b);
  const [w1, w2] = range(s);
  const size = Math.max(u2 - u1, v2 - v1) + 2 * pad;
  const u0 = 0.5 * (u1 + u2) - 0.5 * size;
  const v0 = 0.5 * (v1 + v2) - 0.5 * size;
  const wTop = w2 + pad;
  const depthRange = w2 - w1 + 2 * pad;
  const k = resolution / size;
  const rows = [
    [k * t[0], k * t[1], k * t[2], -k * u0],
    [k * b[0], k * b[1], k * b[2], -k * v0],
    [-s[0], -s[1], -s[2], wTop],
  ];
  const scaled = (row, f) => row.map((x, i) => x * f - (i === 3 ? 1 : 0));
  const c0 = scaled(rows[0], 2 / resolution);
  const c1 = scaled(rows[1], 2 / resolution);
  const c2 = scaled(rows[2], 2 / depthRange);
  const clip = new THREE.Matrix4().set(...c0, ...c1, ...c2, 0, 0, 0, 1);
  return { rows, clip, texel: size / resolution };
}

const DEPTH_VERTEX = `
uniform mat4 clip;
uniform vec4 depthRow;
varying float depth;
void main() {
  vec4 wp = modelMatrix * vec4(position, 1.0);
  depth = dot(depthRow, wp);
  gl_Position = clip * wp;
}
`;

const DEPTH_FRAGMENT = `
varying float depth;
void main() {
  gl_FragColor = vec4(depth, 0.0, 0.0, 1.0);
}
`;

/** The shadow maps of a scene: targets, the depth material, and update(lights). */
export class ShadowMaps {
  constructor(renderer, scene, resolution = RESOLUTION) {
    this.renderer = renderer;
    this.scene = scene;
    this.resolution = resolution;
    this.targets = [];
    this.box = new THREE.Box3().setFromObject(scene, true);
    this.material = new THREE.ShaderMaterial({
      uniforms: { clip: { value: new THREE.Matrix4() }, depthRow: { value: new THREE.Vector4() } },
      vertexShader: DEPTH_VERTEX,
      fragmentShader: DEPTH_FRAGMENT,
      side: THREE.DoubleSide,
    });
    this.camera = new THREE.Camera(); // (unused by the depth shader)
  }

  target(l) {
    while (this.targets.length <= l) {
      this.targets.push(
        new THREE.WebGLRenderTarget(this.resolution, this.resolution, {
          type: THREE.FloatType,
          format: THREE.RedFormat,
          minFilter: THREE.NearestFilter,
          magFilter: THREE.NearestFilter,
          depthBuffer: true,
          generateMipmaps: false,
        }),
      );
    }
    return this.targets[l];
  }

  /** Draw each light's map; returns [{texture, rows, texel}] per light. */
  update(lights) {
    const renderer = this.renderer;
    const previous = {
      target: renderer.getRenderTarget(),
      color: renderer.getClearColor(new THREE.Color()),
      alpha: renderer.getClearAlpha(),
      override: this.scene.overrideMaterial,
      background: this.scene.background,
    };
    const out = [];
    try {
      this.scene.overrideMaterial = this.material;
      this.scene.background = null;
      renderer.setClearColor(0x000000, 0);
      lights.forEach((light, l) => {
        const { rows, clip, texel } = lightRows(light.direction, this.box, this.resolution);
        this.material.uniforms.clip.value.copy(clip);
        this.material.uniforms.depthRow.value.set(...rows[2]);
        const target = this.target(l);
        renderer.setRenderTarget(target);
        renderer.clear(true, true, false);
        renderer.render(this.scene, this.camera);
        out.push({ texture: target.texture, rows, texel });
      });
    } finally {
      this.scene.overrideMaterial = previous.override;
      this.scene.background = previous.background;
      renderer.setRenderTarget(previous.target);
      renderer.setClearColor(previous.color, previous.alpha);
    }
    return out;
  }

  dispose() {
    this.targets.forEach((t) => t.dispose());
    this.material.dispose();
  }
}
