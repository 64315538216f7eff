// npm.test.mjs - the npm package (package.json, tools/npm-dist.mjs, types/): its version is
// the project's (BTF_VERSION); `npm pack` into a temp folder; a fresh project installs the
// tarball and three offline (from npm's cache); examples/three served from that project
// draws a package of a btfd in <btf-viewer> (import 'btf-stream') and on a three.js sphere
// (import 'btf-stream/three'), with the shaders from inside the package; `tsc --noEmit`
// checks a .ts file against the installed types; and the tarball holds dist/ and types/
// only. Run: node --test tests/e2e/npm.test.mjs
import assert from 'node:assert/strict';
import {spawnSync} from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import {after, before, describe, it} from 'node:test';
import {ROOT, assertClean, launch, makeLibrary, newPage, requireBuild, startServer, waitFor} from './util.mjs';
import {serveTree} from './three-page.mjs';

const NPM = process.env.NPM || 'npm';
let tmp, project, tarball, lib, server, site, browser;

function npm(args, cwd) {
  const r = spawnSync(NPM, args, {cwd, encoding: 'utf8', timeout: 300000,
    env: {...process.env, npm_config_audit: 'false', npm_config_fund: 'false', npm_config_update_notifier: 'false'}});
  assert.equal(r.status, 0, `npm ${args.join(' ')} failed (${r.status}): ${r.stderr || r.error}`);
  return r.stdout;
}

function projectVersion() {
  return /#define BTF_VERSION "([^"]+)"/.exec(fs.readFileSync(path.join(ROOT, 'codec/include/btf_version.h'), 'utf8'))[1];
}

before(async () => {
  requireBuild();
  tmp = fs.mkdtempSync(path.join(os.tmpdir(), 'btf-npm-'));
  lib = makeLibrary({knit: ['knit', 4]});
  server = await startServer(lib.lib);
});

after(async () => {
  await browser?.close();
  await site?.close();
  await server?.stop();
  lib?.remove();
  if (tmp) fs.rmSync(tmp, {recursive: true, force: true});
});

describe('the npm package', () => {
  it('is named btf-stream, versioned BTF_VERSION, with exports, types, files and three as an optional peer', () => {
    const pkg = JSON.parse(fs.readFileSync(path.join(ROOT, 'package.json'), 'utf8'));
    assert.equal(pkg.name, 'btf-stream');
    assert.equal(pkg.private, undefined);
    assert.equal(pkg.version, projectVersion(), 'package.json version = BTF_VERSION of codec/include/btf_version.h');
    assert.deepEqual(Object.keys(pkg.exports), ['.', './stream', './three', './package.json']);
    assert.deepEqual(pkg.files, ['dist/', 'types/']);
    assert.ok(pkg.peerDependencies.three && pkg.peerDependenciesMeta.three.optional);
    assert.ok(pkg.devDependencies.three && pkg.devDependencies['@types/three']);
    assert.equal(pkg.dependencies, undefined, 'nothing at run time');
  });

  it('packs dist/ and types/ only, and installs offline into a fresh project', () => {
    const out = JSON.parse(npm(['pack', '--json', '--pack-destination', tmp], ROOT));
    tarball = path.join(tmp, out[0].filename);
    const files = out[0].files.map((f) => f.path).sort();
    console.log(`# ${out[0].filename}: ${files.length} files, ${out[0].size} bytes packed, ${out[0].unpackedSize} unpacked`);
    for (const f of files) assert.match(f, /^(dist\/[a-z0-9-]+\.js|types\/[a-z0-9-]+\.d\.ts|package\.json|README\.md|LICENSE)$/i, f);
    for (const f of ['dist/btf-viewer.js', 'dist/btf-stream.js', 'dist/three.js', 'dist/btf-decode-worker.js',
      'types/btf-viewer.d.ts', 'types/btf-stream.d.ts', 'types/three.d.ts']) assert.ok(files.includes(f), f);
    // three stays an import (a peer), never bundled in
    const dist = fs.mkdtempSync(path.join(tmp, 'x-'));
    spawnSync('tar', ['-xzf', tarball, '-C', dist]);
    const three = fs.readFileSync(path.join(dist, 'package/dist/three.js'), 'utf8');
    assert.match(three, /from "three"/);
    assert.ok(!/class WebGLRenderer/.test(fs.readdirSync(path.join(dist, 'package/dist'))
      .map((f) => fs.readFileSync(path.join(dist, 'package/dist', f), 'utf8')).join('')), 'three.js is not inside');
    // a fresh project: examples/three, the tarball and three (+ its types) from npm's cache
    project = path.join(tmp, 'project');
    fs.mkdirSync(project);
    for (const f of ['index.html', 'main.js']) fs.copyFileSync(path.join(ROOT, 'examples/three', f), path.join(project, f));
    fs.writeFileSync(path.join(project, 'package.json'), JSON.stringify({name: 'page', private: true, type: 'module'}));
    npm(['install', '--prefer-offline', '--no-audit', '--no-fund', tarball, 'three@^0.187.0', '@types/three@^0.187.0'], project);
    const installed = JSON.parse(fs.readFileSync(path.join(project, 'node_modules/btf-stream/package.json'), 'utf8'));
    assert.equal(installed.version, projectVersion());
  });

  it('tsc --noEmit: a TypeScript page of the element, the stream and BTFMaterial against the installed types', () => {
    assert.ok(project, 'installed');
    fs.writeFileSync(path.join(project, 'use.ts'), `import * as THREE from 'three';
import {BtfViewer, autoBudget, type BtfLighting, type BtfProgress} from 'btf-stream';
import {BtfStream, type BtfListener} from 'btf-stream/stream';
import {BTFMaterial} from 'btf-stream/three';
const v = document.createElement('btf-viewer');
const same: BtfViewer = v;
v.material = 'knit';
v.exposure = 1.2;
v.cameraControls = true;
v.addEventListener('progress', (e) => console.log(e.detail.chunks, e.detail.bytesWanted));
v.addEventListener('error', (e) => console.log(e.detail.reason, e.detail.retrying));
v.addEventListener('camera-change', (e) => console.log(e.detail.theta));
const l: BtfLighting = v.lighting;
console.log(l.environment.state, l.toneMapping, autoBudget(300), same.lighting.point.on);
BtfViewer.budgetPolicy = () => -1;
const listener: BtfListener = {budget: () => ({chunks: 2}), onChunk: (sub, j) => console.log(sub.material, j, sub.chunks[j]?.length)};
const sub = BtfStream.for('wss://btf.example.org/stream').subscribe('knit', listener);
sub.stream.unsubscribe(sub, listener);
const mat = new BTFMaterial({src: 'wss://btf.example.org/stream', material: 'knit', light: new THREE.Vector3(1, 1, 1),
  environment: 'studio', toneMapping: 'aces', repeat: [2, 1], up: 'y'});
mat.addEventListener('progress', (e) => { const p: BtfProgress = e; console.log(p.chunks); });
mat.setLighting({exposure: 2});
mat.setBudget({budgetChunks: 4});
console.log(new THREE.Mesh(new THREE.SphereGeometry(1, 64, 32), mat), mat.lighting.environment.on, mat.progress.chunks);
// @ts-expect-error: src and material are required
new BTFMaterial({});
// @ts-expect-error: not a tone mapping
mat.setLighting({toneMapping: 'filmic'});
// @ts-expect-error: a number property
v.exposure = 'bright';
`);
    fs.writeFileSync(path.join(project, 'tsconfig.json'), JSON.stringify({compilerOptions: {target: 'es2020',
      module: 'nodenext', moduleResolution: 'nodenext', strict: true, noEmit: true, lib: ['es2020', 'dom'],
      skipLibCheck: false}, files: ['use.ts']}));
    const r = spawnSync(path.join(ROOT, 'node_modules/.bin/tsc'), ['-p', project], {encoding: 'utf8', timeout: 300000});
    assert.equal(r.status, 0, `tsc: ${r.stdout}${r.stderr}`);
  });

  it('a page of the installed project draws the element and a three.js sphere from a btfd', async () => {
    assert.ok(project, 'installed');
    site = await serveTree({}, {'/': project});
    browser = await launch();
    const page = await newPage(browser);
    await page.setViewportSize({width: 800, height: 500});
    await page.goto(`${site.url}index.html?src=${encodeURIComponent(server.ws)}&material=knit`);
    await waitFor(page, () => window.__example && window.__example.viewerState().drawnChunks === 4 &&
      window.__example.state().drawnChunks === 4, null, 'both drawn');
    const c = await page.evaluate(() => window.__example.capture());
    const st = await page.evaluate(() => window.__example.state());
    assert.ok(c.lit > 0.25 * c.width * c.height, `the sphere covers ${c.lit} of ${c.width * c.height} pixels`);
    assert.equal(st.error, null);
    assert.equal(st.lighting.environment.state, 'ready');
    // the shaders came from inside the package: no request for a shader file
    const shaderRequests = await page.evaluate(() => performance.getEntriesByType('resource')
      .map((e) => e.name).filter((n) => /\.(glsl|vert|frag)$|manifest\.json$/.test(n)));
    assert.deepEqual(shaderRequests, []);
    assertClean(browser);
  });
});
