// hdr.test.mjs - client/btf-hdr.js in node: valid Radiance files (flat and run-length,
// written by hdr-writer.mjs) read back exactly, large ones averaged down by an integer
// box, hostile ones (truncated, huge, runs past the row, bad headers) refused with a
// clear Error, and a few thousand random byte flips of a valid file that may only throw
// an Error or return, promptly.
import assert from 'node:assert/strict';
import {describe, it} from 'node:test';
import {HDR_MAX_HEIGHT, HDR_MAX_WIDTH, hdrFactor, parseHdr} from '../../client/btf-hdr.js';
import {rgbe, rgbeValue, writeHdr} from './hdr-writer.mjs';

// A W x H test image: smooth ramps plus flat stretches (runs) and a few black pixels.
function image(W, H, seed = 1) {
  const data = new Float32Array(3 * W * H);
  let s = seed;
  const rnd = () => ((s = (s * 1103515245 + 12345) >>> 0) / 2 ** 32);
  for (let y = 0; y < H; y++)
    for (let x = 0; x < W; x++) {
      const o = 3 * (y * W + x), flat = x % 20 < 8;
      data[o] = flat ? 0.5 : 0.01 + 4 * rnd();
      data[o + 1] = flat ? 0.5 : 100 * rnd();
      data[o + 2] = (x + y) % 17 === 0 ? 0 : flat ? 0.25 : rnd() * 1e-3;
    }
  return {width: W, height: H, data};
}

// What the reader must return for img: each pixel as its RGBE bytes say.
function expected(img) {
  const out = new Float32Array(img.data.length);
  for (let i = 0; i < img.data.length; i += 3) out.set(rgbeValue(rgbe(img.data[i], img.data[i + 1], img.data[i + 2])), i);
  return out;
}

const enc = (s) => new Uint8Array(Buffer.from(s, 'latin1'));
const cat = (...a) => new Uint8Array(Buffer.concat(a.map((x) => Buffer.from(x))));

describe('btf-hdr.js', () => {
  it('reads flat and run-length files exactly', () => {
    for (const [W, H, rle] of [[37, 11, true], [37, 11, false], [5, 3, true], [300, 4, true], [1, 1, false]]) {
      const img = image(W, H, W + H), bytes = writeHdr(img, {rle});
      const r = parseHdr(bytes);
      assert.deepEqual([r.width, r.height, r.factor], [W, H, 1]);
      assert.deepEqual(r.data, expected(img), `${W}x${H} rle ${rle}`);
    }
    const rle = writeHdr(image(300, 4)), flat = writeHdr(image(300, 4), {rle: false});
    assert.ok(rle.length < 0.8 * flat.length, `the run-length file is shorter (${rle.length} < ${flat.length})`);
    // #?RGBE, no FORMAT line, other header lines, CRLF
    const img = image(12, 2);
    const alt = writeHdr(img, {magic: '#?RGBE', header: ['# made by a test', 'EXPOSURE=1.0', 'GAMMA=1']});
    assert.deepEqual(parseHdr(alt).data, expected(img));
    const crlf = Buffer.from(writeHdr(img, {rle: false})).toString('latin1').replace(/\n(?=.*\n-Y)/s, '\r\n');
    assert.deepEqual(parseHdr(enc(crlf)).data, expected(img));
  });

  it('averages a large image down by an integer box while it is read', () => {
    assert.deepEqual(hdrFactor(4096, 2048), {factor: 4, width: 1024, height: 512});
    assert.deepEqual(hdrFactor(1030, 100), {factor: 2, width: 515, height: 50});
    assert.deepEqual(hdrFactor(100, 1537), {factor: 4, width: 25, height: 385});
    const W = 2051, H = 7, img = image(W, H, 3), r = parseHdr(writeHdr(img));
    assert.deepEqual([r.factor, r.width, r.height, r.sourceWidth, r.sourceHeight], [3, 684, 3, W, H]);
    assert.ok(r.width <= HDR_MAX_WIDTH && r.height <= HDR_MAX_HEIGHT);
    const e = expected(img);
    for (const [ox, oy] of [[0, 0], [100, 1], [683, 2], [683, 0]]) { // the last column: 2 of 3 pixels; last row: 1 of 3
      const sum = [0, 0, 0];
      let n = 0;
      for (let y = 3 * oy; y < Math.min(H, 3 * oy + 3); y++)
        for (let x = 3 * ox; x < Math.min(W, 3 * ox + 3); x++, n++) for (let c = 0; c < 3; c++) sum[c] += e[3 * (y * W + x) + c];
      for (let c = 0; c < 3; c++)
        assert.ok(Math.abs(r.data[3 * (oy * r.width + ox) + c] - sum[c] / n) <= 1e-6 * (1 + sum[c] / n), `box ${ox},${oy}`);
    }
  });

  it('refuses hostile files with a clear error', () => {
    const good = writeHdr(image(40, 6));
    const head = (res) => enc(`#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n${res}\n`);
    const cases = [
      [enc(''), /header ends before the resolution line/],
      [enc('P6\n4 4\n255\n'), /not a Radiance \.hdr file/],
      [enc('#?RADIANCE\nFORMAT=32-bit_rle_xyze\n\n-Y 1 +X 1\n\0\0\0\0'), /FORMAT=32-bit_rle_xyze is not supported/],
      [cat(head('+Y 2 +X 2'), new Uint8Array(16)), /resolution line "\+Y 2 \+X 2" is not/],
      [cat(head('-Y 2 +X'), new Uint8Array(16)), /resolution line/],
      [cat(head('-Y 0 +X 4'), new Uint8Array(16)), /0 pixels: width and height must be 1\.\.65536/],
      [cat(head('-Y 70000 +X 70000'), new Uint8Array(64)), /70000 x 70000 pixels/],
      [cat(head('-Y 65536 +X 65536'), new Uint8Array(64)), /truncated: 64 bytes of pixels cannot hold 65536 x 65536/],
      [enc(`#?RADIANCE\n${'# comment\n'.repeat(8000)}\n-Y 1 +X 1\n\0\0\0\0`), /header is longer than 65536 bytes/],
      [good.subarray(0, good.length - 30), /truncated/],
      // a run-length scanline that claims another width
      [cat(head('-Y 1 +X 8'), [2, 2, 0, 9], new Uint8Array(40)), /scanline 0 says it is 9 pixels wide, the image 8/],
      // a run of 20 in a row of 8
      [cat(head('-Y 1 +X 8'), [2, 2, 0, 8, 128 + 20, 7], new Uint8Array(40)), /run of 20 at pixel 0 of channel 0 passes the row's end \(8\)/],
      // literals past the row
      [cat(head('-Y 1 +X 8'), [2, 2, 0, 8, 5, 1, 2, 3, 4, 5, 6, 1, 2, 3, 4, 5, 6], new Uint8Array(40)), /6 literal bytes at pixel 5 of channel 0 pass/],
      [cat(head('-Y 1 +X 8'), [2, 2, 0, 8, 0], new Uint8Array(40)), /empty run at pixel 0 of channel 0/],
      // the last scanline stops in the middle of a run
      [cat(head('-Y 1 +X 8'), [2, 2, 0, 8, 136, 1, 136, 2, 136, 3, 4, 9, 9, 9, 9]), /truncated in scanline 0/],
    ];
    for (const [bytes, re] of cases) {
      assert.throws(() => parseHdr(bytes, {name: 'sky.hdr'}), (e) => e instanceof Error && /^sky\.hdr: /.test(e.message) &&
        re.test(e.message), `expected ${re}`);
    }
  });

  it('survives random byte flips: an Error or an image, promptly', () => {
    const good = writeHdr(image(64, 16, 7));
    let s = 12345, thrown = 0, read = 0;
    const rnd = (n) => (s = (s * 1103515245 + 12345) >>> 0) % n;
    const t0 = Date.now();
    for (let k = 0; k < 3000; k++) {
      const b = good.slice(), flips = 1 + rnd(8);
      for (let f = 0; f < flips; f++) {
        // half the flips in the header and the first scanlines, where the structure is
        const at = rnd(2) ? rnd(Math.min(b.length, 120)) : rnd(b.length);
        b[at] = rnd(256);
      }
      if (rnd(10) === 0) b.set(enc('-Y 9999 +X 9999\n').subarray(0, Math.min(16, b.length - 40)), 40);
      try {
        const r = parseHdr(b);
        assert.ok(r.width >= 1 && r.height >= 1 && r.data.length === 3 * r.width * r.height);
        assert.ok(r.data.every((v) => Number.isFinite(v) && v >= 0));
        read++;
      } catch (e) {
        assert.ok(e instanceof Error && /^environment image: /.test(e.message), String(e));
        thrown++;
      }
    }
    const ms = Date.now() - t0;
    console.log(`# 3000 damaged files: ${read} read, ${thrown} refused, ${ms} ms`);
    assert.ok(thrown > 100 && read > 100, `both outcomes occur (${read} read, ${thrown} refused)`);
    assert.ok(ms < 20000, `${ms} ms`);
  });
});
