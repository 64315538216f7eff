// btf-session.js - what a <btf-viewer> (btf-viewer.js) shows between two restarts: one
// material on a built-in surface, or a glTF model (btf-model.js) with library materials
// bound to its parts. Each library material is a feed (btf-feed.js: its subscription on
// the page's shared stream, its budget, its GPU package); the session owns the feeds,
// the frames drawn into the viewer's canvas, and the status (label, notes, events),
// which goes out through the host it was given. The session never holds the element:
// it reads the page through the host's functions and reports through its callbacks.
//
//   host = {
//     canvas                  the viewer's 2D canvas; frames are copied into it (the viewer sizes it)
//     resolution              {scale (share of the device pixels, 0: not set yet), slow (the GPU
//                             takes long per frame), fixed (max-dpr is set)}: the viewer's, kept
//                             across its sessions; the session adapts scale and slow, then resize()
//     resize()                lay the canvas out again (after resolution.scale changed; at start)
//     scene(seconds)          the scene in btf render's terms (scene.js), the orbiting light at
//                             `seconds` after the session began: {geometry, camera and light angles,
//                             cameraDist, fov, repeat, background, lighting (btf-lighting.js frame():
//                             {point, env, exposure, tone, pending}); a model: target, extent}
//     lights()                {point, env}: the light terms in use (the program variant)
//     asked()                 {chunks: the budget-chunks attribute (null: none), bytes, threshold}
//     policy(pkg)             chunks for a package without budget-chunks, -1 no cap (budgetPolicy)
//     pixelsPerRepeat()       device pixels one repeat of the material spans (the scene budget)
//     display()               [width, height] of the view in device pixels (a model's budgets)
//     framed(frame)           a model arrived: {target, extent, cameraDist} frame it (btf-model.js frameModel)
//     seen()                  on screen and the tab shown (else streaming pauses)
//     moving()                the light orbits (attribute, and motion allowed, and seen)
//     emit(type, detail)      an event of the element: load, progress, complete, error
//     message(text, soft)     a note at the viewer's foot (soft) or a message over it ('' none)
//     label(text, bar)        the status line (null: the material's name), the bar {percent,
//                             done} of the bytes wanted (undefined: the bar stays)
//     shown()                 the first frame is up (the poster and the placeholder go)
//     noWebgl(on)             whether the failure is a missing WebGL2
//   }
import {BtfStream} from './btf-stream.js';
import {decodeDefines, loadShaders} from './btf-gl.js';
import {MeshRenderer} from './btf-render.js';
import {sharedGl} from './btf-context.js';
import {decoderKind} from './btf-decode.js';
import {promisedError} from './btf-package.js';
import {SHADER_PACK} from './btf-shader-pack.js';
import {MaterialFeed} from './btf-feed.js';
import {cameraMake} from './scene.js';

// btf-model.js and btf-gltf.js, loaded with the first model of the page.
let modelModule = null;
const modelCode = () => (modelModule ??= import('./btf-model.js'));

const SCRIPT_AT = performance.now(); // when the element's modules ran (ms from navigation start)
const GL_AFTER_MS = 1000; // the WebGL context is made once the subscribe is out, or this long after start
const SLOW_FRAME_MS = 150; // a frame the GPU needs longer for (twice in a row) lowers the resolution ...
const SOFTWARE_SCALE = 0.4; // a software rasteriser (SwiftShader, llvmpipe) starts at this share
const MIN_SCALE = 0.35;    // ... down to this share of the device pixels per CSS pixel
const GPU_POLL_MS = 8;     // how often a frame waiting for the GPU asks again
const SHADER_RETRY_MS = [500, 1000, 2000, 4000, 8000]; // then the last, while the viewer lives

// The shader files of programs (all inside the bundle, else fetched per program) as one
// {manifest, files}.
function shaderFiles(base, programs) {
  if (base === 'inside:')
    return Promise.resolve({manifest: SHADER_PACK.manifest, files: new Map(Object.entries(SHADER_PACK.files))});
  return Promise.all(programs.map((p) => loadShaders(base, p))).then((all) => ({
    manifest: {...all[0].manifest, programs: Object.assign({}, ...all.map((s) => s.manifest.programs))},
    files: new Map(all.flatMap((s) => [...s.files])),
  }));
}

// Owned by one <btf-viewer>; lives from the viewer's creation or its last stop (material,
// model, materials, src or shaders changed, removed from the page) until its next stop.
// Started at most once.
export class BtfSession {
  constructor(host) {
    this.host = host;
    this.started = false;
    this.closed = false;
    this.frames = 0;
    this.feeds = [];           // one per library material (btf-feed.js)
    this.model = null;         // a model's ModelScene (btf-model.js), once loaded
    this.modelUrl = null;      // the model attribute (a model session), else null
    this.ctx = this.gl = this.stream = this.renderer = null;
    this.lost = false;
    this.t0 = performance.now();
    this.firstFrameMs = this.firstFrameBytes = null;
    this.loaded = false;
    this.completeFor = null;
    this.error = null;
    this.outages = {stream: null, shaders: null}; // reasons of outages whose error event went out
    this.shaderTry = 0;
    this.shaderFiles = null;   // Promise of the programs' files
    this.times = {script: SCRIPT_AT}; // ms from navigation start: the loading sequence (doc/client.md)
    this.usedVariants = new Set(); // program variants drawn with (a first draw includes the driver's compile)
    this.measured = null;
    this.raf = 0;
  }

  // The first feed's, for the viewer (its budgetPolicy, test hooks) and a one-material session.
  get pkg() { return this.feeds[0] ? this.feeds[0].pkg : null; }
  get sub() { return this.feeds[0] ? this.feeds[0].sub : null; }
  get gpu() { return this.feeds[0] ? this.feeds[0].gpu : null; }
  get complete() { return this.feeds.length > 0 && this.feeds.every((f) => f.complete); }

  // ------------------------------------------------------------ lifetime

  // The loading sequence (doc/client.md, "Loading"): the subscription (its budget from
  // the viewer's size) and the shader files go out first, in parallel; the WebGL
  // context is made while they travel; the program compiles once the manifest says
  // which variant; chunks decode in a worker and every frame draws all that arrived.
  // shaderBase: a URL, or 'inside:' for the files inside the script (the bundle).
  // model: null, or {url, materials (the attribute's text, or null)}: the model's parts
  // with the materials' bindings, `material` bound to every part no binding names.
  start(material, src, shaderBase, model = null, folder = null) {
    this.started = true;
    if (!material && !model) return this.fail(new Error('no material attribute'));
    if (typeof WebGL2RenderingContext === 'undefined') return this.noWebgl();
    this.src = src;
    this.shaderBase = shaderBase;
    this.times.start = performance.now();
    this.host.resize(); // the canvas size: the first subscribe's footprint
    this.fetchShaders(model ? ['render', 'flat'] : ['render']); // before the subscribe: a shared subscription replays its manifest at once
    this.stream = BtfStream.for(src, folder); // connects now (a model's subscriptions follow it)
    if (model) return this.startModel(material, model);
    const feed = new MaterialFeed(this, material, {
      pixels: (drawing) => (!this.host.seen() && !drawing ? 0 : this.host.pixelsPerRepeat()),
      policy: (pkg) => this.host.policy(pkg),
      token: () => this.host.token(),
    });
    this.feeds = [feed];
    feed.subscribe(this.stream);
    this.updateLabel();
    // the context once the subscribe is out (onStreamOpen: made while the manifest and the
    // first chunk travel; it blocks the page, so not before), or later if the server is slow
    setTimeout(() => this.ensureGl(), GL_AFTER_MS);
  }

  // A model session: the model (fetched once per page) and the bindings; then one feed
  // per library material, its footprint from the pixels its parts cover.
  startModel(material, {url, materials}) {
    this.modelUrl = url;
    this.host.label('loading the model…');
    let bindings;
    modelCode().then(({ModelScene, modelAt, parseBindings}) => {
      bindings = parseBindings(materials);
      if (material && !bindings.some((b) => b.name === '*')) bindings.push({name: '*', id: material, repeat: null});
      return modelAt(url).then((m) => [ModelScene, m]);
    }).then(([ModelScene, m]) => {
      if (this.closed) return;
      this.times.model = performance.now();
      this.model = new ModelScene(m, bindings);
      this.host.framed(this.model.frame(this.host.scene(0).fov));
      this.feeds = this.model.materialIds().map((id) => new MaterialFeed(this, id, {
        pixels: (drawing) => (!this.host.seen() && !drawing ? 0 : this.coverage().get(id)?.ppr || 0),
        policy: (pkg) => this.host.policy(pkg),
        token: () => this.host.token(),
      }));
      for (const f of this.feeds) f.subscribe(this.stream);
      this.updateLabel();
      if (!this.ensureGl()) return;
      this.invalidate();
    }).catch((e) => !this.closed && this.fail(e));
  }

  // Per library material of the model: {pixels covered, ppr} in the current view (btf-model.js).
  coverage() {
    if (!this.model) return new Map();
    const [w, h] = this.host.display(), view = this.host.scene(0);
    return this.model.coverage(view, w, h, () => cameraMake(view, w / h).viewProj);
  }

  // Cancels everything in flight: subscriptions, uploads, GPU packages, frames. Final.
  stop() {
    this.closed = true;
    for (const f of this.feeds) f.stop();
    this.model?.dropGpu();
    this.ctx?.users.delete(this);
    this.ctx = null;
    cancelAnimationFrame(this.raf);
    clearTimeout(this.gpuWait);
    clearTimeout(this.timer);
    this.raf = 0;
  }

  get live() {
    return this.started && !this.closed;
  }

  // ------------------------------------------------------------ WebGL and shaders

  noWebgl() {
    return this.fail(new Error('This browser cannot show the material: WebGL2 is not available ' +
                               '(enable hardware acceleration or use a current browser).'), true);
  }

  // The shared context (made once per page) and this session's renderer; false without WebGL2.
  ensureGl() {
    if (!this.live) return false;
    if (this.ctx) return true;
    const ctx = sharedGl();
    if (!ctx) {
      this.noWebgl();
      return false;
    }
    this.ctx = ctx;
    ctx.users.add(this);
    this.gl = ctx.gl;
    this.ctx2d = this.host.canvas.getContext('2d', {alpha: false});
    this.times.gl = performance.now();
    const res = this.host.resolution;
    if (ctx.software && !res.fixed && !res.scale) { // known slow: start at fewer pixels
      res.scale = SOFTWARE_SCALE;
      this.host.resize();
    }
    this.loadRenderer();
    for (const f of this.feeds) if (f.pkg && !f.gpu) f.newGpu(this.gl);
    return true;
  }

  // The programs' files (only those), fetched at once; a failed fetch is tried again
  // with backoff (a dropped link must not leave the viewer without shaders).
  fetchShaders(programs) {
    this.shaderFiles = shaderFiles(this.shaderBase, programs);
    this.shaderFiles.then(() => {
      if (!this.closed) this.times.shaders ??= performance.now();
    }, (e) => {
      if (this.closed) return;
      const delay = SHADER_RETRY_MS[Math.min(this.shaderTry++, SHADER_RETRY_MS.length - 1)];
      this.trouble('shaders', `${e.message}; trying again`);
      setTimeout(() => !this.closed && this.fetchShaders(programs), delay);
    });
  }

  // The context's renderer of this shader base, with this session's programs in it.
  rendererWithPrograms() {
    const files = this.shaderFiles;
    return files.then(() => this.ctx.renderer(this.shaderBase, files)).then((r) => files.then((sh) => {
      r.include(sh);
      return r;
    }));
  }

  loadRenderer() {
    this.rendererWithPrograms().then((r) => {
      if (this.closed) return;
      this.renderer = r;
      // the variant of a first frame (one 4-slot layer; levels once the manifest says)
      // compiles while the first chunk travels
      if (this.feeds.length) for (const f of this.feeds) r.start(this.firstVariant(f));
      else if (!this.model) r.start(this.firstVariant(null));
      this.recovered('shaders');
      this.invalidate();
    }, () => {
      if (!this.closed) setTimeout(() => !this.closed && this.ctx && this.loadRenderer(), 250);
    });
  }

  // btf-context.js: the shared context was lost / restored.
  contextLost() {
    this.lost = true;
    for (const f of this.feeds) f.dropGpu();
    this.model?.dropGpu();
    this.renderer = null;
    this.host.message('WebGL context lost; waiting for the browser to restore it');
  }

  contextRestored() {
    this.lost = false;
    this.host.message('');
    this.rendererWithPrograms().then((r) => {
      if (this.closed) return;
      this.renderer = r;
      this.rebuildGpu();
    }).catch((e) => !this.closed && this.fail(e));
  }

  // Re-uploads every chunk held by the subscriptions (after a context restore).
  rebuildGpu() {
    for (const f of this.feeds) if (f.pkg && f.sub) f.newGpu(this.gl);
    this.invalidate();
  }

  // ------------------------------------------------------------ budget

  // The view changed (zoom, size, on/off screen, tab shown/hidden): a scene budget may too.
  sceneChanged() {
    if (this.feeds.some((f) => f.sub) && this.host.asked().chunks === null) this.budgetChanged();
  }

  // An input of the budget changed (also the budget attributes).
  budgetChanged() {
    for (const f of this.feeds) f.budgetChanged();
    this.updateLabel();
  }

  // Chunks every feed draws, summed (the scene budget of a model).
  ownLimit() {
    return this.feeds.reduce((a, f) => a + f.ownLimit(), 0);
  }

  // ------------------------------------------------------------ feed events (btf-feed.js)

  feedManifest(feed) {
    this.times.manifest ??= performance.now();
    this.recovered('stream');
    if (!this.ctx && !this.ensureGl()) return;
    feed.newGpu(this.lost ? null : this.gl);
    if (this.renderer && feed.gpu) this.renderer.start(this.firstVariant(feed));
    this.updateLabel();
    this.invalidate(); // starts the program's compile
  }

  feedChunk(feed, j) {
    if (j === 0) this.times.chunk ??= feed.sub.arrivedAt[0] ?? performance.now();
    this.recovered('stream');
    this.host.emit('progress', this.progress(feed, j + 1)); // chunks arrive in order: j + 1 are here
  }

  feedComplete() {
    this.recovered('stream');
    this.updateLabel();
    this.invalidate();
  }

  feedError(feed, msg) {
    this.fail(new Error(`${this.model ? `${feed.material}: ` : ''}${msg.message} (${msg.code})`));
  }

  decoded() {
    this.times.decoded ??= performance.now();
    this.invalidate();
  }

  // The connection failed or was lost; the stream tries again (info.retrying) while
  // anything is missing. One `error` event per outage (not for a server that drains:
  // another one takes over at once).
  streamError(text, info = {}) {
    if (!info.retrying) { // a refused request: a note in the label, the stream goes on
      if (!this.complete) this.host.label(text);
      return;
    }
    if (info.drained && info.attempt === 1) return;
    this.trouble('stream', `${text}; trying again in ${(info.delayMs / 1000).toFixed(1)} s`);
  }

  streamOpen() {
    this.times.open ??= performance.now();
    if (this.outages.stream) this.host.message(this.loaded ? '' : 'Connected, loading…', true);
    if (!this.ctx) setTimeout(() => this.ensureGl(), 0);
  }

  // Received against wanted (every feed's budget, summed), and the error the received
  // prefix promises (a model: the largest of its materials'). feed/received: a chunk of
  // that feed has just arrived, `received` of it are here.
  progress(feed = null, received = undefined) {
    const parts = this.feeds.map((f) => f.progress(f === feed ? received : undefined));
    if (parts.length === 1) return parts[0];
    const sum = (k) => parts.reduce((a, p) => a + p[k], 0);
    const errs = parts.filter((p) => p.error !== null);
    return {chunks: sum('chunks'), chunksWanted: sum('chunksWanted'), bytes: sum('bytes'), bytesWanted: sum('bytesWanted'),
      error: errs.length ? Math.max(...errs.map((p) => p.error)) : null,
      metric: errs.length && errs.every((p) => p.metric === 'lab') ? 'lab' : 'rmse',
      materials: this.feeds.map((f, i) => ({material: f.material, ...parts[i]}))};
  }

  // ------------------------------------------------------------ frames

  invalidate() {
    if (!this.raf && this.live) this.raf = requestAnimationFrame((t) => this.frame(t));
  }

  // The scene of this frame: the host's, with the chunks and the program variant.
  view() {
    const seconds = (performance.now() - this.t0) / 1000, f = this.feeds[0];
    return {...this.host.scene(seconds), chunks: f ? f.drawableChunks() : 0, quads: f ? f.quads : 0};
  }

  drawableChunks() {
    return this.feeds.reduce((a, f) => a + f.drawableChunks(), 0);
  }

  // Draws into the shared context and copies the frame into the viewer's canvas.
  draw() {
    if (!this.renderer || this.lost || !this.ctx || this.ctx.lost) return false;
    if (this.modelUrl && !this.model) return false;
    const v = this.view(), w = this.host.canvas.width, h = this.host.canvas.height;
    if (v.lighting && v.lighting.pending) return false; // the environment image is on its way
    this.ctx.fit(w, h);
    if (this.model) {
      const feeds = new Map(this.feeds.map((f) => [f.material, {gpu: f.gpu, chunks: f.drawableChunks(), quads: f.quads}]));
      this.renderer.drawScene(this.model.layers(this.gl, feeds, v), v, w, h);
    } else {
      this.renderer.draw(this.gpu, v, w, h);
    }
    this.ctx.present(this.ctx2d, w, h);
    const chunks = this.drawableChunks();
    if (chunks > 0 || (this.model && !this.feeds.length)) this.drawn();
    return true;
  }

  // Bookkeeping and events of a frame that showed chunks (or a model without materials).
  drawn() {
    this.frames++;
    const chunks = this.drawableChunks();
    if (chunks > (this.drawnTotal || 0)) {
      this.times.drawn = [...(this.times.drawn || []), [chunks, Math.round(performance.now())]];
      this.ctx.afterFrame((at) => { // when the GPU has drawn it (a slow GPU: well after the call)
        this.times.shown = [...(this.times.shown || []), [chunks, Math.round(at)]];
      });
    }
    this.drawnTotal = chunks;
    for (const f of this.feeds) f.drawnChunks = f.drawableChunks();
    if (!this.loaded) this.firstFrame(chunks);
    const limit = this.ownLimit(), key = this.feeds.map((f) => f.ownLimit()).join(',');
    if (this.feeds.every((f) => f.done()) && this.completeFor !== key) {
      this.completeFor = key;
      this.completeAt = performance.now(); // since navigation start
      this.host.emit('complete', this.progress());
    }
    return limit;
  }

  firstFrame(chunks) {
    this.loaded = true;
    this.firstFrameMs = performance.now() - this.t0;
    this.firstFrameAt = performance.now(); // since navigation start
    this.times.frame = this.firstFrameAt;
    this.firstFrameChunks = chunks;
    this.firstFrameBytes = this.stream ? this.stream.bytes : null;
    this.host.shown();
    this.host.emit('load', {chunks});
  }

  // Every decoded chunk into the GPU, in order; before the first frame only the first
  // one of each feed (the first picture comes from the first chunk, whatever else has arrived).
  uploadReady() {
    let up = false, waiting = false;
    for (const f of this.feeds) {
      up = f.upload(this.loaded ? Infinity : 1) || up;
      waiting = waiting || f.waiting;
    }
    if (up) this.updateLabel();
    if (waiting) this.invalidate();
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
    let variants;
    try {
      this.uploadReady();
      if (this.renderer && !this.lost) {
        variants = this.feeds.filter((f) => f.gpu).map((f) => (f.quads = this.variant(f)));
        if (variants.includes(null)) return this.invalidate();
      }
    } catch (e) {
      return this.fail(e);
    }
    this.times.program ??= this.renderer && this.feeds.some((f) => f.gpu) ? performance.now() : undefined;
    if (this.draw()) {
      this.ctx.drewIn(tick);
      const l = this.host.lights(), key = `${(variants || []).join(',')}|${l.point ? 'p' : ''}${l.env ? 'e' : ''}`;
      this.measured = {frame: this.ctx.frameNo || 0, fresh: !this.usedVariants.has(key)};
      this.usedVariants.add(key);
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
    const m = this.measured, res = this.host.resolution;
    // only while frames keep coming (chunks to show, an orbiting light): a still picture
    // is not drawn again for it
    if (res.fixed || (this.complete && !this.animating())) return;
    if (!m || m.frame + 1 !== this.ctx.frameNo) return; // the GPU time of this session's last frame
    this.measured = null;
    res.slow = this.ctx.gpuMs > SLOW_FRAME_MS;
    if (m.fresh || !res.slow || (res.scale || 1) <= MIN_SCALE) return;
    res.scale = Math.max(MIN_SCALE, (res.scale || 1) * Math.max(0.5, Math.sqrt(SLOW_FRAME_MS / this.ctx.gpuMs)));
    this.host.resize();
  }

  // The program variant feed f draws with (MeshRenderer.defines' quads: 0 every slot the
  // package has room for, 1 the first four), or null while it compiles. Until the first
  // frame, a package with more room draws its first chunks with the one-layer variant
  // (compiled while they travelled); the full one is compiled after the first frame.
  // On a software rasteriser every frame draws with the variant that loops over the
  // slots in use (-1): one program for any number of chunks, whose first draw (the
  // rasteriser compiles the shader to machine code then, the longer the more layers are
  // written out) is short.
  variant(f) {
    const r = this.renderer, g = f.gpu, software = this.ctx.software, lights = this.host.lights();
    const full = MeshRenderer.defines(g, 1, software ? -1 : 0, lights);
    if (software) return r.ready(full) ? -1 : null;
    if (g.capacity > 4 && g.slots <= 4 && !r.progs.has(MeshRenderer.key(full))) {
      if (this.loaded) r.start(full);
      return r.ready(MeshRenderer.defines(g, 1, 1, lights)) ? 1 : null;
    }
    return r.ready(full) ? 0 : null;
  }

  // The variant a first frame draws with (started early so the driver compiles it while
  // the first chunk travels): one 4-slot layer, or on a software rasteriser the loop.
  firstVariant(f) {
    const quads = this.ctx.software ? -1 : 1, lights = this.host.lights();
    return f && f.gpu ? MeshRenderer.defines(f.gpu, 1, quads, lights)
      : decodeDefines({version: 1}, 1, 4, lights).filter(([name]) => quads > 0 || name !== 'BTF_QUADS');
  }

  // The orbiting light moves (not while a slow GPU still has chunks to show: each
  // frame would hold the next chunk back).
  animating() {
    return this.host.moving() && (this.drawableChunks() > 0 || (!!this.model && !this.feeds.length)) &&
      !(this.host.resolution.slow && !this.complete);
  }

  // Test hook: draws now and returns the canvas pixels, rows top-down, RGBA, base64.
  capture() {
    this.draw();
    const gl = this.gl, w = this.host.canvas.width, h = this.host.canvas.height;
    const px = new Uint8Array(4 * w * h);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
    const out = new Uint8Array(4 * w * h);
    for (let y = 0; y < h; y++) out.set(px.subarray(4 * w * (h - 1 - y), 4 * w * (h - y)), 4 * w * y);
    let s = '';
    for (let i = 0; i < out.length; i += 0x8000) s += String.fromCharCode.apply(null, out.subarray(i, i + 0x8000));
    return {width: w, height: h, chunks: this.drawnTotal || 0, rgba: btoa(s)};
  }

  // Test hook: ms per frame of n frames drawn now, each waited for (a one-pixel read).
  bench(n) {
    if (!this.draw()) return null;
    const gl = this.gl, px = new Uint8Array(4);
    gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px);
    const t0 = performance.now();
    for (let i = 0; i < n; i++) {
      this.draw();
      gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px);
    }
    return (performance.now() - t0) / n;
  }

  // ------------------------------------------------------------ status

  updateLabel() {
    if (!this.feeds.some((f) => f.pkg && f.sub))
      return this.host.label(this.model ? this.modelName() : this.modelUrl ? 'loading the model…' : null);
    const pr = this.progress(), drawn = this.drawableChunks(), limit = pr.chunksWanted;
    const want = pr.bytesWanted || 1;
    const name = this.model ? this.modelName() : this.pkg.name;
    let t = `${name} · ${drawn}/${limit} chunks · ${(pr.bytes / 1024).toFixed(0)} KB`;
    const e = this.feeds.length === 1 ? promisedError(this.pkg, drawn) : null;
    if (drawn >= limit && limit > 0 && e && Number.isFinite(e.lab)) t += ` · Lab error ${e.lab.toFixed(2)}`;
    else if (drawn >= limit && limit > 0 && e && Number.isFinite(e.rmse)) t += ` · RMSE ${e.rmse.toFixed(2)}`;
    else if (drawn >= limit && limit > 0 && pr.error !== null && this.feeds.length > 1)
      t += ` · ${pr.metric === 'lab' ? 'Lab error' : 'RMSE'} ≤ ${pr.error.toFixed(2)}`;
    this.host.label(t, {percent: Math.min(100, (100 * pr.bytes) / want), done: pr.bytes >= want});
  }

  modelName() {
    return this.model.model.name;
  }

  // A recoverable failure of `source` ('stream' or 'shaders'): a note at the viewer's
  // foot and, the first time in that source's outage, an `error` event {reason, retrying: true}.
  trouble(source, reason) {
    if (this.error) return;
    this.host.message(reason, true);
    if (this.outages[source]) return;
    this.outages[source] = reason;
    this.host.emit('error', {reason, retrying: true});
  }

  // `source` works again: its outage ends, and the note goes unless another one lasts.
  recovered(source) {
    if (!this.outages[source]) return;
    this.outages[source] = null;
    const other = Object.values(this.outages).find(Boolean);
    this.host.message(other || '', !!other);
  }

  // A final failure: the message over the viewer and one `error` event (the first
  // failure of a session; what follows from it says nothing new).
  fail(e, noWebgl = false) {
    if (this.error) return;
    this.error = String(e && e.message ? e.message : e);
    this.host.message(this.error);
    this.host.noWebgl(noWebgl);
    if (e && e.report) console.error(`${this.error}\n${e.report}`);
    this.host.emit('error', {reason: this.error});
  }

  // Test hook (window.__btf.viewers()): the session's part of the viewer's state. A
  // one-material session: its feed's numbers; a model: the sums over its feeds, each
  // feed's own in `feeds`, the model in `model`.
  state() {
    const one = this.feeds.length === 1 && !this.model;
    const fs = this.feeds.map((f) => f.state()), sum = (k) => fs.reduce((a, s) => a + s[k], 0);
    const base = one ? fs[0] : {
      budget: fs.length ? fs.map((s) => s.budget) : null, ownLimit: sum('ownLimit'), manifestChunks: sum('manifestChunks'),
      received: sum('received'), uploaded: sum('uploaded'), uploads: sum('uploads'), capacity: sum('capacity'),
      streamBytes: sum('streamBytes'), version: fs.length ? Math.min(...fs.map((s) => s.version)) : 0,
      footprint: fs.length ? Math.max(...fs.map((s) => s.footprint)) : 0, slots: sum('slots'),
      scene: fs.length && fs.every((s) => s.scene) ? {limit: sum('ownLimit'), bytes: fs.reduce((a, s) => a + s.scene.bytes, 0),
        needed: fs.reduce((a, s) => a + s.scene.needed, 0)} : null,
    };
    const cover = this.model ? this.coverage() : null;
    return {
      ...base, drawnChunks: one ? fs[0].drawnChunks : (this.drawnTotal || 0), frames: this.frames,
      complete: this.complete, error: this.error || null, firstFrameMs: this.firstFrameMs,
      firstFrameAt: this.firstFrameAt ?? null, completeAt: this.completeAt ?? null,
      firstFrameBytes: this.firstFrameBytes, lost: this.lost,
      firstFrameChunks: this.firstFrameChunks ?? null, times: {...this.times},
      decoder: decoderKind(), outage: Object.values(this.outages).filter(Boolean).join('; ') || null,
      gpuMs: this.ctx ? this.ctx.gpuMs ?? null : null,
      ...(this.modelUrl ? {
        feeds: fs.map((s) => ({...s, cover: cover && cover.get(s.material) ? {...cover.get(s.material)} : null})),
        model: this.model ? {url: this.modelUrl, name: this.model.model.name, parts: this.model.model.parts.length,
          triangles: this.model.model.triangles, vertices: this.model.model.vertices, min: this.model.model.min,
          max: this.model.model.max, bindings: this.model.bindings.map((b) => ({...b})), partBind: [...this.model.partBind]}
          : null,
      } : {}),
    };
  }
}
