// The page of tests/browser/test_babylon_ibl.py: a .glb loaded by Babylon.js's glTF loader, its EXT_lights_image_based environment probed.
//
// window.babylonProbe (bundled by babylon_ibl.mjs, run in headless Chromium):
//   load(base64)         -> the loaded environment texture's figures and its shader's SH
//   sample(dirs, lod)    -> [[r, g, b]] the cube texture sampled (textureLod) at glTF directions
//   mirror(dirs, rough)  -> [[r, g, b, a]] 8-bit centre pixel of a PBR metal sphere (roughness rough) seen from each glTF direction
// glTF directions are taken into Babylon's world by the loader's own __root__ node matrix.
import * as BABYLON from '@babylonjs/core';
import '@babylonjs/loaders/glTF/index.js';

const canvas = document.createElement('canvas');
canvas.width = 65;
canvas.height = 65;
document.body.appendChild(canvas);
const engine = new BABYLON.Engine(canvas, false, { preserveDrawingBuffer: true, antialias: false });
const scene = new BABYLON.Scene(engine);
let root = null;

function toBabylon(d) {
  const v = BABYLON.Vector3.TransformNormal(new BABYLON.Vector3(d[0], d[1], d[2]), root);
  return v.normalize();
}

async function load(base64) {
  const bytes = Uint8Array.from(atob(base64), (c) => c.charCodeAt(0));
  await BABYLON.AppendSceneAsync(bytes, scene, { pluginExtension: '.glb' });
  const texture = scene.environmentTexture;
  if (!texture) throw new Error('no environment texture after loading');
  await new Promise((resolve) => {
    const poll = () => (texture.isReady() ? resolve() : setTimeout(poll, 20));
    poll();
  });
  root = scene.getMeshByName('__root__').computeWorldMatrix(true).clone();
  const h = texture.sphericalPolynomial.preScaledHarmonics;
  const names = ['l00', 'l1_1', 'l10', 'l11', 'l2_2', 'l2_1', 'l20', 'l21', 'l22'];
  return {
    size: texture.getSize().width,
    level: texture.level,
    lodGenerationScale: texture.lodGenerationScale,
    lodGenerationOffset: texture.lodGenerationOffset,
    reflectionMatrix: Array.from(texture.getReflectionTextureMatrix().m),
    root: Array.from(root.m),
    useRightHandedSystem: scene.useRightHandedSystem,
    harmonics: names.map((n) => [h[n].x, h[n].y, h[n].z]),
    textureType: texture.getInternalTexture().type,
    mips: texture.getInternalTexture().generateMipMaps,
  };
}

function compile(gl, vertex, fragment) {
  const program = gl.createProgram();
  for (const [kind, source] of [
    [gl.VERTEX_SHADER, vertex],
    [gl.FRAGMENT_SHADER, fragment],
  ]) {
    const shader = gl.createShader(kind);
    gl.shaderSource(shader, source);
    gl.compileShader(shader);
    if (!gl.getShaderParameter(shader, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(shader));
    gl.attachShader(program, shader);
  }
  gl.linkProgram(program);
  if (!gl.getProgramParameter(program, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(program));
  return program;
}

// Raw WebGL2 on Babylon's context: each output texel samples the cube at one direction (the
// shader's lookup vector, as the PBR shader forms it: reflection matrix times world direction).
function sample(dirs, lod) {
  const gl = engine._gl;
  gl.getExtension('EXT_color_buffer_float');
  const matrix = scene.environmentTexture.getReflectionTextureMatrix();
  const data = new Float32Array(dirs.length * 4);
  dirs.forEach((d, i) => {
    const v = BABYLON.Vector3.TransformNormal(toBabylon(d), matrix);
    data.set([v.x, v.y, v.z, 0], 4 * i);
  });
  const program = compile(
    gl,
    '#version 300 es\nin vec2 p; void main() { gl_Position = vec4(p, 0.0, 1.0); }',
    `#version 300 es
precision highp float;
uniform samplerCube env; uniform highp sampler2D dirs; uniform float lod; out vec4 o;
void main() { vec3 d = texelFetch(dirs, ivec2(gl_FragCoord.xy), 0).xyz; o = vec4(textureLod(env, d, lod).rgb, 1.0); }`,
  );
  const vao = gl.createVertexArray();
  gl.bindVertexArray(vao);
  const buffer = gl.createBuffer();
  gl.bindBuffer(gl.ARRAY_BUFFER, buffer);
  gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 3, -1, -1, 3]), gl.STATIC_DRAW);
  const location = gl.getAttribLocation(program, 'p');
  gl.enableVertexAttribArray(location);
  gl.vertexAttribPointer(location, 2, gl.FLOAT, false, 0, 0);
  const dirTexture = gl.createTexture();
  gl.activeTexture(gl.TEXTURE1);
  gl.bindTexture(gl.TEXTURE_2D, dirTexture);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
  gl.pixelStorei(gl.UNPACK_FLIP_Y_WEBGL, false);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, dirs.length, 1, 0, gl.RGBA, gl.FLOAT, data);
  gl.activeTexture(gl.TEXTURE0);
  gl.bindTexture(
    gl.TEXTURE_CUBE_MAP,
    scene.environmentTexture.getInternalTexture()._hardwareTexture.underlyingResource,
  );
  const target = gl.createTexture();
  gl.activeTexture(gl.TEXTURE2);
  gl.bindTexture(gl.TEXTURE_2D, target);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, dirs.length, 1, 0, gl.RGBA, gl.FLOAT, null);
  const framebuffer = gl.createFramebuffer();
  gl.bindFramebuffer(gl.FRAMEBUFFER, framebuffer);
  gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, target, 0);
  gl.useProgram(program);
  gl.uniform1i(gl.getUniformLocation(program, 'env'), 0);
  gl.uniform1i(gl.getUniformLocation(program, 'dirs'), 1);
  gl.uniform1f(gl.getUniformLocation(program, 'lod'), lod);
  for (const cap of [gl.BLEND, gl.DEPTH_TEST, gl.SCISSOR_TEST, gl.CULL_FACE, gl.STENCIL_TEST]) gl.disable(cap);
  gl.colorMask(true, true, true, true);
  gl.viewport(0, 0, dirs.length, 1);
  gl.drawArrays(gl.TRIANGLES, 0, 3);
  const out = new Float32Array(dirs.length * 4);
  gl.readPixels(0, 0, dirs.length, 1, gl.RGBA, gl.FLOAT, out);
  gl.bindFramebuffer(gl.FRAMEBUFFER, null);
  gl.bindVertexArray(null);
  engine.wipeCaches(true);
  return dirs.map((_d, i) => [out[4 * i], out[4 * i + 1], out[4 * i + 2]]);
}

// A PBR metal sphere (albedo 1, metallic 1) at the origin seen from far along each direction with
// a narrow field of view: the centre pixel's normal faces the camera, so it reflects the
// environment in the camera's direction (8-bit output, Babylon's default image processing).
let probe = null;

async function mirror(dirs, roughness) {
  if (!probe) {
    for (const mesh of scene.meshes) mesh.setEnabled(false);
    const sphere = BABYLON.MeshBuilder.CreateSphere('probe sphere', { diameter: 2, segments: 64 }, scene);
    const material = new BABYLON.PBRMaterial('probe metal', scene);
    material.metallic = 1.0;
    material.albedoColor = new BABYLON.Color3(1, 1, 1);
    sphere.material = material;
    const camera = new BABYLON.FreeCamera('probe camera', new BABYLON.Vector3(0, 0, -10), scene);
    camera.fov = 0.02;
    camera.minZ = 0.1;
    scene.activeCamera = camera;
    probe = { material, camera };
  }
  const { material, camera } = probe;
  material.roughness = roughness;
  await scene.whenReadyAsync();
  const gl = engine._gl;
  const out = [];
  for (const d of dirs) {
    const b = toBabylon(d);
    camera.position = b.scale(10);
    camera.upVector = Math.abs(b.y) > 0.9 ? new BABYLON.Vector3(1, 0, 0) : new BABYLON.Vector3(0, 1, 0);
    camera.setTarget(BABYLON.Vector3.Zero());
    scene.render();
    const px = new Uint8Array(4);
    gl.readPixels(32, 32, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px);
    out.push(Array.from(px));
  }
  return out;
}

window.babylonProbe = { load, sample, mirror };
