// btf-subscription.js - what both transports of the page's chunks share: a subscription
// (one material of a stream, its manifest, the chunks received, its listeners: the feeds
// of btf-feed.js) and the merging of its listeners' budgets. btf-stream.js fills it from
// the WebSocket, btf-http.js from HTTP requests; the listeners cannot tell them apart.

// The largest of several budgets (a limit only when every listener has one).
export function mergeBudgets(list) {
  const out = {chunks: -1, bytes: -1, error: -1, pixels: -1, threshold: -1};
  for (const key of ['chunks', 'bytes', 'pixels']) {
    let v = 0;
    for (const b of list) {
      if (!(b[key] >= 0)) { v = -1; break; }
      v = Math.max(v, b[key]);
    }
    out[key] = list.length ? v : 0;
  }
  let e = Infinity;
  for (const b of list) {
    if (!(b.error >= 0)) { e = -1; break; }
    e = Math.min(e, b.error);
  }
  out.error = list.length && e !== Infinity ? e : -1;
  const t = list.map((b) => b.threshold).filter((x) => x >= 0);
  out.threshold = out.pixels >= 0 && t.length ? Math.min(...t) : -1;
  return out;
}

// One material of a stream (a WebSocket, btf-stream.js, or HTTP requests, btf-http.js);
// lives while a listener holds it.
export class Subscription {
  constructor(stream, material, token = null) {
    this.stream = stream;
    this.material = material;
    this.token = token;     // a private library's access token (doc/deploy.md), or null
    this.listeners = new Set();
    this.mid = 0;
    this.seq = 0;           // seq of the subscribe sent on the current connection (its manifest echoes it)
    this.sent = false;      // subscribe sent on the current connection
    this.etag = null;
    this.manifest = null;   // raw manifest JSON object
    this.limit = 0;         // chunks the server says the budget allows
    this.chunks = [];       // chunk index -> array of Uint8Array (its files), when complete
    this.partial = new Map(); // chunk index -> {files: [Uint8Array|undefined], done: Set}
    this.received = 0;      // complete chunks
    this.bytes = 0;         // payload bytes received (header excluded)
    this.complete = false;
    this.sentBudget = null;
    this.error = null;
    this.loading = true;    // reading kept chunks (btf-cache.js); subscribe waits for it
    this.unannounced = 0;   // kept chunks the listeners have not been told about yet
    this.cached = 0;        // chunks that came from the browser's cache
    this.arrivedAt = [];    // chunk index -> when its last byte arrived (performance.now)
  }

  // Chunks kept from an earlier visit become held ones: the subscribe lists them in
  // `have` with their etag, and they are replayed once the manifest confirms the etag.
  adopt(kept) {
    if (kept && !this.manifest) {
      this.etag = kept.etag;
      this.keptManifest = kept.manifest || null; // the manifest of that etag, kept with them
      kept.chunks.forEach((files, j) => { this.chunks[j] = files; });
      this.received = this.cached = this.unannounced = kept.chunks.length;
    }
    this.loading = false;
  }

  have() {
    const h = [];
    this.chunks.forEach((c, i) => c && h.push(i));
    return h;
  }

  // Every chunk of its manifest is here: no budget can ask for more.
  holdsAll() {
    return !!this.manifest && this.have().length >= this.manifest.chunks.length;
  }

  budget() {
    return mergeBudgets([...this.listeners].map((l) => l.budget()));
  }

  // What a listener that joins a running subscription missed: its manifest, the complete
  // chunks, the end of the budget (both transports).
  replay(listener) {
    if (this.manifest && listener.onManifest) listener.onManifest(this);
    this.chunks.forEach((c, j) => c && listener.onChunk && listener.onChunk(this, j));
    if (this.complete && listener.onComplete) listener.onComplete(this, {});
  }

  emit(ev, ...args) {
    for (const l of this.listeners) if (l[ev]) l[ev](this, ...args);
  }
}
