// btf-lighting.js - the lighting of one <btf-viewer> (doc/lighting.md, doc/client.md
// "Lighting"): which lights are on (the point light of `light`, the environment of
// `environment-image`), the environment's quadratic turned by `environment-rotation` and
// by the tilt, `exposure` and `tone-mapping`, and light="tilt" (DeviceOrientationEvent,
// on iOS after the permission asked on the first tap; the pointer over the element
// where no orientation arrives). The element (btf-viewer.js) owns one and asks it for the
// lights of each frame; environment images are fetched (btf-hdr.js) and projected
// (btf-env.js) once per page and URL.
//
//   lights = new ViewerLighting(element, {changed(), failed(reason)})
//     changed()       the picture must be drawn again (an environment arrived, a tilt)
//     failed(reason)  the environment image cannot be used (the point light still draws)
import {parseHdr} from './btf-hdr.js';
import {envQuadratic, envUniforms, matApply, matMul, rotateQuadratic, rotation, rotationZ, studioImage} from './btf-env.js';
import {dir} from './scene.js';

export const TONE = {none: 0, neutral: 1, aces: 2};
export const LIGHT_MODES = ['orbit', 'fixed', 'pointer', 'tilt', 'none'];
const TILT_MAX_BETA = 60;   // degrees the tilt turns the lighting about the camera's horizontal axis, at most
const TILT_MAX_GAMMA = 90;  // ... and about +z
const ENV_MAX_BYTES = 256 * 1024 * 1024; // an environment image's file, at most

let studioQuad = null;   // the studio's quadratic, in place of an environment that failed
const quads = new Map(); // absolute URL (or 'studio') -> Promise of the quadratic (btf-env.js)

// The quadratic of the environment at url ('studio': the built-in), fetched and projected
// once per page; a failure is forgotten, so the next viewer tries again.
export function environmentAt(url) {
  if (!quads.has(url)) {
    const p = url === 'studio' ? Promise.resolve(envQuadratic(studioImage())) : fetchEnvironment(url);
    p.catch(() => quads.get(url) === p && quads.delete(url));
    quads.set(url, p);
  }
  return quads.get(url);
}

async function fetchEnvironment(url) {
  const name = decodeURIComponent(new URL(url).pathname.split('/').pop() || url);
  let r;
  try {
    r = await fetch(url);
  } catch (e) {
    throw new Error(`${name}: cannot be fetched (${e.message})`);
  }
  if (!r.ok) throw new Error(`${name}: cannot be fetched (HTTP ${r.status})`);
  const n = +r.headers.get('content-length');
  if (n > ENV_MAX_BYTES) throw new Error(`${name}: ${n} bytes, more than ${ENV_MAX_BYTES}`);
  const bytes = new Uint8Array(await r.arrayBuffer());
  if (bytes.length > ENV_MAX_BYTES) throw new Error(`${name}: more than ${ENV_MAX_BYTES} bytes`);
  return envQuadratic(parseHdr(bytes, {name}));
}

const clamp = (v, lo, hi) => Math.max(lo, Math.min(hi, v));
const num = (el, name, def) => {
  const v = parseFloat(el.getAttribute(name));
  return Number.isFinite(v) ? v : def;
};

// Owned by one element, for its lifetime.
export class ViewerLighting {
  constructor(el, {changed, failed}) {
    this.el = el;
    this.changed = changed;
    this.failed = failed;
    this.env = {key: null, quad: null, state: 'none', error: null}; // the environment in use
    this.tilt = {beta: 0, gamma: 0, source: null, permission: null, ref: null};
    this.listening = false;
    this.last = null;       // the last frame's lights (the `lighting` property)
    this.rotated = {key: null, uniforms: null};
    this.onOrientation = (e) => this.orientation(e);
    this.onTap = () => this.askPermission();
  }

  // The light attribute, one of LIGHT_MODES, or null when absent (an unknown value reads as fixed).
  get mode() {
    const l = this.el.getAttribute('light');
    return l === null ? null : LIGHT_MODES.includes(l) ? l : 'fixed';
  }

  // The point light is on: any `light` but none (doc/lighting.md: without `light` and
  // without `environment-image` the studio alone lights the scene).
  get point() {
    const m = this.mode;
    return m !== null && m !== 'none';
  }

  // What environment-image asks for: null (none), 'studio', or an absolute URL.
  wanted() {
    const a = this.el.getAttribute('environment-image');
    if (a === null) return this.mode === null ? 'studio' : null;
    const t = a.trim();
    if (t === '' || t === 'none') return null;
    if (t === 'studio') return 'studio';
    try {
      return new URL(t, document.baseURI).href;
    } catch {
      return t; // fails to load, with its name
    }
  }

  // The attributes changed (or the viewer started): loads the environment they name,
  // starts or stops the tilt. load: whether images may be fetched (the viewer started).
  update(load = true) {
    this.tiltListen(this.mode === 'tilt');
    const key = this.wanted();
    if (key === this.env.key && this.env.state !== 'idle') return;
    this.env = {key, quad: null, state: key === null ? 'none' : 'idle', error: null};
    if (key === null || !load) return;
    this.env.state = 'loading';
    const env = this.env;
    environmentAt(key).then((q) => {
      if (this.env !== env) return;
      env.quad = q;
      env.state = 'ready';
      this.changed();
    }, (e) => {
      if (this.env !== env) return;
      env.state = 'failed';
      env.error = e.message;
      this.failed(e.message);
      this.changed();
    });
  }

  // The environment that lights the frame: the one asked for once loaded; in its place
  // the studio when it failed and no point light is on (something must light the scene).
  envQuad() {
    if (this.env.state === 'ready') return this.env.quad;
    if (this.env.state === 'failed' && !this.point) return (studioQuad ??= envQuadratic(studioImage()));
    return null;
  }

  // The light terms a frame uses, {point, env} (the program variant): the environment
  // counts while it loads (the frame waits for it), and the studio in place of one that failed.
  on() {
    return {point: this.point, env: this.env.key !== null && (this.env.state !== 'failed' || !this.point)};
  }

  // The lights of a frame: `base` {lightTheta, lightPhi, cameraPhi} (the point light after
  // the orbit). Returns {point, env (uniforms, btf-env.js envUniforms) | null, exposure,
  // tone (TONE), pending (the environment is on its way: the frame waits), lightTheta,
  // lightPhi}.
  frame(base) {
    const point = this.point, q = this.envQuad(), tilt = this.mode === 'tilt';
    const rot = num(this.el, 'environment-rotation', 0);
    // the tilt: gamma about +z, then beta about the camera's horizontal axis
    const R = tilt ? matMul(rotation([-Math.sin(base.cameraPhi * Math.PI / 180), Math.cos(base.cameraPhi * Math.PI / 180), 0],
      this.tilt.beta), rotationZ(this.tilt.gamma)) : null;
    let {lightTheta, lightPhi} = base;
    if (R && point && !q) { // the tilt turns the point light (an environment, when there is one)
      const l = matApply(R, dir(lightTheta, lightPhi));
      lightTheta = Math.acos(clamp(l[2], -1, 1)) * 180 / Math.PI;
      lightPhi = Math.atan2(l[1], l[0]) * 180 / Math.PI;
    }
    let env = null;
    if (q) {
      const key = `${this.env.key}|${rot}|${R ? R.flat().join(',') : ''}|${this.env.state}`;
      if (this.rotated.key !== key) {
        const Rz = rotationZ(rot);
        this.rotated = {key, uniforms: envUniforms(rotateQuadratic(q, R ? matMul(R, Rz) : Rz))};
      }
      env = this.rotated.uniforms;
    }
    const exposure = Math.max(0, num(this.el, 'exposure', 1));
    const t = this.el.getAttribute('tone-mapping');
    const tone = t in TONE ? TONE[t] : env ? TONE.neutral : TONE.none; // auto
    const pending = this.env.state === 'loading' || this.env.state === 'idle';
    this.last = {point, env: !!env, lightTheta, lightPhi, rotation: rot + (tilt && env ? this.tilt.gamma : 0),
      tilt: tilt && env ? this.tilt.beta : 0, exposure, tone};
    return {point, env, exposure, tone, pending, lightTheta, lightPhi};
  }

  // The `lighting` property of the element (doc/client.md): what the last frame used.
  state() {
    const l = this.last || {point: this.point, env: false, lightTheta: null, lightPhi: null, rotation: 0, tilt: 0,
      exposure: 1, tone: 0};
    return {
      light: this.mode,
      point: {on: l.point, theta: l.point ? l.lightTheta : null, phi: l.point ? l.lightPhi : null},
      environment: {image: this.env.key, state: this.env.state, error: this.env.error, on: l.env,
        rotation: l.rotation, tilt: l.tilt},
      exposure: l.exposure, toneMapping: Object.keys(TONE).find((k) => TONE[k] === l.tone),
      tilt: this.mode === 'tilt' ? {beta: this.tilt.beta, gamma: this.tilt.gamma, source: this.tilt.source,
        permission: this.tilt.permission} : null,
    };
  }

  // ------------------------------------------------------------ tilt

  // light="tilt": listens to the device's orientation (on iOS once the permission is
  // granted, asked on the first tap on the element).
  tiltListen(on) {
    if (on === this.listening) return;
    this.listening = on;
    const DOE = typeof DeviceOrientationEvent !== 'undefined' ? DeviceOrientationEvent : null;
    if (!on) {
      removeEventListener('deviceorientation', this.onOrientation);
      this.el.removeEventListener('click', this.onTap);
      this.el.removeEventListener('touchend', this.onTap);
      this.tilt = {beta: 0, gamma: 0, source: null, permission: this.tilt.permission, ref: null};
      return;
    }
    if (DOE && typeof DOE.requestPermission === 'function' && this.tilt.permission !== 'granted') {
      this.tilt.permission = this.tilt.permission || 'prompt';
      this.el.addEventListener('click', this.onTap);
      this.el.addEventListener('touchend', this.onTap);
    } else {
      if (!this.tilt.permission) this.tilt.permission = 'not-needed';
      addEventListener('deviceorientation', this.onOrientation);
    }
  }

  askPermission() {
    if (this.tilt.permission !== 'prompt') return;
    this.tilt.permission = 'asked';
    this.el.removeEventListener('click', this.onTap);
    this.el.removeEventListener('touchend', this.onTap);
    Promise.resolve().then(() => DeviceOrientationEvent.requestPermission()).then((r) => {
      this.tilt.permission = r === 'granted' ? 'granted' : 'denied';
      if (r === 'granted' && this.listening) addEventListener('deviceorientation', this.onOrientation);
    }, () => {
      this.tilt.permission = 'denied';
    });
  }

  // An orientation reading: angles relative to the first one.
  orientation(e) {
    if (!Number.isFinite(e.beta) || !Number.isFinite(e.gamma)) return; // a desktop without sensors
    if (!this.tilt.ref) this.tilt.ref = {beta: e.beta, gamma: e.gamma};
    const wrap = (a) => ((a % 360) + 540) % 360 - 180;
    this.tilt.beta = clamp(wrap(e.beta - this.tilt.ref.beta), -TILT_MAX_BETA, TILT_MAX_BETA);
    this.tilt.gamma = clamp(wrap(e.gamma - this.tilt.ref.gamma), -TILT_MAX_GAMMA, TILT_MAX_GAMMA);
    this.tilt.source = 'orientation';
    this.changed();
  }

  // The pointer at (x, y) in 0..1 over the element: the tilt where no orientation arrives.
  pointer(x, y) {
    if (this.mode !== 'tilt' || this.tilt.source === 'orientation') return;
    this.tilt.gamma = clamp((x - 0.5) * 2 * TILT_MAX_GAMMA, -TILT_MAX_GAMMA, TILT_MAX_GAMMA);
    this.tilt.beta = clamp((y - 0.5) * 2 * TILT_MAX_BETA, -TILT_MAX_BETA, TILT_MAX_BETA);
    this.tilt.source = 'pointer';
    this.changed();
  }

  dispose() {
    this.tiltListen(false);
  }
}
