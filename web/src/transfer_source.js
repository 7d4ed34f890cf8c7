// Where the PRT material reads the transfer from: one small interface; the per-vertex source (a texture read at gl_VertexID).
//
// A transfer source is {stage, count, blocks, uniforms, glsl, dispose()}: `glsl` defines
// `vec4 prtTransfer(int k)`, the k-th vec4 of the transfer (block b's k-th at b * count + k:
// block 0 the direct transfer, then one per bounced channel), callable in `stage`'s shader;
// `uniforms` are merged into the material's. The per-vertex source below ('vertex' stage) holds
// every vertex's vec4s in an RGBA32F texture (any order fits, whatever the limit of 16 vertex
// attributes). A per-texel source (transfer in textures sampled through a lightmap UV) would be
// a 'fragment'-stage source with the same function; prt_material.js puts the sum there then.
import * as THREE from 'three';

const MAX_TEXTURE_WIDTH = 4096;

/** Float32Array (vertices x 4) of a VEC4 attribute, decoded: offset + scale * value (decode null: as is). */
function attributeRows(attr, decode) {
  const n = attr.count;
  const out = new Float32Array(n * 4);
  const plain = !attr.isInterleavedBufferAttribute && attr.itemSize === 4;
  if (plain && !attr.normalized) out.set(attr.array.subarray(0, n * 4));
  else if (plain && attr.array instanceof Int16Array)
    for (let i = 0; i < n * 4; i++) out[i] = Math.max(attr.array[i] / 32767, -1);
  else if (plain && attr.array instanceof Int8Array)
    for (let i = 0; i < n * 4; i++) out[i] = Math.max(attr.array[i] / 127, -1);
  else {
    for (let v = 0; v < n; v++) {
      out[4 * v] = attr.getX(v);
      out[4 * v + 1] = attr.getY(v);
      out[4 * v + 2] = attr.getZ(v);
      out[4 * v + 3] = attr.getW(v);
    }
  }
  if (decode) {
    const { offset, scale } = decode;
    for (let i = 0; i < n * 4; i++) out[i] = offset[i & 3] + scale[i & 3] * out[i];
  }
  return out;
}

/**
 * The per-vertex transfer source from per-vertex rows: `rows` is one Float32Array (vertices x 4)
 * per vec4 of the transfer (count per block, blocks = 1 + bounced channels).
 */
export function vertexTransferSource(rows, count, maxSize = MAX_TEXTURE_WIDTH) {
  const total = rows.length;
  const vertices = rows[0].length / 4;
  const perRow = Math.max(1, Math.floor(Math.min(MAX_TEXTURE_WIDTH, maxSize) / total));
  const height = Math.ceil(vertices / perRow);
  if (height > maxSize) {
    throw new Error(
      `a mesh of ${vertices} vertices at ${total * 4} values needs a ${perRow * total}x${height} texture; ` +
        `this GPU allows ${maxSize}x${maxSize} (split the mesh or bake a lower order)`,
    );
  }
  const width = perRow * total;
  const data = new Float32Array(width * height * 4);
  rows.forEach((values, k) => {
    for (let v = 0; v < vertices; v++) {
      const texel = (Math.floor(v / perRow) * width + (v % perRow) * total + k) * 4;
      data[texel] = values[4 * v];
      data[texel + 1] = values[4 * v + 1];
      data[texel + 2] = values[4 * v + 2];
      data[texel + 3] = values[4 * v + 3];
    }
  });
  const texture = new THREE.DataTexture(data, width, height, THREE.RGBAFormat, THREE.FloatType);
  texture.minFilter = texture.magFilter = THREE.NearestFilter;
  texture.generateMipmaps = false;
  texture.needsUpdate = true;
  return {
    stage: 'vertex',
    count,
    blocks: total / count,
    uniforms: { prtTransferTx: { value: texture }, prtPerRow: { value: perRow } },
    glsl: `
uniform sampler2D prtTransferTx;
uniform int prtPerRow;
vec4 prtTransfer(int k) {
  return texelFetch(prtTransferTx, ivec2((gl_VertexID % prtPerRow) * ${total} + k, gl_VertexID / prtPerRow), 0);
}`,
    dispose: () => texture.dispose(),
  };
}

/** The per-vertex source of a glTF geometry's _PRT_Tk attributes (a readTransfer spec, format.js), decoded. */
export function geometryTransferSource(geometry, spec, maxSize) {
  const rows = spec.names.map((name, k) => {
    const attr = geometry.attributes[name.toLowerCase()] || geometry.attributes[name];
    return attributeRows(attr, spec.decode ? spec.decode[k] : null);
  });
  return vertexTransferSource(rows, spec.count, maxSize);
}
