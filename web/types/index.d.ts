// Types of prt-lighting-three's public API (src/index.js): the GLTFLoader plugin and the PRT state it makes.
import type { Euler, Matrix3, Matrix4, Mesh, Quaternion, ShaderMaterial, WebGLRenderer } from 'three';
import type { GLTFLoaderPlugin, GLTFParser } from 'three/examples/jsm/loaders/GLTFLoader.js';

/** A rotation of the lighting (glTF world frame): three.js objects or 9 numbers, row-major 3x3. */
export type Rotation = Matrix3 | Matrix4 | Quaternion | Euler | ArrayLike<number>;

export interface PRTLightingOptions {
  /** Exposure in stops (default: the file's `view.exposure`). */
  exposure?: number;
  /** The largest transfer texture side to use (default 4096). */
  maxTextureSize?: number;
  /** No console message for a glTF without PRT data. */
  quiet?: boolean;
  /** 'texture' (default): the decoded transfer in a float texture; 'packed': a quantised transfer's
   * integers in packed vertex attributes when they fit (half the GPU memory). */
  transferSource?: 'texture' | 'packed';
  /** The texture source relit once per lighting change (true, the default: each vertex then reads
   * one value a frame, whatever the order) or summed per vertex every frame (false). Texel bakes
   * are always relit, and looked up per pixel through their lightmap UV map. */
  relight?: boolean;
  /** Principled specular (sky, split-sum table, occlusion, the split lights' highlights) on Principled materials, when the file carries it (default true). */
  specular?: boolean;
}

export interface PRTInfo {
  objects: string[];
  orders: number[];
  /** per object, where its transfer is read from: 'packed' (vertex attributes), 'texture' or 'texel' (a texel bake's images) */
  sources: string[];
  lightingOrder: number;
  lights: number;
  views: { light: number; wide: boolean; samples: number }[];
}

/** A transfer source (transfer_source.js): where the PRT material reads the transfer from. */
export interface TransferSource {
  kind: string;
  stage: 'vertex' | 'texel';
  count: number;
  blocks: number;
  uniforms: Record<string, { value: unknown }>;
  /** GLSL declarations for fetch. */
  glsl: string;
  /** A GLSL expression for the k-th vec4 of the transfer (k a constant). */
  fetch(k: number): string;
  /** The light (rows of [r, g, b]) as the shader dots it with fetch's vec4s, and a constant per channel. */
  lightFor(rows: number[][], blocks: number[]): { rows: number[][]; constant: number[] };
  /** Relit sources (relight.js): the float target's size (one texel per vertex or lightmap texel),
   * the relight pass's GLSL declarations and its k-th vec4 (of the target's texel p). */
  relightSize?: [number, number];
  relightGlsl?: string;
  relightFetch?(k: number): string;
  /** A relit vertex source: the GLSL expression of a vertex's relit radiance. */
  radianceVertex?: string;
  dispose(): void;
}

/** The PRT state of one loaded file: `gltf.userData.prt` (null for a file without usable PRT data). */
export class PRTLighting {
  readonly exposure: number;
  readonly lighting: Record<string, unknown>;
  /** Turn the lighting by R from the file's own. */
  setLightingRotation(rotation: Rotation): void;
  /** The current turn, row-major 3x3. */
  getLightingRotation(): number[];
  /** Turn by `delta` after the current turn. */
  rotateLightingBy(delta: Rotation): void;
  /** Exposure in stops, applied before three.js's tone mapping and output colour space. */
  setExposure(stops: number): void;
  /** The split lights' shadows on or off. */
  setShadows(on: boolean): void;
  /** Bring the meshes' lights and the shadow maps up to date now (done anyway before each draw). */
  update(renderer: WebGLRenderer): void;
  /** The file's world (its EXT_lights_image_based cube) as a background mesh, turned with the lighting. */
  createBackground(): Promise<Mesh | null>;
  info(): PRTInfo;
  /** Frees the GPU resources the plugin made and gives the meshes their original materials back;
   * the file's own geometries, materials, textures and the background mesh stay the app's to free. */
  dispose(): void;
}

/** The GLTFLoader plugin: `loader.register((parser) => new PRTLightingPlugin(parser, options))`. */
export class PRTLightingPlugin implements GLTFLoaderPlugin {
  constructor(parser: GLTFParser, options?: PRTLightingOptions);
  readonly name: string;
  /** The file's PRT state once loaded (also `gltf.userData.prt`). */
  prt: PRTLighting | null;
}

export const EXTRAS_KEY: string;
export const DEFAULT_ALBEDO: [number, number, number];
export const ENCODINGS: Record<'float32' | 'snorm16' | 'snorm8', number>;
export const MESH_VERSION: number;
export const SCENE_VERSION: number;
export class FormatError extends Error {}
export function readLighting(meta: unknown): Record<string, unknown>;
export function readTransfer(meta: unknown, geometry: unknown): Record<string, unknown>;
/** A per-vertex transfer source: one Float32Array (vertices x 4) per vec4, `count` per block. */
export function vertexTransferSource(rows: Float32Array[], count: number, maxSize?: number): TransferSource;
export function geometryTransferSource(geometry: unknown, spec: unknown, maxSize?: number): TransferSource;
export function packedTransferSource(geometry: unknown, spec: unknown): TransferSource | null;
export function prtMaterial(options: {
  source: TransferSource;
  views?: number;
  samples?: number;
  layout?: { count: number; wide: boolean }[];
  albedo: [number, number, number];
  shared: Record<string, { value: unknown }>;
  channels?: number;
  side?: number;
  /** The geometry has the contact tangent as `prtContact` (node frame), which the shadow lookups
   * move along; the material's `tanMatrix` uniform is then the node's 3x3 (PRTLighting sets it). */
  contact?: boolean;
}): ShaderMaterial;
export function bandMatrices(r: ArrayLike<number>, order: number): Float64Array[];
export function rotationMatrix(r: ArrayLike<number>, order: number): Float64Array;
export function rotateRGB(coeffs: number[][], r: ArrayLike<number>, order: number, parity?: boolean): number[][];
export function frameRotation(a: ArrayLike<number>): { rotation: number[]; mirrored: boolean };
export function lightInLocalFrame(
  worldCoeffs: number[][],
  linear: ArrayLike<number>,
  order: number,
  turn?: ArrayLike<number>,
): number[][];
