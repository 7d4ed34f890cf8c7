// Where the PRT material reads the transfer from: one small interface; per vertex from packed integer attributes or a texture.
//
// A transfer source is {kind, stage, count, blocks, uniforms, glsl, fetch(k), lightFor(rows, blocks),
// dispose()}: fetch(k) is a GLSL expression (glsl declares what it needs) for the k-th vec4 of
// the transfer, k a constant (block b's k-th at b * count + k: block 0 the direct transfer, then
// one per bounced channel), in `stage`'s shader; `uniforms` are merged into the material's.
// lightFor(rows, blocks) turns the light (n*n rows of [r, g, b]; channel c lit against block
// blocks[c]) into what the shader dots with the fetched vec4s, and a constant per channel: a
// source whose fetch returns coded values folds their decoding in there. Two per-vertex
// ('vertex' stage) sources: the quantised transfer as the file's integers packed two to an int32
// in a few vertex attributes (decoding folded into the light: sum L_i (o_i + s_i q_i / K) =
// sum L_i o_i + sum (L_i s_i / K) q_i), and any transfer decoded into an RGBA32F texture read at
// gl_VertexID (any order fits, whatever the limit of 16 vertex attributes), by default relit once
// per lighting change (relight.js: relightSize, relightGlsl, relightFetch(k) draw the sums into a
// texture, radianceVertex reads a vertex's). The per-texel source ('texel' stage) reads a texel
// bake's PNG planes in the relight pass and the material looks the relit texture up per pixel.
import * as THREE from 'three';

const MAX_TEXTURE_WIDTH = 4096;
// Vertex attributes the packed source may take (of WebGL2's 16: position, normal and a margin
// for an app's own).
export const MAX_PACKED_ATTRIBUTES = 10;

const plainLight = (rows) => ({ rows, constant: [0, 0, 0] });

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
    kind: 'texture',
    stage: 'vertex',
    count,
    blocks: total / count,
    uniforms: { prtTransferTx: { value: texture }, prtPerRow: { value: perRow } },
    fetch: (k) => `prtTransfer(${k})`,
    lightFor: plainLight,
    glsl: `
uniform sampler2D prtTransferTx;
uniform int prtPerRow;
vec4 prtTransfer(int k) {
  return texelFetch(prtTransferTx, ivec2((gl_VertexID % prtPerRow) * ${total} + k, gl_VertexID / prtPerRow), 0);
}`,
    // Relit once per lighting change (relight.js): one fragment per vertex at (v % perRow, v / perRow).
    relightSize: [perRow, height],
    relightGlsl: `
uniform sampler2D prtTransferTx;`,
    relightFetch: (k) => `texelFetch(prtTransferTx, ivec2(p.x * ${total} + ${k}, p.y), 0)`,
    relitVertex: 'texelFetch(prtRadianceTx, ivec2(gl_VertexID % prtPerRow, gl_VertexID / prtPerRow), 0).rgb',
    dispose: () => texture.dispose(),
  };
}

/** The texture source relit once per lighting change (relight.js): the vertex stage reads one
 * vec4 per vertex whatever the order (docs/export.md, "Speed"). */
export function relitTransferSource(source) {
  return { ...source, radianceVertex: source.relitVertex, relit: true };
}

/** The per-vertex source of a glTF geometry's _PRT_Tk attributes (a readTransfer spec, format.js), decoded. */
export function geometryTransferSource(geometry, spec, maxSize) {
  const rows = spec.names.map((name, k) => {
    const attr = geometry.attributes[name.toLowerCase()] || geometry.attributes[name];
    return attributeRows(attr, spec.decode ? spec.decode[k] : null);
  });
  return vertexTransferSource(rows, spec.count, maxSize);
}

/** The integers of a normalised attribute (Int16Array or Int8Array, count x 4), whatever its layout. */
function attributeIntegers(attr, k) {
  if (!attr.isInterleavedBufferAttribute && attr.itemSize === 4 && attr.normalized) return attr.array;
  const out = new Int16Array(attr.count * 4);
  for (let v = 0; v < attr.count; v++) {
    out[4 * v] = Math.round(attr.getX(v) * k);
    out[4 * v + 1] = Math.round(attr.getY(v) * k);
    out[4 * v + 2] = Math.round(attr.getZ(v) * k);
    out[4 * v + 3] = Math.round(attr.getW(v) * k);
  }
  return out;
}

/**
 * The packed per-vertex source of a quantised glTF geometry (a readTransfer spec with k > 0),
 * or null when it needs more than MAX_PACKED_ATTRIBUTES attributes: vec4s 2j and 2j + 1 as the
 * low and high 16 bits of the ivec4 attribute prtPacked<j>.
 */
export function packedTransferSource(geometry, spec) {
  const total = spec.names.length;
  const slots = Math.ceil(total / 2);
  if (!spec.k || slots > MAX_PACKED_ATTRIBUTES) return null;
  const vertices = geometry.attributes.position.count;
  const ints = spec.names.map((name) =>
    attributeIntegers(geometry.attributes[name.toLowerCase()] || geometry.attributes[name], spec.k),
  );
  const names = [];
  for (let j = 0; j < slots; j++) {
    const lo = ints[2 * j];
    const hi = ints[2 * j + 1];
    const data = new Int32Array(vertices * 4);
    for (let i = 0; i < vertices * 4; i++) data[i] = (lo[i] & 0xffff) | (hi ? hi[i] << 16 : 0);
    const attr = new THREE.Int32BufferAttribute(data, 4);
    attr.gpuType = THREE.IntType;
    geometry.setAttribute(`prtPacked${j}`, attr);
    names.push(`prtPacked${j}`);
  }
  const { decode, k, count } = spec;
  return {
    kind: 'packed',
    stage: 'vertex',
    count,
    blocks: total / count,
    uniforms: {},
    glsl: `${names.map((n) => `attribute ivec4 ${n};`).join('\n')}
vec4 prtLow(ivec4 v) { return vec4((v << 16) >> 16); }
vec4 prtHigh(ivec4 v) { return vec4(v >> 16); }`,
    fetch: (i) => `${i % 2 ? 'prtHigh' : 'prtLow'}(prtPacked${i >> 1})`,
    /** rows[i][c] * s / K for coefficient i = 4k + j of block blocks[c], and sum_i rows[i][c] * o. */
    lightFor(rows, blocks) {
      const constant = [0, 0, 0];
      const out = rows.map((row, i) =>
        row.map((value, c) => {
          const entry = decode[blocks[c] * count + (i >> 2)];
          if (!entry) return 0;
          constant[c] += value * entry.offset[i & 3];
          return (value * entry.scale[i & 3]) / k;
        }),
      );
      return { rows: out, constant };
    },
    dispose: () => names.forEach((n) => geometry.deleteAttribute(n)),
  };
}

/** An ImageBitmap of a glTF texture's PNG, its bytes exactly (no premultiplication, no colour
 * conversion, no flip: row 0 the PNG's top row, v_glTF = 0). */
async function planeTexture(parser, index) {
  const json = parser.json;
  const image = json.images[json.textures[index].source];
  const data = await parser.getDependency('bufferView', image.bufferView);
  const bitmap = await createImageBitmap(new Blob([data], { type: image.mimeType || 'image/png' }), {
    premultiplyAlpha: 'none',
    colorSpaceConversion: 'none',
    imageOrientation: 'none',
  });
  const texture = new THREE.Texture(bitmap);
  texture.colorSpace = THREE.NoColorSpace;
  texture.flipY = false;
  texture.premultiplyAlpha = false;
  texture.generateMipmaps = false;
  texture.minFilter = texture.magFilter = THREE.NearestFilter;
  texture.needsUpdate = true;
  return texture;
}

/**
 * The per-texel source of a texel bake (a readTransfer spec with spec.texel, format.js): the PNG
 * planes of docs/export.md ("Texel transfer"), decoded in the relight pass (relight.js) into one
 * radiance texel per lightmap texel, which the material looks up per pixel at the lightmap UV.
 * `ready` resolves when the planes are loaded.
 */
export function texelTransferSource(parser, geometry, spec) {
  const { resolution, tiles } = spec.texel;
  // Part 0 the direct transfer, part 1 + c bounce channel c's (docs/export.md): each its own
  // planes and decode table, laid out in the same tiles; relight.js's index k of block b is part b.
  const parts = [[spec.texel.textures, spec.texel.decode]];
  for (let c = 0; c < spec.channels; c++) parts.push([spec.texel.bounce_textures[c], spec.texel.bounce_decode[c]]);
  const planes = parts[0][0].length;
  const uvAttribute = 'prtLightmapUv';
  geometry.setAttribute(uvAttribute, geometry.getAttribute(spec.uvName));
  const decode = parts.flatMap(([, table]) => table);
  const vec4s = (key) => decode.map((entry) => new THREE.Vector4(...entry[key]));
  const uniforms = {
    prtDecodeOffset: { value: vec4s('offset') },
    prtDecodeScale: { value: vec4s('scale') },
  };
  const samplers = parts.flatMap(([textures], b) => textures.map((_t, p) => `prtPlane${b}_${p}`));
  samplers.forEach((name) => (uniforms[name] = { value: null }));
  const levels = 256 ** planes - 1;
  const lookup = (b) => {
    const bytes = parts[b][0].map((_t, p) => `floor(texelFetch(prtPlane${b}_${p}, q, 0) * 255.0 + 0.5)`);
    let combined = bytes[0];
    for (let p = 1; p < planes; p++) combined = `(${combined}) * 256.0 + ${bytes[p]}`;
    return `
vec4 prtTexel${b}(int k, ivec2 p) {
  ivec2 q = ivec2((k % ${tiles[0]}) * ${resolution}, (k / ${tiles[0]}) * ${resolution}) + p;
  int d = ${b * spec.count} + k;
  return prtDecodeOffset[d] + prtDecodeScale[d] * ((${combined}) / ${levels.toFixed(1)});
}`;
  };
  const source = {
    kind: 'texel',
    stage: 'texel',
    count: spec.count,
    blocks: parts.length,
    resolution,
    tiles, // (the planes' tile grid: tile k at column k % tiles[0]; texel_occlusion.js decodes the direct ones)
    uvAttribute,
    uniforms,
    glsl: '',
    fetch: () => {
      throw new Error('a texel source is read through its relit texture');
    },
    lightFor: plainLight,
    relightSize: [resolution, resolution],
    relightGlsl: `
${samplers.map((name) => `uniform sampler2D ${name};`).join('\n')}
uniform vec4 prtDecodeOffset[${decode.length}];
uniform vec4 prtDecodeScale[${decode.length}];
${parts.map((_p, b) => lookup(b)).join('\n')}`,
    relightFetch: (k) => `prtTexel${Math.floor(k / spec.count)}(${k % spec.count}, p)`,
    dispose: () => {
      samplers.forEach((name) => uniforms[name].value && uniforms[name].value.dispose());
      geometry.deleteAttribute(uvAttribute);
    },
  };
  const indices = parts.flatMap(([textures]) => textures);
  source.ready = Promise.all(indices.map((index) => planeTexture(parser, index))).then((loaded) => {
    loaded.forEach((texture, i) => (uniforms[samplers[i]].value = texture));
  });
  return source;
}
