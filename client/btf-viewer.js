// btf-viewer.js - <btf-viewer>: an embeddable WebGL2 viewer of one streamed material.
//
//   <script type="module" src="http://HOST:PORT/btf-viewer.js"></script>
//   <btf-viewer material="wool" geometry="sphere" camera-controls></btf-viewer>
//
// The server (src) and the shader files default to the origin of this script, so the
// two lines work on a page of any origin (btfd sends CORS headers, doc/protocol.md).
// Attributes (each also a JS property, camelCase; every one reacts when changed; the
// table with defaults and the events is in doc/client.md):
//   src            WebSocket URL of btfd (default: ws(s) of this script's origin + /stream), or
//                  the http(s) folder of a published library (btf-http.js)
//   token          a private library's access token for the material(s), v1:SCOPE:EXPIRES:SIG,
//                  signed by the page owner's backend (doc/deploy.md, "Private libraries")
//   material       material name in the server's library (with a model: bound to every part
//                  `materials` does not name)
//   model          URL of a glTF 2.0 model (.glb, or .gltf with its buffers) drawn instead of
//                  the geometry, framed by the camera (btf-model.js)
//   materials      with model: bindings NAME:MATERIAL[:REPEAT], comma separated (glTF material
//                  name, '*' = every part no other binding names; library material; package
//                  repeats per unit of TEXCOORD_0, default 1); unbound parts in their base colour
//   geometry       plane | sphere | cylinder (cloth-like tube)        default plane
//   light          the point light: orbit (circles) | fixed | pointer (follows the pointer) |
//                  tilt (the phone's orientation turns the lighting) | none; absent: none,
//                  and the built-in studio lights the scene (doc/lighting.md)
//   light-theta, light-phi  light direction in degrees (fixed; start of the orbit)
//   environment-image  URL of a Radiance .hdr | studio | none; absent: studio without `light`
//   environment-rotation  degrees about +z; exposure (default 1); tone-mapping auto | none |
//                  neutral | aces (btf-lighting.js; the `lighting` property says what is drawn)
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
// The element owns the attributes, the lazy start, the layout, the camera, the poster,
// the status line and accessibility; each stream of a material is a session
// (btf-session.js: subscription, budget, chunk upload, frames), which reads the page
// through the host the element gives it. All viewers share one WebGL2 context
// (btf-context.js) and one WebSocket per server (btf-stream.js). Test hook:
// window.__btf (viewers' state, capture()).

// Every module of the element is imported here, so the browser asks for all of them
// in one round trip (the session's, and btf-cache.js, btf-render.js and btf-dirtab.js,
// are otherwise found one or two levels deeper).
import './btf-cache.js';
import './btf-dirtab.js';
import './btf-render.js';
import './btf-decode.js';
import './btf-package.js';
import './btf-upload.js';
import {BtfSession} from './btf-session.js';
import {BtfStream} from './btf-stream.js';
import {libraryBase, libraryUrl} from './btf-http.js';
import {GpuPackage} from './btf-gl.js';
import {sharedStats} from './btf-context.js';
import {LOD_THRESHOLD} from './btf-lod.js';
import {Orbit} from './orbit.js';
import {ViewerLighting} from './btf-lighting.js';
import {GEOMETRIES, orbitLight, pixelsPerUnit, sceneDefaults} from './scene.js';
import {VIEWER_CSS, viewerSheet} from './btf-viewer-style.js';
import {SHADER_PACK} from './btf-shader-pack.js';

const SHADERS_URL = new URL('shaders/', import.meta.url).href;
const LAZY_MARGIN = '300px'; // loading="lazy": start this far before the viewport

// Attribute -> property type; the property is the camelCase name.
const ATTRS = {
  material: 'string', model: 'string', materials: 'string', src: 'string', geometry: 'string', light: 'string', 'light-theta': 'number',
  'light-phi': 'number', 'camera-theta': 'number', 'camera-phi': 'number', 'camera-dist': 'number', fov: 'number',
  repeat: 'number', 'budget-chunks': 'number', 'budget-bytes': 'number', 'lod-threshold': 'number',
  'max-dpr': 'number', shaders: 'string', poster: 'string', loading: 'string', 'camera-controls': 'boolean',
  alt: 'string', 'environment-image': 'string', 'environment-rotation': 'number', exposure: 'number',
  'tone-mapping': 'string', token: 'string',
};
const RESTART = new Set(['material', 'model', 'materials', 'src', 'shaders', 'token']);
const SCENE = new Set(['repeat', 'lod-threshold', 'fov', 'geometry']);
const CAMERA = new Set(['camera-theta', 'camera-phi', 'camera-dist']);
const LIGHTING = new Set(['light', 'environment-image', 'environment-rotation', 'exposure', 'tone-mapping']);

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
      bench: (i, n) => [...registry][i].session.bench(n), // ms per frame of n frames drawn now
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

const lists = new Map(); // library base -> Promise of its materials.json (poster thumbnails)
function materialList(base) {
  if (!lists.has(base)) {
    lists.set(base, fetch(new URL('materials.json', base)).then((r) => (r.ok ? r.json() : {materials: []}))
      .catch(() => ({materials: []})));
  }
  return lists.get(base);
}

const reducedMotion = () => matchMedia('(prefers-reduced-motion: reduce)').matches;
const camel = (a) => a.replace(/-([a-z])/g, (_, c) => c.toUpperCase());

// Owned by the page (one per <btf-viewer> element); lives as long as the element. Its
// current session (btf-session.js) is replaced on every stop.
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
    const part = (tag, className) => Object.assign(document.createElement(tag), {className});
    this.canvas = document.createElement('canvas');
    this.waitEl = part('div', 'wait');
    this.posterImg = Object.assign(part('img', 'poster'), {alt: '', hidden: true});
    this.bar = part('div', 'bar');
    this.label = part('div', 'label');
    this.msg = Object.assign(part('div', 'msg'), {hidden: true});
    root.append(this.canvas, this.waitEl, this.posterImg, this.bar, this.label, this.msg);
    const el = this;
    // the canvas's share of the device pixels, adapted by the sessions to the GPU (kept across them)
    this.resolution = {scale: 0, slow: false, get fixed() { return el.hasAttribute('max-dpr'); }};
    this.host = this.sessionHost();
    this.session = new BtfSession(this.host);
    this.lights = new ViewerLighting(this, {
      changed: () => this.invalidate(),
      // the point light (or the studio in its place) still draws: a note at the foot
      failed: (reason) => {
        this.showMessage(reason, true);
        this.emit('error', {reason});
      },
    });
  }

  // What the last frame was lit by (doc/client.md, "Lighting"): {light, point: {on, theta,
  // phi}, environment: {image, state, error, on, rotation, tilt}, exposure, toneMapping,
  // tilt: {beta, gamma, source, permission} | null}. Read-only.
  get lighting() {
    return this.lights.state();
  }

  // What this viewer's sessions read of the page and where their status goes (the
  // host of btf-session.js).
  sessionHost() {
    return {
      canvas: this.canvas,
      resolution: this.resolution,
      resize: () => this.resize(),
      scene: (seconds) => this.scene(seconds),
      asked: () => ({chunks: this.getAttribute('budget-chunks'), bytes: num(this, 'budget-bytes', -1),
        threshold: num(this, 'lod-threshold', LOD_THRESHOLD)}),
      policy: (pkg) => BtfViewer.budgetPolicy(this, pkg),
      token: () => this.getAttribute('token') || null,
      pixelsPerRepeat: () => this.pixelsPerRepeat(),
      display: () => this.display || [this.canvas.width, this.canvas.height],
      framed: (frame) => this.framed(frame),
      seen: () => this.onScreen && !document.hidden,
      moving: () => this.getAttribute('light') === 'orbit' && this.onScreen && !reducedMotion() && !document.hidden,
      lights: () => this.lights.on(),
      emit: (type, detail) => this.emit(type, detail),
      message: (text, soft) => this.showMessage(text, soft),
      label: (text, bar) => this.setLabel(text, bar),
      shown: () => {
        this.posterImg.hidden = true;
        this.waitEl.hidden = true;
      },
      noWebgl: (on) => this.classList.toggle('no-webgl', on),
    };
  }

  // The session's, for the test hooks and BtfViewer.budgetPolicy.
  get started() { return this.session.started; }
  get pkg() { return this.session.pkg; }
  get stream() { return this.session.stream; }
  get gl() { return this.session.gl; }

  connectedCallback() {
    hook();
    registry.add(this);
    this.geometry = GEOMETRIES.includes(this.getAttribute('geometry')) ? this.getAttribute('geometry') : 'plane';
    this.makeOrbit();
    this.lightTheta = num(this, 'light-theta', this.defaults().lightTheta);
    this.lightPhi = num(this, 'light-phi', this.defaults().lightPhi);
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
    this.lights.dispose();
    this.near?.disconnect();
    this.near = null;
    document.removeEventListener('visibilitychange', this.onVisibility);
    this.orbit?.dispose();
    this.orbit = null;
    this.stop();
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

  // Starts the session: the stream from `src` (default: this script's origin), the shader
  // files of the `shaders` attribute, else those inside the script (the bundle), else
  // those next to it; the poster from the material list meanwhile.
  start() {
    const s = this.session, model = this.getAttribute('model');
    s.start(this.getAttribute('material'), this.getAttribute('src') || scriptWs(),
      this.getAttribute('shaders') || (SHADER_PACK ? 'inside:' : SHADERS_URL),
      model ? {url: new URL(model, document.baseURI).href, materials: this.getAttribute('materials')} : null,
      this.getAttribute('src') ? null : new URL('./', import.meta.url).href);
    if (s.src && !model) this.defaultPoster(s);
    this.lights.update();
  }

  // Ends the session (everything in flight is cancelled); the next one waits for start().
  stop() {
    this.session.stop();
    this.session = new BtfSession(this.host);
    this.waitEl.hidden = false;
    if (this.frame) { // the next model frames itself again (the same one: the camera stays)
      this.lastFrame = this.frame;
      this.frame = null;
      if (this.orbit && !this.getAttribute('model')) { // back to a built-in surface
        this.zoomRange();
        this.orbit.dist = num(this, 'camera-dist', this.defaults().cameraDist);
      }
    }
  }

  attributeChangedCallback(name, oldV, newV) {
    if (!this.orbit || oldV === newV) return; // before connectedCallback (an upgrade): it reads them all
    if (RESTART.has(name)) return this.restart();
    if (name === 'geometry') this.geometry = GEOMETRIES.includes(newV) ? newV : 'plane';
    if (name === 'light-theta') this.lightTheta = num(this, name, this.defaults().lightTheta);
    if (name === 'light-phi') this.lightPhi = num(this, name, this.defaults().lightPhi);
    if (CAMERA.has(name)) this.setCamera();
    if (name.startsWith('budget')) this.budgetChanged();
    if (SCENE.has(name) || CAMERA.has(name)) this.sceneChanged();
    if (name === 'max-dpr') this.resize();
    if (name === 'poster') this.setPoster();
    if (name === 'loading' && newV === 'eager' && !this.started) this.start();
    if (name === 'camera-controls') this.setControls();
    if (name === 'alt') this.setAria();
    if (LIGHTING.has(name)) this.lights.update(this.started);
    this.invalidate();
  }

  restart() {
    const was = this.started;
    this.stop();
    this.setPoster();
    if (was) this.start();
    else if (this.getAttribute('loading') !== 'eager') this.startWhenNear();
  }

  // ------------------------------------------------------------ page citizenship

  // The scene's defaults (scene.js sceneDefaults): the geometry's; a model takes the
  // sphere's angles, its distance from the framing once it has arrived.
  defaults() {
    const def = sceneDefaults(this.getAttribute('model') ? 'sphere' : this.geometry);
    return this.frame ? {...def, cameraDist: this.frame.cameraDist} : def;
  }

  // A model arrived (the session's framing, btf-model.js frameModel): the camera looks at its
  // centre from the framing distance (unless camera-dist says otherwise); zoom spans the same
  // share of it as on the built-in objects.
  framed(frame) {
    const same = JSON.stringify(frame) === JSON.stringify(this.lastFrame);
    this.frame = frame;
    this.zoomRange();
    if (!same) this.orbit.dist = num(this, 'camera-dist', frame.cameraDist);
    this.sceneChanged();
    this.invalidate();
  }

  zoomRange() {
    const d = this.frame ? this.frame.cameraDist : 0;
    [this.orbit.minDist, this.orbit.maxDist] = d > 0 ? [d * 1.6 / 3.6, d * 8 / 3.6] : [1.6, 8];
  }

  makeOrbit() {
    const def = this.defaults();
    this.orbit = new Orbit(this.canvas, {
      az: num(this, 'camera-phi', def.cameraPhi), el: 90 - num(this, 'camera-theta', def.cameraTheta),
      dist: num(this, 'camera-dist', def.cameraDist),
      onChange: () => this.cameraMoved(),
      onPointer: (x, y) => {
        this.lights.pointer(x, y); // light="tilt" without orientation events
        if (this.getAttribute('light') !== 'pointer') return;
        this.lightPhi = (x - 0.5) * 360 - 90;
        this.lightTheta = Math.max(0, Math.min(85, y * 85));
        this.invalidate();
      },
      canWheel: () => this.engaged,
    });
    this.zoomRange();
  }

  setCamera(emit = true) {
    const def = this.defaults();
    this.zoomRange();
    this.orbit.az = num(this, 'camera-phi', def.cameraPhi);
    this.orbit.el = 90 - num(this, 'camera-theta', def.cameraTheta);
    this.orbit.dist = num(this, 'camera-dist', def.cameraDist);
    if (emit) this.emit('camera-change', this.cameraState());
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
    this.posterImg.hidden = !url || this.session.loaded;
    if (url) this.posterShown = this.posterImg.src;
  }

  async defaultPoster(session) {
    const name = this.getAttribute('material');
    if (this.getAttribute('poster') || !name) return;
    const base = libraryBase(session.src); // btfd's root, or a static host's library folder
    const list = await materialList(base);
    const m = (list.materials || []).find((x) => x.name === name);
    if (session !== this.session || !m || !m.thumbnail || session.loaded) return;
    this.posterImg.src = libraryUrl(base, m.thumbnail);
    this.posterImg.hidden = false;
    this.posterShown = this.posterImg.src;
  }

  emit(type, detail) {
    this.dispatchEvent(new CustomEvent(type, {bubbles: true, composed: true, detail}));
  }

  // ------------------------------------------------------------ layout and scene

  resize() {
    const r = this.getBoundingClientRect();
    this.cssWidth = r.width;
    const dpr = Math.min(window.devicePixelRatio || 1, num(this, 'max-dpr', 2)), k = this.resolution.scale || 1;
    // the display's device pixels (what budgets are for), and the canvas (fewer on a slow
    // GPU: the session's adapt())
    this.display = [Math.max(1, Math.round(r.width * dpr)), Math.max(1, Math.round(r.height * dpr))];
    const w = Math.max(1, Math.round(r.width * dpr * k)), h = Math.max(1, Math.round(r.height * dpr * k));
    if (this.canvas.width !== w || this.canvas.height !== h) {
      this.canvas.width = w;
      this.canvas.height = h;
    }
    this.sceneChanged();
    this.invalidate();
  }

  invalidate() {
    this.session.invalidate();
  }

  // The view changed (zoom, size, on/off screen, tab shown/hidden): a scene budget may too.
  sceneChanged() {
    this.session.sceneChanged();
  }

  budgetChanged() {
    this.session.budgetChanged();
  }

  // The scene in btf render's terms (scene.js sceneDefaults / cameraMake), the orbiting
  // light `seconds` into the session, the lights of the frame (btf-lighting.js frame()).
  scene(seconds) {
    const light = this.getAttribute('light');
    const cam = {cameraTheta: 90 - this.orbit.el, cameraPhi: this.orbit.az, lightTheta: this.lightTheta,
      lightPhi: this.lightPhi};
    // the orbiting light circles the camera's direction, keeping its angle to it: the lit
    // side stays the side the camera sees (scene.js orbitLight)
    const lit = light === 'orbit' && !reducedMotion() ? orbitLight(cam, seconds * 30) : cam;
    const lighting = this.lights.frame({lightTheta: lit.lightTheta, lightPhi: lit.lightPhi, cameraPhi: cam.cameraPhi});
    return {
      geometry: this.getAttribute('model') ? 'model' : this.geometry, ...cam, cameraDist: this.orbit.dist,
      lightTheta: lighting.lightTheta, lightPhi: lighting.lightPhi, lighting, fov: num(this, 'fov', 40),
      repeat: num(this, 'repeat', 1) > 0 ? num(this, 'repeat', 1) : 1,
      background: this.defaults().background,
      ...(this.frame ? {target: this.frame.target, extent: this.frame.extent} : {}),
    };
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

  // ------------------------------------------------------------ status

  // text null: the material's name; bar {percent, done} of the bytes wanted.
  setLabel(text, bar) {
    this.label.textContent = text ?? (this.getAttribute('material') || this.getAttribute('model') || '');
    if (!bar) return;
    this.bar.style.width = `${bar.percent.toFixed(1)}%`;
    this.bar.classList.toggle('done', bar.done);
  }

  // soft: a note at the viewer's foot (trouble the viewer recovers from), else over it.
  showMessage(text, soft = false) {
    this.msg.textContent = text;
    this.msg.hidden = !text;
    this.msg.classList.toggle('soft', soft);
  }

  // Test hook: draws now and returns the canvas pixels, rows top-down, RGBA, base64.
  capture() {
    return this.session.capture();
  }

  state() {
    return {
      material: this.getAttribute('material'), geometry: this.getAttribute('model') ? 'model' : this.geometry,
      cssWidth: this.cssWidth,
      canvas: [this.canvas.width, this.canvas.height], ...this.session.state(), label: this.label.textContent,
      started: this.started, drags: this.orbit ? this.orbit.drags : 0,
      camera: this.orbit ? [this.orbit.az, this.orbit.el, this.orbit.dist] : null,
      poster: this.posterImg.hidden ? null : this.posterImg.src, posterShown: this.posterShown ?? null,
      message: this.msg.hidden ? null : this.msg.textContent, scale: this.resolution.scale || 1,
      display: this.display || null,
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

// Most chunks a viewer asks for a package (pkg: the parsed manifest; a model's viewer asks
// for each of its materials) without a budget-chunks attribute, -1 for no cap beyond the
// scene budget. Replaceable (doc/client.md, "Budgets"); by default packages without
// levels get autoBudget of the CSS width. A viewer calls budgetChanged() when its inputs change.
BtfViewer.budgetPolicy = (viewer, pkg = viewer.pkg) => (pkg && pkg.version < 2 ? autoBudget(viewer.cssWidth || 300) : -1);

if (!customElements.get('btf-viewer')) customElements.define('btf-viewer', BtfViewer);
