// The README's ten-line example, type-checked against index.d.ts and three's types (npm run lint).
import * as THREE from 'three';
import { GLTFLoader } from 'three/examples/jsm/loaders/GLTFLoader.js';
import { PRTLightingPlugin, type PRTLighting } from 'prt-lighting-three';

export async function example(renderer: THREE.WebGLRenderer, scene: THREE.Scene, camera: THREE.Camera) {
  const loader = new GLTFLoader().register((parser) => new PRTLightingPlugin(parser));
  const gltf = await loader.loadAsync('scene.glb');
  scene.add(gltf.scene);
  const prt: PRTLighting | null = gltf.userData.prt;
  const background = prt && (await prt.createBackground());
  if (background) scene.add(background);
  renderer.setAnimationLoop((time: number) => {
    prt?.setLightingRotation(new THREE.Euler(0, time / 4000, 0));
    renderer.render(scene, camera);
  });
}
