// crosscheck.mjs - the browser's canvas against `btf render` (EGL, the headless C
// harness) for the same package, surface, camera and light: equal within 2/255 per
// channel on >= 99% of pixels. Loaded by client.test.mjs only when build/btf has
// the `render` command.
import {spawnSync} from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import {BTF, capture, newPage, readPng, waitFor} from './util.mjs';

// Each geometry with its own camera and light; chunks = a partial package.
const SCENES = [
  {material: 'knit', geometry: 'plane', w: 200, h: 150, camera: [35, -90, 3], light: [40, -60], fov: 40, chunks: 3},
  {material: 'tiles', geometry: 'sphere', w: 160, h: 160, camera: [60, -70, 3.6], light: [45, -50], fov: 40, chunks: 2},
  {material: 'stone', geometry: 'cylinder', w: 160, h: 120, camera: [50, -100, 3.6], light: [30, 20], fov: 40,
    chunks: 3},
  // one block of every view (k 81): a single texture tile per component
  {material: 'tiles-k81', geometry: 'sphere', w: 160, h: 160, camera: [50, -40, 3.6], light: [35, 60], fov: 40,
    chunks: 3},
  // an explicit direction list: the manifest's triangles, mirror images near the horizon
  {material: 'tiles-list', geometry: 'sphere', w: 160, h: 160, camera: [55, -80, 3.6], light: [70, 30], fov: 40,
    chunks: 4},
  // version 2 (spatial levels, shaders/README.md): a coarse prefix (mip levels, 8-bit
  // weights) and the whole package (trilinear between levels, 16-bit weights)
  {material: 'tiles-lod', geometry: 'plane', w: 200, h: 150, camera: [55, -90, 3], light: [40, -60], fov: 40,
    chunks: 5, repeat: 4},
  {material: 'tiles-lod', geometry: 'plane', w: 200, h: 150, camera: [55, -90, 3], light: [40, -60], fov: 40,
    chunks: 18, repeat: 4},
  // portrait: the field of view spans the width (the narrower side)
  {material: 'knit', geometry: 'plane', w: 120, h: 200, camera: [30, -90, 3.5], light: [45, -50], fov: 40, chunks: 3},
];

export async function crossCheck(ctx, server, lib, assert) {
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'btf-xcheck-'));
  const page = await newPage(ctx);
  await page.setViewportSize({width: 400, height: 400});
  try {
    for (const s of SCENES) {
      const out = path.join(dir, `${s.material}-${s.geometry}-${s.chunks}.png`);
      const args = ['render', path.join(lib, s.material), out, '--size', `${s.w}x${s.h}`, '--geometry', s.geometry,
        '--camera', s.camera.join(','), '--fov', String(s.fov), '--light', s.light.join(','),
        '--chunks', String(s.chunks), '--backend', 'egl', ...(s.repeat ? ['--repeat', String(s.repeat)] : [])];
      const r = spawnSync(BTF, args, {encoding: 'utf8'});
      assert.equal(r.status, 0, `btf ${args.join(' ')} failed: ${r.stderr}`);
      const ref = readPng(out);
      await page.goto(`${server.pagesUrl}viewer.html?material=${s.material}&geometry=${s.geometry}&light=fixed` +
        `&light-theta=${s.light[0]}&light-phi=${s.light[1]}&camera-theta=${s.camera[0]}&camera-phi=${s.camera[1]}` +
        `&camera-dist=${s.camera[2]}&fov=${s.fov}&budget-chunks=${s.chunks}&width=${s.w}&height=${s.h}&max-dpr=1` +
        (s.repeat ? `&repeat=${s.repeat}` : ''));
      await waitFor(page, (n) => window.__btf.viewers()[0]?.drawnChunks === n, s.chunks, 'the browser frame');
      const img = await capture(page, 0);
      assert.deepEqual([img.width, img.height], [ref.width, ref.height]);
      let ok = 0, worst = 0, fg = 0;
      for (let i = 0; i < img.data.length; i += 4) {
        const d = Math.max(...[0, 1, 2].map((c) => Math.abs(img.data[i + c] - ref.data[i + c])));
        worst = Math.max(worst, d);
        if (d <= 2) ok++;
        if (Math.abs(ref.data[i] - 31) > 3) fg++;
      }
      const frac = ok / (img.width * img.height);
      // the object must cover a good part of the frame, or equality proves little
      assert.ok(fg > 0.2 * img.width * img.height, `${s.material} ${s.geometry}: the object covers ${fg} pixels`);
      assert.ok(frac >= 0.99, `${s.material} ${s.geometry}: ${(100 * frac).toFixed(2)}% of pixels within 2/255 (worst ${worst})`);
      results.push({geometry: `${s.material} ${s.geometry} ${s.chunks} chunks`, frac, worst});
    }
    return results;
  } finally {
    fs.rmSync(dir, {recursive: true, force: true});
  }
}

const results = [];
