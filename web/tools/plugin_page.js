// A three.js app page for the tests: the plugin's files loaded beside the app's own objects, lights and tone mapping; window.pluginTest.
//
// load(name, base64, plugin, options) parses a .glb with GLTFLoader (with PRTLightingPlugin and
// its options, or without);
// render(options) draws the app's scene (optionally an ordinary lit sphere, the app's lights, the
// file turned by `spin` about up, its background) into a float target (linear, no tone mapping) or to the canvas (the
// renderer's tone mapping and sRGB output) and returns the RGBA pixels as base64 (float32 or
// bytes, top row first); describe(name) says what the loader made of the file's meshes;
// release(name) frees the file as an app would (the plugin's dispose(), then the scene's own
// geometries, materials and textures) and returns the renderer's count of what it still holds.
import * as THREE from 'three';
import { GLTFLoader } from 'three/examples/jsm/loaders/GLTFLoader.js';
import { PRTLightingPlugin } from '../src/index.js';
import { freeScene } from '../src/free_scene.js';

const renderer = new THREE.WebGLRenderer({ antialias: false, preserveDrawingBuffer: true });
document.body.appendChild(renderer.domElement);
const files = {};

function toBase64(array) {
  const bytes = new Uint8Array(array.buffer, array.byteOffset, array.byteLength);
  let text = '';
  for (let i = 0; i < bytes.length; i += 0x8000) text += String.fromCharCode(...bytes.subarray(i, i + 0x8000));
  return btoa(text);
}

function flip(pixels, width, height, channels) {
  const out = new pixels.constructor(pixels.length);
  const row = width * channels;
  for (let y = 0; y < height; y++) out.set(pixels.subarray((height - 1 - y) * row, (height - y) * row), y * row);
  return out;
}

async function load(name, base64, plugin = true, options = {}) {
  const binary = atob(base64);
  const bytes = new Uint8Array(binary.length);
  for (let i = 0; i < binary.length; i++) bytes[i] = binary.charCodeAt(i);
  const loader = new GLTFLoader();
  if (plugin) loader.register((parser) => new PRTLightingPlugin(parser, options));
  const gltf = await loader.parseAsync(bytes.buffer, '');
  const background = gltf.userData.prt ? await gltf.userData.prt.createBackground() : null;
  files[name] = { gltf, background };
  return describe(name);
}

function describe(name) {
  const { gltf, background } = files[name];
  const meshes = [];
  gltf.scene.traverse(
    (o) =>
      o.isMesh && meshes.push({ name: o.name, material: o.material.type, prt: o.material.isShaderMaterial === true }),
  );
  return {
    prt: Boolean(gltf.userData.prt),
    info: gltf.userData.prt ? gltf.userData.prt.info() : null,
    meshes,
    background: Boolean(background),
  };
}

function render({
  name,
  width,
  height,
  target = 'float',
  toneMapping = 'None',
  toneExposure = 1,
  exposure = 0,
  ordinary = false,
  appLights = false,
  background = false,
  turn = null,
  camera = null,
  spin = 0,
}) {
  const scene = new THREE.Scene();
  const file = name ? files[name] : null;
  if (file) {
    file.gltf.scene.rotation.y = spin; // the app turning the model (about up, radians)
    scene.add(file.gltf.scene);
    if (background && file.background) scene.add(file.background);
    const prt = file.gltf.userData.prt;
    if (prt) {
      prt.setExposure(exposure);
      prt.setLightingRotation(turn || [1, 0, 0, 0, 1, 0, 0, 0, 1]);
    }
  }
  if (ordinary) {
    const sphere = new THREE.Mesh(
      new THREE.SphereGeometry(0.35, 48, 24),
      new THREE.MeshStandardMaterial({ color: 0xcc3322, roughness: 0.6 }),
    );
    sphere.position.set(2.6, 0.4, 1.2); // (glTF; Blender (2.6, -1.2, 0.4): between the demo camera and Suzanne, off its line)
    scene.add(sphere);
  }
  if (appLights) {
    const sun = new THREE.DirectionalLight(0xffffff, 2.5);
    sun.position.set(3, 4, 2);
    scene.add(sun, new THREE.AmbientLight(0x404040, 1.0));
  }
  let view;
  if (camera && camera.fov) {
    view = new THREE.PerspectiveCamera(camera.fov, width / height, 0.05, 100);
    view.position.fromArray(camera.position);
    view.lookAt(new THREE.Vector3().fromArray(camera.target));
  } else {
    view = file.gltf.cameras[0].clone();
    view.aspect = width / height;
    view.updateProjectionMatrix();
  }
  renderer.toneMapping = THREE[`${toneMapping}ToneMapping`];
  renderer.toneMappingExposure = toneExposure;
  renderer.setClearColor(0x000000, 0);
  let out;
  if (target === 'float') {
    const rt = new THREE.WebGLRenderTarget(width, height, { type: THREE.FloatType, depthBuffer: true });
    renderer.setRenderTarget(rt);
    renderer.clear();
    renderer.render(scene, view);
    const pixels = new Float32Array(width * height * 4);
    renderer.readRenderTargetPixels(rt, 0, 0, width, height, pixels);
    renderer.setRenderTarget(null);
    rt.dispose();
    out = flip(pixels, width, height, 4);
  } else {
    renderer.setSize(width, height, false);
    renderer.setRenderTarget(null);
    renderer.clear();
    renderer.render(scene, view);
    const gl = renderer.getContext();
    const pixels = new Uint8Array(width * height * 4);
    gl.readPixels(0, 0, width, height, gl.RGBA, gl.UNSIGNED_BYTE, pixels);
    out = flip(pixels, width, height, 4);
  }
  if (file) scene.remove(file.gltf.scene);
  return toBase64(out);
}

function release(name) {
  const { gltf, background } = files[name];
  if (gltf.userData.prt) gltf.userData.prt.dispose();
  freeScene(gltf.scene, background);
  delete files[name];
  return { ...renderer.info.memory };
}

window.pluginTest = { load, render, describe, release, memory: () => ({ ...renderer.info.memory }) };
