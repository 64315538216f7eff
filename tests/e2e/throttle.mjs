// throttle.mjs - a slow link for the tests and bench/bench_client.mjs: a TCP proxy on a
// loopback port in front of another loopback port. Each direction is a token bucket
// at `bps` bits per second (burst: one piece) plus a fixed one-way `delayMs`, delivered
// in pieces of at most 4 KiB; a direction with more than `queue` bytes waiting stops
// reading its source (the bottleneck's buffer), so the sender sees the link's rate.
import net from 'node:net';

const PIECE = 4096;

// One direction src -> dst of one connection through the bucket of the link's direction
// (`lane`, shared by every connection: the browser opens several): a FIFO of pieces, each
// with the time it leaves the link, delivered in order by one timer.
function pipe(src, dst, {bps, delayMs, queue}, lane, conn) {
  let waiting = 0, timer = null; // bytes not yet delivered
  const fifo = [];
  const deliver = () => {
    timer = null;
    const now = performance.now();
    while (fifo.length && fifo[0].at <= now) {
      const {piece} = fifo.shift();
      waiting -= piece.length;
      if (!dst.destroyed) dst.write(piece);
      for (const stats of [lane, conn]) {
        stats.bytes += piece.length;
        stats.last = now;
        stats.first ??= now - (piece.length * 8 * 1000) / bps; // when its first bit went out
        stats.pieces?.push([now, piece.length]);
      }
    }
    if (waiting <= queue / 2 && src.isPaused()) src.resume();
    if (fifo.length) timer = setTimeout(deliver, fifo[0].at - now);
    else if (src.ended) dst.end();
  };
  src.on('data', (buf) => {
    for (let off = 0; off < buf.length; off += PIECE) {
      const piece = buf.subarray(off, off + PIECE);
      const start = Math.max(lane.free, performance.now());
      lane.free = start + (piece.length * 8 * 1000) / bps;
      lane.log?.push([start + delayMs, lane.free + delayMs, piece.length]); // when it is on the far side
      fifo.push({piece, at: lane.free + delayMs});
      waiting += piece.length;
    }
    if (waiting > queue) src.pause();
    if (!timer) timer = setTimeout(deliver, fifo[0].at - performance.now());
  });
  src.on('end', () => {
    src.ended = true;
    if (!timer) deliver();
  });
  src.on('error', () => dst.destroy());
}

// Resolves {port, url, down, close()}; target: the loopback port behind it; down: bytes
// delivered towards the client and when the first and last were (ms, performance.now()),
// down.conns the same per connection, down.log every piece's [first bit, last bit, bytes]
// at the far side (linkShare reads it).
export function startThrottle({target, bps = 4e6, delayMs = 20, queue = 64 * 1024}) {
  const sockets = new Set(), down = {bytes: 0, first: null, last: null, free: 0, conns: [], log: []},
    up = {bytes: 0, first: null, last: null, free: 0};
  const srv = net.createServer((client) => {
    const upstream = net.connect(target, '127.0.0.1');
    for (const s of [client, upstream]) {
      sockets.add(s);
      s.on('close', () => sockets.delete(s));
      s.setNoDelay(true);
    }
    // per connection: towards the client, and each piece's delivery both ways ([ms, bytes])
    const conn = {bytes: 0, first: null, last: null, pieces: [], upPieces: []};
    down.conns.push(conn);
    pipe(client, upstream, {bps, delayMs, queue}, up, {bytes: 0, first: null, last: null, pieces: conn.upPieces});
    pipe(upstream, client, {bps, delayMs, queue}, down, conn);
  });
  return new Promise((resolve) => srv.listen(0, '127.0.0.1', () => {
    const port = srv.address().port;
    resolve({
      port, url: `http://127.0.0.1:${port}/`, down,
      // the link goes down: every connection is cut and new ones are refused for ms
      drop: (ms) => new Promise((r) => {
        for (const s of sockets) s.destroy();
        srv.close(() => setTimeout(() => srv.listen(port, '127.0.0.1', r), ms));
      }),
      close: () => new Promise((r) => {
        for (const s of sockets) s.destroy();
        if (srv.listening) srv.close(r);
        else r();
      }),
    });
  }));
}

// The link's busy share while it carried the last `bytes` bytes it delivered towards the
// client (a page's package, when nothing follows it): those bytes' link time over the time
// from the first bit of the piece where they begin to the last bit of the last piece. 1 is a
// link that never idled meanwhile; it idles while nothing was asked for or sent.
export function linkShare(down, bytes, bps) {
  const log = down.log;
  let n = 0, i = log.length;
  while (i > 0 && n < bytes) n += log[--i][2];
  if (!n) return NaN;
  return (n * 8 * 1000) / bps / (log[log.length - 1][1] - log[i][0]);
}

// Records cumulative layout shift (entries without recent input) in window.__cls; for addInitScript.
export function clsRecorder() {
  window.__cls = 0;
  new PerformanceObserver((list) => {
    for (const e of list.getEntries()) if (!e.hadRecentInput) window.__cls += e.value;
  }).observe({type: 'layout-shift', buffered: true});
}

// One visit of `url` until viewer 0 has drawn its whole budget and the GPU has passed
// that frame (timeout ms): what the page showed and when, in ms from navigation start:
// {firstFrame, firstChunk (the first chunk's last byte arrived), lastChunk, complete,
// scriptRequest (when the page asked for btf-viewer.js), scriptBytes ([its body over the link, decoded]), chunksAtFirstFrame,
// times (the viewer's loading sequence, doc/client.md), streamBytes (chunk payload over the WebSocket), cls, error}.
// A phone's browser already runs its GPU process (it composites with it); a headless
// Chromium launched for one visit starts it at the page's first WebGL context, which then
// blocks that page's main thread for 0.24-1.1 s on this 2-core host (a second context:
// 11-108 ms), delaying every message of the stream by as much, and the stream itself
// once its flow-control window (256 KiB before the rate is known) waits for acks. One context on a blank
// page first (no request: the HTTP cache stays empty), so a timed visit times the page
// and not the browser's start.
export async function warmGpu(page) {
  await page.setContent('<canvas></canvas>');
  const ok = await page.evaluate(() => !!document.querySelector('canvas').getContext('webgl2'));
  if (!ok) throw new Error('no WebGL2 context in this browser');
}

export async function visit(page, url, timeout = 120000) {
  await page.goto(url);
  const t0 = Date.now();
  for (;;) {
    const done = await page.evaluate(() => {
      const v = window.__btf?.viewers()[0];
      const last = (xs) => (xs && xs.length ? xs[xs.length - 1][0] : -1);
      return v && v.complete && v.drawnChunks === v.ownLimit && v.frames > 0 &&
        last(v.times.shown) === last(v.times.drawn);
    });
    if (done) break;
    if (Date.now() - t0 > timeout) {
      const st = await page.evaluate(() => window.__btf?.viewers()).catch(() => null);
      throw new Error(`the page did not complete in ${timeout} ms: ${JSON.stringify(st)}`);
    }
    await new Promise((r) => setTimeout(r, 50));
  }
  return page.evaluate(() => {
    const v = window.__btf.viewers()[0], s = window.__btf.streams()[0], sub = s.subscriptions[0];
    const script = performance.getEntriesByType('resource').find((e) => /\/btf-viewer\.js$/.test(e.name));
    const arrived = sub.arrivedAt || []; // a client without per-chunk times: its first and last piece
    return {firstFrame: v.firstFrameAt, firstChunk: arrived[0] ?? s.pieces.first, complete: v.completeAt,
      scriptRequest: script ? script.startTime : 0,
      scriptBytes: script ? [script.encodedBodySize, script.decodedBodySize] : [0, 0],
      lastChunk: arrived.length ? Math.max(...arrived.filter(Number.isFinite)) : s.pieces.last,
      chunksAtFirstFrame: v.firstFrameChunks, chunks: v.drawnChunks, times: v.times, streamBytes: v.streamBytes,
      cached: sub.cached, cls: window.__cls ?? null, error: v.error, decoder: v.decoder, poster: v.posterShown};
  });
}

// The page `pageName` of pagesUrl (given ?link=PORT: its script, shaders and stream come
// from btfd through a throttled link) until its first viewer has drawn its whole budget.
// Resolves {firstFrameMs, completeMs (from navigation start), bytes (over the link, towards
// the browser), utilisation: bytes / (link rate x time from the first byte to the last
// chunk byte), i.e. the share of the link the viewer used while loading; streamUtilisation:
// the same over the stream's connection alone (the one that carried the most bytes: the
// WebSocket), timed at the link from the first byte btfd sent after the page's first
// message reached it to the last byte, so a browser main thread busy drawing while pieces
// arrive, or setting up WebGL when the socket opened, does not count as link time;
// streamFromOpen: the same from the handshake's answer}.
export async function measureLink(ctx, {btfdPort, pagesUrl, page: pageName, bps, delayMs}) {
  const link = await startThrottle({target: btfdPort, bps, delayMs});
  try {
    const page = ctx.pages()[0] || await ctx.newPage();
    await warmGpu(page); // as a phone's browser is (a cold one holds the page's acks back)
    await page.goto(`${pagesUrl}${pageName}.html?link=${link.port}`);
    const t0 = Date.now();
    for (;;) {
      const done = await page.evaluate(() => window.__btf?.viewers()[0]?.complete &&
        window.__btf.viewers()[0].drawnChunks === window.__btf.viewers()[0].ownLimit);
      if (done) break;
      if (Date.now() - t0 > 120000) throw new Error('the throttled stream did not complete in 120 s');
      await new Promise((r) => setTimeout(r, 50));
    }
    const r = await page.evaluate(() => {
      const v = window.__btf.viewers()[0];
      return {firstFrameMs: v.firstFrameAt, completeMs: v.completeAt};
    });
    const d = link.down, ws = d.conns.reduce((a, c) => (c.bytes > a.bytes ? c : a));
    // the stream from when the page's first message (ack, ping, subscribe: sent when the
    // socket opened, after the handshake's answer) reached btfd: how long the page took
    // to handle the open event (its main thread held by WebGL set-up) is the page's time
    const asked = ws.upPieces.find(([t]) => t > ws.pieces[0][0])?.[0] ?? ws.first;
    const after = ws.pieces.filter(([t]) => t > asked), bytes = after.reduce((a, [, n]) => a + n, 0);
    const start = after.length ? after[0][0] - (after[0][1] * 8 * 1000) / bps : ws.first;
    const stream = (bytes * 8 * 1000) / (ws.last - start);
    return {firstFrameMs: r.firstFrameMs, completeMs: r.completeMs, bytes: d.bytes,
            utilisation: (d.bytes * 8 * 1000) / (d.last - d.first) / bps, streamUtilisation: stream / bps,
            streamFromOpen: (ws.bytes * 8 * 1000) / (ws.last - ws.first) / bps};
  } finally {
    await link.close();
  }
}
