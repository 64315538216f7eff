// lighting.test.mjs - the lighting of <btf-viewer> (doc/lighting.md, doc/client.md
// "Lighting") in headless Chromium: the defaults of `light` and `environment-image`, an
// environment image that fails, light="tilt" under emulated device orientation (with the
// iOS permission asked on a tap) and under the pointer; and the picture against
// `btf render --environment` (the C host, EGL) for the plane and the sphere under the
// studio and a coloured .hdr at two rotations, both lights together, exposure 2 with
// ACES, and a linear-light package. Run: node --test tests/e2e/lighting.test.mjs
import assert from 'node:assert/strict';
import {spawnSync} from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import {after, before, describe, it} from 'node:test';
import {BTF, assertClean, capture, compareCovered as compare, launch, makeLibrary, newPage, readPng, requireBuild, startServer,
  viewers, waitFor} from './util.mjs';
import {writeHdr} from './hdr-writer.mjs';
import {equirectDir} from '../../client/btf-env.js';
import {dir} from '../../client/scene.js';

const MATERIALS = {knit: ['knit', 4], tiles: ['tiles', 3], 'knit-linear': ['knit', 4, 0, ['--linear']],
  'tiles-lod': ['tiles', 6, 3]};
let lib, server, desktop, envDir;

// The coloured environment: a warm sun, a blue sky brighter towards the zenith, a green
// floor, a magenta patch low in the west; 96 x 48 pixels, run-length coded.
function colourEnvironment() {
  const lobe = (d, k, r) => {
    const c = Math.cos(r * Math.PI / 180), t = Math.max(0, (d[0] * k[0] + d[1] * k[1] + d[2] * k[2] - c) / (1 - c));
    return t * t;
  };
  const sun = dir(40, 20), patch = dir(75, 170);
  const W = 96, H = 48, data = new Float32Array(3 * W * H);
  for (let j = 0; j < H; j++)
    for (let i = 0; i < W; i++) {
      const d = equirectDir(i, j, W, H), up = Math.max(0, d[2]), s = lobe(d, sun, 25), p = lobe(d, patch, 30);
      const rgb = d[2] >= 0 ? [0.15 + 0.1 * up + 4 * s + 1.5 * p, 0.2 + 0.2 * up + 3 * s, 0.35 + 0.5 * up + 1.5 * s + 1.5 * p]
        : [0.05 + 1.5 * p, 0.12, 0.04 + 1.5 * p];
      data.set(rgb, 3 * (j * W + i));
    }
  return writeHdr({width: W, height: H, data});
}

before(async () => {
  requireBuild();
  lib = makeLibrary(MATERIALS);
  envDir = path.join(lib.dir, 'env');
  fs.mkdirSync(envDir);
  fs.writeFileSync(path.join(envDir, 'colour.hdr'), colourEnvironment());
  fs.writeFileSync(path.join(envDir, 'broken.hdr'), 'P6\n4 4\n255\n'); // not a Radiance file
  server = await startServer(lib.lib);
  desktop = await launch();
  // environment images on the pages' origin: /env/NAME from envDir (404 for anything else)
  await desktop.route('**/env/*', (route) => {
    const f = path.join(envDir, path.basename(new URL(route.request().url()).pathname));
    if (!fs.existsSync(f)) return route.fulfill({status: 404, body: 'not found'});
    return route.fulfill({status: 200, contentType: 'application/octet-stream', body: fs.readFileSync(f)});
  });
});

after(async () => {
  await desktop?.close();
  await server?.stop();
  lib?.remove();
});

const viewerUrl = (q) => `${server.pagesUrl}viewer.html?max-dpr=1&camera-controls=0&${q}`;

// Opens url; fails with what the page had loaded when the element's modules have not run
// within 20 s (seen once in a full run of the folder: the page without window.__btf).
async function openViewer(page, url) {
  await page.goto(url);
  const t0 = Date.now();
  while (!(await page.evaluate(() => !!window.__btf))) {
    if (Date.now() - t0 > 20000) {
      const st = await page.evaluate(() => ({url: location.href, ready: document.readyState,
        resources: performance.getEntriesByType('resource').map((e) => `${e.name.replace(/^.*\//, '')} ${Math.round(e.responseEnd)}`)}));
      throw new Error(`the viewer's modules did not run: ${JSON.stringify(st)}`);
    }
    await new Promise((r) => setTimeout(r, 100));
  }
}
const lighting = (page) => page.evaluate(() => window.__btf.element(0).lighting);
// every chunk in the budget drawn, and the environment (if any) arrived or failed
const settled = (n) => {
  const v = window.__btf?.viewers()[0], l = window.__btf?.element(0).lighting;
  return v && v.drawnChunks === n && v.frames > 0 && l && !['idle', 'loading'].includes(l.environment.state);
};

describe('lights of <btf-viewer>', () => {
  it('defaults: the studio without `light`, the point light alone with it, both when both are given', async () => {
    const page = await newPage(desktop);
    const base = 'material=knit&geometry=sphere&width=160&height=160&budget-chunks=4';
    const cases = [
      ['', {light: null, point: false, env: 'studio', tone: 'neutral'}],
      ['&light=fixed', {light: 'fixed', point: true, env: null, tone: 'none'}],
      ['&light=fixed&environment-image=studio', {light: 'fixed', point: true, env: 'studio', tone: 'neutral'}],
      ['&environment-image=none&light=none', {light: 'none', point: false, env: null, tone: 'none'}],
      ['&environment-image=studio&tone-mapping=aces&exposure=1.5', {light: null, point: false, env: 'studio', tone: 'aces'}],
    ];
    const shots = [];
    for (const [q, want] of cases) {
      await openViewer(page, viewerUrl(base + q));
      await waitFor(page, settled, 4, `the frame (${q || 'defaults'})`);
      const l = await lighting(page);
      assert.deepEqual([l.light, l.point.on, l.environment.image, l.environment.on, l.toneMapping],
        [want.light, want.point, want.env, want.env !== null, want.tone], `${q}: ${JSON.stringify(l)}`);
      if (want.point) assert.deepEqual([l.point.theta, l.point.phi], [45, -50]);
      shots.push(await capture(page, 0));
    }
    // each lighting draws another picture; with no light at all the sphere is black
    const mean = (img) => {
      let s = 0, n = 0;
      for (let i = 0; i < img.data.length; i += 4) if (img.data[i] !== 31 || img.data[i + 2] !== 31) s += img.data[i + 2], n++;
      return n ? s / n : 0;
    };
    const m = shots.map(mean);
    assert.ok(m[0] > 20 && m[1] > 20 && m[2] > m[0] && m[2] > m[1] && m[3] < 2 && m[4] > m[0],
      `mean blue of the sphere: ${m.map((x) => x.toFixed(1)).join(', ')}`);
    console.log(`# sphere's mean blue: studio ${m[0].toFixed(1)}, point ${m[1].toFixed(1)}, both ${m[2].toFixed(1)}, ` +
      `none ${m[3].toFixed(1)}, studio x1.5 aces ${m[4].toFixed(1)}`);
    assertClean(desktop);
  });

  it('an environment image that fails: one error event, a note, the point light still drawn', async () => {
    const page = await desktop.newPage(); // its own: the init script stays with it
    const q = 'material=knit&geometry=sphere&width=160&height=160&budget-chunks=4&light=fixed';
    await openViewer(page, viewerUrl(q));
    await waitFor(page, settled, 4, 'the point light alone');
    const alone = await capture(page, 0);
    await page.addInitScript(() => {
      window.__errors = [];
      document.addEventListener('error', (e) => e.detail && window.__errors.push(e.detail), true);
    });
    for (const [env, want] of [['env/nosuch.hdr', /nosuch\.hdr: cannot be fetched \(HTTP 404\)/],
      ['env/broken.hdr', /broken\.hdr: not a Radiance \.hdr file/]]) {
      await openViewer(page, viewerUrl(`${q}&environment-image=${env}`));
      await waitFor(page, settled, 4, `the frame with ${env}`);
      await waitFor(page, () => window.__errors.length > 0, null, 'the error event');
      const errs = await page.evaluate(() => window.__errors), l = await lighting(page), v = (await viewers(page))[0];
      assert.equal(errs.length, 1, JSON.stringify(errs));
      assert.match(errs[0].reason, want);
      assert.match(v.message, want, 'the note says it');
      assert.equal(l.environment.state, 'failed');
      assert.deepEqual([l.point.on, l.environment.on], [true, false]);
      const img = await capture(page, 0);
      assert.deepEqual(img.data, alone.data, 'the point light draws as without the environment');
    }
    // without a point light the studio lights the scene in its place
    await openViewer(page, viewerUrl('material=knit&geometry=sphere&width=160&height=160&budget-chunks=4&environment-image=env/nosuch.hdr'));
    await waitFor(page, settled, 4, 'the frame');
    const l = await lighting(page);
    assert.deepEqual([l.point.on, l.environment.on, l.environment.state], [false, true, 'failed']);
    await page.close();
    ctxProblems404();
    assertClean(desktop);
  });
});

// The browser reports the 404 of the missing image on the console: expected here.
function ctxProblems404() {
  desktop.problems = desktop.problems.filter((p) => !/404/.test(p));
}

describe('light="tilt"', () => {
  it('asks for the permission on the first tap (iOS), then the orientation turns the environment or the light', async () => {
    const page = await desktop.newPage(); // its own: the stub stays with it
    await page.addInitScript(() => {
      window.__asked = 0;
      DeviceOrientationEvent.requestPermission = () => {
        window.__asked++;
        return Promise.resolve('granted');
      };
    });
    const orient = (beta, gamma) => page.evaluate(([b, g]) =>
      window.dispatchEvent(new DeviceOrientationEvent('deviceorientation', {beta: b, gamma: g, alpha: 0})), [beta, gamma]);
    for (const [q, what] of [['&environment-image=studio&environment-rotation=20', 'environment'], ['', 'point light']]) {
      await openViewer(page, viewerUrl(`material=knit&geometry=sphere&width=160&height=160&budget-chunks=4&light=tilt${q}`));
      await waitFor(page, settled, 4, 'the frame');
      let l = await lighting(page);
      assert.equal(l.tilt.permission, 'prompt', 'not asked before a tap');
      await orient(50, 10); // not listened to yet
      assert.deepEqual([l.tilt.beta, l.tilt.gamma], [0, 0]);
      const before = await capture(page, 0);
      await page.click('btf-viewer');
      await waitFor(page, () => window.__btf.element(0).lighting.tilt.permission === 'granted', null, 'the permission');
      assert.equal(await page.evaluate(() => window.__asked), 1);
      await page.click('btf-viewer');
      assert.equal(await page.evaluate(() => window.__asked), 1, 'asked once');
      await orient(50, 10); // the first reading: the reference
      await orient(80, -20);
      l = await lighting(page);
      assert.deepEqual([l.tilt.beta, l.tilt.gamma, l.tilt.source], [30, -30, 'orientation']);
      const after = await capture(page, 0);
      l = await lighting(page);
      if (what === 'environment') {
        assert.deepEqual([l.environment.rotation, l.environment.tilt, l.point.on], [20 - 30, 30, true]);
      } else {
        assert.equal(l.environment.on, false);
        assert.ok(Math.abs(l.point.theta - 45) > 5 || Math.abs(l.point.phi + 50) > 5, JSON.stringify(l.point));
      }
      let changed = 0;
      for (let i = 0; i < after.data.length; i += 4) if (Math.abs(after.data[i + 2] - before.data[i + 2]) > 8) changed++;
      assert.ok(changed > 500, `${what}: ${changed} pixels changed by the tilt`);
      console.log(`# tilt (${what}): beta 30, gamma -30 -> ${JSON.stringify(what === 'environment' ? l.environment : l.point)}, ` +
        `${changed} pixels changed`);
    }
    await page.close();
    assertClean(desktop);
  });

  it('without orientation events the pointer tilts', async () => {
    const page = await newPage(desktop);
    await openViewer(page, viewerUrl('material=knit&geometry=sphere&width=200&height=200&budget-chunks=4&light=tilt&' +
      'environment-image=studio'));
    await waitFor(page, settled, 4, 'the frame');
    // Chromium has the permission API, granted on a tap; no tap here, so no orientation events
    assert.ok(['prompt', 'not-needed'].includes((await lighting(page)).tilt.permission));
    const box = await page.locator('btf-viewer').boundingBox();
    const before = await capture(page, 0);
    await page.mouse.move(box.x + 0.75 * box.width, box.y + 0.25 * box.height);
    await waitFor(page, () => window.__btf.element(0).lighting.tilt.source === 'pointer', null, 'the pointer tilt');
    const l = await lighting(page);
    assert.ok(Math.abs(l.tilt.gamma - 45) < 2 && Math.abs(l.tilt.beta + 30) < 2, JSON.stringify(l.tilt));
    assert.ok(Math.abs(l.environment.rotation - l.tilt.gamma) < 1e-9 && l.environment.tilt === l.tilt.beta);
    const after = await capture(page, 0);
    let changed = 0;
    for (let i = 0; i < after.data.length; i += 4) if (Math.abs(after.data[i + 2] - before.data[i + 2]) > 8) changed++;
    assert.ok(changed > 500, `${changed} pixels changed`);
    assertClean(desktop);
  });
});

// ------------------------------------------------------------------ against btf render

function hasEnvironment() {
  const r = spawnSync(BTF, ['render', '--help'], {encoding: 'utf8'});
  return /--environment/.test(`${r.stdout}${r.stderr}`);
}

const GEOMETRY = {
  plane: {material: 'knit', w: 200, h: 150, camera: [35, -90, 3], chunks: 4},
  sphere: {material: 'tiles', w: 160, h: 160, camera: [60, -70, 3.6], chunks: 3},
};

// Each case: geometry, environment ('studio' or a file in envDir), rotation; light:
// the point light too (light-theta, light-phi); exposure, tone.
const CASES = [
  ...['plane', 'sphere'].flatMap((g) => ['studio', 'colour.hdr'].flatMap((env) => [0, 110].map((rot) => ({g, env, rot})))),
  {g: 'sphere', env: 'studio', rot: 0, exposure: 2, tone: 'aces'},
  {g: 'plane', env: 'colour.hdr', rot: 200, light: [40, -60]},
  {g: 'sphere', env: 'colour.hdr', rot: 30, material: 'knit-linear', chunks: 4},
  // version 2: levels, the 8-bit weights of a coarse prefix, then the 16-bit ones
  {g: 'plane', env: 'colour.hdr', rot: 45, material: 'tiles-lod', chunks: 5, repeat: 4},
  {g: 'plane', env: 'colour.hdr', rot: 45, material: 'tiles-lod', chunks: 18, repeat: 4},
];

describe('<btf-viewer> against btf render --environment', () => {
  it('the plane and the sphere under the studio and a coloured environment, as the C host draws them', async (t) => {
    if (!hasEnvironment()) {
      t.skip('build/btf render has no --environment yet');
      return;
    }
    const page = await newPage(desktop);
    const out = [];
    for (const c of CASES) {
      const s = {...GEOMETRY[c.g], ...(c.material ? {material: c.material, chunks: c.chunks} : {})};
      const name = `${s.material}${c.material ? ` (${s.chunks} chunks)` : ''} ${c.g} ${c.env} rot ${c.rot}` +
        `${c.light ? ' + point light' : ''}` +
        `${c.exposure ? ` exposure ${c.exposure}` : ''}${c.tone ? ` ${c.tone}` : ''}`;
      const png = path.join(lib.dir, `ref-${out.length}.png`);
      const args = ['render', path.join(lib.lib, s.material), png, '--size', `${s.w}x${s.h}`, '--geometry', c.g,
        '--camera', s.camera.join(','), '--fov', '40', '--chunks', String(s.chunks), '--backend', 'egl',
        '--environment', c.env === 'studio' ? 'studio' : path.join(envDir, c.env), '--environment-rotation', String(c.rot),
        ...(c.light ? ['--light', c.light.join(',')] : ['--no-light']),
        ...(c.exposure ? ['--exposure', String(c.exposure)] : []), ...(c.tone ? ['--tone-mapping', c.tone] : []),
        ...(c.repeat ? ['--repeat', String(c.repeat)] : [])];
      const r = spawnSync(BTF, args, {encoding: 'utf8'});
      assert.equal(r.status, 0, `btf ${args.join(' ')} failed: ${r.stderr}`);
      const ref = readPng(png);
      await openViewer(page, viewerUrl(`material=${s.material}&geometry=${c.g}&camera-theta=${s.camera[0]}&camera-phi=${s.camera[1]}` +
        `&camera-dist=${s.camera[2]}&fov=40&budget-chunks=${s.chunks}&width=${s.w}&height=${s.h}` +
        `&environment-image=${c.env === 'studio' ? 'studio' : `env/${c.env}`}&environment-rotation=${c.rot}` +
        (c.light ? `&light=fixed&light-theta=${c.light[0]}&light-phi=${c.light[1]}` : '') +
        (c.exposure ? `&exposure=${c.exposure}` : '') + (c.tone ? `&tone-mapping=${c.tone}` : '') +
        (c.repeat ? `&repeat=${c.repeat}` : '')));
      await waitFor(page, settled, s.chunks, `the browser frame (${name})`);
      const l = await lighting(page);
      assert.deepEqual([l.environment.on, l.point.on], [true, !!c.light], name);
      const img = await capture(page, 0);
      const d = compare(img, ref);
      out.push({name, ...d});
      console.log(`# ${name}: ${d.covered} covered pixels, ${(100 * d.within1).toFixed(2)}% within 1/255, ` +
        `${(100 * d.within2).toFixed(2)}% within 2/255 (inside the silhouette ${(100 * d.innerWithin2).toFixed(3)}%), ` +
        `99.9th percentile ${d.p999}, worst ${d.worst} (inside ${d.inner}), mean ${d.mean.toFixed(3)}`);
      assert.ok(d.covered > 0.2 * s.w * s.h, `${name}: the object covers ${d.covered} pixels`);
    }
    // a model (btf render --model, btf_scene.c): every bound part under the environment
    // (its parts' frames from the generated tangents), the trim in its flat colour
    const stool = path.join(envDir, 'stool.glb');
    const g = spawnSync(BTF, ['gen-model', stool], {encoding: 'utf8'});
    assert.equal(g.status, 0, g.stderr);
    for (const [env, rot] of [['studio', 0], ['colour.hdr', 60]]) {
      const name = `stool (Seat knit x3, Frame tiles x8, the trim unbound) ${env} rot ${rot}`, png = path.join(lib.dir, `stool-${rot}.png`);
      const args = ['render', '-', png, '--model', stool, '--bind', `Seat=${path.join(lib.lib, 'knit')},3`,
        '--bind', `Frame=${path.join(lib.lib, 'tiles')},8`, '--size', '240x240', '--camera', '55,-70', '--backend', 'egl',
        '--environment', env === 'studio' ? 'studio' : path.join(envDir, env), '--environment-rotation', String(rot), '--no-light'];
      const r = spawnSync(BTF, args, {encoding: 'utf8'});
      assert.equal(r.status, 0, `btf ${args.join(' ')} failed: ${r.stderr}`);
      await openViewer(page, viewerUrl(`model=env/stool.glb&materials=Seat:knit:3,Frame:tiles:8&budget-chunks=999&camera-theta=55` +
        `&camera-phi=-70&width=240&height=240&environment-image=${env === 'studio' ? 'studio' : `env/${env}`}` +
        `&environment-rotation=${rot}`));
      await waitFor(page, () => {
        const v = window.__btf?.viewers()[0], l = window.__btf?.element(0).lighting;
        return v && v.complete && v.frames > 0 && v.drawnChunks === v.ownLimit && v.ownLimit > 0 && l.environment.state === 'ready';
      }, null, `the stool (${env})`);
      const d = compare(await capture(page, 0), readPng(png));
      out.push({name, ...d});
      console.log(`# ${name}: ${d.covered} covered pixels, ${(100 * d.within2).toFixed(2)}% within 2/255 (inside the ` +
        `silhouette ${(100 * d.innerWithin2).toFixed(3)}%), worst ${d.worst} (inside ${d.inner}), mean ${d.mean.toFixed(3)}`);
      assert.ok(d.covered > 0.15 * 240 * 240, `${name}: covers ${d.covered} pixels`);
    }
    // Tolerances: the two hosts run the same GLSL on float32 inputs made by the same
    // formulas (the quadratic, the cells, G and its 11/10-bit codes), so most pixels agree
    // within the RGBA8 rounding (1/255); float texture fetches, pow and exp differ in their
    // last bits between SwiftShader and llvmpipe, which 2/255 covers. Two kinds of pixel
    // differ more: the silhouette (each rasteriser's coverage rule) and the sphere's pole,
    // where the uv derivatives of the 2 x 2 quads (the level of detail) and the degenerate
    // tangent frame differ (measured: up to 14/255 on 4 to 7 pixels, as under the point light).
    for (const d of out) {
      assert.ok(d.within2 >= 0.998, `${d.name}: ${(100 * d.within2).toFixed(2)}% within 2/255 (worst ${d.worst})`);
      assert.ok(d.innerWithin2 >= 0.999, `${d.name}: ${(100 * d.innerWithin2).toFixed(3)}% inside the silhouette within 2/255`);
      assert.ok(d.mean < 0.5, `${d.name}: mean ${d.mean}`);
    }
    assertClean(desktop);
  });
});
