// PRTLighting: a loaded file's PRT state (materials, lights, shadow maps, rotation, exposure) and its public calls.
//
// Made by the GLTFLoader plugin (plugin.js) for each PRT file; `gltf.userData.prt`. The lighting
// turns by setLightingRotation(R) (glTF world frame, from the file's lighting): the SH of each
// baked mesh by rotationMatrix(R_node^-1 R), the shadow views (directions and samples) by R.
// Each baked mesh's onBeforeRender keeps it up to date with no call from the app: its light
// follows its node's world matrix, and the shadow maps are drawn again (nested render, as
// three.js's Reflector does) when the lighting turned or a caster moved.
import * as THREE from 'three';
import { frameRotation, lightInLocalFrame, multiply3, transpose3 } from './sh_rotation.js';
import { prtMaterial, setLight } from './prt_material.js';
import { MAX_SUNS, ShadowMaps, fileViews } from './shadows.js';
import { rotationRows, turned } from './rotation_input.js';
import { backgroundMesh } from './background.js';
import { Relight } from './relight.js';
import { OcclusionPass } from './occlusion.js';
import { TexelTiles } from './texel_occlusion.js';
import { BAND_COUNT } from './specular.js';

// Blender's display draws a primitive without a material with its default grey (albedo.py).
export const DEFAULT_ALBEDO = [0.8, 0.8, 0.8];
const IDENTITY = [1, 0, 0, 0, 1, 0, 0, 0, 1];

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

export class PRTLighting {
  /**
   * lighting: readLighting's (format.js); baked: [{object, source, spec, albedo, side, surface,
   * constants (a Principled material's, specular.js; null: diffuse only)}] (the meshes to
   * draw with PRT); casters: every mesh of the file (they cast the split lights' shadows).
   */
  constructor({ lighting, baked, casters, exposure, specular = null }) {
    this.lighting = lighting;
    this.lights = lighting.lights.slice(0, MAX_SUNS);
    this.views = fileViews(this.lights);
    const samples = this.views.reduce((n, view) => n + view.samples.length, 0);
    this.neededUniforms = 7 * this.views.length + samples + 16; // the views' vec4s, and a margin
    const extra = lighting.lights_coefficients || [];
    // What a bounced transfer sees: the sky plus the split lights' SH (the exporter's lights_coefficients).
    this.bounceCoefficients = lighting.coefficients.map((row, i) =>
      row.map((v, c) => v + (extra[i] ? extra[i][c] : 0)),
    );
    this.turn = IDENTITY.slice();
    this.shared = {
      exposureScale: { value: 1.0 },
      turnInverse: { value: new THREE.Matrix3() },
      useShadows: { value: true },
      ...viewUniforms(this.views.length, samples),
      sharpMaps: { value: null },
      wideMaps: { value: null },
      // The Principled specular's sky and table (specular.js), when the file has them.
      skyTx: { value: specular ? specular.sky : null },
      brdfTx: { value: specular ? specular.table : null },
      skyRows: { value: new THREE.Matrix3() },
      skySize: {
        value: new THREE.Vector3(...(specular ? [specular.levels, specular.width, specular.height] : [1, 1, 1])),
      },
    };
    this.specular = specular;
    this.setSkyRows();
    const layout = this.views.map((view) => ({
      count: view.samples.length,
      wide: view.wide,
      share: view.weights.reduce((a, b) => a + b, 0), // (of its light's power)
    }));
    this.baked = baked.map(({ object, source, spec, albedo, side, surface, constants }) => {
      const glossy = specular && constants ? { order: spec.order, constants } : null;
      const material = prtMaterial({
        source,
        views: this.views.length,
        samples,
        layout,
        albedo,
        shared: this.shared,
        channels: spec.channels,
        side,
        surface,
        glossy,
        contact: Boolean(spec.contact),
      });
      const relight =
        source.relightSize && (source.relit || source.stage === 'texel')
          ? new Relight(source, material, spec.channels)
          : null;
      if (relight) material.uniforms.prtRadianceTx.value = relight.texture;
      // The full transfer's specular occlusion per vertex, drawn when the view or the node moves.
      const occlusion =
        glossy && source.kind === 'texture'
          ? new OcclusionPass(object.geometry, source, material, Math.min(spec.order, BAND_COUNT))
          : null;
      if (occlusion) material.uniforms.prtOcclusionTx.value = occlusion.texture;
      // A texel bake's: its tiles decoded once, the occlusion summed per pixel (texel_occlusion.js).
      const tiles = glossy && source.stage === 'texel' ? new TexelTiles(source) : null;
      if (tiles) material.uniforms.prtTilesTx.value = tiles.texture;
      object.userData.prtOriginalMaterial = object.material;
      object.material = material;
      const entry = {
        object,
        material,
        source,
        count: spec.count,
        order: spec.order,
        channels: spec.channels,
        frame: null,
        relight,
        occlusion,
        tiles,
      };
      object.onBeforeRender = (renderer, _scene, camera) => this.beforeRender(renderer, entry, camera);
      return entry;
    });
    this.shadows = this.views.length ? new ShadowMaps(casters, this.views) : null;
    this.shadowsDirty = Boolean(this.shadows);
    this.checked = false;
    this.setExposure(exposure ?? Number((lighting.view || {}).exposure || 0));
  }

  /** Turn the lighting by R from the file's own (glTF world frame): a THREE.Matrix3, Matrix4
   * (its rotation), Quaternion or Euler, or 9 numbers (row-major 3x3). */
  setLightingRotation(rotation) {
    this.turn = rotationRows(rotation);
    const r = this.turn;
    this.shared.turnInverse.value.set(r[0], r[3], r[6], r[1], r[4], r[7], r[2], r[5], r[8]);
    for (const entry of this.baked) entry.frame = null; // their lights again (beforeRender)
    this.shadowsDirty = Boolean(this.shadows);
    this.setSkyRows();
  }

  /** The specular sky's lookup rows: glTF world -> the sky's image frame, after undoing the turn. */
  setSkyRows() {
    if (!this.specular) return;
    const r = multiply3(this.specular.rows, transpose3(this.turn));
    this.shared.skyRows.value.set(...r);
  }

  /** The current turn as 9 numbers (row-major 3x3). */
  getLightingRotation() {
    return this.turn.slice();
  }

  /** Turn by `delta` (as setLightingRotation takes it) after the current turn. */
  rotateLightingBy(delta) {
    this.setLightingRotation(multiply3(rotationRows(delta), this.turn));
  }

  /** Exposure in stops: the PRT radiance is multiplied by 2^stops before three.js's tone mapping. */
  setExposure(stops) {
    this.exposure = Number(stops);
    this.shared.exposureScale.value = 2 ** this.exposure;
  }

  /** Shadows of the split lights on (default) or off (visibility 1). */
  setShadows(on) {
    this.shared.useShadows.value = Boolean(on);
  }

  /** A mesh that draws the file's world (its EXT_lights_image_based cube) behind everything,
   * turned with the lighting; null for a file without one. Add it to your scene. */
  async createBackground() {
    const cube = this.environment ? await this.environment() : null;
    return cube ? backgroundMesh(cube, this.shared) : null;
  }

  /** Bring every baked mesh and the shadow maps up to date now (done anyway before each draw). */
  update(renderer) {
    for (const entry of this.baked) this.beforeRender(renderer, entry);
  }

  beforeRender(renderer, entry, camera = null) {
    const map = entry.material.uniforms.prtMap;
    if (map && map.value.matrixAutoUpdate) map.value.updateMatrix(); // (its offset, repeat, rotation)
    this.updateMesh(entry);
    if (entry.relight && entry.relight.dirty) entry.relight.run(renderer);
    if (entry.occlusion && camera) entry.occlusion.update(renderer, camera, entry.object);
    if (entry.tiles) entry.tiles.update(renderer);
    this.updateShadows(renderer);
  }

  updateMesh(entry) {
    const { object, material, count, order, channels } = entry;
    if (entry.frame && entry.frame.equals(object.matrixWorld)) return;
    const frame = linearPart(object.matrixWorld);
    // The light as the transfer source wants it (its decoding folded in, transfer_source.js).
    const direct = entry.source.lightFor(
      lightInLocalFrame(this.lighting.coefficients, frame, order, this.turn),
      [0, 0, 0],
    );
    setLight(material, direct.rows, count);
    material.uniforms.lightConstant.value.set(...direct.constant);
    if (channels) {
      const blocks = channels === 3 ? [1, 2, 3] : [1, 1, 1];
      const bounce = entry.source.lightFor(lightInLocalFrame(this.bounceCoefficients, frame, order, this.turn), blocks);
      setLight(material, bounce.rows, count, 'bounceLight');
      material.uniforms.bounceConstant.value.set(...bounce.constant);
    }
    material.uniforms.nrmMatrix.value.getNormalMatrix(object.matrixWorld);
    material.uniforms.tanMatrix.value.setFromMatrix4(object.matrixWorld); // (a tangent's world direction)
    if (material.uniforms.prtFrame) {
      // The transfer's frame (local SH -> world): the polar factor of the node's matrix.
      const { rotation, mirrored } = frameRotation(frame);
      material.uniforms.prtFrame.value.set(...(mirrored ? rotation.map((x) => -x) : rotation));
    }
    entry.frame = object.matrixWorld.clone();
    if (entry.relight) entry.relight.dirty = true; // (drawn again before the mesh, beforeRender)
  }

  updateShadows(renderer) {
    if (!this.shadows) return;
    if (!this.checked) this.checkUniforms(renderer);
    if (!this.shadowsDirty && !this.shadows.moved()) return;
    this.shadowsDirty = false;
    const s = this.shared;
    const directions = this.views.map(({ direction }) => turned(this.turn, direction));
    const maps = this.shadows.update(renderer, directions);
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

  /** Says so in the console when the views need more fragment uniforms than the GPU has. */
  checkUniforms(renderer) {
    this.checked = true;
    const gl = renderer.getContext();
    const limit = gl.getParameter(gl.MAX_FRAGMENT_UNIFORM_VECTORS);
    if (this.neededUniforms > limit) {
      console.error(
        `PRT Lighting: the lights' ${this.views.length} shadow views need ${this.neededUniforms} fragment uniforms, this GPU has ${limit}: the PRT meshes will not draw`,
      );
    }
  }

  info() {
    return {
      objects: this.baked.map((b) => b.object.name),
      orders: this.baked.map((b) => b.order),
      sources: this.baked.map((b) => b.source.kind),
      lightingOrder: this.lighting.order,
      lights: this.lights.length,
      views: this.views.map(({ light, wide, samples }) => ({ light, wide, samples: samples.length })),
    };
  }

  /** Frees the GPU resources the plugin made (the file's own geometries, materials and textures stay
   * the app's); the meshes get their original materials back. */
  dispose() {
    for (const { object, material, source, relight, occlusion, tiles } of this.baked) {
      object.material = object.userData.prtOriginalMaterial;
      object.onBeforeRender = () => {};
      material.dispose();
      source.dispose();
      if (relight) relight.dispose();
      if (occlusion) occlusion.dispose();
      if (tiles) tiles.dispose();
    }
    if (this.shadows) this.shadows.dispose();
    if (this.specular) [this.specular.sky, this.specular.table].forEach((texture) => texture.dispose());
  }
}
