// A loaded PRT .glb made drawable: each baked primitive gets the PRT material, the lighting turns.
//
// Reads the format of docs/export.md: scene extras PRT_lighting (world SH in glTF's frame, split
// lights), mesh extras PRT_lighting (order, the _PRT_Tk attribute names). setTurn(R) turns the
// lighting by the 3x3 rotation R (glTF world frame): the SH by rotationMatrix(R_node^-1 R), the
// lights' shadow views (directions and samples) by R; their maps are drawn again before the next
// frame (prepare).
import * as THREE from 'three';
import { GLTFLoader } from 'three/examples/jsm/loaders/GLTFLoader.js';
import { lightInLocalFrame, multiply3 } from './sh_rotation.js';
import { prtMaterial, setLight, transferTexture } from './prt_material.js';
import { MAX_SUNS, ShadowMaps, fileViews } from './shadows.js';

/** The 3-vector d turned by the row-major 3x3 r. */
function turned(r, d) {
  return [
    r[0] * d[0] + r[1] * d[1] + r[2] * d[2],
    r[3] * d[0] + r[4] * d[1] + r[5] * d[2],
    r[6] * d[0] + r[7] * d[1] + r[8] * d[2],
  ];
}

// Blender's display draws a primitive without a material with its default grey (albedo.py).
export const DEFAULT_ALBEDO = [0.8, 0.8, 0.8];
const IDENTITY = [1, 0, 0, 0, 1, 0, 0, 0, 1];

export async function parseGLB(buffer) {
  const loader = new GLTFLoader();
  return loader.parseAsync(buffer, '');
}

function linearPart(matrix) {
  const e = matrix.elements; // column-major
  return [e[0], e[4], e[8], e[1], e[5], e[9], e[2], e[6], e[10]];
}

/** The shared uniforms of `views` shadow views holding `samples` samples (prt_material.js). */
function viewUniforms(views, samples) {
  const vec4s = (length) => ({ value: Array.from({ length: Math.max(1, length) }, () => new THREE.Vector4()) });
  return {
    sunRows: vec4s(3 * views),
    sunDir: vec4s(views),
    sunPower: vec4s(views),
    sunParams: vec4s(views),
    sunRange: vec4s(views),
    sunSamples: vec4s(samples),
  };
}

export class PRTScene {
  constructor(gltf, renderer) {
    this.gltf = gltf;
    // GLTFLoader's scene is a Group: a Scene around it (overrideMaterial, for the shadow pass).
    this.scene = new THREE.Scene();
    this.scene.add(gltf.scene);
    this.renderer = renderer;
    const lighting = gltf.scene.userData.PRT_lighting;
    if (!lighting || !Array.isArray(lighting.coefficients)) {
      throw new Error('this .glb has no PRT lighting (export it with PRT Lighting: File > Export > PRT Lighting)');
    }
    this.lighting = lighting;
    this.lights = (lighting.lights || []).slice(0, MAX_SUNS);
    this.views = fileViews(this.lights);
    const samples = this.views.reduce((n, view) => n + view.samples.length, 0);
    this.checkUniforms(renderer, this.views.length, samples);
    // What a bounced transfer sees: the sky plus the split lights' SH (the exporter's lights_coefficients).
    const extra = lighting.lights_coefficients || [];
    this.bounceCoefficients = lighting.coefficients.map((row, i) => row.map((v, c) => v + (extra[i] ? extra[i][c] : 0)));
    this.turn = IDENTITY.slice();
    this.shared = {
      display: { value: true },
      exposureScale: { value: 1.0 },
      useShadows: { value: true },
      ...viewUniforms(this.views.length, samples),
      sharpMaps: { value: null },
      wideMaps: { value: null },
    };
    this.baked = [];
    this.scene.updateMatrixWorld(true);
    const json = gltf.parser.json;
    const textures = new Map();
    this.scene.traverse((object) => {
      if (!object.isMesh) return;
      object.frustumCulled = false;
      const meta = object.userData.PRT_lighting;
      if (!meta || !Array.isArray(meta.attributes)) return;
      const index = gltf.parser.associations.get(object);
      const primitive = index ? json.meshes[index.meshes].primitives[index.primitives] : {};
      const albedo =
        primitive.material === undefined || !object.material.color
          ? DEFAULT_ALBEDO
          : [object.material.color.r, object.material.color.g, object.material.color.b];
      // (A mesh used by several nodes shares one geometry: one texture.)
      if (!textures.has(object.geometry)) {
        const maxSize = renderer.capabilities.maxTextureSize;
        const names = meta.attributes.concat(meta.bounce_attributes || []);
        textures.set(object.geometry, transferTexture(object.geometry, names, maxSize));
        for (const name of names) object.geometry.deleteAttribute(name.toLowerCase());
      }
      const { texture, perRow } = textures.get(object.geometry);
      const count = meta.attributes.length;
      const channels = meta.bounce_channels || 0;
      const views = this.views.length;
      const shared = this.shared;
      const material = prtMaterial({ count, views, samples, texture, perRow, albedo, shared, channels });
      material.uniforms.nrmMatrix.value.getNormalMatrix(object.matrixWorld);
      object.material = material;
      this.baked.push({ object, material, count, order: meta.order, channels });
    });
    if (!this.baked.length) throw new Error('this .glb holds no baked mesh (no _PRT_T attributes)');
    this.shadows = this.views.length ? new ShadowMaps(renderer, this.scene, this.views) : null;
    this.camera = gltf.cameras && gltf.cameras.length ? gltf.cameras[0] : null;
    this.setTurn(IDENTITY);
  }

  /** Turn the lighting by R (row-major 3x3, glTF world frame) from the file's own. */
  setTurn(turn) {
    this.turn = Array.from(turn);
    for (const { object, material, count, order, channels } of this.baked) {
      const frame = linearPart(object.matrixWorld);
      setLight(material, lightInLocalFrame(this.lighting.coefficients, frame, order, this.turn), count);
      if (channels) setLight(material, lightInLocalFrame(this.bounceCoefficients, frame, order, this.turn), count, 'bounceLight');
    }
    this.shadowsDirty = Boolean(this.shadows); // drawn again before the next frame (prepare)
  }

  /** Before drawing: the shadow maps of the current turn (once per turn, however many moves). */
  prepare() {
    if (this.shadowsDirty) this.updateLights();
    this.shadowsDirty = false;
  }

  /** Turn by `delta` after the current turn. */
  turnBy(delta) {
    this.setTurn(multiply3(delta, this.turn));
  }

  /** Refuses, with a message, a file whose views need more fragment uniforms than the GPU has. */
  checkUniforms(renderer, views, samples) {
    const needed = 7 * views + samples + 16; // the views' vec4s, and a margin for the rest
    const gl = renderer.getContext();
    const limit = gl.getParameter(gl.MAX_FRAGMENT_UNIFORM_VECTORS);
    if (views && needed > limit) {
      throw new Error(`the lights' ${views} shadow views need ${needed} fragment uniforms, this GPU has ${limit}`);
    }
  }

  updateLights() {
    const s = this.shared;
    const directions = this.views.map(({ direction }) => turned(this.turn, direction));
    const maps = this.shadows.update(directions);
    let first = 0;
    this.views.forEach((view, v) => {
      const d = directions[v];
      const n = Math.hypot(d[0], d[1], d[2]);
      s.sunDir.value[v].set(d[0] / n, d[1] / n, d[2] / n, 0);
      s.sunPower.value[v].set(...this.lights[view.light].power.map((p) => p / Math.PI), 0);
      const { rows, texel, resolution, layer, wide } = maps[v];
      s.sunParams.value[v].set(texel, Math.tan(Math.min(view.angle, 1.5)), resolution, 0);
      s.sunRange.value[v].set(first, view.samples.length, layer, wide ? 1 : 0);
      // The view's part of the cosine term: sum_j w_j max(0, n . s_j) over its samples.
      view.samples.forEach((sample, j) => {
        s.sunSamples.value[first + j].set(...turned(this.turn, sample), view.weights[j]);
      });
      first += view.samples.length;
      for (let j = 0; j < 3; j++) s.sunRows.value[3 * v + j].set(...rows[j]);
    });
    s.sharpMaps.value = this.shadows.sharp ? this.shadows.sharp.texture : null;
    s.wideMaps.value = this.shadows.wide ? this.shadows.wide.texture : null;
  }

  info() {
    return {
      objects: this.baked.map((b) => b.object.name),
      orders: this.baked.map((b) => b.order),
      lightingOrder: this.lighting.order,
      lights: this.lights.length,
      views: this.views.map(({ light, wide, samples }) => ({ light, wide, samples: samples.length })),
      camera: Boolean(this.camera),
    };
  }
}
