// The split lights' shadow views and their maps, as Blender's display draws them (display/shadows.py).
//
// A view (core.lights.shadow_views, written by the export per light) is one orthographic R32F map of
// the depth from its near plane in world units over every mesh of the scene, fitted to the
// bounding box of all vertices: a compact light has one view holding all its samples, a wide
// light one per group of its samples. The compact views' maps are the layers of one 2048^2
// array target, the wide views' of one 1024^2 array target (one depth buffer each, the maps
// drawn one after the other). Texels no caster covers hold 0 (read as "no blocker").
// prt_material.js filters them (PCSS).
import * as THREE from 'three';

export const MAX_SUNS = 8;
export const MAX_WIDE_VIEWS = 32; // the wide lights' maps together (the export's WEB_WIDE_VIEWS)
export const RESOLUTION = 2048; // the compact lights' maps
export const WIDE_RESOLUTION = 1024; // a wide light's maps
export const BLOCKER_TAPS = 12;
export const PCF_TAPS = 16;
export const WIDE_BLOCKER_TAPS = 6; // a wide light's views (display/shader_suns.py)
export const WIDE_PCF_TAPS = 48;
export const WIDE_FIRST_TAPS = 8; // read first; the rest only where these disagree (a penumbra)
export const MAX_RADIUS = 64.0; // texels: a compact light's widest penumbra (display/shader_suns.py)
export const WIDE_MAX_RADIUS = 24.0; // a wide light's view's
export const MAX_SLOPE = 20.0;
export const MAX_SAMPLES = 16; // a light's samples in the cosine term (display/shader_suns.py)
export const CONTACT_SHIFT = 3.0; // lookups move this many biases along the contact tangent (display/shader_suns.py)
export const MIN_COSINE = 0.05; // the slope bias's cosine when the view's direction is at or below the horizon
const PAD = 0.01;

const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const unit = (a) => {
  const n = Math.hypot(a[0], a[1], a[2]);
  return [a[0] / n, a[1] / n, a[2] / n];
};

/** The shadow views of the file's lights (glTF frame, before any turn): per view {light, direction,
 * angle, samples (rows of [x, y, z]), weights, wide}. A light's `views` (docs/export.md) index its
 * samples, whose weights (the first MAX_SAMPLES, renormalised) the views share; a light without
 * `views` (a file from before them) is one compact view: its direction, filtered over its shadow
 * angle, with all its samples. */
export function fileViews(lights) {
  const out = [];
  lights.forEach((light, l) => {
    const count = light.samples ? Math.min(light.samples.length, MAX_SAMPLES) : 0;
    const total = count ? light.weights.slice(0, count).reduce((a, b) => a + b, 0) : 1;
    const all = Array.from({ length: count }, (_, j) => j);
    const angle = light.samples ? Math.min(light.shadow_angle ?? light.angle, light.angle) : light.angle;
    const views = light.views || [{ direction: light.direction, angle, samples: count ? all : null, wide: false }];
    for (const view of views) {
      const indices = count ? view.samples || all : null;
      out.push({
        light: l,
        direction: view.direction,
        angle: view.angle,
        samples: indices ? indices.map((j) => light.samples[j]) : [unit(light.direction)],
        weights: indices ? indices.map((j) => light.weights[j] / total) : [1.0],
        wide: Boolean(view.wide),
      });
    }
  });
  return out;
}

const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];

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

/** One array target of `layers` maps of `resolution`^2 (R32F, nearest, one depth buffer). */
function arrayTarget(resolution, layers) {
  return new THREE.WebGLArrayRenderTarget(resolution, resolution, layers, {
    type: THREE.FloatType,
    format: THREE.RedFormat,
    minFilter: THREE.NearestFilter,
    magFilter: THREE.NearestFilter,
    depthBuffer: true,
    generateMipmaps: false,
  });
}

/** The shadow maps of the views ({wide} per view, fixed) of `casters` (meshes, drawn through
 * stand-ins that share their geometry, wherever the app puts the originals): the two array
 * targets (null when no view needs one), each view's layer, the depth material, update(). */
export class ShadowMaps {
  constructor(casters, views) {
    this.casters = casters;
    this.scene = new THREE.Scene();
    this.proxies = casters.map((mesh) => {
      const proxy = new THREE.Mesh(mesh.geometry);
      proxy.matrixAutoUpdate = false;
      proxy.matrixWorldAutoUpdate = false;
      proxy.frustumCulled = false;
      this.scene.add(proxy);
      return proxy;
    });
    const counts = [0, 0];
    this.placed = views.map(({ wide }) => ({ wide, layer: counts[wide ? 1 : 0]++ }));
    this.sharp = counts[0] ? arrayTarget(RESOLUTION, counts[0]) : null;
    this.wide = counts[1] ? arrayTarget(WIDE_RESOLUTION, counts[1]) : null;
    this.box = new THREE.Box3();
    this.placedAt = null; // the casters' world matrices the box was fitted to
    this.material = new THREE.ShaderMaterial({
      uniforms: { clip: { value: new THREE.Matrix4() }, depthRow: { value: new THREE.Vector4() } },
      vertexShader: DEPTH_VERTEX,
      fragmentShader: DEPTH_FRAGMENT,
      side: THREE.DoubleSide,
    });
    this.camera = new THREE.Camera(); // (unused by the depth shader)
  }

  /** Whether a caster moved since the maps were drawn (their world matrices). */
  moved() {
    if (!this.placedAt) return true;
    return this.casters.some((mesh, i) => !mesh.matrixWorld.equals(this.placedAt[i]));
  }

  /** The stand-ins at the casters' world matrices, the box (of every vertex) fitted again if they moved. */
  place() {
    if (!this.moved()) return;
    this.casters.forEach((mesh, i) => this.proxies[i].matrixWorld.copy(mesh.matrixWorld));
    this.box.makeEmpty();
    for (const proxy of this.proxies) this.box.expandByObject(proxy, true);
    this.placedAt = this.casters.map((mesh) => mesh.matrixWorld.clone());
  }

  /** Draw each view's map along its direction (same order as the views) with `renderer`; returns
   * per view {rows, texel, resolution, layer, wide}. */
  update(renderer, directions) {
    this.place();
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
      directions.forEach((direction, v) => {
        const { wide, layer } = this.placed[v];
        const resolution = wide ? WIDE_RESOLUTION : RESOLUTION;
        const { rows, clip, texel } = lightRows(direction, this.box, resolution);
        this.material.uniforms.clip.value.copy(clip);
        this.material.uniforms.depthRow.value.set(...rows[2]);
        renderer.setRenderTarget(wide ? this.wide : this.sharp, layer);
        renderer.clear(true, true, false);
        renderer.render(this.scene, this.camera);
        out.push({ rows, texel, resolution, layer, wide });
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
    for (const target of [this.sharp, this.wide]) if (target) target.dispose();
    this.material.dispose();
  }
}
