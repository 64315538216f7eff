// tangents.test.mjs - the tangents both hosts generate for a model without TANGENT
// (shaders/host/btf_gltf_tangent.c; client/btf-gltf.js ports it line for line)
// against MikkTSpace itself: the reference implementation compiled to WebAssembly
// (npm mikktspace), run on the same world-space triangles, its sign negated for
// glTF's uv convention (v along image rows) as glTF readers do.
//
// The rule is MikkTSpace's (per triangle the u direction, projected into each
// corner's tangent plane, summed by corner angle over the triangles that share a
// vertex and a handedness); what can differ is float32 against double arithmetic
// and MikkTSpace's welding of vertices by value. 0.1 degrees bounds that with room
// (measured: at most 0.016); the handedness must agree at every corner.
import { describe, it } from 'node:test';
import assert from 'node:assert/strict';
import { execFileSync } from 'node:child_process';
import { mkdtempSync, readFileSync, rmSync } from 'node:fs';
import { createRequire } from 'node:module';
import { tmpdir } from 'node:os';
import path from 'node:path';
import { parseModel } from '../../client/btf-gltf.js';
import { varietyModel } from './gltf-fixtures.mjs';

const require = createRequire(import.meta.url);
const { generateTangents } = require('mikktspace');
const BUILD = process.env.BTF_BUILD || path.resolve('build');
const F = 12; // floats per baked vertex: position 3, normal 3, tangent 4, uv 2
const MAX_DEG = 0.1;

// Every corner of every part without TANGENT: the angle between the baked tangent
// and MikkTSpace's, and whether the handedness agrees.
function compare(model) {
  let corners = 0, worst = 0, flips = 0;
  for (const p of model.parts) {
    if (p.tangentsGiven || !p.hasUv) continue;
    const v = p.vertices, idx = p.indices, n = idx.length;
    const pos = new Float32Array(n * 3), nrm = new Float32Array(n * 3), uv = new Float32Array(n * 2);
    for (let i = 0; i < n; i++) {
      const o = idx[i] * F;
      for (let c = 0; c < 3; c++) pos[i * 3 + c] = v[o + c], nrm[i * 3 + c] = v[o + 3 + c];
      uv[i * 2] = v[o + 10], uv[i * 2 + 1] = v[o + 11];
    }
    const t = generateTangents(pos, nrm, uv);
    for (let i = 0; i < n; i++) {
      const o = idx[i] * F;
      const d = t[i * 4] * v[o + 6] + t[i * 4 + 1] * v[o + 7] + t[i * 4 + 2] * v[o + 8];
      const l = Math.hypot(t[i * 4], t[i * 4 + 1], t[i * 4 + 2]);
      worst = Math.max(worst, (Math.acos(Math.min(1, d / l)) * 180) / Math.PI);
      flips += -t[i * 4 + 3] !== v[o + 9];
      corners++;
    }
  }
  return { corners, worst, flips };
}

describe('generated tangents against MikkTSpace (npm mikktspace, WebAssembly)', () => {
  it('the stool of btf gen-model: band and legs', async () => {
    const dir = mkdtempSync(path.join(tmpdir(), 'btf-tangents-'));
    try {
      for (const seg of [6, 48]) {
        const file = path.join(dir, `stool${seg}.glb`);
        execFileSync(path.join(BUILD, 'btf'), ['gen-model', file, '--segments', String(seg)]);
        const r = compare(await parseModel(new Uint8Array(readFileSync(file)), { name: file }));
        console.log(`stool ${seg} segments: ${r.corners} corners, at most ${r.worst.toFixed(4)} degrees from MikkTSpace`);
        assert.ok(r.corners >= 5 * 6 * seg, `${seg} segments: only ${r.corners} corners compared`);
        assert.ok(r.worst <= MAX_DEG, `${seg} segments: ${r.worst.toFixed(4)} degrees from MikkTSpace`);
        assert.equal(r.flips, 0, `${seg} segments: handedness differs at ${r.flips} corners`);
      }
    } finally {
      rmSync(dir, { recursive: true, force: true });
    }
  });

  // Tangents are made in mesh space (as an exporter makes them) and then transformed,
  // so the reference, run here on world-space triangles, is the same rule only under
  // rigid and uniformly scaled nodes: the variety model's non-uniform root scale is
  // made uniform for this comparison (its other nodes mirror, turn and scale uniformly).
  it('a mirrored uv seam, a mirroring node and normalized uvs (the variety model)', async () => {
    const d = varietyModel();
    const root = d.doc.nodes.find((n) => n.name === 'root');
    root.scale = [1.25, 1.25, 1.25];
    const r = compare(await parseModel(d.glb(), { name: 'variety' }));
    console.log(`variety: ${r.corners} corners, at most ${r.worst.toFixed(4)} degrees from MikkTSpace`);
    assert.ok(r.corners > 0);
    assert.ok(r.worst <= MAX_DEG, `${r.worst.toFixed(4)} degrees from MikkTSpace`);
    assert.equal(r.flips, 0, `handedness differs at ${r.flips} corners`);
  });
});
