// The PRT data of a .glb read and checked (docs/export.md): the scene's lighting, each mesh's transfer description.
//
// Every check throws a FormatError whose message says what is wrong, so that the plugin can log
// it and load the scene without PRT (or the one mesh without it).

export const SCENE_VERSION = 1; // the newest scene `PRT_lighting` this code reads
export const MESH_VERSION = 3; // the newest mesh `PRT_lighting` (2: quantised transfer, 3: per texel)
// Transfer encodings (docs/export.md, "Quantised transfer"): K of glTF's normalised decoding.
export const ENCODINGS = { float32: 0, snorm16: 32767, snorm8: 127 };
// Texel transfer encodings ("Texel transfer"): 8-bit PNG planes per value.
export const TEXEL_ENCODINGS = { unorm16_png: 2, unorm8_png: 1 };

export class FormatError extends Error {}

const isNumber = (x) => typeof x === 'number' && Number.isFinite(x);
const isVector = (x, n) => Array.isArray(x) && x.length === n && x.every(isNumber);

function checkVersion(meta, newest, what) {
  const version = meta.version === undefined ? 1 : meta.version;
  if (!Number.isInteger(version) || version < 1)
    throw new FormatError(`${what} has a bad version (${JSON.stringify(meta.version)})`);
  if (version > newest) {
    throw new FormatError(
      `${what} is format version ${version}, newer than this plugin reads (${newest}): update prt-lighting-three`,
    );
  }
  return version;
}

function checkRows(rows, what) {
  if (!Array.isArray(rows) || !rows.every((row) => isVector(row, 3))) {
    throw new FormatError(`${what} is not a list of [r, g, b] rows`);
  }
  const order = Math.round(Math.sqrt(rows.length));
  if (order < 1 || order * order !== rows.length)
    throw new FormatError(`${what} has ${rows.length} rows, not a square number`);
  return order;
}

function checkLight(light, index) {
  const what = `light ${index}`;
  if (!light || typeof light !== 'object') throw new FormatError(`${what} is not an object`);
  if (!isVector(light.direction, 3) || !isVector(light.power, 3) || !isNumber(light.angle)) {
    throw new FormatError(`${what} lacks a direction, power or angle`);
  }
  if (light.samples != null) {
    const k = Array.isArray(light.samples) ? light.samples.length : -1;
    if (
      k < 1 ||
      !light.samples.every((s) => isVector(s, 3)) ||
      !Array.isArray(light.weights) ||
      light.weights.length !== k
    ) {
      throw new FormatError(`${what} has broken samples or weights`);
    }
  }
  for (const view of light.views || []) {
    if (!isVector(view.direction, 3) || !isNumber(view.angle))
      throw new FormatError(`${what} has a broken shadow view`);
    if (
      view.samples != null &&
      !(
        Array.isArray(view.samples) &&
        view.samples.every((j) => Number.isInteger(j) && j >= 0 && j < (light.samples || []).length)
      )
    ) {
      throw new FormatError(`${what}'s shadow view indexes samples it does not have`);
    }
  }
}

/** The scene's lighting (scene extras PRT_lighting), checked; throws FormatError. */
export function readLighting(meta) {
  if (meta === undefined) throw new FormatError('this glTF has no PRT lighting (a plain glTF: loaded as it is)');
  if (!meta || typeof meta !== 'object' || Array.isArray(meta))
    throw new FormatError('the scene PRT_lighting block is not an object');
  checkVersion(meta, SCENE_VERSION, 'the scene PRT lighting');
  const order = checkRows(meta.coefficients, 'the lighting coefficients');
  if (meta.order !== undefined && meta.order !== order) {
    throw new FormatError(
      `the lighting declares order ${meta.order} but holds ${order * order} coefficients (truncated?)`,
    );
  }
  if (meta.lights_coefficients !== undefined && !Array.isArray(meta.lights_coefficients)) {
    throw new FormatError('the lights coefficients are not a list');
  }
  if (meta.lights_coefficients && meta.lights_coefficients.length)
    checkRows(meta.lights_coefficients, 'the lights coefficients');
  const lights = meta.lights === undefined ? [] : meta.lights;
  if (!Array.isArray(lights)) throw new FormatError('the lights are not a list');
  lights.forEach(checkLight);
  return { ...meta, order, lights };
}

/** {contact, warnings} of a mesh's contact tangent (docs/export.md, "Contact tangent"): the key of
 * the geometry's attribute named by `contact` (x, y, z first, per vertex), or null, drawn without
 * the contact shift (a file from before it, or without split lights; one whose attribute is broken,
 * with a warning). */
function readContact(meta, geometry) {
  if (meta.contact == null) return { contact: null, warnings: [] };
  const key = [String(meta.contact).toLowerCase(), String(meta.contact)].find((k) => geometry.attributes[k]);
  const attr = key && geometry.attributes[key];
  const vertices = geometry.attributes.position ? geometry.attributes.position.count : 0;
  if (attr && attr.itemSize >= 3 && attr.count === vertices) return { contact: key, warnings: [] };
  const warning = `its contact tangent ${meta.contact} is missing or not a vector per vertex: drawn without the contact shift`;
  return { contact: null, warnings: [warning] };
}

/**
 * A mesh's transfer description (mesh extras PRT_lighting) checked against its geometry:
 * {order, count, names, channels, encoding, k, decode, contact, warnings}; throws FormatError.
 */
export function readTransfer(meta, geometry, json = {}) {
  if (!meta || typeof meta !== 'object') throw new FormatError('its PRT_lighting block is not an object');
  checkVersion(meta, MESH_VERSION, 'its PRT transfer');
  return { ...readTransferOnly(meta, geometry, json), ...readContact(meta, geometry) };
}

function readTransferOnly(meta, geometry, json) {
  const order = meta.order;
  if (!Number.isInteger(order) || order < 1 || order > 32)
    throw new FormatError(`it has a bad order (${JSON.stringify(order)})`);
  const count = Math.ceil((order * order) / 4);
  if (meta.domain === 'TEXEL') return readTexelTransfer(meta, geometry, json, order, count);
  const names = meta.attributes;
  if (!Array.isArray(names) || names.length !== count) {
    throw new FormatError(
      `order ${order} needs ${count} transfer attributes, it lists ${Array.isArray(names) ? names.length : 'none'}`,
    );
  }
  const channels = meta.bounce_channels || 0;
  const bounce = meta.bounce_attributes || [];
  if (![0, 1, 3].includes(channels) || !Array.isArray(bounce) || bounce.length !== count * channels) {
    throw new FormatError(`its bounced transfer is inconsistent (${channels} channels, ${bounce.length} attributes)`);
  }
  const all = names.concat(bounce);
  const encoding = meta.transfer_encoding || 'float32';
  if (!(encoding in ENCODINGS)) throw new FormatError(`its transfer encoding '${encoding}' is unknown`);
  const k = ENCODINGS[encoding];
  const decode = k ? meta.decode : null;
  if (
    k &&
    !(
      Array.isArray(decode) &&
      decode.length === all.length &&
      decode.every((d) => d && isVector(d.offset, 4) && isVector(d.scale, 4))
    )
  ) {
    throw new FormatError(`its ${encoding} transfer has no complete decode table`);
  }
  const vertices = geometry.attributes.position ? geometry.attributes.position.count : 0;
  const missing = all.filter((name) => {
    const attr = geometry.attributes[String(name).toLowerCase()] || geometry.attributes[name];
    return !attr || attr.itemSize !== 4 || attr.count !== vertices;
  });
  if (missing.length) {
    throw new FormatError(`order ${order} needs the attributes ${missing.join(', ')}, missing or not VEC4 per vertex`);
  }
  return { order, count, names: all, channels, encoding, k, decode };
}

/** A texel transfer's description (docs/export.md, "Texel transfer") checked against the geometry
 * and the document's textures: {order, count, names: [], channels, encoding, texel, uvName}. */
function readTexelTransfer(meta, geometry, json, order, count) {
  const texel = meta.texel;
  if (!texel || typeof texel !== 'object') throw new FormatError('its texel transfer has no texel block');
  const encoding = meta.transfer_encoding;
  if (!(encoding in TEXEL_ENCODINGS)) throw new FormatError(`its texel encoding '${encoding}' is unknown`);
  const { resolution, tiles, textures, decode, texcoord } = texel;
  if (!Number.isInteger(resolution) || resolution < 1) throw new FormatError('its texel resolution is bad');
  if (!Array.isArray(tiles) || tiles.length !== 2 || !tiles.every((t) => Number.isInteger(t) && t > 0))
    throw new FormatError('its texel tiles are bad');
  const channels = meta.bounce_channels || 0;
  if (![0, 1, 3].includes(channels)) throw new FormatError(`its texel transfer has ${channels} bounce channels`);
  const bounceTextures = channels ? texel.bounce_textures : [];
  const bounceDecode = channels ? texel.bounce_decode : [];
  if (!Array.isArray(bounceTextures) || !Array.isArray(bounceDecode))
    throw new FormatError('its texel transfer declares bounced light without its bounce planes');
  if (bounceTextures.length !== channels || bounceDecode.length !== channels)
    throw new FormatError(`its texel transfer declares ${channels} bounce channels, it has ${bounceTextures.length}`);
  const parts = [[textures, decode, 'transfer'], ...bounceTextures.map((t, c) => [t, bounceDecode[c], `bounce ${c}`])];
  for (const [planes, table, what] of parts) checkTexelPart(planes, table, what, encoding, count, json);
  if (count > tiles[0] * tiles[1]) throw new FormatError(`its ${count} tiles do not fit its tile grid`);
  const uvName = texcoord === 0 ? 'uv' : `uv${texcoord}`;
  const uv = Number.isInteger(texcoord) && texcoord >= 0 ? geometry.attributes[uvName] : undefined;
  const vertices = geometry.attributes.position ? geometry.attributes.position.count : 0;
  if (!uv || uv.itemSize !== 2 || uv.count !== vertices)
    throw new FormatError(`its lightmap UV map TEXCOORD_${texcoord} is missing`);
  return { order, count, names: [], channels, encoding, texel, uvName };
}

/** One part of a texel transfer (the direct one or a bounce channel's): its planes are textures
 * of the file with an image, its decode table has one entry per tile. */
function checkTexelPart(textures, decode, what, encoding, count, json) {
  const known = (json.textures || []).length;
  const images = json.images || [];
  if (
    !Array.isArray(textures) ||
    textures.length !== TEXEL_ENCODINGS[encoding] ||
    !textures.every(
      (t) =>
        Number.isInteger(t) &&
        t >= 0 &&
        t < known &&
        images[json.textures[t].source] &&
        images[json.textures[t].source].bufferView !== undefined,
    )
  )
    throw new FormatError(`its ${encoding} ${what} needs ${TEXEL_ENCODINGS[encoding]} texture(s) in the file`);
  if (
    !(
      Array.isArray(decode) &&
      decode.length === count &&
      decode.every((d) => d && isVector(d.offset, 4) && isVector(d.scale, 4))
    )
  )
    throw new FormatError(`its texel ${what} has no complete decode table (${count} tiles)`);
}
