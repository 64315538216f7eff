// lap.test.mjs - package version 4 (doc/package-format.md section 12: levels as
// residuals over the next coarser level, 16-bit weights as a residual over the 8-bit
// ones). In node: the client's reader (client/btf-package.js) rebuilds from the
// version-4 files exactly the level bytes and weights of the version-2 package made
// from the same version-1 package (which the C reader is checked to do in
// tests/test_lap.c), and refuses a residual before its coarser level. In headless
// Chromium against a real btfd: a coarse prefix and the whole package draw the same
// pixels as their version-2 twin.
import assert from 'node:assert/strict';
import {spawnSync} from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import {after, before, describe, it} from 'node:test';
import {BTF, assertClean, capture, launch, makeLibrary, meanAbsDiff, newPage, readPng, requireBuild, startServer,
  viewers, waitFor} from './util.mjs';

const pkgMod = await import('../../client/btf-package.js');

let lib, server, desktop;

function btf(args) {
  const r = spawnSync(BTF, args, {encoding: 'utf8'});
  assert.equal(r.status, 0, `btf ${args.join(' ')}: ${r.stderr}`);
}

before(async () => {
  requireBuild();
  lib = makeLibrary({'tiles-v1': ['tiles', 4, 0, ['--plain']]}); // version 1: its levels are version 2 or 4
  const v1 = path.join(lib.lib, 'tiles-v1');
  btf(['lod', v1, path.join(lib.lib, 'tiles-lod'), '--levels', '3', '--quiet']);
  btf(['lod', v1, path.join(lib.lib, 'tiles-lap'), '--levels', '3', '--residual', '--quiet']);
  btf(['lod', v1, path.join(lib.lib, 'tiles-lap-png'), '--levels', '3', '--residual', '--png', '--quiet']);
  server = await startServer(lib.lib);
  desktop = await launch();
  await desktop.addInitScript(() => { window.__btfCache = false; });
});

after(async () => {
  await desktop?.close();
  await server?.stop();
  lib?.remove();
});

const manifestOf = (name) => JSON.parse(fs.readFileSync(path.join(lib.lib, name, 'manifest.json'), 'utf8'));
// A grey texture's pixels (readPng gives RGBA). A lossless WebP texture (section 4:
// R = G = B) is first turned into a PNG of its R channel by oiiotool (OpenImageIO,
// a decoder independent of the client's code under test).
function grey(name, file) {
  let src = path.join(lib.lib, name, file);
  if (file.endsWith('.webp')) {
    const png = path.join(lib.dir, `${name}-${file}.png`);
    const r = spawnSync('oiiotool', [src, '--ch', 'R', '-o', png], {encoding: 'utf8'});
    assert.equal(r.status, 0, `oiiotool ${src}: ${r.stderr}`);
    src = png;
  }
  const img = readPng(src), px = new Uint8Array(img.width * img.height);
  for (let i = 0; i < px.length; i++) px[i] = img.data[4 * i];
  return {width: img.width, height: img.height, data: px};
}
// The 8-bit weights of chunk c of package name: wt-JJ-8.png's grey pixels, or wt-JJ-8.webp
// (section 5.2: L x V RGB pixels, decoded by oiiotool) through the client's weights8Webp.
function weights8(name, p, c) {
  if (!c.wt8.endsWith('.webp')) return grey(name, c.wt8).data;
  const src = path.join(lib.lib, name, c.wt8), png = path.join(lib.dir, `${name}-${c.wt8}.png`);
  pkgMod.checkWeightsWebp(p, c, fs.readFileSync(src), c.wt8);
  const r = spawnSync('oiiotool', [src, '-o', png], {encoding: 'utf8'});
  assert.equal(r.status, 0, `oiiotool ${src}: ${r.stderr}`);
  const img = readPng(png);
  return pkgMod.weights8Webp(p, c, img.width, img.height, img.data);
}

describe('version 4 (residual levels)', () => {
  // name: the version-4 package; its textures are lossless WebP where that is smaller
  // (section 4), or every one a PNG (--png); returns how many are WebP.
  async function rebuildsExactly(name) {
    const p2 = pkgMod.parseManifest(manifestOf('tiles-lod')), p4 = pkgMod.parseManifest(manifestOf(name));
    assert.equal(p4.manifestVersion, 4);
    assert.equal(p4.version, 2, 'the GPU side sees the version-2 layout');
    assert.equal(p4.chunks.length, p2.chunks.length);
    const levels = new Map(), w8 = new Map();
    let residuals = 0, residualWeights = 0, webpWeights8 = 0;
    for (const [j, c4] of p4.chunks.entries()) {
      const c2 = p2.chunks[j];
      assert.deepEqual([c4.component, c4.level], [c2.component, c2.level]);
      const img = grey(name, c4.tex);
      const bytes = c4.residual ? pkgMod.reconstructLevel(p4, c4, img.data, levels.get(`${c4.component}/${c4.level + 1}`))
        : img.data;
      residuals += c4.residual ? 1 : 0;
      levels.set(`${c4.component}/${c4.level}`, bytes);
      assert.deepEqual(Buffer.from(bytes), Buffer.from(grey('tiles-lod', c2.tex).data), `chunk ${j} (${c4.tex})`);
      if (c4.wt8) { // the same 8-bit weights as version 2's wt-JJ-8.png, whichever file holds them
        w8.set(c4.component, weights8(name, p4, c4));
        assert.deepEqual(Buffer.from(w8.get(c4.component)), Buffer.from(grey('tiles-lod', c2.wt8).data),
          `chunk ${j}: ${c4.wt8}`);
        webpWeights8 += c4.wt8.endsWith('.webp') ? 1 : 0;
      }
      if (c4.wt) {
        const buf = fs.readFileSync(path.join(lib.lib, name, c4.wt));
        const w4 = await pkgMod.decodeWeights(p4, c4, buf, w8.get(c4.component));
        const w2 = pkgMod.dequantWeights(p2, c2, fs.readFileSync(path.join(lib.lib, 'tiles-lod', c2.wt)));
        assert.deepEqual(w4, w2, `chunk ${j}: ${c4.wt}`);
        residualWeights += c4.wt.endsWith('-r.z') ? 1 : 0;
      }
    }
    assert.ok(residuals >= 1 && residualWeights >= 1, `${residuals} residual levels, ${residualWeights} residual weights`);
    console.log(`# ${name}: ${webpWeights8} of ${w8.size} components' 8-bit weights as wt-JJ-8.webp`);
    return p4.chunks.filter((c) => c.tex.endsWith('.webp')).length;
  }

  it('the client reader rebuilds the version-2 levels and weights exactly', async () => {
    const webp = await rebuildsExactly('tiles-lap');
    assert.ok(webp >= 1, 'the default package has WebP textures (the test covers them)');
    assert.ok(manifestOf('tiles-lap').chunks.some((c) => c.files.some((f) => /^wt-.*-8\.webp$/.test(f))),
      'the default package has wt-JJ-8.webp weights (the test and the drawing below cover them)');
    assert.equal(await rebuildsExactly('tiles-lap-png'), 0, '--png: every texture a PNG');
    const p4 = pkgMod.parseManifest(manifestOf('tiles-lap'));
    // a residual's name in any texture encoding (section 4.3): -dL.avif as -dL.png and -dL.webp
    const ma = manifestOf('tiles-lap');
    for (const c of ma.chunks) c.files = c.files.map((f) => (f.startsWith('tex-') ? f.replace(/\.\w+$/, '.avif') : f));
    assert.deepEqual(pkgMod.parseManifest(ma).chunks.map((c) => c.residual), p4.chunks.map((c) => c.residual));
    // a residual before its coarser level, a residual weight file without the 8-bit weights
    const m = manifestOf('tiles-lap');
    m.chunks[0].level = 0;
    assert.throws(() => pkgMod.parseManifest(m), /comes before|twice/);
    const cw = p4.chunks.find((c) => c.wt && c.wt.endsWith('-r.z'));
    await assert.rejects(pkgMod.decodeWeights(p4, cw, fs.readFileSync(path.join(lib.lib, 'tiles-lap', cw.wt)), null),
      /8-bit weights/);
    const short = pkgMod.reconstructLevel.bind(null, p4, p4.chunks.find((c) => c.residual));
    assert.throws(() => short(new Uint8Array(3), new Uint8Array(1)), /residual texels/);
    // predictors (the C writer lists one per residual level): refused when malformed
    const ir = m.chunks.findIndex((c) => c.predictor);
    assert.ok(ir >= 0 && p4.chunks[ir].residual, 'a residual level lists its predictor');
    for (const bad of [m.chunks[ir].predictor.slice(1), [...m.chunks[ir].predictor.slice(1), 4097],
      [...m.chunks[ir].predictor.slice(1), 0.5], 'x']) {
      const mb = manifestOf('tiles-lap');
      mb.chunks[ir].predictor = bad;
      assert.throws(() => pkgMod.parseManifest(mb), /"predictor"/, JSON.stringify(bad));
    }
    const mc = manifestOf('tiles-lap');
    mc.chunks[p4.chunks.findIndex((c) => !c.residual)].predictor = m.chunks[ir].predictor;
    assert.throws(() => pkgMod.parseManifest(mc), /"predictor"/, 'on a level that is no residual');
  });

  it('streams and draws a coarse prefix and the whole package as its version-2 twin', async () => {
    const page = await newPage(desktop);
    await page.setViewportSize({width: 400, height: 400});
    const n = manifestOf('tiles-lap').chunks.length;
    for (const chunks of [2, n]) {
      const shots = {};
      for (const m of ['tiles-lod', 'tiles-lap']) {
        await page.goto(`${server.pagesUrl}viewer.html?material=${m}&geometry=plane&light=fixed&light-theta=40` +
          `&light-phi=-60&camera-theta=30&width=256&height=256&max-dpr=1&repeat=4&budget-chunks=${chunks}`);
        await waitFor(page, (k) => {
          const v = window.__btf && window.__btf.viewers()[0];
          return v && v.drawnChunks === k && v.frames > 0;
        }, chunks, `${m} drawn with ${chunks} chunks`);
        const v = (await viewers(page))[0];
        assert.equal(v.error, null);
        shots[m] = await capture(page, 0);
      }
      const d = meanAbsDiff(shots['tiles-lod'], shots['tiles-lap']);
      console.log(`# version 4 vs version 2, ${chunks} of ${n} chunks: mean |difference| ${d.toFixed(4)} of 255`);
      assert.ok(d < 0.01, `the same pixels (${d})`);
    }
    assertClean(desktop);
  });
});
