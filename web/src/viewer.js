// The PRT web viewer page: loads a PRT .glb (embedded, file input or drag-and-drop), draws it with
// the PRT material, turns the lighting with the mouse; window.prtViewer is its scripting API.
//
// Left drag turns the lighting (about the world's up axis, and about the view's horizontal axis),
// right drag orbits the camera, the wheel zooms, a double click resets both. window.prtViewer
// has load(ArrayBuffer), setTurn(R), turn(), renderLinear(w, h) (a float RGBA image: linear radiance,
// no exposure, no view transform, top row first, as base64) and info(), for tests and scripts.
import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
import { PRTScene, parseGLB } from './prt_scene.js';

const $ = (id) => document.getElementById(id);
const TURN_PER_PIXEL = 0.01; // radians

function axisAngle(axis, angle) {
  const n = Math.hypot(axis[0], axis[1], axis[2]);
  const [x, y, z] = axis.map((a) => a / n);
  const c = Math.cos(angle);
  const s = Math.sin(angle);
  const t = 1 - c;
  return [
    t * x * x + c, t * x * y - s * z, t * x * z + s * y,
    t * x * y + s * z, t * y * y + c, t * y * z - s * x,
    t * x * z - s * y, t * y * z + s * x, t * z * z + c,
  ]; // prettier-ignore
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
    this.renderer.toneMapping = THREE.NoToneMapping; // the PRT material applies its own view transform
    this.renderer.setClearColor(0x262626, 1);
    this.prt = null;
    this.camera = new THREE.PerspectiveCamera(40, 1, 0.05, 1000);
    this.controls = new OrbitControls(this.camera, canvas);
    this.controls.mouseButtons = { LEFT: null, MIDDLE: THREE.MOUSE.PAN, RIGHT: THREE.MOUSE.ROTATE };
    this.controls.addEventListener('change', () => this.requestDraw());
    this.pending = false;
    this.bindPointer();
    window.addEventListener('resize', () => this.requestDraw());
  }

  async load(buffer) {
    const gltf = await parseGLB(buffer);
    if (this.prt && this.prt.shadows) this.prt.shadows.dispose();
    this.prt = new PRTScene(gltf, this.renderer);
    const exposure = Number((this.prt.lighting.view || {}).exposure || 0);
    $('exposure').value = String(exposure);
    this.setExposure(exposure);
    this.resetView();
    return this.prt.info();
  }

  resetView() {
    const prt = this.prt;
    const source = prt.camera;
    const box = new THREE.Box3().setFromObject(prt.scene, true);
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
    prt.setTurn([1, 0, 0, 0, 1, 0, 0, 0, 1]);
    this.requestDraw();
  }

  setExposure(stops) {
    if (this.prt) this.prt.shared.exposureScale.value = 2 ** stops;
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
      this.prt.turnBy(multiply(yaw, pitch));
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
    const r = this.prt.turn;
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
    this.prt.shared.display.value = true;
    this.prt.prepare();
    this.renderer.render(this.prt.scene, this.camera);
  }

  /** Linear float RGBA (w x h, top row first, base64 of float32) from the file's camera. */
  renderLinear(width, height) {
    const prt = this.prt;
    if (!prt) throw new Error('nothing loaded');
    const camera = prt.camera ? prt.camera.clone() : this.camera.clone();
    camera.aspect = width / height;
    if (prt.camera) camera.fov = blenderFov(prt.camera.fov, prt.camera.aspect, camera.aspect);
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
    try {
      prt.shared.display.value = false;
      prt.prepare();
      this.renderer.setRenderTarget(target);
      this.renderer.setClearColor(0x000000, 0);
      this.renderer.clear();
      this.renderer.render(prt.scene, camera);
      this.renderer.readRenderTargetPixels(target, 0, 0, width, height, pixels);
    } finally {
      prt.shared.display.value = true;
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
  for (let i = 0; i < 3; i++) for (let j = 0; j < 3; j++) for (let k = 0; k < 3; k++) out[3 * i + j] += a[3 * i + k] * b[3 * k + j];
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
    if (viewer.prt) viewer.prt.shared.useShadows.value = event.target.checked;
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
      viewer.prt.setTurn(matrix);
      viewer.showTurn();
      viewer.requestDraw();
    },
    turn: () => (viewer.prt ? viewer.prt.turn.slice() : null),
    renderLinear: (width, height) => viewer.renderLinear(width, height),
    info: () => (viewer.prt ? viewer.prt.info() : null),
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
