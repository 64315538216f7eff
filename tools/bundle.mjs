// tools/bundle.mjs - the viewer as one file: esbuild bundles client/btf-viewer.js and its
// modules (and the decode worker; the model code as one chunk it loads on demand) into
// OUT/, minified, with the shader files of the
// programs "render" and "flat" (a model's unbound parts) inside (client/btf-shader-pack.js
// is replaced by them), so a page gets
// the element and its shaders in one request. The demo pages (client/pages/) are copied
// beside it, to the root btfd serves (their `import '../btf-viewer.js'` resolves to
// /btf-viewer.js there, the bundle), and every text file gzipped beside it (FILE.gz).
// Run by `make build`:
//   node tools/bundle.mjs OUT        (default build/client)
import fs from 'node:fs';
import path from 'node:path';
import zlib from 'node:zlib';
import * as esbuild from 'esbuild';
import {ROOT, shaderPackPlugin} from './shader-pack.mjs';

const OUT = path.resolve(process.argv[2] || path.join(ROOT, 'build/client'));
const packPlugin = shaderPackPlugin(['render', 'flat']);

const tmp = `${OUT}.tmp-${process.pid}`;
fs.rmSync(tmp, {recursive: true, force: true});
const common = {bundle: true, format: 'esm', minify: true, target: 'es2020', outdir: tmp, legalComments: 'none',
  logLevel: 'warning'};
// the element: one file, except the model code (btf-model.js, btf-gltf.js), which it
// imports on demand and which imports nothing of it: one chunk beside it, fetched by
// pages with a model only
await esbuild.build({...common, entryPoints: [path.join(ROOT, 'client/btf-viewer.js')], splitting: true,
  chunkNames: '[name]-[hash]', plugins: [packPlugin]});
const chunks = fs.readdirSync(tmp).filter((f) => f !== 'btf-viewer.js');
if (chunks.length !== 1 || /\bimport\s*[{"'*]|\bfrom\s*["']/.test(fs.readFileSync(path.join(tmp, chunks[0]), 'utf8')))
  throw new Error(`bundle: expected btf-viewer.js and one model chunk importing nothing, got ${chunks.join(', ')}`);
await esbuild.build({...common, entryPoints: [path.join(ROOT, 'client/btf-decode-worker.js')]});
for (const f of fs.readdirSync(path.join(ROOT, 'client/pages')))
  fs.copyFileSync(path.join(ROOT, 'client/pages', f), path.join(tmp, f));
// FILE.gz beside each text file it shrinks (btfd and nginx's gzip_static send it to a
// browser that accepts gzip: the bundle crosses a phone's link at about a third of its bytes)
for (const f of fs.readdirSync(tmp).filter((x) => /\.(js|html|css|json)$/.test(x))) {
  const src = fs.readFileSync(path.join(tmp, f)), gz = zlib.gzipSync(src, {level: 9});
  if (gz.length < src.length) fs.writeFileSync(path.join(tmp, `${f}.gz`), gz);
}
// replace OUT whole (a directory rename; the old one removed after)
const old = `${OUT}.old-${process.pid}`;
if (fs.existsSync(OUT)) fs.renameSync(OUT, old);
fs.renameSync(tmp, OUT);
fs.rmSync(old, {recursive: true, force: true});
const size = (f) => fs.statSync(path.join(OUT, f)).size;
console.log(`bundle: ${path.relative(ROOT, OUT)}/btf-viewer.js ${size('btf-viewer.js')} bytes (shaders inside), ` +
  `${size('btf-viewer.js.gz')} gzipped, btf-decode-worker.js ${size('btf-decode-worker.js')} bytes, ` +
  `${chunks[0]} ${size(chunks[0])} bytes (models)`);
