// rd.test.mjs - a version-3 package (doc/package-format.md section 9.3: wt-JJ.z
// weights, inflated by the browser's DecompressionStream; what `btf compress` writes
// by default), the same with lossy WebP textures (section 4.1: the default where they
// win) and the version-4 package with levels over it in headless Chromium against a
// real btfd: each streams completely and draws the image its version-1 twin (the same
// source, equal-noise steps, raw weights: --plain) draws, up to quantisation; the
// client's decode of each lossy texture is the C reader's, byte for byte.
import assert from 'node:assert/strict';
import {spawnSync} from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import {after, before, describe, it} from 'node:test';
import {BTF, assertClean, capture, launch, makeLibrary, meanAbsDiff, newPage, readPng, requireBuild, startServer,
  viewers, waitFor} from './util.mjs';

let lib, server, desktop;

// 1 when file f of package dir is a lossy WebP (its first chunk "VP8 ", package-format.md 4.1).
const isLossy = (dir, f) => fs.readFileSync(path.join(dir, f)).subarray(12, 16).toString('latin1') === 'VP8 ';

before(async () => {
  requireBuild();
  lib = makeLibrary({tiles: ['tiles', 4, 0, ['--plain']], 'tiles-rd': ['tiles', 4, 0, ['--lossless']],
    // at 32 texels a side lossy textures win for coarser steps than the default's
    'tiles-rdl': ['tiles', 4, 2], 'tiles-lossy': ['tiles', 4, 0, ['--tex-noise', '1']],
    // and with levels: a lossy component's coarse levels lossy too (package-format.md
    // 10.7); the choice weighs lossy textures with their levels, so a coarser noise
    'tiles-lossyl': ['tiles', 4, 2, ['--tex-noise', '1.5']]});
  server = await startServer(lib.lib);
  desktop = await launch();
  await desktop.addInitScript(() => { window.__btfCache = false; });
});

after(async () => {
  await desktop?.close();
  await server?.stop();
  lib?.remove();
});

describe('version 3 (wt-JJ.z weights)', () => {
  it('streams, decodes and draws as its version-1 twin does, with levels too', async () => {
    const page = await newPage(desktop);
    await page.setViewportSize({width: 400, height: 400});
    const shots = {};
    for (const m of ['tiles', 'tiles-rd', 'tiles-rdl', 'tiles-lossy', 'tiles-lossyl']) {
      await page.goto(`${server.pagesUrl}viewer.html?material=${m}&geometry=plane&light=fixed&light-theta=40` +
        '&light-phi=-60&camera-theta=30&width=256&height=256&max-dpr=1');
      await waitFor(page, () => {
        const v = window.__btf && window.__btf.viewers()[0];
        return v && v.complete && v.drawnChunks === v.ownLimit && v.drawnChunks === v.manifestChunks && v.frames > 0;
      }, null, `${m} drawn completely`);
      const v = (await viewers(page))[0];
      assert.equal(v.error, null);
      const levels = m === 'tiles-rdl' || m === 'tiles-lossyl';
      assert.equal(v.drawnChunks, levels ? v.manifestChunks : 4);
      if (levels) assert.ok(v.manifestChunks > 4, 'levels add chunks');
      shots[m] = await capture(page, 0);
    }
    // The packages differ only in their quantisation steps (each adds about 0.5 RMS
    // on the 0..255 scale per component, 4 components): their images differ by about
    // a level; a weight file decoded wrongly (a wrong byte plane, prediction or
    // range) changes them by tens of levels.
    const d = meanAbsDiff(shots.tiles, shots['tiles-rd']);
    console.log(`# version 3 vs version 1, 4 chunks: mean |difference| ${d.toFixed(3)} of 255`);
    assert.ok(d < 3, `version-3 image within 3 levels of version 1 (${d})`);
    // With every chunk drawn at this size the finest level shows: the version-3
    // package's values exactly, so the same image but for the level blend.
    const d4 = meanAbsDiff(shots['tiles-rd'], shots['tiles-rdl']);
    console.log(`# version 4 over version 3 vs version 3: mean |difference| ${d4.toFixed(3)} of 255`);
    assert.ok(d4 < 3, `version-4 image within 3 levels of version 3 (${d4})`);
    // Lossy textures (at twice the default's noise per component here) add about the
    // error of lossless steps at that noise: the same bound holds.
    const dl = meanAbsDiff(shots.tiles, shots['tiles-lossy']);
    console.log(`# version 3 with lossy textures vs version 1: mean |difference| ${dl.toFixed(3)} of 255`);
    assert.ok(dl < 3, `lossy version-3 image within 3 levels of version 1 (${dl})`);
    // Lossy coarse levels: every chunk drawn, within the bound of the others (1.5
    // times the default's noise per component).
    const dir = path.join(lib.lib, 'tiles-lossyl');
    const coarse = JSON.parse(fs.readFileSync(path.join(dir, 'manifest.json'), 'utf8')).chunks
      .filter((c) => c.level > 0 && isLossy(dir, c.files[0]));
    assert.ok(coarse.length >= 1, 'the package has lossy coarse levels (the test covers them)');
    const dll = meanAbsDiff(shots.tiles, shots['tiles-lossyl']);
    console.log(`# ${coarse.length} lossy coarse levels: mean |difference| ${dll.toFixed(3)} of 255 from version 1`);
    assert.ok(dll < 3, `lossy levels within 3 levels of version 1 (${dll})`);
    assertClean(desktop);
  });
});

describe('lossy WebP textures', () => {
  it('the client decodes each lossy texture to the C reader\'s bytes', async () => {
    const dir = path.join(lib.lib, 'tiles-lossy');
    const m = JSON.parse(fs.readFileSync(path.join(dir, 'manifest.json'), 'utf8'));
    const lossy = m.chunks.map((c) => c.files[0])
      .filter((f) => isLossy(dir, f));
    assert.ok(lossy.length >= 1, 'the package has lossy textures (the test covers them)');
    // The C reader's values: `btf lod --levels 1 --png` reads the package through
    // btf_package_read and writes each level-0 atlas as the PNG of its decoded bytes.
    const ref = path.join(lib.dir, 'lossy-ref');
    const r = spawnSync(BTF, ['lod', dir, ref, '--levels', '1', '--png', '--quiet'], {encoding: 'utf8'});
    assert.equal(r.status, 0, `btf lod: ${r.stderr}`);
    const page = await newPage(desktop);
    await page.goto(`${server.pagesUrl}viewer.html?material=tiles&width=64&height=64`);
    let g = 0;
    for (const f of lossy) {
      // the client's own decoder (client/btf-decode.js, its worker), R as btf-gl.js readAtlas takes it
      const got = await page.evaluate(async ([url, b64]) => {
        const {decodeImage} = await import(url);
        const d = await decodeImage(Uint8Array.from(atob(b64), (c) => c.charCodeAt(0)), 'image/webp');
        const q = new Array(d.width * d.height);
        let rg = 0;
        for (let i = 0; i < q.length; i++) {
          q[i] = d.rgba[4 * i];
          rg += d.rgba[4 * i + 1] !== q[i];
        }
        return {width: d.width, height: d.height, q, rg};
      }, [`${server.url}btf-decode.js`, fs.readFileSync(path.join(dir, f)).toString('base64')]);
      const png = readPng(path.join(ref, f.replace(/\.webp$/, '.png')));
      assert.deepEqual([got.width, got.height], [png.width, png.height], f);
      let differ = 0;
      for (let i = 0; i < got.q.length; i++) differ += got.q[i] !== png.data[4 * i];
      assert.equal(differ, 0, `${f}: ${differ} texels differ from the C reader's`);
      g += got.rg;
    }
    console.log(`# ${lossy.length} lossy textures decoded as the C reader does; G differs from R at ${g} texels`);
    assertClean(desktop);
  });
});
