// prt-lighting-three's public API: the GLTFLoader plugin, the PRT state it makes, and the pieces a custom setup reuses.
export { PRTLightingPlugin, EXTRAS_KEY } from './plugin.js';
export { PRTLighting, DEFAULT_ALBEDO } from './prt_lighting.js';
export { FormatError, ENCODINGS, MESH_VERSION, SCENE_VERSION, readLighting, readTransfer } from './format.js';
export { vertexTransferSource, geometryTransferSource, packedTransferSource } from './transfer_source.js';
export { prtMaterial } from './prt_material.js';
export { bandMatrices, rotationMatrix, rotateRGB, frameRotation, lightInLocalFrame } from './sh_rotation.js';
