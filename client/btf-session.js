// btf-session.js - one stream of one material for a <btf-viewer> (btf-viewer.js): the
// subscription and its budget, the GPU package its chunks go into (btf-upload.js), and
// the frames drawn into the viewer's canvas; its status (label, notes, events) goes
// out through the host it was given. The session never holds the element: it reads the
// page through the host's functions and reports through its callbacks.
//
//   host = {
//     canvas                  the viewer's 2D canvas; frames are copied into it (the viewer sizes it)
//     resolution              {scale (share of the device pixels, 0: not set yet), slow (the GPU
//                             takes long per frame), fixed (max-dpr is set)}: the viewer's, kept
//                             across its sessions; the session adapts scale and slow, then resize()
//     resize()                lay the canvas out again (after resolution.scale changed; at start)
//     scene(seconds)          the scene in btf render's terms (scene.js), the orbiting light at
//                             `seconds` after the session began: {geometry, camera and light angles,
//                             cameraDist, fov, repeat, background}
//     asked()                 {chunks: the budget-chunks attribute (null: none), bytes, threshold}
//     policy()                chunks for a package without budget-chunks, -1 no cap (budgetPolicy)
//     pixelsPerRepeat()       device pixels one repeat of the material spans (the scene budget)
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
import {chunksWithinBytes, parseManifest, promisedError} from './btf-package.js';
import {lodSelect} from './btf-lod.js';
import {SHADER_PACK} from './btf-shader-pack.js';
import {ChunkUploads} from './btf-upload.js';

const SCRIPT_AT = performance.now(); // when the element's modules ran (ms from navigation start)
const GL_AFTER_MS = 1000; // the WebGL context is made once the subscribe is out, or this long after start
const SLOW_FRAME_MS = 150; // a frame the GPU needs longer for (twice in a row) lowers the resolution ...
const SOFTWARE_SCALE = 0.4; // a software rasteriser (SwiftShader, llvmpipe) starts at this share
const MIN_SCALE = 0.35;    // ... down to this share of the device pixels per CSS pixel
const GPU_POLL_MS = 8;     // how often a frame waiting for the GPU asks again
const SHADER_RETRY_MS = [500, 1000, 2000, 4000, 8000]; // then the last, while the viewer lives

// Owned by one <btf-viewer>; lives from the viewer's creation or its last stop (material,
// src or shaders changed, removed from the page) until its next stop. Started at most once.
export class BtfSession {
  constructor(host) {
    this.host = host;
    this.started = false;
    this.closed = false;
    this.frames = 0;
    this.drawnChunks = 0;
    this.uploads = null;       // the GPU package and the chunks decoded for it (btf-upload.js)
    this.ctx = this.gl = this.pkg = this.sub = this.stream = this.renderer = null;
    this.lost = false;
    this.t0 = performance.now();
    this.firstFrameMs = this.firstFrameBytes = null;
    this.complete = this.loaded = false;
    this.completeFor = -1;
    this.error = null;
    this.outages = {stream: null, shaders: null}; // reasons of outages whose error event went out
    this.shaderTry = 0;
    this.shaderFiles = null;   // Promise of the "render" program's files
    this.times = {script: SCRIPT_AT}; // ms from navigation start: the loading sequence (doc/client.md)
    this.usedVariants = new Set(); // program variants drawn with (a first draw includes the driver's compile)
    this.measured = null;
    this.raf = 0;
  }

  // ------------------------------------------------------------ lifetime

  // The loading sequence (doc/client.md, "Loading"): the subscription (its budget from
  // the viewer's size) and the shader files go out first, in parallel; the WebGL
  // context is made while they travel; the program compiles once the manifest says
  // which variant; chunks decode in a worker and every frame draws all that arrived.
  // shaderBase: a URL, or 'inside:' for the files inside the script (the bundle).
  start(material, src, shaderBase) {
    this.started = true;
    if (!material) return this.fail(new Error('no material attribute'));
    if (typeof WebGL2RenderingContext === 'undefined') return this.noWebgl();
    this.src = src;
    this.shaderBase = shaderBase;
    this.times.start = performance.now();
    this.host.resize(); // the canvas size: the first subscribe's footprint
    this.fetchShaders(); // before the subscribe: a shared subscription replays its manifest at once
    this.stream = BtfStream.for(src);
    this.stream.subscribe(material, this); // sets this.sub (onSubscribe)
    this.updateLabel();
    // the context once the subscribe is out (onStreamOpen: made while the manifest and the
    // first chunk travel; it blocks the page, so not before), or later if the server is slow
    setTimeout(() => this.ensureGl(), GL_AFTER_MS);
  }

  // Cancels everything in flight: subscription, uploads, GPU package, frames. Final.
  stop() {
    this.closed = true;
    if (this.sub) this.sub.stream.unsubscribe(this.sub, this);
    this.sub = null;
    this.dropGpu();
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

  // The GPU package (btf-gl.js GpuPackage), or null.
  get gpu() {
    return this.uploads ? this.uploads.gpu : null;
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
    if (this.pkg && !this.gpu) this.newGpu();
    return true;
  }

  // The "render" program's files (only those), fetched at once; a failed fetch is tried
  // again with backoff (a dropped link must not leave the viewer without shaders).
  fetchShaders() {
    this.shaderFiles = this.shaderBase === 'inside:'
      ? Promise.resolve({manifest: SHADER_PACK.manifest, files: new Map(Object.entries(SHADER_PACK.files))})
      : loadShaders(this.shaderBase, 'render');
    this.shaderFiles.then(() => {
      if (!this.closed) this.times.shaders ??= performance.now();
    }, (e) => {
      if (this.closed) return;
      const delay = SHADER_RETRY_MS[Math.min(this.shaderTry++, SHADER_RETRY_MS.length - 1)];
      this.trouble('shaders', `${e.message}; trying again`);
      setTimeout(() => !this.closed && this.fetchShaders(), delay);
    });
  }

  loadRenderer() {
    this.shaderFiles.then(() => this.ctx.renderer(this.shaderBase, this.shaderFiles)).then((r) => {
      if (this.closed) return;
      this.renderer = r;
      // the variant of a first frame (one 4-slot layer; levels once the manifest says)
      // compiles while the first chunk travels
      r.start(this.firstVariant());
      this.recovered('shaders');
      this.invalidate();
    }, () => {
      if (!this.closed) setTimeout(() => !this.closed && this.ctx && this.loadRenderer(), 250);
    });
  }

  // btf-context.js: the shared context was lost / restored.
  contextLost() {
    this.lost = true;
    this.dropGpu();
    this.renderer = null;
    this.host.message('WebGL context lost; waiting for the browser to restore it');
  }

  contextRestored() {
    this.lost = false;
    this.host.message('');
    this.ctx.renderer(this.shaderBase, this.shaderFiles).then((r) => {
      if (this.closed) return;
      this.renderer = r;
      this.rebuildGpu();
    }).catch((e) => !this.closed && this.fail(e));
  }

  // Re-uploads every chunk held by the subscription (after a context restore).
  rebuildGpu() {
    if (!this.pkg || !this.sub) return;
    this.newGpu();
    this.invalidate();
  }

  // ------------------------------------------------------------ budget

  // This session's own budget {chunks, bytes, error, pixels, threshold}; -1 = no limit
  // (btf-stream.js merges the budgets of a subscription's listeners). Without a
  // budget-chunks attribute: the scene budget, sent as the footprint (`pixels`, device
  // pixels one repeat of the material spans) so the server applies it from the first
  // subscribe on, before the manifest is here; once it is, also as the chunk count of
  // lodSelect (client/btf-lod.js), capped for packages without levels by the host's
  // policy (BtfViewer.budgetPolicy). 0 pixels while the viewer is off screen or the tab
  // hidden (streaming pauses).
  budget(drawing = false) {
    const a = this.host.asked();
    if (a.chunks !== null && a.chunks !== '')
      return {chunks: Math.max(0, parseInt(a.chunks, 10) || 0), bytes: a.bytes, error: -1, pixels: -1, threshold: -1};
    const pixels = !this.host.seen() && !drawing ? 0 : this.host.pixelsPerRepeat();
    let chunks = -1;
    if (this.pkg) {
      const policy = this.host.policy();
      chunks = this.sceneBudget(drawing).limit;
      if (policy >= 0) chunks = Math.min(chunks, policy);
    }
    return {chunks, bytes: a.bytes, error: -1, pixels, threshold: a.threshold};
  }

  // Texels per device pixel of the material at the object's centre (btf_lod_footprint).
  footprint() {
    if (!this.pkg) return 0;
    const px = this.host.pixelsPerRepeat();
    return px > 0 && this.pkg.width > 0 ? this.pkg.width / px : 0;
  }

  // lodSelect of the current view (client/btf-lod.js); nothing while paused unless drawing.
  sceneBudget(drawing = false) {
    const tpp = !this.host.seen() && !drawing ? 0 : this.footprint();
    return lodSelect(this.pkg, {texelsPerPixel: tpp, threshold: this.host.asked().threshold});
  }

  // Chunks this session draws: its own budget within the manifest.
  ownLimit() {
    if (!this.pkg) return 0;
    const b = this.budget(true);
    let n = this.pkg.chunks.length;
    if (b.chunks >= 0) n = Math.min(n, b.chunks);
    if (b.bytes >= 0) n = Math.min(n, chunksWithinBytes(this.pkg, b.bytes));
    return n;
  }

  // The view changed (zoom, size, on/off screen, tab shown/hidden): a scene budget may too.
  sceneChanged() {
    if (this.sub && this.host.asked().chunks === null) this.budgetChanged();
  }

  // An input of the budget changed (also the budget attributes).
  budgetChanged() {
    if (this.sub) this.sub.stream.updateBudget(this.sub);
    if (this.gpu) this.gpu.reserve(this.ownLimit());
    this.pump();
    this.updateLabel();
  }

  // ------------------------------------------------------------ stream events (btf-stream.js)

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

  onChunk(sub, j) {
    if (sub !== this.sub || !this.pkg) return;
    if (j === 0) this.times.chunk ??= sub.arrivedAt[0] ?? performance.now();
    this.recovered('stream');
    this.host.emit('progress', this.progress(j + 1)); // chunks arrive in order: j + 1 are here
    this.pump();
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
      if (!this.complete) this.host.label(text);
      return;
    }
    if (info.drained && info.attempt === 1) return;
    this.trouble('stream', `${text}; trying again in ${(info.delayMs / 1000).toFixed(1)} s`);
  }

  onStreamOpen(sub) {
    if (sub !== this.sub) return;
    this.times.open ??= performance.now();
    if (this.outages.stream) this.host.message(this.loaded ? '' : 'Connected, loading…', true);
    if (!this.ctx) setTimeout(() => this.ensureGl(), 0);
  }

  // Received against wanted (this session's budget), and the error the received prefix promises.
  progress(received = this.sub ? this.sub.received : 0) {
    const p = this.pkg, limit = this.ownLimit();
    const got = Math.min(received, limit);
    const bytes = (n) => p.chunks.slice(0, n).reduce((a, c) => a + c.bytes, 0);
    const e = promisedError(p, got);
    return {chunks: got, chunksWanted: limit, bytes: bytes(got), bytesWanted: bytes(limit),
            error: e ? (Number.isFinite(e.lab) ? e.lab : e.rmse ?? null) : null,
            metric: e && Number.isFinite(e.lab) ? 'lab' : 'rmse'};
  }

  // ------------------------------------------------------------ decode and upload

  // A fresh GPU package for the manifest (also after a context restore); uploads what is held.
  newGpu() {
    this.dropGpu();
    if (!this.gl || this.lost || !this.sub) return;
    this.uploads = new ChunkUploads(this.gl, this.pkg, this.sub, Math.max(1, this.ownLimit()), {
      decoded: () => {
        this.times.decoded ??= performance.now();
        this.invalidate();
      },
      fail: (e) => !this.closed && this.fail(e),
    });
    this.pump();
  }

  dropGpu() {
    this.uploads?.free();
    this.uploads = null;
  }

  // Queues the decode of the held chunks inside this session's budget.
  pump() {
    if (this.uploads) this.uploads.pump(this.ownLimit());
  }

  // Every decoded chunk into the GPU, in order; before the first frame only the first
  // one (the first picture comes from the first chunk, whatever else has arrived).
  uploadReady() {
    if (!this.uploads) return;
    if (this.uploads.upload(this.loaded ? Infinity : 1)) this.updateLabel();
    if (this.uploads.ready.length) this.invalidate();
  }

  // ------------------------------------------------------------ frames

  invalidate() {
    if (!this.raf && this.live) this.raf = requestAnimationFrame((t) => this.frame(t));
  }

  // The scene of this frame: the host's, with the chunks and the program variant.
  view() {
    const seconds = (performance.now() - this.t0) / 1000;
    return {...this.host.scene(seconds), chunks: this.drawableChunks(), quads: this.quads || 0};
  }

  drawableChunks() {
    return this.gpu ? Math.min(this.gpu.uploaded, this.ownLimit()) : 0;
  }

  // Draws into the shared context and copies the frame into the viewer's canvas.
  draw() {
    if (!this.renderer || this.lost || !this.ctx || this.ctx.lost) return false;
    const v = this.view(), w = this.host.canvas.width, h = this.host.canvas.height;
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
    if (!this.loaded) this.firstFrame(chunks);
    const limit = this.ownLimit();
    if (chunks >= limit && this.complete && this.completeFor !== limit) {
      this.completeFor = limit;
      this.completeAt = performance.now(); // since navigation start
      this.host.emit('complete', this.progress());
    }
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
    return this.host.moving() && this.drawableChunks() > 0 && !(this.host.resolution.slow && !this.complete);
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
    return {width: w, height: h, chunks: this.drawnChunks, rgba: btoa(s)};
  }

  // ------------------------------------------------------------ status

  updateLabel() {
    const p = this.pkg, s = this.sub;
    if (!p || !s) return this.host.label(null);
    const pr = this.progress();
    const want = pr.bytesWanted || 1;
    const drawn = this.drawableChunks(), limit = pr.chunksWanted;
    let t = `${p.name} · ${drawn}/${limit} chunks · ${(pr.bytes / 1024).toFixed(0)} KB`;
    const e = promisedError(p, drawn);
    if (drawn >= limit && limit > 0 && e && Number.isFinite(e.lab)) t += ` · Lab error ${e.lab.toFixed(2)}`;
    else if (drawn >= limit && limit > 0 && e && Number.isFinite(e.rmse)) t += ` · RMSE ${e.rmse.toFixed(2)}`;
    this.host.label(t, {percent: Math.min(100, (100 * pr.bytes) / want), done: pr.bytes >= want});
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

  fail(e, noWebgl = false) {
    this.error = String(e && e.message ? e.message : e);
    this.host.message(this.error);
    this.host.noWebgl(noWebgl);
    if (e && e.report) console.error(`${this.error}\n${e.report}`);
    this.host.emit('error', {reason: this.error});
  }

  // Test hook (window.__btf.viewers()): the session's part of the viewer's state.
  state() {
    const g = this.gpu, scene = this.pkg && this.pkg.version >= 2 ? this.sceneBudget() : null;
    return {
      budget: this.budget(), ownLimit: this.ownLimit(), manifestChunks: this.pkg ? this.pkg.chunks.length : 0,
      received: this.sub ? this.sub.received : 0, uploaded: g ? g.uploaded : 0, uploads: g ? g.uploads : 0,
      capacity: g ? g.capacity : 0, drawnChunks: this.drawnChunks, frames: this.frames, complete: this.complete,
      error: this.error || null, firstFrameMs: this.firstFrameMs, firstFrameAt: this.firstFrameAt ?? null,
      completeAt: this.completeAt ?? null, firstFrameBytes: this.firstFrameBytes,
      streamBytes: this.sub ? this.sub.bytes : 0, lost: this.lost, version: this.pkg ? this.pkg.version : 0,
      footprint: this.footprint(),
      scene: scene && {level: scene.level, components: scene.components, needed: scene.needed, limit: scene.limit,
        bytes: scene.bytes},
      slots: g ? g.slots : 0, firstFrameChunks: this.firstFrameChunks ?? null, times: {...this.times},
      decoder: decoderKind(), outage: Object.values(this.outages).filter(Boolean).join('; ') || null,
      gpuMs: this.ctx ? this.ctx.gpuMs ?? null : null,
    };
  }
}
