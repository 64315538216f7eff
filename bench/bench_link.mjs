// bench/bench_link.mjs - the README embed through a slow link (run by bench/bench_link.sh,
// which bench/run.sh runs; stdout: `name value unit` lines). The README's two lines on a
// page of another origin (a node http server) on an emulated phone (390 x 700, device
// pixel ratio 2), the script (BTF_CLIENT: btfd's --client folder, default the bundle
// BUILD/client), its shaders and stream from btfd through the throttling proxy of
// tests/e2e/throttle.mjs (fixed one-way delay 20 ms = 40 ms RTT) at 1, 4 and 16 Mbit/s,
// a fresh browser profile per rate. Package: `btf gen knit --size 32`, 24 components at
// 2 spatial levels (the phone's footprint needs 28 chunks, about 840 KB).
// Per rate: the first frame (ms from navigation start, and the chunks it showed), the
// first chunk's arrival, completion, the link time of the streamed bytes, and the
// loading sequence broken down (the viewer's `times`, doc/client.md "Loading"; for a
// client without them, the script and shader files' resource timings).
// Then the two transports side by side at 4 Mbit/s and 40 ms (STATIC_RUNS fresh visits each,
// default 3): the library from a static host (`btf library publish` into an nginx root that
// adds only Access-Control-Allow-Origin: *, the page's `src` its URL: client/btf-http.js)
// against btfd's WebSocket, the page on a second origin in both: `static_*` and `ws_*` lines,
// the first frame (ms, chunks drawn) and the package's link utilisation, measured at the link
// (throttle.mjs linkShare): the link time of the package's bytes over the time the link took
// to carry the last that many bytes it delivered (goals: at most 2 chunks at the first frame,
// a utilisation of at least 0.9).
// Chromium with SwiftShader (software GL): GPU work costs CPU time.
import {spawnSync} from 'node:child_process';
import path from 'node:path';
import {BTF, BUILD, freePort, launch, makeLibrary, newPage, servePages, startNginx, startServer}
  from '../tests/e2e/util.mjs';
import {linkShare, startThrottle, visit, warmGpu} from '../tests/e2e/throttle.mjs';

const CLIENT = process.env.BTF_CLIENT || path.join(BUILD, 'client');
const lib = makeLibrary({knit: ['knit', 24, 2]}, {thumbnails: true});
const server = await startServer(lib.lib, ['--client', CLIENT]);
const page = (port, src = false) => `<!doctype html><html><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1"><link rel="icon" href="data:,">
<script type="module" src="http://127.0.0.1:${port}/btf-viewer.js"></script></head>
<body><btf-viewer ${src ? `src="http://127.0.0.1:${port}/" ` : ''}material="knit" geometry="sphere" camera-controls alt="Knitted wool"
style="display:inline-block;width:320px;height:320px"></btf-viewer></body></html>`;
const pages = await servePages({slow: (req) => page(new URL(req.url, 'http://x').searchParams.get('link')),
  static: (req) => page(new URL(req.url, 'http://x').searchParams.get('link'), true)});
const f = (x) => (Number.isFinite(x) ? x.toFixed(0) : 'nan');
try {
  for (const mbit of [1, 4, 16]) {
    const ctx = await launch({viewport: {width: 390, height: 700}, deviceScaleFactor: 2, isMobile: true,
      hasTouch: true});
    const link = await startThrottle({target: server.port, bps: mbit * 1e6, delayMs: 20});
    try {
      const p = await newPage(ctx);
      await warmGpu(p);
      const r = await visit(p, `${pages.url}slow.html?link=${link.port}`);
      const res = await p.evaluate(() => performance.getEntriesByType('resource').map((e) => [e.name, e.responseEnd]));
      const t = r.times || {};
      t.script ??= Math.max(...res.filter(([n]) => n.endsWith('.js')).map(([, e]) => e));
      const shaderEnds = res.filter(([n]) => n.includes('/shaders/')).map(([, e]) => e);
      t.shaders ??= shaderEnds.length ? Math.max(...shaderEnds) : NaN;
      const n = `link_${mbit}mbit`;
      const lines = [[`${n}_first_frame`, f(r.firstFrame), 'ms'], [`${n}_first_frame_chunks`, r.chunksAtFirstFrame, 'chunks'],
        [`${n}_first_chunk`, f(r.firstChunk), 'ms'], [`${n}_load_after_first_chunk`, f(r.firstFrame - r.firstChunk), 'ms'],
        [`${n}_complete`, f(r.complete), 'ms'], [`${n}_chunks`, r.chunks, 'chunks'], [`${n}_stream_bytes`, r.streamBytes, 'bytes'],
        [`${n}_link_time`, f((r.streamBytes * 8 * 1000) / (mbit * 1e6)), 'ms']];
      for (const k of ['script', 'start', 'open', 'shaders', 'manifest', 'gl', 'chunk', 'decoded', 'program'])
        lines.push([`${n}_at_${k}`, f(t[k]), 'ms']);
      for (const l of lines) console.log(l.join(' '));
      if (ctx.problems.length) throw new Error(ctx.problems.join('\n'));
    } finally {
      await ctx.close();
      await link.close();
    }
  }
  await sideBySide();
} finally {
  await pages.close();
  await server.stop();
  lib.remove();
}

// One fresh phone visit of pages/NAME.html through a 4 Mbit/s, 40 ms link to `target`.
async function phoneVisit(name, target, bps) {
  const ctx = await launch({viewport: {width: 390, height: 700}, deviceScaleFactor: 2, isMobile: true, hasTouch: true});
  const link = await startThrottle({target, bps, delayMs: 20});
  try {
    const p = await newPage(ctx);
    await warmGpu(p);
    const r = await visit(p, `${pages.url}${name}.html?link=${link.port}`);
    r.transport = (await p.evaluate(() => window.__btf.streams()[0].transport));
    r.utilisation = linkShare(link.down, r.streamBytes, bps);
    if (ctx.problems.length) throw new Error(ctx.problems.join('\n'));
    return r;
  } finally {
    await ctx.close();
    await link.close();
  }
}

// The static host against btfd's WebSocket, STATIC_RUNS visits each, interleaved.
async function sideBySide() {
  const bps = 4e6, runs = Number(process.env.STATIC_RUNS || 3);
  const out = path.join(lib.dir, 'static');
  const pub = spawnSync(BTF, ['library', 'publish', lib.lib, out, '--client', CLIENT], {encoding: 'utf8'});
  if (pub.status !== 0) throw new Error(`btf library publish: ${pub.stderr}`);
  const nport = await freePort();
  const nginx = await startNginx(out, nport, lib.dir);
  const rows = {static: [], ws: []};
  try {
    for (let i = 0; i < runs; i++) {
      rows.static.push(await phoneVisit('static', nport, bps));
      rows.ws.push(await phoneVisit('slow', server.port, bps));
    }
  } finally {
    await nginx.stop();
  }
  const med = (xs) => [...xs].sort((a, b) => a - b)[Math.floor(xs.length / 2)];
  for (const [name, rs] of Object.entries(rows)) {
    const util = rs.map((r) => r.utilisation);
    rs.forEach((r, i) => console.log(`${name}_4mbit_run${i} first_frame=${f(r.firstFrame)}ms chunks_at_first_frame=` +
      `${r.chunksAtFirstFrame} first_chunk=${f(r.firstChunk)}ms last_chunk=${f(r.lastChunk)}ms complete=${f(r.complete)}ms ` +
      `bytes=${r.streamBytes} utilisation=${util[i].toFixed(3)} transport=${r.transport}`));
    const lines = [[`${name}_4mbit_first_frame`, f(med(rs.map((r) => r.firstFrame))), 'ms'],
      [`${name}_4mbit_first_frame_chunks`, Math.max(...rs.map((r) => r.chunksAtFirstFrame)), 'chunks (most of the runs)'],
      [`${name}_4mbit_complete`, f(med(rs.map((r) => r.complete))), 'ms'],
      [`${name}_4mbit_link_time`, f((rs[0].streamBytes * 8 * 1000) / bps), 'ms'],
      [`${name}_4mbit_utilisation`, med(util).toFixed(3), `(median; runs ${util.map((u) => u.toFixed(3)).join(' ')})`]];
    for (const l of lines) console.log(l.join(' '));
  }
}
