// btf-gltf.js - glTF 2.0 models for <btf-viewer model="...">: every triangle primitive
// of the model's scene, node transforms applied, as world-space meshes, each with its
// glTF material's name and base colour. The browser twin of shaders/host/btf_gltf.cpp
// (`btf render --model`): the same checks, the same limits (BTF_GLTF_MAX_* of
// shaders/host/btf_gltf.h) and the same arithmetic (float32 storage, double in
// between, in the C code's order), so both hosts draw the same triangles.
//
//   const model = await loadModel('chair.glb');        // or parseModel(bytes, {name})
//   for (const p of model.parts) draw(p.material, p.vertices, p.indices);
//
// A part: {material (name, '' when none), materialIndex (-1 when none), baseColor [r, g,
// b, a] (linear, baseColorFactor), hasUv, tangentsGiven, vertices (Float32Array, 12 per
// vertex: position 3, normal 3, tangent 4 (w = handedness), uv 2, world space), indices
// (Uint32Array, triangles)}; model.min/max: world bounds.
//
// Checked before anything is trusted or allocated: the .glb framing, every accessor's
// type, component type, count, offset and stride against its buffer view and buffer,
// every index against its vertex count, finite values, the limits. Refused: modes
// other than triangles, sparse accessors, required extensions, primitive extensions
// (Draco, meshopt). Images are never read. Errors are thrown as Error('NAME: reason').
//
// World: glTF's +y up becomes the world's +z (x' = x, y' = -z, z' = y). Normals: NORMAL,
// else flat face normals. Tangents: TANGENT (with NORMAL), else generateTangents (a
// port of shaders/host/btf_gltf_tangent.c). No DOM, no GL: usable in node.

export const MAX_FILE_BYTES = 256 * 1024 * 1024; // BTF_GLTF_MAX_FILE_BYTES: a .glb, .gltf or external buffer
export const MAX_VERTICES = 4000000;   // all parts, after node instancing
export const MAX_TRIANGLES = 4000000;  // all parts, after node instancing
export const MAX_PARTS = 4096;         // drawn primitives, after instancing
export const MAX_DEPTH = 64;           // node hierarchy depth
export const MAX_NODE_VISITS = 65536;  // node instances in the scene
export const NAME_MAX = 64;            // material name bytes, including the C string's NUL

const F = 12; // floats per vertex (BTF_RENDER_VERTEX_FLOATS)
const f32 = Math.fround;
const UV_AREA_MIN = 1e-20; // BTF__UV_AREA_MIN of btf_gltf_tangent.c

const COMPONENTS = {SCALAR: 1, VEC2: 2, VEC3: 3, VEC4: 4};
const COMPONENT_BYTES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4};
const FLOAT = 5126, UBYTE = 5121, USHORT = 5123, UINT = 5125, BYTE = 5120, SHORT = 5122;

class ModelError extends Error {}

// ------------------------------------------------------------------ container

const isInt = (v) => Number.isInteger(v) && v >= 0;

// The JSON document and the .glb's binary chunk (null for a .gltf) of bytes.
function container(bytes, name) {
  if (bytes.length > MAX_FILE_BYTES) throw new ModelError(`${name}: larger than ${MAX_FILE_BYTES} bytes`);
  if (bytes.length < 4) throw new ModelError(`${name}: not a glTF file (${bytes.length} bytes)`);
  const dv = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  let text, bin = null;
  if (dv.getUint32(0, true) === 0x46546c67) { // "glTF"
    const bad = (why) => new ModelError(`${name}: not a valid glTF: ${why}`);
    if (bytes.length < 20) throw bad(`truncated .glb header (${bytes.length} bytes)`);
    const version = dv.getUint32(4, true), length = dv.getUint32(8, true);
    if (version !== 2) throw bad(`.glb version ${version} (only 2)`);
    if (length > bytes.length) throw bad(`truncated: the header says ${length} bytes, the file has ${bytes.length}`);
    if (length < 20) throw bad(`.glb length ${length}`);
    const jlen = dv.getUint32(12, true);
    if (dv.getUint32(16, true) !== 0x4e4f534a) throw bad('the first chunk is not JSON');
    if (jlen > length - 20) throw bad(`truncated: the JSON chunk (${jlen} bytes) runs past the file`);
    text = bytes.subarray(20, 20 + jlen);
    const at = 20 + jlen;
    if (at + 8 <= length) {
      const blen = dv.getUint32(at, true);
      if (dv.getUint32(at + 4, true) !== 0x004e4942) throw bad('the second chunk is not BIN');
      if (blen > length - at - 8) throw bad(`truncated: the BIN chunk (${blen} bytes) runs past the file`);
      bin = bytes.subarray(at + 8, at + 8 + blen);
    } else if (at !== length && at + 8 > length) {
      throw bad('truncated: a chunk header runs past the file');
    }
  } else {
    text = bytes;
  }
  let doc;
  try {
    doc = JSON.parse(new TextDecoder('utf-8', {fatal: true}).decode(text), (k, v) => {
      if (typeof v === 'number' && !Number.isFinite(v)) throw new Error(`number overflow at "${k}"`); // as tinygltf's JSON
      return v;
    });
  } catch (e) {
    throw new ModelError(`${name}: not a valid glTF: ${e.message}`);
  }
  if (!doc || typeof doc !== 'object' || Array.isArray(doc)) throw new ModelError(`${name}: not a valid glTF: not a JSON object`);
  return {doc, bin};
}

// Base64 of a data URI (data:[type][;base64],DATA) to bytes, its size checked first.
function dataUri(uri, name, what) {
  const m = /^data:[^,]*?;base64,/.exec(uri);
  if (!m) throw new ModelError(`${name}: ${what}: only base64 data URIs are supported`);
  const b64 = uri.slice(m[0].length).replace(/\s+/g, '');
  if (b64.length / 4 * 3 > MAX_FILE_BYTES + 3) throw new ModelError(`${name}: ${what} is larger than the model limit`);
  let s;
  try {
    s = atob(b64);
  } catch (e) {
    throw new ModelError(`${name}: ${what}: invalid base64`);
  }
  const out = new Uint8Array(s.length);
  for (let i = 0; i < s.length; i++) out[i] = s.charCodeAt(i);
  return out;
}

const arr = (x) => (Array.isArray(x) ? x : []);

// Every buffer's bytes: the .glb's BIN chunk, a data URI, or (loadBuffer) a file
// beside the .gltf; each at least its byteLength, cut to it.
async function buffers(doc, bin, name, loadBuffer) {
  const list = doc.buffers === undefined ? [] : doc.buffers;
  if (!Array.isArray(list)) throw new ModelError(`${name}: not a valid glTF: "buffers" is not an array`);
  const out = [];
  for (let i = 0; i < list.length; i++) {
    const b = list[i];
    if (!b || typeof b !== 'object' || !isInt(b.byteLength))
      throw new ModelError(`${name}: not a valid glTF: buffer ${i} has no valid byteLength`);
    if (b.byteLength > MAX_FILE_BYTES) throw new ModelError(`${name}: buffer ${i} is larger than the model limit`);
    let data;
    if (b.uri === undefined) {
      if (i !== 0 || !bin) throw new ModelError(`${name}: not a valid glTF: buffer ${i} has no uri and no .glb BIN chunk`);
      data = bin;
    } else if (typeof b.uri !== 'string') {
      throw new ModelError(`${name}: not a valid glTF: buffer ${i} has an invalid uri`);
    } else if (b.uri.startsWith('data:')) {
      data = dataUri(b.uri, name, `buffer ${i}`);
    } else {
      if (!loadBuffer) throw new ModelError(`${name}: buffer ${i} is a file (${b.uri}), and a model from memory can only use data URIs`);
      data = await loadBuffer(b.uri, i);
      if (!(data instanceof Uint8Array)) data = new Uint8Array(data);
      if (data.length > MAX_FILE_BYTES) throw new ModelError(`${name}: buffer ${b.uri} is larger than the model limit`);
    }
    if (data.length < b.byteLength)
      throw new ModelError(`${name}: not a valid glTF: buffer ${i} has ${data.length} bytes, byteLength says ${b.byteLength}`);
    out.push(data.subarray(0, b.byteLength));
  }
  return out;
}

// ------------------------------------------------------------------ the loader

// The loading of one model: the document, its buffers, what has been made so far.
class Loader {
  constructor(doc, bufs, name) {
    this.g = doc;
    this.bufs = bufs;
    this.name = name;
    this.parts = [];
    this.vertices = 0;
    this.triangles = 0;
    this.visits = 0;
    this.accessors = arr(doc.accessors);
    this.views = arr(doc.bufferViews);
    this.nodes = arr(doc.nodes);
    this.meshes = arr(doc.meshes);
    this.materials = arr(doc.materials);
  }

  fail(msg) {
    throw new ModelError(`${this.name}: ${msg}`);
  }
}

// The bytes of accessor a (btf_gltf.cpp accessor_bytes): view and buffer exist, every
// element inside both, no sparse storage, 1 <= count <= maxCount.
function accessorBytes(L, a, what, maxCount) {
  if (!Number.isInteger(a) || a < 0 || a >= L.accessors.length) L.fail(`${what}: accessor ${a} does not exist`);
  const acc = L.accessors[a];
  if (!acc || typeof acc !== 'object') L.fail(`${what}: accessor ${a} is not an object`);
  if (acc.sparse !== undefined) L.fail(`${what}: accessor ${a} is sparse (not supported)`);
  const nc = COMPONENTS[acc.type] || 0, cb = COMPONENT_BYTES[acc.componentType] || 0;
  if (nc === 0 || cb === 0) L.fail(`${what}: accessor ${a} has an unknown type`);
  const count = acc.count;
  if (!isInt(count) || count === 0 || count > maxCount)
    L.fail(`${what}: accessor ${a} has ${count} elements (1..${maxCount})`);
  const bvi = acc.bufferView;
  if (!Number.isInteger(bvi) || bvi < 0 || bvi >= L.views.length) L.fail(`${what}: accessor ${a} has no buffer view`);
  const bv = L.views[bvi] || {};
  if (!Number.isInteger(bv.buffer) || bv.buffer < 0 || bv.buffer >= L.bufs.length)
    L.fail(`${what}: buffer view ${bvi} has no buffer`);
  const buf = L.bufs[bv.buffer];
  const bvOff = bv.byteOffset ?? 0, bvLen = bv.byteLength;
  if (!isInt(bvOff) || !isInt(bvLen) || bvOff > buf.length || bvLen > buf.length - bvOff)
    L.fail(`${what}: buffer view ${bvi} lies outside its buffer`);
  const es = nc * cb, stride = bv.byteStride ?? 0;
  if (!isInt(stride)) L.fail(`${what}: buffer view ${bvi} has an invalid stride`);
  const st = stride || es;
  if (st < es || st > 252) L.fail(`${what}: buffer view ${bvi} has stride ${st} for ${es}-byte elements`);
  const accOff = acc.byteOffset ?? 0;
  if (!isInt(accOff) || accOff > bvLen || (count - 1) * st + es > bvLen - accOff)
    L.fail(`${what}: accessor ${a} reads past its buffer view`);
  return {acc, base: buf.byteOffset + bvOff + accOff, buffer: buf.buffer, stride: st, nc, cb, count};
}

// One component as a float (btf_gltf.cpp component): floats as they are, normalized
// integers to 0..1 / -1..1.
function component(dv, off, ct, normalized) {
  switch (ct) {
  case FLOAT: return dv.getFloat32(off, true);
  case UBYTE: return normalized ? f32(dv.getUint8(off) / 255) : dv.getUint8(off);
  case BYTE: { const f = dv.getInt8(off); return normalized ? Math.max(f32(f / 127), -1) : f; }
  case USHORT: return normalized ? f32(dv.getUint16(off, true) / 65535) : dv.getUint16(off, true);
  case SHORT: { const s = dv.getInt16(off, true); return normalized ? Math.max(f32(s / 32767), -1) : s; }
  default: return 0;
  }
}

// Attribute accessor a into v (n vertices) at float offset off (read_attribute).
function readAttribute(L, a, what, type, normalizedOk, n, v, off) {
  const r = accessorBytes(L, a, what, n), acc = r.acc;
  const normInt = normalizedOk && acc.normalized === true && (acc.componentType === UBYTE || acc.componentType === USHORT);
  if (acc.type !== type || (acc.componentType !== FLOAT && !normInt))
    L.fail(`${what}: accessor ${a} has the wrong type or component type`);
  if (r.count !== n) L.fail(`${what}: accessor ${a} has ${r.count} elements, POSITION ${n}`);
  const dv = new DataView(r.buffer), nc = COMPONENTS[type], norm = acc.normalized === true;
  for (let i = 0; i < n; i++)
    for (let c = 0; c < nc; c++) {
      const x = component(dv, r.base + i * r.stride + c * r.cb, acc.componentType, norm);
      if (!Number.isFinite(x)) L.fail(`${what}: accessor ${a} element ${i} is not finite`);
      v[i * F + off + c] = x;
    }
}

// Triangle indices of primitive p (or 0..n-1), each < n (read_indices).
function readIndices(L, p, n) {
  if (!given(p.indices)) {
    if (n % 3) L.fail(`a primitive without indices has ${n} vertices (not triangles)`);
    const idx = new Uint32Array(n);
    for (let i = 0; i < n; i++) idx[i] = i;
    return idx;
  }
  const r = accessorBytes(L, p.indices, 'indices', 3 * MAX_TRIANGLES), acc = r.acc, ct = acc.componentType;
  if (acc.type !== 'SCALAR' || (ct !== UBYTE && ct !== USHORT && ct !== UINT))
    L.fail(`indices: accessor ${p.indices} is not unsigned integer scalars`);
  if (r.count % 3) L.fail(`indices: accessor ${p.indices} has ${r.count} indices (not triangles)`);
  const dv = new DataView(r.buffer), idx = new Uint32Array(r.count);
  for (let i = 0; i < r.count; i++) {
    const q = r.base + i * r.stride;
    const k = ct === UBYTE ? dv.getUint8(q) : ct === USHORT ? dv.getUint16(q, true) : dv.getUint32(q, true);
    if (k >= n) L.fail(`indices: index ${k} at ${i} is out of bounds (${n} vertices)`);
    idx[i] = k;
  }
  return idx;
}

// Flat normals: every triangle its own three vertices with the face normal (edges in
// float, as the C code subtracts floats).
function flatNormals(geo) {
  const {v, idx} = geo, out = new Float32Array(idx.length * F);
  for (let t = 0; t + 2 < idx.length; t += 3) {
    const a = idx[t] * F, b = idx[t + 1] * F, c = idx[t + 2] * F;
    const e1 = [f32(v[b] - v[a]), f32(v[b + 1] - v[a + 1]), f32(v[b + 2] - v[a + 2])];
    const e2 = [f32(v[c] - v[a]), f32(v[c + 1] - v[a + 1]), f32(v[c + 2] - v[a + 2])];
    const nn = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
    const l = Math.sqrt(nn[0] * nn[0] + nn[1] * nn[1] + nn[2] * nn[2]);
    for (let k = 0; k < 3; k++) {
      const o = (t + k) * F;
      out.set(v.subarray(idx[t + k] * F, idx[t + k] * F + F), o);
      for (let c2 = 0; c2 < 3; c2++) out[o + 3 + c2] = l > 0 ? nn[c2] / l : (c2 === 2 ? 1 : 0);
    }
  }
  geo.v = out;
  geo.idx = new Uint32Array(idx.length);
  for (let i = 0; i < idx.length; i++) geo.idx[i] = i;
}

// An index field: absent (undefined or a negative integer, as tinygltf's -1) or given.
const given = (x) => x !== undefined && !(Number.isInteger(x) && x < 0);

function attribute(p, key) {
  const at = p.attributes && typeof p.attributes === 'object' ? p.attributes[key] : undefined;
  return given(at) ? at : -1;
}

// Primitive p of mesh mi in object space, checked (load_geometry).
function loadGeometry(L, p, mi) {
  if (!p || typeof p !== 'object') L.fail(`mesh ${mi}: a primitive is not an object`);
  const mode = p.mode ?? 4;
  if (mode !== 4) L.fail(`mesh ${mi}: primitive mode ${mode} (only triangles, mode 4)`);
  if (p.extensions && typeof p.extensions === 'object' && Object.keys(p.extensions).length)
    L.fail(`mesh ${mi}: primitive extension ${Object.keys(p.extensions)[0]} (not supported)`);
  const pos = attribute(p, 'POSITION');
  if (pos === -1) L.fail(`mesh ${mi}: a primitive has no POSITION`);
  if (!Number.isInteger(pos) || pos < 0 || pos >= L.accessors.length)
    L.fail(`mesh ${mi}: POSITION accessor ${pos} does not exist`);
  const n = L.accessors[pos] && L.accessors[pos].count;
  if (!isInt(n) || n === 0 || n > MAX_VERTICES) L.fail(`mesh ${mi}: ${n} vertices (1..${MAX_VERTICES})`);
  accessorBytes(L, pos, 'POSITION', n); // the count is backed by the file before anything is allocated for it
  const geo = {v: new Float32Array(n * F), idx: null, hasUv: false, hasTangent: false};
  readAttribute(L, pos, 'POSITION', 'VEC3', false, n, geo.v, 0);
  const nrm = attribute(p, 'NORMAL'), tan = attribute(p, 'TANGENT'), uv = attribute(p, 'TEXCOORD_0');
  if (nrm !== -1) readAttribute(L, nrm, 'NORMAL', 'VEC3', false, n, geo.v, 3);
  if (tan !== -1 && nrm !== -1) readAttribute(L, tan, 'TANGENT', 'VEC4', false, n, geo.v, 6);
  if (uv !== -1) readAttribute(L, uv, 'TEXCOORD_0', 'VEC2', true, n, geo.v, 10);
  geo.idx = readIndices(L, p, n);
  geo.hasUv = uv !== -1;
  geo.hasTangent = tan !== -1 && nrm !== -1; // without NORMAL, glTF says TANGENT is ignored
  if (nrm === -1) {
    if (L.vertices + geo.idx.length > MAX_VERTICES) // flat normals: a vertex per corner
      L.fail(`more than ${MAX_VERTICES} vertices or ${MAX_TRIANGLES} triangles in the scene`);
    flatNormals(geo);
  }
  const v = geo.v;
  for (let i = 0; i < v.length / F; i++) { // unit normals (a file's may not be)
    const q = i * F + 3, l = Math.sqrt(v[q] * v[q] + v[q + 1] * v[q + 1] + v[q + 2] * v[q + 2]);
    for (let c = 0; c < 3; c++) v[q + c] = l > 0 ? v[q + c] / l : (c === 2 ? 1 : 0);
  }
  return geo;
}

// ------------------------------------------------------------------ transforms

// 4x4 column-major product c = a b (mat_mul).
function matMul(a, b) {
  const c = new Float64Array(16);
  for (let col = 0; col < 4; col++)
    for (let row = 0; row < 4; row++) {
      let s = 0;
      for (let k = 0; k < 4; k++) s += a[k * 4 + row] * b[col * 4 + k];
      c[col * 4 + row] = s;
    }
  return c;
}

function numbers(L, x, n, what, ni) {
  if (x === undefined) return null;
  if (!Array.isArray(x) || !x.every((e) => typeof e === 'number')) L.fail(`node ${ni}: ${what} is not numbers`);
  return x.length === n ? x : null;
}

// A node's local matrix: matrix, else T * R * S (local_matrix).
function localMatrix(L, nd, ni) {
  const m = new Float64Array(16);
  const mat = numbers(L, nd.matrix, 16, 'matrix', ni);
  if (mat) {
    for (let i = 0; i < 16; i++) m[i] = mat[i];
  } else {
    const t = numbers(L, nd.translation, 3, 'translation', ni) || [0, 0, 0];
    const q = numbers(L, nd.rotation, 4, 'rotation', ni) || [0, 0, 0, 1];
    const s = numbers(L, nd.scale, 3, 'scale', ni) || [1, 1, 1];
    const ql = Math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (!(ql > 0)) L.fail(`node ${ni}: zero rotation quaternion`);
    const x = q[0] / ql, y = q[1] / ql, z = q[2] / ql, w = q[3] / ql;
    const r = [1 - 2 * (y * y + z * z), 2 * (x * y + z * w), 2 * (x * z - y * w),
      2 * (x * y - z * w), 1 - 2 * (x * x + z * z), 2 * (y * z + x * w),
      2 * (x * z + y * w), 2 * (y * z - x * w), 1 - 2 * (x * x + y * y)];
    for (let col = 0; col < 3; col++)
      for (let row = 0; row < 3; row++) m[col * 4 + row] = r[col * 3 + row] * s[col];
    m[12] = t[0];
    m[13] = t[1];
    m[14] = t[2];
    m[15] = 1;
  }
  for (let i = 0; i < 16; i++) if (!Number.isFinite(m[i])) L.fail(`node ${ni}: its transform is not finite`);
  return m;
}

// Determinant of m's upper 3x3 and the inverse transpose up to scale (normal_matrix).
function normalMatrix(m) {
  const a = m[0], b = m[4], c = m[8], d = m[1], e = m[5], f = m[9], g = m[2], h = m[6], i = m[10];
  const det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g);
  const co = [e * i - f * h, -(d * i - f * g), d * h - e * g, -(b * i - c * h), a * i - c * g,
    -(a * h - b * g), b * f - c * e, -(a * f - c * d), a * e - b * d];
  const nm = new Float64Array(9);
  for (let row = 0; row < 3; row++)
    for (let col = 0; col < 3; col++) nm[col * 3 + row] = det < 0 ? -co[row * 3 + col] : co[row * 3 + col];
  return {det, nm};
}

// out = tr + M v (xform3: M the 3x3 of a 4x4 when stride4, else a 3x3).
function xform3(m3, v, o, stride4, tr) {
  const out = [0, 0, 0];
  for (let r = 0; r < 3; r++) {
    out[r] = tr ? tr[r] : 0;
    for (let c = 0; c < 3; c++) out[r] += (stride4 ? m3[c * 4 + r] : m3[c * 3 + r]) * v[o + c];
  }
  return out;
}

function unit(v, dst, o, fallback) {
  const l = Math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]), ok = l > 0 && Number.isFinite(l);
  for (let c = 0; c < 3; c++) dst[o + c] = ok ? v[c] / l : fallback[c];
}

const UP = [0, 0, 1], UX = [1, 0, 0];

// One drawn part: geo under world matrix m (add_part).
function addPart(L, geo, p, m) {
  const nv = geo.v.length / F, ni = geo.idx.length;
  if (L.parts.length >= MAX_PARTS) L.fail(`more than ${MAX_PARTS} drawn primitives`);
  if (L.vertices + nv > MAX_VERTICES || L.triangles + ni / 3 > MAX_TRIANGLES)
    L.fail(`more than ${MAX_VERTICES} vertices or ${MAX_TRIANGLES} triangles in the scene`);
  const vertices = new Float32Array(nv * F), indices = new Uint32Array(ni);
  const {det, nm} = normalMatrix(m), tr = [m[12], m[13], m[14]], s = geo.v;
  for (let i = 0; i < nv; i++) {
    const o = i * F;
    const x = xform3(m, s, o, true, tr);
    vertices[o] = x[0];
    vertices[o + 1] = x[1];
    vertices[o + 2] = x[2];
    unit(xform3(nm, s, o + 3, false, null), vertices, o + 3, UP);
    unit(xform3(m, s, o + 6, true, null), vertices, o + 6, UX);
    vertices[o + 9] = (s[o + 9] < 0 ? -1 : 1) * (det < 0 ? -1 : 1);
    vertices[o + 10] = s[o + 10];
    vertices[o + 11] = s[o + 11];
    for (let c = 0; c < F; c++)
      if (!Number.isFinite(vertices[o + c])) L.fail(`a vertex is not finite under its node's transform (${i})`);
  }
  for (let t = 0; t < ni; t += 3) { // a mirroring transform turns the triangles over
    indices[t] = geo.idx[t];
    indices[t + 1] = geo.idx[det < 0 ? t + 2 : t + 1];
    indices[t + 2] = geo.idx[det < 0 ? t + 1 : t + 2];
  }
  const mi = Number.isInteger(p.material) && p.material >= 0 && p.material < L.materials.length ? p.material : -1;
  const part = {material: '', materialIndex: mi, baseColor: [1, 1, 1, 1], hasUv: geo.hasUv,
    tangentsGiven: geo.hasTangent, vertices, indices};
  if (mi >= 0) {
    const mt = L.materials[mi] || {};
    part.material = cName(typeof mt.name === 'string' ? mt.name : '');
    const bc = mt.pbrMetallicRoughness && Array.isArray(mt.pbrMetallicRoughness.baseColorFactor)
      ? mt.pbrMetallicRoughness.baseColorFactor : [];
    for (let c = 0; c < 4 && c < bc.length; c++)
      part.baseColor[c] = typeof bc[c] === 'number' && Number.isFinite(bc[c]) ? f32(Math.min(Math.max(bc[c], 0), 1)) : 1;
  }
  L.parts.push(part);
  L.vertices += nv;
  L.triangles += ni / 3;
}

// A name as the C host keeps it: at most NAME_MAX - 1 bytes of UTF-8.
function cName(s) {
  const b = new TextEncoder().encode(s);
  if (b.length < NAME_MAX) return s;
  let n = NAME_MAX - 1;
  while (n > 0 && (b[n] & 0xc0) === 0x80) n--; // not inside a character
  return new TextDecoder().decode(b.subarray(0, n));
}

// The parts of node ni and its children under parent matrix pm (visit).
function visit(L, ni, pm, depth, geos) {
  if (!Number.isInteger(ni) || ni < 0 || ni >= L.nodes.length) L.fail(`node ${ni} does not exist`);
  if (depth > MAX_DEPTH) L.fail(`the node hierarchy is deeper than ${MAX_DEPTH} (or a cycle)`);
  if (++L.visits > MAX_NODE_VISITS) L.fail(`more than ${MAX_NODE_VISITS} node instances in the scene`);
  const nd = L.nodes[ni];
  if (!nd || typeof nd !== 'object') L.fail(`node ${ni} is not an object`);
  const m = matMul(pm, localMatrix(L, nd, ni));
  if (given(nd.mesh)) {
    if (!Number.isInteger(nd.mesh) || nd.mesh < 0 || nd.mesh >= L.meshes.length)
      L.fail(`node ${ni}: mesh ${nd.mesh} does not exist`);
    const prims = arr(L.meshes[nd.mesh] && L.meshes[nd.mesh].primitives);
    if (!geos.has(nd.mesh)) { // each mesh's geometry once, however many nodes use it
      const gs = prims.map((p) => {
        const geo = loadGeometry(L, p, nd.mesh);
        if (!geo.hasTangent && geo.idx.length) Object.assign(geo, generateTangents(geo.v, geo.idx));
        return geo;
      });
      geos.set(nd.mesh, gs);
    }
    const gs = geos.get(nd.mesh);
    prims.forEach((p, k) => addPart(L, gs[k], p, m));
  }
  for (const c of arr(nd.children)) visit(L, c, m, depth + 1, geos);
}

// The default scene's (or the first scene's) roots; without scenes every node that is
// nobody's child (roots()).
function roots(L) {
  const g = L.g, scenes = arr(g.scenes);
  if (scenes.length) {
    const s = Number.isInteger(g.scene) && g.scene >= 0 && g.scene < scenes.length ? g.scene : 0;
    return arr(scenes[s] && scenes[s].nodes);
  }
  const child = new Uint8Array(L.nodes.length);
  for (const n of L.nodes) for (const c of arr(n && n.children)) if (Number.isInteger(c) && c >= 0 && c < child.length) child[c] = 1;
  const r = [];
  for (let i = 0; i < child.length; i++) if (!child[i]) r.push(i);
  return r;
}

// glTF's +y up becomes the world's +z: x' = x, y' = -z, z' = y (column-major).
const Y_UP = new Float64Array([1, 0, 0, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 0, 0, 1]);

function bake(doc, bufs, name) {
  for (const e of arr(doc.extensionsRequired)) throw new ModelError(`${name}: required extension ${e} is not supported`);
  const L = new Loader(doc, bufs, name);
  const geos = new Map();
  for (const n of roots(L)) visit(L, n, Y_UP, 0, geos);
  if (!L.parts.length) L.fail('the scene draws no triangles');
  const min = [Infinity, Infinity, Infinity], max = [-Infinity, -Infinity, -Infinity];
  for (const p of L.parts)
    for (let v = 0; v < p.vertices.length; v += F)
      for (let c = 0; c < 3; c++) {
        min[c] = Math.min(min[c], p.vertices[v + c]);
        max[c] = Math.max(max[c], p.vertices[v + c]);
      }
  return {name, parts: L.parts, min, max, vertices: L.vertices, triangles: L.triangles};
}

// A model from bytes (a .glb, or a .gltf's JSON text); loadBuffer(uri, i) -> bytes of
// an external buffer (without it, only the .glb chunk and data URIs).
export async function parseModel(bytes, {name = 'model', loadBuffer = null} = {}) {
  if (!(bytes instanceof Uint8Array)) bytes = new Uint8Array(bytes);
  try {
    const {doc, bin} = container(bytes, name);
    return bake(doc, await buffers(doc, bin, name, loadBuffer), name);
  } catch (e) {
    if (e instanceof ModelError) throw new Error(e.message);
    if (e instanceof RangeError && /allocat|length/i.test(e.message)) throw new Error(`${name}: out of memory`);
    throw new Error(`${name}: not a valid glTF: ${e.message}`);
  }
}

// Fetches url's bytes, at most MAX_FILE_BYTES (the announced length checked first).
async function fetchBytes(url, what) {
  let r;
  try {
    r = await fetch(url);
  } catch (e) {
    throw new ModelError(`${what}: cannot load ${url} (${e.message})`);
  }
  if (!r.ok) throw new ModelError(`${what}: cannot load ${url} (HTTP ${r.status})`);
  const len = +r.headers.get('content-length');
  if (len > MAX_FILE_BYTES) throw new ModelError(`${what}: ${url} is larger than ${MAX_FILE_BYTES} bytes`);
  const b = new Uint8Array(await r.arrayBuffer());
  if (b.length > MAX_FILE_BYTES) throw new ModelError(`${what}: ${url} is larger than ${MAX_FILE_BYTES} bytes`);
  return b;
}

// A model by URL (.glb, or .gltf with its buffers: data URIs, or files by URL relative to it).
export async function loadModel(url) {
  const name = String(url).split(/[?#]/)[0].split('/').pop() || 'model';
  let bytes;
  try {
    bytes = await fetchBytes(url, 'model');
  } catch (e) {
    throw new Error(e.message);
  }
  return parseModel(bytes, {name, loadBuffer: (uri) => fetchBytes(new URL(uri, url).href, `${name}: buffer`)});
}

// ------------------------------------------------------------------ tangents

// Handedness w (0 degenerate in uv) and the unit u direction tu of triangle t (btf__face).
function face(v, ix, t, tu) {
  const a = ix[t] * F, b = ix[t + 1] * F, c = ix[t + 2] * F;
  const e1 = [v[b] - v[a], v[b + 1] - v[a + 1], v[b + 2] - v[a + 2]];
  const e2 = [v[c] - v[a], v[c + 1] - v[a + 1], v[c + 2] - v[a + 2]];
  const du1 = v[b + 10] - v[a + 10], dv1 = v[b + 11] - v[a + 11];
  const du2 = v[c + 10] - v[a + 10], dv2 = v[c + 11] - v[a + 11];
  const r = du1 * dv2 - du2 * dv1;
  if (Math.abs(r) < UV_AREA_MIN) return 0;
  let l = 0;
  for (let k = 0; k < 3; k++) {
    tu[t + k] = (e1[k] * dv2 - e2[k] * dv1) / r;
    l += tu[t + k] * tu[t + k];
  }
  l = Math.sqrt(l);
  if (!(l > 0) || !Number.isFinite(l)) return 0;
  for (let k = 0; k < 3; k++) tu[t + k] /= l;
  return r > 0 ? -1 : 1;
}

// Angle at corner k of the triangle at ix[t..t+2] (btf__corner_angle).
function cornerAngle(v, ix, t, k) {
  const p = ix[t + k] * F, q = ix[t + (k + 1) % 3] * F, s = ix[t + (k + 2) % 3] * F;
  let d = 0, la = 0, lb = 0;
  for (let c = 0; c < 3; c++) {
    const a = v[q + c] - v[p + c], b = v[s + c] - v[p + c];
    d += a * b;
    la += a * a;
    lb += b * b;
  }
  if (!(la > 0) || !(lb > 0)) return 0;
  const cs = d / Math.sqrt(la * lb);
  return Math.acos(cs > 1 ? 1 : cs < -1 ? -1 : cs);
}

const F09 = f32(0.9);

// Any unit vector orthogonal to the unit normal at v[o..o+2] (btf__any_tangent).
function anyTangent(v, o, t) {
  const x = Math.abs(v[o]) < F09;
  const a = [x ? 1 : 0, x ? 0 : 1, 0], d = a[0] * v[o] + a[1] * v[o + 1];
  let l = 0;
  for (let k = 0; k < 3; k++) {
    t[k] = a[k] - d * v[o + k];
    l += t[k] * t[k];
  }
  l = Math.sqrt(l);
  for (let k = 0; k < 3; k++) t[k] /= l;
}

// Tangents of an indexed triangle mesh (interleaved vertices, F floats each) by the
// MikkTSpace convention as glTF reads it: a line-by-line port of btf_gltf_tangents
// (shaders/host/btf_gltf_tangent.c), so both hosts make the same ones. Per triangle
// the unit direction of increasing u (and its handedness), projected into each
// corner's tangent plane and summed weighted by the corner's angle over the triangles
// sharing a vertex and a handedness; a vertex whose triangles disagree is split.
// Returns {v, idx}: the vertices (grown by the splits) with tangents, the indices.
export function generateTangents(vertices, indices) {
  const nv = vertices.length / F, ni = indices.length, nt = Math.floor(ni / 3);
  const idx = new Uint32Array(indices);
  const slot = new Int32Array(2 * nv).fill(-1), hand = new Int8Array(nt), tu = new Float64Array(nt * 3);
  let nNew = 0;
  const slotOf = (i, s) => {
    const x = 2 * i + s;
    if (slot[x] < 0) slot[x] = slot[2 * i + (1 - s)] < 0 ? i : nv + nNew++;
    return slot[x];
  };
  for (let t = 0; t < nt; t++) hand[t] = face(vertices, idx, 3 * t, tu);
  for (let pass = 0; pass < 2; pass++)
    for (let t = 0; t < nt; t++) {
      if ((hand[t] === 0) !== (pass === 1)) continue;
      for (let k = 0; k < 3; k++) {
        const i = idx[3 * t + k];
        let s = hand[t] < 0 ? 1 : 0;
        if (hand[t] === 0 && slot[2 * i] < 0 && slot[2 * i + 1] >= 0) s = 1;
        idx[3 * t + k] = slotOf(i, s);
      }
    }
  let v = vertices;
  if (nNew > 0) {
    v = new Float32Array((nv + nNew) * F);
    v.set(vertices);
    for (let i = 0; i < nv; i++)
      for (let s = 0; s < 2; s++)
        if (slot[2 * i + s] >= nv) v.copyWithin(slot[2 * i + s] * F, i * F, i * F + F);
  } else {
    v = new Float32Array(vertices);
  }
  const n = v.length / F, acc = new Float64Array(n * 3), w = new Int8Array(n).fill(1);
  for (let t = 0; t < nt; t++) {
    if (hand[t] === 0) continue;
    for (let k = 0; k < 3; k++) {
      const i = idx[3 * t + k], o = i * F + 3, d = 3 * t;
      const dn = tu[d] * v[o] + tu[d + 1] * v[o + 1] + tu[d + 2] * v[o + 2];
      const p = [0, 0, 0];
      let l = 0;
      for (let c = 0; c < 3; c++) {
        p[c] = tu[d + c] - dn * v[o + c];
        l += p[c] * p[c];
      }
      if (!(l > 1e-24)) continue;
      const a = cornerAngle(v, idx, 3 * t, k) / Math.sqrt(l);
      for (let c = 0; c < 3; c++) acc[3 * i + c] += a * p[c];
      w[i] = hand[t];
    }
  }
  const a = [0, 0, 0];
  for (let i = 0; i < n; i++) {
    const q = i * F;
    for (let c = 0; c < 3; c++) a[c] = acc[3 * i + c];
    const dn = a[0] * v[q + 3] + a[1] * v[q + 4] + a[2] * v[q + 5];
    let l = 0;
    for (let c = 0; c < 3; c++) {
      a[c] -= dn * v[q + 3 + c];
      l += a[c] * a[c];
    }
    if (l > 1e-24) for (let c = 0; c < 3; c++) a[c] /= Math.sqrt(l);
    else anyTangent(v, q + 3, a);
    for (let c = 0; c < 3; c++) v[q + 6 + c] = a[c];
    v[q + 9] = w[i];
  }
  return {v, idx};
}

// ------------------------------------------------------------------ bindings

export const MAX_BINDINGS = 64; // BTF_SCENE_MAX_BINDINGS

// The `materials` attribute: comma-separated NAME:ID[:REPEAT] (NAME a glTF material
// name, '*' for every part no other binding names; ID a library material; REPEAT
// package repeats per unit of TEXCOORD_0, default 1). A name may hold ':' (the last one
// or two fields are ID and REPEAT); ',' and '%' in a name are written %2C and %25.
// Returns [{name, id, repeat}]; throws on a malformed entry.
export function parseBindings(text) {
  const out = [];
  for (const raw of String(text ?? '').split(',')) {
    const e = raw.trim();
    if (!e) continue;
    const f = e.split(':');
    let repeat = 1;
    if (f.length >= 3 && /^\s*[-+0-9.eE]+\s*$/.test(f[f.length - 1])) {
      repeat = Number(f.pop());
      if (!(repeat > 0 && repeat <= 1e4)) throw new Error(`materials: "${e}": repeat outside (0, 1e4]`);
    }
    if (f.length < 2) throw new Error(`materials: "${e}" is not NAME:MATERIAL[:REPEAT]`);
    const id = f.pop().trim();
    let name = f.join(':').trim();
    try {
      name = decodeURIComponent(name);
    } catch (_) { /* a literal % */ }
    if (!name || !id) throw new Error(`materials: "${e}" is not NAME:MATERIAL[:REPEAT]`);
    if (out.some((b) => b.name === name)) throw new Error(`materials: "${name}" is bound twice`);
    out.push({name, id, repeat});
  }
  if (out.length > MAX_BINDINGS) throw new Error(`materials: ${out.length} bindings (at most ${MAX_BINDINGS})`);
  return out;
}

// Which binding (index) each part takes, or -1 (btf_scene_bind): the one naming its
// material, else '*', else none. A binding naming no material of the model, or a bound
// part without TEXCOORD_0, is an error.
export function bindParts(model, bindings) {
  const any = bindings.findIndex((b) => b.name === '*');
  const out = model.parts.map((p, i) => {
    let j = bindings.findIndex((b) => b.name === p.material);
    if (j < 0) j = any;
    if (j >= 0 && !p.hasUv)
      throw new Error(`${model.name}: part ${i} (material "${p.material}") has no TEXCOORD_0: a BTF needs texture coordinates`);
    return j;
  });
  bindings.forEach((b, j) => {
    if (j !== any && !model.parts.some((p) => p.material === b.name))
      throw new Error(`${model.name}: the model has no material named "${b.name}"`);
  });
  return out;
}
