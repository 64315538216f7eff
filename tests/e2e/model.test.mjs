// model.test.mjs - glTF models in the client (issue 32): client/btf-gltf.js in node
// against the stool `btf gen-model` writes (its formulas, recomputed here), the variety
// model and the hostile set of gltf-fixtures.mjs; then <btf-viewer model materials> in
// headless Chromium against a real btfd: the stool with its materials bound, equal to
// `btf render --model --bind` of the same scene within 2/255 on >= 99% of covered
// pixels (as crosscheck.mjs does for the built-in surfaces), an unbound part in its
// base colour (btf_flat.frag's formula), the camera framing, one `error` event per bad
// model, the scene budget per material, and the frame time against the sphere.
// Run: node --test tests/e2e/model.test.mjs (after make build)
import assert from 'node:assert/strict';
import {spawnSync} from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import {after, before, describe, it} from 'node:test';
import {BTF, assertClean, capture, launch, makeLibrary, newPage, readPng, requireBuild, startServer, viewers,
  waitFor} from './util.mjs';
import {hostileModels, varietyModel} from './gltf-fixtures.mjs';

const gltf = await import('../../client/btf-gltf.js');
const {frameModel} = await import('../../client/btf-model.js');

// 32x32 texels: version 2 (3 spatial levels: the scene budget) and version 1 packages.
const MATERIALS = {'knit-lod': ['knit', 6, 3], 'tiles-lod': ['tiles', 6, 3], 'stone-lod': ['stone', 4, 3],
  knit: ['knit', 4], tiles: ['tiles', 4]};
let lib, server, desktop, dir, stool;

const hasGenModel = () => {
  const r = spawnSync(BTF, ['gen-model', '--help'], {encoding: 'utf8'});
  return !r.error && /gen-model/.test(`${r.stdout}${r.stderr}`) && !/unknown (sub)?command/i.test(`${r.stdout}${r.stderr}`);
};

before(async () => {
  requireBuild();
  assert.ok(hasGenModel(), `${BTF} has no gen-model command: run make build`);
  lib = makeLibrary(MATERIALS);
  dir = lib.dir;
  const r = spawnSync(BTF, ['gen-model', path.join(dir, 'stool.glb')], {encoding: 'utf8'});
  assert.equal(r.status, 0, r.stderr);
  stool = fs.readFileSync(path.join(dir, 'stool.glb'));
  server = await startServer(lib.lib);
  desktop = await launch();
  await desktop.addInitScript(() => {
    window.__btfCache = false; // every page streams from a cold start
    window.__errors = [];
    document.addEventListener('error', (e) => e.detail && window.__errors.push(e.detail));
  });
});

after(async () => {
  await desktop?.close();
  await server?.stop();
  lib?.remove();
});

// The models the pages load, served under .../models/NAME by the page's routes.
const MODELS = new Map();
async function modelPage(viewport = {width: 500, height: 500}) {
  const page = await newPage(desktop);
  await page.setViewportSize(viewport);
  if (!page.modelsRouted) {
    await page.route('**/models/**', (route) => {
      const name = decodeURIComponent(new URL(route.request().url()).pathname.split('/models/')[1]);
      const body = MODELS.get(name);
      return body ? route.fulfill({body, contentType: 'model/gltf-binary'}) : route.fulfill({status: 404, body: ''});
    });
    page.modelsRouted = true;
  }
  return page;
}

const open = (page, q) => page.goto(`${server.pagesUrl}viewer.html?light=fixed&max-dpr=1&${q}`);
const drawnAll = () => {
  const v = window.__btf && window.__btf.viewers()[0];
  return v && (v.error || (v.complete && v.frames > 0 && v.drawnChunks === v.ownLimit && v.ownLimit > 0));
};

// ------------------------------------------------------------------ node: the loader

// The stool's legs from the formulas of bench/gen/btf_gen_stool.c: an open tube of
// radius 0.035 around +y from y 0 to 0.43 (glTF axes), under its leg node and the root
// node of the file (rotations and scale applied here by quaternion, not by matrices as
// the loaders do), in world axes (x, -z, y): the position and the tangent (the
// direction of increasing u, the angle) of the vertex at angle a and height y.
function rot(q, v) {
  const c = [q[1] * v[2] - q[2] * v[1], q[2] * v[0] - q[0] * v[2], q[0] * v[1] - q[1] * v[0]];
  const cc = [q[1] * c[2] - q[2] * c[1], q[2] * c[0] - q[0] * c[2], q[0] * c[1] - q[1] * c[0]];
  return v.map((x, k) => x + 2 * q[3] * c[k] + 2 * cc[k]);
}
function stoolLeg(doc, i, a, y) {
  const root = doc.nodes[doc.scenes[doc.scene ?? 0].nodes[0]], leg = doc.nodes[root.children.filter((c) =>
    doc.nodes[c].mesh === 1)[i]];
  const toWorld = (v) => [v[0], -v[2], v[1]], sc = root.scale || [1, 1, 1], tl = leg.translation || [0, 0, 0];
  const p = rot(leg.rotation, [0.035 * Math.cos(a), y, 0.035 * Math.sin(a)]).map((x, k) => x + tl[k]);
  return {p: toWorld(rot(root.rotation, p.map((x, k) => sc[k] * x))),
    t: toWorld(rot(root.rotation, rot(leg.rotation, [-Math.sin(a), 0, Math.cos(a)])))};
}
const glbJson = (b) => JSON.parse(b.subarray(20, 20 + b.readUInt32LE(12)).toString());

describe('btf-gltf.js (node)', () => {
  it('bakes the stool as btf_gltf.cpp does: parts, materials, node transforms, generated tangents', async () => {
    const m = await gltf.parseModel(stool, {name: 'stool.glb'});
    assert.deepEqual(m.parts.map((p) => p.material), ['Seat', 'Trim', 'Frame', 'Frame', 'Frame', 'Frame']);
    assert.deepEqual(m.parts.map((p) => p.tangentsGiven), [true, false, false, false, false, false]);
    assert.ok(m.parts.every((p) => p.hasUv));
    assert.deepEqual(m.parts[0].baseColor, [0.8, 0.25, 0.2, 1].map(Math.fround));
    // the legs: one mesh under four nodes, u8 indices; each vertex where the formulas put
    // it, its generated tangent the formula's (MikkTSpace averages the two faces around
    // a vertex, weighted by their unequal corner angles: within 0.1 degree; at the seam
    // a vertex has faces on one side: half a segment off), handedness -1
    // (v grows down the leg, cross(normal, tangent) points down: towards increasing v)
    const S = 48, doc = glbJson(stool);
    for (let i = 0; i < 4; i++) {
      const v = m.parts[2 + i].vertices;
      assert.equal(v.length / 12, 2 * (S + 1));
      for (let k = 0; k < 2; k++)
        for (let j = 0; j <= S; j++) {
          const o = (k * (S + 1) + j) * 12, f = stoolLeg(doc, i, 2 * Math.PI * j / S, k ? 0 : 0.43);
          for (let c = 0; c < 3; c++) assert.ok(Math.abs(v[o + c] - f.p[c]) < 1e-6, `leg ${i} vertex ${j} position`);
          const cos = f.t[0] * v[o + 6] + f.t[1] * v[o + 7] + f.t[2] * v[o + 8];
          const seam = j === 0 || j === S;
          assert.ok(cos > Math.cos((seam ? 180 / S + 0.1 : 0.1) * Math.PI / 180), `leg ${i} vertex ${j}: tangent cos ${cos}`);
          assert.equal(v[o + 9], -1, 'handedness');
        }
    }
    // the framing of btf_scene_frame: the bounds' centre and half diagonal
    const f = frameModel(m.min, m.max, 40);
    const r = Math.hypot(...[0, 1, 2].map((c) => (m.max[c] - m.min[c]) / 2));
    assert.ok(Math.abs(f.extent - r) < 1e-6 && Math.abs(f.cameraDist - 1.05 * r / Math.sin(20 * Math.PI / 180)) < 1e-5);
  });

  it('bakes the variety model: flat normals, no uv, mirrored nodes, normalized uvs, split tangents', async () => {
    const d = varietyModel();
    for (const bytes of [d.glb(), d.gltf()]) {
      const m = await gltf.parseModel(bytes, {name: 'variety'});
      assert.deepEqual(m.parts.map((p) => p.material), ['Skin', 'Bare', 'Skin', 'Bare', 'Flat', 'Cap']);
      assert.deepEqual(m.parts.map((p) => p.hasUv), [true, false, true, false, true, true]);
      assert.deepEqual(m.parts[5].baseColor, [1, 0, 0.5, 1], 'base colour clamped to 0..1');
      for (const p of m.parts) {
        const v = p.vertices;
        for (let o = 0; o < v.length; o += 12) {
          const n = Math.hypot(v[o + 3], v[o + 4], v[o + 5]), t = Math.hypot(v[o + 6], v[o + 7], v[o + 8]);
          assert.ok(Math.abs(n - 1) < 1e-6 && Math.abs(t - 1) < 1e-6, `${p.material}: unit normal and tangent`);
          assert.ok(Math.abs(v[o + 3] * v[o + 6] + v[o + 4] * v[o + 7] + v[o + 5] * v[o + 8]) < 1e-5,
            `${p.material}: tangent in the surface`);
          assert.ok(v[o + 9] === 1 || v[o + 9] === -1);
        }
        // every triangle faces its normals (a mirroring node turned it over)
        for (let t = 0; t < p.indices.length; t += 3) {
          const [a, b, c] = [0, 1, 2].map((k) => p.indices[t + k] * 12);
          const e1 = [0, 1, 2].map((k) => v[b + k] - v[a + k]), e2 = [0, 1, 2].map((k) => v[c + k] - v[a + k]);
          const fn = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
          assert.ok(fn[0] * v[a + 3] + fn[1] * v[a + 4] + fn[2] * v[a + 5] > 0, `${p.material} triangle ${t / 3} faces its normal`);
        }
      }
      // the grid's mirrored uv seam: both handednesses, so vertices were split
      const skin = m.parts[0], hands = new Set();
      for (let o = 9; o < skin.vertices.length; o += 12) hands.add(skin.vertices[o]);
      assert.deepEqual([...hands].sort(), [-1, 1]);
      assert.ok(skin.vertices.length / 12 > 49, 'split vertices');
      // flat normals: three vertices per triangle; u8 normalized uv k/255
      assert.equal(m.parts[4].vertices.length / 12, 9);
      assert.equal(m.parts[4].vertices[12 * 8 + 10], Math.fround(128 / 255));
    }
  });

  it('refuses hostile and unsupported files with a reason, allocating nothing from unchecked counts', async () => {
    for (const [name, bytes, why] of hostileModels(stool))
      await assert.rejects(gltf.parseModel(bytes, {name}), (e) => {
        assert.match(e.message, why, name);
        assert.ok(e.message.startsWith(`${name}: `), e.message);
        return true;
      });
    await assert.rejects(gltf.parseModel(Buffer.from(varietyModel().gltf().toString().replace('data:', 'buf.bin?')), {name: 'x'}),
      /only use data URIs|a file/);
  });

  it('survives random damage: a model or one clean error, never another exception (fuzz loop)', async () => {
    let seed = 32, ok = 0;
    const rnd = () => (seed = (seed * 1103515245 + 12345) & 0x7fffffff) / 0x7fffffff;
    const jlen = stool.readUInt32LE(12);
    for (let n = 0; n < 300; n++) {
      const b = Buffer.from(stool);
      for (let k = 1 + Math.floor(rnd() * 4); k > 0; k--) // mostly the JSON, sometimes the binary chunk
        b[Math.floor(rnd() * (rnd() < 0.7 ? 20 + jlen : b.length))] = Math.floor(rnd() * 256);
      try {
        const m = await gltf.parseModel(b, {name: 'fuzz'});
        assert.ok(m.parts.length > 0 && m.parts.every((p) => p.vertices.every(Number.isFinite)));
        ok++;
      } catch (e) {
        assert.ok(e instanceof Error && e.message.startsWith('fuzz: '), `${n}: ${e && e.stack}`);
      }
    }
    assert.ok(ok > 0 && ok < 300, `${ok} of 300 damaged files still load`);
  });

  it('parses bindings NAME:MATERIAL[:REPEAT] and binds parts as btf_scene_bind', async () => {
    assert.deepEqual(gltf.parseBindings('Seat:wool, Frame:impalla:2,*:knit:0.5'),
      [{name: 'Seat', id: 'wool', repeat: 1}, {name: 'Frame', id: 'impalla', repeat: 2}, {name: '*', id: 'knit', repeat: 0.5}]);
    assert.deepEqual(gltf.parseBindings('a:b:c:3,Odd%2CName:x'), [{name: 'a:b', id: 'c', repeat: 3}, {name: 'Odd,Name', id: 'x', repeat: 1}]);
    for (const bad of ['Seat', 'Seat:', ':wool', 'Seat:wool:0', 'Seat:wool:-1', 'A:x,A:y'])
      assert.throws(() => gltf.parseBindings(bad), /materials: /, bad);
    const m = await gltf.parseModel(stool, {name: 'stool.glb'});
    assert.deepEqual(gltf.bindParts(m, gltf.parseBindings('Seat:a,Frame:b')), [0, -1, 1, 1, 1, 1]);
    assert.deepEqual(gltf.bindParts(m, gltf.parseBindings('Seat:a,*:c')), [0, 1, 1, 1, 1, 1]);
    assert.throws(() => gltf.bindParts(m, gltf.parseBindings('Sofa:a')), /no material named "Sofa"/);
    const v = await gltf.parseModel(varietyModel().glb(), {name: 'variety'});
    assert.throws(() => gltf.bindParts(v, gltf.parseBindings('*:a')), /no TEXCOORD_0/);
  });
});

// ------------------------------------------------------------------ browser

// The browser's canvas against `btf render` (EGL) of the same model, bindings, camera
// and light: within 2/255 per channel on >= 99% of the pixels either covers.
function crossCheck(img, ref, what) {
  assert.deepEqual([img.width, img.height], [ref.width, ref.height]);
  let ok = 0, worst = 0, fg = 0;
  for (let i = 0; i < img.data.length; i += 4) {
    if (Math.abs(ref.data[i] - 31) <= 3 && Math.abs(img.data[i] - 31) <= 3) continue; // background in both
    fg++;
    const d = Math.max(...[0, 1, 2].map((c) => Math.abs(img.data[i + c] - ref.data[i + c])));
    worst = Math.max(worst, d);
    if (d <= 2) ok++;
  }
  assert.ok(fg > 0.2 * img.width * img.height, `${what}: the model covers ${fg} pixels`);
  assert.ok(ok / fg >= 0.99, `${what}: ${(100 * ok / fg).toFixed(2)}% of covered pixels within 2/255 (worst ${worst})`);
  console.log(`# ${what}: ${(100 * ok / fg).toFixed(2)}% of ${fg} covered pixels within 2/255, worst ${worst}`);
}

function btfRender(pkg, out, args) {
  const r = spawnSync(BTF, ['render', pkg === '-' ? pkg : path.join(lib.lib, pkg), out, '--model', path.join(dir, 'stool.glb'),
    '--backend', 'egl', ...args], {encoding: 'utf8'});
  assert.equal(r.status, 0, `btf render ${pkg} ${args.join(' ')} failed (${r.status} ${r.signal || ''}): ${r.stderr}`);
  return readPng(out);
}

const SIZE = 240;
const CAM = {theta: 55, phi: -70, light: [40, -40]};
const camQuery = `camera-theta=${CAM.theta}&camera-phi=${CAM.phi}&light-theta=${CAM.light[0]}&light-phi=${CAM.light[1]}` +
  `&width=${SIZE}&height=${SIZE}`;
const camArgs = ['--size', `${SIZE}x${SIZE}`, '--camera', `${CAM.theta},${CAM.phi}`, '--light', CAM.light.join(',')];

describe('<btf-viewer model> against btf render --model', () => {
  before(() => MODELS.set('stool.glb', stool));

  for (const [what, star, seat, frame] of [
    ['version-1 packages', 'tiles', 'knit', 'tiles'],
    ['version-2 packages (levels)', 'stone-lod', 'knit-lod', 'tiles-lod']]) {
    it(`three bindings, ${what}: equal within 2/255 on >= 99% of covered pixels`, async () => {
      const page = await modelPage();
      await open(page, `model=models/stool.glb&material=${star}&materials=Seat:${seat}:3,Frame:${frame}:8&budget-chunks=999&` +
        camQuery);
      await waitFor(page, drawnAll, null, 'the stool drawn');
      const v = (await viewers(page))[0];
      assert.equal(v.error, null);
      assert.deepEqual(v.model.partBind, [0, 2, 1, 1, 1, 1], 'Seat, Frame, and * (the material attribute) on the trim');
      const img = await capture(page, 0);
      const ref = btfRender(star, path.join(dir, `stool-${star}.png`), [...camArgs, '--bind', `Seat=${path.join(lib.lib, seat)},3`,
        '--bind', `Frame=${path.join(lib.lib, frame)},8`]);
      crossCheck(img, ref, `stool, ${what}`);
      assertClean(desktop);
    });
  }

  it('an unbound part draws in its base colour (btf_flat.frag), the rest as btf render', async () => {
    const page = await modelPage();
    await open(page, `model=models/stool.glb&materials=Seat:knit-lod:3,Frame:tiles-lod:8&budget-chunks=999&${camQuery}`);
    await waitFor(page, drawnAll, null, 'the stool drawn');
    const v = (await viewers(page))[0];
    assert.deepEqual(v.model.partBind, [0, -1, 1, 1, 1, 1], 'the trim unbound');
    const flat = await capture(page, 0);
    // the trim's pixels: where the picture differs from the trim bound to a package
    await open(page, `model=models/stool.glb&material=stone-lod&materials=Seat:knit-lod:3,Frame:tiles-lod:8&budget-chunks=999&` +
      camQuery);
    await waitFor(page, drawnAll, null, 'the stool drawn, trim bound');
    const bound = await capture(page, 0);
    const ref = btfRender('stone-lod', path.join(dir, 'stool-bound.png'), [...camArgs, '--bind',
      `Seat=${path.join(lib.lib, 'knit-lod')},3`, '--bind', `Frame=${path.join(lib.lib, 'tiles-lod')},8`]);
    const lin = (s) => (s <= 0.04045 ? s / 12.92 : ((s + 0.055) / 1.055) ** 2.4);
    const enc = (c) => 255 * (c <= 0.0031308 ? 12.92 * c : 1.055 * c ** (1 / 2.4) - 0.055);
    const base = [0.2, 0.2, 0.25].map(Math.fround); // the trim's baseColorFactor
    let trim = 0, shaded = 0, other = 0, same = 0, lit = 0;
    for (let i = 0; i < flat.data.length; i += 4) {
      const d = Math.max(...[0, 1, 2].map((c) => Math.abs(flat.data[i + c] - bound.data[i + c])));
      if (d > 2) { // the trim: u_base_color * (ambient + (1 - ambient) max(n.l, 0)), sRGB-encoded
        trim++;
        const k = lin(flat.data[i + 2] / 255) / base[2]; // from blue, the largest channel
        const pred = base.map((b) => enc(Math.min(1, b * k)));
        if (k >= 0.25 - 0.02 && k <= 1 + 0.02 && [0, 1, 2].every((c) => Math.abs(pred[c] - flat.data[i + c]) <= 2)) shaded++;
        if (k > 0.3) lit++;
      } else if (Math.abs(flat.data[i] - 31) > 3) {
        other++;
        if (Math.max(...[0, 1, 2].map((c) => Math.abs(flat.data[i + c] - ref.data[i + c]))) <= 2) same++;
      }
    }
    assert.ok(trim > 500, `the trim covers ${trim} pixels`);
    assert.ok(shaded >= 0.99 * trim, `${shaded} of ${trim} trim pixels are the base colour shaded by the flat rule`);
    assert.ok(lit > 0.5 * trim, 'the lit side of the trim is brighter than the ambient share');
    assert.ok(same >= 0.99 * other, `${same} of ${other} other pixels equal btf render's within 2/255`);
    console.log(`# unbound trim: ${trim} pixels in its base colour (${lit} lit), ${same}/${other} others as btf render`);
    // and the whole picture against btf render with no package on the trim (PACKAGE -)
    if (/PACKAGE - for none/.test(spawnSync(BTF, ['render', '--help'], {encoding: 'utf8'}).stdout)) {
      const none = btfRender('-', path.join(dir, 'stool-unbound.png'), [...camArgs, '--bind',
        `Seat=${path.join(lib.lib, 'knit-lod')},3`, '--bind', `Frame=${path.join(lib.lib, 'tiles-lod')},8`]);
      crossCheck(flat, none, 'stool, trim unbound (flat program)');
    }
    assertClean(desktop);
  });
});

describe('<btf-viewer model> in the page', () => {
  before(() => {
    MODELS.set('stool.glb', stool);
    MODELS.set('variety.glb', varietyModel().glb());
    for (const [name, bytes] of hostileModels(stool)) MODELS.set(`hostile/${name}`, bytes);
  });

  it('frames the model as btf_scene_frame; orbit, zoom and camera-* keep working', async () => {
    const page = await modelPage();
    await open(page, `model=models/stool.glb&materials=Seat:knit,Frame:tiles&width=300&height=300`);
    await waitFor(page, drawnAll, null, 'the stool drawn');
    const m = await gltf.parseModel(stool, {name: 'stool.glb'});
    const f = frameModel(m.min, m.max, 40);
    let v = (await viewers(page))[0];
    assert.deepEqual(v.camera, [-90, 30, f.cameraDist], 'the sphere\'s angles, the framing distance');
    const events = [];
    await page.exposeFunction('__cameraEvent', (d) => events.push(d)).catch(() => {});
    await page.evaluate(() => window.__btf.element(0).addEventListener('camera-change', (e) => window.__cameraEvent(e.detail)));
    const box = await page.evaluate(() => {
      const r = window.__btf.element(0).getBoundingClientRect();
      return {x: r.x + r.width / 2, y: r.y + r.height / 2};
    });
    await page.mouse.move(box.x, box.y);
    await page.mouse.down();
    await page.mouse.move(box.x + 60, box.y + 20, {steps: 4});
    await page.mouse.up();
    await page.keyboard.press('-');
    v = (await viewers(page))[0];
    assert.ok(v.camera[0] < -90 && v.camera[1] > 30 && v.camera[2] > f.cameraDist, JSON.stringify(v.camera));
    await page.evaluate(() => window.__btf.element(0).setAttribute('camera-dist', '4'));
    await waitFor(page, () => window.__btf.viewers()[0].camera[2] === 4, null, 'camera-dist');
    assert.ok(events.length >= 3, `camera-change events: ${events.length}`);
    assertClean(desktop);
  });

  it('draws a .gltf with its buffer beside it as the same .glb', async () => {
    const d = varietyModel(), bin = d.bin(), doc = structuredClone(d.doc);
    doc.buffers[0].uri = 'variety%20data.bin';
    MODELS.set('variety.gltf', Buffer.from(JSON.stringify(doc)));
    MODELS.set('variety data.bin', Buffer.from(bin));
    const page = await modelPage();
    const shots = [];
    for (const file of ['variety.glb', 'variety.gltf']) {
      await open(page, `model=models/${file}&materials=Skin:knit:2,Cap:tiles&budget-chunks=999&width=200&height=200`);
      await waitFor(page, drawnAll, null, file);
      const v = (await viewers(page))[0];
      assert.deepEqual(v.model.partBind, [0, -1, 0, -1, -1, 1], `${file}: Skin and Cap bound, the rest flat`);
      shots.push(await capture(page, 0));
    }
    assert.deepEqual(shots[1].data, shots[0].data, 'the same picture');
    assertClean(desktop);
  });

  it('survives a lost WebGL context: packages and meshes rebuilt, the same picture', async () => {
    const page = await modelPage();
    await open(page, 'model=models/stool.glb&materials=Seat:knit:2,Frame:tiles:4&width=200&height=200');
    await waitFor(page, drawnAll, null, 'the stool drawn');
    const before = await capture(page, 0), n = (await viewers(page))[0].uploaded;
    await page.evaluate(() => {
      window.__lose = window.__btf.element(0).gl.getExtension('WEBGL_lose_context');
      window.__lose.loseContext();
    });
    await waitFor(page, () => window.__btf.viewers()[0].lost, null, 'context lost');
    await page.evaluate(() => window.__lose.restoreContext());
    await waitFor(page, (k) => !window.__btf.viewers()[0].lost && window.__btf.viewers()[0].uploaded === k, n,
      'context restored');
    const after = await capture(page, 0);
    assert.deepEqual(after.data, before.data, 'the same picture after the restore');
    assertClean(desktop);
  });

  it('gives one error event with a reason per bad model or binding, and recovers with a good one', async () => {
    const page = await modelPage();
    await open(page, 'model=models/stool.glb&materials=Seat:knit,Frame:tiles&width=200&height=200');
    await waitFor(page, drawnAll, null, 'the stool drawn');
    const cases = hostileModels(stool).map(([name, , why]) => [`models/hostile/${name}`, 'Seat:knit', why]);
    cases.push(['models/variety.glb', 'Bare:knit', /no TEXCOORD_0/], ['models/stool.glb', 'Sofa:knit', /no material named "Sofa"/],
      ['models/stool.glb', 'Seat', /not NAME:MATERIAL/], ['models/missing.glb', 'Seat:knit', /cannot load .*HTTP 404/],
      ['models/stool.glb', 'Seat:no-such-material', /^no-such-material: .*unknown_material/]);
    for (const [url, materials, why] of cases) {
      await page.evaluate(() => { window.__errors = []; });
      await page.evaluate(([u, b]) => {
        const el = window.__btf.element(0);
        el.setAttribute('materials', b);
        el.setAttribute('model', u);
      }, [url, materials]);
      await waitFor(page, () => window.__errors.length > 0, null, `the error of ${url}`, 20000);
      await new Promise((r) => setTimeout(r, 300));
      const errs = await page.evaluate(() => window.__errors);
      assert.equal(errs.length, 1, `${url} ${materials}: one error event, got ${JSON.stringify(errs)}`);
      assert.match(errs[0].reason, why, url);
      assert.ok(!errs[0].retrying, 'final');
      const v = (await viewers(page))[0];
      assert.equal(v.message, errs[0].reason, 'the reason over the viewer');
    }
    await page.evaluate(() => {
      window.__errors = [];
      const el = window.__btf.element(0);
      el.setAttribute('materials', 'Seat:knit,Frame:tiles');
      el.setAttribute('model', 'models/stool.glb');
    });
    await waitFor(page, drawnAll, null, 'the stool again');
    assert.deepEqual(await page.evaluate(() => window.__errors), []);
    // the only console errors are the browser's own report of the 404
    const problems = desktop.problems.splice(0).filter((p) => !/404/.test(p));
    assert.deepEqual(problems, []);
  });

  it('streams each material as far as the pixels it covers can show (the scene budget)', async () => {
    const page = await modelPage({width: 700, height: 700});
    const full = Object.fromEntries((await (await fetch(`${server.url}materials`)).json()).materials
      .map((m) => [m.name, m.bytes]));
    const runs = [];
    for (const size of [160, 600]) {
      await open(page, `model=models/stool.glb&materials=Seat:knit-lod:3,Frame:tiles-lod:8&width=${size}&height=${size}`);
      await waitFor(page, drawnAll, null, `the ${size}-px stool drawn with its scene budget`);
      const v = (await viewers(page))[0];
      const subs = (await page.evaluate(() => window.__btf.streams()))[0].subscriptions;
      for (const f of v.feeds) {
        // the footprint from the covered pixels, lodSelect of it, the server's prefix
        assert.ok(f.cover.pixels > 0 && f.cover.ppr > 0, JSON.stringify(f.cover));
        const tpp = 32 / f.cover.ppr;
        assert.ok(Math.abs(f.footprint - tpp) < 1e-9, `${f.material}: footprint ${f.footprint}, 32 texels / ${f.cover.ppr} px`);
        assert.equal(f.scene.level, tpp >= 4 ? 2 : tpp >= 2 ? 1 : 0, `${f.material}: the level its footprint resolves`);
        const sub = subs.find((s) => s.material === f.material);
        assert.equal(sub.limit, f.scene.limit, `${f.material}: the server granted the scene budget`);
        assert.equal(f.received, f.scene.limit);
        assert.equal(f.streamBytes, f.scene.bytes, `${f.material}: exactly the budgeted bytes`);
      }
      runs.push({size, v});
    }
    const [small, large] = runs.map((r) => r.v);
    const fullBytes = small.feeds.reduce((a, f) => a + full[f.material], 0);
    assert.ok(small.streamBytes < large.streamBytes && large.streamBytes <= fullBytes);
    assert.ok(small.streamBytes < fullBytes, 'the small view does not need both whole packages');
    for (const {size, v} of runs)
      console.log(`# scene budget, stool ${size} px (Seat knit-lod x3, Frame tiles-lod x8): ` + v.feeds.map((f) =>
        `${f.material} covers ${Math.round(f.cover.pixels)} px, ${f.cover.ppr.toFixed(1)} px/repeat -> level ` +
        `${f.scene.level}, ${f.scene.components} components, ${f.scene.limit}/${f.manifestChunks} chunks, ` +
        `${f.streamBytes} B`).join('; ') + `; scene ${v.streamBytes} B of ${fullBytes} B (both whole packages)`);
    assertClean(desktop);
  });

  it('measures the frame time of the two-material stool against the sphere (recorded, not judged)', async () => {
    const page = await modelPage({width: 500, height: 500});
    // ms per frame (each waited for) and the share of the view the objects cover
    const time = async (q) => {
      await open(page, `${q}&width=320&height=320&budget-chunks=999`);
      await waitFor(page, drawnAll, null, q);
      await page.evaluate(() => window.__btf.bench(0, 2)); // warm
      const ms = await page.evaluate(() => window.__btf.bench(0, 8)), img = await capture(page, 0);
      let fg = 0;
      for (let i = 0; i < img.data.length; i += 4) if (Math.abs(img.data[i] - 31) > 3) fg++;
      return {ms, cover: fg / (img.width * img.height)};
    };
    const a = await time('material=knit-lod&geometry=sphere');
    const m = await time('model=models/stool.glb&materials=Seat:knit-lod:3,Frame:tiles-lod:8');
    const b = await time('material=knit-lod&geometry=sphere');
    const s = (a.ms + b.ms) / 2, model = m.ms;
    console.log(`# frame time at 320x320 (SwiftShader, same run): sphere (knit-lod) ${s.toFixed(1)} ms covering ` +
      `${(100 * a.cover).toFixed(0)}% of the view, stool (Seat knit-lod, Frame tiles-lod, trim flat) ${model.toFixed(1)} ms ` +
      `covering ${(100 * m.cover).toFixed(0)}%; ratio ${(model / s).toFixed(2)}, per covered pixel ` +
      `${((model / m.cover) / (s / a.cover)).toFixed(2)}`);
    assert.ok(model > 0 && s > 0);
    assertClean(desktop);
  });

  it('the product page shows the stool with two materials', async () => {
    const page = await modelPage({width: 900, height: 800});
    await page.goto(`${server.pagesUrl}product.html?model=models/stool.glb&seat=knit-lod&frame=tiles-lod`);
    await waitFor(page, drawnAll, null, 'the product viewer');
    const v = (await viewers(page))[0];
    assert.equal(v.error, null);
    assert.deepEqual(v.feeds.map((f) => f.material), ['knit-lod', 'tiles-lod']);
    assert.match(await page.textContent('#snippet'), /model="models\/stool.glb" materials="Seat:knit-lod:2,Frame:tiles-lod:6"/);
    await page.selectOption('#frame', 'stone-lod');
    await waitFor(page, () => {
      const s = window.__btf.viewers()[0];
      return s.feeds && s.feeds.some((f) => f.material === 'stone-lod') && s.complete && s.drawnChunks === s.ownLimit;
    }, null, 'another frame material');
    assertClean(desktop);
  });
});
