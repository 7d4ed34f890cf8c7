// The world as a background: the file's EXT_lights_image_based cube map (mip 0, RGBD PNGs) drawn behind everything, turned with the lighting.
//
// The export's cube is in Babylon.js's frame (docs/export.md, "Cube frame and faces"): its face
// texel for the glTF direction (x, y, z) is the cube-map lookup of (-x, y, z), with the PNGs
// flipped on upload; the texel is RGBD, radiance = rgb^2.2 / D. The background samples it at
// R^-1 d for the view direction d (the lighting turned by R), times the PRT exposure, through
// three.js's tone mapping and output colour space like the PRT material. Mip 0 is 128 texels a
// face by default: a soft background.
import * as THREE from 'three';

/** The cube texture of the file's image-based light (6 RGBD faces of mip 0), or null without one. */
export async function loadEnvironment(parser) {
  const json = parser.json;
  const light = (((json.extensions || {}).EXT_lights_image_based || {}).lights || [])[0];
  const faces = light && light.specularImages && light.specularImages[0];
  if (!faces || faces.length !== 6) return null;
  const images = await Promise.all(
    faces.map(async (index) => {
      const image = json.images[index];
      const data = await parser.getDependency('bufferView', image.bufferView);
      const blob = new Blob([data], { type: image.mimeType || 'image/png' });
      // Alpha holds D: no premultiplication, no colour conversion; rows flipped as Babylon uploads them.
      return createImageBitmap(blob, {
        premultiplyAlpha: 'none',
        colorSpaceConversion: 'none',
        imageOrientation: 'flipY',
      });
    }),
  );
  const cube = new THREE.CubeTexture(images);
  cube.colorSpace = THREE.NoColorSpace;
  cube.generateMipmaps = false;
  cube.minFilter = THREE.LinearFilter;
  cube.magFilter = THREE.LinearFilter;
  cube.flipY = false;
  cube.premultiplyAlpha = false;
  cube.needsUpdate = true;
  return cube;
}

const VERTEX = `
varying vec3 direction;
void main() {
  direction = position;
  vec4 p = projectionMatrix * vec4(mat3(viewMatrix) * position, 1.0);
  gl_Position = p.xyww;
}
`;

const FRAGMENT = `
uniform samplerCube environment;
uniform mat3 turnInverse;
uniform float exposureScale;
varying vec3 direction;
void main() {
  vec3 d = turnInverse * normalize(direction);
  vec4 c = textureCube(environment, vec3(-d.x, d.y, d.z));
  gl_FragColor = vec4(pow(c.rgb, vec3(2.2)) / max(c.a, 1.0 / 255.0) * exposureScale, 1.0);
  #include <tonemapping_fragment>
  #include <colorspace_fragment>
}
`;

/** A mesh drawing the cube behind everything (add it to the app's scene); the shared uniforms
 * (prt_lighting.js) turn it and set its exposure. */
export function backgroundMesh(cube, shared) {
  const material = new THREE.ShaderMaterial({
    uniforms: { environment: { value: cube }, turnInverse: shared.turnInverse, exposureScale: shared.exposureScale },
    vertexShader: VERTEX,
    fragmentShader: FRAGMENT,
    side: THREE.BackSide,
    depthTest: false,
    depthWrite: false,
  });
  const mesh = new THREE.Mesh(new THREE.BoxGeometry(2, 2, 2), material);
  mesh.name = 'PRT background';
  mesh.frustumCulled = false;
  mesh.renderOrder = -1e9;
  return mesh;
}
