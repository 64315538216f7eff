// btf-env.js - the environment light of doc/lighting.md on the client: the built-in
// studio (section 2.1), an equirectangular image projected on the nine spherical
// harmonics of order <= 2 and written as the quadratic c0 + a.d + d^T Q d per channel
// (section 3), turned by a rotation (a -> R a, Q -> R Q R^T), the light cells of a
// package's light directions (section 1.1) and the material side G of the shader
// (section 3; btf-gl.js packs it into u_btf_env_w). Double precision throughout; what goes
// to the GPU is rounded to float32 there. No DOM, no GL: usable in node.
import {dir} from './scene.js';

export const STUDIO_WIDTH = 128;
export const STUDIO_HEIGHT = 64;
export const CELL_BANDS = 64;      // the cells' hemisphere samples: 64 bands ...
export const CELL_AZIMUTHS = 128;  // ... times 128 azimuths, equal in solid angle
export const ENV_FUNCS = 9;        // f = (1, x, y, z, xx, yy, xy, xz, yz)

const SH = [0.282095, 0.488603, 1.092548, 0.315392, 0.546274];

// The unit direction of the centre of pixel (i, j) of a W x H equirectangular image
// (section 2: row 0 up, the image's centre facing +x).
export function equirectDir(i, j, W, H) {
  const theta = Math.PI * (j + 0.5) / H, phi = Math.PI - 2 * Math.PI * (i + 0.5) / W;
  const s = Math.sin(theta);
  return [s * Math.cos(phi), s * Math.sin(phi), Math.cos(theta)];
}

// The studio's radiance at the unit direction d (section 2.1; all channels equal).
const STUDIO_LOBES = [[6, dir(35, -60), 20], [2, dir(60, 130), 30], [3, dir(80, 180), 12]];
export function studioRadiance(d) {
  let L = 0.25 + 0.15 * d[2];
  for (const [k, c, r] of STUDIO_LOBES) {
    const cr = Math.cos(r * Math.PI / 180);
    const t = Math.max(0, (d[0] * c[0] + d[1] * c[1] + d[2] * c[2] - cr) / (1 - cr));
    L += k * t * t;
  }
  return L;
}

// The studio as an image: {width: 128, height: 64, data: Float32Array RGB}, sampled at the
// pixel centres (made once).
let studio = null;
export function studioImage() {
  if (studio) return studio;
  const data = new Float32Array(3 * STUDIO_WIDTH * STUDIO_HEIGHT);
  for (let j = 0; j < STUDIO_HEIGHT; j++)
    for (let i = 0; i < STUDIO_WIDTH; i++)
      data.fill(studioRadiance(equirectDir(i, j, STUDIO_WIDTH, STUDIO_HEIGHT)), 3 * (j * STUDIO_WIDTH + i),
        3 * (j * STUDIO_WIDTH + i) + 3);
  studio = {width: STUDIO_WIDTH, height: STUDIO_HEIGHT, data};
  return studio;
}

// The nine real spherical harmonics at the unit direction d, in the order
// (0,0), (1,-1), (1,0), (1,1), (2,-2), (2,-1), (2,0), (2,1), (2,2).
export function shBasis(d) {
  const [x, y, z] = d;
  return [SH[0], SH[1] * y, SH[1] * z, SH[1] * x, SH[2] * x * y, SH[2] * y * z, SH[3] * (3 * z * z - 1),
    SH[2] * x * z, SH[4] * (x * x - y * y)];
}

// e_c = sum over pixels of L Y_c(d) dW (section 3) of an image {width, height, data RGB}:
// Float64Array(27), index 3 c + channel.
export function shProject(img) {
  const {width: W, height: H, data} = img, e = new Float64Array(27);
  for (let j = 0; j < H; j++) {
    const dW = (2 * Math.PI / W) * (Math.cos(Math.PI * j / H) - Math.cos(Math.PI * (j + 1) / H));
    for (let i = 0; i < W; i++) {
      const y = shBasis(equirectDir(i, j, W, H)), o = 3 * (j * W + i);
      for (let c = 0; c < 9; c++)
        for (let ch = 0; ch < 3; ch++) e[3 * c + ch] += data[o + ch] * y[c] * dW;
    }
  }
  return e;
}

// The value of the projection e (shProject) at the unit direction d: [r, g, b].
export function shEval(e, d) {
  const y = shBasis(d), out = [0, 0, 0];
  for (let c = 0; c < 9; c++) for (let ch = 0; ch < 3; ch++) out[ch] += e[3 * c + ch] * y[c];
  return out;
}

// The projection as the quadratic per channel: {c0: [3], a: [ch][3], q: [ch][3][3]} with
// L2(d) = c0 + a.d + d^T Q d.
export function shQuadratic(e) {
  const c0 = [], a = [], q = [];
  for (let ch = 0; ch < 3; ch++) {
    const k = (c) => e[3 * c + ch];
    c0.push(SH[0] * k(0) - SH[3] * k(6));
    a.push([SH[1] * k(3), SH[1] * k(1), SH[1] * k(2)]);
    const xy = SH[2] * k(4) / 2, yz = SH[2] * k(5) / 2, xz = SH[2] * k(7) / 2;
    q.push([[SH[4] * k(8), xy, xz], [xy, -SH[4] * k(8), yz], [xz, yz, 3 * SH[3] * k(6)]]);
  }
  return {c0, a, q};
}

// The environment quadratic of an image (shProject, then shQuadratic).
export function envQuadratic(img) {
  return shQuadratic(shProject(img));
}

// The quadratic's value at d: [r, g, b].
export function quadraticEval(quad, d) {
  return [0, 1, 2].map((ch) => {
    const a = quad.a[ch], Q = quad.q[ch];
    let v = quad.c0[ch] + a[0] * d[0] + a[1] * d[1] + a[2] * d[2];
    for (let r = 0; r < 3; r++) for (let c = 0; c < 3; c++) v += d[r] * Q[r][c] * d[c];
    return v;
  });
}

const mul = (A, B) => A.map((row) => [0, 1, 2].map((c) => row[0] * B[0][c] + row[1] * B[1][c] + row[2] * B[2][c]));
const transpose = (A) => [0, 1, 2].map((r) => [A[0][r], A[1][r], A[2][r]]);

// The rotation by deg degrees about the unit axis (right-handed: counter-clockwise seen
// from the axis' tip), as rows.
export function rotation(axis, deg) {
  const t = deg * Math.PI / 180, c = Math.cos(t), s = Math.sin(t), C = 1 - c, [x, y, z] = axis;
  return [[c + x * x * C, x * y * C - z * s, x * z * C + y * s],
          [y * x * C + z * s, c + y * y * C, y * z * C - x * s],
          [z * x * C - y * s, z * y * C + x * s, c + z * z * C]];
}

export const rotationZ = (deg) => rotation([0, 0, 1], deg);
export const matMul = mul;
export const matApply = (R, v) => R.map((row) => row[0] * v[0] + row[1] * v[1] + row[2] * v[2]);

// The environment turned by the rotation R (rows): L_rot(d) = L(R^T d), so a -> R a and
// Q -> R Q R^T. `environment-rotation` is R = rotationZ(degrees).
export function rotateQuadratic(quad, R) {
  const Rt = transpose(R);
  return {c0: quad.c0.slice(), a: quad.a.map((a) => matApply(R, a)), q: quad.q.map((Q) => mul(mul(R, Q), Rt))};
}

// The uniforms of the quadratic (btf_light.glsl): u_env_c0 (vec3), u_env_a (mat3, column
// ch = a of channel ch), u_env_q (three mat3, column-major), as Float32Arrays.
export function envUniforms(quad) {
  const q = new Float32Array(27);
  quad.q.forEach((Q, ch) => {
    for (let c = 0; c < 3; c++) for (let r = 0; r < 3; r++) q[9 * ch + 3 * c + r] = Q[r][c];
  });
  return {c0: Float32Array.from(quad.c0), a: Float32Array.from(quad.a.flat()), q};
}

// M_ij of section 1.1 for the unit light directions `lights` ([[x, y, z]], local frame):
// Float64Array(9 L), index 9 i + j. Each of the 8192 hemisphere samples goes to the light
// of the largest dot product (a tie to the lower index).
export function lightCells(lights) {
  const L = lights.length, M = new Float64Array(9 * L), dw = 2 * Math.PI / (CELL_BANDS * CELL_AZIMUTHS);
  for (let b = 0; b < CELL_BANDS; b++) {
    const z = 1 - (b + 0.5) / CELL_BANDS, r = Math.sqrt(1 - z * z);
    for (let a = 0; a < CELL_AZIMUTHS; a++) {
      const phi = 2 * Math.PI * (a + 0.5) / CELL_AZIMUTHS, x = r * Math.cos(phi), y = r * Math.sin(phi);
      let best = 0, bd = -Infinity;
      for (let i = 0; i < L; i++) {
        const d = x * lights[i][0] + y * lights[i][1] + z * lights[i][2];
        if (d > bd) {
          bd = d;
          best = i;
        }
      }
      const f = [1, x, y, z, x * x, y * y, x * y, x * z, y * z], o = 9 * best;
      for (let j = 0; j < 9; j++) M[o + j] += dw * f[j];
    }
  }
  return M;
}

// G_j(v, ch) = (1/pi) sum_i W(l_i, v, ch) M_ij of one slot (section 3): weights w as
// dequantised (index (v L + l) 3 + ch), M of lightCells. Returns {g: Float32Array(27 V),
// index 27 v + 3 j + ch, big: the largest |G| (before rounding to float32)}.
export function envWeights(M, w, L, V) {
  const G = new Float32Array(27 * V), acc = new Float64Array(27);
  let big = 0;
  for (let v = 0; v < V; v++) {
    acc.fill(0);
    for (let i = 0; i < L; i++) {
      const o = 3 * (v * L + i);
      for (let j = 0; j < 9; j++) {
        const m = M[9 * i + j];
        acc[3 * j] += w[o] * m;
        acc[3 * j + 1] += w[o + 1] * m;
        acc[3 * j + 2] += w[o + 2] * m;
      }
    }
    for (let k = 0; k < 27; k++) {
      const g = acc[k] / Math.PI;
      G[27 * v + k] = g;
      big = Math.max(big, Math.abs(g));
    }
  }
  return {g: G, big};
}
