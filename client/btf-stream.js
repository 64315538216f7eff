// btf-stream.js - one WebSocket (subprotocol btf-stream.v1, doc/protocol.md) per
// server, shared by every viewer of the page. The server picks the next chunk
// across all subscriptions of the connection by error reduction per byte: that is
// the scene-wide priority. Several viewers of one material share one subscription;
// its budget is the largest any of them asks for.
//
// Binary frames: 20-byte header of little-endian u32 (subscription id, chunk,
// file index in the chunk's "files", offset, file size), then payload bytes.

import {dropChunks, loadChunks, storeChunk} from './btf-cache.js';

export const SUBPROTOCOL = 'btf-stream.v1';
const HEADER = 20;

const streams = new Map(); // url -> BtfStream

// Budget {chunks, bytes, error} with -1 (or absent) meaning "no limit" -> wire form.
function wireBudget(b) {
  const o = {};
  if (b.chunks >= 0) o.chunks = Math.floor(b.chunks);
  if (b.bytes >= 0) o.bytes = Math.floor(b.bytes);
  if (b.error >= 0) o.error = b.error;
  return o;
}

// The largest of several budgets (a limit only when every listener has one).
export function mergeBudgets(list) {
  const out = {chunks: -1, bytes: -1, error: -1};
  for (const key of ['chunks', 'bytes']) {
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
  return out;
}

// One material on one connection; lives while a listener holds it.
class Subscription {
  constructor(stream, material) {
    this.stream = stream;
    this.material = material;
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
  }

  // Chunks kept from an earlier visit become held ones: the subscribe lists them in
  // `have` with their etag, and they are replayed once the manifest confirms the etag.
  adopt(kept) {
    if (kept && !this.manifest) {
      this.etag = kept.etag;
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

  budget() {
    return mergeBudgets([...this.listeners].map((l) => l.budget()));
  }

  emit(ev, ...args) {
    for (const l of this.listeners) if (l[ev]) l[ev](this, ...args);
  }
}

export class BtfStream {
  // The shared stream of a server URL (ws:// or wss://).
  static for(url) {
    const key = new URL(url).href;
    if (!streams.has(key)) streams.set(key, new BtfStream(key));
    return streams.get(key);
  }

  static all() {
    return [...streams.values()];
  }

  constructor(url) {
    this.url = url;
    this.subs = new Map(); // material -> Subscription
    this.byMid = new Map();
    this.ws = null;
    this.open = false;
    this.seq = 0;
    this.retry = 0;
    this.bytes = 0;        // all bytes received (headers and text included)
    this.frames = 0;
    this.pieces = {bytes: 0, first: null, last: null, firstBytes: 0}; // binary frames: bytes, arrival times (ms)
    this.connects = 0;
    this.hello = null;
    this.lastError = null;
    this.retryTimer = 0;
    this.connect();
  }

  connect() {
    let ws;
    try {
      ws = new WebSocket(this.url, SUBPROTOCOL);
    } catch (e) {
      this.lastError = String(e.message || e);
      this.broadcast('onStreamError', this.lastError);
      return;
    }
    ws.binaryType = 'arraybuffer';
    this.ws = ws;
    ws.onopen = () => {
      this.open = true;
      this.retry = 0;
      this.connects++;
      for (const sub of this.subs.values()) this.sendSubscribe(sub);
    };
    ws.onmessage = (ev) => this.onMessage(ev.data);
    ws.onclose = (ev) => {
      if (this.ws !== ws) return;
      this.open = false;
      this.ws = null;
      this.byMid.clear();
      this.lastError = `connection closed (${ev.code}${ev.reason ? ': ' + ev.reason : ''})`;
      for (const sub of this.subs.values()) {
        sub.mid = 0;
        sub.sent = false;
        sub.partial.clear();
      }
      if (ev.code === 1008 && ev.reason === 'origin not allowed') { // btfd --allow-origin: retrying is futile
        this.broadcast('onError', {code: 'origin_not_allowed', message: `${this.url} refuses this page's origin`});
      } else if (this.subs.size) {
        this.broadcast('onStreamError', this.lastError + ', reconnecting');
        this.reconnectLater();
      }
    };
    ws.onerror = () => {}; // onclose follows with the code
  }

  reconnectLater() {
    const delay = Math.min(8000, 250 * 2 ** this.retry++);
    this.retryTimer = setTimeout(() => {
      this.retryTimer = 0;
      this.connect();
    }, delay);
  }

  broadcast(ev, ...args) {
    for (const sub of this.subs.values()) sub.emit(ev, ...args);
  }

  send(obj) {
    if (!this.open) return false;
    this.ws.send(JSON.stringify(obj));
    return true;
  }

  // listener: {budget() -> {chunks, bytes, error}, onSubscribe(sub), onManifest(sub), onChunk(sub, j),
  //            onComplete(sub, msg), onError(sub, msg), onStreamError(sub, text)}
  // Returns the subscription; chunks already here are replayed to the listener.
  subscribe(material, listener) {
    let sub = this.subs.get(material);
    const fresh = !sub;
    if (fresh) {
      sub = new Subscription(this, material);
      this.subs.set(material, sub);
    }
    sub.listeners.add(listener);
    if (listener.onSubscribe) listener.onSubscribe(sub); // before any replay below
    if (!this.ws && !this.retryTimer) this.connect(); // closed while nothing was subscribed
    if (fresh) {
      loadChunks(this.url, material).then((kept) => {
        sub.adopt(kept);
        if (this.subs.get(material) === sub) this.sendSubscribe(sub);
      });
    } else {
      if (sub.manifest && listener.onManifest) listener.onManifest(sub);
      sub.chunks.forEach((c, j) => c && listener.onChunk && listener.onChunk(sub, j));
      if (sub.complete && listener.onComplete) listener.onComplete(sub, {});
      this.updateBudget(sub);
    }
    return sub;
  }

  unsubscribe(sub, listener) {
    sub.listeners.delete(listener);
    if (sub.listeners.size) return this.updateBudget(sub);
    this.subs.delete(sub.material);
    if (sub.mid) this.byMid.delete(sub.mid);
    if (sub.sent) this.send({type: 'unsubscribe', material: sub.material}); // also before its manifest came
    sub.sent = false;
  }

  sendSubscribe(sub) {
    if (sub.loading) return; // sent once the kept chunks are read
    const budget = sub.budget();
    const msg = {type: 'subscribe', material: sub.material, seq: ++this.seq, budget: wireBudget(budget)};
    const have = sub.have();
    if (have.length && sub.etag) {
      msg.have = have;
      msg.etag = sub.etag;
    }
    if (!this.send(msg)) return;
    sub.seq = msg.seq;
    sub.sent = true;
    sub.sentBudget = JSON.stringify(msg.budget);
  }

  // Sends the subscription's merged budget when it changed (e.g. a viewer resized).
  updateBudget(sub) {
    const wire = JSON.stringify(wireBudget(sub.budget()));
    if (!sub.mid || wire === sub.sentBudget) return;
    sub.sentBudget = wire;
    sub.complete = false;
    this.send({type: 'budget', material: sub.material, seq: ++this.seq, budget: JSON.parse(wire)});
  }

  onMessage(data) {
    this.frames++;
    if (typeof data === 'string') {
      this.bytes += data.length;
      let msg;
      try {
        msg = JSON.parse(data);
      } catch (e) {
        this.lastError = 'server sent invalid JSON';
        return;
      }
      return this.onText(msg);
    }
    this.bytes += data.byteLength;
    this.pieces.bytes += data.byteLength;
    this.pieces.last = performance.now();
    if (this.pieces.first === null) [this.pieces.first, this.pieces.firstBytes] = [this.pieces.last, data.byteLength];
    if (data.byteLength < HEADER) return;
    const h = new DataView(data, 0, HEADER);
    const [mid, chunk, file, off, total] = [0, 4, 8, 12, 16].map((o) => h.getUint32(o, true));
    const sub = this.byMid.get(mid);
    if (!sub || !sub.manifest) return;
    const entry = sub.manifest.chunks[chunk];
    if (!entry || file >= entry.files.length || sub.chunks[chunk]) return;
    if (!(total <= (entry.bytes > 0 ? entry.bytes : 256 << 20))) return; // no buffer the manifest does not announce
    let p = sub.partial.get(chunk);
    if (!p) sub.partial.set(chunk, p = {files: [], next: [], done: new Set()});
    if (!p.files[file]) [p.files[file], p.next[file]] = [new Uint8Array(total), 0];
    const n = data.byteLength - HEADER;
    // pieces of a file come with ascending offsets and no gaps (doc/protocol.md)
    if (off !== p.next[file] || off + n > total || p.files[file].length !== total || p.done.has(file)) return;
    p.files[file].set(new Uint8Array(data, HEADER, n), off);
    p.next[file] = off + n;
    sub.bytes += n;
    if (p.next[file] === total) p.done.add(file);
    if (p.done.size === entry.files.length) {
      sub.partial.delete(chunk);
      sub.chunks[chunk] = p.files;
      sub.received++;
      storeChunk(this.url, sub.material, sub.etag, chunk, p.files);
      sub.emit('onChunk', chunk);
    }
  }

  // The subscription a message is for: a manifest by the seq of its subscribe, the
  // rest by mid (an older subscription of the same name may still be in flight).
  target(msg) {
    if (msg.type === 'manifest') {
      const sub = this.subs.get(msg.material);
      return sub && sub.sent && sub.seq === msg.seq ? sub : null;
    }
    if (msg.type === 'error') return msg.material ? this.subs.get(msg.material) : null;
    return this.byMid.get(msg.mid) || null;
  }

  onText(msg) {
    const sub = this.target(msg);
    switch (msg.type) {
    case 'hello':
      this.hello = msg;
      break;
    case 'manifest':
      if (!sub) return;
      if (sub.etag && (sub.etag !== msg.etag || !msg.resumed) && sub.received) { // the package changed
        sub.chunks = [];
        sub.received = sub.cached = sub.unannounced = 0;
        dropChunks(this.url, sub.material);
      }
      sub.mid = msg.mid;
      sub.etag = msg.etag;
      sub.limit = msg.limit;
      this.byMid.set(msg.mid, sub);
      if (!sub.manifest || !msg.resumed) {
        sub.manifest = msg.manifest;
        sub.emit('onManifest');
      }
      for (; sub.unannounced; sub.unannounced--) sub.emit('onChunk', sub.received - sub.unannounced);
      this.updateBudget(sub);
      break;
    case 'budget':
      if (sub) sub.limit = msg.limit;
      break;
    case 'complete':
      if (!sub) return;
      sub.complete = true;
      sub.limit = msg.limit;
      sub.emit('onComplete', msg);
      break;
    case 'error':
      this.lastError = `${msg.code}: ${msg.message}`;
      if (sub) {
        sub.error = msg;
        sub.emit('onError', msg);
      } else {
        this.broadcast('onStreamError', this.lastError);
      }
      break;
    default:
      break;
    }
  }

  stats() {
    return {url: this.url, open: this.open, bytes: this.bytes, frames: this.frames, connects: this.connects,
            pieces: this.pieces,
            subscriptions: [...this.subs.values()].map((s) => ({material: s.material, received: s.received,
              cached: s.cached,
              bytes: s.bytes, limit: s.limit, complete: s.complete, listeners: s.listeners.size,
              budget: s.budget()}))};
  }
}
