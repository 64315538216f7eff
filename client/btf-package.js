// btf-package.js - the package manifest (doc/package-format.md) on the client:
// validation against the limits of section 8, direction-set uniforms, the view ->
// block table, and the dequantisation of weights, exactly as codec/btf_package.c
// does it (float32 arithmetic: Wt = lo + step * q). No DOM, no GL: usable in node.

export const MAX_RINGS = 32;      // BTF_MAX_RINGS of shaders/btf_dirs.glsl
export const MAX_DIRS = 2048;
export const MAX_LIST_DIRS = 1024; // BTF_MAX_LIST_DIRS
export const MAX_CHUNKS = 1024;
export const MAX_SIZE = 16384;

const f32 = Math.fround;

function fail(name, msg) {
  throw new Error(`package ${name}: ${msg}`);
}

function isInt(v, lo, hi) {
  return Number.isInteger(v) && v >= lo && v <= hi;
}

// "lights" / "views" -> {rings: Float32Array(4 * n) of (theta, count, phi_offset, start), n, dirs,
// maxTheta}; a direction list (doc/data-model.md) -> {list: Float32Array(2 * dirs) of (theta, phi),
// tris: Int32Array(3 * triangles) in list numbering, n: 0, dirs, maxTheta}.
function parseDirset(name, what, j) {
  if (j && j.directions !== undefined) return parseList(name, what, j);
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
  return {rings: out, n: rings.length, dirs: total, maxTheta: out[4 * (rings.length - 1)]};
}

// A direction list with the triangles its writer made (checked when the table is built).
function parseList(name, what, j) {
  const a = j.directions, t = j.triangles;
  if (!Array.isArray(a) || a.length < 3 || a.length > MAX_LIST_DIRS)
    fail(name, `"${what}" must list 3..${MAX_LIST_DIRS} directions`);
  const n = a.length, list = new Float32Array(2 * n);
  let maxTheta = 0;
  a.forEach((e, i) => {
    const theta = e && e.theta, phi = e && e.phi;
    if (!Number.isFinite(theta) || theta < 0 || theta > 90 || !Number.isFinite(phi) || Math.abs(phi) > 1e6)
      fail(name, `"${what}" direction ${i} is invalid`);
    let p = f32(f32(phi) % 360);            // as btf_dirset_make_list
    if (p < 0) p = f32(p + 360);
    list[2 * i] = theta;
    list[2 * i + 1] = f32(theta) === 0 ? 0 : p;
    maxTheta = Math.max(maxTheta, list[2 * i]);
  });
  if (!Array.isArray(t) || t.length % 3 !== 0 || t.length < 3 || t.length > 12 * (2 * n + 2))
    fail(name, `"${what}" "triangles" must hold 1..${4 * (2 * n + 2)} vertex triples`);
  t.forEach((x, i) => {
    if (!isInt(x, 0, 2 * n - 1)) fail(name, `"${what}" triangle vertex ${i} is not in 0..${2 * n - 1}`);
  });
  return {list, tris: Int32Array.from(t), n: 0, dirs: n, maxTheta};
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

// Standard base64 -> Uint8Array (browser atob or node Buffer).
function fromBase64(s) {
  if (typeof atob === 'function') return Uint8Array.from(atob(s), (ch) => ch.charCodeAt(0));
  return new Uint8Array(Buffer.from(s, 'base64'));
}

// Version 2 "ranges" (section 10): per component, base64 of B x 4 float32 LE
// (tex lo, tex step, wt lo, wt step) -> [{tex: Float32Array(2B), wt: Float32Array(2B)}],
// null for an empty entry (a component no chunk has).
function parseCompactRanges(name, list, nBlocks) {
  if (!Array.isArray(list) || list.length < 1) fail(name, '"ranges" needs one entry per component');
  return list.map((e, c) => {
    if (e === '') return null; // a component without chunks (section 3.4)
    let bytes = null;
    if (typeof e === 'string' && e.length === 4 * Math.ceil((16 * nBlocks) / 3)) {
      try { bytes = fromBase64(e); } catch { bytes = null; }
    }
    if (!bytes || bytes.length !== 16 * nBlocks) fail(name, `"ranges"[${c}] is not ${nBlocks} x 4 float32 in base64`);
    const dv = new DataView(bytes.buffer, bytes.byteOffset, bytes.length);
    const tex = new Float32Array(2 * nBlocks), wt = new Float32Array(2 * nBlocks);
    for (let b = 0; b < nBlocks; b++) {
      tex[2 * b] = dv.getFloat32(16 * b, true);
      tex[2 * b + 1] = dv.getFloat32(16 * b + 4, true);
      wt[2 * b] = dv.getFloat32(16 * b + 8, true);
      wt[2 * b + 1] = dv.getFloat32(16 * b + 12, true);
    }
    for (const v of [...tex, ...wt]) if (!Number.isFinite(v)) fail(name, `"ranges"[${c}] holds a non-finite number`);
    for (let b = 0; b < nBlocks; b++)
      if (tex[2 * b + 1] < 0 || wt[2 * b + 1] < 0) fail(name, `"ranges"[${c}] block ${b} has a negative step`);
    return {tex, wt};
  });
}

// Version-2 and 4 header: levels (tiles divisible by 2^(levels-1)), ranges, weights8_step;
// version 3: ranges, when the chunks leave theirs out.
function parseLevels(name, m, nb) {
  const compact = () => (m.ranges === undefined ? null : parseCompactRanges(name, m.ranges, nb));
  if (m.version === 3) return {levels: 1, ranges: compact(), wt8Step: []}; // version 3: "ranges" optional
  if (m.version !== 2 && m.version !== 4) return {levels: 1, ranges: null, wt8Step: []};
  if (m.version === 4 && m.bits !== 8) fail(name, 'version 4 (residual levels) needs "bits": 8');
  if (!isInt(m.levels, 1, 15) || m.width % (1 << (m.levels - 1)) || m.height % (1 << (m.levels - 1)))
    fail(name, '"levels" is invalid for the texture size');
  const ranges = compact();
  const w8 = m.weights8_step === undefined ? [] : m.weights8_step;
  if (!Array.isArray(w8) || !w8.every((v) => isInt(v, 0, 65535))) fail(name, '"weights8_step" is invalid');
  return {levels: m.levels, ranges, wt8Step: w8.map((v) => v || 257)};
}

// One chunk's client view; v2 adds level, contrib, the 8-bit weights, ranges by component.
// version: the layout (1 or 2), mv: the manifest's version.
function parseChunk(name, c, i, nb, lv, version, mv) {
  const fileOk = (f) => typeof f === 'string' && /^[A-Za-z0-9._-]+$/.test(f) && f[0] !== '.';
  if (!c || !Array.isArray(c.files) || !c.files.every(fileOk)) fail(name, `chunk ${i} has invalid "files"`);
  const tex = c.files.find((f) => f.startsWith('tex-'));
  // Weights files (section 7.1). 8-bit: wt-*.png, else (version 4) wt-*-8.webp; 16-bit:
  // any other wt-* file, .bin first, else .z (-r.z too), else .pz, else (version 3) .webp.
  const w8s = c.files.filter((f) => f.startsWith('wt-') && (f.endsWith('.png') || (mv === 4 && f.endsWith('-8.webp'))));
  const wts = c.files.filter((f) => f.startsWith('wt-') && !w8s.includes(f));
  const wt = ['.bin', '.z', '.pz', '.webp'].reduce((w, e) => w ?? wts.find((f) => f.endsWith(e)), undefined) ?? wts[0];
  const wt8 = version >= 2 ? w8s.find((f) => f.endsWith('.png')) ?? w8s[0] : undefined;
  if (!tex || (version < 2 && !wt)) fail(name, `chunk ${i} lacks a tex-* or wt-* file`);
  const level = version >= 2 ? c.level ?? 0 : 0;
  if (!isInt(level, 0, lv.levels - 1)) fail(name, `chunk ${i} "level" is out of range`);
  const component = version >= 2 || c.component !== undefined ? c.component : i;
  if (version >= 2 && !isInt(component, 0, MAX_CHUNKS - 1)) fail(name, `chunk ${i} "component" is invalid`);
  const own = c.tex_range !== undefined || (version < 2 && !lv.ranges);
  const r = own ? null : lv.ranges && lv.ranges[component];
  if (!own && !r) fail(name, `chunk ${i}: no "ranges" entry for component ${component}`);
  return {
    id: i, component, level, contrib: c.contrib, files: c.files.slice(), tex, wt, wt8, predictor: c.predictor,
    bytes: Number.isFinite(c.bytes) ? c.bytes : 0,
    rmse: c.rmse, lab: c.lab, psnr: c.psnr ?? psnrOf(c.rmse), deltaE: c.delta_e76,
    texRange: own ? parseRanges(name, c.tex_range, nb, i, 'tex_range') : r.tex,
    wtRange: own || c.wt_range !== undefined ? parseRanges(name, c.wt_range, nb, i, 'wt_range') : r.wt,
    wt8Step: lv.wt8Step[component] || 257,
  };
}

// Version 4 (section 12): each (component, level) once, and a residual level (a
// texture named ...-dL.png, .webp or .avif, L its level, below the coarsest) only after the same
// component's next coarser level. Marks the chunks (.residual).
function residualOrder(name, chunks, levels) {
  const seen = new Set();
  chunks.forEach((c, i) => {
    const key = (l) => `${c.component}/${l}`;
    if (seen.has(key(c.level))) fail(name, `chunk ${i}: level ${c.level} of component ${c.component} twice`);
    c.residual = c.level < levels - 1 && /-d(\d+)\.(png|webp|avif)$/.exec(c.tex)?.[1] === String(c.level);
    const pr = c.predictor;
    if (pr !== undefined && (!c.residual || !Array.isArray(pr) || pr.length !== 3 * PRED_N ||
        !pr.every((v) => isInt(v, -PRED_MAX, PRED_MAX))))
      fail(name, `chunk ${i}: "predictor" is not ${3 * PRED_N} integers within +-${PRED_MAX} of a residual level`);
    c.pred = pr === undefined ? DEFAULT_PRED : Int32Array.from(pr);
    if (c.residual && !seen.has(key(c.level + 1)))
      fail(name, `chunk ${i} (residual level ${c.level} of component ${c.component}) comes before that component's ` +
               `level ${c.level + 1}`);
    seen.add(key(c.level));
  });
}

// Version 4 residual predictor (section 12, a chunk's "predictor"): per texel class
// (even x and y, odd x, odd y) 6 weights of (eL, eU, eUR, eUL, D, 1), in 64ths; a
// residual chunk that lists none has the default p + floor((eL + eU) / 4).
const PRED_N = 6, PRED_MAX = 4096;
const DEFAULT_PRED = Int32Array.from([16, 16, 0, 0, 0, 0, 16, 16, 0, 0, 0, 0, 16, 16, 0, 0, 0, 0]);

// The 9-3-3-1 bilinear prediction of every fine texel from the coarse level, clamped
// to its tile (tiles of tw x th fine texels, the atlas aw x ah).
function bilinearLevel(coarse, aw, ah, tw, th) {
  const cw = aw >> 1, tcw = tw >> 1, tch = th >> 1, P = new Int16Array(aw * ah);
  for (let y = 0; y < ah; y++) {
    const Y = y >> 1, y0 = Y - (Y % tch), Y2 = Math.min(Math.max(Y + (y & 1 ? 1 : -1), y0), y0 + tch - 1);
    for (let x = 0; x < aw; x++) {
      const X = x >> 1, x0 = X - (X % tcw), X2 = Math.min(Math.max(X + (x & 1 ? 1 : -1), x0), x0 + tcw - 1);
      P[y * aw + x] = (9 * coarse[Y * cw + X] + 3 * coarse[Y * cw + X2] + 3 * coarse[Y2 * cw + X] + coarse[Y2 * cw + X2] + 8) >> 4;
    }
  }
  return P;
}

// Version 4 residual level (section 12) -> the level's atlas bytes. res: the decoded
// residual PNG (aw x ah values 0..255, any indexable), coarse: the reconstructed bytes
// of the component's next coarser level ((aw/2) x (ah/2)); chunk.level gives the tile
// size, chunk.pred the predictor.
export function reconstructLevel(pkg, chunk, res, coarse) {
  const l = chunk.level, tw = pkg.width >> l, th = pkg.height >> l;
  const aw = tw * pkg.atlas.cols, ah = th * pkg.atlas.rows, cw = aw >> 1;
  if (res.length !== aw * ah || coarse.length !== (aw >> 1) * (ah >> 1))
    fail(pkg.name, `${chunk.tex}: ${res.length} residual texels over ${coarse.length} coarse ones, expected ` +
                   `${aw * ah} over ${(aw >> 1) * (ah >> 1)}`);
  const P = bilinearLevel(coarse, aw, ah, tw, th), w = chunk.pred || DEFAULT_PRED, out = new Uint8Array(aw * ah);
  for (let y = 0; y < ah; y++) {
    const ty = y % th;
    for (let x = 0; x < aw; x++) {
      const i = y * aw + x, C4 = 4 * coarse[(y >> 1) * cw + (x >> 1)];
      let v;
      if (x & 1 && y & 1) v = C4 + res[i] - 128 - out[i - aw - 1] - out[i - aw] - out[i - 1];
      else {
        const tx = x % tw, k = PRED_N * ((x & 1) + 2 * (y & 1)), c = (y & ~1) * aw + (x & ~1);
        const eL = tx > 0 ? out[i - 1] - P[i - 1] : 0, eU = ty > 0 ? out[i - aw] - P[i - aw] : 0;
        const eUR = ty > 0 && tx < tw - 1 ? out[i - aw + 1] - P[i - aw + 1] : 0;
        const eUL = ty > 0 && tx > 0 ? out[i - aw - 1] - P[i - aw - 1] : 0;
        const d = C4 - (P[c] + P[c + 1] + P[c + aw] + P[c + aw + 1]);
        const s = w[k] * eL + w[k + 1] * eU + w[k + 2] * eUR + w[k + 3] * eUL + w[k + 4] * d + w[k + 5];
        v = P[i] + Math.floor(s / 64) + res[i] - 128;
      }
      out[i] = v & 255; // mod 256 (two's complement)
    }
  }
  return out;
}

// Validates a manifest object and returns the client's view of it. Throws Error
// naming the material and the field on anything outside doc/package-format.md.
// Versions 1, 2 (section 10: (component, level) chunks) and 3 (section 11: version
// 1 with wt-JJ.z, wt-JJ.pz or wt-JJ.webp weights). `version` of the result is the chunk
// layout the GPU side follows (1: one chunk per component at level 0, 2: levels), so a version-3
// manifest reads as 1 there; `manifestVersion` is the number in the file.
export function parseManifest(m) {
  const name = m && typeof m.name === 'string' ? m.name : '?';
  if (!m || m.format !== 'btf-package') fail(name, 'manifest "format" is not "btf-package"');
  if (![1, 2, 3, 4].includes(m.version)) fail(name, `manifest version ${m.version} is not 1, 2, 3 or 4`);
  const layout = m.version === 2 || m.version === 4 ? 2 : 1;
  if (!isInt(m.width, 1, MAX_SIZE) || !isInt(m.height, 1, MAX_SIZE)) fail(name, 'width/height out of range');
  if (m.bits !== 8 && m.bits !== 16) fail(name, '"bits" must be 8 or 16');
  // "encoding" (section 3.7): absent or "srgb" = sRGB-encoded values, "linear" = linear light
  if (m.encoding !== undefined && m.encoding !== 'srgb' && m.encoding !== 'linear')
    fail(name, '"encoding" must be "srgb" or "linear"');
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
  const lv = parseLevels(name, m, nb);
  const chunks = m.chunks.map((c, i) => parseChunk(name, c, i, nb, lv, layout, m.version));
  if (m.version === 3 && !chunks.every((c) => ['.z', '.pz', '.webp'].some((e) => c.wt.endsWith(e))))
    fail(name, 'version 3 needs a wt-*.z, wt-*.pz or wt-*.webp file per chunk');
  chunks.forEach((c, i) => {
    if (m.version !== 3 && c.wt && c.wt.endsWith('.webp'))
      fail(name, `chunk ${i}: ${c.wt}: WebP weights are version 3's`);
  });
  if (m.version === 4) residualOrder(name, chunks, lv.levels);
  const comps = [...new Set(chunks.map((c) => c.component))];
  return {
    name, version: layout, manifestVersion: m.version, levels: lv.levels, components: comps, width: m.width, height: m.height, bits: m.bits,
    linear: m.encoding === 'linear', lights, views, viewBlock, nBlocks: nb,
    atlas: {cols: a.cols, rows: a.rows, width: a.width, height: a.height}, chunks,
    totalBytes: chunks.reduce((s, c) => s + c.bytes, 0),
  };
}

// q(i) (index (v*L + l)*3 + c) -> Float32Array, Wt = lo + step * q in float32 with
// the range of the view's block.
function dequantQ(pkg, chunk, q) {
  const L = pkg.lights.dirs, V = pkg.views.dirs;
  const out = new Float32Array(V * L * 3);
  for (let v = 0; v < V; v++) {
    const b = pkg.viewBlock[v];
    const lo = chunk.wtRange[2 * b], step = chunk.wtRange[2 * b + 1];
    for (let i = v * L * 3, e = (v + 1) * L * 3; i < e; i++) out[i] = f32(lo + f32(step * q(i)));
  }
  return out;
}

// wt-JJ.bin (little-endian uint16, index (v*L + l)*3 + c) -> Float32Array of the
// same layout, Wt = lo + step * q in float32 with the range of the view's block.
export function dequantWeights(pkg, chunk, buf) {
  const n = pkg.views.dirs * pkg.lights.dirs * 3;
  if (buf.byteLength !== 2 * n)
    fail(pkg.name, `${chunk.wt} has ${buf.byteLength} bytes, expected ${2 * n}`);
  const dv = new DataView(buf instanceof ArrayBuffer ? buf : buf.buffer, buf.byteOffset || 0, 2 * n);
  return dequantQ(pkg, chunk, (i) => dv.getUint16(2 * i, true));
}

// Inflates a zlib stream (DecompressionStream 'deflate' = RFC 1950) that must
// produce exactly `want` bytes; stops reading once it produces more.
async function inflateExactly(name, file, buf, want) {
  const bytes = buf instanceof Uint8Array ? buf : new Uint8Array(buf);
  const ds = new DecompressionStream('deflate');
  const writer = ds.writable.getWriter();
  writer.write(bytes).catch(() => {});
  writer.close().catch(() => {});
  const reader = ds.readable.getReader();
  const out = new Uint8Array(want);
  let got = 0;
  try {
    for (;;) {
      const {done, value} = await reader.read();
      if (done) break;
      if (got + value.length > want) {
        reader.cancel().catch(() => {});
        fail(name, `${file} inflates to more than ${want} bytes`);
      }
      out.set(value, got);
      got += value.length;
    }
  } catch (e) {
    if (e.message.startsWith(`package ${name}:`)) throw e;
    fail(name, `${file} is not a complete zlib stream (${e.message})`);
  }
  if (got !== want) fail(name, `${file} inflates to ${got} bytes, expected ${want}`);
  return out;
}

// Version 3 wt-JJ.z (section 11): zlib of two byte planes of zigzag differences
// along the lights -> the same Float32Array as dequantWeights.
export async function dequantWeightsZ(pkg, chunk, buf) {
  const L = pkg.lights.dirs, n = pkg.views.dirs * L * 3;
  if (buf.byteLength < 1 || buf.byteLength > 2 * n + 1024)
    fail(pkg.name, `${chunk.wt} has ${buf.byteLength} bytes, expected 1..${2 * n + 1024}`);
  const raw = await inflateExactly(pkg.name, chunk.wt, buf, 2 * n);
  const q = new Uint16Array(n);
  for (let i = 0; i < n; i++) {
    const z = raw[i] | (raw[n + i] << 8);
    const d = (z >>> 1) ^ -(z & 1);
    q[i] = ((Math.floor(i / 3) % L) > 0 ? q[i - 3] : 0) + d; // Uint16Array wraps mod 65536
  }
  return dequantQ(pkg, chunk, (i) => q[i]);
}

// wt-JJ.pz (section 5.4), versions 3 and 4: zlib of two byte planes of zigzag
// residuals; the prediction adds to the previous light's value the change of the
// view before in the same block (prev) from its previous light to this one, and
// channels 0 and 2 store their residual less channel 1's.
export async function dequantWeightsP(pkg, chunk, buf) {
  const L = pkg.lights.dirs, V = pkg.views.dirs, n = V * L * 3;
  if (buf.byteLength < 1 || buf.byteLength > 2 * n + 1024)
    fail(pkg.name, `${chunk.wt} has ${buf.byteLength} bytes, expected 1..${2 * n + 1024}`);
  const raw = await inflateExactly(pkg.name, chunk.wt, buf, 2 * n);
  const q = new Uint16Array(n), r = new Int32Array(3);
  for (let v = 0; v < V; v++) {
    let u = v - 1;
    while (u >= 0 && pkg.viewBlock[u] !== pkg.viewBlock[v]) u--;
    for (let l = 0; l < L; l++) {
      const i = (v * L + l) * 3;
      for (let c = 0; c < 3; c++) {
        const z = raw[i + c] | (raw[n + i + c] << 8);
        r[c] = (z >>> 1) ^ -(z & 1);
      }
      for (let c = 0; c < 3; c++) {
        const a = l > 0 ? q[i - 3 + c] : 0;
        const p = u < 0 ? a : l > 0 ? a + q[(u * L + l) * 3 + c] - q[(u * L + l - 1) * 3 + c] : q[u * L * 3 + c];
        q[i + c] = p + r[c] + (c !== 1 ? r[1] : 0); // Uint16Array wraps mod 65536
      }
    }
  }
  return dequantQ(pkg, chunk, (i) => q[i]);
}

// Version 4 wt-JJ-r.z (section 12): zlib of two byte planes of the zigzag codes of
// r = (q16 - s_c q8) mod 65536 (no prediction along the lights), over q8, the
// component's 8-bit weights (wt-JJ-8.png pixels) -> the same Float32Array as dequantWeights.
export async function dequantWeightsR(pkg, chunk, buf, q8) {
  const n = pkg.views.dirs * pkg.lights.dirs * 3;
  if (buf.byteLength < 1 || buf.byteLength > 2 * n + 1024)
    fail(pkg.name, `${chunk.wt} has ${buf.byteLength} bytes, expected 1..${2 * n + 1024}`);
  if (!q8 || q8.length !== n) fail(pkg.name, `${chunk.wt}: the component's 8-bit weights have not arrived before it`);
  const raw = await inflateExactly(pkg.name, chunk.wt, buf, 2 * n);
  const sc = chunk.wt8Step;
  return dequantQ(pkg, chunk, (i) => {
    const z = raw[i] | (raw[n + i] << 8);
    return (sc * q8[i] + ((z >>> 1) ^ -(z & 1))) & 0xffff;
  });
}

// Weights as a WebP: version 3's wt-JJ.webp (section 5.5: the 16-bit weight codes, every
// one at most 255) and version 4's wt-JJ-8.webp (section 5.2: the 8-bit weights), each
// L x V pixels, lossless (every pixel opaque) or lossy (its decode the codes), pixel (l, v)
// holding channels 0, 1, 2 of view v and light l in R, G, B. The bytes of file f (default:
// the chunk's 16-bit weights), checked before an image decoder sees them as the C reader
// does: a simple-format file (RIFF WEBP, one VP8L chunk or one VP8 key frame, filling it)
// whose header says L x V; another kind (VP8X) or another size fails naming the package
// and file.
export function checkWeightsWebp(pkg, chunk, buf, f = chunk.wt) {
  const b = buf instanceof Uint8Array ? buf : new Uint8Array(buf), n = b.length;
  const tag = (o) => String.fromCharCode(b[o], b[o + 1], b[o + 2], b[o + 3]);
  const le32 = (o) => (b[o] | (b[o + 1] << 8) | (b[o + 2] << 16) | (b[o + 3] << 24)) >>> 0;
  const L = pkg.lights.dirs, V = pkg.views.dirs, max = 2 * V * L * 3 + 1024;
  if (n < 1 || n > max) fail(pkg.name, `${f} has ${n} bytes, expected 1..${max}`);
  if (n < 12 || tag(0) !== 'RIFF' || tag(8) !== 'WEBP')
    fail(pkg.name, `${f}: not a WebP file (no RIFF/WEBP signature)`);
  if (n < 25) fail(pkg.name, `${f}: WebP file of ${n} bytes is truncated`);
  if (le32(4) + 8 !== n) fail(pkg.name, `${f}: RIFF size ${le32(4)} does not match the file's ${n} bytes`);
  const [w, h] = tag(12) === 'VP8 ' ? vp8Size(pkg, f, b, n, le32) : vp8lSize(pkg, f, b, n, tag, le32);
  if (w !== L || h !== V) fail(pkg.name, `${f}: WebP of ${w}x${h}, expected ${L}x${V}`);
}

// [width, height] of a lossless (VP8L) WebP whose RIFF header checkWeightsWebp checked.
function vp8lSize(pkg, f, b, n, tag, le32) {
  if (tag(12) !== 'VP8L') fail(pkg.name, `${f}: WebP chunk '${tag(12)}' is not a simple lossless (VP8L) image`);
  const size = le32(16), bits = le32(21);
  if (size < 5 || size + 20 + (size & 1) !== n)
    fail(pkg.name, `${f}: VP8L chunk of ${size} bytes does not fill the file`);
  if (b[20] !== 0x2f || bits >>> 29 !== 0) fail(pkg.name, `${f}: bad VP8L signature or version`);
  return [(bits & 0x3fff) + 1, ((bits >>> 14) & 0x3fff) + 1];
}

// [width, height] of a lossy (VP8) WebP: one shown key frame of version 0..3 with its
// start code, no scaling, its first partition inside the chunk (the C reader's check).
function vp8Size(pkg, f, b, n, le32) {
  const size = le32(16);
  if (n < 30 || size < 10 || size + 20 + (size & 1) !== n)
    fail(pkg.name, `${f}: VP8 chunk of ${size} bytes does not fill the file`);
  const tag = b[20] | (b[21] << 8) | (b[22] << 16);
  if (tag & 1) fail(pkg.name, `${f}: VP8 frame is not a key frame`);
  if (((tag >> 1) & 7) > 3 || !((tag >> 4) & 1)) fail(pkg.name, `${f}: VP8 frame of a version above 3 or not shown`);
  if (b[23] !== 0x9d || b[24] !== 0x01 || b[25] !== 0x2a) fail(pkg.name, `${f}: bad VP8 start code`);
  const ws = b[26] | (b[27] << 8), hs = b[28] | (b[29] << 8);
  if (ws >> 14 || hs >> 14 || !(ws & 0x3fff) || !(hs & 0x3fff)) fail(pkg.name, `${f}: VP8 frame scaled or empty`);
  if (tag >>> 5 > size - 10) fail(pkg.name, `${f}: VP8 first partition of ${tag >>> 5} bytes overruns its chunk`);
  return [ws & 0x3fff, hs & 0x3fff];
}

// The codes of a weights WebP f from its decoded pixels (width x height, rgba: 4 bytes a
// pixel, rows top-down, alpha as decoded, neither premultiplied nor colour-converted):
// q[(v*L + l)*3 + c] = sample c of pixel (x = l, y = v), a Uint8Array of V*L*3. Another
// size or a pixel whose alpha is not 255 fails naming the package and file.
function webpCodes(pkg, f, width, height, rgba) {
  const L = pkg.lights.dirs, V = pkg.views.dirs;
  if (width !== L || height !== V) fail(pkg.name, `${f} is ${width}x${height}, expected ${L}x${V}`);
  if (!rgba || rgba.length !== 4 * L * V)
    fail(pkg.name, `${f} has ${rgba ? rgba.length : 0} pixel bytes, expected ${4 * L * V}`);
  const q = new Uint8Array(3 * L * V);
  for (let p = 0; p < L * V; p++) {
    if (rgba[4 * p + 3] !== 255) fail(pkg.name, `${f}: pixel ${p} is not opaque (alpha ${rgba[4 * p + 3]})`);
    q[3 * p] = rgba[4 * p];
    q[3 * p + 1] = rgba[4 * p + 1];
    q[3 * p + 2] = rgba[4 * p + 2];
  }
  return q;
}

// Version 3's wt-JJ.webp decoded (webpCodes) -> the same Float32Array as dequantWeights.
export function dequantWeightsW(pkg, chunk, width, height, rgba) {
  const q = webpCodes(pkg, chunk.wt, width, height, rgba);
  return dequantQ(pkg, chunk, (i) => q[i]);
}

// Version 4's wt-JJ-8.webp decoded (webpCodes) -> the 8-bit weights q8 (Uint8Array, the
// index order of wt-JJ-8.png's pixels) for dequantWeights8 and dequantWeightsR.
export function weights8Webp(pkg, chunk, width, height, rgba) {
  return webpCodes(pkg, chunk.wt8, width, height, rgba);
}

// A chunk's 16-bit weights file, whichever coding its name says: a Promise of the
// Float32Array (q8: version 4's 8-bit weights of the component, for wt-JJ-r.z). A
// wt-JJ.webp is an image: checkWeightsWebp, the browser's decoder, then dequantWeightsW
// (btf-upload.js); here it fails.
export async function decodeWeights(pkg, chunk, buf, q8) {
  if (chunk.wt.endsWith('.webp'))
    fail(pkg.name, `${chunk.wt}: WebP weights need an image decoder (checkWeightsWebp, dequantWeightsW)`);
  if (pkg.manifestVersion === 4 && chunk.wt.endsWith('-r.z')) return dequantWeightsR(pkg, chunk, buf, q8);
  if (pkg.manifestVersion >= 3 && chunk.wt.endsWith('.pz')) return dequantWeightsP(pkg, chunk, buf);
  return chunk.wt.endsWith('.z') ? dequantWeightsZ(pkg, chunk, buf) : dequantWeights(pkg, chunk, buf);
}

// wt-JJ-8.png pixels (grey, 3L x V, the same index order as wt-JJ.bin; or version 4's
// wt-JJ-8.webp codes, weights8Webp) -> Float32Array,
// Wt = lo + (s_c * step) * q in float32 as codec/btf_package.c.
export function dequantWeights8(pkg, chunk, px) {
  const L = pkg.lights.dirs, V = pkg.views.dirs, n = V * L * 3;
  if (px.length !== n) fail(pkg.name, `${chunk.wt8} has ${px.length} pixels, expected ${n}`);
  const out = new Float32Array(n);
  for (let v = 0; v < V; v++) {
    const b = pkg.viewBlock[v];
    const lo = chunk.wtRange[2 * b], st = f32(f32(chunk.wt8Step) * chunk.wtRange[2 * b + 1]);
    for (let i = v * L * 3, e = (v + 1) * L * 3; i < e; i++) out[i] = f32(lo + f32(st * px[i]));
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

// A chunk's PSNR from its RMSE (0..255 scale), where the manifest leaves it out
// (version 3, doc/package-format.md section 9.3): 20 log10(255 / rmse), 999 at 0.
function psnrOf(rmse) {
  if (!Number.isFinite(rmse)) return undefined;
  return rmse > 0 ? 20 * Math.log10(255 / rmse) : 999;
}

// Error the decoder reaches with chunks [0, n): the manifest's promise.
export function promisedError(pkg, n) {
  const c = pkg.chunks[Math.min(n, pkg.chunks.length) - 1];
  if (!c) return null;
  return {chunks: n, lab: c.lab, rmse: c.rmse, psnr: c.psnr};
}
