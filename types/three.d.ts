// btf-stream/three: BTFMaterial, a streamed BTF on a three.js mesh (WebGLRenderer, r171 or
// later). doc/client.md "three.js". Hand-written for dist/three.js.
import {RawShaderMaterial, Vector3} from 'three';
import type {BtfProgress} from './btf-viewer.js';

export type BtfVec3 = Vector3 | [number, number, number];

export interface BTFMaterialLighting {
  /** Direction towards a distant point light, world space; null: none. */
  light?: BtfVec3 | null;
  /** 'studio', the URL of an equirectangular Radiance .hdr, or null. Default: 'studio' without a light, else null. */
  environment?: string | null;
  /** Degrees about the up axis. Default 0. */
  environmentRotation?: number;
  /** 'y' (default): the environment's top is +y, its centre faces +x; 'z': the project's frame (+z up). */
  up?: 'y' | 'z';
  /** Default 1. */
  exposure?: number;
  /** Default 'auto': neutral with an environment, else none. */
  toneMapping?: 'auto' | 'none' | 'neutral' | 'aces';
  /** Default true: lights below the outermost measured light ring fade out. */
  horizonFade?: boolean;
}

export interface BTFMaterialBudget {
  /** Most chunks to stream. Default: no cap. */
  budgetChunks?: number | null;
  /** Most bytes to stream. Default -1: no cap. */
  budgetBytes?: number;
  /** Device pixels one repeat of the material spans (the scene budget of packages with levels). Default 1e6: every level. */
  pixels?: number;
  /** The scene budget's visibility threshold (RMS on 0..255). Default 1. */
  lodThreshold?: number;
}

export interface BTFMaterialOptions extends BTFMaterialLighting, BTFMaterialBudget {
  /** ws(s):// of a btfd's /stream, or the http(s) folder of a published library (relative to the page). */
  src: string;
  /** The library material's name. */
  material: string;
  /** A private library's access token v1:SCOPE:EXPIRES:SIG (the element's `token`). */
  token?: string | null;
  /** Base URL of the shader files. Default: those inside the package. */
  shaders?: string | null;
  /** Material repeats per unit of uv. Default 1. */
  repeat?: number | [number, number];
  /** Tile the material (default true), else clamp at uv 0 and 1. */
  wrap?: boolean;
  /** Default 'bilinear'. */
  filter?: 'bilinear' | 'nearest';
  /** true (default, three's geometries): image row 0 at uv.y = 1; false for glTF models (GLTFLoader). */
  flipY?: boolean;
}

export interface BTFMaterialLightingState {
  point: {on: boolean; direction: [number, number, number] | null};
  environment: {image: string | null; state: 'none' | 'loading' | 'ready' | 'failed'; error: string | null; on: boolean;
    rotation: number};
  exposure: number;
  toneMapping: 'none' | 'neutral' | 'aces';
  up: 'y' | 'z';
}

export interface BTFMaterialEventMap {
  /** Draw again: a chunk, the environment or a lighting change arrived. */
  change: {};
  progress: BtfProgress;
  load: {chunks: number};
  complete: BtfProgress;
  error: {reason: string; retrying?: boolean};
  dispose: {};
}

/**
 * A streamed BTF material: a RawShaderMaterial (GLSL3) drawn with the element's shaders.
 * Meshes need position, normal, tangent (computeTangents()) and uv. Not drawn until its
 * first chunk is here; refines as chunks arrive ('change').
 */
export declare class BTFMaterial extends RawShaderMaterial {
  constructor(options: BTFMaterialOptions);
  addEventListener<K extends keyof BTFMaterialEventMap>(type: K,
    listener: (event: BTFMaterialEventMap[K] & {type: K; target: any}) => void): void;
  removeEventListener<K extends keyof BTFMaterialEventMap>(type: K,
    listener: (event: BTFMaterialEventMap[K] & {type: K; target: any}) => void): void;
  readonly isBTFMaterial: true;
  /** The absolute source URL. */
  readonly src: string;
  readonly material: string;
  /** What the draws are lit by. */
  readonly lighting: BTFMaterialLightingState;
  /** Received against the budget. */
  readonly progress: BtfProgress;
  /** Changes the lighting; fires 'change'. */
  setLighting(changes: BTFMaterialLighting): void;
  /** Changes the budget. */
  setBudget(changes: BTFMaterialBudget): void;
  /** Diagnostics: chunks received, uploaded, drawn; the program variant; texture versions. */
  state(): Record<string, unknown>;
  /** Unsubscribes and frees the textures. */
  dispose(): void;
}

