// btf-dirtab.js - a direction set as triangles plus a lookup table, the JS twin
// of codec/btf_dirtab.c (ring sets: the ring algorithm's triangles; list sets: the
// manifest's triangles over the directions and their mirror images, checked as the
// C reader checks them) (doc/data-model.md, "Direction tables"), and their GPU layout
// for shaders/btf_dirs.glsl (the C host's shaders/host/btf_gl_dirs.c). Float32
// arithmetic (Math.fround) where the C code uses float, so both make the same
// triangles. No DOM, no GL: usable in node.

const f32 = Math.fround;
const TIE = f32(1e-3); // aligned "next" vertices go inner first
export const CELLS = 64;
export const MAX_VERTS = 1024; // BTF_GL_MAX_VERTS: vertices of both sets together
const TRI_W = 1024;

// det(p, a, b) = p . ((a - p) x (b - p)), in float32 like btf__det3.
function det3(p, a, b) {
  const u0 = f32(a[0] - p[0]), u1 = f32(a[1] - p[1]), u2 = f32(a[2] - p[2]);
  const v0 = f32(b[0] - p[0]), v1 = f32(b[1] - p[1]), v2 = f32(b[2] - p[2]);
  const cx = f32(f32(u1 * v2) - f32(u2 * v1));
  const cy = f32(f32(u2 * v0) - f32(u0 * v2));
  const cz = f32(f32(u0 * v1) - f32(u1 * v0));
  return f32(f32(f32(p[0] * cx) + f32(p[1] * cy)) + f32(p[2] * cz));
}

// Unit vector of direction m of ring r of a parsed ring table (btf-package.js
// parseDirset), as btf_dirset_vector: phi in float32, the trigonometry in double.
function dirVector(d, r, m) {
  const theta = d.rings[4 * r], count = d.rings[4 * r + 1], off = d.rings[4 * r + 2];
  let phi = f32(off + f32(m * f32(360 / count)));
  if (phi >= 360) phi = f32(phi - 360);
  const t = theta * (Math.PI / 180), p = phi * (Math.PI / 180);
  return [f32(Math.sin(t) * Math.cos(p)), f32(Math.sin(t) * Math.sin(p)), f32(Math.cos(t))];
}

// Unit vectors (local frame, float32 as btf_dirset_vector) of every direction of a parsed
// set, in the set's order: [[x, y, z], ...].
export function dirVectors(d) {
  if (d.list) return Array.from({length: d.dirs}, (_, i) => listVector(d, i));
  const out = [];
  for (let r = 0; r < d.n; r++)
    for (let m = 0; m < d.rings[4 * r + 1]; m++) out.push(dirVector(d, r, m));
  return out;
}

// Builds the table of a parsed direction set (btf-package.js parseDirset):
// {nDirs, nVerts, verts: [[x, y, z, real]], dir: [direction of each vertex, -1 virtual],
//  tris: [[a, b, c]], adj: [[n0, n1, n2]], cells: Int32Array}. Throws on bad list triangles.
export function buildDirtab(d) {
  if (d.list) return buildListDirtab(d);
  const nDirs = d.dirs, verts = [];
  for (let r = 0; r < d.n; r++)
    for (let m = 0; m < d.rings[4 * r + 1]; m++) verts.push([...dirVector(d, r, m), 1]);
  verts.push([0, 0, 1, 0], [0, 0, -1, 0]); // virtual north and south poles
  const tris = [];
  const add = (a, b, c) => {
    if (a === b || b === c || a === c) return;
    if (det3(verts[a], verts[b], verts[c]) < 0) [b, c] = [c, b]; // counter-clockwise from outside
    tris.push([a, b, c]);
  };
  const count = (r) => d.rings[4 * r + 1], start = (r) => d.rings[4 * r + 3];
  const vertex = (r, k) => {
    const n = count(r), m = k % n;
    return start(r) + (m < 0 ? m + n : m);
  };
  const ringPhi = (r, k) => count(r) === 1 ? 1e9 : f32(d.rings[4 * r + 2] + f32(k * f32(360 / count(r))));
  const fan = (r, pole) => {
    for (let k = 0; k < count(r) && count(r) > 1; k++) add(vertex(r, k), vertex(r, k + 1), pole);
  };
  if (count(0) > 1) fan(0, nDirs);
  for (let lo = 0; lo + 1 < d.n; lo++) { // the zipper between ring lo and lo + 1
    let ki = Math.floor(f32(f32(0 - d.rings[4 * lo + 2]) / f32(360 / count(lo))));
    let ko = Math.floor(f32(f32(0 - d.rings[4 * lo + 6]) / f32(360 / count(lo + 1))));
    const steps = (count(lo) === 1 ? 0 : count(lo)) + (count(lo + 1) === 1 ? 0 : count(lo + 1));
    for (let s = 0; s < steps; s++) {
      const inner = f32(ringPhi(lo, ki + 1) - ringPhi(lo + 1, ko + 1)) <= TIE;
      const x = inner ? vertex(lo, ki + 1) : vertex(lo + 1, ko + 1);
      add(vertex(lo, ki), vertex(lo + 1, ko), x);
      if (inner) ki++;
      else ko++;
    }
  }
  fan(d.n - 1, nDirs + 1);
  const dir = verts.map((v, i) => (i < nDirs ? i : -1));
  const tab = {nDirs, nVerts: nDirs + 2, verts, dir, tris, adj: adjacency(tris), cells: new Int32Array(CELLS * CELLS)};
  if (tris.length) fillCells(tab);
  return tab;
}

// Neighbour across each edge: the triangle holding the reversed edge (-1 none).
function adjacency(tris) {
  const edge = new Map();
  tris.forEach((t, i) => t.forEach((_, e) => edge.set(`${t[(e + 1) % 3]},${t[(e + 2) % 3]}`, i)));
  return tris.map((t) => t.map((_, e) => {
    const n = edge.get(`${t[(e + 2) % 3]},${t[(e + 1) % 3]}`);
    return n === undefined ? -1 : n;
  }));
}

// Unit vector of list entry i (i >= n: the mirror image of i - n), as btf__list_vertex.
function listVector(d, i) {
  const k = i % d.dirs, t = d.list[2 * k] * (Math.PI / 180), p = d.list[2 * k + 1] * (Math.PI / 180);
  const v = [f32(Math.sin(t) * Math.cos(p)), f32(Math.sin(t) * Math.sin(p)), f32(Math.cos(t))];
  if (i >= d.dirs) v[2] = -v[2];
  return v;
}

const MIRROR_MIN_Z = f32(1e-6), CONVEX_EPS = 1e-5;

// The table of a list set from its triangles (btf_dirtab_build_list): vertices are the
// directions, then the mirror images in the order the triangles first use them.
function buildListDirtab(d) {
  const n = d.dirs, nt = d.tris.length / 3, map = new Int32Array(2 * n).fill(-1);
  const bad = (msg) => { throw new Error(`direction list: ${msg}`); };
  for (let i = 0; i < n; i++) map[i] = i;
  let nv = n;
  for (let i = 0; i < nt; i++) {
    let real = 0;
    for (let k = 0; k < 3; k++) {
      const x = d.tris[3 * i + k];
      if (x >= n && !(listVector(d, x)[2] < -MIRROR_MIN_Z)) bad(`triangle ${i} mirrors direction ${x - n}, on the horizon`);
      if (map[x] < 0) map[x] = nv++;
      real += x < n;
    }
    if (!real) bad(`triangle ${i} holds no measured direction`);
  }
  const verts = new Array(nv), dir = new Array(nv);
  for (let i = 0; i < 2 * n; i++)
    if (map[i] >= 0) {
      verts[map[i]] = [...listVector(d, i), 1];
      dir[map[i]] = i % n;
    }
  const tris = [];
  for (let i = 0; i < nt; i++) tris.push([0, 1, 2].map((k) => map[d.tris[3 * i + k]]));
  const tab = {nDirs: n, nVerts: nv, verts, dir, tris, adj: [], cells: new Int32Array(CELLS * CELLS)};
  checkListShape(tab, bad);
  tab.adj = adjacency(tris);
  tab.adj.forEach((a, i) => a.forEach((x, e) => {
    const u = tris[i][(e + 1) % 3], v = tris[i][(e + 2) % 3];
    if (x < 0 && (u < n || v < n)) bad(`triangle ${i}'s edge ${u}-${v} has no neighbour: the hemisphere is not covered`);
  }));
  fillCells(tab);
  const w = [0, 0, 0];
  for (let c = 0; c < CELLS * CELLS; c++)
    if (w[volumes(tab, tab.cells[c], cellCentre(c % CELLS, Math.floor(c / CELLS)), w)] < -1e-6)
      bad('the triangles do not cover the upper hemisphere');
  return tab;
}

// Orientation, convexity and each directed edge once (btf__list_shape_ok).
function checkListShape(t, bad) {
  const edges = new Set();
  t.tris.forEach((tr, i) => {
    const [a, b, c] = tr.map((v) => t.verts[v]);
    if (!(det3(a, b, c) > 0)) bad(`triangle ${i} is flat or clockwise seen from outside`);
    const u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]], w = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    const nx = u[1] * w[2] - u[2] * w[1], ny = u[2] * w[0] - u[0] * w[2], nz = u[0] * w[1] - u[1] * w[0];
    const len = Math.sqrt(nx * nx + ny * ny + nz * nz);
    for (let v = 0; v < t.nVerts; v++) {
      const p = t.verts[v];
      if (nx * (p[0] - a[0]) + ny * (p[1] - a[1]) + nz * (p[2] - a[2]) > CONVEX_EPS * len)
        bad(`triangle ${i} is not on the convex hull (vertex ${v} outside)`);
    }
    for (let e = 0; e < 3; e++) {
      const key = `${tr[e]},${tr[(e + 1) % 3]}`;
      if (edges.has(key)) bad(`triangle ${i} repeats an edge`);
      edges.add(key);
    }
  });
}

// Barycentric volumes of p in triangle i; returns the index of the smallest.
function volumes(t, i, p, w) {
  const [x, y, z] = t.tris[i].map((v) => t.verts[v]);
  w[0] = det3(p, y, z);
  w[1] = det3(p, z, x);
  w[2] = det3(p, x, y);
  return w[0] <= w[1] && w[0] <= w[2] ? 0 : w[1] <= w[2] ? 1 : 2;
}

function walk(t, i, p, steps, w) {
  for (let s = 0; ; s++) {
    const k = volumes(t, i, p, w);
    if (w[k] >= 0 || s >= steps || t.adj[i][k] < 0) return i;
    i = t.adj[i][k];
  }
}

// Unit direction at the centre of cell (i, j) of the octahedral map (btf__cell_centre).
function cellCentre(i, j) {
  const u = f32(f32(f32(i + 0.5) / CELLS) * 2 - 1), v = f32(f32(f32(j + 0.5) / CELLS) * 2 - 1);
  const a = f32(0.5 * f32(u + v)), b = f32(0.5 * f32(u - v)), z = f32(1 - Math.max(Math.abs(u), Math.abs(v)));
  const n = f32(Math.sqrt(f32(f32(f32(a * a) + f32(b * b)) + f32(z * z))));
  return [f32(a / n), f32(b / n), f32(z / n)];
}

function fillCells(t) {
  let prev = 0;
  const w = [0, 0, 0];
  for (let j = 0; j < CELLS; j++)
    for (let i = 0; i < CELLS; i++) {
      const p = cellCentre(i, j);
      let c = walk(t, prev, p, 4 * CELLS, w), k = volumes(t, c, p, w);
      for (let s = 0; s < t.tris.length && w[k] < 0; s++)
        if (w[k = volumes(t, s, p, w)] >= 0) c = s;
      t.cells[j * CELLS + i] = prev = c;
    }
}

// GPU arrays of both tables (btf_gl_dirs_upload): the uniform block (Float32Array of
// MAX_VERTS vec4), cells (Uint32Array, CELLS x 2 CELLS RGBA32UI), triangles
// (Uint32Array, TRI_W x rows RGBA32UI); viewBlock (Int32Array) into bits 12.. of the
// view vertices' w.
export function dirtabGpu(lights, views, viewBlock) {
  const nv = lights.nVerts + views.nVerts, nt = lights.tris.length + views.tris.length;
  if (nv > MAX_VERTS || nt >= 0xffff)
    throw new Error(`${lights.nDirs} + ${views.nDirs} directions: the GPU tables hold at most ${MAX_VERTS - 4}`);
  const rows = Math.max(1, Math.ceil(nt / TRI_W));
  const ubo = new Float32Array(4 * MAX_VERTS), cells = new Uint32Array(4 * CELLS * CELLS * 2);
  const tris = new Uint32Array(4 * TRI_W * rows);
  const vbase = [0, lights.nVerts], tbase = [0, lights.tris.length];
  const texel = (t, s, i, out, o) => {
    const tr = t.tris[i], n = t.adj[i].map((x) => (x < 0 ? 0xffff : x + tbase[s]));
    out[o] = ((tr[0] + vbase[s]) | ((tr[1] + vbase[s]) << 16)) >>> 0;
    out[o + 1] = tr[2] + vbase[s];
    out[o + 2] = (n[0] | (n[1] << 16)) >>> 0;
    out[o + 3] = n[2];
  };
  [lights, views].forEach((t, s) => {
    t.verts.forEach((v, i) => {
      const o = 4 * (vbase[s] + i), d = v[3] > 0 ? t.dir[i] : -1;
      ubo.set(v.slice(0, 3), o);
      ubo[o + 3] = d >= 0 ? d + 1 + 4096 * (s === 1 && viewBlock ? viewBlock[d] : 0) : 0;
    });
    t.tris.forEach((_, i) => texel(t, s, i, tris, 4 * (tbase[s] + i)));
    if (t.tris.length) for (let c = 0; c < CELLS * CELLS; c++) texel(t, s, t.cells[c], cells, 4 * (s * CELLS * CELLS + c));
  });
  return {ubo, cells, tris, rows, triWidth: TRI_W};
}

// Interpolation of a direction vector (local frame, any length): the JS twin of
// btf_dirtab_interp_vec -> {idx: [3], w: [3]} (weights sum to 1).
export function dirtabInterp(t, v) {
  const r = {idx: [0, 0, 0], w: [1, 0, 0]};
  if (!t.tris.length) return r;
  const m = Math.max(Math.abs(v[0]), Math.abs(v[1]), Math.abs(v[2]));
  let p = [0, 0, 1];
  if (v.every(Number.isFinite) && m > 0) {
    let x = f32(v[0] / m), y = f32(v[1] / m), z = Math.max(f32(v[2] / m), 0);
    if (x === 0 && y === 0 && z === 0) x = 1;
    const n = f32(Math.sqrt(f32(f32(f32(x * x) + f32(y * y)) + f32(z * z))));
    p = [f32(x / n), f32(y / n), f32(z / n)];
  }
  const s = Math.abs(p[0]) + Math.abs(p[1]) + p[2], a = p[0] / s, b = p[1] / s;
  const ci = Math.min(CELLS - 1, Math.max(0, Math.floor((a + b + 1) * 0.5 * CELLS)));
  const cj = Math.min(CELLS - 1, Math.max(0, Math.floor((a - b + 1) * 0.5 * CELLS)));
  const w = [0, 0, 0], i = walk(t, t.cells[cj * CELLS + ci], p, 8, w), tri = t.tris[i];
  let sum = 0, first = -1;
  for (let k = 0; k < 3; k++) {
    w[k] = Math.max(w[k], 0) * t.verts[tri[k]][3];
    sum += w[k];
    if (first < 0 && t.verts[tri[k]][3] > 0) first = tri[k];
  }
  for (let k = 0; k < 3; k++) {
    r.idx[k] = t.dir[t.verts[tri[k]][3] > 0 ? tri[k] : first];
    r.w[k] = sum > 1e-30 ? w[k] / sum : 0;
  }
  if (!(sum > 1e-30)) {
    r.idx[0] = t.dir[first];
    r.w = [1, 0, 0];
  }
  return r;
}
