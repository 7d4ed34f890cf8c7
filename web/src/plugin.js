// The GLTFLoader plugin: a PRT Lighting .glb comes out of the loader drawable with PRT (gltf.userData.prt).
//
//   loader.register((parser) => new PRTLightingPlugin(parser, { exposure, maxTextureSize }));
//
// afterRoot reads the scene's and each mesh's PRT_lighting extras (format.js), gives every baked
// primitive the PRT material (its transfer through a transfer source, transfer_source.js) and
// leaves every other mesh and material alone. What is wrong with a file is said in the console
// (prefix "PRT Lighting:") and the scene still loads: without PRT when the lighting is missing,
// newer or broken (gltf.userData.prt is then null), a mesh whose transfer is broken keeps its
// own material.
import { readLighting, readTransfer } from './format.js';
import {
  geometryTransferSource,
  packedTransferSource,
  relitTransferSource,
  texelTransferSource,
} from './transfer_source.js';
import { DEFAULT_ALBEDO, PRTLighting } from './prt_lighting.js';
import { loadEnvironment } from './background.js';
import { loadF0Map, loadSpecular, readMaterial } from './specular.js';

export const EXTRAS_KEY = 'PRT_lighting';

function say(level, message) {
  console[level](`PRT Lighting: ${message}`);
}

/** What of the source material varies per pixel (prt_material.js): its base colour map, its
 * vertex colours when it uses them and the geometry has them (GLTFLoader's COLOR_0), and its
 * roughness and metalness maps with their factors (used where the file says Blender reads them). */
function baseColorSurface(object) {
  const material = object.material || {};
  return {
    map: material.map || null,
    vertexColors: Boolean(material.vertexColors && object.geometry.getAttribute('color')),
    roughnessMap: material.roughnessMap || null,
    metalnessMap: material.metalnessMap || null,
    roughness: material.roughness ?? 1,
    metalness: material.metalness ?? 1,
  };
}

export class PRTLightingPlugin {
  /** options: {exposure (stops; default the file's), maxTextureSize (default 4096), quiet (no
   * message for a glTF without PRT data), transferSource ('texture', the default: the decoded
   * transfer in a float texture; 'packed': a quantised transfer's integers in packed vertex
   * attributes when they fit, half the GPU memory, slower in software WebGL: docs/export.md),
   * relight (true, the default: the texture's sums drawn once per lighting change into a texture
   * each vertex reads; false: summed per vertex every frame), specular (true, the default: the
   * Principled specular of docs/specular.md on meshes whose material is a Principled one, when the
   * file carries the specular sky and table; false: the diffuse only). A texel bake is always relit. */
  constructor(parser, options = {}) {
    this.parser = parser;
    this.options = options;
    this.name = 'PRT_lighting'; // (extras, not an extension: GLTFLoader calls afterRoot all the same)
    this.prt = null;
  }

  /** The transfer source of a geometry (transfer_source.js): per texel for a texel bake, else
   * the option's (the texture relit once per lighting change by default). */
  transferSource(geometry, spec) {
    if (spec.texel) return texelTransferSource(this.parser, geometry, spec);
    const choice = this.options.transferSource || 'texture';
    const packed = choice === 'packed' ? packedTransferSource(geometry, spec) : null;
    if (packed) return packed;
    const texture = geometryTransferSource(geometry, spec, this.options.maxTextureSize);
    return this.options.relight === false ? texture : relitTransferSource(texture);
  }

  /** Each baked material's dielectric F0 map (specular.js's loadF0Map; one texture per bufferView);
   * one that cannot be read is said, and its material's constant F0 drawn. */
  async loadF0Maps(baked) {
    const textures = new Map();
    for (const { constants } of baked) {
      const block = constants && constants.f0Block;
      if (!block) continue;
      if (!textures.has(block.bufferView)) textures.set(block.bufferView, loadF0Map(this.parser, block));
      try {
        constants.f0Map = await textures.get(block.bufferView);
      } catch (error) {
        say('error', `a material's F0 map cannot be read (${error.message}); its constant F0 is drawn`);
      }
    }
  }

  async afterRoot(gltf) {
    gltf.userData.prt = null;
    const json = this.parser.json;
    const scene = (json.scenes || [])[json.scene || 0] || {};
    const meta = (scene.extras || {})[EXTRAS_KEY];
    let lighting;
    try {
      lighting = readLighting(meta);
    } catch (error) {
      // (any error: a FormatError, or data too broken for the checks themselves)
      if (meta === undefined) {
        if (!this.options.quiet) say('info', error.message);
      } else say('error', `${error.message}; the scene is drawn without PRT`);
      return;
    }
    const baked = [];
    const casters = [];
    const sources = new Map(); // a geometry shared by several nodes: one transfer source
    gltf.scene.updateMatrixWorld(true);
    gltf.scene.traverse((object) => {
      if (!object.isMesh) return;
      casters.push(object);
      const where = this.parser.associations.get(object);
      if (!where || where.meshes === undefined) return;
      const mesh = json.meshes[where.meshes];
      const transfer = (mesh.extras || {})[EXTRAS_KEY];
      if (transfer === undefined) return;
      const name = mesh.name || `mesh ${where.meshes}`;
      try {
        const spec = readTransfer(transfer, object.geometry, json);
        for (const warning of spec.warnings) say('warn', `mesh '${name}': ${warning}`);
        if (!sources.has(object.geometry)) {
          sources.set(object.geometry, this.transferSource(object.geometry, spec));
          for (const attr of spec.names) object.geometry.deleteAttribute(attr.toLowerCase());
          // The contact tangent, as the shader reads it (prt_material.js; normalised bytes: the GPU decodes them).
          if (spec.contact) object.geometry.setAttribute('prtContact', object.geometry.getAttribute(spec.contact));
        }
        const primitive = mesh.primitives[where.primitives] || {};
        const color = object.material && object.material.color;
        const albedo = primitive.material === undefined || !color ? DEFAULT_ALBEDO : [color.r, color.g, color.b];
        object.frustumCulled = false; // (as before the plugin: the bounding box is the file's)
        const side = object.material ? object.material.side : undefined; // (glTF's doubleSided)
        const surface = primitive.material === undefined ? {} : baseColorSurface(object);
        const gltfMaterial = primitive.material === undefined ? null : (json.materials || [])[primitive.material];
        const constants = gltfMaterial ? readMaterial((gltfMaterial.extras || {})[EXTRAS_KEY]) : null;
        baked.push({ object, spec, albedo, side, surface, constants, source: sources.get(object.geometry) });
      } catch (error) {
        // (a FormatError, or e.g. a transfer texture larger than the GPU allows)
        say('error', `mesh '${name}': ${error.message}; drawn with its own material`);
      }
    });
    try {
      await Promise.all([...sources.values()].map((source) => source.ready));
    } catch (error) {
      say('error', `the texel transfer's images cannot be read (${error.message}); drawn without PRT`);
      return;
    }
    if (!baked.length) {
      say('warn', 'the file has PRT lighting but no mesh with a usable transfer: drawn without PRT');
      return;
    }
    let specular = null;
    if (this.options.specular !== false) {
      try {
        specular = await loadSpecular(this.parser, meta.specular);
      } catch (error) {
        say('error', `the specular data cannot be read (${error.message}); drawn diffuse only`);
      }
      if (specular) await this.loadF0Maps(baked);
    }
    try {
      this.prt = new PRTLighting({ lighting, baked, casters, exposure: this.options.exposure, specular });
    } catch (error) {
      say('error', `${error.message}; the scene is drawn without PRT`);
      for (const { object } of baked) object.frustumCulled = true;
      return;
    }
    this.prt.environment = () => loadEnvironment(this.parser);
    gltf.userData.prt = this.prt;
  }
}
