// btf-gl.js - WebGL2 side of the viewer: shader files from shaders/ assembled exactly
// as shaders/host/btf_shader.c does (shaders/README.md), compile/link errors reported
// twgl-style against the numbered source, and the package's textures (the same
// layout as shaders/host/btf_gl_package.c: u_btf_tex, u_btf_wt, u_btf_range,
// u_btf_view_block), uploaded one chunk at a time; version-2 packages as mip levels
// of per-component slots (shaders/README.md, "Spatial levels").

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

// shaders/manifest.json and every file it names, fetched once per base URL.
export function loadShaders(base) {
  if (!manifests.has(base)) {
    const p = fetchText(new URL('manifest.json', base)).then(async (text) => {
      const manifest = JSON.parse(text);
      if (!Array.isArray(manifest.prefix) || !manifest.prefix.length || typeof manifest.programs !== 'object')
        throw new Error('shader: manifest.json lacks "prefix" or "programs"');
      const names = new Set();
      for (const prog of Object.values(manifest.programs))
        for (const stage of ['vertex', 'fragment'])
          for (const f of prog[stage] || []) names.add(f);
      const files = new Map();
      await Promise.all([...names].map(async (f) => {
        if (!plainName(f)) throw new Error(`shader: manifest.json names '${f}', not a plain file name`);
        files.set(f, await fetchText(new URL(f, base)));
      }));
      return {manifest, files};
    });
    p.catch(() => manifests.delete(base));
    manifests.set(base, p);
  }
  return manifests.get(base);
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

function compile(gl, program, stageName, src) {
  const sh = gl.createShader(stageName === 'vertex' ? gl.VERTEX_SHADER : gl.FRAGMENT_SHADER);
  gl.shaderSource(sh, src.text);
  gl.compileShader(sh);
  if (gl.getShaderParameter(sh, gl.COMPILE_STATUS) || gl.isContextLost()) return sh;
  const log = gl.getShaderInfoLog(sh) || '';
  gl.deleteShader(sh);
  const first = (log.split('\n').find((l) => l.trim()) || 'unknown error').trim();
  const [file, fl] = sourceLine(src, logLine(first));
  const err = new Error(`shader '${program}' ${stageName}: ${first}${file ? ` (${file} line ${fl})` : ''}`);
  err.report = annotate(src, log);
  throw err;
}

// Builds a program from the manifest; throws Error with .report (annotated listing).
export function buildProgram(gl, shaders, program, defines = []) {
  const vsrc = assemble(shaders, program, 'vertex', defines);
  const fsrc = assemble(shaders, program, 'fragment', defines);
  const vs = compile(gl, program, 'vertex', vsrc);
  const fs = compile(gl, program, 'fragment', fsrc);
  const p = gl.createProgram();
  gl.attachShader(p, vs);
  gl.attachShader(p, fs);
  gl.linkProgram(p);
  gl.deleteShader(vs);
  gl.deleteShader(fs);
  if (!gl.getProgramParameter(p, gl.LINK_STATUS) && !gl.isContextLost()) {
    const log = gl.getProgramInfoLog(p) || '';
    gl.deleteProgram(p);
    const err = new Error(`shader '${program}': link failed: ${(log.split('\n')[0] || '').trim()}`);
    err.report = log;
    throw err;
  }
  const uniforms = new Map();
  const n = gl.getProgramParameter(p, gl.ACTIVE_UNIFORMS) || 0;
  for (let i = 0; i < n; i++) {
    const info = gl.getActiveUniform(p, i);
    const name = info.name.replace(/\[0\]$/, '');
    uniforms.set(name, gl.getUniformLocation(p, info.name));
  }
  return {program: p, name: program, uniforms, loc: (u) => uniforms.get(u) ?? null};
}

// ---------------------------------------------------------------- package textures

function nearest(gl, target) {
  gl.texParameteri(target, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
  gl.texParameteri(target, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
  gl.texParameteri(target, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
  gl.texParameteri(target, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
}

// A package's GPU textures. Version 1: layers for `capacity` chunks (the budget);
// grows by a GPU-side copy of the layers already there, so no chunk is uploaded
// twice. Version 2 (shaders/README.md, "Spatial levels"): one layer (slot) per
// component with every mip level, allocated at once; chunk (component, level) goes
// into that mip level. Owned by one viewer; free() with the same context.
export class GpuPackage {
  constructor(gl, pkg, capacity) {
    this.gl = gl;
    this.pkg = pkg;
    this.uploaded = 0;
    this.capacity = 0;
    this.uploads = 0; // texture-layer uploads so far (tests check: one per chunk)
    GpuPackage.live++;
    const V = pkg.views.dirs, L = pkg.lights.dirs;
    // Version 2 (shaders/README.md, "Spatial levels"): textures by slot (the s-th
    // component to arrive), levels as mip levels; version 1: slot = chunk, one level.
    this.levels = pkg.version >= 2 ? pkg.levels : 1;
    this.slotOf = new Map(); // component -> slot (version 2)
    this.loaded = [];        // per slot: {fine, coarse, wt16} (version 2)
    const nc = pkg.version >= 2 ? pkg.components.length : pkg.chunks.length;
    // weights for every chunk (slot) of the manifest: 12 * L * V bytes each (78 KB at 81 x 81)
    this.wt = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D_ARRAY, this.wt);
    nearest(gl, gl.TEXTURE_2D_ARRAY);
    gl.texStorage3D(gl.TEXTURE_2D_ARRAY, 1, gl.RGB32F, L, V, nc);
    this.range = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, this.range);
    nearest(gl, gl.TEXTURE_2D);
    gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA32F, pkg.nBlocks, nc * this.levels);
    this.rangeRows = new Float32Array(4 * pkg.nBlocks * nc * this.levels); // CPU copy (version 2)
    this.viewBlock = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, this.viewBlock);
    nearest(gl, gl.TEXTURE_2D);
    gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA32F, V, 1);
    const vb = new Float32Array(4 * V);
    for (let v = 0; v < V; v++) vb[4 * v] = pkg.viewBlock[v];
    gl.texSubImage2D(gl.TEXTURE_2D, 0, 0, 0, V, 1, gl.RGBA, gl.FLOAT, vb);
    this.tex = null;
    this.reserve(pkg.version >= 2 ? nc : capacity);
  }

  // Slots in use (version 2: components with a loaded chunk; version 1: chunks).
  get slots() {
    return this.pkg.version >= 2 ? this.loaded.length : this.uploaded;
  }

  get texFormat() {
    const gl = this.gl;
    return this.pkg.bits === 16 ? [gl.RGB8, gl.RGB] : [gl.R8, gl.RED];
  }

  // Makes room for n chunk layers (n <= manifest chunks); copies existing layers on the GPU.
  // Version 2 allocates every component's slot with all its mip levels at once.
  reserve(n) {
    const gl = this.gl, pkg = this.pkg;
    if (pkg.version >= 2) {
      if (this.tex) return;
      n = pkg.components.length;
    }
    n = Math.max(1, Math.min(n, pkg.chunks.length));
    if (n <= this.capacity) return;
    const [ifmt] = this.texFormat;
    const tex = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D_ARRAY, tex);
    nearest(gl, gl.TEXTURE_2D_ARRAY);
    if (this.levels > 1) {
      gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MIN_FILTER, gl.NEAREST_MIPMAP_NEAREST);
      gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MAX_LEVEL, this.levels - 1);
    }
    gl.texStorage3D(gl.TEXTURE_2D_ARRAY, this.levels, ifmt, pkg.atlas.width, pkg.atlas.height, n);
    if (this.tex && this.uploaded) {
      const fb = gl.createFramebuffer();
      gl.bindFramebuffer(gl.READ_FRAMEBUFFER, fb);
      for (let j = 0; j < this.uploaded; j++) {
        gl.framebufferTextureLayer(gl.READ_FRAMEBUFFER, gl.COLOR_ATTACHMENT0, this.tex, 0, j);
        gl.copyTexSubImage3D(gl.TEXTURE_2D_ARRAY, 0, 0, 0, j, 0, 0, pkg.atlas.width, pkg.atlas.height);
      }
      gl.bindFramebuffer(gl.READ_FRAMEBUFFER, null);
      gl.deleteFramebuffer(fb);
    }
    if (this.tex) gl.deleteTexture(this.tex);
    this.tex = tex;
    this.capacity = n;
  }

  // Uploads chunk j (must be the next one): its atlas (ImageBitmap decoded without
  // colour conversion), its dequantised weights, its range row.
  upload(j, bitmap, weights) {
    const gl = this.gl, pkg = this.pkg;
    if (j !== this.uploaded) throw new Error(`chunk ${j} uploaded out of order (next is ${this.uploaded})`);
    if (pkg.version >= 2) return this.uploadLevel(j, bitmap, weights);
    if (bitmap.width !== pkg.atlas.width || bitmap.height !== pkg.atlas.height)
      throw new Error(`package ${pkg.name}: ${pkg.chunks[j].tex} is ${bitmap.width}x${bitmap.height}, ` +
                      `expected ${pkg.atlas.width}x${pkg.atlas.height}`);
    this.reserve(j + 1);
    const [, fmt] = this.texFormat;
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
    gl.pixelStorei(gl.UNPACK_FLIP_Y_WEBGL, false);
    gl.pixelStorei(gl.UNPACK_PREMULTIPLY_ALPHA_WEBGL, false);
    gl.pixelStorei(gl.UNPACK_COLORSPACE_CONVERSION_WEBGL, gl.NONE);
    gl.bindTexture(gl.TEXTURE_2D_ARRAY, this.tex);
    gl.texSubImage3D(gl.TEXTURE_2D_ARRAY, 0, 0, 0, j, pkg.atlas.width, pkg.atlas.height, 1, fmt,
                     gl.UNSIGNED_BYTE, bitmap);
    gl.bindTexture(gl.TEXTURE_2D_ARRAY, this.wt);
    gl.texSubImage3D(gl.TEXTURE_2D_ARRAY, 0, 0, 0, j, pkg.lights.dirs, pkg.views.dirs, 1, gl.RGB, gl.FLOAT,
                     weights);
    const row = new Float32Array(4 * pkg.nBlocks);
    const r = pkg.chunks[j].texRange;
    for (let b = 0; b < pkg.nBlocks; b++) {
      row[4 * b] = r[2 * b];
      row[4 * b + 1] = r[2 * b + 1];
    }
    gl.bindTexture(gl.TEXTURE_2D, this.range);
    gl.texSubImage2D(gl.TEXTURE_2D, 0, 0, j, pkg.nBlocks, 1, gl.RGBA, gl.FLOAT, row);
    this.uploaded = j + 1;
    this.uploads++;
  }

  // Version 2: chunk j = (component c, level l) into mip level l of c's slot; its
  // texture range into row s*N + l of u_btf_range and the slot's loaded level range
  // into .zw of all N rows; weights (8-bit coarse or 16-bit) replace the slot's layer
  // unless 16-bit weights are there already. weights.precise: from wt-JJ.bin.
  uploadLevel(j, bitmap, weights) {
    const gl = this.gl, pkg = this.pkg, ch = pkg.chunks[j], l = ch.level, N = this.levels;
    const aw = pkg.atlas.width >> l, ah = pkg.atlas.height >> l;
    if (bitmap.width !== aw || bitmap.height !== ah)
      throw new Error(`package ${pkg.name}: ${ch.tex} is ${bitmap.width}x${bitmap.height}, expected ${aw}x${ah}`);
    let s = this.slotOf.get(ch.component);
    if (s === undefined) { // the component's first chunk: loaded levels [l, l]
      if (!weights) throw new Error(`package ${pkg.name}: chunk ${j} is the first of component ${ch.component} ` +
                                    'but carries no weights');
      s = this.loaded.length;
      this.slotOf.set(ch.component, s);
      this.loaded.push({fine: l, coarse: l, wt16: false});
    } else if (l === this.loaded[s].fine - 1) this.loaded[s].fine = l;
    else if (l === this.loaded[s].coarse + 1) this.loaded[s].coarse = l;
    else throw new Error(`package ${pkg.name}: chunk ${j} makes the levels of component ${ch.component} ` +
                         'non-contiguous');
    const slot = this.loaded[s];
    const [, fmt] = this.texFormat;
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
    gl.pixelStorei(gl.UNPACK_FLIP_Y_WEBGL, false);
    gl.pixelStorei(gl.UNPACK_PREMULTIPLY_ALPHA_WEBGL, false);
    gl.pixelStorei(gl.UNPACK_COLORSPACE_CONVERSION_WEBGL, gl.NONE);
    gl.bindTexture(gl.TEXTURE_2D_ARRAY, this.tex);
    gl.texSubImage3D(gl.TEXTURE_2D_ARRAY, l, 0, 0, s, aw, ah, 1, fmt, gl.UNSIGNED_BYTE, bitmap);
    if (weights && (weights.precise || !slot.wt16)) {
      gl.bindTexture(gl.TEXTURE_2D_ARRAY, this.wt);
      gl.texSubImage3D(gl.TEXTURE_2D_ARRAY, 0, 0, 0, s, pkg.lights.dirs, pkg.views.dirs, 1, gl.RGB, gl.FLOAT,
                       weights);
      slot.wt16 = slot.wt16 || !!weights.precise;
    }
    const nb = pkg.nBlocks, rows = this.rangeRows;
    for (let k = 0; k < N; k++) {
      const o = 4 * nb * (s * N + k);
      for (let b = 0; b < nb; b++) {
        if (k === l) {
          rows[o + 4 * b] = ch.texRange[2 * b];
          rows[o + 4 * b + 1] = ch.texRange[2 * b + 1];
        }
        rows[o + 4 * b + 2] = slot.fine;
        rows[o + 4 * b + 3] = slot.coarse;
      }
    }
    gl.bindTexture(gl.TEXTURE_2D, this.range);
    gl.texSubImage2D(gl.TEXTURE_2D, 0, 0, s * N, nb, N, gl.RGBA, gl.FLOAT,
                     rows.subarray(4 * nb * s * N, 4 * nb * (s + 1) * N));
    this.uploaded = j + 1;
    this.uploads++;
  }

  // Binds the 4 textures to units first..first+3 and sets the u_btf_* uniforms of prog
  // (in use), as btf_gl_package_bind + btf_gl_package_settings do.
  bind(prog, first, {chunks = this.uploaded, filter = 1, wrap = 0} = {}) {
    const gl = this.gl, pkg = this.pkg;
    const units = [[gl.TEXTURE_2D_ARRAY, this.tex, 'u_btf_tex'], [gl.TEXTURE_2D_ARRAY, this.wt, 'u_btf_wt'],
                   [gl.TEXTURE_2D, this.range, 'u_btf_range'], [gl.TEXTURE_2D, this.viewBlock, 'u_btf_view_block']];
    units.forEach(([target, t, name], i) => {
      gl.activeTexture(gl.TEXTURE0 + first + i);
      gl.bindTexture(target, t);
      gl.uniform1i(prog.loc(name), first + i);
    });
    gl.activeTexture(gl.TEXTURE0);
    for (const [u, d] of [['u_btf_lights', pkg.lights], ['u_btf_views', pkg.views]]) {
      gl.uniform4fv(prog.loc(`${u}.rings`), d.rings.subarray(0, 4 * d.n));
      gl.uniform1i(prog.loc(`${u}.n_rings`), d.n);
    }
    gl.uniform2i(prog.loc('u_btf_size'), pkg.width, pkg.height);
    gl.uniform1i(prog.loc('u_btf_atlas_cols'), pkg.atlas.cols);
    gl.uniform1i(prog.loc('u_btf_bits'), pkg.bits);
    // version 2: every loaded slot (the shader picks the level per pixel)
    const used = pkg.version >= 2 ? (chunks > 0 ? this.slots : 0) : Math.max(0, Math.min(chunks, this.uploaded));
    gl.uniform1i(prog.loc('u_btf_chunks'), used);
    gl.uniform1i(prog.loc('u_btf_levels'), this.levels);
    gl.uniform1f(prog.loc('u_btf_lod'), 0);
    gl.uniform1i(prog.loc('u_btf_lod_auto'), 1);
    gl.uniform1i(prog.loc('u_btf_filter'), filter);
    gl.uniform1i(prog.loc('u_btf_wrap'), wrap);
  }

  // Pixels of a grey PNG (wt-JJ-8.png) decoded by the browser: uploaded into an R8
  // texture (no colour conversion) and read back, so they are exactly the PNG's bytes.
  readGrey(bitmap) {
    const gl = this.gl, w = bitmap.width, h = bitmap.height;
    const t = gl.createTexture(), fb = gl.createFramebuffer();
    gl.bindTexture(gl.TEXTURE_2D, t);
    nearest(gl, gl.TEXTURE_2D);
    gl.texStorage2D(gl.TEXTURE_2D, 1, gl.R8, w, h);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
    gl.pixelStorei(gl.UNPACK_FLIP_Y_WEBGL, false);
    gl.pixelStorei(gl.UNPACK_PREMULTIPLY_ALPHA_WEBGL, false);
    gl.pixelStorei(gl.UNPACK_COLORSPACE_CONVERSION_WEBGL, gl.NONE);
    gl.texSubImage2D(gl.TEXTURE_2D, 0, 0, 0, w, h, gl.RED, gl.UNSIGNED_BYTE, bitmap);
    gl.bindFramebuffer(gl.READ_FRAMEBUFFER, fb);
    gl.framebufferTexture2D(gl.READ_FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, t, 0);
    const rgba = new Uint8Array(4 * w * h);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, rgba);
    gl.bindFramebuffer(gl.READ_FRAMEBUFFER, null);
    gl.deleteFramebuffer(fb);
    gl.deleteTexture(t);
    const out = new Uint8Array(w * h);
    for (let i = 0; i < w * h; i++) out[i] = rgba[4 * i];
    return out;
  }

  free() {
    const gl = this.gl;
    if (this.wt) GpuPackage.live--;
    for (const t of [this.tex, this.wt, this.range, this.viewBlock]) if (t) gl.deleteTexture(t);
    this.tex = this.wt = this.range = this.viewBlock = null;
  }
}

GpuPackage.live = 0; // packages not yet freed (test hook: nothing leaks)
