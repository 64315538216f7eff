// btf-hdr.js - Radiance .hdr (RGBE) images, the environment images of <btf-viewer>
// (doc/lighting.md section 2). Reads the header (#?RADIANCE or #?RGBE, FORMAT=32-bit_rle_rgbe,
// the resolution line -Y H +X W), then each scanline flat or new-style run-length coded,
// every count and run checked against the row and the buffer before it is used. An image
// larger than 1024 x 512 is box-averaged by an integer factor while it is read (one row of
// sums held), so memory stays bounded by the output. Pixel value: m * 2^(e - 136) per
// channel (e = 0: black), as OpenImageIO reads it in the C host. Old-style run-length
// scanlines (1, 1, 1, n markers) are read as flat pixels. No DOM, no GL: usable in node.
//
//   parseHdr(bytes, {name}) -> {width, height, factor, sourceWidth, sourceHeight,
//                               data: Float32Array RGB, rows top-down (row 0 = up)}
//   throws Error `NAME: what is wrong`

export const HDR_MAX_DIM = 65536;     // width and height each
export const HDR_MAX_WIDTH = 1024;    // larger images are averaged down to at most this ...
export const HDR_MAX_HEIGHT = 512;    // ... by this
const HEADER_MAX = 65536;             // bytes of header before the resolution line

// The integer box factor that brings width x height within HDR_MAX_WIDTH x HDR_MAX_HEIGHT,
// and the output size (the last box of a row or column may be narrower).
export function hdrFactor(width, height) {
  const f = Math.max(1, Math.ceil(width / HDR_MAX_WIDTH), Math.ceil(height / HDR_MAX_HEIGHT));
  return {factor: f, width: Math.ceil(width / f), height: Math.ceil(height / f)};
}

export function parseHdr(input, {name = 'environment image'} = {}) {
  const bytes = input instanceof Uint8Array ? input : new Uint8Array(input);
  const fail = (msg) => { throw new Error(`${name}: ${msg}`); };
  let pos = 0;
  // one header line (without its newline); null at the end of the buffer
  const line = () => {
    const end = bytes.indexOf(10, pos);
    if (end < 0 || end > HEADER_MAX) fail(end < 0 ? 'the header ends before the resolution line' :
      `the header is longer than ${HEADER_MAX} bytes`);
    let s = '';
    for (let i = pos; i < end; i++) s += String.fromCharCode(bytes[i]);
    pos = end + 1;
    return s.replace(/\r$/, '');
  };
  const first = line();
  if (!/^#\?(RADIANCE|RGBE)\b/.test(first))
    fail(`not a Radiance .hdr file (it starts with ${JSON.stringify(first.slice(0, 16))}, not #?RADIANCE or #?RGBE)`);
  for (;;) {
    const l = line();
    if (l === '') break;
    const m = /^FORMAT=(.*)$/.exec(l);
    if (m && m[1].trim() !== '32-bit_rle_rgbe')
      fail(`FORMAT=${m[1].trim().slice(0, 32)} is not supported (only 32-bit_rle_rgbe)`);
  }
  const res = line();
  const r = /^-Y\s+(\d{1,9})\s+\+X\s+(\d{1,9})\s*$/.exec(res);
  if (!r) fail(`the resolution line ${JSON.stringify(res.slice(0, 32))} is not "-Y height +X width"`);
  const H = +r[1], W = +r[2];
  if (W < 1 || H < 1 || W > HDR_MAX_DIM || H > HDR_MAX_DIM)
    fail(`${W} x ${H} pixels: width and height must be 1..${HDR_MAX_DIM}`);
  // a flat scanline holds 4 bytes a pixel; a run-length one at least 2 bytes per 128
  // pixels and channel: a file shorter than that cannot hold the image
  const minBytes = W >= 8 && W < 32768 ? H * (4 + 8 * Math.ceil(W / 128)) : 4 * W * H;
  if (bytes.length - pos < minBytes)
    fail(`truncated: ${bytes.length - pos} bytes of pixels cannot hold ${W} x ${H} pixels`);

  const {factor, width: ow, height: oh} = hdrFactor(W, H);
  const out = new Float32Array(3 * ow * oh), sums = new Float64Array(3 * ow);
  const row = new Uint8Array(4 * W);
  const need = (n, y) => {
    if (pos + n > bytes.length) fail(`truncated in scanline ${y}`);
  };
  for (let y = 0; y < H; y++) {
    if (W >= 8 && W < 32768 && pos + 4 <= bytes.length && bytes[pos] === 2 && bytes[pos + 1] === 2 &&
        !(bytes[pos + 2] & 0x80)) {
      const rw = (bytes[pos + 2] << 8) | bytes[pos + 3];
      if (rw !== W) fail(`scanline ${y} says it is ${rw} pixels wide, the image ${W}`);
      pos += 4;
      for (let c = 0; c < 4; c++)
        for (let x = 0; x < W;) {
          need(1, y);
          let n = bytes[pos++];
          if (n > 128) {
            n -= 128;
            if (x + n > W) fail(`scanline ${y}: a run of ${n} at pixel ${x} of channel ${c} passes the row's end (${W})`);
            need(1, y);
            const v = bytes[pos++];
            for (const e = x + n; x < e; x++) row[4 * x + c] = v;
          } else {
            if (n === 0) fail(`scanline ${y}: an empty run at pixel ${x} of channel ${c}`);
            if (x + n > W) fail(`scanline ${y}: ${n} literal bytes at pixel ${x} of channel ${c} pass the row's end (${W})`);
            need(n, y);
            for (const e = x + n; x < e; x++) row[4 * x + c] = bytes[pos++];
          }
        }
    } else {
      need(4 * W, y);
      row.set(bytes.subarray(pos, pos + 4 * W));
      pos += 4 * W;
    }
    for (let x = 0; x < W; x++) {
      const e = row[4 * x + 3];
      if (!e) continue;
      const f = 2 ** (e - 136), o = 3 * Math.floor(x / factor);
      sums[o] += row[4 * x] * f;
      sums[o + 1] += row[4 * x + 1] * f;
      sums[o + 2] += row[4 * x + 2] * f;
    }
    const oy = Math.floor(y / factor);
    if ((y + 1) % factor === 0 || y === H - 1) { // the box row is complete
      const rows = y + 1 - oy * factor;
      for (let ox = 0; ox < ow; ox++) {
        const n = rows * (Math.min(W, (ox + 1) * factor) - ox * factor);
        for (let c = 0; c < 3; c++) {
          const v = Math.fround(sums[3 * ox + c] / n);
          if (!Number.isFinite(v) || v < 0) fail(`pixel (${ox * factor}, ${oy * factor}) channel ${c} is ${v}`);
          out[3 * (oy * ow + ox) + c] = v;
        }
      }
      sums.fill(0);
    }
  }
  return {width: ow, height: oh, factor, sourceWidth: W, sourceHeight: H, data: out};
}
