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
// Chromium with SwiftShader (software GL): GPU work costs CPU time.
import path from 'node:path';
import {BUILD, launch, makeLibrary, newPage, servePages, startServer} from '../tests/e2e/util.mjs';
import {startThrottle, visit} from '../tests/e2e/throttle.mjs';

const CLIENT = process.env.BTF_CLIENT || path.join(BUILD, 'client');
const lib = makeLibrary({knit: ['knit', 24, 2]}, {thumbnails: true});
const server = await startServer(lib.lib, ['--client', CLIENT]);
const page = (port) => `<!doctype html><html><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1"><link rel="icon" href="data:,">
<script type="module" src="http://127.0.0.1:${port}/btf-viewer.js"></script></head>
<body><btf-viewer material="knit" geometry="sphere" camera-controls alt="Knitted wool"
style="display:inline-block;width:320px;height:320px"></btf-viewer></body></html>`;
const pages = await servePages({slow: (req) => page(new URL(req.url, 'http://x').searchParams.get('link'))});
const f = (x) => (Number.isFinite(x) ? x.toFixed(0) : 'nan');
try {
  for (const mbit of [1, 4, 16]) {
    const ctx = await launch({viewport: {width: 390, height: 700}, deviceScaleFactor: 2, isMobile: true,
      hasTouch: true});
    const link = await startThrottle({target: server.port, bps: mbit * 1e6, delayMs: 20});
    try {
      const p = await newPage(ctx);
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
} finally {
  await pages.close();
  await server.stop();
  lib.remove();
}
