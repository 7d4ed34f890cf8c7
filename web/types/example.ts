// The README's ten-line example, type-checked against index.d.ts and three's types (npm run lint).
import * as THREE from 'three';
import { GLTFLoader } from 'three/examples/jsm/loaders/GLTFLoader.js';
import { PRTLightingPlugin, type PRTLighting } from 'prt-lighting-three';

export async function example() {
  const renderer = new THREE.WebGLRenderer();
  renderer.setSize(innerWidth, innerHeight);
  document.body.append(renderer.domElement);
  const loader = new GLTFLoader().register((parser) => new PRTLightingPlugin(parser));
  const gltf = await loader.loadAsync('scene.glb');
  const prt: PRTLighting = gltf.userData.prt;
  const scene = new THREE.Scene().add(gltf.scene, (await prt.createBackground())!);
  renderer.setAnimationLoop((t: number) => {
    prt.setLightingRotation(new THREE.Euler(0, t / 4000, 0));
    renderer.render(scene, gltf.cameras[0]);
  });
}
