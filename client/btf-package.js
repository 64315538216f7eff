// btf-package.js - the package manifest (doc/package-format.md) on the client:
// validation against the limits of section 8, direction-set uniforms, the view ->
// block table, and the dequantisation of weights, exactly as codec/btf_package.c
// does it (float32 arithmetic: Wt = lo + step * q). No DOM, no GL: usable in node.

export const MAX_RINGS = 32;      // BTF_MAX_RINGS of shaders/btf_dirs.glsl
export const MAX_DIRS = 2048;
export const MAX_CHUNKS = 1024;
export const MAX_SIZE = 16384;

const f32 = Math.fround;

function fail(name, msg) {
  throw new Error(`package ${name}: ${msg}`);
}

function isInt(v, lo, hi) {
  return Number.isInteger(v) && v >= lo && v <= hi;
}

// Ring table -> {rings: Float32Array(4 * n) of (theta, count, phi_offset, start), n, dirs}.
function parseDirset(name, what, j) {
  const rings = j && Array.isArray(j.rings) ? j.rings : null;
  if (!rings || rings.length < 1 || rings.length > MAX_RINGS)
    fail(name, `"${what}" needs 1..${MAX_RINGS} rings`);
  const out = new Float32Array(4 * MAX_RINGS);
  let total = 0;
  rings.forEach((g, r) => {
    const theta = g && g.theta, count = g && g.count, off = g && g.phi_offset;
    if (!Number.isFinite(theta) || theta < 0 || theta > 90 || !isInt(count, 1, MAX_DIRS) ||
        !Number.isFinite(off))
      fail(name, `"${what}" ring ${r} is invalid`);
    if (r > 0 && !(f32(theta) > out[4 * (r - 1)]))
      fail(name, `"${what}" ring thetas must ascend (ring ${r})`);
    let phi = f32(f32(off) % 360);          // fmodf, as btf_dirset_make
    if (phi < 0) phi = f32(phi + 360);
    out[4 * r] = theta;
    out[4 * r + 1] = count;
    out[4 * r + 2] = phi;
    out[4 * r + 3] = total;
    total += count;
    if (total > MAX_DIRS) fail(name, `"${what}" has more than ${MAX_DIRS} directions`);
  });
  return {rings: out, n: rings.length, dirs: total};
}

function parseRanges(name, list, nBlocks, ci, key) {
  if (!Array.isArray(list) || list.length !== nBlocks)
    fail(name, `chunk ${ci} "${key}" needs ${nBlocks} entries`);
  const out = new Float32Array(2 * nBlocks);
  list.forEach((e, b) => {
    if (!Array.isArray(e) || e.length !== 2 || !Number.isFinite(e[0]) || !Number.isFinite(e[1]) || e[1] < 0)
      fail(name, `chunk ${ci} "${key}"[${b}] is invalid`);
    out[2 * b] = e[0];
    out[2 * b + 1] = e[1];
  });
  return out;
}

// Validates a manifest object and returns the client's view of it. Throws Error
// naming the material and the field on anything outside doc/package-format.md.
export function parseManifest(m) {
  const name = m && typeof m.name === 'string' ? m.name : '?';
  if (!m || m.format !== 'btf-package') fail(name, 'manifest "format" is not "btf-package"');
  if (m.version !== 1) fail(name, `manifest version ${m.version} is not 1`);
  if (!isInt(m.width, 1, MAX_SIZE) || !isInt(m.height, 1, MAX_SIZE)) fail(name, 'width/height out of range');
  if (m.bits !== 8 && m.bits !== 16) fail(name, '"bits" must be 8 or 16');
  const lights = parseDirset(name, 'lights', m.lights);
  const views = parseDirset(name, 'views', m.views);
  const blocks = m.blocks;
  if (!Array.isArray(blocks) || blocks.length < 1 || blocks.length > views.dirs) fail(name, '"blocks" is invalid');
  const viewBlock = new Int32Array(views.dirs).fill(-1);
  blocks.forEach((bl, b) => {
    if (!Array.isArray(bl) || bl.length < 1) fail(name, `block ${b} is empty`);
    for (const v of bl) {
      if (!isInt(v, 0, views.dirs - 1) || viewBlock[v] !== -1) fail(name, `block ${b} names view ${v} twice or out of range`);
      viewBlock[v] = b;
    }
  });
  if (viewBlock.includes(-1)) fail(name, '"blocks" do not cover every view');
  const a = m.atlas || {};
  const nb = blocks.length;
  if (!isInt(a.cols, 1, nb) || !isInt(a.rows, 1, nb) || a.cols * a.rows < nb || a.tile_width !== m.width ||
      a.tile_height !== m.height || a.width !== a.cols * m.width || a.height !== a.rows * m.height)
    fail(name, '"atlas" does not match the blocks and the texture size');
  if (!Array.isArray(m.chunks) || m.chunks.length < 1 || m.chunks.length > MAX_CHUNKS)
    fail(name, `needs 1..${MAX_CHUNKS} chunks`);
  const fileOk = (f) => typeof f === 'string' && /^[A-Za-z0-9._-]+$/.test(f) && f[0] !== '.';
  const chunks = m.chunks.map((c, i) => {
    if (!c || !Array.isArray(c.files) || !c.files.every(fileOk)) fail(name, `chunk ${i} has invalid "files"`);
    const tex = c.files.find((f) => f.startsWith('tex-'));
    const wt = c.files.find((f) => f.startsWith('wt-'));
    if (!tex || !wt) fail(name, `chunk ${i} lacks a tex-* or wt-* file`);
    return {
      id: i, component: c.component, files: c.files.slice(), tex, wt,
      bytes: Number.isFinite(c.bytes) ? c.bytes : 0,
      rmse: c.rmse, lab: c.lab, psnr: c.psnr, deltaE: c.delta_e76,
      texRange: parseRanges(name, c.tex_range, nb, i, 'tex_range'),
      wtRange: parseRanges(name, c.wt_range, nb, i, 'wt_range'),
    };
  });
  return {
    name, width: m.width, height: m.height, bits: m.bits, lights, views, viewBlock, nBlocks: nb,
    atlas: {cols: a.cols, rows: a.rows, width: a.width, height: a.height}, chunks,
    totalBytes: chunks.reduce((s, c) => s + c.bytes, 0),
  };
}

// wt-JJ.bin (little-endian uint16, index (v*L + l)*3 + c) -> Float32Array of the
// same layout, Wt = lo + step * q in float32 with the range of the view's block.
export function dequantWeights(pkg, chunk, buf) {
  const L = pkg.lights.dirs, V = pkg.views.dirs;
  const n = V * L * 3;
  if (buf.byteLength !== 2 * n)
    fail(pkg.name, `${chunk.wt} has ${buf.byteLength} bytes, expected ${2 * n}`);
  const dv = new DataView(buf instanceof ArrayBuffer ? buf : buf.buffer, buf.byteOffset || 0, 2 * n);
  const out = new Float32Array(n);
  for (let v = 0; v < V; v++) {
    const b = pkg.viewBlock[v];
    const lo = chunk.wtRange[2 * b], step = chunk.wtRange[2 * b + 1];
    for (let i = v * L * 3, e = (v + 1) * L * 3; i < e; i++)
      out[i] = f32(lo + f32(step * dv.getUint16(2 * i, true)));
  }
  return out;
}

// Chunks [0, n) whose summed bytes stay within maxBytes (-1 / undefined: no limit).
export function chunksWithinBytes(pkg, maxBytes) {
  if (!(maxBytes >= 0)) return pkg.chunks.length;
  let sum = 0;
  for (let i = 0; i < pkg.chunks.length; i++)
    if ((sum += pkg.chunks[i].bytes) > maxBytes) return i;
  return pkg.chunks.length;
}

// Error the decoder reaches with chunks [0, n): the manifest's promise.
export function promisedError(pkg, n) {
  const c = pkg.chunks[Math.min(n, pkg.chunks.length) - 1];
  if (!c) return null;
  return {chunks: n, lab: c.lab, rmse: c.rmse, psnr: c.psnr};
}
