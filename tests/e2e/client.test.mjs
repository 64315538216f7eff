// client.test.mjs - the WebGL2 client (client/) in headless Chromium against a real
// btfd serving a small library made by the built tools. Run: node --test tests/e2e/
// Every page must load without a page error or a console error.
// Two pictures of the docs come from here (doc/figures/gallery.png, chunks-1-vs-all.png):
// written there only when BTF_FIGURES_OUT names that folder (`make figure` does), else
// into a scratch folder, so a test run leaves the source tree as it was.
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import {after, before, describe, it} from 'node:test';
import {ROOT, assertClean, capture, hasRender, launch, makeLibrary, meanAbsDiff, newPage, requireBuild, sideBySide,
  writeSpiralList,
  startServer, viewers, waitFor, writePng} from './util.mjs';
import os from 'node:os';

const FIGURES = process.env.BTF_FIGURES_OUT || fs.mkdtempSync(path.join(os.tmpdir(), 'btf-figures-'));
if (!process.env.BTF_FIGURES_OUT) after(() => fs.rmSync(FIGURES, {recursive: true, force: true}));

// 32x32 texels, 81 x 81 directions: knit with 6 chunks (progressive capture after
// 1, 2, 4, all), tiles and stone with 3 (three different materials on the embed page);
// tiles-lod: version 2 with 3 spatial levels (scene budgets; sorts last, so the embed
// page's first three materials stay version 1).
// tiles-list: an explicit direction list (a spiral, not rings; doc/data-model.md); sorts
// between tiles and tiles-lod. tiles-k81: one block of every view (k 81, one texture
// tile a component), what a budget search chooses on generated materials; sorts
// between tiles and tiles-list.
const LIST = writeSpiralList(48, 11);
const MATERIALS = {knit: ['knit', 6], 'tiles-list': ['tiles', 4, 0, [], ['--sampling', LIST]], tiles: ['tiles', 3],
  'tiles-k81': ['tiles', 3, 0, ['--k', '81']], stone: ['stone', 3], 'tiles-lod': ['tiles', 6, 3]};
let lib, server, desktop;

before(async () => {
  requireBuild();
  lib = makeLibrary(MATERIALS);
  server = await startServer(lib.lib);
  desktop = await launch();
  // these tests count what streams from a cold start: no chunks kept between pages (btf-cache.js)
  await desktop.addInitScript(() => { window.__btfCache = false; });
});

after(async () => {
  await desktop?.close();
  await server?.stop();
  lib?.remove();
});

const allDrawn = (vs) => vs.length > 0 && vs.every((v) => v.error === null && v.drawnChunks > 0 &&
  v.drawnChunks === v.ownLimit && v.frames > 0);

describe('gallery (index.html)', () => {
  it('lists every material with its size and opens a large viewer', async () => {
    const page = await newPage(desktop);
    await page.setViewportSize({width: 860, height: 560});
    await page.goto(`${server.pagesUrl}index.html`);
    await page.waitForSelector('#grid .card');
    const cards = await page.$$eval('#grid .card', (els) => els.map((e) => e.textContent));
    assert.equal(cards.length, Object.keys(MATERIALS).length);
    for (const name of Object.keys(MATERIALS))
      assert.ok(cards.some((t) => t.includes(name) && /32×32 texels/.test(t) && /KB/.test(t)), `card of ${name}`);
    // no thumbnails in this library: each card shows a live viewer of the first chunk
    // (version 1) or of its scene budget (version 2)
    await waitFor(page, () => window.__btf.viewers().every((v) => v.drawnChunks === (v.version >= 2 ?
      v.scene.limit : 1) && v.frames > 0 && (v.version < 2 || v.complete)), null, 'the thumbnail viewers');
    const vs = await viewers(page);
    const v1 = vs.filter((v) => v.version === 1), v2 = vs.filter((v) => v.version === 2);
    assert.equal(v2.length, 1, JSON.stringify(vs));
    assert.ok(v1.every((v) => v.budget.chunks === 1 && v.received === 1), JSON.stringify(v1));
    const t = v2[0], full = (await (await fetch(`${server.url}materials`)).json()).materials
      .find((m) => m.name === 'tiles-lod');
    assert.ok(t.scene.limit >= 1 && t.budget.chunks === t.scene.limit && t.received === t.scene.limit,
      `the version-2 thumbnail asks for and receives its scene budget: ${JSON.stringify(t)}`);
    const sent = (await page.evaluate(() => window.__btf.streams()))[0].subscriptions
      .find((s) => s.material === 'tiles-lod');
    assert.equal(sent.budget.chunks, t.scene.limit, 'the server is asked for the scene budget');
    assert.ok(t.streamBytes <= t.scene.bytes && t.streamBytes <= full.bytes, JSON.stringify(t));
    console.log(`# gallery thumbnail of tiles-lod (v2, ${t.cssWidth} CSS px): level ${t.scene.level}, ` +
      `${t.received}/${t.manifestChunks} chunks, ${t.streamBytes} of ${full.bytes} bytes`);
    await page.screenshot({path: path.join(FIGURES, 'gallery.png')});

    await page.click('#grid .card a');
    await page.waitForSelector('#detail:not([hidden]) btf-viewer');
    await waitFor(page, () => {
      const v = window.__btf.viewers().find((s) => s.cssWidth > 500);
      return v && v.drawnChunks === v.ownLimit && v.frames > 0 && v.complete;
    }, null, 'the large viewer');
    const large = (await viewers(page)).find((v) => v.cssWidth > 500);
    assert.ok(large.ownLimit > 1, 'the large viewer draws more than the first chunk');
    assert.match(large.label, /Lab error \d+\.\d\d/, 'the final error is shown');
    assertClean(desktop);
  });
});

// Scene budgets (doc/performance.md section 6, "Budgets"; doc/client.md): the same version-2 material tiled 16 times on a plane, as a
// 128-px thumbnail and as a 600-px view. The budgets come from client/btf-lod.js on
// the viewer's footprint; the server must send exactly those prefixes.
describe('scene budgets (version 2)', () => {
  const open = async (size) => {
    const page = await newPage(desktop);
    await page.setViewportSize({width: size + 40, height: size + 40});
    await page.goto(`${server.pagesUrl}viewer.html?material=tiles-lod&geometry=plane&light=fixed&repeat=16` +
      `&width=${size}&height=${size}&max-dpr=1`);
    await waitFor(page, () => {
      const v = window.__btf && window.__btf.viewers()[0];
      return v && v.scene && v.complete && v.received === v.scene.limit && v.drawnChunks === v.scene.limit &&
        v.frames > 0;
    }, null, `the ${size}-px viewer streamed and drew its scene budget`);
    return page;
  };

  it('a thumbnail gets the coarse prefix, a large view more, a zoom in more again', async () => {
    const page = await open(128); // newPage reuses the context's one page
    const s = (await viewers(page))[0];
    assert.equal(s.version, 2);
    assert.ok(s.received < s.manifestChunks, 'the thumbnail does not get the whole package');
    assert.equal(s.streamBytes, s.scene.bytes, 'exactly the budgeted bytes arrive');
    const sub = (await page.evaluate(() => window.__btf.streams()))[0].subscriptions[0];
    assert.deepEqual([sub.budget.chunks, sub.limit], [s.scene.limit, s.scene.limit],
      'asked for the scene budget, and the server granted that prefix');
    // the thumbnail drew something other than the background from its coarse levels
    const img = await capture(page, 0);
    const bg = img.data.slice(0, 4);
    let fg = 0;
    for (let k = 0; k < img.data.length; k += 4) if (Math.abs(img.data[k] - bg[0]) > 8) fg++;
    assert.ok(fg > img.width * img.height * 0.1, `the thumbnail covers > 10% of its canvas (${fg} px)`);
    // zooming in (a view change) asks for and receives a longer prefix
    await page.evaluate(() => window.__btf.element(0).setAttribute('repeat', '1'));
    await waitFor(page, (n) => {
      const v = window.__btf.viewers()[0];
      return v.scene.limit > n && v.received === v.scene.limit && v.complete;
    }, s.received, 'the zoomed thumbnail streams more');
    // a large view of the same scene receives more than the thumbnail
    await open(600);
    const l = (await viewers(page))[0];
    assert.ok(s.scene.level > l.scene.level, `thumbnail level ${s.scene.level} > large ${l.scene.level}`);
    assert.ok(s.received < l.received && s.streamBytes < l.streamBytes,
      `thumbnail ${s.received} chunks / ${s.streamBytes} B < large ${l.received} / ${l.streamBytes} B`);
    console.log(`# scene budgets, tiles-lod: 128 px x16 level ${s.scene.level} ${s.received}/${s.manifestChunks} ` +
      `chunks ${s.streamBytes} B; 600 px x16 level ${l.scene.level} ${l.received} chunks ${l.streamBytes} B`);
    assertClean(desktop);
  });

  it('pauses while the tab is hidden and while the viewer is off screen', async () => {
    const page = await newPage(desktop);
    await page.setViewportSize({width: 400, height: 400});
    await page.goto(`${server.pagesUrl}viewer.html?material=tiles-lod&geometry=plane&light=fixed&repeat=16` +
      '&width=128&height=128&max-dpr=1');
    await waitFor(page, () => window.__btf && window.__btf.viewers()[0].scene, null, 'the manifest');
    const sentBudget = () => page.evaluate(() => window.__btf.streams()[0].subscriptions[0].budget.chunks);
    const want = (await viewers(page))[0].scene.limit;
    assert.ok(want > 0);
    await page.evaluate(() => {
      Object.defineProperty(document, 'hidden', {configurable: true, get: () => true});
      document.dispatchEvent(new Event('visibilitychange'));
    });
    assert.equal(await sentBudget(), 0, 'hidden tab: budget 0');
    await page.evaluate(() => {
      delete document.hidden;
      document.dispatchEvent(new Event('visibilitychange'));
    });
    assert.equal(await sentBudget(), want, 'shown again: the scene budget');
    await page.evaluate(() => { window.__btf.element(0).style.marginTop = '3000px'; });
    await waitFor(page, () => window.__btf.streams()[0].subscriptions[0].budget.chunks === 0, null,
      'off screen: budget 0');
    await page.evaluate(() => { window.__btf.element(0).style.marginTop = '0px'; });
    await waitFor(page, (n) => window.__btf.streams()[0].subscriptions[0].budget.chunks === n, want,
      'back on screen: the scene budget');
    assertClean(desktop);
  });
});

describe('embed (embed.html)', () => {
  it('shows three materials through one WebSocket', async () => {
    const page = await newPage(desktop);
    await page.setViewportSize({width: 1000, height: 700});
    const sockets = [];
    page.on('websocket', (ws) => sockets.push(ws.url()));
    await page.goto(`${server.pagesUrl}embed.html`);
    await waitFor(page, () => window.__btf && window.__btf.viewers().length === 3, null, 'three viewers');
    await waitFor(page, () => window.__btf.viewers().every((v) => v.complete && v.drawnChunks === v.ownLimit &&
      v.frames > 0), null, 'every embed drawn with its budget');
    const vs = await viewers(page);
    // the page shows the library's first three materials (by name): the version-1 ones
    assert.deepEqual(new Set(vs.map((v) => v.material)), new Set(['knit', 'stone', 'tiles']));
    assert.deepEqual(new Set(vs.map((v) => v.geometry)), new Set(['plane', 'sphere', 'cylinder']));
    assert.equal(sockets.length, 1, `one shared WebSocket, saw ${sockets.join(', ')}`);
    const streams = await page.evaluate(() => window.__btf.streams());
    assert.equal(streams.length, 1);
    assert.equal(streams[0].subscriptions.length, 3);
    const snippet = await page.textContent('#snippet');
    assert.match(snippet, /<script type="module" src="http:\/\/127\.0\.0\.1:\d+\/btf-viewer\.js"><\/script>/);
    // every viewer drew something other than the background
    for (let i = 0; i < 3; i++) {
      const img = await capture(page, i);
      const bg = img.data.slice(0, 4);
      let fg = 0;
      for (let k = 0; k < img.data.length; k += 4) if (Math.abs(img.data[k] - bg[0]) > 8) fg++;
      assert.ok(fg > img.width * img.height * 0.1, `viewer ${i} covers > 10% of its canvas (${fg} px)`);
    }
    assertClean(desktop);
  });
});

describe('progressive refinement', () => {
  it('draws from the first chunk and converges on the final image', async () => {
    const page = await newPage(desktop);
    await page.setViewportSize({width: 400, height: 400});
    await page.goto(`${server.pagesUrl}viewer.html?material=knit&geometry=plane&light=fixed&light-theta=40` +
      '&light-phi=-60&camera-theta=30&budget-chunks=1&width=256&height=256&max-dpr=1');
    const shots = {};
    for (const n of [1, 2, 4, 6]) {
      await page.evaluate((k) => window.__btf.element(0).setAttribute('budget-chunks', String(k)), n === 6 ? 1000 : n);
      await waitFor(page, (k) => {
        const v = window.__btf.viewers()[0];
        return v && v.drawnChunks === k && v.uploaded === k && v.frames > 0;
      }, n, `${n} chunks drawn`);
      shots[n] = await capture(page, 0);
      assert.equal(shots[n].chunks, n);
    }
    const v = (await viewers(page))[0];
    assert.equal(v.manifestChunks, 6);
    assert.equal(v.uploads, 6, 'each chunk uploaded once, none re-uploaded');
    assert.equal(v.received, 6);
    const d = [1, 2, 4].map((n) => meanAbsDiff(shots[n], shots[6]));
    // the image changes with every step, and moves toward the final image
    for (const [a, b] of [[1, 2], [2, 4], [4, 6]])
      assert.ok(meanAbsDiff(shots[a], shots[b]) > 0.05, `image changes from ${a} to ${b} chunks`);
    assert.ok(d[0] > d[1] && d[1] > d[2] && d[2] > 0, `difference to the final image shrinks: ${d.join(' > ')}`);
    writePng(path.join(FIGURES, 'chunks-1-vs-all.png'), sideBySide([shots[1], shots[6]]));
    assertClean(desktop);
  });

  it('survives a lost WebGL context and redraws every chunk after the restore', async () => {
    const page = await newPage(desktop);
    await page.goto(`${server.pagesUrl}viewer.html?material=tiles&light=fixed&width=200&height=200&max-dpr=1`);
    await waitFor(page, () => window.__btf.viewers()[0]?.complete && window.__btf.viewers()[0].drawnChunks === 3,
      null, 'all chunks');
    const before = await capture(page, 0);
    await page.evaluate(() => {
      const e = window.__btf.element(0);
      window.__lose = e.gl.getExtension('WEBGL_lose_context');
      window.__lose.loseContext();
    });
    await waitFor(page, () => window.__btf.viewers()[0].lost, null, 'context lost');
    await page.evaluate(() => window.__lose.restoreContext());
    await waitFor(page, () => !window.__btf.viewers()[0].lost && window.__btf.viewers()[0].uploaded === 3,
      null, 'context restored');
    const after = await capture(page, 0);
    assert.ok(meanAbsDiff(before, after) < 0.01, 'same picture after the restore');
    assertClean(desktop);
  });
});

describe('mobile', () => {
  it('renders on a phone, orbits by touch, zooms by pinch and asks for a smaller budget', async () => {
    const url = `${server.pagesUrl}viewer.html?material=knit&geometry=sphere&light=fixed&height=300`;
    const dpage = await newPage(desktop);
    await dpage.setViewportSize({width: 1280, height: 800});
    await dpage.goto(url);
    await waitFor(dpage, () => window.__btf.viewers()[0]?.frames > 0, null, 'desktop frame');
    const dBudget = (await viewers(dpage))[0].budget.chunks;

    const phone = await launch({viewport: {width: 390, height: 844}, deviceScaleFactor: 3, isMobile: true,
      hasTouch: true});
    try {
      const page = await newPage(phone);
      await page.goto(url);
      await waitFor(page, () => window.__btf.viewers()[0]?.frames > 0, null, 'phone frame');
      const v0 = (await viewers(page))[0];
      const inf = (c) => (c < 0 ? Infinity : c);
      assert.ok(inf(v0.budget.chunks) < inf(dBudget), `phone budget ${v0.budget.chunks} < desktop ${dBudget}`);
      const sent = (await page.evaluate(() => window.__btf.streams()))[0].subscriptions[0].budget.chunks;
      assert.equal(sent, v0.budget.chunks, 'the smaller budget is what the server is asked for');
      // devicePixelRatio 3, capped at 2 by max-dpr's default (the display's pixels: a slow
      // GPU may draw the canvas at fewer, doc/client.md "Loading")
      assert.equal(v0.display[0], Math.round(v0.cssWidth * 2));

      const cdp = await phone.newCDPSession(page);
      const touch = (type, pts) => cdp.send('Input.dispatchTouchEvent', {type,
        touchPoints: pts.map(([x, y], id) => ({x, y, id}))});
      await touch('touchStart', [[150, 150]]);
      for (let i = 1; i <= 6; i++) await touch('touchMove', [[150 + 20 * i, 150]]);
      await touch('touchEnd', []);
      await waitFor(page, (az) => {
        const v = window.__btf.viewers()[0];
        return v.drags >= 1 && v.camera[0] !== az;
      }, v0.camera[0], 'a touch drag to orbit');
      const v1 = (await viewers(page))[0];
      assert.ok(v1.camera[0] < v0.camera[0] - 10, `azimuth moved: ${v0.camera[0]} -> ${v1.camera[0]}`);
      await waitFor(page, (f) => window.__btf.viewers()[0].frames > f, v0.frames, 'a redraw after the drag');

      await touch('touchStart', [[180, 150], [220, 150]]);
      for (let i = 1; i <= 5; i++) await touch('touchMove', [[180 - 15 * i, 150], [220 + 15 * i, 150]]);
      await touch('touchEnd', []);
      const v2 = (await viewers(page))[0];
      assert.ok(v2.camera[2] < v1.camera[2], `pinch out zooms in: ${v1.camera[2]} -> ${v2.camera[2]}`);
      assertClean(phone);
    } finally {
      await phone.close();
    }
    assertClean(desktop);
  });
});

describe('without WebGL2', () => {
  it('says so clearly', async () => {
    const ctx = await launch();
    try {
      const page = await newPage(ctx);
      await page.addInitScript(() => {
        const get = HTMLCanvasElement.prototype.getContext;
        HTMLCanvasElement.prototype.getContext = function (type, ...rest) {
          return type === 'webgl2' ? null : get.call(this, type, ...rest);
        };
      });
      await page.goto(`${server.pagesUrl}viewer.html?material=knit`);
      await waitFor(page, () => window.__btf?.viewers()[0]?.error, null, 'the error');
      const msg = await page.evaluate(() => window.__btf.element(0).shadowRoot.querySelector('.msg').textContent);
      assert.match(msg, /WebGL2 is not available/);
      assertClean(ctx);
    } finally {
      await ctx.close();
    }
  });
});

describe('browser vs headless C renderer', () => {
  it('equals `btf render` of the same scene within 2/255 on >= 99% of pixels', async (t) => {
    if (!hasRender()) {
      t.skip('build/btf has no `render` command yet (tools/cmd_render.c): cross-check not possible');
      return;
    }
    const {crossCheck} = await import('./crosscheck.mjs');
    const r = await crossCheck(desktop, server, lib.lib, assert);
    t.diagnostic(r.map((x) => `${x.geometry}: ${(100 * x.frac).toFixed(2)}% within 2/255, worst ${x.worst}`).join('; '));
    assertClean(desktop);
  });
});

describe('benchmark: first frame on a 4 Mbit/s link (recorded, not judged)', () => {
  it('records bytes and time before the first frame into bench/results/client.txt', async () => {
    const ctx = await launch();
    try {
      const page = await newPage(ctx);
      const cdp = await ctx.newCDPSession(page);
      await cdp.send('Network.enable');
      await cdp.send('Network.setCacheDisabled', {cacheDisabled: true});
      const bps = 4e6 / 8; // 4 Mbit/s in bytes per second
      await cdp.send('Network.emulateNetworkConditions', {offline: false, latency: 20,
        downloadThroughput: bps, uploadThroughput: bps});
      const lines = [];
      for (const m of ['knit', 'tiles']) {
        await page.goto(`${server.pagesUrl}viewer.html?material=${m}&light=fixed&width=300&height=300&max-dpr=1`);
        await waitFor(page, () => window.__btf?.viewers()[0]?.complete &&
          window.__btf.viewers()[0].drawnChunks === window.__btf.viewers()[0].ownLimit, null, 'all chunks', 120000);
        const r = await page.evaluate(() => {
          const v = window.__btf.viewers()[0];
          const res = performance.getEntriesByType('resource');
          const http = res.filter((e) => e.responseEnd <= v.firstFrameAt).reduce((s, e) => s + e.transferSize, 0);
          const nav = performance.getEntriesByType('navigation')[0];
          return {v, http: http + (nav ? nav.transferSize : 0), streams: window.__btf.streams()};
        });
        const sub = r.streams[0].subscriptions[0];
        lines.push(`${m.padEnd(6)} ${String(r.v.firstFrameBytes).padStart(9)} ${String(r.http).padStart(9)} ` +
          `${r.v.firstFrameAt.toFixed(0).padStart(7)} ${String(sub.received).padStart(6)} ` +
          `${String(sub.bytes).padStart(9)}`);
      }
      const out = [
        '# client first frame, Chromium (SwiftShader), loopback throttled to 4 Mbit/s + 20 ms via CDP',
        '# Network.emulateNetworkConditions; viewer.html, 300x300 CSS px, light fixed, automatic budget;',
        '# 32x32-texel packages (k = 3), 81 x 81 directions (tests/e2e/client.test.mjs).',
        `# date ${new Date().toISOString()}`,
        '# material  ws_bytes_before_first_frame  http_bytes_before_first_frame  ms_to_first_frame' +
          '  chunks_streamed  chunk_bytes_streamed',
        '# ws bytes = every WebSocket byte received (hello, manifest, chunk pieces) when the first frame was drawn;',
        '# http bytes = page, scripts, style and shader files (transfer sizes); ms from navigation start.',
        ...lines, ''];
      fs.mkdirSync(path.join(ROOT, 'bench/results'), {recursive: true});
      const file = path.join(ROOT, 'bench/results/client.txt');
      fs.writeFileSync(`${file}.tmp`, out.join('\n'));
      fs.renameSync(`${file}.tmp`, file);
      process.stdout.write(`# ${out.join('\n# ')}\n`);
    } finally {
      await ctx.close();
    }
  });
});
