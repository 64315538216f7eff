// rd.test.mjs - a version-3 package (doc/package-format.md section 9.3: wt-JJ.z
// weights, inflated by the browser's DecompressionStream; what `btf compress` writes
// by default) and the version-4 package with levels over it in headless Chromium
// against a real btfd: each streams completely and draws the image its version-1
// twin (the same source, equal-noise steps, raw weights: --plain) draws, up to
// quantisation.
import assert from 'node:assert/strict';
import {after, before, describe, it} from 'node:test';
import {assertClean, capture, launch, makeLibrary, meanAbsDiff, newPage, requireBuild, startServer, viewers,
  waitFor} from './util.mjs';

let lib, server, desktop;

before(async () => {
  requireBuild();
  lib = makeLibrary({tiles: ['tiles', 4, 0, ['--plain']], 'tiles-rd': ['tiles', 4], 'tiles-rdl': ['tiles', 4, 2]});
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
    for (const m of ['tiles', 'tiles-rd', 'tiles-rdl']) {
      await page.goto(`${server.pagesUrl}viewer.html?material=${m}&geometry=plane&light=fixed&light-theta=40` +
        '&light-phi=-60&camera-theta=30&width=256&height=256&max-dpr=1');
      await waitFor(page, () => {
        const v = window.__btf && window.__btf.viewers()[0];
        return v && v.complete && v.drawnChunks === v.ownLimit && v.drawnChunks === v.manifestChunks && v.frames > 0;
      }, null, `${m} drawn completely`);
      const v = (await viewers(page))[0];
      assert.equal(v.error, null);
      assert.equal(v.drawnChunks, m === 'tiles-rdl' ? v.manifestChunks : 4);
      if (m === 'tiles-rdl') assert.ok(v.manifestChunks > 4, 'levels add chunks');
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
    assertClean(desktop);
  });
});
