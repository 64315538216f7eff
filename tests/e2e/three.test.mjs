// three.test.mjs - BTFMaterial (client/three/btf-material.js) on three.js meshes in headless
// Chromium against <btf-viewer> drawing the same scene (package, camera, light, size): a
// plane and a sphere (three's PlaneGeometry and SphereGeometry, tangents by
// computeTangents), the point light, the studio, both with exposure and ACES, and a
// version-2 package with levels (the mip levels three does not upload itself); then the
// refinement: a budget of one chunk, raised, each chunk a texture update and a 'change';
// then nearest texels with levels against `btf render --filter nearest`.
// The source modules, three from node_modules. Run: node --test tests/e2e/three.test.mjs
import assert from 'node:assert/strict';
import {spawnSync} from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import {after, before, describe, it} from 'node:test';
import {BTF, ROOT, assertClean, capture, compareCovered, hasRender, launch, makeLibrary, newPage, readPng, requireBuild,
  startServer, waitFor} from './util.mjs';
import {pageHtml, serveTree, threeScript} from './three-page.mjs';

const MATERIALS = {knit: ['knit', 4], tiles: ['tiles', 3], 'tiles-lod': ['tiles', 6, 3]};
let lib, server, site, browser;

before(async () => {
  requireBuild();
  lib = makeLibrary(MATERIALS);
  server = await startServer(lib.lib);
  // the page on its own origin, laid out as btfd serves the client: client/ at /, shaders/
  // at /shaders/ (the defaults of both: shaders/ next to btf-viewer.js), three at /vendor/three/
  site = await serveTree({three: pageHtml({three: '/vendor/three/three.module.js'},
    threeScript('/three/btf-material.js', '/btf-viewer.js'))},
  {'/vendor/three/': path.join(ROOT, 'node_modules/three/build'), '/shaders/': path.join(ROOT, 'shaders'),
    '/': path.join(ROOT, 'client')});
  browser = await launch();
});

after(async () => {
  await browser?.close();
  await site?.close();
  await server?.stop();
  lib?.remove();
});

export async function openPage(ctx, url) {
  const page = await newPage(ctx);
  await page.setViewportSize({width: 900, height: 500});
  await page.goto(url);
  await waitFor(page, () => window.__threeReady === true, null, 'the page script');
  return page;
}

// The three.js render of scene s, captured once its chunks are drawn.
async function drawThree(page, s) {
  await page.evaluate((sc) => window.__three.draw(sc), s);
  await waitFor(page, (n) => window.__three.drawn() === n && window.__three.state().visible, s.chunks,
    `the three.js frame (${s.material} ${s.geometry})`);
  const c = await page.evaluate(() => window.__three.capture());
  return {width: c.width, height: c.height, data: new Uint8Array(Buffer.from(c.rgba, 'base64'))};
}

// Both renders of scene s: [three, element] captures.
export async function drawBoth(page, s, shaders = null) {
  await page.evaluate(([sc, sh]) => window.__three.viewer(sc, sh), [s, shaders]);
  await waitFor(page, (n) => {
    const v = window.__btf?.viewers()[0], l = window.__btf?.element(0).lighting;
    return v && v.drawnChunks === n && v.frames > 0 && l && !['idle', 'loading'].includes(l.environment.state);
  }, s.chunks, `the element's frame (${s.material} ${s.geometry})`);
  const element = await capture(page, 0);
  return [await drawThree(page, s), element];
}

// The three.js scenes against the element: the package, camera, light and size of each.
export const SCENES = [
  {name: 'knit plane, point light', material: 'knit', geometry: 'plane', w: 200, h: 150, camera: [35, -90, 3],
    light: [40, -60], chunks: 4},
  {name: 'tiles sphere, the studio', material: 'tiles', geometry: 'sphere', w: 160, h: 160, camera: [60, -70, 3.6],
    chunks: 3},
  {name: 'knit sphere, point light and the studio, exposure 1.5, aces', material: 'knit', geometry: 'sphere', w: 160,
    h: 160, camera: [50, -100, 3.6], light: [45, -50], environment: 'studio', environmentRotation: 40, exposure: 1.5,
    toneMapping: 'aces', chunks: 4},
  {name: 'tiles sphere, the studio, the element\'s mesh', material: 'tiles', geometry: 'sphere', w: 160, h: 160,
    camera: [60, -70, 3.6], chunks: 3, mesh: 'element'},
  {name: 'knit sphere, exposure 1.5, aces, the element\'s mesh', material: 'knit', geometry: 'sphere', w: 160,
    h: 160, camera: [50, -100, 3.6], light: [45, -50], environment: 'studio', environmentRotation: 40, exposure: 1.5,
    toneMapping: 'aces', chunks: 4, mesh: 'element'},
  {name: 'tiles-lod plane x4 (levels), point light', material: 'tiles-lod', geometry: 'plane', w: 200, h: 150,
    camera: [55, -90, 3], light: [40, -60], repeat: 4, chunks: 18},
];

// Tolerances, from the measured numbers (doc/client.md "three.js"). On the element's own
// mesh (scene.js buildMesh as a BufferGeometry) BTFMaterial draws the element's picture:
// the same GLSL, uploads and context type (SwiftShader), measured 99.99-100% of the
// covered pixels within 1/255, worst 2/255, so 1/255 on 99.9% is asked. three's own
// geometries: the plane is the element's (2 triangles, same uv), measured identical; the
// sphere has the element's 64 x 32 vertices, normals and uv but splits each quad along
// the other diagonal, so a pixel sees another point of the (non-planar) quad and other
// texels: measured 99.76% within 2/255 under the studio (mean 0.16/255, worst 7/255),
// 98.3% with exposure 1.5 and ACES (mean 0.49, worst 9), which steepen the curve;
// computeTangents against the exact tangents changes these by under 0.1%. Asked: 97%
// within 2/255 and a mean under 1/255 there.
export function judge(d, name) {
  console.log(`# ${name}: ${d.covered} covered pixels, ${(100 * d.within1).toFixed(2)}% within 1/255, ` +
    `${(100 * d.within2).toFixed(2)}% within 2/255 (inside the silhouette ${(100 * d.innerWithin2).toFixed(3)}%), ` +
    `99.9th percentile ${d.p999}, worst ${d.worst} (inside ${d.inner}), mean ${d.mean.toFixed(3)}`);
  return d;
}

describe('BTFMaterial against <btf-viewer>', () => {
  it('refines as chunks arrive: each chunk a texture update and a change event, the budget raised', async () => {
    const page = await openPage(browser, `${site.url}three.html`);
    const s = {...SCENES[0], src: server.ws, chunks: 1};
    await page.evaluate((sc) => window.__three.draw(sc), s);
    await waitFor(page, () => window.__three.drawn() === 1, null, 'one chunk drawn');
    const one = await page.evaluate(() => window.__three.capture());
    const st1 = await page.evaluate(() => window.__three.state());
    await page.evaluate(() => {
      window.__events = [];
      const m = window.__three.material();
      for (const t of ['progress', 'complete', 'change']) m.addEventListener(t, (e) => window.__events.push(e.type));
      m.setBudget({budgetChunks: 4});
    });
    await waitFor(page, () => window.__three.drawn() === 4 && window.__events.includes('complete'), null, 'four chunks');
    const st4 = await page.evaluate(() => window.__three.state()), ev = await page.evaluate(() => window.__events);
    const four = await page.evaluate(() => window.__three.capture());
    assert.equal(ev.filter((e) => e === 'progress').length, 3, ev.join(','));
    assert.ok(ev.filter((e) => e === 'change').length >= 3, ev.join(','));
    // version 1: a slot per chunk; its texture layer rewritten per chunk (three's version counts needsUpdate)
    assert.deepEqual([st1.uploaded, st4.uploaded, st4.uploads], [1, 4, 4]);
    assert.ok(st4.textures.tex > st1.textures.tex && st4.textures.wt > st1.textures.wt, JSON.stringify([st1.textures, st4.textures]));
    let changed = 0;
    const a = Buffer.from(one.rgba, 'base64'), b = Buffer.from(four.rgba, 'base64');
    for (let i = 0; i < a.length; i += 4) if (Math.abs(a[i] - b[i]) > 2) changed++;
    assert.ok(changed > 1000, `${changed} pixels changed from 1 to 4 chunks`);
    // the refined picture is the element's picture of 4 chunks
    const [three, element] = await drawBoth(page, {...SCENES[0], src: server.ws});
    const d = judge(compareCovered(three, element), 'knit plane after refinement');
    assert.ok(d.within1 >= 0.999 && d.worst <= 2, `${(100 * d.within1).toFixed(2)}% within 1/255, worst ${d.worst}`);
    assertClean(browser);
  });

  it('plane and sphere, point light, the studio, exposure and tone mapping, levels: the element\'s picture', async () => {
    const page = await openPage(browser, `${site.url}three.html`);
    const out = [];
    for (const s0 of SCENES) {
      const s = {...s0, src: server.ws};
      const [three, element] = await drawBoth(page, s);
      const d = judge(compareCovered(three, element), s.name);
      assert.ok(d.covered > 0.2 * s.w * s.h, `${s.name}: the object covers ${d.covered} pixels`);
      out.push({name: s.name, exact: s.geometry === 'plane' || s.mesh === 'element', ...d});
    }
    for (const d of out) {
      if (d.exact) {
        assert.ok(d.within1 >= 0.999 && d.worst <= 2, `${d.name}: ${(100 * d.within1).toFixed(2)}% within 1/255, worst ${d.worst}`);
      } else {
        assert.ok(d.within2 >= 0.97, `${d.name}: ${(100 * d.within2).toFixed(2)}% within 2/255`);
        assert.ok(d.mean < 1, `${d.name}: mean ${d.mean}`);
      }
    }
    assertClean(browser);
  });
});

// Nearest texels on a package with levels read one texel for two levels (shaders/README.md,
// "GPU layout", paired levels), which the element's bilinear picture never does: three's
// nearest plane (the element's plane) against `btf render --filter nearest` of the scene.
// Measured 99.6% of the covered pixels within 2/255 (the version-1 tiles without levels:
// 99.5%; nearest taps turn the two hosts' tiny uv differences into whole texels at texel
// edges); high halves left 0 measured 25%.
describe('BTFMaterial, nearest texels with levels', () => {
  it('equals btf render --filter nearest within 2/255 on >= 99% of covered pixels', async (t) => {
    if (!hasRender()) {
      t.skip('build/btf has no `render` command');
      return;
    }
    const s = {...SCENES.find((x) => x.material === 'tiles-lod'), src: server.ws, filter: 'nearest'};
    const out = path.join(fs.mkdtempSync(path.join(os.tmpdir(), 'btf-three-')), 'nearest.png');
    const args = ['render', path.join(lib.lib, s.material), out, '--size', `${s.w}x${s.h}`, '--geometry', s.geometry,
      '--camera', s.camera.join(','), '--fov', '40', '--light', s.light.join(','), '--chunks', String(s.chunks),
      '--repeat', String(s.repeat), '--filter', 'nearest', '--backend', 'egl'];
    const r = spawnSync(BTF, args, {encoding: 'utf8'});
    assert.equal(r.status, 0, `btf ${args.join(' ')} failed: ${r.stderr}`);
    const ref = readPng(out);
    fs.rmSync(path.dirname(out), {recursive: true, force: true});
    const page = await openPage(browser, `${site.url}three.html`);
    const d = judge(compareCovered(await drawThree(page, s), ref), `${s.name}, nearest, against btf render`);
    assert.ok(d.covered > 0.2 * s.w * s.h, `the plane covers ${d.covered} pixels`);
    assert.ok(d.within2 >= 0.99, `${(100 * d.within2).toFixed(2)}% within 2/255, worst ${d.worst}`);
    assertClean(browser);
  });
});
