// The PRT web viewer page, a thin page on the plugin: loads a PRT .glb (embedded, file input or drop), draws it and its world, turns the lighting.
//
// GLTFLoader with PRTLightingPlugin (plugin.js) does the PRT; this page adds the world behind
// (prt.createBackground()), the camera of the file, the mouse, the exposure slider and a
// frame-time read-out (draw time to a finished frame, read back one pixel). window.prtViewer is
// its scripting API.
//
// Left drag turns the lighting (about the world's up axis, and about the view's horizontal axis),
// right drag orbits the camera, the wheel zooms, a double click resets both. window.prtViewer
// has load(ArrayBuffer), setTurn(R), turn(), renderLinear(w, h) (a float RGBA image: linear radiance,
// no exposure, no view transform, top row first, as base64) and info(), for tests and scripts.
import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
import { GLTFLoader } from 'three/examples/jsm/loaders/GLTFLoader.js';
import { PRTLightingPlugin } from './index.js';
import { freeScene } from './free_scene.js';

const $ = (id) => document.getElementById(id);
const TURN_PER_PIXEL = 0.01; // radians

function axisAngle(axis, angle) {
  const n = Math.hypot(axis[0], axis[1], axis[2]);
  const [x, y, z] = axis.map((a) => a / n);
  const c = Math.cos(angle);
  const s = Math.sin(angle);
  const t = 1 - c;
  // prettier-ignore
  return [
    t * x * x + c, t * x * y - s * z, t * x * z + s * y,
    t * x * y + s * z, t * y * y + c, t * y * z - s * x,
    t * x * z - s * y, t * y * z + s * x, t * z * z + c,
  ];
}

function base64ToBuffer(text) {
  const binary = atob(text.replace(/\s+/g, ''));
  const bytes = new Uint8Array(binary.length);
  for (let i = 0; i < binary.length; i++) bytes[i] = binary.charCodeAt(i);
  return bytes.buffer;
}

function bufferToBase64(buffer) {
  const bytes = new Uint8Array(buffer);
  let binary = '';
  for (let i = 0; i < bytes.length; i += 0x8000) binary += String.fromCharCode(...bytes.subarray(i, i + 0x8000));
  return btoa(binary);
}

class Viewer {
  constructor(canvas) {
    this.canvas = canvas;
    this.renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(window.devicePixelRatio || 1);
    // Blender's "Standard" view: no tone mapping, the sRGB curve (three.js's output colour space).
    this.renderer.toneMapping = THREE.NoToneMapping;
    this.renderer.outputColorSpace = THREE.SRGBColorSpace;
    this.renderer.setClearColor(0x262626, 1);
    this.prt = null;
    this.camera = new THREE.PerspectiveCamera(40, 1, 0.05, 1000);
    this.controls = new OrbitControls(this.camera, canvas);
    this.controls.mouseButtons = { LEFT: null, MIDDLE: THREE.MOUSE.PAN, RIGHT: THREE.MOUSE.ROTATE };
    this.controls.addEventListener('change', () => this.requestDraw());
    this.pending = false;
    this.pixel = new Uint8Array(4);
    this.frameTimes = [];
    this.bindPointer();
    window.addEventListener('resize', () => this.requestDraw());
  }

  async load(buffer) {
    const loader = new GLTFLoader().register((parser) => new PRTLightingPlugin(parser));
    const gltf = await loader.parseAsync(buffer, '');
    const prt = gltf.userData.prt;
    if (!prt)
      throw new Error(
        'this .glb has no PRT lighting (export it with PRT Lighting: File > Export > PRT Lighting); see the console',
      );
    if (this.prt) {
      this.prt.dispose();
      freeScene(this.model, this.background);
    }
    this.scene = new THREE.Scene();
    this.scene.add(gltf.scene);
    this.prt = prt;
    this.model = gltf.scene;
    this.fileCamera = gltf.cameras && gltf.cameras.length ? gltf.cameras[0] : null;
    this.background = await prt.createBackground();
    if (this.background) this.scene.add(this.background);
    $('exposure').value = String(prt.exposure);
    this.setExposure(prt.exposure);
    this.resetView();
    return this.info();
  }

  info() {
    return { ...this.prt.info(), camera: Boolean(this.fileCamera), background: Boolean(this.background) };
  }

  resetView() {
    const prt = this.prt;
    const source = this.fileCamera;
    const box = new THREE.Box3().setFromObject(this.model, true);
    const centre = box.getCenter(new THREE.Vector3());
    if (source) {
      source.updateMatrixWorld(true);
      source.matrixWorld.decompose(this.camera.position, this.camera.quaternion, new THREE.Vector3());
      this.camera.fov = source.fov;
      this.camera.near = source.near;
      this.camera.far = source.far;
      this.fileAspect = source.aspect;
      this.fileFov = source.fov;
    } else {
      const radius = box.getSize(new THREE.Vector3()).length() * 0.5 || 1;
      this.camera.position.copy(centre).add(new THREE.Vector3(0.6, 0.5, 1).multiplyScalar(radius * 2.2));
      this.camera.lookAt(centre);
      this.fileAspect = null;
    }
    // Orbit about the point of the view axis nearest the scene's centre.
    const forward = new THREE.Vector3(0, 0, -1).applyQuaternion(this.camera.quaternion);
    const along = Math.max(centre.clone().sub(this.camera.position).dot(forward), 0.1);
    this.controls.target.copy(this.camera.position).addScaledVector(forward, along);
    this.camera.updateProjectionMatrix();
    this.controls.update();
    prt.setLightingRotation([1, 0, 0, 0, 1, 0, 0, 0, 1]);
    this.requestDraw();
  }

  setExposure(stops) {
    if (this.prt) this.prt.setExposure(stops);
    $('exposure-value').textContent = `${Number(stops).toFixed(1)} EV`;
    this.requestDraw();
  }

  bindPointer() {
    let last = null;
    this.canvas.addEventListener('pointerdown', (event) => {
      if (event.button !== 0 || !this.prt) return;
      last = [event.clientX, event.clientY];
      this.canvas.setPointerCapture(event.pointerId);
    });
    this.canvas.addEventListener('pointermove', (event) => {
      if (!last) return;
      const dx = event.clientX - last[0];
      const dy = event.clientY - last[1];
      last = [event.clientX, event.clientY];
      const right = new THREE.Vector3(1, 0, 0).applyQuaternion(this.camera.quaternion);
      const yaw = axisAngle([0, 1, 0], dx * TURN_PER_PIXEL);
      const pitch = axisAngle([right.x, right.y, right.z], dy * TURN_PER_PIXEL);
      this.prt.rotateLightingBy(multiply(yaw, pitch));
      this.showTurn();
      this.requestDraw();
    });
    const end = () => (last = null);
    this.canvas.addEventListener('pointerup', end);
    this.canvas.addEventListener('pointercancel', end);
    this.canvas.addEventListener('dblclick', () => this.prt && this.resetView());
    this.canvas.addEventListener('contextmenu', (event) => event.preventDefault());
  }

  showTurn() {
    const r = this.prt.getLightingRotation();
    const angle = Math.acos(Math.max(-1, Math.min(1, (r[0] + r[4] + r[8] - 1) / 2)));
    $('turn').textContent = `lighting turned by ${((angle * 180) / Math.PI).toFixed(0)}°`;
  }

  requestDraw() {
    if (this.pending) return;
    this.pending = true;
    requestAnimationFrame(() => {
      this.pending = false;
      this.draw();
    });
  }

  draw() {
    const width = this.canvas.clientWidth;
    const height = this.canvas.clientHeight;
    if (this.canvas.width !== Math.floor(width * this.renderer.getPixelRatio())) {
      this.renderer.setSize(width, height, false);
    }
    if (!this.prt) {
      this.renderer.clear();
      return;
    }
    this.camera.aspect = width / height;
    if (this.fileAspect) this.camera.fov = blenderFov(this.fileFov, this.fileAspect, this.camera.aspect);
    this.camera.updateProjectionMatrix();
    const started = performance.now();
    this.renderer.render(this.scene, this.camera);
    this.renderer
      .getContext()
      .readPixels(0, 0, 1, 1, WebGL2RenderingContext.RGBA, WebGL2RenderingContext.UNSIGNED_BYTE, this.pixel);
    this.frameTimes.push(performance.now() - started);
    if (this.frameTimes.length > 20) this.frameTimes.shift();
    const sorted = this.frameTimes.slice().sort((a, b) => a - b);
    $('frame-time').textContent = `frame ${sorted[sorted.length >> 1].toFixed(1)} ms`;
  }

  /** Linear float RGBA (w x h, top row first, base64 of float32) from the file's camera. */
  renderLinear(width, height) {
    const prt = this.prt;
    if (!prt) throw new Error('nothing loaded');
    const source = this.fileCamera;
    const camera = source ? source.clone() : this.camera.clone();
    camera.aspect = width / height;
    if (source) camera.fov = blenderFov(source.fov, source.aspect, camera.aspect);
    camera.updateProjectionMatrix();
    const target = new THREE.WebGLRenderTarget(width, height, {
      type: THREE.FloatType,
      format: THREE.RGBAFormat,
      minFilter: THREE.NearestFilter,
      magFilter: THREE.NearestFilter,
      depthBuffer: true,
    });
    const clear = [this.renderer.getClearColor(new THREE.Color()), this.renderer.getClearAlpha()];
    const pixels = new Float32Array(width * height * 4);
    const exposure = prt.exposure;
    try {
      prt.setExposure(0); // (into a float target: no tone mapping, no output conversion)
      if (this.background) this.background.visible = false;
      this.renderer.setRenderTarget(target);
      this.renderer.setClearColor(0x000000, 0);
      this.renderer.clear();
      this.renderer.render(this.scene, camera);
      this.renderer.readRenderTargetPixels(target, 0, 0, width, height, pixels);
    } finally {
      prt.setExposure(exposure);
      if (this.background) this.background.visible = true;
      this.renderer.setRenderTarget(null);
      this.renderer.setClearColor(...clear);
      target.dispose();
    }
    const flipped = new Float32Array(pixels.length);
    const row = width * 4;
    for (let y = 0; y < height; y++) flipped.set(pixels.subarray((height - 1 - y) * row, (height - y) * row), y * row);
    this.requestDraw();
    return bufferToBase64(flipped.buffer);
  }
}

/**
 * Vertical field of view (degrees) for a window of aspect `aspect`, from the file's camera (fov,
 * fileAspect), as Blender's sensor fit AUTO frames it: the larger side of the picture spans the
 * camera's larger field of view.
 */
function blenderFov(fov, fileAspect, aspect) {
  const t = Math.tan((fov * Math.PI) / 360);
  const wide = fileAspect >= 1 ? t * fileAspect : t; // tan of half the larger field of view
  const vertical = aspect >= 1 ? wide / aspect : wide;
  return (Math.atan(vertical) * 360) / Math.PI;
}

function multiply(a, b) {
  const out = new Array(9).fill(0);
  for (let i = 0; i < 3; i++)
    for (let j = 0; j < 3; j++) for (let k = 0; k < 3; k++) out[3 * i + j] += a[3 * i + k] * b[3 * k + j];
  return out;
}

function showError(error) {
  $('message').textContent = String(error && error.message ? error.message : error);
  $('message').hidden = false;
}

async function loadInto(viewer, buffer, name) {
  $('message').hidden = true;
  try {
    const info = await viewer.load(buffer);
    $('info').textContent =
      `${name}: ${info.objects.length} baked object(s), order ${Math.max(...info.orders)}, ` +
      `${info.lights} split light(s)${info.views.length ? ` (${info.views.length} shadow maps)` : ''}` +
      `${info.camera ? '' : ', no camera in the file'}`;
    $('drop-hint').hidden = true;
    viewer.showTurn();
    return info;
  } catch (error) {
    showError(error);
    throw error;
  }
}

function main() {
  const viewer = new Viewer($('view'));
  const open = (file) => file.arrayBuffer().then((buffer) => loadInto(viewer, buffer, file.name));
  $('file').addEventListener('change', (event) => event.target.files[0] && open(event.target.files[0]));
  $('exposure').addEventListener('input', (event) => viewer.setExposure(Number(event.target.value)));
  $('shadows').addEventListener('change', (event) => {
    if (viewer.prt) viewer.prt.setShadows(event.target.checked);
    viewer.requestDraw();
  });
  document.addEventListener('dragover', (event) => event.preventDefault());
  document.addEventListener('drop', (event) => {
    event.preventDefault();
    const file = event.dataTransfer.files[0];
    if (file) open(file);
  });
  window.prtViewer = {
    load: (buffer, name = 'file') => loadInto(viewer, buffer, name),
    loadBase64: (text, name = 'file') => loadInto(viewer, base64ToBuffer(text), name),
    setTurn: (matrix) => {
      viewer.prt.setLightingRotation(matrix);
      viewer.showTurn();
      viewer.requestDraw();
    },
    turn: () => (viewer.prt ? viewer.prt.getLightingRotation() : null),
    renderLinear: (width, height) => viewer.renderLinear(width, height),
    info: () => (viewer.prt ? viewer.info() : null),
    frameTime: () => viewer.frameTimes.slice(),
  };
  const embedded = $('prt-embedded');
  if (embedded && embedded.textContent.trim()) {
    window.prtViewer.ready = loadInto(viewer, base64ToBuffer(embedded.textContent), embedded.dataset.name || 'scene');
  } else {
    window.prtViewer.ready = Promise.resolve(null);
    viewer.requestDraw();
  }
}

main();
