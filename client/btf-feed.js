// btf-feed.js - one material of a session (btf-session.js): its subscription on the
// page's shared stream (btf-stream.js calls it as a listener), the manifest, the budget
// of what it shows, and the GPU package its chunks go into (btf-upload.js). A viewer of
// one material has one feed; a viewer of a model has one per library material its
// bindings name (bindings of the same material share its feed and GPU package).
// The feed reads the page only through its session and reports back to it.
//
//   feed = new MaterialFeed(session, material, {pixels(drawing), policy(pkg)})
//     pixels(drawing)  device pixels one repeat of the material spans (its footprint;
//                      0: nothing visible, streaming pauses unless drawing)
//     policy(pkg)      chunks for a package without budget-chunks, -1 no cap
import {ChunkUploads} from './btf-upload.js';
import {chunksWithinBytes, parseManifest, promisedError} from './btf-package.js';
import {lodSelect} from './btf-lod.js';

// Owned by a session; lives until the session stops (stop()).
export class MaterialFeed {
  constructor(session, material, view) {
    this.session = session;
    this.material = material;
    this.view = view;
    this.sub = this.pkg = this.uploads = null;
    this.quads = 0;          // the program variant of the last frame (MeshRenderer.defines)
    this.complete = false;   // the server sent everything in the subscription's budget
    this.drawnChunks = 0;    // chunks the last frame that showed any drew
  }

  subscribe(stream) {
    stream.subscribe(this.material, this); // sets this.sub (onSubscribe)
  }

  // The access token of a private library for this material (the element's `token`), or null.
  token() {
    return this.view.token ? this.view.token() : null;
  }

  stop() {
    if (this.sub) this.sub.stream.unsubscribe(this.sub, this);
    this.sub = null;
    this.dropGpu();
  }

  // The GPU package (btf-gl.js GpuPackage), or null.
  get gpu() {
    return this.uploads ? this.uploads.gpu : null;
  }

  get closed() {
    return this.session.closed;
  }

  // ------------------------------------------------------------ budget

  // This feed's own budget {chunks, bytes, error, pixels, threshold}; -1 = no limit
  // (btf-stream.js merges the budgets of a subscription's listeners). Without a
  // budget-chunks attribute: the scene budget, sent as the footprint (`pixels`, device
  // pixels one repeat of the material spans) so the server applies it from the first
  // subscribe on, before the manifest is here; once it is, also as the chunk count of
  // lodSelect (client/btf-lod.js), capped for packages without levels by the policy
  // (BtfViewer.budgetPolicy). 0 pixels while nothing of it is to be seen (streaming pauses).
  budget(drawing = false) {
    const a = this.session.host.asked();
    if (a.chunks !== null && a.chunks !== '')
      return {chunks: Math.max(0, parseInt(a.chunks, 10) || 0), bytes: a.bytes, error: -1, pixels: -1, threshold: -1};
    const pixels = this.view.pixels(drawing);
    let chunks = -1;
    if (this.pkg) {
      const policy = this.view.policy(this.pkg);
      chunks = this.sceneBudget(drawing).limit;
      if (policy >= 0) chunks = Math.min(chunks, policy);
    }
    return {chunks, bytes: a.bytes, error: -1, pixels, threshold: a.threshold};
  }

  // Texels per device pixel of the material (btf_lod_footprint); 0 when nothing shows.
  footprint(drawing = true) {
    if (!this.pkg) return 0;
    const px = this.view.pixels(drawing);
    return px > 0 && this.pkg.width > 0 ? this.pkg.width / px : 0;
  }

  // lodSelect of the current view (client/btf-lod.js); nothing while paused unless drawing.
  sceneBudget(drawing = false) {
    return lodSelect(this.pkg, {texelsPerPixel: this.footprint(drawing), threshold: this.session.host.asked().threshold});
  }

  // Chunks this feed draws: its own budget within the manifest.
  ownLimit() {
    if (!this.pkg) return 0;
    const b = this.budget(true);
    let n = this.pkg.chunks.length;
    if (b.chunks >= 0) n = Math.min(n, b.chunks);
    if (b.bytes >= 0) n = Math.min(n, chunksWithinBytes(this.pkg, b.bytes));
    return n;
  }

  // An input of the budget changed (the view, the budget attributes).
  budgetChanged() {
    if (this.sub) this.sub.stream.updateBudget(this.sub);
    if (this.gpu) this.gpu.reserve(this.ownLimit());
    this.pump();
  }

  // Received against wanted (this feed's budget), and the error the received prefix promises.
  progress(received = this.sub ? this.sub.received : 0) {
    const p = this.pkg, limit = this.ownLimit();
    if (!p) return {chunks: 0, chunksWanted: 0, bytes: 0, bytesWanted: 0, error: null, metric: 'rmse'};
    const got = Math.min(received, limit);
    const bytes = (n) => p.chunks.slice(0, n).reduce((a, c) => a + c.bytes, 0);
    const e = promisedError(p, got);
    return {chunks: got, chunksWanted: limit, bytes: bytes(got), bytesWanted: bytes(limit),
            error: e ? (Number.isFinite(e.lab) ? e.lab : e.rmse ?? null) : null,
            metric: e && Number.isFinite(e.lab) ? 'lab' : 'rmse'};
  }

  // Everything in its budget is drawn (nothing wanted counts as drawn).
  done() {
    const limit = this.ownLimit();
    return !!this.pkg && this.drawableChunks() >= limit && (this.complete || limit === 0);
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
      return this.session.fail(e);
    }
    this.session.feedManifest(this);
  }

  onChunk(sub, j) {
    if (sub !== this.sub || !this.pkg) return;
    this.session.feedChunk(this, j);
    this.pump();
  }

  onComplete(sub) {
    if (sub !== this.sub) return;
    this.complete = true;
    this.session.feedComplete(this);
  }

  onError(sub, msg) {
    if (sub === this.sub) this.session.feedError(this, msg);
  }

  onStreamError(sub, text, info) {
    if (sub === this.sub) this.session.streamError(text, info);
  }

  onStreamOpen(sub) {
    if (sub === this.sub) this.session.streamOpen();
  }

  // ------------------------------------------------------------ decode and upload

  // A fresh GPU package for the manifest (also after a context restore); uploads what is held.
  newGpu(gl) {
    this.dropGpu();
    if (!gl || !this.sub || !this.pkg) return;
    this.uploads = new ChunkUploads(gl, this.pkg, this.sub, Math.max(1, this.ownLimit()), {
      decoded: () => this.session.decoded(),
      fail: (e) => !this.closed && this.session.fail(e),
    });
    this.pump();
  }

  dropGpu() {
    this.uploads?.free();
    this.uploads = null;
  }

  // Queues the decode of the held chunks inside this feed's budget.
  pump() {
    if (this.uploads) this.uploads.pump(this.ownLimit());
  }

  // Decoded chunks into the GPU, in order, at most max; true when any went in. `waiting`
  // tells whether more are decoded and queued.
  upload(max) {
    return this.uploads ? this.uploads.upload(max) > 0 : false;
  }

  get waiting() {
    return this.uploads ? this.uploads.ready.length > 0 : false;
  }

  drawableChunks() {
    return this.gpu ? Math.min(this.gpu.uploaded, this.ownLimit()) : 0;
  }

  // Test hook: this feed's part of the viewer's state.
  state() {
    const g = this.gpu, scene = this.pkg && this.pkg.version >= 2 ? this.sceneBudget() : null;
    return {
      material: this.material, budget: this.budget(), ownLimit: this.ownLimit(),
      manifestChunks: this.pkg ? this.pkg.chunks.length : 0, received: this.sub ? this.sub.received : 0,
      uploaded: g ? g.uploaded : 0, uploads: g ? g.uploads : 0, capacity: g ? g.capacity : 0,
      drawnChunks: this.drawnChunks, complete: this.complete, streamBytes: this.sub ? this.sub.bytes : 0,
      version: this.pkg ? this.pkg.version : 0, footprint: this.footprint(true), pixels: this.view.pixels(true),
      packageBytes: this.pkg ? this.pkg.chunks.reduce((a, c) => a + c.bytes, 0) : 0,
      scene: scene && {level: scene.level, components: scene.components, needed: scene.needed, limit: scene.limit,
        bytes: scene.bytes},
      slots: g ? g.slots : 0,
    };
  }
}
