// btf-viewer.js - <btf-viewer>: an embeddable WebGL2 viewer of one streamed material.
//
//   <script type="module" src="http://HOST:PORT/btf-viewer.js"></script>
//   <btf-viewer src="ws://HOST:PORT/" material="wool" geometry="sphere"></btf-viewer>
//
// Attributes (all optional but material):
//   src            WebSocket URL of btfd (default: the page's own host)
//   material       material name in the server's library
//   geometry       plane | sphere | cylinder (cloth-like tube)        default plane
//   light          orbit (circles) | fixed | pointer (follows the pointer)  default orbit
//   light-theta, light-phi  light direction in degrees (fixed; start of the orbit)
//   camera-theta, camera-phi, camera-dist, fov   initial camera (then mouse/touch)
//   repeat         material repeats times the geometry's default (default 1)
// Angles, distances and surfaces follow `btf render` (doc/client.md, scene.js).
//   budget-chunks  most chunks to ask for; default: version-2 packages the scene budget
//                  (client/btf-lod.js: finest level the footprint resolves, visible
//                  components; 0 off screen / tab hidden), version 1 by CSS width (autoBudget)
//   lod-threshold  visibility threshold of the scene budget (default 1, RMS on 0..255)
//   budget-bytes   most bytes to ask for
//   max-dpr        cap of devicePixelRatio for the canvas (default 2)
//   shaders        base URL of the shader files (default: http(s) of src + /shaders/)
// Several viewers share one WebSocket per server (btf-stream.js). Test hook:
// window.__btf (viewers' state, capture()).

import {BtfStream} from './btf-stream.js';
import {GpuPackage, loadShaders} from './btf-gl.js';
import {chunksWithinBytes, dequantWeights, dequantWeights8, parseManifest, promisedError} from './btf-package.js';
import {LOD_THRESHOLD, lodFootprint, lodSelect} from './btf-lod.js';
import {MeshRenderer} from './btf-render.js';
import {Orbit} from './orbit.js';
import {GEOMETRIES, sceneDefaults} from './scene.js';

const STYLE_URL = new URL('btf-viewer.css', import.meta.url).href;

// Chunks a viewer of this CSS width asks for when no budget-chunks is set: a small
// viewer cannot show what the later components add ("model no more than a scene
// needs"); refined from the manifest's per-chunk errors by a later issue (8).
export function autoBudget(cssWidth) {
  if (cssWidth >= 1000) return -1;
  return Math.max(2, Math.ceil(cssWidth / 100) + 1);
}

const registry = new Set();
function hook() {
  if (!window.__btf) {
    window.__btf = {
      viewers: () => [...registry].map((v) => v.state()),
      streams: () => BtfStream.all().map((s) => s.stats()),
      capture: (i) => [...registry][i].capture(),
      element: (i) => [...registry][i],
    };
  }
}

function num(el, name, def) {
  const v = parseFloat(el.getAttribute(name));
  return Number.isFinite(v) ? v : def;
}

function sameOriginWs() {
  return `${location.protocol === 'https:' ? 'wss:' : 'ws:'}//${location.host}/`;
}

export class BtfViewer extends HTMLElement {
  static get observedAttributes() {
    return ['material', 'src', 'geometry', 'light', 'light-theta', 'light-phi', 'budget-chunks', 'budget-bytes',
      'repeat', 'lod-threshold', 'fov'];
  }

  constructor() {
    super();
    const root = this.attachShadow({mode: 'open'});
    const link = document.createElement('link');
    link.rel = 'stylesheet';
    link.href = STYLE_URL;
    this.canvas = document.createElement('canvas');
    this.bar = document.createElement('div');
    this.bar.className = 'bar';
    this.label = document.createElement('div');
    this.label.className = 'label';
    this.msg = document.createElement('div');
    this.msg.className = 'msg';
    this.msg.hidden = true;
    root.append(link, this.canvas, this.bar, this.label, this.msg);
    this.frames = 0;
    this.drawnChunks = 0;
    this.uploadChain = Promise.resolve();
    this.gpu = null;
    this.pkg = null;
    this.sub = null;
    this.lost = false;
    this.cssWidth = 0;
    this.t0 = performance.now();
    this.firstFrameMs = null;
    this.firstFrameBytes = null;
    this.complete = false;
  }

  connectedCallback() {
    hook();
    registry.add(this);
    this.geometry = GEOMETRIES.includes(this.getAttribute('geometry')) ? this.getAttribute('geometry') : 'plane';
    const def = sceneDefaults(this.geometry);
    this.orbit = new Orbit(this.canvas, {
      az: num(this, 'camera-phi', def.cameraPhi), el: 90 - num(this, 'camera-theta', def.cameraTheta),
      dist: num(this, 'camera-dist', def.cameraDist),
      onChange: () => {
        this.sceneChanged();
        this.invalidate();
      },
      onPointer: (x, y) => {
        if (this.getAttribute('light') !== 'pointer') return;
        this.lightPhi = (x - 0.5) * 360 - 90;
        this.lightTheta = Math.max(0, Math.min(85, y * 85));
        this.invalidate();
      },
    });
    this.lightTheta = num(this, 'light-theta', def.lightTheta);
    this.lightPhi = num(this, 'light-phi', def.lightPhi);
    this.resizer = new ResizeObserver(() => this.resize());
    this.resizer.observe(this);
    this.onScreen = true;
    this.visibility = new IntersectionObserver((entries) => {
      this.onScreen = entries[entries.length - 1].isIntersecting;
      this.sceneChanged();
      if (this.onScreen) this.invalidate();
    });
    this.visibility.observe(this);
    this.onVisibility = () => this.sceneChanged();
    document.addEventListener('visibilitychange', this.onVisibility);
    this.onLost = (e) => {
      e.preventDefault();
      this.lost = true;
      this.fence = null;
      this.gpu = null;
      this.renderer = null;
      this.showMessage('WebGL context lost; waiting for the browser to restore it');
    };
    this.onRestored = () => {
      this.lost = false;
      this.showMessage('');
      this.setupGl().then(() => this.rebuildGpu()).catch((e) => this.fail(e));
    };
    this.canvas.addEventListener('webglcontextlost', this.onLost);
    this.canvas.addEventListener('webglcontextrestored', this.onRestored);
    this.start();
  }

  disconnectedCallback() {
    registry.delete(this);
    this.resizer?.disconnect();
    this.visibility?.disconnect();
    document.removeEventListener('visibilitychange', this.onVisibility);
    if (this.fence && this.gl) this.gl.deleteSync(this.fence);
    this.fence = null;
    this.orbit?.dispose();
    this.canvas.removeEventListener('webglcontextlost', this.onLost);
    this.canvas.removeEventListener('webglcontextrestored', this.onRestored);
    if (this.sub) this.sub.stream.unsubscribe(this.sub, this);
    this.sub = null;
    this.gpu?.free();
    this.renderer?.free();
    this.gpu = this.renderer = null;
    cancelAnimationFrame(this.raf);
    clearTimeout(this.timer);
    this.raf = 0;
  }

  attributeChangedCallback(name, oldV, newV) {
    if (!this.isConnected || oldV === newV) return;
    if (name === 'material' || name === 'src') {
      this.disconnectedCallback();
      this.connectedCallback();
      return;
    }
    if (name === 'geometry') this.geometry = GEOMETRIES.includes(newV) ? newV : 'plane';
    if (name === 'light-theta') this.lightTheta = num(this, 'light-theta', 45);
    if (name === 'light-phi') this.lightPhi = num(this, 'light-phi', -50);
    if (name.startsWith('budget')) this.budgetChanged();
    if (name === 'repeat' || name === 'lod-threshold' || name === 'fov') this.sceneChanged();
    this.invalidate();
  }

  // ------------------------------------------------------------ setup

  async start() {
    const material = this.getAttribute('material');
    if (!material) return this.fail(new Error('no material attribute'));
    this.gl = this.canvas.getContext('webgl2', {antialias: false, premultipliedAlpha: false, alpha: false});
    if (!this.gl) {
      return this.fail(new Error('This browser cannot show the material: WebGL2 is not available ' +
                                 '(enable hardware acceleration or use a current browser).'), true);
    }
    const src = this.getAttribute('src') || sameOriginWs();
    this.shaderBase = this.getAttribute('shaders') ||
      new URL('shaders/', src.replace(/^ws(s?):/, 'http$1:')).href;
    this.resize();
    try {
      await this.setupGl();
    } catch (e) {
      return this.fail(e);
    }
    if (!this.isConnected) return;
    this.stream = BtfStream.for(src);
    this.sub = this.stream.subscribe(material, this);
    this.updateLabel();
  }

  async setupGl() {
    this.shaders = await loadShaders(this.shaderBase);
    if (this.lost || !this.gl) return;
    this.renderer = new MeshRenderer(this.gl, this.shaders);
  }

  // ------------------------------------------------------------ budget

  // This viewer's own budget {chunks, bytes, error}; -1 = no limit. Without a
  // budget-chunks attribute a version-2 package gets its scene budget (sceneBudget),
  // 0 while the viewer is off screen or the tab hidden (streaming pauses).
  budget(drawing = false) {
    const c = this.getAttribute('budget-chunks');
    let chunks;
    if (c !== null && c !== '') chunks = Math.max(0, parseInt(c, 10) || 0);
    else if (this.pkg && this.pkg.version >= 2) chunks = this.sceneBudget(drawing).limit;
    else chunks = BtfViewer.budgetPolicy(this);
    const bytes = num(this, 'budget-bytes', -1);
    return {chunks, bytes, error: -1};
  }

  // Texels per device pixel of the material at the object's centre (doc/client.md, "Budgets"): the
  // object (2 units across) spans canvas height / (dist tan(fov/2)) device pixels;
  // u runs over 2 units on plane and cylinder, over 2 pi (twice) on the sphere.
  footprint() {
    if (!this.pkg) return 0;
    const fov = num(this, 'fov', 40), dist = this.orbit ? this.orbit.dist : sceneDefaults(this.geometry).cameraDist;
    const px = this.canvas.height / (Math.max(dist, 1e-3) * Math.tan((fov * Math.PI) / 360));
    const rep = num(this, 'repeat', 1) > 0 ? num(this, 'repeat', 1) : 1;
    const perUnit = this.geometry === 'sphere' ? 2 / Math.PI : 1;
    return lodFootprint(this.pkg.width, rep * perUnit, px);
  }

  // lodSelect of the current view (client/btf-lod.js); nothing while paused unless drawing.
  sceneBudget(drawing = false) {
    const paused = !this.onScreen || document.hidden;
    const tpp = paused && !drawing ? 0 : this.footprint();
    return lodSelect(this.pkg, {texelsPerPixel: tpp, threshold: num(this, 'lod-threshold', LOD_THRESHOLD)});
  }

  // Chunks this viewer draws: its own budget within the manifest.
  ownLimit() {
    if (!this.pkg) return 0;
    const b = this.budget(true);
    let n = this.pkg.chunks.length;
    if (b.chunks >= 0) n = Math.min(n, b.chunks);
    if (b.bytes >= 0) n = Math.min(n, chunksWithinBytes(this.pkg, b.bytes));
    return n;
  }

  // The view changed (zoom, on/off screen, tab shown/hidden): a scene budget may too.
  sceneChanged() {
    if (this.sub && this.pkg && this.pkg.version >= 2 && this.getAttribute('budget-chunks') === null)
      this.budgetChanged();
  }

  budgetChanged() {
    if (this.sub) this.sub.stream.updateBudget(this.sub);
    if (this.gpu) this.gpu.reserve(this.ownLimit());
    this.updateLabel();
  }

  // ------------------------------------------------------------ stream events

  onManifest(sub) {
    try {
      this.pkg = parseManifest(sub.manifest);
    } catch (e) {
      return this.fail(e);
    }
    this.gpu?.free();
    this.gpu = null;
    this.uploadChain = Promise.resolve();
    if (this.gl && !this.lost) this.gpu = new GpuPackage(this.gl, this.pkg, Math.max(1, this.ownLimit()));
    this.updateLabel();
  }

  onChunk(sub, j) {
    const gen = this.gpu;
    this.uploadChain = this.uploadChain.then(() => this.uploadChunk(sub, j, gen)).catch((e) => this.fail(e));
  }

  async uploadChunk(sub, j, gpu) {
    if (!gpu || gpu !== this.gpu || this.lost || j < gpu.uploaded) return;
    const chunk = this.pkg.chunks[j];
    const files = sub.chunks[j];
    const data = (name) => files[chunk.files.indexOf(name)];
    const bitmap = await createImageBitmap(new Blob([data(chunk.tex)], {type: 'image/png'}),
                                           {premultiplyAlpha: 'none', colorSpaceConversion: 'none'});
    if (gpu !== this.gpu || this.lost) return bitmap.close();
    const wt = await this.chunkWeights(chunk, data, gpu);
    if (gpu !== this.gpu || this.lost) return bitmap.close();
    gpu.upload(j, bitmap, wt);
    bitmap.close();
    this.updateLabel();
    this.invalidate();
  }

  // Dequantised weights of a chunk: wt-JJ.bin (16-bit, .precise), else version 2's
  // wt-JJ-8.png (8-bit coarse), else null (a chunk that lists only its texture).
  async chunkWeights(chunk, data, gpu) {
    if (chunk.wt) {
      const w = dequantWeights(this.pkg, chunk, data(chunk.wt));
      w.precise = true;
      return w;
    }
    if (!chunk.wt8) return null;
    const bm = await createImageBitmap(new Blob([data(chunk.wt8)], {type: 'image/png'}),
                                       {premultiplyAlpha: 'none', colorSpaceConversion: 'none'});
    const L = this.pkg.lights.dirs, V = this.pkg.views.dirs;
    if (bm.width !== 3 * L || bm.height !== V) {
      bm.close();
      throw new Error(`package ${this.pkg.name}: ${chunk.wt8} is ${bm.width}x${bm.height}, expected ${3 * L}x${V}`);
    }
    const px = gpu.readGrey(bm);
    bm.close();
    return dequantWeights8(this.pkg, chunk, px);
  }

  onComplete() {
    this.complete = true;
    this.updateLabel();
  }

  onError(sub, msg) {
    this.fail(new Error(`${msg.message} (${msg.code})`));
  }

  onStreamError(sub, text) {
    if (!this.complete) this.label.textContent = text;
  }

  // Re-uploads every chunk held by the subscription (after a context restore).
  rebuildGpu() {
    if (!this.pkg || !this.sub) return;
    this.gpu = new GpuPackage(this.gl, this.pkg, Math.max(1, this.ownLimit()));
    this.uploadChain = Promise.resolve();
    this.sub.chunks.forEach((c, j) => c && this.onChunk(this.sub, j));
    this.invalidate();
  }

  // ------------------------------------------------------------ drawing

  resize() {
    const r = this.getBoundingClientRect();
    this.cssWidth = r.width;
    const dpr = Math.min(window.devicePixelRatio || 1, num(this, 'max-dpr', 2));
    const w = Math.max(1, Math.round(r.width * dpr)), h = Math.max(1, Math.round(r.height * dpr));
    if (this.canvas.width !== w || this.canvas.height !== h) {
      this.canvas.width = w;
      this.canvas.height = h;
    }
    if (this.sub && this.getAttribute('budget-chunks') === null) this.budgetChanged();
    this.invalidate();
  }

  invalidate() {
    if (!this.raf && this.isConnected) this.raf = requestAnimationFrame((t) => this.frame(t));
  }

  // The scene in btf render's terms (scene.js sceneDefaults / cameraMake).
  view() {
    const light = this.getAttribute('light') || 'orbit';
    let phi = this.lightPhi;
    if (light === 'orbit' && !matchMedia('(prefers-reduced-motion: reduce)').matches)
      phi += ((performance.now() - this.t0) / 1000) * 30;
    return {
      geometry: this.geometry, cameraTheta: 90 - this.orbit.el, cameraPhi: this.orbit.az,
      cameraDist: this.orbit.dist, lightTheta: this.lightTheta, lightPhi: phi, fov: num(this, 'fov', 40),
      repeat: num(this, 'repeat', 1) > 0 ? num(this, 'repeat', 1) : 1, chunks: this.drawableChunks(),
      background: sceneDefaults(this.geometry).background,
    };
  }

  drawableChunks() {
    return this.gpu ? Math.min(this.gpu.uploaded, this.ownLimit()) : 0;
  }

  draw() {
    if (!this.renderer || this.lost) return false;
    const v = this.view();
    this.renderer.draw(this.gpu, v, this.canvas.width, this.canvas.height);
    if (this.gpu && v.chunks > 0) {
      this.frames++;
      this.drawnChunks = v.chunks;
      if (this.firstFrameMs === null) {
        this.firstFrameMs = performance.now() - this.t0;
        this.firstFrameAt = performance.now(); // since navigation start
        this.firstFrameBytes = this.stream ? this.stream.bytes : null;
      }
    }
    return true;
  }

  // One frame. An orbiting light asks for the next one only after the GPU has
  // finished this one (a fence), and waits as long again: software GL and many
  // viewers on one page never queue frames faster than they are drawn.
  frame() {
    this.raf = 0;
    this.draw();
    clearTimeout(this.timer);
    if (!this.animating()) return;
    const gl = this.gl;
    if (this.fence) gl.deleteSync(this.fence);
    this.fence = gl.fenceSync(gl.SYNC_GPU_COMMANDS_COMPLETE, 0);
    gl.flush();
    const t0 = performance.now();
    const poll = () => {
      if (!this.fence || this.lost || gl.isContextLost()) return;
      if (gl.getSyncParameter(this.fence, gl.SYNC_STATUS) !== gl.SIGNALED) {
        this.timer = setTimeout(poll, 16);
        return;
      }
      gl.deleteSync(this.fence);
      this.fence = null;
      const cost = performance.now() - t0;
      this.timer = setTimeout(() => this.invalidate(), Math.max(16, cost));
    };
    this.timer = setTimeout(poll, 0);
  }

  animating() {
    return (this.getAttribute('light') || 'orbit') === 'orbit' && this.drawableChunks() > 0 && this.onScreen &&
      !matchMedia('(prefers-reduced-motion: reduce)').matches && !document.hidden;
  }

  // Test hook: draws now and returns the canvas pixels, rows top-down, RGBA, base64.
  capture() {
    this.draw();
    const gl = this.gl, w = this.canvas.width, h = this.canvas.height;
    const px = new Uint8Array(4 * w * h);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
    const out = new Uint8Array(4 * w * h);
    for (let y = 0; y < h; y++) out.set(px.subarray(4 * w * (h - 1 - y), 4 * w * (h - y)), 4 * w * y);
    let s = '';
    for (let i = 0; i < out.length; i += 0x8000) s += String.fromCharCode.apply(null, out.subarray(i, i + 0x8000));
    return {width: w, height: h, chunks: this.drawnChunks, rgba: btoa(s)};
  }

  // ------------------------------------------------------------ status

  updateLabel() {
    const p = this.pkg, s = this.sub;
    if (!p || !s) {
      this.label.textContent = this.getAttribute('material') || '';
      return;
    }
    const limit = this.ownLimit();
    const want = p.chunks.slice(0, limit).reduce((a, c) => a + c.bytes, 0) || 1;
    const got = p.chunks.slice(0, Math.min(s.received, limit)).reduce((a, c) => a + c.bytes, 0);
    this.bar.style.width = `${Math.min(100, (100 * got) / want).toFixed(1)}%`;
    this.bar.classList.toggle('done', got >= want);
    const drawn = this.drawableChunks();
    let t = `${p.name} · ${drawn}/${limit} chunks · ${(got / 1024).toFixed(0)} KB`;
    const done = drawn >= limit && limit > 0;
    const e = promisedError(p, drawn);
    if (done && e && Number.isFinite(e.lab)) t += ` · Lab error ${e.lab.toFixed(2)}`;
    else if (done && e && Number.isFinite(e.rmse)) t += ` · RMSE ${e.rmse.toFixed(2)}`;
    this.label.textContent = t;
  }

  showMessage(text) {
    this.msg.textContent = text;
    this.msg.hidden = !text;
  }

  fail(e, noWebgl = false) {
    this.error = String(e && e.message ? e.message : e);
    this.showMessage(this.error);
    this.classList.toggle('no-webgl', noWebgl);
    if (e && e.report) console.error(`${this.error}\n${e.report}`);
  }

  state() {
    return {
      material: this.getAttribute('material'), geometry: this.geometry, cssWidth: this.cssWidth,
      canvas: [this.canvas.width, this.canvas.height], budget: this.budget(), ownLimit: this.ownLimit(),
      manifestChunks: this.pkg ? this.pkg.chunks.length : 0, received: this.sub ? this.sub.received : 0,
      uploaded: this.gpu ? this.gpu.uploaded : 0, uploads: this.gpu ? this.gpu.uploads : 0,
      capacity: this.gpu ? this.gpu.capacity : 0, drawnChunks: this.drawnChunks, frames: this.frames,
      complete: this.complete, error: this.error || null, label: this.label.textContent,
      firstFrameMs: this.firstFrameMs, firstFrameAt: this.firstFrameAt ?? null, firstFrameBytes: this.firstFrameBytes,
      streamBytes: this.sub ? this.sub.bytes : 0, drags: this.orbit ? this.orbit.drags : 0,
      camera: this.orbit ? [this.orbit.az, this.orbit.el, this.orbit.dist] : null, lost: this.lost,
      version: this.pkg ? this.pkg.version : 0, footprint: this.footprint(),
      scene: this.pkg && this.pkg.version >= 2 ? (({level, components, needed, limit, bytes}) =>
        ({level, components, needed, limit, bytes}))(this.sceneBudget()) : null,
      slots: this.gpu ? this.gpu.slots : 0,
    };
  }
}

// Chunks a viewer asks for without a budget-chunks attribute. Replaceable (doc/client.md,
// "Budgets": scene-driven budgets from the screen footprint and the manifest's per-chunk errors);
// a viewer calls budgetChanged() when its inputs change.
BtfViewer.budgetPolicy = (viewer) => autoBudget(viewer.cssWidth || 300);

if (!customElements.get('btf-viewer')) customElements.define('btf-viewer', BtfViewer);
