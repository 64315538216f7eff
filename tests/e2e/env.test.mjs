// env.test.mjs - client/btf-env.js in node (doc/lighting.md sections 1.1, 2.1, 3): the
// studio's quadratic is its SH projection, a constant environment is the constant
// quadratic, the light cells tile the hemisphere, a rotation turns a lobe where it should,
// and G of a Lambertian material under a constant environment gives its albedo.
import assert from 'node:assert/strict';
import {describe, it} from 'node:test';
import {envQuadratic, envUniforms, envWeights, equirectDir, lightCells, quadraticEval, rotateQuadratic, rotationZ,
  shEval, shProject, shQuadratic, studioImage, studioRadiance} from '../../client/btf-env.js';
import {dirVectors} from '../../client/btf-dirtab.js';
import {parseManifest} from '../../client/btf-package.js';

let seed = 7;
const rnd = () => ((seed = (seed * 1103515245 + 12345) >>> 0) / 2 ** 32);
function randomDir() {
  const z = 2 * rnd() - 1, p = 2 * Math.PI * rnd(), r = Math.sqrt(1 - z * z);
  return [r * Math.cos(p), r * Math.sin(p), z];
}

// A W x H equirect image of the function f(d) -> [r, g, b] at the pixel centres.
function imageOf(W, H, f) {
  const data = new Float32Array(3 * W * H);
  for (let j = 0; j < H; j++) for (let i = 0; i < W; i++) data.set(f(equirectDir(i, j, W, H)), 3 * (j * W + i));
  return {width: W, height: H, data};
}

// The UBO2003 light set (81 directions in 6 rings).
const UBO = {rings: [[0, 1, 0], [15, 6, 0], [30, 12, 0], [45, 18, 0], [60, 20, 0], [75, 24, 0]]
  .map(([theta, count, phi_offset]) => ({theta, count, phi_offset}))};
function uboLights() {
  const m = {format: 'btf-package', version: 1, name: 'm', width: 4, height: 4, bits: 8, lights: UBO, views: UBO,
    blocks: [[...Array(81).keys()]], atlas: {cols: 1, rows: 1, width: 4, height: 4, tile_width: 4, tile_height: 4},
    chunks: [{files: ['tex-00.png', 'wt-00.bin'], tex_range: [[0, 1]], wt_range: [[0, 1]]}]};
  return dirVectors(parseManifest(m).lights);
}

describe('btf-env.js', () => {
  it('the studio: the function of section 2.1, its quadratic equal to its SH projection', () => {
    assert.ok(Math.abs(studioRadiance([0, 0, 1]) - 0.4) < 1e-12 && Math.abs(studioRadiance([0, 0, -1]) - 0.1) < 1e-12);
    const key = [Math.sin(35 * Math.PI / 180) * Math.cos(-Math.PI / 3), Math.sin(35 * Math.PI / 180) *
      Math.sin(-Math.PI / 3), Math.cos(35 * Math.PI / 180)];
    assert.ok(Math.abs(studioRadiance(key) - (0.25 + 0.15 * key[2] + 6)) < 1e-9, 'the key light peaks at 6 above the base');
    const img = studioImage();
    assert.deepEqual([img.width, img.height], [128, 64]);
    const e = shProject(img), q = shQuadratic(e);
    let worst = 0;
    for (let k = 0; k < 2000; k++) {
      const d = randomDir(), a = shEval(e, d), b = quadraticEval(q, d);
      for (let c = 0; c < 3; c++) worst = Math.max(worst, Math.abs(a[c] - b[c]));
      assert.ok(Math.abs(a[0] - a[1]) < 1e-12 && Math.abs(a[0] - a[2]) < 1e-12, 'grey');
    }
    assert.ok(worst < 1e-9, `quadratic against SH: ${worst}`);
    // the mean radiance: e00 Y00 = the image's integral over 4 pi
    let integral = 0;
    for (let j = 0; j < 64; j++)
      for (let i = 0; i < 128; i++)
        integral += img.data[3 * (j * 128 + i)] * (2 * Math.PI / 128) * (Math.cos(Math.PI * j / 64) - Math.cos(Math.PI * (j + 1) / 64));
    assert.ok(Math.abs(e[0] * 0.282095 - integral / (4 * Math.PI)) < 1e-5);
    console.log(`# studio: c0 ${q.c0[0].toFixed(4)}, a ${q.a[0].map((v) => v.toFixed(4)).join(' ')}`);
  });

  it('a constant environment L = 1 is c0 = 1, a = 0, Q = 0', () => {
    const q = envQuadratic(imageOf(128, 64, () => [1, 1, 1])); // the studio's size
    for (let c = 0; c < 3; c++) {
      assert.ok(Math.abs(q.c0[c] - 1) < 1e-3, `c0 ${q.c0[c]}`);
      assert.ok(q.a[c].every((v) => Math.abs(v) < 1e-3), `a ${q.a[c]}`);
      assert.ok(q.q[c].flat().every((v) => Math.abs(v) < 1e-3), `Q ${q.q[c].flat()}`);
    }
  });

  it('the light cells tile the hemisphere (solid angles sum to 2 pi)', () => {
    const L = uboLights(), M = lightCells(L);
    assert.equal(L.length, 81);
    let sum = 0, z = 0;
    for (let i = 0; i < 81; i++) {
      sum += M[9 * i];
      z += M[9 * i + 3];
      assert.ok(M[9 * i] > 0, `cell ${i} is not empty`);
    }
    assert.ok(Math.abs(sum - 2 * Math.PI) < 1e-9, `sum ${sum}`);
    assert.ok(Math.abs(z - Math.PI) < 1e-3, `the integral of z over the hemisphere is pi: ${z}`);
    // the normal's cell holds the first band of samples (z > 0.984; the next band, at 12.4
    // degrees, is nearer the 15-degree ring)
    assert.ok(Math.abs(M[0] - 2 * Math.PI / 64) < 1e-12, `top cell ${M[0]}`);
  });

  it('G: a Lambertian material under L = 1 gives its albedo', () => {
    const L = uboLights(), M = lightCells(L), V = 2;
    const w = new Float32Array(V * 81 * 3);
    for (let v = 0; v < V; v++) for (let i = 0; i < 81; i++) for (let c = 0; c < 3; c++) w[3 * (v * 81 + i) + c] = [0.8, 0.5, 0.2][c] * L[i][2];
    const {g: G, big} = envWeights(M, w, 81, V);
    assert.ok(big >= Math.max(...G.map(Math.abs)) * (1 - 1e-6));
    // E = (c0 + Q'zz, ...) of L = 1: E_0 = 1, the rest 0: the pixel is G_0, the albedo up to
    // the cells' own error (each cell takes cos(theta) of its light: 75 degrees for the
    // cells down to the horizon, where the mean is lower): 5.6% here
    for (let c = 0; c < 3; c++) {
      const rel = G[27 + c] / [0.8, 0.5, 0.2][c] - 1;
      assert.ok(rel > 0 && rel < 0.07, `channel ${c}: ${G[27 + c]}`);
    }
  });

  it('rotation by 90 degrees about +z maps a lobe at +x to +y', () => {
    const lobe = (d) => {
      const t = Math.max(0, d[0]);
      return [t * t * 3, t * t, 0];
    };
    const q = envQuadratic(imageOf(128, 64, lobe)), r = rotateQuadratic(q, rotationZ(90));
    const at = (quad, d) => quadraticEval(quad, d);
    assert.ok(at(q, [1, 0, 0])[0] > 1 && at(q, [1, 0, 0])[0] > 4 * Math.abs(at(q, [0, 1, 0])[0]));
    for (const d of [[1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0], [0, 0, 1]]) {
      const turned = [-d[1], d[0], d[2]]; // Rz(90) d
      const a = at(q, d), b = at(r, turned);
      for (let c = 0; c < 3; c++) assert.ok(Math.abs(a[c] - b[c]) < 1e-9, `L_rot(Rz d) = L(d) at ${d}`);
    }
    assert.ok(at(r, [0, 1, 0])[0] > 4 * Math.abs(at(r, [1, 0, 0])[0]), 'the lobe is at +y now');
    // the uniforms: u_env_a column ch = a of channel ch, u_env_q column-major
    const u = envUniforms(r);
    assert.deepEqual([...u.a.subarray(0, 3)], [...Float32Array.from(r.a[0])]);
    assert.equal(u.q[3 * 1 + 0], Math.fround(r.q[0][0][1]));
  });
});
