// rd.test.mjs - a version-3 package (doc/package-format.md section 9.3: wt-JJ.z or
// wt-JJ.pz weights, inflated by the browser's DecompressionStream, or wt-JJ.webp ones,
// section 5.5, decoded by the browser's image decoder; what `btf compress` writes
// by default), the same with lossy WebP textures (section 4.1: the default where they
// win) or lossy AVIF ones (--avif), and the version-4 package with levels over it in
// headless Chromium against a real btfd: each streams completely and draws the image
// its version-1 twin (the same source, equal-noise steps, raw weights: --plain) draws,
// up to quantisation; the client's decode of each lossy texture and of each wt-JJ.webp
// (lossless or lossy) is the C reader's, exactly, and a wt-JJ.webp not opaque is refused;
// version 4's lossy wt-JJ-8.webp (the same files under levels) draws as well.
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
// 1 when it is an AVIF: named .avif, its first box an 'ftyp' of major brand 'avif' (section 4.1).
const isAvif = (dir, f) => f.endsWith('.avif') &&
  fs.readFileSync(path.join(dir, f)).subarray(4, 12).toString('latin1') === 'ftypavif';
// The manifest of package `name` in the library.
const manifestOf = (name) => JSON.parse(fs.readFileSync(path.join(lib.lib, name, 'manifest.json'), 'utf8'));
// The chunks' texture files of package `name` in the library that pass test(dir, f).
function textures(name, test) {
  const dir = path.join(lib.lib, name);
  return manifestOf(name).chunks.map((c) => ({file: c.files[0], level: c.level ?? 0})).filter((t) => test(dir, t.file));
}
// The chunks' 16-bit weights files of package `name` (wt-*, not the 8-bit wt-JJ-8.png).
const weightFiles = (name) => manifestOf(name).chunks.flatMap((c) => c.files)
  .filter((f) => f.startsWith('wt-') && !f.endsWith('-8.png'));

before(async () => {
  requireBuild();
  lib = makeLibrary({tiles: ['tiles', 4, 0, ['--plain']], 'tiles-rd': ['tiles', 4, 0, ['--lossless']],
    // at 32 texels a side lossy textures win for coarser steps than the default's
    'tiles-rdl': ['tiles', 4, 2], 'tiles-lossy': ['tiles', 4, 0, ['--tex-noise', '1']],
    // coarser: lossy weights win too (section 5.5)
    'tiles-lossyw': ['tiles', 4, 0, ['--tex-noise', '2']],
    // and with levels: those files as wt-JJ-8.webp, no 16-bit weights after them (5.2, 7.1)
    'tiles-lossywl': ['tiles', 4, 2, ['--tex-noise', '2']],
    // fine steps: weight codes above 255, so wt-JJ.pz or wt-JJ.z (no wt-JJ.webp)
    'tiles-fine': ['tiles', 4, 0, ['--tex-noise', '0.05']],
    // and with levels: a lossy component's coarse levels lossy too (package-format.md
    // 10.7); the choice weighs lossy textures with their levels, so a coarser noise
    'tiles-lossyl': ['tiles', 4, 2, ['--tex-noise', '1.5']],
    // the same two with AVIF for every lossy texture
    'tiles-avif': ['tiles', 4, 0, ['--tex-noise', '1', '--avif']],
    'tiles-avifl': ['tiles', 4, 2, ['--tex-noise', '1.5', '--avif']]});
  // tiles-avif with a second texture no browser decodes (its boxes zeroed after 'ftyp avif'),
  // as an AVIF is to a browser without an AVIF decoder
  const cut = path.join(lib.lib, 'tiles-avifcut'), file = path.join(cut, 'tex-01.avif');
  fs.cpSync(path.join(lib.lib, 'tiles-avif'), cut, {recursive: true});
  fs.writeFileSync(file, fs.readFileSync(file).fill(0, 28));
  server = await startServer(lib.lib);
  desktop = await launch();
  await desktop.addInitScript(() => { window.__btfCache = false; });
});

after(async () => {
  await desktop?.close();
  await server?.stop();
  lib?.remove();
});

// Each package of `names` streamed completely and drawn (a plane under a fixed light,
// 256 x 256): name -> its capture. `levels`: those with levels (more than 4 chunks).
async function drawAll(names, levels) {
  const page = await newPage(desktop);
  await page.setViewportSize({width: 400, height: 400});
  const shots = {};
  for (const m of names) {
    await page.goto(`${server.pagesUrl}viewer.html?material=${m}&geometry=plane&light=fixed&light-theta=40` +
      '&light-phi=-60&camera-theta=30&width=256&height=256&max-dpr=1');
    await waitFor(page, () => {
      const v = window.__btf && window.__btf.viewers()[0];
      return v && v.complete && v.drawnChunks === v.ownLimit && v.drawnChunks === v.manifestChunks && v.frames > 0;
    }, null, `${m} drawn completely`);
    const v = (await viewers(page))[0];
    assert.equal(v.error, null);
    assert.equal(v.drawnChunks, levels.includes(m) ? v.manifestChunks : 4);
    if (levels.includes(m)) assert.ok(v.manifestChunks > 4, 'levels add chunks');
    shots[m] = await capture(page, 0);
  }
  return shots;
}

// The client's own decoder (client/btf-decode.js, its worker, the type its imageType
// gives) on each of `files` of package `name`, R as btf-gl.js readGrey takes it, against
// the C reader's bytes: `btf lod --levels 1 --png` reads the package through
// btf_package_read and writes each level-0 atlas as the PNG of its decoded bytes.
// Returns the MIME types used and at how many texels G differs from R.
async function decodesAsReader(name, files) {
  const dir = path.join(lib.lib, name), ref = path.join(lib.dir, `${name}-ref`);
  const r = spawnSync(BTF, ['lod', dir, ref, '--levels', '1', '--png', '--quiet'], {encoding: 'utf8'});
  assert.equal(r.status, 0, `btf lod: ${r.stderr}`);
  const page = await newPage(desktop);
  await page.goto(`${server.pagesUrl}viewer.html?material=tiles&width=64&height=64`);
  let g = 0;
  const types = new Set();
  for (const f of files) {
    const got = await page.evaluate(async ([url, file, b64]) => {
      const {decodeImage, imageType} = await import(url);
      const type = imageType(file);
      const d = await decodeImage(Uint8Array.from(atob(b64), (c) => c.charCodeAt(0)), type);
      const q = new Array(d.width * d.height);
      let rg = 0;
      for (let i = 0; i < q.length; i++) {
        q[i] = d.rgba[4 * i];
        rg += d.rgba[4 * i + 1] !== q[i];
      }
      return {type, width: d.width, height: d.height, q, rg};
    }, [`${server.url}btf-decode.js`, f, fs.readFileSync(path.join(dir, f)).toString('base64')]);
    const png = readPng(path.join(ref, f.replace(/\.(webp|avif)$/, '.png')));
    assert.deepEqual([got.width, got.height], [png.width, png.height], f);
    let differ = 0;
    for (let i = 0; i < got.q.length; i++) differ += got.q[i] !== png.data[4 * i];
    assert.equal(differ, 0, `${f}: ${differ} texels differ from the C reader's`);
    g += got.rg;
    types.add(got.type);
  }
  return {types: [...types], g};
}

// The client's decode of each wt-JJ.webp of package `name` (checked, decoded by the
// browser's image decoder, dequantised) against the C reader's weights: `btf lod --levels 1`
// reads the package through btf_package_read and writes its 16-bit weights again in a zlib
// coding (version 4: wt-JJ.z, wt-JJ.pz). Returns per chunk {file, lossy, ...}.
async function weightsAsReader(name) {
  const dir = path.join(lib.lib, name), ref = path.join(lib.dir, `${name}-wref`);
  const r = spawnSync(BTF, ['lod', dir, ref, '--levels', '1', '--quiet'], {encoding: 'utf8'});
  assert.equal(r.status, 0, `btf lod: ${r.stderr}`);
  const m = manifestOf(name), mr = JSON.parse(fs.readFileSync(path.join(ref, 'manifest.json'), 'utf8'));
  const b64 = (d, f) => fs.readFileSync(path.join(d, f)).toString('base64');
  const files = m.chunks.map((c) => c.files.find((f) => f.startsWith('wt-'))).filter((f) => f.endsWith('.webp'));
  assert.ok(files.length >= 2, `${name}: wt-JJ.webp weights (${files})`);
  assert.ok(mr.chunks.every((c) => /^wt-\d+\.p?z$/.test(c.files.find((f) => f.startsWith('wt-')))), 'the reference\'s in zlib');
  const page = await newPage(desktop);
  await page.goto(`${server.pagesUrl}viewer.html?material=tiles&width=64&height=64`);
  const got = await page.evaluate(async ([base, m, mr, wt, wtRef]) => {
    const {decodeImage} = await import(`${base}btf-decode.js`);
    const P = await import(`${base}btf-package.js`);
    const bytes = (s) => Uint8Array.from(atob(s), (c) => c.charCodeAt(0));
    const pkg = P.parseManifest(m), pr = P.parseManifest(mr), out = [];
    for (const c of pkg.chunks.filter((x) => wt[x.wt])) {
      const file = bytes(wt[c.wt]);
      P.checkWeightsWebp(pkg, c, file, c.wt);
      const d = await decodeImage(file, 'image/webp', true);
      const w = P.dequantWeightsW(pkg, c, d.width, d.height, d.rgba);
      const rc = pr.chunks.find((x) => x.component === c.component && x.wt);
      const want = await P.decodeWeights(pr, rc, bytes(wtRef[rc.wt]));
      let differ = 0;
      for (let i = 0; i < want.length; i++) differ += w[i] !== want[i];
      const lossy = String.fromCharCode(...file.subarray(12, 16)) === 'VP8 ';
      out.push({file: c.wt, ref: rc.wt, n: w.length, nRef: want.length, differ, lossy});
    }
    return out;
  }, [server.url, m, mr, Object.fromEntries(files.map((f) => [f, b64(dir, f)])),
    Object.fromEntries(mr.chunks.map((c) => c.files.find((f) => f.startsWith('wt-'))).map((f) => [f, b64(ref, f)]))]);
  assert.equal(got.length, files.length);
  for (const g of got) {
    assert.ok(g.n === g.nRef && g.n === 81 * 81 * 3, `${g.file}: ${g.n} weights, the reference ${g.nRef}`);
    assert.equal(g.differ, 0, `${g.file}: ${g.differ} weights differ from the C reader's (${g.ref})`);
  }
  console.log(`# ${name}: ${got.length} wt-JJ.webp files (${got.filter((g) => g.lossy).length} lossy) decoded to ` +
    `the C reader's weights (${got.map((g) => g.ref).join(', ')})`);
  assertClean(desktop);
  return got;
}


describe('version 3 (wt-JJ.z, wt-JJ.pz or wt-JJ.webp weights)', () => {
  it('streams, decodes and draws as its version-1 twin does, with levels too', async () => {
    // the writer keeps the smallest coding of each component's weights: at this size
    // wt-JJ.webp (section 5.5), which the browser's image decoder reads
    const webp = ['tiles-rd', 'tiles-lossy'].flatMap((m) => weightFiles(m).filter((f) => /^wt-.*\.webp$/.test(f)));
    assert.ok(webp.length >= 1, 'a version-3 package drawn carries wt-JJ.webp weights (the test covers them)');
    console.log(`# ${webp.length} wt-JJ.webp weights files among the version-3 packages drawn`);
    const zlib = weightFiles('tiles-fine').filter((f) => /^wt-.*\.p?z$/.test(f));
    assert.ok(zlib.length >= 1, 'a version-3 package drawn carries wt-JJ.pz or wt-JJ.z weights (the test covers them)');
    const shots = await drawAll(['tiles', 'tiles-rd', 'tiles-rdl', 'tiles-lossy', 'tiles-lossyl', 'tiles-fine', 'tiles-lossyw',
      'tiles-lossywl'], ['tiles-rdl', 'tiles-lossyl', 'tiles-lossywl']);
    // Finer steps than the default's: closer to the float model, the same bound.
    const df = meanAbsDiff(shots.tiles, shots['tiles-fine']);
    console.log(`# version 3 with ${zlib.length} zlib weights files vs version 1: mean |difference| ${df.toFixed(3)} of 255`);
    assert.ok(df < 3, `version-3 image with zlib weights within 3 levels of version 1 (${df})`);
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
    const coarse = textures('tiles-lossyl', isLossy).filter((t) => t.level > 0);
    assert.ok(coarse.length >= 1, 'the package has lossy coarse levels (the test covers them)');
    const dll = meanAbsDiff(shots.tiles, shots['tiles-lossyl']);
    console.log(`# ${coarse.length} lossy coarse levels: mean |difference| ${dll.toFixed(3)} of 255 from version 1`);
    assert.ok(dll < 3, `lossy levels within 3 levels of version 1 (${dll})`);
    const lw = weightFiles('tiles-lossyw').filter((f) => isLossy(path.join(lib.lib, 'tiles-lossyw'), f));
    assert.ok(lw.length >= 1, 'the package has lossy weights (the test covers them)');
    const dw = meanAbsDiff(shots.tiles, shots['tiles-lossyw']);
    console.log(`# ${lw.length} lossy weights files (noise 2): mean |difference| ${dw.toFixed(3)} of 255 from version 1`);
    assert.ok(dw < 3, `lossy weights within 3 levels of version 1 (${dw})`); // 0.81 measured; a wrong decode: tens
    // Under levels the lossy files are the coarse chunks' wt-JJ-8.webp, and no chunk
    // after them carries weights for those components: drawn with the 8-bit weights.
    const wl = manifestOf('tiles-lossywl').chunks, wlDir = path.join(lib.lib, 'tiles-lossywl');
    const lw8 = wl.flatMap((c) => c.files).filter((f) => f.endsWith('-8.webp') && isLossy(wlDir, f));
    assert.ok(lw8.length >= 1, 'the levelled package has lossy wt-JJ-8.webp weights (the test covers them)');
    assert.ok(wl.some((c) => c.level === 0 && c.files.length === 1), 'a level-0 chunk without weights');
    const dwl = meanAbsDiff(shots.tiles, shots['tiles-lossywl']);
    console.log(`# ${lw8.length} lossy wt-JJ-8.webp under levels: mean |difference| ${dwl.toFixed(3)} of 255 from version 1`);
    assert.ok(dwl < 3, `lossy weights under levels within 3 levels of version 1 (${dwl})`);
    assertClean(desktop);
  });
});

// A simple-format WebP (RIFF, WEBP, one chunk) holding the chunk `tag` ('VP8L' or 'VP8 ') of
// WebP file b, which may be an extended one (VP8X: Chromium writes one for an image with alpha).
function simpleWebp(b, tag) {
  for (let o = 12; o + 8 <= b.length;) {
    const t = b.toString('latin1', o, o + 4), n = b.readUInt32LE(o + 4), end = o + 8 + n + (n & 1);
    if (t === tag) {
      const out = Buffer.alloc(12 + end - o);
      out.write('RIFF', 0);
      out.writeUInt32LE(out.length - 8, 4);
      out.write('WEBP', 8);
      b.copy(out, 12, o, end);
      return out;
    }
    o = end;
  }
  throw new Error(`no ${tag} chunk in the WebP file`);
}

describe('wt-JJ.webp weights (version 3, section 5.5)', () => {
  it('the client decodes each wt-JJ.webp to the C reader\'s weights, exactly: lossless ones', async () => {
    const got = await weightsAsReader('tiles-rd');
    assert.ok(got.every((g) => !g.lossy), 'tiles-rd (--lossless): every wt-JJ.webp lossless');
  });

  it('the client decodes each wt-JJ.webp to the C reader\'s weights, exactly: lossy ones', async () => {
    const got = await weightsAsReader('tiles-lossyw');
    assert.ok(got.some((g) => g.lossy), `tiles-lossyw: lossy weights chosen (${got.map((g) => g.file)})`);
  });

  it('a wt-JJ.webp with a pixel that is not opaque: one final error event naming it', async () => {
    const page = await newPage(desktop);
    await page.goto(`${server.pagesUrl}viewer.html?material=tiles&width=64&height=64`);
    // L x V = 81 x 81 pixels from Chromium's own WebP encoder: quality 1 is lossless
    const encode = (alpha, quality) => page.evaluate(async ([alpha, quality]) => {
      const c = new OffscreenCanvas(81, 81), d = new ImageData(81, 81);
      for (let i = 0; i < d.data.length; i++) d.data[i] = i % 4 === 3 ? 255 : (i * 37) & 127;
      d.data[4 * 100 + 3] = alpha;
      c.getContext('2d').putImageData(d, 0, 0);
      return Array.from(new Uint8Array(await (await c.convertToBlob({type: 'image/webp', quality})).arrayBuffer()));
    }, [alpha, quality]).then((a) => Buffer.from(a));
    // (a lossy wt-JJ.webp is a valid one, section 5.5; a lossy wt-JJ-8.webp is refused: modules.test.mjs)
    const cases = {'tiles-wtalpha': [simpleWebp(await encode(128, 1), 'VP8L'), /pixel 100 is not opaque \(alpha 128\)/]};
    const second = manifestOf('tiles-rd').chunks[1].files.find((f) => f.startsWith('wt-'));
    assert.match(second, /^wt-\d+\.webp$/);
    for (const [name, [file]] of Object.entries(cases)) {
      fs.cpSync(path.join(lib.lib, 'tiles-rd'), path.join(lib.lib, name), {recursive: true});
      fs.writeFileSync(path.join(lib.lib, name, second), file);
    }
    server.proc.kill('SIGHUP'); // btfd rescans the library
    await waitFor(page, async (url) => {
      const list = await (await fetch(url)).text();
      return list.includes('"tiles-wtalpha"');
    }, `${server.url}materials`, 'btfd lists the new packages');
    for (const [name, [, reason]] of Object.entries(cases)) {
      const p = await desktop.newPage();
      await p.addInitScript(() => {
        window.__events = [];
        document.addEventListener('error', (e) => window.__events.push(e.detail));
      });
      await p.goto(`${server.pagesUrl}viewer.html?material=${name}&geometry=plane&light=fixed&width=256&height=256`);
      await waitFor(p, () => window.__events.length > 0 && window.__btf.viewers()[0].frames > 0, null, `${name}: the error`);
      await new Promise((r) => setTimeout(r, 500));
      const ev = await p.evaluate(() => window.__events), v = (await viewers(p))[0];
      assert.equal(ev.length, 1, JSON.stringify(ev));
      // (the copy keeps the manifest's "name", which the message gives)
      assert.ok(ev[0].reason.startsWith(`package tiles-rd: ${second}: `) && reason.test(ev[0].reason), ev[0].reason);
      assert.equal(ev[0].retrying, undefined, 'final, not retried');
      assert.equal(v.drawnChunks, 1, 'chunk 0 drawn, nothing after the one that failed');
      console.log(`# ${name}: error "${v.error}", ${v.drawnChunks} chunk drawn`);
      await p.close();
    }
    assertClean(desktop);
  });
});

describe('lossy WebP textures', () => {
  it('the client decodes each lossy texture to the C reader\'s bytes', async () => {
    const lossy = textures('tiles-lossy', isLossy).map((t) => t.file);
    assert.ok(lossy.length >= 1, 'the package has lossy textures (the test covers them)');
    const {types, g} = await decodesAsReader('tiles-lossy', lossy);
    assert.deepEqual(types, ['image/webp']);
    console.log(`# ${lossy.length} lossy textures decoded as the C reader does; G differs from R at ${g} texels`);
    assertClean(desktop);
  });
});

describe('lossy AVIF textures (--avif)', () => {
  // Each lossy texture of `name` an AVIF (level 0 and, with levels, coarse levels), no
  // lossy WebP: the AVIF files of the package.
  function avifOnly(name) {
    const avif = textures(name, isAvif);
    assert.ok(avif.some((t) => t.level === 0), `${name} has AVIF level-0 textures (the test covers them)`);
    assert.deepEqual(textures(name, isLossy), [], `${name} has no lossy WebP`);
    return avif;
  }

  it('the client decodes each AVIF texture to the C reader\'s bytes (G = R)', async () => {
    const avif = avifOnly('tiles-avif').map((t) => t.file);
    const {types, g} = await decodesAsReader('tiles-avif', avif);
    assert.deepEqual(types, ['image/avif']);
    assert.equal(g, 0, 'a monochrome AVIF decodes to R = G = B');
    console.log(`# ${avif.length} AVIF textures decoded as the C reader does`);
    assertClean(desktop);
  });

  it('streams and draws within 3 levels of version 1, with lossy AVIF coarse levels too', async () => {
    avifOnly('tiles-avif');
    const coarse = avifOnly('tiles-avifl').filter((t) => t.level > 0);
    assert.ok(coarse.length >= 1, 'the package has AVIF coarse levels (the test covers them)');
    const shots = await drawAll(['tiles', 'tiles-avif', 'tiles-avifl'], ['tiles-avifl']);
    for (const m of ['tiles-avif', 'tiles-avifl']) {
      const d = meanAbsDiff(shots.tiles, shots[m]);
      console.log(`# ${m} vs version 1: mean |difference| ${d.toFixed(3)} of 255` +
        (m === 'tiles-avifl' ? ` (${coarse.length} AVIF coarse levels)` : ''));
      assert.ok(d < 3, `${m} image within 3 levels of version 1 (${d})`);
    }
    assertClean(desktop);
  });

  it('a texture the browser cannot decode: one final error event naming it, the chunks before it drawn', async () => {
    const page = await desktop.newPage();
    await page.addInitScript(() => {
      window.__events = [];
      for (const t of ['load', 'complete', 'error'])
        document.addEventListener(t, (e) => window.__events.push({type: t, detail: e.detail}));
    });
    await page.goto(`${server.pagesUrl}viewer.html?material=tiles-avifcut&geometry=plane&light=fixed&width=256&height=256`);
    await waitFor(page, () => window.__events.some((e) => e.type === 'error') && window.__btf.viewers()[0].frames > 0,
      null, 'the error and a frame');
    await new Promise((r) => setTimeout(r, 1000)); // nothing follows it
    const ev = await page.evaluate(() => window.__events), v = (await viewers(page))[0];
    const errors = ev.filter((e) => e.type === 'error');
    assert.equal(errors.length, 1, JSON.stringify(ev));
    assert.match(errors[0].detail.reason, /^package tiles-avif: tex-01\.avif: /);
    assert.equal(errors[0].detail.retrying, undefined, 'final, not retried');
    assert.equal(v.error, errors[0].detail.reason);
    assert.equal(v.message, v.error, 'the reason shows over the viewer');
    assert.equal(v.drawnChunks, 1, 'chunk 0 (tex-00.avif) drawn, nothing after the one that failed');
    console.log(`# an undecodable AVIF: error "${v.error}", ${v.drawnChunks} chunk drawn`);
    await page.close();
    assertClean(desktop);
  });
});
