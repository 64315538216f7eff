// btf-gl.js - WebGL2 side of the viewer: shader files from shaders/ assembled exactly
// as shaders/host/btf_shader.c does (shaders/README.md), compile/link errors reported
// twgl-style against the numbered source, and the package's GPU layout (the same as
// shaders/host/btf_gl_package.c, shaders/README.md "GPU layout"), uploaded one chunk
// at a time; version-2 packages as mip levels of per-component slots.

import {buildDirtab, dirtabGpu, dirVectors, CELLS} from './btf-dirtab.js';
import {reconstructLevel} from './btf-package.js';
import {envWeights, lightCells} from './btf-env.js';

const manifests = new Map(); // shaders base URL -> Promise of {manifest, files: Map}

function fetchText(url) {
  return fetch(url, {cache: 'no-cache'}).then((r) => {
    if (!r.ok) throw new Error(`shader: cannot load ${url} (HTTP ${r.status})`);
    return r.text();
  });
}

function plainName(f) {
  return typeof f === 'string' && /^[A-Za-z0-9_.-]+$/.test(f) && f[0] !== '.' && f.length < 64;
}

// shaders/manifest.json and every file it names (or, given `program`, only the files
// of that program), fetched once per base URL and program. A failed load is forgotten,
// so the next call tries again.
export function loadShaders(base, program = null) {
  const key = `${base}|${program || ''}`;
  if (!manifests.has(key)) {
    const p = fetchText(new URL('manifest.json', base)).then(async (text) => {
      const manifest = JSON.parse(text);
      if (!Array.isArray(manifest.prefix) || !manifest.prefix.length || typeof manifest.programs !== 'object')
        throw new Error('shader: manifest.json lacks "prefix" or "programs"');
      if (program && !manifest.programs[program]) throw new Error(`shader: program '${program}' not in manifest.json`);
      const names = new Set();
      for (const [name, prog] of Object.entries(manifest.programs))
        if (!program || name === program)
          for (const stage of ['vertex', 'fragment'])
            for (const f of prog[stage] || []) names.add(f);
      const files = new Map();
      await Promise.all([...names].map(async (f) => {
        if (!plainName(f)) throw new Error(`shader: manifest.json names '${f}', not a plain file name`);
        files.set(f, await fetchText(new URL(f, base)));
      }));
      return {manifest, files};
    });
    p.catch(() => manifests.delete(key));
    manifests.set(key, p);
  }
  return manifests.get(key);
}

// One stage's source: prefix lines, defines, then "// ---- FILE" + text per file.
// Returns {text, pieces: [{file, firstLine, nLines}]} (lines 1-based).
export function assemble(shaders, program, stage, defines = []) {
  const {manifest, files} = shaders;
  const prog = manifest.programs[program];
  if (!prog) throw new Error(`shader: program '${program}' not in manifest.json`);
  const list = prog[stage];
  if (!Array.isArray(list) || !list.length) throw new Error(`shader: program '${program}' has no ${stage} file list`);
  let text = '';
  for (const line of manifest.prefix) {
    if (typeof line !== 'string' || line.includes('\n'))
      throw new Error('shader: manifest.json prefix entries must be one-line strings');
    text += line + '\n';
  }
  for (const [name, value] of defines) {
    if (!/^[A-Za-z_][A-Za-z0-9_]*$/.test(name) || /[\r\n]/.test(String(value ?? '')))
      throw new Error(`shader: invalid define '${name}'`);
    const v = value === undefined || value === null ? '' : String(value);
    text += `#define ${name}${v ? ' ' + v : ''}\n`;
  }
  const pieces = [];
  const lines = (s) => (s.match(/\n/g) || []).length;
  for (const f of list) {
    const body = files.get(f);
    if (body === undefined) throw new Error(`shader: ${f} was not loaded`);
    text += `// ---- ${f}\n`;
    const firstLine = lines(text) + 1;
    text += body;
    if (!body.endsWith('\n')) text += '\n';
    pieces.push({file: f, firstLine, nLines: lines(body) + (body.length && !body.endsWith('\n') ? 1 : 0)});
  }
  return {text, pieces};
}

// Line number named by a compiler log line: ANGLE "ERROR: 0:12: ...", Mesa "0:12(3): ...",
// NVIDIA "0(12) : ...". 0 when none.
export function logLine(l) {
  const s = l.trim().replace(/^(ERROR|WARNING): /, '');
  let m = /^\d+:(\d+)/.exec(s);
  if (m && +m[1] > 0) return +m[1];
  m = /^\d+\((\d+)\)/.exec(s);
  return m && +m[1] > 0 ? +m[1] : 0;
}

// Assembled line -> [file, line in file] (file null for prefix/define/marker lines).
export function sourceLine(src, line) {
  for (const p of src.pieces)
    if (line >= p.firstLine && line < p.firstLine + p.nLines) return [p.file, line - p.firstLine + 1];
  return [null, line];
}

// Numbered listing with each log message under the line it names (twgl style).
export function annotate(src, log) {
  const msgs = log.split('\n').filter((l) => l.trim());
  const out = msgs.filter((l) => logLine(l) === 0);
  src.text.split('\n').forEach((l, i) => {
    if (i === src.text.split('\n').length - 1 && l === '') return;
    out.push(`${String(i + 1).padStart(4)}: ${l}`);
    for (const m of msgs) if (logLine(m) === i + 1) out.push(`      ^^^ ${m}`);
  });
  return out.join('\n');
}

function compileStage(gl, stageName, src) {
  const sh = gl.createShader(stageName === 'vertex' ? gl.VERTEX_SHADER : gl.FRAGMENT_SHADER);
  gl.shaderSource(sh, src.text);
  gl.compileShader(sh);
  return sh;
}

function stageError(gl, program, stageName, sh, src) {
  const log = gl.getShaderInfoLog(sh) || '';
  const first = (log.split('\n').find((l) => l.trim()) || 'unknown error').trim();
  const [file, fl] = sourceLine(src, logLine(first));
  const err = new Error(`shader '${program}' ${stageName}: ${first}${file ? ` (${file} line ${fl})` : ''}`);
  err.report = annotate(src, log);
  return err;
}

// Starts compiling and linking a program of the manifest without waiting for the driver:
// with KHR_parallel_shader_compile the work runs beside the page until programReady says
// so; finishProgram then checks it (and waits, where the extension is missing).
export function startProgram(gl, shaders, program, defines = []) {
  const srcs = {vertex: assemble(shaders, program, 'vertex', defines),
    fragment: assemble(shaders, program, 'fragment', defines)};
  const vs = compileStage(gl, 'vertex', srcs.vertex), fs = compileStage(gl, 'fragment', srcs.fragment);
  const p = gl.createProgram();
  gl.attachShader(p, vs);
  gl.attachShader(p, fs);
  gl.linkProgram(p);
  return {gl, name: program, program: p, vs, fs, srcs, ext: gl.getExtension('KHR_parallel_shader_compile')};
}

// 1 when finishProgram(pending) will not block (always, without the extension: it blocks there).
export function programReady(pending) {
  return !pending.ext || pending.gl.isContextLost() ||
    pending.gl.getProgramParameter(pending.program, pending.ext.COMPLETION_STATUS_KHR);
}

// The linked program of startProgram: {program, name, uniforms, loc(name)}; throws an
// Error with .report (the annotated listing) when a stage does not compile or link.
export function finishProgram(pending) {
  const {gl, name, program: p, vs, fs, srcs} = pending;
  const lost = gl.isContextLost();
  try {
    if (!lost && !gl.getProgramParameter(p, gl.LINK_STATUS)) {
      for (const [stage, sh] of [['vertex', vs], ['fragment', fs]])
        if (!gl.getShaderParameter(sh, gl.COMPILE_STATUS)) throw stageError(gl, name, stage, sh, srcs[stage]);
      const log = gl.getProgramInfoLog(p) || '';
      const err = new Error(`shader '${name}': link failed: ${(log.split('\n')[0] || '').trim()}`);
      err.report = log;
      throw err;
    }
  } catch (e) {
    gl.deleteProgram(p);
    throw e;
  } finally {
    gl.deleteShader(vs);
    gl.deleteShader(fs);
  }
  const uniforms = new Map();
  const n = gl.getProgramParameter(p, gl.ACTIVE_UNIFORMS) || 0;
  for (let i = 0; i < n; i++) {
    const info = gl.getActiveUniform(p, i);
    const uname = info.name.replace(/\[0\]$/, '');
    uniforms.set(uname, gl.getUniformLocation(p, info.name));
  }
  return {program: p, name, uniforms, loc: (u) => uniforms.get(u) ?? null};
}

// Builds a program from the manifest at once; throws Error with .report (annotated listing).
export function buildProgram(gl, shaders, program, defines = []) {
  return finishProgram(startProgram(gl, shaders, program, defines));
}

// ---------------------------------------------------------------- package textures

function nearest(gl, target) {
  gl.texParameteri(target, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
  gl.texParameteri(target, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
  gl.texParameteri(target, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
  gl.texParameteri(target, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
}

const f32 = Math.fround;
const WQMAX = [2047, 2047, 1023], WSHIFT = [0, 11, 22];
const ENV_MID = [1024, 1024, 512]; // the zero of u_btf_env_w's signed codes
// Rounding to nearest, ties to even (C's lrint).
const rint = (x) => {
  const r = Math.round(x);
  return r - x === 0.5 && r % 2 !== 0 ? r - 1 : r;
};

// Decoder program variants (shaders/btf_decode.glsl, "Host specialisation"): the
// defines for a package drawn with `filter` and `slots` slots in use, as
// btf_gl_package_defines does; `lights` ({point, env}, shaders/btf_light.glsl) adds
// BTF_POINT and BTF_ENV, so a frame compiles only the light terms it uses.
export function decodeDefines(pkg, filter, slots, lights = null) {
  const d = [['BTF_FILTER', filter === 1 ? 1 : 0], ['BTF_LEVELS', pkg.version >= 2 && pkg.levels > 1 ? 1 : 0],
             ['BTF_QUADS', Math.max(1, Math.ceil(slots / 4))]];
  if (lights) d.push(['BTF_POINT', lights.point ? 1 : 0], ['BTF_ENV', lights.env ? 1 : 0]);
  return d;
}

// The light cells (btf-env.js lightCells) of a parsed light set, made once per set.
const cellsOf = new WeakMap();
function envCells(lights) {
  if (!cellsOf.has(lights)) cellsOf.set(lights, lightCells(dirVectors(lights)));
  return cellsOf.get(lights);
}

// The GPU side of a package in WebGL2 (GpuPackage writes its layout through it): the
// direction block (a uniform buffer), the two table textures and the three layered
// integer textures. Another store with the same methods keeps the layout elsewhere
// (client/three/btf-material.js: three.js textures); GpuPackage takes either.
export class GlStore {
  constructor(gl) {
    this.gl = gl;
    this.ubo = this.cells = this.tris = this.tex = this.wt = this.envW = null;
  }

  // The direction tables (btf-dirtab.js dirtabGpu): the block's Float32Array, and the
  // RGBA32UI tables {width, height, data} of u_btf_dir_cells and u_btf_dir_tris.
  dirs(ubo, cells, tris) {
    const gl = this.gl;
    this.ubo = gl.createBuffer();
    gl.bindBuffer(gl.UNIFORM_BUFFER, this.ubo);
    gl.bufferData(gl.UNIFORM_BUFFER, ubo, gl.STATIC_DRAW);
    gl.bindBuffer(gl.UNIFORM_BUFFER, null);
    this.cells = this.intTexture(cells);
    this.tris = this.intTexture(tris);
  }

  intTexture({width, height, data}) {
    const gl = this.gl, t = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, t);
    nearest(gl, gl.TEXTURE_2D);
    gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA32UI, width, height);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
    gl.texSubImage2D(gl.TEXTURE_2D, 0, 0, 0, width, height, gl.RGBA_INTEGER, gl.UNSIGNED_INT, data);
    return t;
  }

  // New layered textures for `layers` layers of 4 slots (the old ones are dropped; the
  // package puts every layer again): u_btf_tex (allocateTex), u_btf_wt RGBA32UI lights x
  // views, u_btf_env_w RGBA32UI 9 x views.
  allocate({levels, paired, width, height, lights, views, layers}) {
    const gl = this.gl, wt = gl.createTexture(), envW = gl.createTexture();
    this.allocateTex({levels, paired, width, height, layers});
    gl.bindTexture(gl.TEXTURE_2D_ARRAY, wt);
    nearest(gl, gl.TEXTURE_2D_ARRAY);
    gl.texStorage3D(gl.TEXTURE_2D_ARRAY, 1, gl.RGBA32UI, lights, views, layers);
    gl.bindTexture(gl.TEXTURE_2D_ARRAY, envW);
    nearest(gl, gl.TEXTURE_2D_ARRAY);
    gl.texStorage3D(gl.TEXTURE_2D_ARRAY, 1, gl.RGBA32UI, 9, views, layers);
    for (const t of [this.wt, this.envW]) if (t) gl.deleteTexture(t);
    this.wt = wt;
    this.envW = envW;
  }

  // A new u_btf_tex alone (the old one is dropped; the package puts its layers again):
  // RGBA16UI atlas x levels, or paired RGBA32UI (each level's texel with the next coarser
  // level's beside it).
  allocateTex({levels, paired, width, height, layers}) {
    const gl = this.gl, tex = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D_ARRAY, tex);
    nearest(gl, gl.TEXTURE_2D_ARRAY);
    if (levels > 1) {
      gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MIN_FILTER, gl.NEAREST_MIPMAP_NEAREST);
      gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MAX_LEVEL, levels - 1);
    }
    gl.texStorage3D(gl.TEXTURE_2D_ARRAY, levels, paired ? gl.RGBA32UI : gl.RGBA16UI, width, height, layers);
    this.texType = paired ? gl.UNSIGNED_INT : gl.UNSIGNED_SHORT;
    if (this.tex) gl.deleteTexture(this.tex);
    this.tex = tex;
  }

  // Layer h (at mip level l, width x height texels) of u_btf_tex, u_btf_wt, u_btf_env_w.
  putTex(h, l, width, height, data) {
    this.put(this.tex, l, h, width, height, this.texType, data);
  }

  putWt(h, width, height, data) {
    this.put(this.wt, 0, h, width, height, this.gl.UNSIGNED_INT, data);
  }

  putEnv(h, width, height, data) {
    this.put(this.envW, 0, h, width, height, this.gl.UNSIGNED_INT, data);
  }

  put(t, l, h, width, height, type, data) {
    const gl = this.gl;
    gl.bindTexture(gl.TEXTURE_2D_ARRAY, t);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
    gl.texSubImage3D(gl.TEXTURE_2D_ARRAY, l, 0, 0, h, width, height, 1, gl.RGBA_INTEGER, type, data);
  }

  free() {
    const gl = this.gl;
    for (const t of [this.tex, this.wt, this.envW, this.cells, this.tris]) if (t) gl.deleteTexture(t);
    if (this.ubo) gl.deleteBuffer(this.ubo);
    this.tex = this.wt = this.envW = this.cells = this.tris = this.ubo = null;
  }
}

// The paired texels of a level (shaders/README.md, "GPU layout"; the C host's
// btf__pair_levels): the level's RGBA values q (aw x ah texels) in bits 0..15, those of
// texel (x/2, y/2) of next, the next coarser level (aw/2 wide; null at the top: 0), in
// bits 16..31.
export function pairLevel(q, next, aw, ah) {
  const out = new Uint32Array(q.length);
  for (let y = 0; y < ah; y++)
    for (let x = 0; x < aw; x++) {
      const i = 4 * (y * aw + x), k = 4 * ((y >> 1) * (aw >> 1) + (x >> 1));
      for (let c = 0; c < 4; c++) out[i + c] = q[i + c] + (next ? next[k + c] * 65536 : 0);
    }
  return out;
}

// A package's GPU layout (shaders/README.md, "GPU layout"; the C host's
// shaders/host/btf_gl_package.c): u_btf_tex RGBA16UI layers of 4 slots at 16 bits on
// one grid per component, N mip levels (paired, N > 1 drawn with nearest taps: RGBA32UI,
// each texel's value in the low 16 bits, that of texel (x/2, y/2) of the next coarser
// level in the high 16, so one texel read serves two levels; setFilter); u_btf_wt
// RGBA32UI layers of 4 slots as 11/11/10-bit RGB; u_btf_env_w RGBA32UI layers of 4
// slots, the environment light's G_j (doc/lighting.md section 3) made from the same
// dequantised weights, 9 x views as signed 11/11/10-bit RGB codes on one scale per slot
// (u_btf_env_s; shaders/btf_light.glsl); the direction tables (btf-dirtab.js). Slot s:
// version 1 chunk s;
// version 2 the s-th component to arrive, whose chunks are its levels. Keeps a CPU
// copy of every layer it uploaded, so a new chunk rewrites only its slot's channel
// (and, in version 2, the levels it fills) and growing the layer count re-uploads
// from the copies. Owned by one viewer; free() with the same context.
// gl: a WebGL2 context (a GlStore is made on it), or a store with GlStore's methods
// and `packageStore: true` (three.js: client/three/btf-material.js).
export class GpuPackage {
  constructor(gl, pkg, capacity) {
    this.store = gl && gl.packageStore ? gl : new GlStore(gl);
    this.gl = this.store.gl || null;
    this.pkg = pkg;
    this.uploaded = 0;
    this.capacity = 0;
    this.uploads = 0; // chunk uploads so far (tests check: one per chunk)
    GpuPackage.live++;
    this.levels = pkg.version >= 2 ? pkg.levels : 1;
    this.slotOf = new Map(); // component -> slot (version 2)
    this.loaded = [];        // per slot: {component, fine, coarse, wt16}
    this.q16 = [];           // per slot, per level: Uint16Array of the atlas on the slot's grid (or null)
    this.q8 = [];            // version 4: per slot, per level, the reconstructed atlas bytes (residuals are over them)
    this.w8q = new Map();    // version 4: component -> its 8-bit weights (wt-JJ-r.z is a residual over them)
    this.paired = false;     // u_btf_tex paired (RGBA32UI), see setFilter; bilinear first, the viewer's default
    this.texCopy = [];       // per layer, per level: Uint16Array RGBA
    this.wtCopy = [];        // per layer: Uint32Array RGBA
    this.envCopy = [];       // per layer: Uint32Array RGBA, 9 x views
    this.tq = new Float32Array(0);
    this.wq = new Float32Array(0);
    this.envS = new Float32Array(0); // u_btf_env_s: per slot the scale of its G codes
    const tabs = [buildDirtab(pkg.lights), buildDirtab(pkg.views)];
    const d = dirtabGpu(tabs[0], tabs[1], pkg.viewBlock);
    this.outerCos = Math.cos(pkg.lights.maxTheta * Math.PI / 180);
    this.store.dirs(d.ubo, {width: CELLS, height: 2 * CELLS, data: d.cells}, {width: d.triWidth, height: d.rows, data: d.tris});
    this.live = true;
    this.reserve(pkg.version >= 2 ? pkg.components.length : capacity);
  }

  // Slots in use (version 2: components with a loaded chunk; version 1: chunks).
  get slots() {
    return this.pkg.version >= 2 ? this.loaded.length : this.uploaded;
  }

  // Makes room for n slots (n <= manifest chunks); layers grow in steps of 4 slots and
  // are re-uploaded from the CPU copies. Version 2 allocates every component at once.
  reserve(n) {
    const pkg = this.pkg;
    n = pkg.version >= 2 ? pkg.components.length : Math.max(1, Math.min(n, pkg.chunks.length));
    if (n <= this.capacity) return;
    const layers = Math.ceil(n / 4);
    this.store.allocate({...this.texShape(layers), lights: pkg.lights.dirs, views: pkg.views.dirs});
    const tq = new Float32Array(8 * layers), wq = new Float32Array(24 * layers);
    const envS = new Float32Array(4 * layers);
    tq.set(this.tq);
    wq.set(this.wq);
    envS.set(this.envS);
    this.tq = tq;
    this.wq = wq;
    this.envS = envS;
    for (let h = 0; h < this.texCopy.length; h++) {
      for (let l = 0; l < this.levels; l++) this.putTex(h, l);
      this.putWt(h);
      this.putEnv(h);
    }
    this.capacity = layers * 4;
  }

  // u_btf_tex's shape for `layers` layers, paired or not (store.allocateTex).
  texShape(layers) {
    const pkg = this.pkg;
    return {levels: this.levels, paired: this.paired, width: pkg.atlas.width, height: pkg.atlas.height, layers};
  }

  // The layout of u_btf_tex for draws with `filter` (0 nearest, 1 bilinear), as the
  // program's BTF_FILTER and BTF_LEVELS have it: paired only for levels on nearest taps
  // (one texel read for two levels); bilinear taps read each level's own texels, so
  // there RGBA16UI, half the memory. A change makes u_btf_tex anew from the copies.
  setFilter(filter) {
    const paired = this.levels > 1 && filter === 0;
    if (paired === this.paired) return;
    this.paired = paired;
    this.store.allocateTex(this.texShape(this.capacity / 4));
    for (let h = 0; h < this.texCopy.length; h++) for (let l = 0; l < this.levels; l++) this.putTex(h, l);
  }

  // Level l of layer h into u_btf_tex (paired: with level l + 1 beside it).
  putTex(h, l) {
    const pkg = this.pkg, aw = pkg.atlas.width >> l, ah = pkg.atlas.height >> l, lv = this.texCopy[h];
    const data = this.paired ? pairLevel(lv[l], l + 1 < this.levels ? lv[l + 1] : null, aw, ah) : lv[l];
    this.store.putTex(h, l, aw, ah, data);
  }

  putWt(h) {
    this.store.putWt(h, this.pkg.lights.dirs, this.pkg.views.dirs, this.wtCopy[h]);
  }

  putEnv(h) {
    this.store.putEnv(h, 9, this.pkg.views.dirs, this.envCopy[h]);
  }

  // The layer copies of layer h (created empty on first use).
  layer(h) {
    const pkg = this.pkg;
    while (this.texCopy.length <= h) {
      const lv = [];
      for (let l = 0; l < this.levels; l++) lv.push(new Uint16Array(4 * (pkg.atlas.width >> l) * (pkg.atlas.height >> l)));
      this.texCopy.push(lv);
      this.wtCopy.push(new Uint32Array(4 * pkg.lights.dirs * pkg.views.dirs));
      this.envCopy.push(new Uint32Array(4 * 9 * pkg.views.dirs));
    }
  }

  // RGBA bytes of an image decoded by btf-decode.js ({width, height, rgba}: the file's
  // exact samples, read in its worker).
  pixels(img) {
    if (!img.rgba) throw new Error('an image to upload must be decoded by btf-decode.js');
    return img.rgba;
  }

  // Quantised texels of a decoded atlas image (16-bit: q = R*256 + G, as in the PNG).
  readAtlas(bitmap) {
    const n = bitmap.width * bitmap.height, rgb = this.pkg.bits === 16, px = this.pixels(bitmap);
    const q = new Uint16Array(n);
    for (let i = 0; i < n; i++) q[i] = rgb ? px[4 * i] * 256 + px[4 * i + 1] : px[4 * i];
    return q;
  }

  // The 16-bit grid of a component: the smallest lo and the span of every chunk of
  // it in the manifest (all blocks, all levels), over 65535 (btf__tex_grid).
  grid(component, v1chunk) {
    const pkg = this.pkg, qmax = pkg.bits === 16 ? 65535 : 255;
    let a = Infinity, b = -Infinity;
    pkg.chunks.forEach((c, i) => {
      if (pkg.version < 2 ? i !== v1chunk : c.component !== component) return;
      for (let k = 0; k < pkg.nBlocks; k++) {
        a = Math.min(a, c.texRange[2 * k]);
        b = Math.max(b, f32(c.texRange[2 * k] + f32(c.texRange[2 * k + 1] * qmax)));
      }
    });
    return a <= b ? [f32(a), a < b ? f32(f32(b - a) / 65535) : 0] : [0, 0];
  }

  // Chunk j's atlas (level l) on slot s's grid: T = lo + step * q of the texel's block.
  requant(j, s, q, l) {
    const pkg = this.pkg, ch = pkg.chunks[j], cols = pkg.atlas.cols;
    const wl = pkg.width >> l, hl = pkg.height >> l, aw = wl * cols, ah = hl * pkg.atlas.rows;
    const lo = this.tq[8 * (s >> 2) + (s & 3)], st = this.tq[8 * (s >> 2) + 4 + (s & 3)];
    const out = new Uint16Array(aw * ah);
    for (let y = 0; y < ah; y++)
      for (let x = 0; x < aw; x++) {
        const b = Math.floor(y / hl) * cols + Math.floor(x / wl);
        if (b >= pkg.nBlocks) continue;
        const t = f32(ch.texRange[2 * b] + f32(ch.texRange[2 * b + 1] * q[y * aw + x]));
        const v = st > 0 ? Math.round(f32(f32(t - lo) / st)) : 0;
        out[y * aw + x] = v < 0 ? 0 : v > 65535 ? 65535 : v;
      }
    return out;
  }

  // Slot s into every level of its layer: each level takes the slot's nearest loaded
  // one, texel by texel (btf_lod_texel_of); then the layer's levels are uploaded (all
  // filled first: a paired level carries the next coarser one).
  fillSlot(s) {
    const pkg = this.pkg, {fine, coarse} = this.loaded[s], h = s >> 2, c = s & 3;
    const map = (x, l, from) => (from >= l ? x >> (from - l) : (x << (l - from)) + (1 << (l - from - 1)));
    for (let l = 0; l < this.levels; l++) {
      const lam = l < fine ? fine : l > coarse ? coarse : l, src = this.q16[s][lam], dst = this.texCopy[h][l];
      const wl = pkg.width >> l, hl = pkg.height >> l, aw = wl * pkg.atlas.cols, ah = hl * pkg.atlas.rows;
      const wm = pkg.width >> lam, hm = pkg.height >> lam, am = wm * pkg.atlas.cols;
      for (let y = 0; y < ah; y++) {
        const ty = Math.floor(y / hl), ym = ty * hm + map(y % hl, l, lam);
        for (let x = 0; x < aw; x++) {
          const tx = Math.floor(x / wl);
          dst[4 * (y * aw + x) + c] = src[ym * am + tx * wm + map(x % wl, l, lam)];
        }
      }
    }
    for (let l = 0; l < this.levels; l++) this.putTex(h, l);
  }

  // Weights of slot s on their own grid per channel (btf__pack_weights_slot).
  packWeights(s, w) {
    const n = this.pkg.lights.dirs * this.pkg.views.dirs, dst = this.wtCopy[s >> 2], c4 = s & 3;
    for (let i = 0; i < n; i++) dst[4 * i + c4] = 0;
    for (let c = 0; c < 3; c++) {
      let lo = Infinity, hi = -Infinity;
      for (let i = 0; i < n; i++) {
        lo = Math.min(lo, w[3 * i + c]);
        hi = Math.max(hi, w[3 * i + c]);
      }
      const step = hi > lo ? f32(f32(hi - lo) / WQMAX[c]) : 0;
      this.wq[24 * (s >> 2) + 4 * c + c4] = lo;
      this.wq[24 * (s >> 2) + 12 + 4 * c + c4] = step;
      for (let i = 0; i < n; i++) {
        const v = step > 0 ? Math.round(f32(f32(w[3 * i + c] - lo) / step)) : 0;
        dst[4 * i + c4] = (dst[4 * i + c4] | ((v < 0 ? 0 : v > WQMAX[c] ? WQMAX[c] : v) << WSHIFT[c])) >>> 0;
      }
    }
    this.putWt(s >> 2);
    this.envSlot(s, w);
  }

  // G_j of slot s from its dequantised weights w (btf-env.js envWeights) into channel s % 4
  // of its layer of u_btf_env_w: texel (j, v) = R | G << 11 | B << 22, the codes
  // m + round(G / s (m - 1)), m = 1024, 1024, 512, s the slot's largest |G| (btf__env_pack).
  envSlot(s, w) {
    const pkg = this.pkg, V = pkg.views.dirs, dst = this.envCopy[s >> 2], c4 = s & 3;
    const {g, big} = envWeights(envCells(pkg.lights), w, pkg.lights.dirs, V), scale = big > 0 ? big : 1;
    for (let i = 0; i < 9 * V; i++) {
      let u = 0;
      for (let ch = 0; ch < 3; ch++) u += (ENV_MID[ch] + rint(g[3 * i + ch] / scale * (ENV_MID[ch] - 1))) * 2 ** WSHIFT[ch];
      dst[4 * i + c4] = u;
    }
    this.envS[s] = scale;
    this.putEnv(s >> 2);
  }

  // Uploads chunk j (must be the next one): its atlas (decoded pixels of btf-decode.js, or
  // its decoded pixels) on its slot's grid, and its weights (dequantised Float32Array;
  // version 2: replaced unless 16-bit weights are there already; .precise = 16-bit).
  upload(j, bitmap, weights) {
    const pkg = this.pkg, ch = pkg.chunks[j], l = pkg.version >= 2 ? ch.level : 0;
    if (j !== this.uploaded) throw new Error(`chunk ${j} uploaded out of order (next is ${this.uploaded})`);
    const aw = pkg.atlas.width >> l, ah = pkg.atlas.height >> l;
    if (bitmap.width !== aw || bitmap.height !== ah)
      throw new Error(`package ${pkg.name}: ${ch.tex} is ${bitmap.width}x${bitmap.height}, expected ${aw}x${ah}`);
    let s = pkg.version >= 2 ? this.slotOf.get(ch.component) : j;
    if (s === undefined || pkg.version < 2) { // the slot's first chunk: loaded levels [l, l]
      if (!weights) throw new Error(`package ${pkg.name}: chunk ${j} is the first of component ${ch.component} ` +
                                    'but carries no weights');
      s = this.loaded.length;
      this.reserve(s + 1);
      this.slotOf.set(ch.component, s);
      this.loaded.push({fine: l, coarse: l, wt16: false});
      this.q16.push(new Array(this.levels).fill(null));
      const [lo, st] = this.grid(ch.component, j);
      this.tq[8 * (s >> 2) + (s & 3)] = lo;
      this.tq[8 * (s >> 2) + 4 + (s & 3)] = st;
    } else if (l === this.loaded[s].fine - 1) this.loaded[s].fine = l;
    else if (l === this.loaded[s].coarse + 1) this.loaded[s].coarse = l;
    else throw new Error(`package ${pkg.name}: chunk ${j} makes the levels of component ${ch.component} ` +
                         'non-contiguous');
    this.layer(s >> 2);
    let q = this.readAtlas(bitmap);
    if (pkg.manifestVersion === 4) { // section 12: a residual level over the component's next coarser one
      const coarse = this.q8[s] && this.q8[s][l + 1];
      if (ch.residual && !coarse) throw new Error(`package ${pkg.name}: chunk ${j} is a residual but level ` +
                                                  `${l + 1} of component ${ch.component} has not arrived`);
      if (ch.residual) q = reconstructLevel(pkg, ch, q, coarse);
      (this.q8[s] = this.q8[s] || [])[l] = q;
    }
    this.q16[s][l] = this.requant(j, s, q, l);
    this.fillSlot(s);
    const slot = this.loaded[s];
    if (weights && (weights.precise || !slot.wt16 || pkg.version < 2)) {
      this.packWeights(s, weights);
      slot.wt16 = slot.wt16 || !!weights.precise;
    }
    this.uploaded = j + 1;
    this.uploads++;
  }

  // The u_btf_* uniforms of a frame, as btf_gl_package_settings sets them: [name, type
  // ('1i', '1f', '2i', '4fv'), value]. chunks: what the frame draws; filter: 0 nearest,
  // 1 bilinear; wrap: 1 tile, 0 clamp.
  uniforms({chunks = this.uploaded, filter = 1, wrap = 0} = {}) {
    const pkg = this.pkg;
    // version 2: every loaded slot (the shader picks the level per pixel)
    const used = pkg.version >= 2 ? (chunks > 0 ? this.slots : 0) : Math.max(0, Math.min(chunks, this.uploaded));
    const wq = this.wq.slice();
    for (let k = used; k < wq.length / 6; k++) for (let c = 0; c < 6; c++) wq[24 * (k >> 2) + 4 * c + (k & 3)] = 0;
    return [['u_btf_tq', '4fv', this.tq], ['u_btf_wq', '4fv', wq], ['u_btf_size', '2i', [pkg.width, pkg.height]],
      ['u_btf_atlas_cols', '1i', pkg.atlas.cols], ['u_btf_outer_cos', '1f', this.outerCos], ['u_btf_chunks', '1i', used],
      ['u_btf_levels', '1i', this.levels], ['u_btf_lod', '1f', 0], ['u_btf_lod_auto', '1i', 1],
      ['u_btf_filter', '1i', filter], ['u_btf_wrap', '1i', wrap], ['u_btf_linear', '1i', pkg.linear ? 1 : 0],
      ['u_btf_env_s', '4fv', this.envS]];
  }

  // Binds the textures to units first..first+4 and the direction block to uniform
  // buffer binding 0, and sets the u_btf_* uniforms of prog (in use), as
  // btf_gl_package_bind + btf_gl_package_settings do; u_btf_tex laid out for
  // settings.filter (setFilter), the filter prog must be specialised for.
  bind(prog, first, settings = {}) {
    const gl = this.gl, st = this.store;
    this.setFilter(settings.filter ?? 1);
    const units = [[gl.TEXTURE_2D_ARRAY, st.tex, 'u_btf_tex'], [gl.TEXTURE_2D_ARRAY, st.wt, 'u_btf_wt'],
                   [gl.TEXTURE_2D, st.cells, 'u_btf_dir_cells'], [gl.TEXTURE_2D, st.tris, 'u_btf_dir_tris'],
                   [gl.TEXTURE_2D_ARRAY, st.envW, 'u_btf_env_w']];
    units.forEach(([target, t, name], i) => {
      gl.activeTexture(gl.TEXTURE0 + first + i);
      gl.bindTexture(target, t);
      gl.uniform1i(prog.loc(name), first + i);
    });
    gl.activeTexture(gl.TEXTURE0);
    const block = gl.getUniformBlockIndex(prog.program, 'btf_dirs_block');
    if (block !== gl.INVALID_INDEX) gl.uniformBlockBinding(prog.program, block, 0);
    gl.bindBufferBase(gl.UNIFORM_BUFFER, 0, st.ubo);
    for (const [name, type, v] of this.uniforms(settings)) {
      if (type === '2i') gl.uniform2i(prog.loc(name), v[0], v[1]);
      else gl[`uniform${type}`](prog.loc(name), v);
    }
  }

  // Pixels of a grey image decoded by the browser (a PNG such as wt-JJ-8.png, or a WebP
  // or AVIF texture): R of each pixel, the file's grey bytes (a lossy WebP's G may differ from
  // its R by one: package-format.md 4.1 reads R).
  readGrey(bitmap) {
    const n = bitmap.width * bitmap.height, px = this.pixels(bitmap), out = new Uint8Array(n);
    for (let i = 0; i < n; i++) out[i] = px[4 * i];
    return out;
  }

  free() {
    if (this.live) GpuPackage.live--;
    this.live = false;
    this.store.free();
    this.texCopy = this.wtCopy = this.envCopy = this.q16 = this.q8 = [];
  }
}

GpuPackage.live = 0; // packages not yet freed (test hook: nothing leaks)
