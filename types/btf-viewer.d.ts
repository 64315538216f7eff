// btf-stream: importing it registers <btf-viewer> (doc/client.md has every attribute,
// event and default). Hand-written for dist/btf-viewer.js.

/** The `detail` of `progress` and `complete`: received against this viewer's budget. */
export interface BtfProgress {
  chunks: number;
  chunksWanted: number;
  bytes: number;
  bytesWanted: number;
  /** The error the received prefix promises (CIELab or RMSE on 0..255), null when unknown. */
  error: number | null;
  metric: 'lab' | 'rmse';
  /** A model's viewer: each library material's numbers. */
  materials?: Array<{material: string} & Omit<BtfProgress, 'materials'>>;
}

export interface BtfErrorDetail {
  reason: string;
  /** true: the viewer keeps trying (server unreachable, connection lost, shaders not loaded). */
  retrying?: boolean;
}

export interface BtfCameraDetail {
  theta: number;
  phi: number;
  dist: number;
}

export type BtfToneMapping = 'none' | 'neutral' | 'aces';

/** The read-only `lighting` property: what the last frame was lit by (doc/client.md "Lighting"). */
export interface BtfLighting {
  light: 'orbit' | 'fixed' | 'pointer' | 'tilt' | 'none' | null;
  point: {on: boolean; theta: number | null; phi: number | null};
  environment: {
    image: string | null;
    state: 'none' | 'idle' | 'loading' | 'ready' | 'failed';
    error: string | null;
    on: boolean;
    /** environment-rotation plus the tilt's gamma, degrees about +z */
    rotation: number;
    /** the tilt's beta */
    tilt: number;
  };
  exposure: number;
  toneMapping: BtfToneMapping;
  tilt: {beta: number; gamma: number; source: 'orientation' | 'pointer' | null;
    permission: 'prompt' | 'asked' | 'granted' | 'denied' | 'not-needed' | null} | null;
}

export interface BtfViewerEventMap extends Omit<HTMLElementEventMap, 'error' | 'progress' | 'load'> {
  progress: CustomEvent<BtfProgress>;
  load: CustomEvent<{chunks: number}>;
  complete: CustomEvent<BtfProgress>;
  error: CustomEvent<BtfErrorDetail>;
  'camera-change': CustomEvent<BtfCameraDetail>;
}

/**
 * <btf-viewer>: one streamed material on a plane, sphere or cylinder, or a glTF model with
 * library materials bound to its parts. Each property reflects the attribute of the same
 * name in kebab-case (numbers read as numbers, null when the attribute is absent; setting
 * null removes it).
 */
export declare class BtfViewer extends HTMLElement {
  /** The library material (required without `model`). */
  material: string | null;
  /** URL of a glTF 2.0 model (.glb, or .gltf with its buffers). */
  model: string | null;
  /** With `model`: NAME:MATERIAL[:REPEAT],... */
  materials: string | null;
  /** ws(s):// of a btfd (its /stream), or the http(s) folder of a published library. Default: ws(s) of the script's origin + /stream; set it when the script comes from an npm build. */
  src: string | null;
  /** A private library's access token v1:SCOPE:EXPIRES:SIG for the material(s). */
  token: string | null;
  /** Base URL of the shader files; default: those inside the script. */
  shaders: string | null;
  geometry: 'plane' | 'sphere' | 'cylinder' | string | null;
  light: 'orbit' | 'fixed' | 'pointer' | 'tilt' | 'none' | string | null;
  lightTheta: number | null;
  lightPhi: number | null;
  /** 'studio', 'none' or the URL of an equirectangular Radiance .hdr */
  environmentImage: string | null;
  environmentRotation: number | null;
  exposure: number | null;
  toneMapping: 'auto' | BtfToneMapping | string | null;
  cameraTheta: number | null;
  cameraPhi: number | null;
  cameraDist: number | null;
  fov: number | null;
  repeat: number | null;
  budgetChunks: number | null;
  budgetBytes: number | null;
  lodThreshold: number | null;
  maxDpr: number | null;
  poster: string | null;
  loading: 'lazy' | 'eager' | string | null;
  cameraControls: boolean;
  alt: string | null;
  /** What the last frame was lit by. */
  readonly lighting: BtfLighting;

  addEventListener<K extends keyof BtfViewerEventMap>(type: K,
    listener: (this: BtfViewer, ev: BtfViewerEventMap[K]) => any, options?: boolean | AddEventListenerOptions): void;
  addEventListener(type: string, listener: EventListenerOrEventListenerObject, options?: boolean | AddEventListenerOptions): void;
  removeEventListener<K extends keyof BtfViewerEventMap>(type: K,
    listener: (this: BtfViewer, ev: BtfViewerEventMap[K]) => any, options?: boolean | EventListenerOptions): void;
  removeEventListener(type: string, listener: EventListenerOrEventListenerObject, options?: boolean | EventListenerOptions): void;

  /**
   * Chunks a viewer asks for a package without `budget-chunks` (pkg: its parsed manifest),
   * -1 for no cap beyond the scene budget. Replaceable.
   */
  static budgetPolicy: (viewer: BtfViewer, pkg?: {version: number} | null) => number;
}

/** Chunks a viewer of this CSS width asks for a package without levels (the default policy). */
export declare function autoBudget(cssWidth: number): number;

declare global {
  interface HTMLElementTagNameMap {
    'btf-viewer': BtfViewer;
  }
}
