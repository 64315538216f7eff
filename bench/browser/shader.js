// bench/browser/shader.js - the page half of bench/bench_browser.mjs: the viewer's
// renderer (client/btf-render.js, the program the viewer draws with) against the
// thesis shader (shaders/bench/thesis.frag, its data built here exactly as
// bench/bench_shader.c builds it) in one WebGL2 context, 1280x720, the same plane,
// camera, light and package; frames timed to a one-pixel readback, interleaved.
import {decodeImage} from '/client/btf-decode.js';
import {loadShaders, GpuPackage} from '/client/btf-gl.js';
import {parseManifest, dequantWeights} from '/client/btf-package.js';
import {MeshRenderer} from '/client/btf-render.js';
import {cameraMake} from '/client/scene.js';
import {buildDirtab, dirtabInterp} from '/client/btf-dirtab.js';

const W = 1280, H = 720, MAPN = 512, FRAMES = 7;
const SCENE = {geometry: 'plane', cameraTheta: 30, cameraPhi: -90, cameraDist: 1.1, lightTheta: 40, lightPhi: -30,
  fov: 40, repeat: 8, background: [0, 0, 0], horizonFade: true};

async function load(gl, C) {
  const pkg = parseManifest(await (await fetch('/pkg/manifest.json')).json());
  const gpu = new GpuPackage(gl, pkg, C), weights = [];
  for (let j = 0; j < C; j++) {
    const ch = pkg.chunks[j];
    const bm = await decodeImage(new Uint8Array(await (await fetch(`/pkg/${ch.tex}`)).arrayBuffer()), 'image/png');
    const w = dequantWeights(pkg, ch, await (await fetch(`/pkg/${ch.wt}`)).arrayBuffer());
    w.precise = true;
    weights.push(w);
    gpu.upload(j, bm, w);
  }
  return {pkg, gpu, weights};
}

function compile(gl, type, text) {
  const s = gl.createShader(type);
  gl.shaderSource(s, text);
  gl.compileShader(s);
  if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
  return s;
}

// The render vertex stage with thesis.frag after the manifest's prefix lines.
async function thesisProgram(gl, shaders) {
  const pre = shaders.manifest.prefix.join('\n') + '\n';
  const vs = pre + shaders.manifest.programs.render.vertex.map((f) => shaders.files.get(f)).join('\n');
  const fs = pre + await (await fetch('/shaders/bench/thesis.frag')).text();
  const p = gl.createProgram();
  gl.attachShader(p, compile(gl, gl.VERTEX_SHADER, vs));
  gl.attachShader(p, compile(gl, gl.FRAGMENT_SHADER, fs));
  gl.linkProgram(p);
  if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(p));
  return p;
}

function rgba8(gl, w, h, data) {
  const t = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_2D, t);
  for (const [k, v] of [[gl.TEXTURE_MIN_FILTER, gl.NEAREST], [gl.TEXTURE_MAG_FILTER, gl.NEAREST],
    [gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE], [gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE]]) gl.texParameteri(gl.TEXTURE_2D, k, v);
  gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA8, w, h, 0, gl.RGBA, gl.UNSIGNED_BYTE, data);
  return t;
}

// Lookup maps of one direction set (azimuthal-equidistant hemisphere, bench_shader.c thesis_maps).
function maps(gl, set) {
  const tab = buildDirtab(set), a = new Uint8Array(MAPN * MAPN * 4), b = new Uint8Array(MAPN * MAPN * 4);
  for (let j = 0; j < MAPN; j++)
    for (let i = 0; i < MAPN; i++) {
      const x = (i + 0.5) / MAPN * 2 - 1, y = (j + 0.5) / MAPN * 2 - 1, r = Math.min(Math.hypot(x, y), 1);
      const t = 90 * r * Math.PI / 180, p = Math.atan2(y, x);
      const it = dirtabInterp(tab, [Math.sin(t) * Math.cos(p), Math.sin(t) * Math.sin(p), Math.cos(t)]);
      const o = 4 * (j * MAPN + i);
      for (let k = 0; k < 3; k++) {
        a[o + k] = it.idx[k];
        b[o + k] = Math.round(it.w[k] * 255);
      }
      a[o + 3] = b[o + 3] = 255;
    }
  return [rgba8(gl, MAPN, MAPN, a), rgba8(gl, MAPN, MAPN, b)];
}

// The thesis's textures for the first C components: T from the GPU package's 16-bit
// layers (its grid), weights as loaded; one global 8-bit range per component.
function thesisData(gl, pkg, gpu, weights, C) {
  const Wd = pkg.width, Hd = pkg.height, B = pkg.nBlocks, L = pkg.lights.dirs, V = pkg.views.dirs, G = Math.ceil(C / 4);
  const cols = pkg.atlas.cols, aw = pkg.atlas.width;
  const T = (s, b, x, y) => {
    const q = gpu.q16[s][0][((Math.floor(b / cols) * Hd + y) * aw) + (b % cols) * Wd + x];
    return gpu.tq[8 * (s >> 2) + (s & 3)] + gpu.tq[8 * (s >> 2) + 4 + (s & 3)] * q;
  };
  const tlo = new Float32Array(16), tst = new Float32Array(16), wlo = new Float32Array(16), wst = new Float32Array(16);
  const mask = new Float32Array(16);
  for (let j = 0; j < C; j++) {
    let lo = Infinity, hi = -Infinity, a = Infinity, z = -Infinity;
    for (let b = 0; b < B; b++) for (let y = 0; y < Hd; y++) for (let x = 0; x < Wd; x++) {
      const v = T(j, b, x, y);
      lo = Math.min(lo, v);
      hi = Math.max(hi, v);
    }
    for (const v of weights[j]) {
      a = Math.min(a, v);
      z = Math.max(z, v);
    }
    [tlo[j], tst[j], wlo[j], wst[j], mask[j]] = [lo, (hi - lo) / 255, a, (z - a) / 255, 1];
  }
  const q8 = (x, lo, st) => Math.round(st > 0 ? (x - lo) / st : 0);
  const Lw = Wd * G, Lh = Hd * B, Rw = L * 3 * G, Rh = V;
  const Lt = new Uint8Array(Lw * Lh * 4), Rt = new Uint8Array(Rw * Rh * 4);
  for (let j = 0; j < C; j++) {
    const g = j >> 2, ch = j & 3;
    for (let b = 0; b < B; b++) for (let y = 0; y < Hd; y++) for (let x = 0; x < Wd; x++)
      Lt[((b * Hd + y) * Lw + g * Wd + x) * 4 + ch] = q8(T(j, b, x, y), tlo[j], tst[j]);
    for (let v = 0; v < V; v++) for (let l = 0; l < L; l++) for (let c = 0; c < 3; c++)
      Rt[(v * Rw + (l * 3 + c) * G + g) * 4 + ch] = q8(weights[j][(v * L + l) * 3 + c], wlo[j], wst[j]);
  }
  return {G, Lw, Lh, Rw, Rh, tlo, tst, wlo, wst, mask, L: rgba8(gl, Lw, Lh, Lt), R: rgba8(gl, Rw, Rh, Rt),
    maps: [...maps(gl, pkg.lights), ...maps(gl, pkg.views)]};
}

function drawThesis(gl, prog, mesh, pkg, td) {
  const cam = cameraMake(SCENE, W / H), loc = (n) => gl.getUniformLocation(prog, n);
  gl.viewport(0, 0, W, H);
  gl.clearColor(0, 0, 0, 1);
  gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
  gl.useProgram(prog);
  [['u_light_idx', td.maps[0]], ['u_light_w', td.maps[1]], ['u_view_idx', td.maps[2]], ['u_view_w', td.maps[3]],
    ['u_L', td.L], ['u_R', td.R]].forEach(([n, t], i) => {
    gl.activeTexture(gl.TEXTURE0 + i);
    gl.bindTexture(gl.TEXTURE_2D, t);
    gl.uniform1i(loc(n), i);
  });
  gl.uniform2i(loc('u_size'), pkg.width, pkg.height);
  gl.uniform2f(loc('u_L_size'), td.Lw, td.Lh);
  gl.uniform2f(loc('u_R_size'), td.Rw, td.Rh);
  gl.uniform1i(loc('u_groups'), td.G);
  gl.uniform1iv(loc('u_view_block'), Int32Array.from(pkg.viewBlock));
  for (const [n, a] of [['u_tlo', td.tlo], ['u_tstep', td.tst], ['u_wlo', td.wlo], ['u_wstep', td.wst],
    ['u_cmask', td.mask]]) gl.uniform4fv(loc(n), a);
  gl.uniformMatrix4fv(loc('u_model'), false, new Float32Array([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]));
  gl.uniformMatrix4fv(loc('u_view_proj'), false, cam.viewProj);
  gl.uniform3fv(loc('u_camera'), cam.eye);
  gl.uniform4f(loc('u_light'), cam.light[0], cam.light[1], cam.light[2], 0);
  gl.uniform2f(loc('u_uv_scale'), cam.uvScale[0], cam.uvScale[1]);
  gl.enable(gl.DEPTH_TEST);
  gl.bindVertexArray(mesh.vao);
  gl.drawElements(gl.TRIANGLES, mesh.count, gl.UNSIGNED_INT, 0);
  gl.bindVertexArray(null);
  gl.disable(gl.DEPTH_TEST);
}

// Median ms of FRAMES frames of draw() after one warm-up, each ended by reading one
// pixel back (gl.finish() does not wait for Chromium's GPU process).
function time(gl, draw) {
  const ms = [], px = new Uint8Array(4);
  for (let i = -1; i < FRAMES; i++) {
    const t0 = performance.now();
    draw();
    gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px);
    if (i >= 0) ms.push(performance.now() - t0);
  }
  return ms.sort((a, b) => a - b)[FRAMES >> 1];
}

export async function run(C) {
  const cv = document.createElement('canvas');
  cv.width = W;
  cv.height = H;
  document.body.append(cv);
  const gl = cv.getContext('webgl2', {antialias: false, depth: true, preserveDrawingBuffer: true});
  const shaders = await loadShaders(new URL('/shaders/', location.href));
  const {pkg, gpu, weights} = await load(gl, C);
  const renderer = new MeshRenderer(gl, shaders), prog = await thesisProgram(gl, shaders);
  const td = thesisData(gl, pkg, gpu, weights, C), mesh = renderer.mesh('plane');
  const out = {renderer: gl.getParameter(gl.RENDERER)};
  const view = (filter) => ({...SCENE, chunks: C, filter});
  const runtime = {...view(0), fixedLight: false}; // the run-time light path (curved meshes, models)
  for (let r = 0; r < 2; r++) { // interleaved rounds; the lower median of each
    const v = time(gl, () => renderer.draw(gpu, view(1), W, H));
    const n = time(gl, () => renderer.draw(gpu, view(0), W, H));
    const rt = time(gl, () => renderer.draw(gpu, runtime, W, H));
    const t = time(gl, () => drawThesis(gl, prog, mesh, pkg, td));
    out.viewer = Math.min(out.viewer ?? Infinity, v);
    out.nearest = Math.min(out.nearest ?? Infinity, n);
    out.runtime = Math.min(out.runtime ?? Infinity, rt);
    out.thesis = Math.min(out.thesis ?? Infinity, t);
  }
  out.fixed = [...renderer.progs.keys()].some((k) => k.includes('BTF_FIXED_LIGHT=1'));
  const e = gl.getError();
  if (e) throw new Error(`GL error 0x${e.toString(16)}`);
  return out;
}
