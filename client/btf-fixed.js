// btf-fixed.js - the light's weights blended once per draw, for a distant light on a flat
// surface (the built-in plane): programs built with BTF_FIXED_LIGHT = 1
// (shaders/btf_decode.glsl) read u_btf_lw and u_btf_lq from here instead of u_btf_wt. The
// JS twin of shaders/host/btf_gl_fixed.c: for the light's three samples (dirtabInterp, the
// twin of the table btf_decode walks) and every view v, slot s and colour channel c,
// W(v) = sum_e w_e W_q(l_e, v) with W_q exactly what u_btf_wt holds (the GpuPackage's codes
// and grids), rounded onto 11/11/10-bit grids of its own range over the views.

import {buildDirtab, dirtabInterp} from './btf-dirtab.js';

const f32 = Math.fround;
const QMAX = [2047, 2047, 1023], SHIFT = [0, 11, 22];
const rint = (x) => { // C's rint: to nearest, ties to even
  const r = Math.round(x);
  return r - x === 0.5 && r % 2 !== 0 ? r - 1 : r;
};

// u_btf_lw texels (Uint32Array, views x layers x 4) and u_btf_lq (Float32Array, 24 per
// layer) of gpu (a GpuPackage) for local light `light` and its first `used` slots.
export function fixedBlend(gpu, tab, light, used) {
  const pkg = gpu.pkg, L = pkg.lights.dirs, V = pkg.views.dirs, layers = gpu.capacity >> 2;
  const codes = new Uint32Array(V * layers * 4), lq = new Float32Array(24 * layers), w = new Float64Array(V);
  const il = dirtabInterp(tab, light);
  for (let s = 0; s < used; s++) {
    const h = s >> 2, c4 = s & 3, src = gpu.wtCopy[h];
    for (let c = 0; c < 3; c++) {
      const lo = gpu.wq[24 * h + 4 * c + c4], step = gpu.wq[24 * h + 12 + 4 * c + c4];
      let a = Infinity, b = -Infinity;
      for (let v = 0; v < V; v++) {
        let sum = 0;
        for (let e = 0; e < 3; e++) {
          if (il.w[e] === 0) continue;
          const q = (src[4 * (v * L + il.idx[e]) + c4] >>> SHIFT[c]) & QMAX[c];
          sum += f32(il.w[e]) * f32(lo + f32(step * q));
        }
        w[v] = sum;
        a = Math.min(a, sum);
        b = Math.max(b, sum);
      }
      const flo = f32(a), st = b > a ? f32((b - a) / QMAX[c]) : 0;
      lq[24 * h + 4 * c + c4] = flo;
      lq[24 * h + 12 + 4 * c + c4] = st;
      for (let v = 0; v < V; v++) {
        const q = st > 0 ? Math.min(QMAX[c], Math.max(0, rint((w[v] - flo) / st))) : 0;
        codes[4 * (h * V + v) + c4] = (codes[4 * (h * V + v) + c4] | (q << SHIFT[c])) >>> 0;
      }
    }
  }
  return {codes, lq};
}

// The per-draw texture of one GpuPackage, rebuilt only when the light, the slots in use,
// the package's uploads or its layers change; free() with the renderer that made it.
export class FixedLight {
  constructor(gl, gpu) {
    this.gl = gl;
    this.gpu = gpu;
    this.tab = buildDirtab(gpu.pkg.lights);
    this.tex = null;
    this.layers = 0;
    this.key = '';
    this.lq = null;
  }

  // Binds u_btf_lw to `unit` and sets u_btf_lq of p (in use) for local light `light` and
  // `used` slots, blending first when they changed.
  bind(p, unit, light, used) {
    const gl = this.gl, gpu = this.gpu, layers = gpu.capacity >> 2;
    const key = `${light[0]},${light[1]},${light[2]}|${used}|${gpu.uploads}|${layers}`;
    gl.activeTexture(gl.TEXTURE0 + unit);
    if (key !== this.key) {
      const {codes, lq} = fixedBlend(gpu, this.tab, light, used), V = gpu.pkg.views.dirs;
      if (!this.tex || layers !== this.layers) {
        if (this.tex) gl.deleteTexture(this.tex);
        this.tex = gl.createTexture();
        gl.bindTexture(gl.TEXTURE_2D, this.tex);
        gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA32UI, V, layers);
        gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
        gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
        this.layers = layers;
      }
      gl.bindTexture(gl.TEXTURE_2D, this.tex);
      gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
      gl.texSubImage2D(gl.TEXTURE_2D, 0, 0, 0, V, layers, gl.RGBA_INTEGER, gl.UNSIGNED_INT, codes);
      this.lq = lq;
      this.key = key;
    }
    gl.bindTexture(gl.TEXTURE_2D, this.tex);
    gl.uniform1i(p.loc('u_btf_lw'), unit);
    gl.uniform4fv(p.loc('u_btf_lq'), this.lq);
    gl.activeTexture(gl.TEXTURE0);
  }

  free() {
    if (this.tex) this.gl.deleteTexture(this.tex);
    this.tex = null;
  }
}
