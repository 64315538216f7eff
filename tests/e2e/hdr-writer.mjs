// hdr-writer.mjs - a small Radiance .hdr (RGBE) writer for the tests: flat or new-style
// run-length scanlines, from a float RGB image (rows top-down). The reader under test is
// client/btf-hdr.js; the C host reads the same files through OpenImageIO.

// One pixel's RGBE bytes (Ward's frexp rule: mantissas m with value m * 2^(e - 136)).
export function rgbe(r, g, b) {
  const v = Math.max(r, g, b);
  if (!(v >= 1e-32)) return [0, 0, 0, 0];
  let e = Math.floor(Math.log2(v)) + 1; // frexp: v = f 2^e with f in [0.5, 1)
  while (2 ** (e - 1) > v) e--;
  while (2 ** e <= v) e++;
  const s = 256 / 2 ** e;
  return [Math.floor(r * s), Math.floor(g * s), Math.floor(b * s), e + 128];
}

// The value the reader gives for a pixel written by rgbe().
export function rgbeValue(p) {
  return p[3] ? [0, 1, 2].map((c) => p[c] * 2 ** (p[3] - 136)) : [0, 0, 0];
}

// Run-length codes of one channel of a scanline (runs of 3 or more repeat, else literals).
function rleChannel(v) {
  const out = [];
  for (let x = 0; x < v.length;) {
    let run = 1;
    while (x + run < v.length && run < 127 && v[x + run] === v[x]) run++;
    if (run >= 3) {
      out.push(128 + run, v[x]);
      x += run;
      continue;
    }
    let n = 0;
    while (x + n < v.length && n < 128) {
      if (x + n + 2 < v.length && v[x + n] === v[x + n + 1] && v[x + n] === v[x + n + 2]) break;
      n++;
    }
    out.push(n, ...v.slice(x, x + n));
    x += n;
  }
  return out;
}

// The file's bytes for {width, height, data: RGB floats}; rle: new-style scanlines
// (width 8..32767); header: extra header lines.
export function writeHdr(img, {rle = true, header = ['FORMAT=32-bit_rle_rgbe'], magic = '#?RADIANCE'} = {}) {
  const {width: W, height: H, data} = img;
  const parts = [Buffer.from(`${magic}\n${header.map((l) => `${l}\n`).join('')}\n-Y ${H} +X ${W}\n`, 'latin1')];
  for (let y = 0; y < H; y++) {
    const px = [];
    for (let x = 0; x < W; x++) px.push(rgbe(data[3 * (y * W + x)], data[3 * (y * W + x) + 1], data[3 * (y * W + x) + 2]));
    if (rle && W >= 8 && W < 32768) {
      const row = [2, 2, W >> 8, W & 255];
      for (let c = 0; c < 4; c++) row.push(...rleChannel(px.map((p) => p[c])));
      parts.push(Buffer.from(row));
    } else parts.push(Buffer.from(px.flat()));
  }
  return new Uint8Array(Buffer.concat(parts));
}
