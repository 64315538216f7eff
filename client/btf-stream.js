// btf-stream.js - one WebSocket (subprotocol btf-stream.v1, doc/protocol.md) per
// server, shared by every viewer of the page. The server picks the next chunk
// across all subscriptions of the connection by error reduction per byte: that is
// the scene-wide priority. Several viewers of one material share one subscription;
// its budget is the largest any of them asks for.
//
// Binary frames: 20-byte header of little-endian u32 (subscription id, chunk,
// file index in the chunk's "files", offset, file size), then payload bytes.
//
// Flow control (doc/protocol.md): the stream keeps at most a window of bytes in flight
// (acknowledged as they arrive, at most every ACK_MS): what the link carries in two round
// trips and a short pause of the page (STALL_MS), so a budget change, another material or a shader file the page asks for
// later waits behind that much, not behind megabytes the server pushed into the network.
// Reconnects: after a lost connection the stream reconnects with backoff and jitter while
// anything it was asked for is missing, and stays closed once everything has arrived
// until a listener asks for more.

import {dropChunks, loadChunks, mayHaveChunks, storeChunk, storeManifest} from './btf-cache.js';
import {Subscription, mergeBudgets} from './btf-subscription.js';
import {HttpStream, libraryBase} from './btf-http.js';

export {mergeBudgets};

export const SUBPROTOCOL = 'btf-stream.v1';
const HEADER = 20;
const ACK_MS = 25;                 // at most one ack per this many ms (the server allows 128 messages/s)
const WINDOW_START = 256 * 1024;   // bytes in flight before the rate is known (the page is busiest then)
const WINDOW_MIN = 64 * 1024;      // never less ...
const WINDOW_MAX = 32 * 1024 * 1024; // ... nor more
const RATE_SPAN_MS = 500;          // the receive rate is measured over this much of the recent past
const STALL_MS = 700;              // the window also covers this long a pause of the page (acks wait for it)
const RETRY_MS = [500, 1000, 2000, 4000, 8000, 15000]; // reconnect delays (then the last), +-25% jitter

const streams = new Map(); // url -> BtfStream

// Budget {chunks, bytes, error, pixels, threshold} with -1 (or absent) meaning "no
// limit" -> wire form (pixels: device pixels one repeat of the material spans, the
// server's footprint rule; doc/protocol.md "Budget").
function wireBudget(b) {
  const o = {};
  if (b.chunks >= 0) o.chunks = Math.floor(b.chunks);
  if (b.bytes >= 0) o.bytes = Math.floor(b.bytes);
  if (b.error >= 0) o.error = b.error;
  if (b.pixels >= 0) o.pixels = Math.round(b.pixels * 100) / 100;
  if (b.pixels >= 0 && b.threshold >= 0) o.threshold = b.threshold;
  return o;
}

// Flow state of one connection: bytes received, when, the round trip (ping at open).
function newFlow() {
  return {received: 0, window: WINDOW_START, rtt: null, hist: [], timer: 0, lastAck: 0, pingSeq: 0,
    pingAt: 0, refused: false};
}

// What the link carries in twice a round trip plus an ack interval, and in STALL_MS
// (the main thread of a page that compiles shaders or makes a WebGL context sends no
// acks meanwhile; the link must not run dry): the rate measured over RATE_SPAN_MS;
// while the window limits it, the window grows.
function flowWindow(f) {
  const h = f.hist, span = h.length > 1 ? h[h.length - 1][0] - h[0][0] : 0;
  if (span < 50 || f.rtt === null) return f.window;
  const rate = (h[h.length - 1][1] - h[0][1]) / span; // bytes per ms
  const w = Math.round(rate * (2 * (f.rtt + ACK_MS) + STALL_MS));
  return Math.round(Math.max(WINDOW_MIN, Math.min(WINDOW_MAX, Math.max(w, f.window / 2))));
}

export class BtfStream {
  // The shared stream of a source: a btfd's WebSocket (ws:// or wss://), or a library over
  // HTTP (http:// or https://: a static host, btf-http.js), one per page.
  // folder: where else a WebSocket source's library may be found over HTTP when the
  // socket never opens (the viewer's default source: its script's folder, which is
  // where `btf library publish` puts the script beside the library on a static host).
  static for(url, folder = null) {
    const u = new URL(url, globalThis.location?.href);
    const http = u.protocol === 'http:' || u.protocol === 'https:';
    const key = http ? libraryBase(u.href) : u.href;
    if (!streams.has(key)) streams.set(key, http ? new HttpStream(key) : new BtfStream(key));
    const s = streams.get(key);
    if (folder && !http && !s.folders.includes(folder)) s.folders.push(folder);
    return s;
  }

  static all() {
    return [...streams.values()];
  }

  constructor(url) {
    this.url = url;
    this.folders = [libraryBase(url)]; // where probeHttp looks for the library over HTTP, in order
    this.subs = new Map(); // material -> Subscription
    this.byMid = new Map();
    this.ws = null;
    this.open = false;
    this.seq = 0;
    this.retry = 0;        // failed connection attempts since the last open
    this.bytes = 0;        // all bytes received (headers and text included)
    this.frames = 0;
    this.pieces = {bytes: 0, first: null, last: null, firstBytes: 0}; // binary frames: bytes, arrival times (ms)
    this.connects = 0;     // connections opened
    this.attempts = 0;     // connections tried
    this.hello = null;
    this.lastError = null;
    this.retryTimer = 0;
    this.flow = null;      // this connection's flow control (newFlow)
    this.connect();
  }

  // Anything asked for and not here yet: worth a connection.
  wanted() {
    return [...this.subs.values()].some((sub) => sub.loading || !sub.complete || !sub.manifest);
  }

  connect() {
    if (this.http) return;
    let ws;
    this.attempts++;
    try {
      ws = new WebSocket(this.url, SUBPROTOCOL);
    } catch (e) {
      this.lastError = String(e.message || e);
      this.broadcast('onError', {code: 'bad_url', message: this.lastError});
      return;
    }
    ws.binaryType = 'arraybuffer';
    this.ws = ws;
    ws.onopen = () => {
      this.open = true;
      this.retry = 0;
      this.connects++;
      this.flow = newFlow();
      this.sendFlow(true);
      for (const sub of this.subs.values()) this.sendSubscribe(sub);
      this.broadcast('onStreamOpen'); // after the subscribes: a listener's work here delays nothing on the wire
    };
    ws.onmessage = (ev) => this.onMessage(ev.data);
    ws.onclose = (ev) => this.onClose(ws, ev);
    ws.onerror = () => {}; // onclose follows with the code
  }

  onClose(ws, ev) {
    if (this.ws !== ws) return;
    const opened = this.open;
    if (!opened && !this.connects && !this.probed && this.subs.size) return this.probeHttp(ws, ev);
    this.open = false;
    this.ws = null;
    clearTimeout(this.flow?.timer);
    this.flow = null;
    this.byMid.clear();
    this.lastError = opened ? `connection closed (${ev.code}${ev.reason ? ': ' + ev.reason : ''})`
      : `cannot reach ${this.url}`;
    for (const sub of this.subs.values()) {
      sub.mid = 0;
      sub.sent = false;
      sub.partial.clear();
    }
    if (ev.code === 1008 && ev.reason === 'origin not allowed') { // btfd --allow-origin: retrying is futile
      this.broadcast('onError', {code: 'origin_not_allowed', message: `${this.url} refuses this page's origin`});
    } else if (this.wanted()) {
      this.retry++;
      const delay = this.reconnectLater();
      this.broadcast('onStreamError', this.lastError, {retrying: true, attempt: this.retry, delayMs: delay,
        drained: ev.code === 1001});
    }
    // else: everything asked for is here; the next subscribe or larger budget reconnects
  }

  // The socket never opened: is it the WebSocket only (a proxy that refuses upgrades), or
  // no btfd at all but a published library? When the server answers its list over HTTP
  // (btfd: GET /materials.json), or the script's folder does (a static host), the stream
  // goes on over HTTP from there (btf-http.js); else the failure takes its usual course.
  probeHttp(ws, ev, i = 0) {
    this.probed = true;
    const base = this.folders[i];
    if (!base) {
      this.ws = ws;
      return this.onClose(ws, ev);
    }
    fetch(new URL('materials.json', base), {credentials: 'omit'})
      .then((r) => (r.ok ? r.json() : null))
      .catch(() => null)
      .then((list) => (list && Array.isArray(list.materials) ? this.fallBack(base) : this.probeHttp(ws, ev, i + 1)));
  }

  // From now on every subscription of this stream is one of an HTTP stream of the same
  // server; the listeners move there (onSubscribe gives them the new subscription).
  fallBack(base) {
    this.ws = null;
    this.http = new HttpStream(base, this);
    const subs = [...this.subs.values()];
    this.subs.clear();
    this.byMid.clear();
    for (const sub of subs) for (const l of sub.listeners) this.http.subscribe(sub.material, l);
  }

  // Schedules the next attempt: RETRY_MS[retry - 1], +-25% jitter so many pages do not
  // come back in step (a draining server's 1001 too: another one behind the proxy takes over).
  reconnectLater() {
    if (this.retryTimer) return 0;
    const base = RETRY_MS[Math.min(this.retry, RETRY_MS.length) - 1] ?? RETRY_MS[0];
    const delay = Math.round(base * (0.75 + 0.5 * Math.random()));
    this.retryTimer = setTimeout(() => {
      this.retryTimer = 0;
      if (!this.ws && this.subs.size) this.connect();
    }, delay);
    return delay;
  }

  // Reconnects now if closed and something is wanted (a new subscription, a larger budget).
  wake() {
    if (this.ws || !this.subs.size) return;
    clearTimeout(this.retryTimer);
    this.retryTimer = 0;
    this.connect();
  }

  broadcast(ev, ...args) {
    for (const sub of this.subs.values()) sub.emit(ev, ...args);
  }

  send(obj) {
    if (!this.open) return false;
    this.ws.send(JSON.stringify(obj));
    return true;
  }

  // The window and what has arrived (first: also a ping, whose pong times the round trip).
  sendFlow(first = false) {
    const f = this.flow;
    if (!f) return;
    f.timer = 0;
    f.lastAck = performance.now();
    f.window = flowWindow(f);
    this.send({type: 'ack', received: f.received, window: f.window});
    if (first) {
      f.pingSeq = ++this.seq;
      f.pingAt = performance.now();
      this.send({type: 'ping', seq: f.pingSeq});
    }
  }

  // Binary bytes arrived: acknowledged at once when ACK_MS has passed, else when it has.
  onFlow(n) {
    const f = this.flow;
    if (!f) return;
    f.received += n;
    const now = performance.now();
    f.hist.push([now, f.received]);
    while (f.hist.length > 2 && f.hist[1][0] < now - RATE_SPAN_MS) f.hist.shift();
    if (f.timer) return;
    const wait = ACK_MS - (now - f.lastAck);
    if (wait <= 0) this.sendFlow();
    else f.timer = setTimeout(() => this.sendFlow(), wait);
  }

  // listener: {budget() -> {chunks, bytes, error}, onSubscribe(sub), onManifest(sub), onChunk(sub, j),
  //            onComplete(sub, msg), onError(sub, msg), onStreamError(sub, text)}
  // Returns the subscription; chunks already here are replayed to the listener.
  subscribe(material, listener) {
    if (this.http) return this.http.subscribe(material, listener);
    let sub = this.subs.get(material);
    const fresh = !sub;
    if (fresh) {
      sub = new Subscription(this, material, listener.token?.() || null);
      this.subs.set(material, sub);
    }
    sub.listeners.add(listener);
    if (listener.onSubscribe) listener.onSubscribe(sub); // before any replay below
    if (!this.ws && !this.retryTimer) this.connect(); // closed: nothing was subscribed, or all had arrived
    if (fresh && !mayHaveChunks(this.url, material)) {
      sub.adopt(null); // nothing kept: the subscribe goes out as soon as the socket opens
      this.sendSubscribe(sub);
    } else if (fresh) {
      loadChunks(this.url, material).then((kept) => {
        sub.adopt(kept);
        if (this.subs.get(material) === sub) this.sendSubscribe(sub);
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
    this.subs.delete(sub.material);
    if (sub.mid) this.byMid.delete(sub.mid);
    if (sub.sent) this.send({type: 'unsubscribe', material: sub.material}); // also before its manifest came
    sub.sent = false;
  }

  sendSubscribe(sub) {
    if (sub.loading) return; // sent once the kept chunks are read
    const budget = sub.budget();
    const msg = {type: 'subscribe', material: sub.material, seq: ++this.seq, budget: wireBudget(budget)};
    if (sub.token) msg.token = sub.token;
    const have = sub.have();
    if (have.length && sub.etag) {
      msg.have = have;
      msg.etag = sub.etag;
      if (sub.manifest || sub.keptManifest) msg.manifest_kept = true; // resumed: the server leaves it out
    }
    if (!this.send(msg)) return;
    sub.seq = msg.seq;
    sub.sent = true;
    sub.sentBudget = JSON.stringify(msg.budget);
  }

  // Sends the subscription's merged budget when it changed (e.g. a viewer resized); a
  // stream closed because everything had arrived reconnects for it, unless the
  // subscription holds its whole package (no budget can ask for more).
  updateBudget(sub) {
    const wire = JSON.stringify(wireBudget(sub.budget()));
    if (wire === sub.sentBudget) return;
    if (!this.ws) {
      if (sub.holdsAll()) return;
      sub.complete = false;
      return this.wake(); // the subscribe on open carries the new budget
    }
    if (!sub.mid) return;
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
    this.onFlow(data.byteLength);
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
      sub.arrivedAt[chunk] = performance.now();
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
    case 'pong':
      if (this.flow && msg.seq === this.flow.pingSeq) this.flow.rtt = performance.now() - this.flow.pingAt;
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
      if (msg.manifest) storeManifest(this.url, sub.material, msg.etag, msg.manifest);
      if (!sub.manifest || !msg.resumed) {
        // left out when resumed with "manifest_kept": the one kept with the chunks
        sub.manifest = msg.manifest || (msg.resumed && sub.keptManifest) || null;
        sub.keptManifest = null;
        if (!sub.manifest) { // a server that left out a manifest this page does not hold
          sub.error = {code: 'bad_manifest', message: `the manifest of ${sub.material} did not come`};
          return sub.emit('onError', sub.error);
        }
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
      if (msg.code === 'unknown_type' && !msg.material && this.flow && !this.flow.refused) { // a btfd without "ack"
        this.flow.refused = true;
        return;
      }
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
    if (this.http) return {...this.http.stats(), url: this.url, fallback: this.http.url, bytes: this.bytes};
    return {url: this.url, transport: 'ws', open: this.open, bytes: this.bytes, frames: this.frames, connects: this.connects,
            attempts: this.attempts, pieces: this.pieces,
            flow: this.flow ? {window: this.flow.window, rtt: this.flow.rtt, received: this.flow.received} : null,
            subscriptions: [...this.subs.values()].map((s) => ({material: s.material, received: s.received,
              cached: s.cached,
              bytes: s.bytes, limit: s.limit, complete: s.complete, listeners: s.listeners.size,
              arrivedAt: s.arrivedAt,
              budget: s.budget()}))};
  }
}
