// The benchmark page: the PRT material against MeshStandardMaterial with the same environment (PMREM) on one large mesh, and a file's load time; window.prtBench.
//
// loadFile(base64) times GLTFLoader + PRTLightingPlugin on a .glb and its first frame; setup(n,
// lights) builds a torus knot of about n triangles drawn several ways: 'prt' (order 8 snorm16
// transfer per vertex summed every frame from a float texture, the plugin's relight: false; the
// file's lighting without its split lights), 'prt_packed' (the same from packed integer vertex
// attributes, transferSource 'packed'), 'prt_relit' (the texture relit once per lighting change,
// the plugin's default: a vertex reads one vec4 a frame), 'prt_relit_turning' (the same with the
// lighting turned before every frame: the relight pass and the frame), 'prt_specular' (relit, with
// the Principled specular: the file's sky and table, its first Principled material's constants;
// when the file has them), 'prt_specular_moving' (the same with the view turned a little before
// every frame, so that its occlusion pass runs in every frame), with `lights` also 'prt_lights' (the file's split lights
// and shadow views) and 'prt_lights_unshadowed' (their cosine terms only), and 'standard'
// (MeshStandardMaterial, white, roughness 0.5, lit by the file's world as a PMREM environment);
// frames(k) draws each in turn k times, each frame finished by reading one pixel back, and
// returns the times in milliseconds.
import * as THREE from 'three';
import { GLTFLoader } from 'three/examples/jsm/loaders/GLTFLoader.js';
import { PRTLightingPlugin, geometryTransferSource, readLighting, readTransfer } from '../src/index.js';
import { packedTransferSource, relitTransferSource } from '../src/transfer_source.js';
import { PRTLighting } from '../src/prt_lighting.js';
import { EXTRAS_KEY } from '../src/plugin.js';
import { readMaterial } from '../src/specular.js';

const WIDTH = 800;
const HEIGHT = 600;
const renderer = new THREE.WebGLRenderer({ antialias: false });
renderer.setSize(WIDTH, HEIGHT, false);
document.body.appendChild(renderer.domElement);
const gl = renderer.getContext();
const pixel = new Uint8Array(4);
const state = {};

function decode(base64) {
  const binary = atob(base64);
  const bytes = new Uint8Array(binary.length);
  for (let i = 0; i < binary.length; i++) bytes[i] = binary.charCodeAt(i);
  return bytes.buffer;
}

function finish() {
  gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, pixel);
}

async function loadFile(base64) {
  const buffer = decode(base64);
  const started = performance.now();
  const loader = new GLTFLoader().register((parser) => new PRTLightingPlugin(parser));
  const gltf = await loader.parseAsync(buffer, '');
  const parsed = performance.now();
  const scene = new THREE.Scene();
  scene.add(gltf.scene);
  const background = await gltf.userData.prt.createBackground();
  scene.add(background);
  const camera = gltf.cameras[0];
  renderer.render(scene, camera);
  finish();
  const drawn = performance.now();
  state.gltf = gltf;
  state.background = background;
  // The file's specular data and its first Principled material's constants (prt_specular).
  const materials = (gltf.parser.json.materials || []).map((m) => readMaterial((m.extras || {})[EXTRAS_KEY]));
  state.specular = gltf.userData.prt.specular;
  state.constants = materials.find(Boolean) || null;
  return { bytes: buffer.byteLength, parse: parsed - started, firstFrame: drawn - parsed };
}

/** Transfer rows at `order` of the clamped cosine about each normal (bands 0-1; the rest 0: the cost is the same). */
function transferRows(normals, vertices, order) {
  const rows = Array.from({ length: Math.ceil((order * order) / 4) }, () => new Float32Array(vertices * 4));
  for (let v = 0; v < vertices; v++) {
    const [x, y, z] = [normals[3 * v], normals[3 * v + 1], normals[3 * v + 2]];
    rows[0].set(
      [
        (0.886227 * 0.282095) / Math.PI,
        (1.023328 * 0.488603 * y) / Math.PI,
        (1.023328 * 0.488603 * z) / Math.PI,
        (1.023328 * 0.488603 * x) / Math.PI,
      ],
      4 * v,
    );
  }
  return rows;
}

/** The rows as the export writes them (snorm16 _PRT_Tk attributes on the geometry); their readTransfer spec. */
function quantised(geometry, rows, order) {
  const decode = rows.map((values, k) => {
    const lo = [Infinity, Infinity, Infinity, Infinity];
    const hi = [-Infinity, -Infinity, -Infinity, -Infinity];
    values.forEach((x, i) => {
      lo[i & 3] = Math.min(lo[i & 3], x);
      hi[i & 3] = Math.max(hi[i & 3], x);
    });
    const offset = lo.map((l, c) => (l + hi[c]) / 2);
    const scale = lo.map((l, c) => (hi[c] - l) / 2);
    const q = Int16Array.from(values, (x, i) =>
      scale[i & 3] ? Math.round(((x - offset[i & 3]) / scale[i & 3]) * 32767) : 0,
    );
    geometry.setAttribute(`_prt_t${k}`, new THREE.BufferAttribute(q, 4, true));
    return { offset, scale };
  });
  const meta = {
    version: 2,
    order,
    attributes: rows.map((_, k) => `_PRT_T${k}`),
    transfer_encoding: 'snorm16',
    decode,
  };
  return readTransfer(meta, geometry);
}

async function setup(triangles, withLights, order = 8) {
  const tubular = Math.round(Math.sqrt(triangles / 2) * 2);
  const radial = Math.round(triangles / 2 / tubular);
  const geometry = new THREE.TorusKnotGeometry(1, 0.35, tubular, radial);
  const count = geometry.index.count / 3;
  const vertices = geometry.attributes.position.count;
  const file = state.gltf.scene.userData.PRT_lighting;
  const camera = new THREE.PerspectiveCamera(40, WIDTH / HEIGHT, 0.1, 50);
  camera.position.set(0, 0.6, 4.2);
  camera.lookAt(0, 0, 0);
  const variants = {};
  const spec = quantised(geometry, transferRows(geometry.attributes.normal.array, vertices, order), order);
  const kinds = [
    ['prt', []],
    ['prt_packed', []],
    ['prt_relit', []],
    ['prt_relit_turning', []],
  ];
  const glossy = Boolean(state.specular && state.constants);
  if (glossy) kinds.push(['prt_specular', []], ['prt_specular_moving', []]);
  if (withLights) kinds.push(['prt_lights', file.lights], ['prt_lights_unshadowed', file.lights]);
  const packed = packedTransferSource(geometry, spec);
  const texture = geometryTransferSource(geometry, spec, renderer.capabilities.maxTextureSize);
  for (const [name, lights] of kinds) {
    const mesh = new THREE.Mesh(geometry);
    const source =
      name === 'prt_packed'
        ? packed
        : name.startsWith('prt_relit') || name.startsWith('prt_specular')
          ? relitTransferSource(texture)
          : texture;
    const lighting = readLighting({ ...file, lights });
    const prt = new PRTLighting({
      lighting,
      baked: [
        {
          object: mesh,
          source,
          spec,
          albedo: [0.8, 0.8, 0.8],
          side: THREE.FrontSide,
          constants: name.startsWith('prt_specular') ? state.constants : null,
        },
      ],
      casters: [mesh],
      exposure: 0,
      specular: name.startsWith('prt_specular') ? state.specular : null,
    });
    const scene = new THREE.Scene();
    scene.add(mesh);
    if (name === 'prt_lights_unshadowed') prt.setShadows(false);
    variants[name] = { scene, prt };
  }
  // MeshStandardMaterial lit by the same world: the file's cube map (the background) into a PMREM.
  const environmentScene = new THREE.Scene();
  environmentScene.add(state.background);
  const pmrem = new THREE.PMREMGenerator(renderer);
  const environment = pmrem.fromScene(environmentScene).texture;
  const standard = new THREE.Scene();
  standard.environment = environment;
  standard.add(
    new THREE.Mesh(geometry, new THREE.MeshStandardMaterial({ color: 0xcccccc, roughness: 0.5, metalness: 0 })),
  );
  variants.standard = { scene: standard };
  state.variants = variants;
  state.camera = camera;
  state.moving = camera.clone();
  const prepare = {};
  const images = {};
  for (const [name, { scene }] of Object.entries(variants)) {
    const started = performance.now();
    renderer.render(scene, camera); // (compile, shadow maps)
    finish();
    prepare[name] = performance.now() - started;
    if (name === 'prt_relit' || name === 'prt_specular') {
      images[name] = new Uint8Array(WIDTH * HEIGHT * 4);
      gl.readPixels(0, 0, WIDTH, HEIGHT, gl.RGBA, gl.UNSIGNED_BYTE, images[name]);
    }
  }
  // The specular drawn: the mean change of the knot's pixels (those not of the clear colour) from the diffuse frame.
  let specularChange = null;
  if (images.prt_specular) {
    const [a, b] = [images.prt_relit, images.prt_specular];
    let sum = 0;
    let covered = 0;
    for (let i = 0; i < a.length; i += 4) {
      if (a[i] + a[i + 1] + a[i + 2] === 0 && b[i] + b[i + 1] + b[i + 2] === 0) continue;
      sum += Math.abs(a[i] - b[i]) + Math.abs(a[i + 1] - b[i + 1]) + Math.abs(a[i + 2] - b[i + 2]);
      covered += 1;
    }
    specularChange = { mean: sum / 3 / Math.max(covered, 1), pixels: covered };
  }
  const rendererName = gl.getParameter(gl.RENDERER);
  return { order, prepare, specularChange, triangles: count, vertices, size: [WIDTH, HEIGHT], renderer: rendererName };
}

function frames(rounds) {
  const times = Object.fromEntries(Object.keys(state.variants).map((name) => [name, []]));
  for (let i = 0; i < rounds; i++) {
    for (const [name, { scene, prt }] of Object.entries(state.variants)) {
      const started = performance.now();
      if (name === 'prt_relit_turning') prt.setLightingRotation(new THREE.Euler(0, 0.01 * (i + 1), 0));
      let camera = state.camera;
      if (name === 'prt_specular_moving') {
        // The view turned a little about the knot before every frame: the occlusion pass runs each time.
        camera = state.moving;
        camera.position.copy(state.camera.position).applyAxisAngle(new THREE.Vector3(0, 1, 0), 0.01 * (i + 1));
        camera.lookAt(0, 0, 0);
        camera.updateMatrixWorld();
      }
      renderer.render(scene, camera);
      finish();
      times[name].push(performance.now() - started);
    }
  }
  return times;
}

window.prtBench = { loadFile, setup, frames };
