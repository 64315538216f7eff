// tools/npm-dist.mjs - the npm package's dist/ (package.json "files", run by `npm pack` and
// `npm publish` as the prepack script): the client's modules bundled by esbuild as ES
// modules, not minified (the page's own build minifies), three.js left as an import:
//   dist/btf-viewer.js        registers <btf-viewer> (exports BtfViewer, autoBudget)
//   dist/btf-stream.js        the stream of a btfd or a published library (BtfStream)
//   dist/three.js             BTFMaterial (client/three/btf-material.js), imports 'three'
//   dist/btf-decode-worker.js the decode worker btf-decode.js starts beside itself
//   dist/chunk-*.js           what they share (one stream per server and page for all of them)
// with the shader files of the programs render, flat and three inside (client/btf-shader-pack.js
// replaced), so the installed package needs no shaders/ folder and survives a bundler that
// moves its files. Refuses to run when package.json's version is not BTF_VERSION of
// codec/include/btf_version.h (the one project version).
//   node tools/npm-dist.mjs [OUT]        (default dist)
import fs from 'node:fs';
import path from 'node:path';
import * as esbuild from 'esbuild';
import {ROOT, shaderPackPlugin} from './shader-pack.mjs';

export function projectVersion() {
  const h = fs.readFileSync(path.join(ROOT, 'codec/include/btf_version.h'), 'utf8');
  const m = /#define BTF_VERSION "([^"]+)"/.exec(h);
  if (!m) throw new Error('codec/include/btf_version.h has no BTF_VERSION');
  return m[1];
}

const pkg = JSON.parse(fs.readFileSync(path.join(ROOT, 'package.json'), 'utf8'));
if (pkg.version !== projectVersion())
  throw new Error(`package.json version ${pkg.version} is not BTF_VERSION ${projectVersion()} (codec/include/btf_version.h)`);

const OUT = path.resolve(ROOT, process.argv[2] || 'dist');
const tmp = `${OUT}.tmp-${process.pid}`;
fs.rmSync(tmp, {recursive: true, force: true});
const common = {bundle: true, format: 'esm', target: 'es2020', outdir: tmp, legalComments: 'none', logLevel: 'warning',
  external: ['three'], plugins: [shaderPackPlugin(['render', 'flat', 'three'])]};
await esbuild.build({...common, splitting: true, chunkNames: 'chunk-[hash]',
  entryPoints: {'btf-viewer': path.join(ROOT, 'client/btf-viewer.js'), 'btf-stream': path.join(ROOT, 'client/btf-stream.js'),
    three: path.join(ROOT, 'client/three/btf-material.js')}});
await esbuild.build({...common, entryPoints: {'btf-decode-worker': path.join(ROOT, 'client/btf-decode-worker.js')}});
fs.rmSync(OUT, {recursive: true, force: true});
fs.renameSync(tmp, OUT);
const files = fs.readdirSync(OUT);
console.error(`npm-dist: ${path.relative(ROOT, OUT)}/ ${files.length} files, ` +
  `${files.reduce((a, f) => a + fs.statSync(path.join(OUT, f)).size, 0)} bytes`);
