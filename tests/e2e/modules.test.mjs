// modules.test.mjs - the client's browser-free modules in node: manifest validation
// and weight dequantisation (client/btf-package.js), shader assembly and compiler-log
// mapping (client/btf-gl.js), budget merging (client/btf-stream.js), the HTTP transport's
// budget, priority and URL rules (client/btf-http.js), ray casts and
// meshes (client/scene.js), direction tables (client/btf-dirtab.js). No server, no browser.
import assert from 'node:assert/strict';
import child from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import {describe, it} from 'node:test';
import zlib from 'node:zlib';
import {BTF, ROOT, writeSpiralList} from './util.mjs';

const pkgMod = await import('../../client/btf-package.js');
globalThis.WebSocket ??= class {}; // btf-stream.js only needs it when connecting
const streamMod = await import('../../client/btf-stream.js');
const httpMod = await import('../../client/btf-http.js');
const glMod = await import('../../client/btf-gl.js');
const scene = await import('../../client/scene.js');

const UBO = {rings: [{theta: 0, count: 1, phi_offset: 0}, {theta: 15, count: 6, phi_offset: 0},
  {theta: 30, count: 12, phi_offset: 0}, {theta: 45, count: 18, phi_offset: 0}, {theta: 60, count: 20, phi_offset: 0},
  {theta: 75, count: 24, phi_offset: 0}]};

// A valid manifest of 81 x 81 directions, k = 3 (27 blocks), 2 chunks.
function manifest() {
  const blocks = Array.from({length: 27}, (_, b) => [3 * b, 3 * b + 1, 3 * b + 2]);
  const ranges = (lo, st) => blocks.map((_, b) => [lo + b, st * (b + 1)]);
  return {format: 'btf-package', version: 1, name: 'm', width: 4, height: 4, lights: structuredClone(UBO),
    views: structuredClone(UBO), bits: 8,
    blocks, atlas: {cols: 6, rows: 5, tile_width: 4, tile_height: 4, width: 24, height: 20, channels: 1},
    chunks: [0, 1].map((j) => ({id: j, component: j, files: [`tex-0${j}.png`, `wt-0${j}.bin`], bytes: 1000 + j,
      rmse: 10 - j, lab: 3 - j, tex_range: ranges(0, 0.01), wt_range: ranges(-2.5, 1e-4)}))};
}

describe('btf-package.js', () => {
  it('parses a valid manifest: ring starts, view blocks, ranges', () => {
    const p = pkgMod.parseManifest(manifest());
    assert.equal(p.lights.dirs, 81);
    assert.deepEqual([...p.lights.rings.subarray(0, 24)].filter((_, i) => i % 4 === 3), [0, 1, 7, 19, 37, 57]);
    assert.equal(p.viewBlock[80], 26);
    assert.equal(p.nBlocks, 27);
    assert.equal(p.totalBytes, 2001);
    assert.equal(pkgMod.chunksWithinBytes(p, 1000), 1);
    assert.equal(pkgMod.chunksWithinBytes(p, 999), 0);
    assert.equal(pkgMod.chunksWithinBytes(p, -1), 2);
    assert.equal(pkgMod.promisedError(p, 2).lab, 2);
  });

  it('refuses manifests outside the format', () => {
    const bad = [
      (m) => { m.version = 4; }, (m) => { m.version = 3; }, (m) => { m.format = 'x'; }, (m) => { m.width = 0; },
      (m) => { m.bits = 12; }, (m) => { m.blocks[0] = [0, 1]; }, (m) => { m.blocks[1][0] = 0; },
      (m) => { m.atlas.cols = 2; }, (m) => { m.chunks = []; }, (m) => { m.chunks[0].files = ['../x.png', 'wt-00.bin']; },
      (m) => { m.chunks[1].wt_range.pop(); }, (m) => { m.chunks[0].tex_range[3] = [0, -1]; },
      (m) => { m.lights.rings = [{theta: 30, count: 4, phi_offset: 0}, {theta: 15, count: 4, phi_offset: 0}]; },
      (m) => { m.views.rings = Array.from({length: 40}, (_, i) => ({theta: i, count: 1, phi_offset: 0})); },
    ];
    bad.forEach((f, i) => {
      const m = manifest();
      f(m);
      assert.throws(() => pkgMod.parseManifest(m), /package m:/, `case ${i}`);
    });
  });

  it('reads "encoding" as the C reader does: absent or "srgb" sRGB, "linear" linear, anything else refused', () => {
    const withEncoding = (e) => Object.assign(manifest(), e === undefined ? {} : {encoding: e});
    assert.equal(pkgMod.parseManifest(withEncoding(undefined)).linear, false);
    assert.equal(pkgMod.parseManifest(withEncoding('srgb')).linear, false);
    assert.equal(pkgMod.parseManifest(withEncoding('linear')).linear, true);
    for (const e of ['Linear', 'rgb', '', 1, true, null, ['linear'], {linear: 1}])
      assert.throws(() => pkgMod.parseManifest(withEncoding(e)), /package m: "encoding" must be "srgb" or "linear"/,
        JSON.stringify(e));
  });

  it('dequantises weights as lo + step * q in float32 and checks the size', () => {
    const p = pkgMod.parseManifest(manifest());
    const n = 81 * 81 * 3, q = new Uint16Array(n);
    for (let i = 0; i < n; i++) q[i] = (i * 7919) % 65536;
    const buf = Buffer.from(q.buffer);
    const w = pkgMod.dequantWeights(p, p.chunks[1], buf);
    for (const i of [0, 1, 242, 243, 5000, n - 1]) {
      const v = Math.floor(i / (81 * 3)), b = Math.floor(v / 3);
      const lo = Math.fround(-2.5 + b), step = Math.fround(1e-4 * (b + 1));
      const want = lo + step * q[i]; // double: float32 result within its rounding
      assert.ok(Math.abs(w[i] - want) <= 2 * Math.abs(want) * 2 ** -23 + 1e-7, `weight ${i}: ${w[i]} vs ${want}`);
    }
    assert.throws(() => pkgMod.dequantWeights(p, p.chunks[0], buf.subarray(0, n)), /wt-00\.bin has/);
  });
});

// wt-JJ.webp (section 5.5; version 4's wt-JJ-8.webp, 5.2): weight codes of at most 255
// as a lossless WebP of L x V opaque pixels, pixel (x = l, y = v) holding channel c of
// view v, light l in its R, G or B sample. rgba of q as a decoder returns it (4 bytes a
// pixel, rows top-down).
const rgbaOf = (q, L, V) => {
  const rgba = new Uint8Array(4 * L * V).fill(255);
  for (let v = 0; v < V; v++)
    for (let l = 0; l < L; l++)
      for (let c = 0; c < 3; c++) rgba[4 * (v * L + l) + c] = q[(v * L + l) * 3 + c];
  return rgba;
};
// The first bytes of a simple-format WebP: RIFF, WEBP, one chunk `tag` that fills a
// file of n bytes; VP8L: its signature and header for w x h (the rest zeros).
const webpHead = (tag, w, h, n = 64) => {
  const b = Buffer.alloc(n);
  b.write('RIFF', 0);
  b.writeUInt32LE(n - 8, 4);
  b.write('WEBP', 8);
  b.write(tag, 12);
  b.writeUInt32LE(n - 20, 16);
  b[20] = 0x2f;
  b.writeUInt32LE(((w - 1) | ((h - 1) << 14)) >>> 0, 21);
  return b;
};

// The head of a lossy (VP8) WebP of w x h as the format spells it (RFC 9649): a shown key
// frame of version 0 whose first partition (`part` bytes) fits its chunk, then zeros.
const vp8Head = (w, h, n = 64, part = 20) => {
  const b = Buffer.alloc(n);
  b.write('RIFF', 0);
  b.writeUInt32LE(n - 8, 4);
  b.write('WEBP', 8);
  b.write('VP8 ', 12);
  b.writeUInt32LE(n - 20, 16);
  const tag = 0 | (0 << 1) | (1 << 4) | (part << 5); // key frame, version 0, shown
  b[20] = tag & 255, b[21] = (tag >> 8) & 255, b[22] = (tag >> 16) & 255;
  b[23] = 0x9d, b[24] = 0x01, b[25] = 0x2a;
  b.writeUInt16LE(w, 26), b.writeUInt16LE(h, 28);
  return b;
};

// Version 3 of the same package (doc/package-format.md section 11): wt-JJ.z weights.
describe('btf-package.js version 3', () => {
    // q -> wt-JJ.z written from the format text: zigzag differences along the lights, two byte planes, zlib.
  const encode = (q, L) => {
    const n = q.length, raw = new Uint8Array(2 * n);
    for (let i = 0; i < n; i++) {
      let d = q[i] - ((Math.floor(i / 3) % L) > 0 ? q[i - 3] : 0);
      d = ((d + 32768) & 0xffff) - 32768;
      const z = ((d << 1) ^ (d >> 15)) & 0xffff;
      raw[i] = z & 255;
      raw[n + i] = z >> 8;
    }
    return zlib.deflateSync(raw);
  };
  const v3 = () => {
    const m = manifest();
    m.version = 3;
    m.chunks.forEach((c, j) => { c.files = [`tex-0${j}.png`, `wt-0${j}.z`]; });
    return m;
  };
  it('reads as the version-1 layout and needs .z weights', () => {
    const p = pkgMod.parseManifest(v3());
    assert.equal(p.version, 1);
    assert.equal(p.manifestVersion, 3);
    assert.equal(p.chunks[1].wt, 'wt-01.z');
    const bad = v3();
    bad.chunks[0].files[1] = 'wt-00.bin';
    assert.throws(() => pkgMod.parseManifest(bad), /version 3 needs a wt-\*\.z/);
  });
  it('decodes wt-JJ.z to the same Float32Array as the raw 16-bit file', async () => {
    const p = pkgMod.parseManifest(v3()), p1 = pkgMod.parseManifest(manifest());
    const n = 81 * 81 * 3, q = new Uint16Array(n);
    for (let i = 0; i < n; i++) q[i] = i % 5 === 0 ? 0 : i % 5 === 1 ? 65535 : (i * 7919) % 65536; // wrapping differences
    const want = pkgMod.dequantWeights(p1, p1.chunks[1], Buffer.from(q.buffer));
    const got = await pkgMod.decodeWeights(p, p.chunks[1], encode(q, 81));
    assert.deepEqual(got, want);
    await assert.rejects(pkgMod.decodeWeights(p, p.chunks[1], encode(q.subarray(0, n - 3), 81)), /inflates to \d+ bytes/);
    const z = encode(q, 81);
    await assert.rejects(pkgMod.decodeWeights(p, p.chunks[1], z.subarray(0, z.length - 4)), /wt-01\.z/);
    await assert.rejects(pkgMod.decodeWeights(p, p.chunks[1], new Uint8Array(2 * n + 1025)), /bytes, expected 1\.\./);
    const more = new Uint16Array(n + 3);
    more.set(q);
    await assert.rejects(pkgMod.decodeWeights(p, p.chunks[1], encode(more, 81)), /more than/);
  });
  // q -> wt-JJ.pz written from the format text (section 5.4): u = the largest view
  // below v in v's block; prediction a + (b - c) from the previous light a, u's light
  // b and u's previous light c (u's light 0 alone at l = 0, a alone without u);
  // channels 0 and 2 less channel 1's residual; zigzag, two byte planes, zlib.
  const encodeP = (q, L, blockOf) => {
    const n = q.length, V = n / (3 * L), raw = new Uint8Array(2 * n), at = (v, l, c) => q[(v * L + l) * 3 + c];
    const zig = (d) => { d = ((d % 65536) + 65536 + 32768) % 65536 - 32768; return ((d << 1) ^ (d >> 15)) & 0xffff; };
    for (let v = 0; v < V; v++) {
      let u = -1;
      for (let w = 0; w < v; w++) if (blockOf(w) === blockOf(v)) u = w;
      for (let l = 0; l < L; l++) {
        const r = [0, 1, 2].map((c) => {
          const pred = u < 0 ? (l ? at(v, l - 1, c) : 0) : l ? at(v, l - 1, c) + at(u, l, c) - at(u, l - 1, c) : at(u, 0, c);
          return at(v, l, c) - pred;
        });
        [r[0] - r[1], r[1], r[2] - r[1]].forEach((d, c) => {
          const i = (v * L + l) * 3 + c, z = zig(d);
          raw[i] = z & 255;
          raw[n + i] = z >> 8;
        });
      }
    }
    return zlib.deflateSync(raw);
  };
  it('decodes wt-JJ.pz (views of a block not adjacent) to the same Float32Array as the raw 16-bit file', async () => {
    const spread = (m) => {
      m.blocks = Array.from({length: 27}, (_, b) => [b, b + 27, b + 54]);
      return m;
    };
    const m3 = spread(v3());
    m3.chunks.forEach((c, j) => { c.files = [`tex-0${j}.png`, `wt-0${j}.pz`]; });
    const p = pkgMod.parseManifest(m3), p1 = pkgMod.parseManifest(spread(manifest()));
    const n = 81 * 81 * 3, q = new Uint16Array(n);
    for (let i = 0; i < n; i++) q[i] = i % 7 === 0 ? 0 : i % 7 === 1 ? 65535 : (i * 7919 + ((i * i) % 977)) % 65536;
    const want = pkgMod.dequantWeights(p1, p1.chunks[1], Buffer.from(q.buffer));
    const z = encodeP(q, 81, (v) => v % 27);
    assert.deepEqual(await pkgMod.decodeWeights(p, p.chunks[1], z), want);
    // the same bytes read as wt-JJ.z (no view or channel prediction) decode to other weights
    const asZ = pkgMod.parseManifest(spread(v3()));
    assert.notDeepEqual(await pkgMod.decodeWeights(asZ, asZ.chunks[1], z), want);
    await assert.rejects(pkgMod.decodeWeights(p, p.chunks[1], z.subarray(0, z.length - 4)), /wt-01\.pz/);
    await assert.rejects(pkgMod.decodeWeights(p, p.chunks[1], new Uint8Array(2 * n + 1025)), /bytes, expected 1\.\./);
  });
  const v3w = () => {
    const m = v3();
    m.chunks.forEach((c, j) => { c.files = [`tex-0${j}.webp`, `wt-0${j}.webp`]; });
    return m;
  };
  it('gives a version-3 chunk without psnr 20 log10(255 / rmse), as version 1 writes it', () => {
    const m = v3();
    m.chunks.forEach((c, j) => { c.rmse = 10 + j; delete c.psnr; });
    m.chunks[0].rmse = 0;
    const p = pkgMod.parseManifest(m);
    assert.equal(p.chunks[0].psnr, 999);
    for (const c of p.chunks.slice(1)) assert.ok(Math.abs(c.psnr - 20 * Math.log10(255 / c.rmse)) < 1e-12, `${c.psnr}`);
    const given = v3();
    given.chunks[1].psnr = 12.5; // one the manifest gives is kept
    assert.equal(pkgMod.parseManifest(given).chunks[1].psnr, 12.5);
  });
  it('takes wt-JJ.webp as a version-3 chunk\'s weights and tex-JJ.webp as its texture, nowhere else', () => {
    const p = pkgMod.parseManifest(v3w());
    assert.equal(p.chunks[1].wt, 'wt-01.webp');
    assert.equal(p.chunks[1].tex, 'tex-01.webp');
    const swapped = v3w();
    swapped.chunks[0].files.reverse(); // the order of "files" does not matter
    assert.equal(pkgMod.parseManifest(swapped).chunks[0].wt, 'wt-00.webp');
    assert.equal(pkgMod.parseManifest(swapped).chunks[0].tex, 'tex-00.webp');
    const both = v3w(); // a file of section 9.3 or 5.4 comes first (section 7.1)
    both.chunks[0].files = ['wt-00.webp', 'tex-00.webp', 'wt-00.pz'];
    both.chunks[1].files = ['wt-01.webp', 'wt-01.pz', 'tex-01.webp', 'wt-01.z'];
    assert.deepEqual(pkgMod.parseManifest(both).chunks.map((c) => [c.tex, c.wt]),
      [['tex-00.webp', 'wt-00.pz'], ['tex-01.webp', 'wt-01.z']]);
    const noWt = v3w();
    noWt.chunks[0].files = ['tex-00.webp'];
    assert.throws(() => pkgMod.parseManifest(noWt), /package m: chunk 0 lacks a tex-\* or wt-\* file/);
    const v1 = manifest();
    v1.chunks[0].files = ['tex-00.png', 'wt-00.webp'];
    assert.throws(() => pkgMod.parseManifest(v1), /package m: chunk 0: wt-00\.webp: WebP weights are version 3's/);
  });
  it('dequantises wt-JJ.webp pixels to the same Float32Array as the raw 16-bit file', async () => {
    const p = pkgMod.parseManifest(v3w()), p1 = pkgMod.parseManifest(manifest());
    const L = 81, V = 81, n = V * L * 3, q = new Uint16Array(n);
    for (let i = 0; i < n; i++) q[i] = i % 11 === 0 ? 0 : i % 11 === 1 ? 255 : (i * 7919 + ((i * i) % 977)) % 256;
    const want = pkgMod.dequantWeights(p1, p1.chunks[1], Buffer.from(q.buffer));
    const rgba = rgbaOf(q, L, V);
    const got = pkgMod.dequantWeightsW(p, p.chunks[1], L, V, rgba);
    assert.ok(got instanceof Float32Array);
    assert.deepEqual(got, want);
    // pixel (x = 5, y = 7)'s green is view 7, light 5, channel 1, in block 7 / 3 = 2
    const i = (7 * L + 5) * 3 + 1, one = Uint8Array.from(rgba);
    one[4 * (7 * L + 5) + 1] = 200;
    const [lo, step] = p.chunks[1].wtRange.subarray(4, 6);
    assert.equal(lo, -0.5);
    assert.equal(pkgMod.dequantWeightsW(p, p.chunks[1], L, V, one)[i], Math.fround(lo + Math.fround(step * 200)));
    // refusals, each naming the package and the file
    assert.throws(() => pkgMod.dequantWeightsW(p, p.chunks[1], L - 1, V, rgba),
      /package m: wt-01\.webp is 80x81, expected 81x81/);
    assert.throws(() => pkgMod.dequantWeightsW(p, p.chunks[1], V * 3, L / 3, rgba), /package m: wt-01\.webp is 243x27/);
    assert.throws(() => pkgMod.dequantWeightsW(p, p.chunks[1], L, V, rgba.subarray(4)), /wt-01\.webp has \d+ pixel bytes/);
    for (const [px, a] of [[0, 254], [L * V - 1, 0], [1234, 128]]) {
      const t = Uint8Array.from(rgba);
      t[4 * px + 3] = a;
      assert.throws(() => pkgMod.dequantWeightsW(p, p.chunks[0], L, V, t),
        new RegExp(`package m: wt-00\\.webp: pixel ${px} is not opaque \\(alpha ${a}\\)`));
    }
    await assert.rejects(pkgMod.decodeWeights(p, p.chunks[1], Buffer.alloc(10)),
      /package m: wt-01\.webp: WebP weights need/);
  });
  it('checks a wt-JJ.webp file before decoding: simple format, L x V', () => {
    const p = pkgMod.parseManifest(v3w()), c = p.chunks[0];
    pkgMod.checkWeightsWebp(p, c, webpHead('VP8L', 81, 81));
    const bad = [
      [webpHead('VP8X', 81, 81), /WebP chunk 'VP8X' is not a simple lossless/],
      [webpHead('VP8L', 80, 81), /WebP of 80x81, expected 81x81/],
      [webpHead('VP8L', 81, 27), /WebP of 81x27, expected 81x81/],
      [webpHead('VP8L', 81, 81).subarray(0, 60), /RIFF size 56 does not match/],
      [Buffer.from('GIF89a-not-a-webp-file-at-all-xxxx'), /not a WebP file/],
      [Buffer.alloc(0), /has 0 bytes/],
      [Buffer.alloc(2 * 81 * 81 * 3 + 1025), /bytes, expected 1\.\./],
    ];
    for (const [b, re] of bad)
      assert.throws(() => pkgMod.checkWeightsWebp(p, c, b), (e) => /^package m: wt-00\.webp/.test(e.message) &&
        re.test(e.message), String(re));
  });
  it('takes a lossy (VP8) wt-JJ.webp, checked as the C reader checks it', () => {
    const p = pkgMod.parseManifest(v3w()), c = p.chunks[0];
    pkgMod.checkWeightsWebp(p, c, vp8Head(81, 81), c.wt);
    const scaled = vp8Head(81, 81);
    scaled[27] |= 0x40; // a horizontal scale of 1
    const inter = vp8Head(81, 81);
    inter[20] |= 1; // an inter frame
    const bad = [
      [vp8Head(80, 81), /WebP of 80x81, expected 81x81/],
      [scaled, /VP8 frame scaled or empty/],
      [inter, /not a key frame/],
      [vp8Head(81, 81, 64, 40), /first partition of 40 bytes overruns/],
      [Buffer.from(vp8Head(81, 81)).fill(0, 23, 26), /bad VP8 start code/],
    ];
    for (const [b, re] of bad)
      assert.throws(() => pkgMod.checkWeightsWebp(p, c, b, c.wt), (e) => /^package m: wt-00\.webp/.test(e.message) &&
        re.test(e.message), String(re));
  });
  it('decodes the wt-JJ.z and wt-JJ.pz files btf compress --rd writes, every weight within its block range; ' +
     'its wt-JJ.webp files pass the check', async (t) => {
    const btf = BTF;
    if (!fs.existsSync(btf)) return t.skip(`${btf} missing`);
    const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'btf-v3-'));
    try {
      child.execFileSync(btf, ['compress', 'gen:stone:8:901', path.join(dir, 'p'), '--rd', '--components', '3', '--quiet']);
      const m = JSON.parse(fs.readFileSync(path.join(dir, 'p', 'manifest.json'), 'utf8'));
      const p = pkgMod.parseManifest(m);
      for (const c of p.chunks) {
        if (c.wt.endsWith('.webp')) { // an image: decoded by the browser (rd.test.mjs)
          pkgMod.checkWeightsWebp(p, c, fs.readFileSync(path.join(dir, 'p', c.wt)), c.wt);
          continue;
        }
        const w = await pkgMod.decodeWeights(p, c, fs.readFileSync(path.join(dir, 'p', c.wt)));
        for (let v = 0; v < p.views.dirs; v++) {
          const b = p.viewBlock[v], lo = c.wtRange[2 * b], hi = lo + 65535 * c.wtRange[2 * b + 1];
          for (let i = v * p.lights.dirs * 3; i < (v + 1) * p.lights.dirs * 3; i++)
            assert.ok(w[i] >= lo && w[i] <= hi * (1 + 1e-6) + 1e-12, `chunk ${c.id} weight ${i}`);
        }
      }
    } finally {
      fs.rmSync(dir, {recursive: true, force: true});
    }
  });
});

// Version 2 of the same package: 2 components x 2 levels, compact "ranges", 8-bit
// coarse weights (doc/package-format.md section 10).
// Component c's "ranges" entry: 27 blocks of (c + b, 0.01 (b + 1), -2.5 - c, 1e-4 (b + 1)).
function compactRanges(c) {
  const f = new Float32Array(27 * 4);
  for (let b = 0; b < 27; b++) f.set([c + b, 0.01 * (b + 1), -2.5 - c, 1e-4 * (b + 1)], 4 * b);
  return Buffer.from(f.buffer).toString('base64');
}

function manifestV2() {
  const m = manifest();
  m.version = 2;
  m.levels = 2;
  m.ranges = [compactRanges(0), compactRanges(1)];
  m.weights8_step = [257, 514];
  m.chunks = [
    {component: 0, level: 1, files: ['tex-00-l1.png', 'wt-00-8.png'], bytes: 10, rmse: 9, contrib: 50},
    {component: 1, level: 1, files: ['tex-01-l1.png', 'wt-01-8.png'], bytes: 11, rmse: 8, contrib: 3},
    {component: 0, level: 0, files: ['tex-00.png', 'wt-00.bin'], bytes: 20, rmse: 5, contrib: 50},
    {component: 1, level: 0, files: ['tex-01.png', 'wt-01.bin'], bytes: 21, rmse: 4, contrib: 0.5}];
  return m;
}

// Version 3 as written since 2026-12-07: the ranges in the header (section 9.3), one
// entry per component, empty for a component no chunk has (a budget cut it).
function manifestV3() {
  const m = manifest();
  m.version = 3;
  m.ranges = [compactRanges(0), compactRanges(1), ''];
  for (const c of m.chunks) {
    c.files[1] = c.files[1].replace('.bin', '.z');
    delete c.tex_range;
    delete c.wt_range;
  }
  return m;
}

describe('btf-package.js version 3', () => {
  it('takes the ranges from the header by component, bit-exact, and still reads them per chunk', () => {
    const p = pkgMod.parseManifest(manifestV3());
    assert.equal(p.manifestVersion, 3);
    assert.equal(p.chunks[1].texRange[10], Math.fround(1 + 5));
    assert.equal(p.chunks[1].texRange[11], Math.fround(0.01 * 6));
    assert.equal(p.chunks[1].wtRange[10], Math.fround(-3.5));
    assert.equal(p.chunks[0].wtRange[11], Math.fround(1e-4 * 6));
    const older = manifestV3(); // the per-chunk form of version 1, which writers before wrote
    delete older.ranges;
    for (const c of older.chunks) {
      const j = c.component;
      c.tex_range = Array.from({length: 27}, (_, b) => [j + b, Math.fround(0.01 * (b + 1))]);
      c.wt_range = Array.from({length: 27}, (_, b) => [-2.5 - j, Math.fround(1e-4 * (b + 1))]);
    }
    const q = pkgMod.parseManifest(older);
    for (let i = 0; i < 2; i++) {
      assert.deepEqual(q.chunks[i].texRange, p.chunks[i].texRange, `chunk ${i}`);
      assert.deepEqual(q.chunks[i].wtRange, p.chunks[i].wtRange, `chunk ${i}`);
    }
  });

  it('refuses a chunk whose component has no entry, an empty one or a short one', () => {
    const bad = [
      (m) => { delete m.ranges; }, (m) => { m.ranges[1] = ''; }, (m) => { m.ranges = [m.ranges[0]]; },
      (m) => { m.ranges[0] = m.ranges[0].slice(4); }, (m) => { m.chunks[1].component = 2; },
    ];
    bad.forEach((f, i) => {
      const m = manifestV3();
      f(m);
      assert.throws(() => pkgMod.parseManifest(m), /package m:/, `case ${i}`);
    });
  });
});

describe('btf-package.js version 2', () => {
  it('parses levels, per-component ranges and the 8-bit weight steps', () => {
    const p = pkgMod.parseManifest(manifestV2());
    assert.equal(p.version, 2);
    assert.equal(p.levels, 2);
    assert.deepEqual(p.components, [0, 1]);
    assert.deepEqual(p.chunks.map((c) => [c.component, c.level, c.tex, c.wt ?? null, c.wt8 ?? null]),
      [[0, 1, 'tex-00-l1.png', null, 'wt-00-8.png'], [1, 1, 'tex-01-l1.png', null, 'wt-01-8.png'],
        [0, 0, 'tex-00.png', 'wt-00.bin', null], [1, 0, 'tex-01.png', 'wt-01.bin', null]]);
    // ranges of component 1, block 5, decoded from base64 float32 (bit-exact)
    assert.equal(p.chunks[3].texRange[10], Math.fround(1 + 5));
    assert.equal(p.chunks[3].texRange[11], Math.fround(0.01 * 6));
    assert.equal(p.chunks[1].wtRange[10], Math.fround(-3.5));
    assert.equal(p.chunks[1].wtRange[11], Math.fround(1e-4 * 6));
    assert.equal(p.chunks[1].wt8Step, 514);
    assert.equal(p.totalBytes, 62);
  });

  it('refuses version-2 manifests outside the format', () => {
    const bad = [
      (m) => { delete m.levels; }, (m) => { m.levels = 4; }, // 4 x 4 texels: at most 3 levels
      (m) => { m.chunks[0].level = 2; }, (m) => { m.ranges = [m.ranges[0]]; },
      (m) => { m.ranges[0] = m.ranges[0].slice(4); }, (m) => { m.ranges[1] = 'not base64!'; },
      (m) => { m.weights8_step = [257, 70000]; }, (m) => { m.chunks[2].files = ['wt-00.bin']; },
      (m) => { m.chunks[0].component = -1; },
    ];
    bad.forEach((f, i) => {
      const m = manifestV2();
      f(m);
      assert.throws(() => pkgMod.parseManifest(m), /package m:/, `case ${i}`);
    });
  });

  it('dequantises 8-bit weights as lo + (s_c * step) * q in float32', () => {
    const p = pkgMod.parseManifest(manifestV2());
    const n = 81 * 81 * 3, q = new Uint8Array(n);
    for (let i = 0; i < n; i++) q[i] = (i * 31) % 256;
    const w = pkgMod.dequantWeights8(p, p.chunks[1], q);
    for (const i of [0, 1, 242, 243, 5000, n - 1]) {
      const v = Math.floor(i / (81 * 3)), b = Math.floor(v / 3);
      const want = -3.5 + 514 * 1e-4 * (b + 1) * q[i]; // double: float32 result within its rounding
      assert.ok(Math.abs(w[i] - want) <= 4 * Math.abs(want) * 2 ** -23 + 1e-6, `weight ${i}: ${w[i]} vs ${want}`);
    }
    assert.throws(() => pkgMod.dequantWeights8(p, p.chunks[1], q.subarray(1)), /wt-01-8\.png has/);
  });

  // Version 4 (section 12) with the 8-bit weights as wt-JJ-8.webp (section 5.2) and the
  // 16-bit ones as residuals over them.
  const v4w = () => {
    const m = manifestV2();
    m.version = 4;
    m.chunks.forEach((c) => { c.files = c.files.map((f) => f.replace('-8.png', '-8.webp').replace('.bin', '-r.z')); });
    return m;
  };
  it('version 4: wt-JJ-8.webp as the 8-bit weights, its pixels in wt-JJ-8.png\'s order, checked as wt-JJ.webp', () => {
    const p = pkgMod.parseManifest(v4w()), p2 = pkgMod.parseManifest(manifestV2());
    assert.deepEqual(p.chunks.map((c) => [c.tex, c.wt ?? null, c.wt8 ?? null]),
      [['tex-00-l1.png', null, 'wt-00-8.webp'], ['tex-01-l1.png', null, 'wt-01-8.webp'],
        ['tex-00.png', 'wt-00-r.z', null], ['tex-01.png', 'wt-01-r.z', null]]);
    const both = v4w(); // a chunk listing both: the PNG (section 7.1)
    both.chunks[0].files = ['wt-00-8.webp', 'tex-00-l1.png', 'wt-00-8.png'];
    assert.equal(pkgMod.parseManifest(both).chunks[0].wt8, 'wt-00-8.png');
    const v2 = manifestV2(); // not in version 2: read as 16-bit weights, which WebP are only in version 3
    v2.chunks[0].files[1] = 'wt-00-8.webp';
    assert.throws(() => pkgMod.parseManifest(v2), /package m: chunk 0: wt-00-8\.webp: WebP weights are version 3's/);
    const L = 81, V = 81, n = V * L * 3, q = new Uint8Array(n);
    for (let i = 0; i < n; i++) q[i] = (i * 7919 + ((i * i) % 977)) % 256;
    const rgba = rgbaOf(q, L, V), q8 = pkgMod.weights8Webp(p, p.chunks[1], L, V, rgba);
    assert.deepEqual(q8, q);
    assert.deepEqual(pkgMod.dequantWeights8(p, p.chunks[1], q8), pkgMod.dequantWeights8(p2, p2.chunks[1], q));
    assert.throws(() => pkgMod.weights8Webp(p, p.chunks[1], 3 * L, V, rgba),
      /package m: wt-01-8\.webp is 243x81, expected 81x81/);
    const t = Uint8Array.from(rgba);
    t[4 * 7 + 3] = 200;
    assert.throws(() => pkgMod.weights8Webp(p, p.chunks[0], L, V, t),
      /package m: wt-00-8\.webp: pixel 7 is not opaque \(alpha 200\)/);
    pkgMod.checkWeightsWebp(p, p.chunks[0], webpHead('VP8L', L, V), p.chunks[0].wt8);
    pkgMod.checkWeightsWebp(p, p.chunks[0], vp8Head(L, V), p.chunks[0].wt8); // lossy too (section 5.2)
    assert.throws(() => pkgMod.checkWeightsWebp(p, p.chunks[0], webpHead('VP8L', 3 * L, V), p.chunks[0].wt8),
      /package m: wt-00-8\.webp: WebP of 243x81, expected 81x81/);
  });
});

describe('btf-gl.js shader assembly', () => {
  const files = new Map([['a.vert', 'void a() {}\n'], ['b.glsl', 'int b;\nint c;'], ['c.frag', 'void main() {}\n']]);
  const shaders = {manifest: {prefix: ['#version 300 es', 'precision highp float;'],
    programs: {p: {vertex: ['a.vert'], fragment: ['b.glsl', 'c.frag']}}}, files};

  it('assembles prefix, defines, then "// ---- FILE" + text, as shaders/README.md specifies', () => {
    const s = glMod.assemble(shaders, 'p', 'fragment', [['N', 4], ['FLAG', '']]);
    assert.equal(s.text, '#version 300 es\nprecision highp float;\n#define N 4\n#define FLAG\n' +
      '// ---- b.glsl\nint b;\nint c;\n// ---- c.frag\nvoid main() {}\n');
    assert.deepEqual(s.pieces, [{file: 'b.glsl', firstLine: 6, nLines: 2}, {file: 'c.frag', firstLine: 9, nLines: 1}]);
    assert.deepEqual(glMod.sourceLine(s, 7), ['b.glsl', 2]);
    assert.deepEqual(glMod.sourceLine(s, 3), [null, 3]);
    assert.throws(() => glMod.assemble(shaders, 'q', 'vertex'), /program 'q'/);
    assert.throws(() => glMod.assemble(shaders, 'p', 'vertex', [['1x', 1]]), /invalid define/);
  });

  it('maps ANGLE, Mesa and NVIDIA log lines and annotates the numbered source', () => {
    assert.equal(glMod.logLine("ERROR: 0:7: 'c' : redefinition"), 7);
    assert.equal(glMod.logLine('0:12(3): error: x'), 12);
    assert.equal(glMod.logLine('0(9) : error C0000: y'), 9);
    assert.equal(glMod.logLine('link failed'), 0);
    const s = glMod.assemble(shaders, 'p', 'fragment');
    const rep = glMod.annotate(s, "ERROR: 0:5: 'c' : redefinition\n");
    assert.match(rep, / {3}5: int c;\n {6}\^\^\^ ERROR: 0:5: 'c' : redefinition/);
  });

  it('the real shaders/manifest.json names existing plain files', () => {
    const m = JSON.parse(fs.readFileSync(path.join(ROOT, 'shaders/manifest.json'), 'utf8'));
    assert.ok(m.programs.render || m.programs.decode_probe, 'a program the client can draw with');
    for (const prog of Object.values(m.programs))
      for (const f of [...prog.vertex, ...prog.fragment]) assert.ok(fs.existsSync(path.join(ROOT, 'shaders', f)), f);
  });
});

// The texture layer with levels (shaders/README.md, "GPU layout"; the C host's
// btf__pack_slot, btf__pair_levels): each level holds the slot's nearest loaded one;
// paired, texel (x, y) of level l is uploaded with the slot's value there in its low 16
// bits and that of texel (x/2, y/2) of level l + 1 in its high 16 (0 at the top level);
// not paired, the 16-bit values alone.
describe('btf-gl.js texture layers', () => {
  const {fillSlot, putTex} = glMod.GpuPackage.prototype;
  const pkg = {width: 8, height: 4, atlas: {cols: 2, rows: 1, width: 16, height: 4}}, size = (l) => [16 >> l, 4 >> l];
  let seed = 99;
  const rnd16 = () => ((seed = (seed * 1103515245 + 12345) >>> 0) >>> 16);
  const atlas = (l) => Uint16Array.from({length: size(l)[0] * size(l)[1]}, rnd16);
  // slot s's value at texel (x, y) of level l when levels fine..N-1 are loaded: level
  // max(l, fine)'s texel at the same place in the tile
  const want = (q16, fine, l, x, y) => {
    const m = Math.max(l, fine), d = m - l, wl = 8 >> l, wm = 8 >> m;
    return q16[m][(y >> d) * size(m)[0] + Math.floor(x / wl) * wm + ((x % wl) >> d)];
  };
  // A package's layer 0 with two slots filled (levels fine..N-1 loaded), as uploaded.
  const upload = (N, paired, loaded) => {
    const q16 = loaded.map(() => Array.from({length: N}, (_, l) => atlas(l)));
    const texCopy = [Array.from({length: N}, (_, l) => new Uint16Array(4 * size(l)[0] * size(l)[1]))];
    const put = [];
    const gpu = {pkg, levels: N, paired, loaded, q16, texCopy, putTex, store: {putTex: (h, l, w, ht, data) => (put[l] = data)}};
    loaded.forEach((_, s) => fillSlot.call(gpu, s));
    return {q16, put};
  };

  it('pairs each level with the next coarser one, slot by slot, unloaded levels filled', () => {
    const N = 3, loaded = [{fine: 0, coarse: 2}, {fine: 1, coarse: 2}], {q16, put} = upload(N, true, loaded);
    for (let l = 0; l < N; l++) {
      assert.ok(put[l] instanceof Uint32Array, `level ${l} uploaded as 32-bit texels`);
      for (let y = 0; y < size(l)[1]; y++)
        for (let x = 0; x < size(l)[0]; x++)
          for (let c = 0; c < 4; c++) {
            const u = put[l][4 * (y * size(l)[0] + x) + c], at = `level ${l} (${x}, ${y}) channel ${c}`;
            const lo = c < 2 ? want(q16[c], loaded[c].fine, l, x, y) : 0;
            const hi = c < 2 && l < N - 1 ? want(q16[c], loaded[c].fine, l + 1, x >> 1, y >> 1) : 0;
            assert.deepEqual([u & 0xffff, u >>> 16], [lo, hi], at);
          }
    }
  });

  it('uploads the 16-bit values alone where not paired (bilinear, or no levels)', () => {
    for (const N of [1, 3]) {
      const loaded = [{fine: 0, coarse: N - 1}], {q16, put} = upload(N, false, loaded);
      for (let l = 0; l < N; l++) {
        assert.ok(put[l] instanceof Uint16Array, `${N} levels: level ${l} uploaded as 16-bit texels`);
        for (let i = 0; i < q16[0][l].length; i++) assert.equal(put[l][4 * i], q16[0][l][i], `level ${l} texel ${i}`);
      }
    }
  });
});

// Where u_btf_tex is paired (shaders/README.md, "GPU layout"): only for a package with
// levels drawn with nearest taps (one texel read for two levels); bilinear taps read each
// level's own texels, so there (the viewer's default) and without levels it stays
// RGBA16UI, half the GPU memory. A GpuPackage on a recording WebGL2 stand-in: the
// internal format and bytes of the u_btf_tex that bind() hands the program, as the
// filter changes both ways.
describe('btf-gl.js paired layout', () => {
  const BYTES = {RGBA16UI: 8, RGBA32UI: 16};
  // A WebGL2 stand-in: enums are their names, textures records of their storage.
  const fakeGl = () => {
    const st = {bound: null, sampled: null}; // the bound texture, that of the u_btf_tex unit
    const calls = {
      createTexture: () => ({storage: null, deleted: false}), deleteTexture: (t) => { t.deleted = true; },
      bindTexture: (target, t) => { st.bound = t; },
      texStorage3D: (target, levels, format, w, h, layers) => { st.bound.storage = {levels, format, w, h, layers}; },
      texSubImage3D: (...a) => { assert.equal(a[8] === 'UNSIGNED_INT', st.bound.storage.format === 'RGBA32UI', 'type'); },
      uniform1i: (loc) => { if (loc === 'u_btf_tex') st.sampled = st.bound; }, // bind(): a unit's texture, its sampler
    };
    calls.packageStore = false; // a context, not a store
    const gl = new Proxy({}, {get: (_, k) => (k in calls ? calls[k] : /^[A-Z0-9_]+$/.test(k) ? k : () => ({}))});
    return {gl, st};
  };
  // The texture bind() gave u_btf_tex: its format and bytes (every level and layer).
  const texOf = (gpu, st, filter) => {
    gpu.bind({program: {}, loc: (name) => name}, 0, {filter});
    const t = st.sampled, {levels, format, w, h, layers} = t.storage;
    assert.ok(!t.deleted && t === gpu.store.tex, 'the store\'s live texture is bound');
    let texels = 0;
    for (let l = 0; l < levels; l++) texels += (w >> l) * (h >> l) * layers;
    return [format, BYTES[format] * texels];
  };

  it('pairs a package with levels for nearest taps only, both ways', () => {
    const {gl, st} = fakeGl(), pkg = pkgMod.parseManifest(manifestV2()), gpu = new glMod.GpuPackage(gl, pkg, 0);
    const texels = (24 * 20 + 12 * 10) * 1; // 2 levels of the 24 x 20 atlas, one layer of 4 slots
    assert.deepEqual(texOf(gpu, st, 1), ['RGBA16UI', 8 * texels], 'bilinear');
    assert.deepEqual(texOf(gpu, st, 0), ['RGBA32UI', 16 * texels], 'nearest');
    assert.deepEqual(texOf(gpu, st, 0), ['RGBA32UI', 16 * texels], 'nearest again');
    assert.deepEqual(texOf(gpu, st, 1), ['RGBA16UI', 8 * texels], 'bilinear after nearest');
    gpu.free();
  });

  it('keeps RGBA16UI without levels, whatever the filter', () => {
    const {gl, st} = fakeGl(), gpu = new glMod.GpuPackage(gl, pkgMod.parseManifest(manifest()), 2);
    for (const f of [0, 1, 0]) assert.deepEqual(texOf(gpu, st, f), ['RGBA16UI', 8 * 24 * 20], `filter ${f}`);
    gpu.free();
  });
});

describe('btf-stream.js budgets', () => {
  it('merges viewer budgets into the largest, unlimited when any is', () => {
    const m = streamMod.mergeBudgets;
    const none = {pixels: -1, threshold: -1};
    assert.deepEqual(m([{chunks: 2, bytes: -1}, {chunks: 5, bytes: -1}]), {chunks: 5, bytes: -1, error: -1, ...none});
    assert.deepEqual(m([{chunks: 2, bytes: 100}, {chunks: -1, bytes: 300}]),
      {chunks: -1, bytes: 300, error: -1, ...none});
    assert.deepEqual(m([{chunks: 1, bytes: 10, error: 2}, {chunks: 1, bytes: 10, error: 1}]),
      {chunks: 1, bytes: 10, error: 1, ...none});
    // footprints: the largest view wins, with the lowest threshold; a viewer without one lifts the limit
    assert.deepEqual(m([{chunks: -1, pixels: 300, threshold: 1}, {chunks: -1, pixels: 600, threshold: 2}]),
      {chunks: -1, bytes: -1, error: -1, pixels: 600, threshold: 1});
    assert.equal(m([{chunks: 3, pixels: -1}, {chunks: -1, pixels: 600}]).pixels, -1);
  });
});

describe('btf-http.js (the HTTP transport: the rules of btfd in the client)', () => {
  it('the library base of a source: an http(s) folder, its materials.json, a btfd WebSocket', () => {
    const b = httpMod.libraryBase;
    assert.equal(b('https://cdn.example/lib/'), 'https://cdn.example/lib/');
    assert.equal(b('https://cdn.example/lib'), 'https://cdn.example/lib/');
    assert.equal(b('https://cdn.example/lib/materials.json?x=1'), 'https://cdn.example/lib/');
    assert.equal(b('ws://127.0.0.1:8080/stream'), 'http://127.0.0.1:8080/');
    assert.equal(b('wss://btf.example/lib/stream'), 'https://btf.example/lib/');
    assert.equal(httpMod.libraryUrl('https://cdn.example/lib/', '/materials/knit/0123/'),
      'https://cdn.example/lib/materials/knit/0123/');
  });

  it('budgetLimit is the prefix rule of btfd: chunks, bytes, error, footprint', () => {
    const m = manifest(), L = (b) => httpMod.budgetLimit(m, {chunks: -1, bytes: -1, error: -1, pixels: -1, ...b});
    assert.equal(L({}), 2);
    assert.equal(L({chunks: 1}), 1);
    assert.equal(L({chunks: 0}), 0);
    assert.equal(L({bytes: 1000}), 1);
    assert.equal(L({bytes: 2000}), 1);
    assert.equal(L({bytes: 2001}), 2);
    assert.equal(L({error: 3}), 1, 'the first chunk whose lab error is within the budget');
    assert.equal(L({error: 0.5}), 2);
    assert.equal(L({pixels: 0}), 0, 'off screen');
    assert.equal(L({pixels: 100}), 2, 'a package without levels: every chunk');
    assert.equal(httpMod.manifestMetric(m), 'lab');
  });

  it('nextChunk: first chunks before any refinement, then error reduction per byte, ties to the earlier', () => {
    const m = manifest(), n = httpMod.nextChunk;
    assert.deepEqual(n([{manifest: m, held: 1, next: 1, limit: 2}, {manifest: m, held: 0, next: 0, limit: 2}]),
      {index: 1, chunk: 0, first: true});
    assert.deepEqual(n([{manifest: m, held: 1, next: 1, limit: 2}, {manifest: m, held: 1, next: 1, limit: 2}]),
      {index: 0, chunk: 1, first: false});
    const cheap = structuredClone(m);
    cheap.chunks[1].bytes = 10;
    assert.equal(n([{manifest: m, held: 1, next: 1, limit: 2}, {manifest: cheap, held: 1, next: 1, limit: 2}]).index, 1);
    assert.equal(n([{manifest: m, held: 2, next: 2, limit: 2}]), null, 'everything held');
    assert.equal(n([{manifest: m, held: 1, next: 1, limit: 1}]), null, 'the budget allows no more');
  });
});

describe('scene.js (port of shaders/host/btf_render.c conventions)', () => {
  const apply = (m, p) => [0, 1, 2, 3].map((r) => m[r] * p[0] + m[4 + r] * p[1] + m[8 + r] * p[2] + m[12 + r]);
  it('the camera looks at the origin from dist * dir(theta, phi), +z up on screen', () => {
    const s = {...scene.sceneDefaults('plane'), geometry: 'plane', cameraTheta: 35, cameraPhi: -90, cameraDist: 3};
    const c = scene.cameraMake(s, 4 / 3);
    const d = scene.dir(35, -90);
    [0, 1, 2].forEach((i) => assert.ok(Math.abs(c.eye[i] - 3 * d[i]) < 1e-6));
    const o = apply(c.viewProj, [0, 0, 0]);
    assert.ok(Math.abs(o[0] / o[3]) < 1e-6 && Math.abs(o[1] / o[3]) < 1e-6, 'origin at the centre');
    const top = apply(c.viewProj, [0, 0, 0.5]);
    assert.ok(top[1] / top[3] > 0, '+z is up on screen');
    const far = apply(c.viewProj, [0, 1, 0]); // +y (image row 0 of the plane) is further away: higher up
    assert.ok(far[1] / far[3] > 0);
    assert.deepEqual(c.uvScale, [1, 1]);
    assert.equal(c.wrap, 0);
    assert.equal(scene.cameraMake({...s, geometry: 'sphere'}, 1).wrap, 1);
  });

  // The same check as render/default_camera_frames_the_object_in_any_aspect (tests/test_render.c):
  // points bounding each object (plane corners, cylinder rims, the sphere at every
  // 2 degrees) projected here through cameraMake's viewProj.
  it('the default camera frames each object in portrait, square and landscape views', () => {
    const bound = {plane: [[-1, -1, 0], [1, -1, 0], [-1, 1, 0], [1, 1, 0]], sphere: [], cylinder: []};
    for (let t = 0; t <= 180; t += 2) for (let p = 0; p < 360; p += 2) bound.sphere.push(scene.dir(t, p));
    for (const x of [-1, 1]) {
      for (let a = 0; a < 360; a++) {
        const r = a * Math.PI / 180;
        bound.cylinder.push([x, 2 / Math.PI * Math.cos(r), 2 / Math.PI * Math.sin(r)]);
      }
    }
    const minFill = {plane: 0.6, sphere: 0.6, cylinder: 0.45}; // the cylinder is 2 x 1.27
    for (const g of scene.GEOMETRIES) {
      const s = {...scene.sceneDefaults(g), geometry: g};
      for (const aspect of [0.5, 0.65, 0.75, 1, 4 / 3, 16 / 9]) {
        const c = scene.cameraMake(s, aspect);
        const lo = [Infinity, Infinity], hi = [-Infinity, -Infinity];
        for (const p of bound[g]) {
          const q = apply(c.viewProj, p);
          assert.ok(q[3] > 0);
          for (const k of [0, 1]) {
            lo[k] = Math.min(lo[k], q[k] / q[3]);
            hi[k] = Math.max(hi[k], q[k] / q[3]);
          }
        }
        const at = `${g} aspect ${aspect.toFixed(2)}: x ${lo[0].toFixed(3)}..${hi[0].toFixed(3)} y ` +
          `${lo[1].toFixed(3)}..${hi[1].toFixed(3)}`;
        for (const k of [0, 1]) {
          assert.ok(lo[k] >= -0.95 && hi[k] <= 0.95, `${at}: outside the view`);
          assert.ok(Math.abs(lo[k] + hi[k]) / 2 <= 0.12, `${at}: off centre`);
        }
        const narrow = aspect < 1 ? 0 : 1;
        assert.ok((hi[narrow] - lo[narrow]) / 2 >= minFill[g], `${at}: too small`);
      }
    }
  });

  it('fov spans the narrower side; pixelsPerUnit is the scale at the origin', () => {
    const s = {...scene.sceneDefaults('sphere'), geometry: 'sphere'};
    const t = Math.tan(s.fov * Math.PI / 360);
    for (const [w, h] of [[390, 600], [600, 600], [320, 240], [1280, 720]]) {
      const c = scene.cameraMake(s, w / h);
      // a point at the origin's distance, half the narrower side's fov off the axis:
      // on the edge of the view
      const right = [1, 0, 0]; // the default camera (phi -90) has world +x to the right
      const edge = apply(c.viewProj, right.map((v) => v * s.cameraDist * t * (w < h ? 1 : w / h)));
      assert.ok(Math.abs(edge[0] / edge[3] - 1) < 1e-5, `${w}x${h}: ${edge[0] / edge[3]}`);
      const e = 1e-3, q = apply(c.viewProj, [e, 0, 0]);
      const ppu = (q[0] / q[3]) * (w / 2) / e;
      assert.ok(Math.abs(ppu / scene.pixelsPerUnit(s, w, h) - 1) < 1e-4, `${w}x${h}: ${ppu} vs ${scene.pixelsPerUnit(s, w, h)}`);
    }
    // landscape: the same scale as the old vertical-fov footprint, canvas height / (2 dist tan(fov/2))
    assert.ok(Math.abs(scene.pixelsPerUnit(s, 320, 240) - 240 / (2 * 3.6 * t)) < 1e-9);
    assert.ok(Math.abs(scene.pixelsPerUnit(s, 390, 600) - 390 / (2 * 3.6 * t)) < 1e-9);
  });

  it('orbitLight turns the light about the camera direction, keeping its angle to it', () => {
    for (const g of scene.GEOMETRIES) {
      const s = {...scene.sceneDefaults(g), geometry: g};
      const cam = scene.dir(s.cameraTheta, s.cameraPhi), d0 = scene.dir(s.lightTheta, s.lightPhi);
      const cos0 = cam.reduce((a, v, i) => a + v * d0[i], 0);
      const l0 = scene.orbitLight(s, 0);
      assert.ok(Math.abs(l0.lightTheta - s.lightTheta) < 1e-9 && Math.abs(l0.lightPhi - s.lightPhi) < 1e-9);
      const seen = [];
      for (let a = 0; a < 360; a += 30) {
        const l = scene.orbitLight(s, a), d = scene.dir(l.lightTheta, l.lightPhi);
        assert.ok(Math.abs(cam.reduce((acc, v, i) => acc + v * d[i], 0) - cos0) < 1e-9, `${g} ${a}: same angle`);
        seen.push(d);
      }
      // a full circle: the light passes opposite its start
      const far = Math.min(...seen.map((d) => d.reduce((a, v, i) => a + v * d0[i], 0)));
      assert.ok(far < 2 * cos0 * cos0 - 1 + 1e-6);
    }
  });

  it('meshes: unit normals, tangents orthogonal to them, uv as documented', () => {
    for (const g of scene.GEOMETRIES) {
      const {vertices: v, indices} = scene.buildMesh(g, 16);
      assert.equal(indices.length % 3, 0);
      for (let i = 0; i < v.length; i += 12) {
        const n = v.subarray(i + 3, i + 6), t = v.subarray(i + 6, i + 9);
        assert.ok(Math.abs(Math.hypot(...n) - 1) < 1e-5, `${g}: unit normal`);
        assert.ok(Math.abs(n[0] * t[0] + n[1] * t[1] + n[2] * t[2]) < 1e-5, `${g}: tangent in the surface`);
        if (g === 'plane') {
          assert.ok(Math.abs((v[i] + 1) / 2 - v[i + 10]) < 1e-6 && Math.abs((1 - v[i + 1]) / 2 - v[i + 11]) < 1e-6);
        }
        if (g === 'sphere') assert.ok(Math.abs(Math.hypot(v[i], v[i + 1], v[i + 2]) - 1) < 1e-5);
      }
    }
  });
});

// The chunk selection of package version 2: the same cases as btf_lod_select in
// tests/test_lod.c (tests/lod_select_cases.json), so C and the client agree.
describe('btf-lod.js', async () => {
  const lod = await import('../../client/btf-lod.js');
  const shared = JSON.parse(fs.readFileSync(path.join(ROOT, 'tests/lod_select_cases.json'), 'utf8'));
  it('selects the same chunks as btf_lod_select', () => {
    assert.ok(shared.cases.length > 5);
    for (const [k, c] of shared.cases.entries()) {
      const s = lod.lodSelect(shared.package, {texelsPerPixel: c.tpp, threshold: c.threshold});
      assert.equal([...s.need].join(''), c.need, `case ${k}`);
      if (c.tpp > 0) assert.equal(s.level, c.level, `case ${k}`);
      assert.equal(s.components, c.components, `case ${k}`);
      assert.equal(s.limit, c.limit, `case ${k}`);
      assert.equal(s.bytes, c.bytes, `case ${k}`);
    }
  });
  it('footprint: texels per device pixel, 0 off screen', () => {
    for (const c of shared.footprint) assert.ok(Math.abs(lod.lodFootprint(c.width, c.repeat, c.pixels) - c.tpp) < 1e-12);
    assert.equal(lod.lodFootprint(256, 1, NaN), 0);
  });
  it('version 1: every chunk at level 0', () => {
    const m = {version: 1, chunks: [{component: 0, bytes: 5}, {component: 1, bytes: 7}]};
    const s = lod.lodSelect(m, {texelsPerPixel: 50, threshold: 1});
    assert.deepEqual([s.level, s.limit, s.bytes, s.components], [0, 2, 12, 2]);
  });
});

const tabMod = await import('../../client/btf-dirtab.js');

describe('btf-dirtab.js', () => {
  const sets = {
    ubo2003: UBO,
    'no pole, horizon ring': {rings: [{theta: 15, count: 6, phi_offset: 0}, {theta: 40, count: 12, phi_offset: 7},
      {theta: 90, count: 16, phi_offset: 11.25}]},
  };
  for (const [name, j] of Object.entries(sets)) {
    it(`${name}: a closed triangulation (2V - 4 triangles, every edge shared) like btf_dirtab_build`, () => {
      const d = pkgMod.parseManifest({...manifest(), lights: structuredClone(j)}).lights;
      const t = tabMod.buildDirtab(d);
      const V = d.dirs + (d.rings[1] > 1 ? 2 : 1);
      assert.equal(t.tris.length, 2 * V - 4);
      assert.ok(t.adj.every((a) => a.every((n) => n >= 0)), 'an edge without a neighbour');
    });
    it(`${name}: weights sum to 1, exact at the measured directions, continuous along a scan`, () => {
      const d = pkgMod.parseManifest({...manifest(), lights: structuredClone(j)}).lights;
      const t = tabMod.buildDirtab(d);
      for (let i = 0; i < t.nDirs; i++) {
        const r = tabMod.dirtabInterp(t, t.verts[i].slice(0, 3));
        const own = r.idx.reduce((s, x, k) => s + (x === i ? r.w[k] : 0), 0);
        assert.ok(own > 1 - 1e-5, `direction ${i}: own weight ${own}`);
      }
      // f = x + 2y + z^2 interpolated along phi at theta 50: a jump beyond 3.5e-4 per 0.004 degree step is a seam
      const f = (v) => v[0] + 2 * v[1] + v[2] * v[2];
      let prev = null, worst = 0;
      for (let p = -2; p <= 362; p += 0.004) {
        const a = 50 * Math.PI / 180, b = p * Math.PI / 180;
        const r = tabMod.dirtabInterp(t, [Math.sin(a) * Math.cos(b), Math.sin(a) * Math.sin(b), Math.cos(a)]);
        assert.ok(Math.abs(r.w[0] + r.w[1] + r.w[2] - 1) < 1e-6);
        const v = r.idx.reduce((s, x, k) => s + r.w[k] * f(t.verts[x]), 0);
        if (prev !== null) worst = Math.max(worst, Math.abs(v - prev));
        prev = v;
      }
      assert.ok(worst < 3.5e-4, `largest step ${worst}`);
    });
  }
});

// A list set as the C writer puts it in a manifest (btf gen + compress with a direction
// list): the JS table takes the manifest's triangles, is exact at the directions,
// continuous through the horizon, and refuses triangles a hostile file could break.
describe('btf-dirtab.js direction lists', () => {
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'btf-list-'));
  const list = writeSpiralList(40, 29);
  const run = (args) => {
    const r = child.spawnSync(BTF, args, {encoding: 'utf8'});
    assert.equal(r.status, 0, `btf ${args.join(' ')}: ${r.stderr}`);
  };
  run(['gen', 'stone', path.join(dir, 'img'), '--size', '4', '--sampling', list, '--seed', '313']);
  run(['compress', path.join(dir, 'img'), path.join(dir, 'pkg'), '--sampling', list, '--k', '1', '--components', '2',
    '--quiet']);
  const man = JSON.parse(fs.readFileSync(path.join(dir, 'pkg', 'manifest.json'), 'utf8'));
  fs.rmSync(dir, {recursive: true, force: true});
  const f = (v) => 0.5 + 0.3 * v[0] - 0.2 * v[1] + 0.4 * v[2] * v[2];
  it('exact at the listed directions; weights sum to 1; no seam along theta and phi lines', () => {
    const d = pkgMod.parseManifest(man).lights;
    assert.equal(d.dirs, 40);
    const t = tabMod.buildDirtab(d);
    for (let i = 0; i < t.nDirs; i++) {
      const r = tabMod.dirtabInterp(t, t.verts[i].slice(0, 3));
      const own = r.idx.reduce((s, x, k) => s + (x === i ? r.w[k] : 0), 0);
      assert.ok(own > 1 - 1e-5, `direction ${i}: own weight ${own}`);
    }
    // f at the weights' directions; a jump beyond 1e-3 per 0.004 degree step is a seam
    const at = (th, ph) => {
      const a = th * Math.PI / 180, b = ph * Math.PI / 180;
      const r = tabMod.dirtabInterp(t, [Math.sin(a) * Math.cos(b), Math.sin(a) * Math.sin(b), Math.cos(a)]);
      assert.ok(Math.abs(r.w[0] + r.w[1] + r.w[2] - 1) < 1e-6);
      return r.idx.reduce((s, x, k) => s + r.w[k] * f(t.verts[x]), 0);
    };
    let worst = 0;
    for (const ph of [3.3, 97, 211.5]) {
      let prev = at(0.05, ph);
      for (let th = 0.054; th <= 92; th += 0.004) {
        const v = at(th, ph);
        worst = Math.max(worst, Math.abs(v - prev));
        prev = v;
      }
    }
    for (const th of [40, 84, 89.99]) {
      let prev = at(th, -2);
      for (let ph = -1.996; ph <= 362; ph += 0.004) {
        const v = at(th, ph);
        worst = Math.max(worst, Math.abs(v - prev));
        prev = v;
      }
    }
    assert.ok(worst < 1e-3, `largest step ${worst}`);
  });
  it('refuses broken triangles with a message', () => {
    const cases = [
      [(t) => t.splice(0, 3), /not covered|cover/],                       // a hole
      [(t) => { [t[1], t[2]] = [t[2], t[1]]; }, /clockwise|hull|edge/],   // flipped
      [(t) => t.push(...t.slice(0, 3)), /edge/],                          // twice
      [(t) => { t[0] = 80; }, /not in 0..79/],                             // out of range
    ];
    for (const [edit, re] of cases) {
      const m = structuredClone(man);
      edit(m.lights.triangles);
      assert.throws(() => tabMod.buildDirtab(pkgMod.parseManifest(m).lights), re);
    }
  });
});

// The per-draw light blend of the plane (client/btf-fixed.js, the twin of
// shaders/host/btf_gl_fixed.c): on random weight codes and grids laid out as a GpuPackage
// holds them, every stored value is the light-blended weight within half its per-draw
// step, each grid spans its views (codes 0 and the maximum both used), slots beyond the
// prefix stay zero.
describe('btf-fixed.js', async () => {
  const fixed = await import('../../client/btf-fixed.js');
  it('stores the light-blended weights within half a per-draw step', () => {
    const d = pkgMod.parseManifest(manifest()).lights, L = d.dirs, V = d.dirs, layers = 2, used = 6;
    let seed = 12345;
    const rnd = () => ((seed = (seed * 1103515245 + 12345) >>> 0) >>> 8) / 2 ** 24;
    const wtCopy = [], wq = new Float32Array(24 * layers), QMAX = [2047, 2047, 1023], SHIFT = [0, 11, 22];
    for (let h = 0; h < layers; h++) {
      const a = new Uint32Array(4 * L * V);
      for (let i = 0; i < a.length; i++)
        a[i] = (Math.floor(rnd() * 2048) | Math.floor(rnd() * 2048) << 11 | Math.floor(rnd() * 1024) << 22) >>> 0;
      wtCopy.push(a);
    }
    for (let i = 0; i < 12 * layers; i++) wq[i + 12 * Math.floor(i / 12)] = rnd() * 2 - 1; // lo
    for (let i = 0; i < 12 * layers; i++) wq[i + 12 * Math.floor(i / 12) + 12] = rnd() * 1e-3; // step
    const gpu = {pkg: {lights: {dirs: L}, views: {dirs: V}}, capacity: 4 * layers, wtCopy, wq};
    const tab = tabMod.buildDirtab(d);
    for (const light of [[0, 0, 1], [0.3, -0.5, 0.8], [0.9, 0.2, 0.1], [0.5, 0.5, -0.2]]) {
      const {codes, lq} = fixed.fixedBlend(gpu, tab, light, used), il = tabMod.dirtabInterp(tab, light);
      for (let s = 0; s < 4 * layers; s++)
        for (let c = 0; c < 3; c++) {
          const h = s >> 2, k = s & 3, lo = lq[24 * h + 4 * c + k], st = lq[24 * h + 12 + 4 * c + k];
          let min = Infinity, max = -Infinity;
          for (let v = 0; v < V; v++) {
            const q = (codes[4 * (h * V + v) + k] >>> SHIFT[c]) & QMAX[c];
            min = Math.min(min, q);
            max = Math.max(max, q);
            if (s >= used) continue;
            let want = 0;
            for (let e = 0; e < 3; e++) {
              const qe = (wtCopy[h][4 * (v * L + il.idx[e]) + k] >>> SHIFT[c]) & QMAX[c];
              want += il.w[e] * (wq[24 * h + 4 * c + k] + wq[24 * h + 12 + 4 * c + k] * qe);
            }
            assert.ok(Math.abs(lo + st * q - want) <= st / 2 + 1e-6, `slot ${s} c${c} view ${v}: ${lo + st * q} ${want}`);
          }
          if (s >= used) assert.deepEqual([min, max, lo, st], [0, 0, 0, 0], `slot ${s} beyond the prefix`);
          else assert.deepEqual([min, max], [0, QMAX[c]], `slot ${s} c${c}: the grid spans the views`);
        }
    }
  });
});
