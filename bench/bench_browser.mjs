// bench/bench_browser.mjs - frame time of the viewer's renderer against the thesis
// shader in headless Chromium (SwiftShader WebGL2), 1280x720, C = 8 (the viewer on the
// plane: the light blended once per draw, btf-fixed.js; `runtime`: the run-time light
// path of curved meshes), one page, one
// context, interleaved (the page half: bench/browser/shader.js). Run by
// bench/bench_browser.sh (bench/run.sh); stdout: `name value unit` lines.
// Package: generated knit 64x64 at UBO2003's 81 x 81 directions, k = 3, 16 components,
// 8-bit textures, version 1 (--plain): the package of bench/bench_shader.c.
import {spawnSync} from 'node:child_process';
import fs from 'node:fs';
import http from 'node:http';
import os from 'node:os';
import path from 'node:path';
import {BTF, ROOT, launch, newPage} from '../tests/e2e/util.mjs';

const C = 8;
const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'btf-bench-browser-'));
const pkgDir = path.join(dir, 'knit');
const r = spawnSync(BTF, ['compress', 'gen:knit:64', pkgDir, '--k', '3', '--components', '16', '--bits', '8', '--plain',
  '--quiet']);
if (r.status !== 0) throw new Error(`btf compress failed: ${r.stderr}`);
const types = {'.js': 'text/javascript', '.json': 'application/json', '.png': 'image/png', '.html': 'text/html'};
const page = `<!doctype html><html><head><meta charset="utf-8"><link rel="icon" href="data:,"></head><body>
<script type="module">import {run} from '/bench/browser/shader.js';
run(${C}).then((r) => { window.__result = r; }, (e) => { window.__result = {error: String(e && e.stack || e)}; });
</script></body></html>`;
const srv = http.createServer((req, res) => {
  const u = decodeURIComponent(new URL(req.url, 'http://x').pathname);
  if (u === '/bench.html') return res.writeHead(200, {'content-type': 'text/html'}).end(page);
  const file = u.startsWith('/pkg/') ? path.join(pkgDir, u.slice(5)) : path.join(ROOT, u);
  const ok = /^\/(client|shaders|bench\/browser|pkg)\//.test(u) && !u.includes('..') && fs.existsSync(file);
  if (!ok) return res.writeHead(404).end();
  res.writeHead(200, {'content-type': types[path.extname(file)] || 'application/octet-stream'});
  res.end(fs.readFileSync(file));
});
await new Promise((ok) => srv.listen(0, '127.0.0.1', ok));
const ctx = await launch();
try {
  const p = await newPage(ctx);
  await p.setViewportSize({width: 1300, height: 760});
  await p.goto(`http://127.0.0.1:${srv.address().port}/bench.html`);
  await p.waitForFunction(() => window.__result, null, {timeout: 600000, polling: 500});
  const res = await p.evaluate(() => window.__result);
  if (res.error) throw new Error(res.error);
  console.log(`browser_renderer ${JSON.stringify(res.renderer)} name`);
  console.log(`browser_viewer_C${C}_ms ${res.viewer.toFixed(1)} ms`);
  console.log(`browser_nearest_C${C}_ms ${res.nearest.toFixed(1)} ms`);
  console.log(`browser_thesis_C${C}_ms ${res.thesis.toFixed(1)} ms`);
  console.log(`browser_thesis_over_viewer_C${C}_ratio ${(res.thesis / res.viewer).toFixed(3)} x`);
  console.log(`browser_thesis_over_nearest_C${C}_ratio ${(res.thesis / res.nearest).toFixed(3)} x`);
  console.log(`browser_fixed_light_used ${res.fixed ? 1 : 0} bool`);
  console.log(`browser_runtime_nearest_C${C}_ms ${res.runtime.toFixed(1)} ms`);
  console.log(`browser_thesis_over_runtime_nearest_C${C}_ratio ${(res.thesis / res.runtime).toFixed(3)} x`);
} finally {
  await ctx.close();
  srv.close();
  fs.rmSync(dir, {recursive: true, force: true});
}
