// btf-http.js - the chunks of a library over plain HTTP: a static host or CDN holding what
// `btf library publish` wrote, or btfd's own HTTP routes when its WebSocket cannot be opened
// (btf-stream.js falls back here). Same interface and same listeners as the WebSocket stream
// (btf-stream.js): subscribe, unsubscribe, updateBudget, stats; the feeds cannot tell them apart.
//
//   LIB/materials.json                 the list (btfd: GET /materials.json)
//   LIB/materials/NAME/ETAG/FILE       manifest.json and the chunks' files, immutable
//
// The client does here what btfd does for a WebSocket (doc/protocol.md): the budget's prefix
// of each material (budgetLimit, the server's rule), chunks in the manifest's order, the next
// chunk across the page's materials by the scene-wide priority (first chunks first, then
// error reduction per byte: nextChunk), whole files (no Range: a server that ignores it
// works). What is asked for and not here yet is bounded as the WebSocket's flow window
// bounds what btfd sends (btf-stream.js): the bytes the measured rate carries in two round
// trips and STALL_MS, a pause of the page's main thread (drawing, compiling) during which no
// request would go out; the browser runs the requests (6 at once per host over HTTP/1.1) and
// starts the queued ones as others finish, without the page. So the link stays full, and a
// budget change or another material waits behind under a second of the link, not megabytes. Chunks reach the
// listeners in order, are kept in the browser (btf-cache.js) and resumed from it as the
// WebSocket's are; requests that fail are retried with the WebSocket's backoff and jitter.

import {dropChunks, loadChunks, mayHaveChunks, storeChunk} from './btf-cache.js';
import {Subscription} from './btf-subscription.js';
import {lodSelect, LOD_THRESHOLD} from './btf-lod.js';

const WINDOW_START = 256 * 1024;   // bytes asked for and not here, before the rate is known
const WINDOW_MIN = 64 * 1024;      // never less ...
const WINDOW_MAX = 32 * 1024 * 1024; // ... nor more
const RATE_SPAN_MS = 500;          // the receive rate is measured over this much of the recent past
const STALL_MS = 700;              // the window also covers this long a pause of the page
const RETRY_MS = [500, 1000, 2000, 4000, 8000, 15000]; // as btf-stream.js, +-25% jitter
const LIST_AGAIN_MS = 1000;        // an unknown material asks for the list again at most this often

// The library's base URL (ending in '/') of a source: an http(s) folder (with or without its
// trailing '/'), its materials.json, or a btfd WebSocket URL (ws://HOST/stream -> http://HOST/).
export function libraryBase(src) {
  const u = new URL(src, globalThis.location?.href);
  u.search = u.hash = '';
  if (u.protocol === 'ws:' || u.protocol === 'wss:') {
    u.protocol = u.protocol === 'wss:' ? 'https:' : 'http:';
    return new URL('./', u).href;
  }
  if (/\.json$/.test(u.pathname)) return new URL('./', u).href;
  if (!u.pathname.endsWith('/')) u.pathname += '/';
  return u.href;
}

// A package file's URL with the subscription's access token of a private library
// (doc/deploy.md, "Private libraries"), if it has one.
function signed(sub, url) {
  return sub.token ? `${url}?token=${encodeURIComponent(sub.token)}` : url;
}

// A path of the list (`files`, `thumbnail`: "/materials/...", the library's root being "/")
// as a URL under the library's base.
export function libraryUrl(base, p) {
  return new URL(String(p).replace(/^\/+/, ''), base).href;
}

// The error metric of a manifest's chunks, as btfd chooses it: "lab" when every chunk has it,
// else "rmse", else null.
export function manifestMetric(m) {
  const all = (k) => m.chunks.every((c) => Number.isFinite(c[k]) && c[k] >= 0);
  return all('lab') ? 'lab' : all('rmse') ? 'rmse' : null;
}

// The prefix of the manifest's chunks a budget {chunks, bytes, error, pixels, threshold}
// (-1: no limit) allows: btfd's rule (server/btfd_protocol.c budget_limit, doc/protocol.md
// "Budget"); pixels by the selection rule of packages with levels (versions 2 and 4).
export function budgetLimit(m, b) {
  const ch = m.chunks;
  let limit = ch.length;
  if (b.chunks >= 0) limit = Math.min(limit, Math.floor(b.chunks));
  if (b.bytes >= 0) {
    let sum = 0;
    for (let i = 0; i < limit; i++) if ((sum += ch[i].bytes) > b.bytes) { limit = i; break; }
  }
  if (b.pixels >= 0) {
    let need = ch.length;
    if (!(b.pixels > 0)) need = 0;
    else if ((m.version === 2 || m.version === 4) && m.levels >= 1 && m.width >= 1)
      need = lodSelect(m, {texelsPerPixel: m.width / b.pixels, threshold: b.threshold >= 0 ? b.threshold : LOD_THRESHOLD}).limit;
    limit = Math.min(limit, need);
  }
  const metric = manifestMetric(m);
  if (b.error >= 0 && metric)
    for (let i = 0; i < limit; i++) if (ch[i][metric] <= b.error) { limit = i + 1; break; }
  return limit;
}

// The next chunk to ask for among subscriptions [{held, next, limit, manifest}] (held: chunks
// here or asked for; next: the first of them not held): the index in the list and the chunk,
// or null. btfd's scene-wide priority (doc/protocol.md): a material with nothing held, or its
// chunk 0, first (infinite); else the error reduction per byte of its next chunk; ties to the
// earlier subscription.
export function nextChunk(list) {
  let best = -1, pick = null;
  list.forEach((s, k) => {
    if (!s.manifest || s.next >= s.limit) return;
    const ch = s.manifest.chunks, i = s.next, metric = manifestMetric(s.manifest);
    let p = Infinity;
    if (s.held > 0 && i > 0) {
      const red = metric ? ch[i - 1][metric] - ch[i][metric] : 0;
      p = (red > 0 ? red : 0) / (ch[i].bytes > 0 ? ch[i].bytes : 1);
    }
    if (p > best) [best, pick] = [p, {index: k, chunk: i, first: p === Infinity}];
  });
  return pick;
}

const lists = new Map(); // base -> {at, promise} of its materials.json, shared by the page

// The library's list ({generation, materials}); fresh: asks the server again (a package
// replaced, or a material the list did not name).
function fetchList(base, fresh = false) {
  const known = lists.get(base);
  if (known && (!fresh || (known.fresh && performance.now() - known.at < LIST_AGAIN_MS))) return known.promise;
  const promise = fetch(new URL('materials.json', base), {cache: fresh ? 'no-cache' : 'default', credentials: 'omit'})
    .then((r) => {
      if (!r.ok) throw new HttpError(`${base}materials.json: HTTP ${r.status}`, r.status);
      return r.json();
    });
  const entry = {at: performance.now(), promise, fresh};
  lists.set(base, entry);
  promise.catch(() => { if (lists.get(base) === entry) lists.delete(base); });
  return promise;
}

class HttpError extends Error {
  constructor(message, status) {
    super(message);
    this.status = status;
  }
}

// The chunks of one library over HTTP; one per library base URL, shared by every viewer of
// the page (btf-stream.js makes them: BtfStream.for an http(s) URL, or its fallback).
export class HttpStream {
  // base: the library's base URL (libraryBase); parent: a WebSocket stream that fell back
  // to this one (it counts the bytes, the session reads them there).
  constructor(base, parent = null) {
    this.url = this.base = libraryBase(base);
    this.parent = parent;
    this.transport = 'http';
    this.subs = new Map();   // material -> Subscription
    this.order = 0;          // subscription order (mid): ties of the priority go to the earlier one
    this.open = false;       // the last request succeeded
    this.bytes = 0;          // bytes of files received
    this.frames = 0;         // files received
    this.connects = 0;       // recoveries: the first success and each after an outage
    this.attempts = 0;       // requests made
    this.requests = [];      // files in flight: {sub, chunk, file, ctrl, bytes}
    this.inFlightMax = 0;    // most files asked for at once
    this.window = WINDOW_START; // bytes asked for and not here (flowWindow of btf-stream.js)
    this.rtt = null;         // ms from asking for the first manifest to its bytes
    this.hist = [];          // [when, bytes received so far] over RATE_SPAN_MS
    this.pieces = {bytes: 0, first: null, last: null, firstBytes: 0};
    this.retry = 0;
    this.retryTimer = 0;
    this.lastError = null;
    fetchList(this.base).catch(() => {}); // on its way before the first subscribe
  }

  // ------------------------------------------------------------ the feeds' interface

  // listener: as BtfStream.subscribe's. Returns the subscription; what is here is replayed.
  subscribe(material, listener) {
    let sub = this.subs.get(material);
    const fresh = !sub;
    if (fresh) {
      sub = new Subscription(this, material, listener.token?.() || null);
      sub.mid = ++this.order;
      sub.want = [];         // chunk index -> {files, done}: asked for, not yet handed on
      this.subs.set(material, sub);
    }
    sub.listeners.add(listener);
    if (listener.onSubscribe) listener.onSubscribe(sub);
    if (fresh) {
      const kept = mayHaveChunks(this.url, material) ? loadChunks(this.url, material) : Promise.resolve(null);
      kept.then((k) => {
        sub.adopt(k);
        if (this.subs.get(material) === sub) this.start(sub);
      });
    } else {
      sub.replay(listener);
      this.updateBudget(sub);
    }
    return sub;
  }

  unsubscribe(sub, listener) {
    sub.listeners.delete(listener);
    if (sub.listeners.size) return this.updateBudget(sub);
    if (this.subs.get(sub.material) === sub) this.subs.delete(sub.material);
    sub.gone = true;
    for (const r of this.requests.filter((x) => x.sub === sub)) r.ctrl.abort();
    this.requests = this.requests.filter((x) => x.sub !== sub);
    this.pump();
  }

  // The listeners' budget changed: a new prefix; more requests when it grew.
  updateBudget(sub) {
    if (!sub.manifest) return;
    const limit = budgetLimit(sub.manifest, sub.budget());
    if (limit === sub.limit) return;
    sub.limit = limit;
    sub.complete = false;
    this.checkComplete(sub);
    this.pump();
  }

  // ------------------------------------------------------------ list and manifest

  // The material's entry in the list, its manifest, then its chunks.
  async start(sub) {
    try {
      let list = await fetchList(this.base);
      this.succeeded(); // the server answers: the session makes its WebGL context while the manifest travels
      let entry = (list.materials || []).find((m) => m.name === sub.material);
      if (!entry) { // added since the list was fetched?
        list = await fetchList(this.base, true);
        entry = (list.materials || []).find((m) => m.name === sub.material);
      }
      if (sub.gone) return;
      if (!entry) {
        sub.error = {code: 'unknown_material', message: `no material "${sub.material}" in ${this.base}materials.json`};
        return sub.emit('onError', sub.error);
      }
      const files = libraryUrl(this.base, entry.files || `/materials/${entry.name}/${entry.etag}/`);
      const t0 = performance.now();
      const manifest = await this.fetchBytes(signed(sub, `${files}manifest.json`)).then((b) => JSON.parse(new TextDecoder().decode(b)));
      this.rtt ??= performance.now() - t0; // a round trip and a small file
      if (sub.gone) return;
      if (!manifest || !Array.isArray(manifest.chunks) || !manifest.chunks.length) throw new Error(`${files}manifest.json: no chunks`);
      this.takeManifest(sub, entry.etag, files, manifest);
    } catch (e) {
      if (e.status === 404) lists.delete(this.base); // a manifest the list names is gone: ask for the list again
      if (!sub.gone && !this.refused(sub, e)) this.failed(e, () => this.start(sub));
    }
  }

  // As btf-stream.js takes a manifest message: kept chunks of another etag are dropped,
  // those of this one replayed.
  takeManifest(sub, etag, files, manifest) {
    if (sub.etag && sub.etag !== etag && sub.received) {
      sub.chunks = [];
      sub.received = sub.cached = sub.unannounced = 0;
      dropChunks(this.url, sub.material);
    }
    for (const r of this.requests.filter((x) => x.sub === sub)) r.ctrl.abort();
    this.requests = this.requests.filter((x) => x.sub !== sub);
    sub.want = [];
    sub.etag = etag;
    sub.files = files;
    sub.manifest = manifest;
    sub.limit = budgetLimit(manifest, sub.budget());
    sub.complete = false;
    sub.emit('onManifest');
    for (; sub.unannounced; sub.unannounced--) sub.emit('onChunk', sub.received - sub.unannounced);
    this.checkComplete(sub);
    this.pump();
  }

  // A file of the current etag is gone (btfd replaced the package): the list again, and
  // the new package from its start.
  async restart(sub) {
    try {
      const list = await fetchList(this.base, true);
      const entry = (list.materials || []).find((m) => m.name === sub.material);
      if (sub.gone) return;
      if (!entry || entry.etag === sub.etag) {
        sub.error = {code: 'not_found', message: `${sub.files}: a file of "${sub.material}" is missing`};
        return sub.emit('onError', sub.error);
      }
      sub.manifest = null;
      this.start(sub);
    } catch (e) {
      if (!sub.gone) this.failed(e, () => this.restart(sub));
    }
  }

  // ------------------------------------------------------------ chunks

  // Bytes asked for and not here yet.
  pending() {
    return this.requests.reduce((a, r) => a + r.bytes, 0);
  }

  // What the link carries in two round trips and STALL_MS at the rate measured over
  // RATE_SPAN_MS (as btf-stream.js flowWindow); while the window limits it, it grows.
  flowWindow() {
    const h = this.hist, span = h.length > 1 ? h[h.length - 1][0] - h[0][0] : 0;
    if (span < 50 || this.rtt === null) return this.window;
    const rate = (h[h.length - 1][1] - h[0][1]) / span;
    const w = Math.round(rate * (2 * this.rtt + STALL_MS));
    return Math.round(Math.max(WINDOW_MIN, Math.min(WINDOW_MAX, Math.max(w, this.window / 2))));
  }

  // Every subscription's next chunk not held nor asked for, by the scene-wide priority,
  // while the window has room (one chunk may cross it). While a first chunk is on its way
  // nothing else is asked for (it is a picture on its own: it has the link to itself).
  pump() {
    if (this.retryTimer) return;
    const subs = [...this.subs.values()].filter((s) => s.manifest && !s.error);
    this.window = this.flowWindow();
    while (this.pending() < this.window) {
      if (this.requests.some((r) => r.first)) return;
      const pick = nextChunk(subs.map((s) => {
        const held = Math.max(s.received, s.want.length);
        return {manifest: s.manifest, held, next: held, limit: s.limit};
      }));
      if (!pick) return;
      const sub = subs[pick.index], j = pick.chunk, entry = sub.manifest.chunks[j];
      if (pick.first && this.requests.length) return; // the first chunk waits for the link
      sub.want[j] = {files: [], done: 0};
      entry.files.forEach((name, f) => this.request(sub, j, f, name, pick.first));
    }
  }

  request(sub, j, f, name, first) {
    const ctrl = new AbortController(), w = sub.want[j];
    const r = {sub, chunk: j, file: f, ctrl, first, bytes: sub.manifest.chunks[j].bytes / sub.manifest.chunks[j].files.length};
    this.requests.push(r);
    this.inFlightMax = Math.max(this.inFlightMax, this.requests.length);
    this.fetchBytes(signed(sub, sub.files + name), ctrl.signal).then((bytes) => {
      this.requests = this.requests.filter((x) => x !== r);
      if (sub.gone || sub.want[j] !== w) return;
      this.succeeded();
      this.took(bytes.length);
      w.files[f] = bytes;
      sub.bytes += bytes.length;
      if (++w.done === sub.manifest.chunks[j].files.length) this.deliver(sub);
      this.pump();
    }, (e) => {
      this.requests = this.requests.filter((x) => x !== r);
      if (e.name === 'AbortError' || sub.gone || sub.want[j] !== w) return;
      if (e.status === 404 || this.refused(sub, e)) { // 404: btfd replaced the package (a static host keeps old etags)
        for (const x of this.requests.filter((y) => y.sub === sub)) x.ctrl.abort();
        this.requests = this.requests.filter((y) => y.sub !== sub);
        return sub.error ? undefined : this.restart(sub);
      }
      sub.want.length = Math.min(sub.want.length, j); // asked for again, from this chunk on
      this.failed(e, () => this.pump());
    });
  }

  // A private library's refusal (403; nginx's secure_link answers 410 for an expired
  // link) is final for the subscription, as btfd's error frame is: no retry. 1 if so.
  refused(sub, e) {
    if (e.status !== 403 && e.status !== 410) return 0;
    sub.error = {code: e.status === 410 ? 'token_expired' : 'forbidden',
      message: `${e.message}: a private library, and the token is missing, wrong or expired`};
    sub.emit('onError', sub.error);
    return 1;
  }

  // Complete chunks, in order, to the listeners (and the browser's cache).
  deliver(sub) {
    for (let j = sub.received; sub.want[j] && sub.want[j].done === sub.manifest.chunks[j].files.length; j++) {
      sub.chunks[j] = sub.want[j].files;
      sub.received++;
      sub.arrivedAt[j] = performance.now();
      storeChunk(this.url, sub.material, sub.etag, j, sub.chunks[j]);
      sub.emit('onChunk', j);
    }
    this.checkComplete(sub);
  }

  // `complete` once everything in the budget is here (again after each budget change).
  checkComplete(sub) {
    if (sub.complete || !sub.manifest || sub.received < sub.limit) return;
    sub.complete = true;
    sub.emit('onComplete', {type: 'complete', material: sub.material, limit: sub.limit, held: sub.received});
  }

  // ------------------------------------------------------------ requests and failures

  // The bytes of url (whole: no Range), or an error with the HTTP status.
  async fetchBytes(url, signal) {
    this.attempts++;
    const r = await fetch(url, {signal, credentials: 'omit'});
    if (!r.ok) throw new HttpError(`${url}: HTTP ${r.status}`, r.status);
    return new Uint8Array(await r.arrayBuffer());
  }

  took(n) {
    const now = performance.now();
    this.bytes += n;
    this.frames++;
    if (this.parent) this.parent.bytes += n;
    this.pieces.bytes += n;
    this.hist.push([now, this.bytes]);
    while (this.hist.length > 2 && this.hist[1][0] < now - RATE_SPAN_MS) this.hist.shift();
    this.pieces.last = now;
    if (this.pieces.first === null) [this.pieces.first, this.pieces.firstBytes] = [now, n];
  }

  // A request succeeded: an outage is over (the listeners hear the stream is open).
  succeeded() {
    if (this.open) return;
    this.open = true;
    this.retry = 0;
    this.connects++;
    for (const sub of this.subs.values()) sub.emit('onStreamOpen');
  }

  // A request failed (no answer, or an HTTP error other than 404): `again` after the
  // backoff; the listeners hear of the outage as of a lost WebSocket.
  failed(e, again) {
    this.open = false;
    this.lastError = e.status ? String(e.message) : `cannot reach ${this.base}`;
    (this.again ??= new Set()).add(again);
    if (this.retryTimer) return;
    this.retry++;
    const base = RETRY_MS[Math.min(this.retry, RETRY_MS.length) - 1];
    const delay = Math.round(base * (0.75 + 0.5 * Math.random()));
    this.retryTimer = setTimeout(() => {
      this.retryTimer = 0;
      const fns = [...this.again];
      this.again.clear();
      for (const fn of fns) fn();
      this.pump();
    }, delay);
    for (const sub of this.subs.values())
      sub.emit('onStreamError', this.lastError, {retrying: true, attempt: this.retry, delayMs: delay});
  }

  stats() {
    return {url: this.url, transport: 'http', open: this.open, bytes: this.bytes, frames: this.frames,
      connects: this.connects, attempts: this.attempts, pieces: this.pieces, flow: null,
      inFlight: this.requests.length, inFlightMax: this.inFlightMax, window: this.window, rtt: this.rtt,
      subscriptions: [...this.subs.values()].map((s) => ({material: s.material, received: s.received,
        cached: s.cached, bytes: s.bytes, limit: s.limit, complete: s.complete, listeners: s.listeners.size,
        arrivedAt: s.arrivedAt, budget: s.budget()}))};
  }
}
