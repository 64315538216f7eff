// btf-viewer.js - <btf-viewer>: an embeddable WebGL2 viewer of one streamed material.
//
//   <script type="module" src="http://HOST:PORT/btf-viewer.js"></script>
//   <btf-viewer material="wool" geometry="sphere" camera-controls></btf-viewer>
//
// The server (src) and the shader files default to the origin of this script, so the
// two lines work on a page of any origin (btfd sends CORS headers, doc/protocol.md).
// Attributes (each also a JS property, camelCase; every one reacts when changed; the
// table with defaults and the events is in doc/client.md):
//   src            WebSocket URL of btfd (default: ws(s) of this script's origin + /stream)
//   material       material name in the server's library
//   geometry       plane | sphere | cylinder (cloth-like tube)        default plane
//   light          orbit (circles) | fixed | pointer (follows the pointer)  default orbit
//   light-theta, light-phi  light direction in degrees (fixed; start of the orbit)
//   camera-theta, camera-phi, camera-dist, fov   camera (then mouse/touch/keys with camera-controls)
//   repeat         material repeats times the geometry's default (default 1)
// Angles, distances and surfaces follow `btf render` (doc/client.md, scene.js).
//   budget-chunks  most chunks to ask for; default: version-2 packages the scene budget
//                  (client/btf-lod.js: finest level the footprint resolves, visible
//                  components; 0 off screen / tab hidden), version 1 by CSS width (autoBudget)
//   lod-threshold  visibility threshold of the scene budget (default 1, RMS on 0..255)
//   budget-bytes   most bytes to ask for
//   max-dpr        cap of devicePixelRatio for the canvas (default 2)
//   shaders        base URL of the shader files (default: shaders/ next to this script)
//   poster         image shown until the first frame (default: the material's thumbnail, if any)
//   loading        lazy (default: nothing starts until the viewer nears the viewport) | eager
//   camera-controls  orbit/zoom by pointer, wheel (once engaged) and arrow keys
//   alt            accessible description (role="img", aria-label)
// Events (bubbling, composed): load, progress, complete, error, camera-change.
// All viewers share one WebGL2 context (btf-context.js) and one WebSocket per server
// (btf-stream.js). Test hook: window.__btf (viewers' state, capture()).

// Every module of the element is imported here, so the browser asks for all of them
// in one round trip (btf-cache.js, btf-render.js and btf-dirtab.js are otherwise found
// one level deeper).
import './btf-cache.js';
import './btf-dirtab.js';
import {BtfStream} from './btf-stream.js';
import {GpuPackage, decodeDefines, loadShaders} from './btf-gl.js';
import {MeshRenderer} from './btf-render.js';
import {sharedGl, sharedStats} from './btf-context.js';
import {decodeImage, decoderKind} from './btf-decode.js';
import {chunksWithinBytes, decodeWeights, dequantWeights8, parseManifest, promisedError} from './btf-package.js';
import {LOD_THRESHOLD, lodSelect} from './btf-lod.js';
import {Orbit} from './orbit.js';
import {GEOMETRIES, orbitLight, pixelsPerUnit, sceneDefaults} from './scene.js';
import {VIEWER_CSS, viewerSheet} from './btf-viewer-style.js';
import {SHADER_PACK} from './btf-shader-pack.js';

const SCRIPT_AT = performance.now(); // when the element's modules ran (ms from navigation start)
const SHADERS_URL = new URL('shaders/', import.meta.url).href;
const GL_AFTER_MS = 1000; // the WebGL context is made once the subscribe is out, or this long after start
const SLOW_FRAME_MS = 150; // a frame the GPU needs longer for (twice in a row) lowers the resolution ...
const SOFTWARE_SCALE = 0.4; // a software rasteriser (SwiftShader, llvmpipe) starts at this share
const MIN_SCALE = 0.35;    // ... down to this share of the device pixels per CSS pixel
const GPU_POLL_MS = 8;     // how often a frame waiting for the GPU asks again // the WebGL context is made this long after start at the latest
const SHADER_RETRY_MS = [500, 1000, 2000, 4000, 8000]; // then the last, while the viewer lives
const LAZY_MARGIN = '300px'; // loading="lazy": start this far before the viewport

// Attribute -> property type; the property is the camelCase name.
const ATTRS = {
  material: 'string', src: 'string', geometry: 'string', light: 'string', 'light-theta': 'number',
  'light-phi': 'number', 'camera-theta': 'number', 'camera-phi': 'number', 'camera-dist': 'number', fov: 'number',
  repeat: 'number', 'budget-chunks': 'number', 'budget-bytes': 'number', 'lod-threshold': 'number',
  'max-dpr': 'number', shaders: 'string', poster: 'string', loading: 'string', 'camera-controls': 'boolean',
  alt: 'string',
};
const RESTART = new Set(['material', 'src', 'shaders']);
const SCENE = new Set(['repeat', 'lod-threshold', 'fov', 'geometry']);
const CAMERA = new Set(['camera-theta', 'camera-phi', 'camera-dist']);

// Chunks a viewer of this CSS width asks for a package without levels when no
// budget-chunks is set: a small viewer cannot show what the later components add
// ("model no more than a scene needs"). Packages with levels get the scene budget.
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
      gl: () => ({...sharedStats(), packages: GpuPackage.live}),
    };
  }
}

function num(el, name, def) {
  const v = parseFloat(el.getAttribute(name));
  return Number.isFinite(v) ? v : def;
}

// ws(s)://HOST/stream of the origin this script came from.
function scriptWs() {
  const u = new URL(import.meta.url);
  return `${u.protocol === 'https:' ? 'wss:' : 'ws:'}//${u.host}/stream`;
}

const lists = new Map(); // http base -> Promise of GET /materials (poster thumbnails)
function materialList(base) {
  if (!lists.has(base)) {
    lists.set(base, fetch(new URL('materials', base)).then((r) => (r.ok ? r.json() : {materials: []}))
      .catch(() => ({materials: []})));
  }
  return lists.get(base);
}

const reducedMotion = () => matchMedia('(prefers-reduced-motion: reduce)').matches;
const camel = (a) => a.replace(/-([a-z])/g, (_, c) => c.toUpperCase());

export class BtfViewer extends HTMLElement {
  static get observedAttributes() {
    return Object.keys(ATTRS);
  }

  constructor() {
    super();
    const root = this.attachShadow({mode: 'open'});
    const sheet = viewerSheet();
    if (sheet) root.adoptedStyleSheets = [sheet];
    else root.append(Object.assign(document.createElement('style'), {textContent: VIEWER_CSS}));
    this.canvas = document.createElement('canvas');
    this.waitEl = document.createElement('div');
    this.waitEl.className = 'wait';
    this.posterImg = document.createElement('img');
    this.posterImg.className = 'poster';
    this.posterImg.alt = '';
    this.posterImg.hidden = true;
    this.bar = document.createElement('div');
    this.bar.className = 'bar';
    this.label = document.createElement('div');
    this.label.className = 'label';
    this.msg = document.createElement('div');
    this.msg.className = 'msg';
    this.msg.hidden = true;
    root.append(this.canvas, this.waitEl, this.posterImg, this.bar, this.label, this.msg);
    this.ctx2d = null;
    this.gen = 0;
    this.started = false;
    this.reset();
  }

  // Per-stream state (cleared when material, src or shaders change).
  reset() {
    this.frames = 0;
    this.drawnChunks = 0;
    this.uploadChain = Promise.resolve();
    this.closeReady();
    this.gpu = null;
    this.pkg = null;
    this.sub = null;
    this.renderer = null;
    this.lost = false;
    this.t0 = performance.now();
    this.firstFrameMs = null;
    this.firstFrameBytes = null;
    this.complete = false;
    this.loaded = false;
    this.completeFor = -1;
    this.error = null;
    this.outages = {stream: null, shaders: null}; // reasons of outages whose error event went out
    this.shaderTry = 0;
    this.shaderFiles = null;    // Promise of the "render" program's files
    this.nextDecode = 0;
    this.times = {script: SCRIPT_AT}; // ms from navigation start: the loading sequence (doc/client.md)
    this.usedVariants = new Set(); // program variants drawn with (a first draw includes the driver's compile)
    this.measured = null;
    this.waitEl.hidden = false;
  }

  connectedCallback() {
    hook();
    registry.add(this);
    this.geometry = GEOMETRIES.includes(this.getAttribute('geometry')) ? this.getAttribute('geometry') : 'plane';
    this.makeOrbit();
    this.lightTheta = num(this, 'light-theta', sceneDefaults(this.geometry).lightTheta);
    this.lightPhi = num(this, 'light-phi', sceneDefaults(this.geometry).lightPhi);
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
    this.setControls();
    this.setAria();
    this.setPoster();
    if (this.getAttribute('loading') === 'eager') this.start();
    else this.startWhenNear();
  }

  disconnectedCallback() {
    registry.delete(this);
    this.resizer?.disconnect();
    this.visibility?.disconnect();
    this.near?.disconnect();
    this.near = null;
    document.removeEventListener('visibilitychange', this.onVisibility);
    this.orbit?.dispose();
    this.orbit = null;
    this.stop();
    this.started = false;
  }

  // loading="lazy": starts once the viewer is within LAZY_MARGIN of the viewport.
  startWhenNear() {
    if (this.started || this.near) return;
    const r = this.getBoundingClientRect(), m = parseInt(LAZY_MARGIN, 10);
    if (r.width > 0 && r.height > 0 && r.bottom > -m && r.top < innerHeight + m && r.right > -m && r.left < innerWidth + m && !document.hidden)
      return this.start(); // near the viewport already: no observer round (it answers only after a frame)
    this.near = new IntersectionObserver((entries) => {
      if (!entries.some((e) => e.isIntersecting)) return;
      this.near.disconnect();
      this.near = null;
      if (!this.started && this.isConnected) this.start();
    }, {rootMargin: LAZY_MARGIN});
    this.near.observe(this);
  }

  // Cancels everything in flight: subscription, uploads, GPU package, frames.
  stop() {
    this.gen++;
    if (this.sub) this.sub.stream.unsubscribe(this.sub, this);
    this.gpu?.free();
    this.ctx?.users.delete(this);
    this.ctx = null;
    cancelAnimationFrame(this.raf);
    clearTimeout(this.gpuWait);
    clearTimeout(this.timer);
    this.raf = 0;
    this.reset();
  }

  attributeChangedCallback(name, oldV, newV) {
    if (!this.orbit || oldV === newV) return; // before connectedCallback (an upgrade): it reads them all
    if (RESTART.has(name)) return this.restart();
    if (name === 'geometry') this.geometry = GEOMETRIES.includes(newV) ? newV : 'plane';
    if (name === 'light-theta') this.lightTheta = num(this, name, sceneDefaults(this.geometry).lightTheta);
    if (name === 'light-phi') this.lightPhi = num(this, name, sceneDefaults(this.geometry).lightPhi);
    if (CAMERA.has(name)) this.setCamera();
    if (name.startsWith('budget')) this.budgetChanged();
    if (SCENE.has(name) || CAMERA.has(name)) this.sceneChanged();
    if (name === 'max-dpr') this.resize();
    if (name === 'poster') this.setPoster();
    if (name === 'loading' && newV === 'eager' && !this.started) this.start();
    if (name === 'camera-controls') this.setControls();
    if (name === 'alt') this.setAria();
    this.invalidate();
  }

  restart() {
    const was = this.started;
    this.stop();
    this.started = false;
    this.setPoster();
    if (was) this.start();
    else if (this.getAttribute('loading') !== 'eager') this.startWhenNear();
  }

  // ------------------------------------------------------------ page citizenship

  makeOrbit() {
    const def = sceneDefaults(this.geometry);
    this.orbit = new Orbit(this.canvas, {
      az: num(this, 'camera-phi', def.cameraPhi), el: 90 - num(this, 'camera-theta', def.cameraTheta),
      dist: num(this, 'camera-dist', def.cameraDist),
      onChange: () => this.cameraMoved(),
      onPointer: (x, y) => {
        if (this.getAttribute('light') !== 'pointer') return;
        this.lightPhi = (x - 0.5) * 360 - 90;
        this.lightTheta = Math.max(0, Math.min(85, y * 85));
        this.invalidate();
      },
      canWheel: () => this.engaged,
    });
  }

  setCamera() {
    const def = sceneDefaults(this.geometry);
    this.orbit.az = num(this, 'camera-phi', def.cameraPhi);
    this.orbit.el = 90 - num(this, 'camera-theta', def.cameraTheta);
    this.orbit.dist = num(this, 'camera-dist', def.cameraDist);
    this.emit('camera-change', this.cameraState());
  }

  cameraMoved() {
    this.sceneChanged();
    this.invalidate();
    this.emit('camera-change', this.cameraState());
  }

  cameraState() {
    return {theta: 90 - this.orbit.el, phi: this.orbit.az, dist: this.orbit.dist};
  }

  // camera-controls: pointer orbit and pinch, wheel zoom once engaged (clicked or
  // focused), arrow keys; without it the page scrolls and zooms as if the viewer were an image.
  setControls() {
    const on = this.hasAttribute('camera-controls');
    this.orbit.attach(on);
    if (on && !this.hasAttribute('tabindex')) {
      this.tabIndex = 0; // keyboard orbit
      this.autoTab = true;
    } else if (!on && this.autoTab) {
      this.removeAttribute('tabindex');
      this.autoTab = false;
    }
    if (!this.onKey) {
      this.onKey = (e) => {
        if (this.hasAttribute('camera-controls') && this.orbit.key(e)) e.preventDefault();
      };
      this.addEventListener('keydown', this.onKey);
      this.addEventListener('pointerdown', () => { this.engaged = true; });
      this.addEventListener('focus', () => { this.engaged = true; });
      this.addEventListener('blur', () => { this.engaged = false; });
    }
  }

  setAria() {
    const alt = this.getAttribute('alt');
    if (alt !== null) {
      this.setAttribute('role', 'img');
      this.setAttribute('aria-label', alt);
    } else if (this.getAttribute('role') === 'img') {
      this.removeAttribute('role');
      this.removeAttribute('aria-label');
    }
  }

  // poster: the attribute's image, else (once started) the material's thumbnail when the server has one.
  setPoster() {
    const url = this.getAttribute('poster');
    this.posterImg.loading = this.getAttribute('loading') === 'eager' ? 'eager' : 'lazy';
    if (url) this.posterImg.src = new URL(url, document.baseURI).href;
    else this.posterImg.removeAttribute('src');
    this.posterImg.hidden = !url || this.loaded;
    if (url) this.posterShown = this.posterImg.src;
  }

  async defaultPoster(gen) {
    const name = this.getAttribute('material');
    if (this.getAttribute('poster') || !name) return;
    const base = this.src.replace(/^ws(s?):/, 'http$1:');
    const list = await materialList(base);
    const m = (list.materials || []).find((x) => x.name === name);
    if (gen !== this.gen || !m || !m.thumbnail || this.loaded) return;
    this.posterImg.src = new URL(m.thumbnail, base).href;
    this.posterImg.hidden = false;
    this.posterShown = this.posterImg.src;
  }

  emit(type, detail) {
    this.dispatchEvent(new CustomEvent(type, {bubbles: true, composed: true, detail}));
  }

  // ------------------------------------------------------------ setup

  // The loading sequence (doc/client.md, "Loading"): the subscription (its budget from
  // the element's size) and the shader files go out first, in parallel; the WebGL
  // context is made while they travel; the program compiles once the manifest says
  // which variant; chunks decode in a worker and every frame draws all that arrived.
  start() {
    this.started = true;
    const gen = this.gen;
    const material = this.getAttribute('material');
    if (!material) return this.fail(new Error('no material attribute'));
    if (typeof WebGL2RenderingContext === 'undefined') return this.noWebgl();
    this.src = this.getAttribute('src') || scriptWs();
    // the shader files: the `shaders` attribute's, else those inside the script (the
    // bundle), else those next to it
    this.shaderBase = this.getAttribute('shaders') || (SHADER_PACK ? 'inside:' : SHADERS_URL);
    this.times.start = performance.now();
    this.resize(); // the canvas size: the first subscribe's footprint
    this.fetchShaders(gen); // before the subscribe: a shared subscription replays its manifest at once
    this.stream = BtfStream.for(this.src);
    this.stream.subscribe(material, this); // sets this.sub (onSubscribe)
    this.defaultPoster(gen);
    this.updateLabel();
    // the context once the subscribe is out (onStreamOpen: made while the manifest and the
    // first chunk travel; it blocks the page, so not before), or later if the server is slow
    setTimeout(() => this.ensureGl(gen), GL_AFTER_MS);
  }

  noWebgl() {
    return this.fail(new Error('This browser cannot show the material: WebGL2 is not available ' +
                               '(enable hardware acceleration or use a current browser).'), true);
  }

  // The shared context (made once per page) and this viewer's renderer; false without WebGL2.
  ensureGl(gen = this.gen) {
    if (gen !== this.gen || !this.started) return false;
    if (this.ctx) return true;
    const ctx = sharedGl();
    if (!ctx) {
      this.noWebgl();
      return false;
    }
    this.ctx = ctx;
    this.ctx.users.add(this);
    this.gl = ctx.gl;
    this.ctx2d = this.ctx2d || this.canvas.getContext('2d', {alpha: false});
    this.times.gl = performance.now();
    if (ctx.software && !this.hasAttribute('max-dpr') && !this.scale) { // known slow: start at fewer pixels
      this.scale = SOFTWARE_SCALE;
      this.resize();
    }
    this.loadRenderer(gen);
    if (this.pkg && !this.gpu) this.newGpu();
    return true;
  }

  // The "render" program's files (only those), fetched at once; a failed fetch is tried
  // again with backoff (a dropped link must not leave the viewer without shaders).
  fetchShaders(gen) {
    this.shaderFiles = this.shaderBase === 'inside:'
      ? Promise.resolve({manifest: SHADER_PACK.manifest, files: new Map(Object.entries(SHADER_PACK.files))})
      : loadShaders(this.shaderBase, 'render');
    this.shaderFiles.then(() => {
      if (gen === this.gen) this.times.shaders ??= performance.now();
    }, (e) => {
      if (gen !== this.gen) return;
      const delay = SHADER_RETRY_MS[Math.min(this.shaderTry++, SHADER_RETRY_MS.length - 1)];
      this.trouble('shaders', `${e.message}; trying again`);
      setTimeout(() => gen === this.gen && this.fetchShaders(gen), delay);
    });
  }

  loadRenderer(gen) {
    const base = this.shaderBase;
    this.shaderFiles.then(() => this.ctx.renderer(base, this.shaderFiles)).then((r) => {
      if (gen !== this.gen) return;
      this.renderer = r;
      // the variant of a first frame (one 4-slot layer; levels once the manifest says)
      // compiles while the first chunk travels
      r.start(this.firstVariant());
      this.recovered('shaders');
      this.invalidate();
    }, () => {
      if (gen === this.gen) setTimeout(() => gen === this.gen && this.ctx && this.loadRenderer(gen), 250);
    });
  }

  contextLost() {
    this.lost = true;
    this.closeReady();
    this.gpu?.free();
    this.gpu = null;
    this.renderer = null;
    this.showMessage('WebGL context lost; waiting for the browser to restore it');
  }

  contextRestored() {
    const gen = this.gen;
    this.lost = false;
    this.showMessage('');
    this.ctx.renderer(this.shaderBase, this.shaderFiles).then((r) => {
      if (gen !== this.gen) return;
      this.renderer = r;
      this.rebuildGpu();
    }).catch((e) => gen === this.gen && this.fail(e));
  }

  // ------------------------------------------------------------ budget

  // This viewer's own budget {chunks, bytes, error, pixels, threshold}; -1 = no limit.
  // Without a budget-chunks attribute: the scene budget, sent as the footprint (`pixels`,
  // device pixels one repeat of the material spans) so the server applies it from the
  // first subscribe on, before the manifest is here; once it is, also as the chunk count
  // of lodSelect (client/btf-lod.js), capped for packages without levels by
  // BtfViewer.budgetPolicy. 0 pixels while the viewer is off screen or the tab hidden
  // (streaming pauses).
  budget(drawing = false) {
    const c = this.getAttribute('budget-chunks'), bytes = num(this, 'budget-bytes', -1);
    if (c !== null && c !== '')
      return {chunks: Math.max(0, parseInt(c, 10) || 0), bytes, error: -1, pixels: -1, threshold: -1};
    const paused = !this.onScreen || document.hidden;
    const pixels = paused && !drawing ? 0 : this.pixelsPerRepeat();
    const threshold = num(this, 'lod-threshold', LOD_THRESHOLD);
    let chunks = -1;
    if (this.pkg) {
      const policy = BtfViewer.budgetPolicy(this);
      chunks = this.sceneBudget(drawing).limit;
      if (policy >= 0) chunks = Math.min(chunks, policy);
    }
    return {chunks, bytes, error: -1, pixels, threshold};
  }

  // Device pixels across which one repeat of the material spans at the object's centre
  // (doc/client.md, "Budgets"): the object, 2 units across, spans 2 pixelsPerUnit
  // (scene.js: the field of view spans the narrower side); u runs over 2 units on plane
  // and cylinder, over 2 pi (twice) on the sphere.
  pixelsPerRepeat() {
    const fov = num(this, 'fov', 40), dist = this.orbit ? this.orbit.dist : sceneDefaults(this.geometry).cameraDist;
    const [w, h] = this.display || [this.canvas.width, this.canvas.height];
    const px = 2 * pixelsPerUnit({cameraDist: Math.max(dist, 1e-3), fov}, w, h);
    const rep = num(this, 'repeat', 1) > 0 ? num(this, 'repeat', 1) : 1;
    const perUnit = this.geometry === 'sphere' ? 2 / Math.PI : 1;
    return px / (rep * perUnit);
  }

  // Texels per device pixel of the material at the object's centre (btf_lod_footprint).
  footprint() {
    if (!this.pkg) return 0;
    const px = this.pixelsPerRepeat();
    return px > 0 && this.pkg.width > 0 ? this.pkg.width / px : 0;
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
    if (this.sub && this.getAttribute('budget-chunks') === null) this.budgetChanged();
  }

  budgetChanged() {
    if (this.sub) this.sub.stream.updateBudget(this.sub);
    if (this.gpu) this.gpu.reserve(this.ownLimit());
    this.pump();
    this.updateLabel();
  }

  // ------------------------------------------------------------ stream events

  onSubscribe(sub) {
    this.sub = sub;
  }

  onManifest(sub) {
    if (sub !== this.sub) return;
    try {
      this.pkg = parseManifest(sub.manifest);
    } catch (e) {
      return this.fail(e);
    }
    this.times.manifest ??= performance.now();
    this.recovered('stream');
    if (!this.ctx && !this.ensureGl()) return;
    this.newGpu();
    if (this.renderer && this.gpu) this.renderer.start(this.firstVariant());
    this.updateLabel();
    this.invalidate(); // starts the program's compile
  }

  // A fresh GPU package for the manifest (also after a context restore); uploads what is held.
  newGpu() {
    this.gpu?.free();
    this.gpu = null;
    this.uploadChain = Promise.resolve();
    this.closeReady();
    this.nextDecode = 0;
    if (this.gl && !this.lost) this.gpu = new GpuPackage(this.gl, this.pkg, Math.max(1, this.ownLimit()));
    this.pump();
  }

  onChunk(sub, j) {
    if (sub !== this.sub || !this.pkg) return;
    if (j === 0) this.times.chunk ??= sub.arrivedAt[0] ?? performance.now();
    this.recovered('stream');
    this.emit('progress', this.progress(j + 1)); // chunks arrive in order: j + 1 are here
    this.pump();
  }

  // Queues the decode of every held chunk inside this viewer's budget not queued yet: the
  // subscription may hold more (a larger budget of another viewer, the browser cache).
  pump() {
    const sub = this.sub, gpu = this.gpu, gen = this.gen, limit = this.ownLimit();
    if (!sub || !gpu) return;
    for (; this.nextDecode < limit && sub.chunks[this.nextDecode]; this.nextDecode++) {
      const j = this.nextDecode;
      this.uploadChain = this.uploadChain.then(() => this.decodeChunk(sub, j, gpu))
        .catch((e) => gen === this.gen && this.fail(e));
    }
  }

  // Received against wanted (this viewer's budget), and the error the received prefix promises.
  progress(received = this.sub ? this.sub.received : 0) {
    const p = this.pkg, limit = this.ownLimit();
    const got = Math.min(received, limit);
    const bytes = (n) => p.chunks.slice(0, n).reduce((a, c) => a + c.bytes, 0);
    const e = promisedError(p, got);
    return {chunks: got, chunksWanted: limit, bytes: bytes(got), bytesWanted: bytes(limit),
            error: e ? (Number.isFinite(e.lab) ? e.lab : e.rmse ?? null) : null,
            metric: e && Number.isFinite(e.lab) ? 'lab' : 'rmse'};
  }

  current(sub, gpu) {
    return sub === this.sub && gpu && gpu === this.gpu && !this.lost;
  }

  // Decodes chunk j off the main thread (btf-decode.js: its image files; btf-package.js:
  // its weights) and queues it; the next frame uploads every queued chunk, then draws.
  async decodeChunk(sub, j, gpu) {
    if (!this.current(sub, gpu) || j < gpu.uploaded) return;
    const chunk = this.pkg.chunks[j];
    const files = sub.chunks[j];
    const data = (name) => files[chunk.files.indexOf(name)];
    // a texture is a PNG or (versions 3 and 4) a lossless WebP: doc/package-format.md section 4
    const img = await decodeImage(data(chunk.tex), chunk.tex.endsWith('.webp') ? 'image/webp' : 'image/png');
    if (!this.current(sub, gpu)) return;
    const wt = await this.chunkWeights(chunk, data, gpu);
    if (!this.current(sub, gpu)) return;
    this.times.decoded ??= performance.now();
    this.ready.push({j, img, wt, gpu});
    this.invalidate();
  }

  // Every decoded chunk into the GPU, in order; before the first frame only the first
  // one (the first picture comes from the first chunk, whatever else has arrived).
  uploadReady() {
    let n = 0;
    for (let r; (this.loaded || n < 1) && (r = this.ready.shift()); n++)
      if (r.gpu === this.gpu && !this.lost && r.j === r.gpu.uploaded) r.gpu.upload(r.j, r.img, r.wt);
    if (n) this.updateLabel();
    if (this.ready.length) this.invalidate();
  }

  closeReady() {
    this.ready = [];
  }

  // Dequantised weights of a chunk (btf-package.js decodeWeights: wt-JJ.bin, version 3's
  // wt-JJ.z or version 4's wt-JJ-r.z, all 16-bit: .precise), else version 2's wt-JJ-8.png
  // (8-bit coarse), else null (a chunk that lists only its texture).
  async chunkWeights(chunk, data, gpu) {
    if (chunk.wt) {
      const w = await decodeWeights(this.pkg, chunk, data(chunk.wt), gpu.w8q.get(chunk.component));
      w.precise = true;
      return w;
    }
    if (!chunk.wt8) return null;
    const img = await decodeImage(data(chunk.wt8), 'image/png');
    const L = this.pkg.lights.dirs, V = this.pkg.views.dirs;
    if (img.width !== 3 * L || img.height !== V)
      throw new Error(`package ${this.pkg.name}: ${chunk.wt8} is ${img.width}x${img.height}, expected ${3 * L}x${V}`);
    const px = gpu.readGrey(img);
    gpu.w8q.set(chunk.component, px); // version 4: the component's wt-JJ-r.z is a residual over these
    return dequantWeights8(this.pkg, chunk, px);
  }

  onComplete(sub) {
    if (sub !== this.sub) return;
    this.recovered('stream');
    this.complete = true;
    this.updateLabel();
    this.invalidate();
  }

  onError(sub, msg) {
    if (sub === this.sub) this.fail(new Error(`${msg.message} (${msg.code})`));
  }

  // The connection failed or was lost; the stream tries again (info.retrying) while
  // anything is missing. One `error` event per outage (not for a server that drains:
  // another one takes over at once).
  onStreamError(sub, text, info = {}) {
    if (sub !== this.sub) return;
    if (!info.retrying) { // a refused request: a note in the label, the stream goes on
      if (!this.complete) this.label.textContent = text;
      return;
    }
    if (info.drained && info.attempt === 1) return;
    this.trouble('stream', `${text}; trying again in ${(info.delayMs / 1000).toFixed(1)} s`);
  }

  onStreamOpen(sub) {
    if (sub !== this.sub) return;
    this.times.open ??= performance.now();
    if (this.outages.stream) this.showMessage(this.loaded ? '' : 'Connected, loading…', true);
    if (!this.ctx) setTimeout(() => this.ensureGl(this.gen), 0);
  }

  // A recoverable failure of `source` ('stream' or 'shaders'): a note at the viewer's
  // foot and, the first time in that source's outage, an `error` event {reason, retrying: true}.
  trouble(source, reason) {
    if (this.error) return;
    this.showMessage(reason, true);
    if (this.outages[source]) return;
    this.outages[source] = reason;
    this.emit('error', {reason, retrying: true});
  }

  // `source` works again: its outage ends, and the note goes unless another one lasts.
  recovered(source) {
    if (!this.outages[source]) return;
    this.outages[source] = null;
    const other = Object.values(this.outages).find(Boolean);
    this.showMessage(other || '', !!other);
  }

  // Re-uploads every chunk held by the subscription (after a context restore).
  rebuildGpu() {
    if (!this.pkg || !this.sub) return;
    this.newGpu();
    this.invalidate();
  }

  // ------------------------------------------------------------ drawing

  resize() {
    const r = this.getBoundingClientRect();
    this.cssWidth = r.width;
    const dpr = Math.min(window.devicePixelRatio || 1, num(this, 'max-dpr', 2)), k = this.scale || 1;
    // the display's device pixels (what budgets are for), and the canvas (fewer on a slow GPU, adapt())
    this.display = [Math.max(1, Math.round(r.width * dpr)), Math.max(1, Math.round(r.height * dpr))];
    const w = Math.max(1, Math.round(r.width * dpr * k)), h = Math.max(1, Math.round(r.height * dpr * k));
    if (this.canvas.width !== w || this.canvas.height !== h) {
      this.canvas.width = w;
      this.canvas.height = h;
    }
    if (this.sub && this.getAttribute('budget-chunks') === null) this.budgetChanged();
    this.invalidate();
  }

  invalidate() {
    if (!this.raf && this.isConnected && this.started) this.raf = requestAnimationFrame((t) => this.frame(t));
  }

  // The scene in btf render's terms (scene.js sceneDefaults / cameraMake).
  view() {
    const light = this.getAttribute('light') || 'orbit';
    const cam = {cameraTheta: 90 - this.orbit.el, cameraPhi: this.orbit.az, lightTheta: this.lightTheta,
      lightPhi: this.lightPhi};
    // the orbiting light circles the camera's direction, keeping its angle to it: the lit
    // side stays the side the camera sees (scene.js orbitLight)
    const lit = light === 'orbit' && !reducedMotion() ? orbitLight(cam, ((performance.now() - this.t0) / 1000) * 30)
      : cam;
    return {
      geometry: this.geometry, ...cam, cameraDist: this.orbit.dist, lightTheta: lit.lightTheta,
      lightPhi: lit.lightPhi, fov: num(this, 'fov', 40),
      repeat: num(this, 'repeat', 1) > 0 ? num(this, 'repeat', 1) : 1, chunks: this.drawableChunks(),
      quads: this.quads || 0,
      background: sceneDefaults(this.geometry).background,
    };
  }

  drawableChunks() {
    return this.gpu ? Math.min(this.gpu.uploaded, this.ownLimit()) : 0;
  }

  // Draws into the shared context and copies the frame into this viewer's canvas.
  draw() {
    if (!this.renderer || this.lost || !this.ctx || this.ctx.lost) return false;
    const v = this.view(), w = this.canvas.width, h = this.canvas.height;
    this.ctx.fit(w, h);
    this.renderer.draw(this.gpu, v, w, h);
    this.ctx.present(this.ctx2d, w, h);
    if (this.gpu && v.chunks > 0) this.drawn(v.chunks);
    return true;
  }

  // Bookkeeping and events of a frame that showed chunks.
  drawn(chunks) {
    this.frames++;
    if (chunks > this.drawnChunks) this.times.drawn = [...(this.times.drawn || []), [chunks, Math.round(performance.now())]];
    this.drawnChunks = chunks;
    if (!this.loaded) {
      this.loaded = true;
      this.firstFrameMs = performance.now() - this.t0;
      this.firstFrameAt = performance.now(); // since navigation start
      this.times.frame = this.firstFrameAt;
      this.firstFrameChunks = chunks;
      this.firstFrameBytes = this.stream ? this.stream.bytes : null;
      this.posterImg.hidden = true;
      this.waitEl.hidden = true;
      this.emit('load', {chunks});
    }
    const limit = this.ownLimit();
    if (chunks >= limit && this.complete && this.completeFor !== limit) {
      this.completeFor = limit;
      this.completeAt = performance.now(); // since navigation start
      this.emit('complete', this.progress());
    }
  }

  // One frame: every decoded chunk uploaded, then the draw of all of them, once the
  // program is linked (until then the placeholder or poster stays and the next frame
  // asks again). An orbiting light asks for the next frame only after as long again as
  // this one took (the copy into the 2D canvas waits for the shared context's draw),
  // so software GL and many viewers on one page never queue frames faster than they are drawn.
  frame(tick) {
    this.raf = 0;
    const t0 = performance.now();
    if (this.ctx && !this.ctx.idle(tick)) { // the GPU is still on the last frame
      clearTimeout(this.gpuWait);
      this.gpuWait = setTimeout(() => this.invalidate(), GPU_POLL_MS);
      return;
    }
    this.adapt();
    try {
      this.uploadReady();
      if (this.renderer && this.gpu && !this.lost && (this.quads = this.variant()) === null) return this.invalidate();
    } catch (e) {
      return this.fail(e);
    }
    this.times.program ??= this.renderer && this.gpu ? performance.now() : undefined;
    if (this.draw()) {
      this.ctx.drewIn(tick);
      this.measured = {frame: this.ctx.frameNo || 0, fresh: !this.usedVariants.has(this.quads)};
      this.usedVariants.add(this.quads);
    }
    clearTimeout(this.timer);
    if (!this.animating()) return;
    const cost = performance.now() - t0;
    this.timer = setTimeout(() => this.invalidate(), Math.max(16, cost));
  }

  // Resolution follows the GPU: a frame that took it over SLOW_FRAME_MS (a program's
  // first frame excluded: it includes the driver's compile) scales the canvas down so
  // the next one would take about that long (pixels in proportion), to MIN_SCALE of its
  // device pixels (software GL, weak phones); the picture stays whole, only softer, and
  // the budget stays that of the display. A page that sets max-dpr keeps its resolution.
  adapt() {
    const m = this.measured;
    // only while frames keep coming (chunks to show, an orbiting light): a still picture
    // is not drawn again for it
    if (this.hasAttribute('max-dpr') || (this.complete && !this.animating())) return;
    if (!m || m.frame + 1 !== this.ctx.frameNo) return; // the GPU time of this viewer's last frame
    this.measured = null;
    this.slowGpu = this.ctx.gpuMs > SLOW_FRAME_MS;
    if (m.fresh || !this.slowGpu || (this.scale || 1) <= MIN_SCALE) return;
    this.scale = Math.max(MIN_SCALE, (this.scale || 1) * Math.max(0.5, Math.sqrt(SLOW_FRAME_MS / this.ctx.gpuMs)));
    this.resize();
  }

  // The program variant to draw with (MeshRenderer.defines' quads: 0 every slot the
  // package has room for, 1 the first four), or null while it compiles. Until the first
  // frame, a package with more room draws its first chunks with the one-layer variant
  // (compiled while they travelled); the full one is compiled after the first frame.
  // On a software rasteriser every frame draws with the variant that loops over the
  // slots in use (-1): one program for any number of chunks, whose first draw (the
  // rasteriser compiles the shader to machine code then, the longer the more layers are
  // written out) is short.
  variant() {
    const r = this.renderer, g = this.gpu, software = this.ctx.software;
    const full = MeshRenderer.defines(g, 1, software ? -1 : 0);
    if (software) return r.ready(full) ? -1 : null;
    if (g.capacity > 4 && g.slots <= 4 && !r.progs.has(MeshRenderer.key(full))) {
      if (this.loaded) r.start(full);
      return r.ready(MeshRenderer.defines(g, 1, 1)) ? 1 : null;
    }
    return r.ready(full) ? 0 : null;
  }

  // The variant a first frame draws with (started early so the driver compiles it while
  // the first chunk travels): one 4-slot layer, or on a software rasteriser the loop.
  firstVariant() {
    const quads = this.ctx.software ? -1 : 1;
    return this.gpu ? MeshRenderer.defines(this.gpu, 1, quads)
      : decodeDefines({version: 1}, 1, 4).filter(([name]) => quads > 0 || name !== 'BTF_QUADS');
  }

  // The orbiting light moves (not while a slow GPU still has chunks to show: each
  // frame would hold the next chunk back).
  animating() {
    return (this.getAttribute('light') || 'orbit') === 'orbit' && this.drawableChunks() > 0 && this.onScreen &&
      !reducedMotion() && !document.hidden && !(this.slowGpu && !this.complete);
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
    const pr = this.progress();
    const want = pr.bytesWanted || 1;
    this.bar.style.width = `${Math.min(100, (100 * pr.bytes) / want).toFixed(1)}%`;
    this.bar.classList.toggle('done', pr.bytes >= want);
    const drawn = this.drawableChunks(), limit = pr.chunksWanted;
    let t = `${p.name} · ${drawn}/${limit} chunks · ${(pr.bytes / 1024).toFixed(0)} KB`;
    const done = drawn >= limit && limit > 0;
    const e = promisedError(p, drawn);
    if (done && e && Number.isFinite(e.lab)) t += ` · Lab error ${e.lab.toFixed(2)}`;
    else if (done && e && Number.isFinite(e.rmse)) t += ` · RMSE ${e.rmse.toFixed(2)}`;
    this.label.textContent = t;
  }

  // soft: a note at the viewer's foot (trouble the viewer recovers from), else over it.
  showMessage(text, soft = false) {
    this.msg.textContent = text;
    this.msg.hidden = !text;
    this.msg.classList.toggle('soft', soft);
  }

  fail(e, noWebgl = false) {
    this.error = String(e && e.message ? e.message : e);
    this.showMessage(this.error);
    this.classList.toggle('no-webgl', noWebgl);
    if (e && e.report) console.error(`${this.error}\n${e.report}`);
    this.emit('error', {reason: this.error});
  }

  state() {
    return {
      material: this.getAttribute('material'), geometry: this.geometry, cssWidth: this.cssWidth,
      canvas: [this.canvas.width, this.canvas.height], budget: this.budget(), ownLimit: this.ownLimit(),
      manifestChunks: this.pkg ? this.pkg.chunks.length : 0, received: this.sub ? this.sub.received : 0,
      uploaded: this.gpu ? this.gpu.uploaded : 0, uploads: this.gpu ? this.gpu.uploads : 0,
      capacity: this.gpu ? this.gpu.capacity : 0, drawnChunks: this.drawnChunks, frames: this.frames,
      complete: this.complete, error: this.error || null, label: this.label.textContent, started: this.started,
      firstFrameMs: this.firstFrameMs, firstFrameAt: this.firstFrameAt ?? null,
      completeAt: this.completeAt ?? null, firstFrameBytes: this.firstFrameBytes,
      streamBytes: this.sub ? this.sub.bytes : 0, drags: this.orbit ? this.orbit.drags : 0,
      camera: this.orbit ? [this.orbit.az, this.orbit.el, this.orbit.dist] : null, lost: this.lost,
      version: this.pkg ? this.pkg.version : 0, footprint: this.footprint(),
      scene: this.pkg && this.pkg.version >= 2 ? (({level, components, needed, limit, bytes}) =>
        ({level, components, needed, limit, bytes}))(this.sceneBudget()) : null,
      slots: this.gpu ? this.gpu.slots : 0, poster: this.posterImg.hidden ? null : this.posterImg.src,
      posterShown: this.posterShown ?? null, firstFrameChunks: this.firstFrameChunks ?? null,
      times: {...this.times}, decoder: decoderKind(),
      outage: Object.values(this.outages).filter(Boolean).join('; ') || null,
      message: this.msg.hidden ? null : this.msg.textContent, scale: this.scale || 1, display: this.display || null,
      gpuMs: this.ctx ? this.ctx.gpuMs ?? null : null,
    };
  }
}

// A property per attribute (camelCase): strings and numbers reflect the attribute
// (null when absent), booleans its presence.
for (const [attr, type] of Object.entries(ATTRS)) {
  Object.defineProperty(BtfViewer.prototype, camel(attr), {
    configurable: true,
    get() {
      if (type === 'boolean') return this.hasAttribute(attr);
      const v = this.getAttribute(attr);
      return type === 'number' && v !== null ? parseFloat(v) : v;
    },
    set(v) {
      if (type === 'boolean') this.toggleAttribute(attr, !!v);
      else if (v === null || v === undefined) this.removeAttribute(attr);
      else this.setAttribute(attr, String(v));
    },
  });
}

// Most chunks a viewer asks for without a budget-chunks attribute, -1 for no cap beyond
// the scene budget. Replaceable (doc/client.md, "Budgets"); by default packages without
// levels get autoBudget of the CSS width. A viewer calls budgetChanged() when its inputs change.
BtfViewer.budgetPolicy = (viewer) => (viewer.pkg && viewer.pkg.version < 2 ? autoBudget(viewer.cssWidth || 300) : -1);

if (!customElements.get('btf-viewer')) customElements.define('btf-viewer', BtfViewer);
