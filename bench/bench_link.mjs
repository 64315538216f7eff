// bench/bench_link.mjs - the browser viewer through a slow link (run by bench/bench_link.sh,
// which bench/run.sh runs; stdout: `name value unit` lines). One <btf-viewer> on a page of
// another origin (a node http server), its script, shaders and stream from btfd through the
// throttling proxy of tests/e2e/throttle.mjs (one token bucket per direction, fixed one-way
// delay 20 ms = 40 ms RTT) at 1, 4 and 16 Mbit/s: time to first frame and to complete (ms
// from navigation start), link utilisation over the whole load (bytes over the link / (rate
// x first byte to last chunk byte)) and over the stream alone (its WebSocket connection, timed at the link).
// Package: `btf gen knit --size 32`, 16 components (16 chunks, about 1 MB), whole package.
// Chromium with SwiftShader (software GL): the frames after the last byte cost CPU time.
import {launch, makeLibrary, servePages, startServer} from '../tests/e2e/util.mjs';
import {measureLink} from '../tests/e2e/throttle.mjs';

const lib = makeLibrary({wide: ['knit', 16]});
const server = await startServer(lib.lib);
const page = (port) => `<!doctype html><html><head><meta charset="utf-8"><link rel="icon" href="data:,">
<script type="module" src="http://127.0.0.1:${port}/btf-viewer.js"></script></head>
<body><btf-viewer material="wide" light="fixed" budget-chunks="1000" max-dpr="1"
style="width:300px;height:300px"></btf-viewer></body></html>`;
const pages = await servePages({slow: (req) => page(new URL(req.url, 'http://x').searchParams.get('link'))});
const ctx = await launch();
try {
  for (const mbit of [1, 4, 16]) {
    const r = await measureLink(ctx, {btfdPort: server.port, pagesUrl: pages.url, page: 'slow', bps: mbit * 1e6,
      delayMs: 20});
    const n = `link_${mbit}mbit`;
    console.log(`${n}_first_frame ${r.firstFrameMs.toFixed(0)} ms`);
    console.log(`${n}_complete ${r.completeMs.toFixed(0)} ms`);
    console.log(`${n}_bytes ${r.bytes} bytes`);
    console.log(`${n}_utilisation ${(100 * r.utilisation).toFixed(1)} %`);
    console.log(`${n}_stream_utilisation ${(100 * r.streamUtilisation).toFixed(1)} %`);
  }
  if (ctx.problems.length) throw new Error(ctx.problems.join('\n'));
} finally {
  await ctx.close();
  await pages.close();
  await server.stop();
  lib.remove();
}
