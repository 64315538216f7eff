// embed.test.mjs - <btf-viewer> embedded in pages of another origin (a node http server
// on another loopback port) with the README's two-line snippet: cross-origin loading,
// events, attribute changes in flight, lazy loading, touch scrolling on a phone, and
// 40 viewers on one page. Run: node --test tests/e2e/
import assert from 'node:assert/strict';
import {after, before, describe, it} from 'node:test';
import {spawnSync} from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import {measureLink, startThrottle} from './throttle.mjs';
import {BTF, assertClean, capture, launch, makeLibrary, meanAbsDiff, newPage, requireBuild, servePages, startServer, viewers, waitFor, watchFrames, writePng}
  from './util.mjs';

// knit, tiles and wide keep the equal-noise steps (--plain): the cache test needs two
// packages that do not fit its limit together, the link test enough bytes to fill the
// link (the default's rate-distortion packages are about 40% smaller); stone is what
// `btf compress` writes by default.
const MATERIALS = {knit: ['knit', 6, 0, ['--plain']], stone: ['stone', 3], tiles: ['tiles', 3, 0, ['--plain']],
  wide: ['knit', 16, 0, ['--plain']],
  // version 4 (residual levels), textures PNG or lossless WebP as written by default, and its PNG-only
  // twin (equal-noise steps: the default's steps depend on the file type its rates are measured on)
  lap: ['stone', 4, 3, ['--plain', '--residual']], 'lap-png': ['stone', 4, 3, ['--plain', '--residual', '--png']]};
let lib, server, pages, desktop;

// The README snippet (script from btfd, element with no src: the script's origin), plus `body`.
const snippet = (body) => `<!doctype html><html><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1"><link rel="icon" href="data:,">
<script type="module" src="${server.url}btf-viewer.js"></script></head>
<body style="margin:0">${body}</body></html>`;

// The snippet with its script from btfd through the throttled link on port `port`.
export const linkPage = (port, material) => `<!doctype html><html><head><meta charset="utf-8">
<link rel="icon" href="data:,"><script type="module" src="http://127.0.0.1:${port}/btf-viewer.js"></script></head>
<body><btf-viewer material="${material}" light="fixed" budget-chunks="1000" max-dpr="1"
style="width:300px;height:300px"></btf-viewer></body></html>`;

const viewer = (attrs, style = 'width:200px;height:200px') => `<btf-viewer ${attrs} style="${style}"></btf-viewer>`;

before(async () => {
  requireBuild();
  lib = makeLibrary(MATERIALS);
  // tiles gets a thumbnail (the default poster): 8x8 pure red
  writePng(path.join(lib.lib, 'tiles', 'thumbnail.png'), {width: 8, height: 8,
    data: new Uint8Array(256).map((_, i) => (i % 4 === 0 || i % 4 === 3 ? 255 : 0))});
  server = await startServer(lib.lib);
  pages = await servePages({
    one: () => snippet(viewer('material="knit" geometry="sphere" light="fixed" budget-chunks="3"')),
    events: () => snippet(`<script type="module">
      window.__events = [];
      for (const t of ['load', 'progress', 'complete', 'error', 'camera-change'])
        document.addEventListener(t, (e) => window.__events.push({type: t, detail: e.detail,
          target: e.target.getAttribute('material')}));
    </script>${viewer('material="knit" light="fixed" budget-chunks="4" loading="eager"')}
    ${viewer('material="nosuch" light="fixed" loading="eager"')}`),
    lazy: () => snippet(`<div style="height:4000px">top</div>${viewer('material="tiles" light="fixed"')}`),
    scroll: () => snippet(`${viewer('material="stone" light="fixed"', 'display:block;width:100%;height:300px')}
      <div style="height:1200px"></div>
      ${viewer('material="stone" light="fixed" camera-controls', 'display:block;width:100%;height:300px')}
      <div style="height:3000px"></div>`),
    lru: () => snippet(`<script type="module">
      window.__cache = await import('${server.url}btf-cache.js'); // the viewer's own module instance
      window.__cache.chunkCache.limit = 250000;
    </script>${viewer('material="knit" light="fixed" budget-chunks="3" loading="eager"')}`),
    // ?link=PORT: the script (so shaders and stream too) through a throttled link (throttle.mjs)
    slow: (req) => linkPage(new URL(req.url, 'http://x').searchParams.get('link'), 'wide'),
    twins: (req) => {
      const port = new URL(req.url, 'http://x').searchParams.get('link');
      const v = (m) => `<btf-viewer material="${m}" light="fixed" budget-chunks="1000" max-dpr="1" loading="eager"
        style="display:block;width:160px;height:160px"></btf-viewer>`;
      return `<!doctype html><html><head><meta charset="utf-8">
        <meta name="viewport" content="width=device-width, initial-scale=1"><link rel="icon" href="data:,">
        <script type="module" src="http://127.0.0.1:${port}/btf-viewer.js"></script></head>
        <body style="margin:0">${v('lap')}${v('lap-png')}</body></html>`;
    },
    forty: () => snippet(Array.from({length: 40}, (_, i) =>
      viewer(`material="${['knit', 'stone', 'tiles'][i % 3]}" light="fixed" budget-chunks="1" max-dpr="1"`,
        'width:96px;height:96px')).join('')),
  });
  desktop = await launch();
});

after(async () => {
  await desktop?.close();
  await pages?.close();
  await server?.stop();
  lib?.remove();
});

// Share of pixels of viewer i that differ from its background (something was drawn).
async function coverage(page, i) {
  return page.evaluate((k) => {
    const c = window.__btf.capture(k), px = atob(c.rgba);
    let fg = 0;
    for (let p = 0; p < px.length; p += 4) if (Math.abs(px.charCodeAt(p) - px.charCodeAt(0)) > 8) fg++;
    return fg / (c.width * c.height);
  }, i);
}

describe('cross-origin embedding (README snippet on another origin)', () => {
  it('loads the script, shaders and stream from btfd and draws', async () => {
    const page = await newPage(desktop);
    const sockets = [];
    page.on('websocket', (ws) => sockets.push(ws.url()));
    await page.goto(`${pages.url}one.html`);
    assert.notEqual(new URL(pages.url).origin, new URL(server.url).origin);
    await waitFor(page, () => window.__btf?.viewers()[0]?.drawnChunks === 3, null, 'three chunks drawn');
    assert.deepEqual(sockets, [`${server.ws}`], 'the stream defaults to the script origin');
    assert.ok(await coverage(page, 0) > 0.1, 'the sphere covers > 10% of the canvas');
    assertClean(desktop);
  });
});

describe('events and properties', () => {
  it('fires load, progress and complete in order, error with a reason, camera-change', async () => {
    const page = await newPage(desktop);
    await page.goto(`${pages.url}events.html`);
    await waitFor(page, () => window.__events?.some((e) => e.type === 'complete'), null, 'complete');
    await waitFor(page, () => window.__events.some((e) => e.type === 'error'), null, 'error');
    const ev = (await page.evaluate(() => window.__events)).filter((e) => e.target === 'knit');
    const types = ev.map((e) => e.type);
    const load = types.indexOf('load'), complete = types.indexOf('complete');
    assert.ok(types[0] === 'progress' && load > 0 && complete > load, types.join(' '));
    const prog = ev.filter((e) => e.type === 'progress').map((e) => e.detail);
    assert.deepEqual(prog.map((p) => p.chunks), [1, 2, 3, 4], 'one progress per chunk');
    assert.ok(prog.every((p) => p.chunksWanted === 4 && p.bytes > 0 && p.bytes <= p.bytesWanted), JSON.stringify(prog));
    assert.ok(prog[0].error > prog[3].error, 'the promised error falls');
    assert.equal(prog[3].bytes, prog[3].bytesWanted);
    assert.equal(types.filter((t) => t === 'complete').length, 1);
    const err = (await page.evaluate(() => window.__events)).find((e) => e.type === 'error');
    assert.equal(err.target, 'nosuch');
    assert.match(err.detail.reason, /unknown_material/);
    // properties reflect attributes; a camera attribute moves the camera and says so
    const r = await page.evaluate(() => {
      const v = document.querySelector('btf-viewer');
      v.cameraTheta = 10;
      return {material: v.material, budget: v.budgetChunks, attr: v.getAttribute('camera-theta'),
        controls: v.cameraControls, cam: window.__events.filter((e) => e.type === 'camera-change').pop()};
    });
    assert.deepEqual([r.material, r.budget, r.attr, r.controls], ['knit', 4, '10', false]);
    assert.equal(Math.round(r.cam.detail.theta), 10);
    ctxProblemsWithout(desktop, /404|unknown_material/);
    assertClean(desktop);
  });

  it('attribute changes in flight leave one subscription and one GPU package', async () => {
    const page = await newPage(desktop);
    const frames = watchFrames(page);
    await page.goto(`${pages.url}one.html`);
    await waitFor(page, () => window.__btf?.viewers()[0]?.received >= 1, null, 'streaming');
    // switch material, src-independent attributes and geometry while chunks are in flight
    await page.evaluate(async () => {
      const v = document.querySelector('btf-viewer');
      for (const m of ['tiles', 'stone', 'knit', 'tiles', 'stone']) {
        v.material = m;
        v.geometry = m === 'stone' ? 'plane' : 'cylinder';
        await new Promise((r) => setTimeout(r, 15));
      }
      v.budgetChunks = 2;
    });
    await waitFor(page, () => {
      const v = window.__btf.viewers()[0];
      return v.material === 'stone' && v.drawnChunks === 2 && v.complete;
    }, null, 'the last material drawn');
    await new Promise((r) => setTimeout(r, 300)); // late replies of the old subscriptions
    const st = await page.evaluate(() => ({gl: window.__btf.gl(), streams: window.__btf.streams()}));
    assert.equal(st.gl.packages, 1, `GPU packages alive: ${st.gl.packages}`);
    assert.equal(st.gl.contexts, 1);
    assert.equal(st.streams.length, 1);
    assert.deepEqual(st.streams[0].subscriptions.map((s) => [s.material, s.listeners]), [['stone', 1]]);
    // the server's view: subscriptions it created (manifests) minus those it ended (unsubscribed)
    const made = frames.text.filter((m) => m.type === 'manifest').map((m) => m.mid);
    const ended = new Set(frames.text.filter((m) => m.type === 'unsubscribed').map((m) => m.mid));
    const live = made.filter((m) => !ended.has(m));
    assert.ok(made.length >= 2, `several subscriptions were made: ${made}`);
    assert.equal(live.length, 1, `server-side live subscriptions: ${live} of ${made}`);
    assert.equal(frames.text.filter((m) => m.type === 'error').length, 0, JSON.stringify(frames.text
      .filter((m) => m.type === 'error')));
    assertClean(desktop);
  });
});

describe('streams and motion', () => {
  it('a btfd that does not allow the page origin: an error event, no retries', async () => {
    const strict = await startServer(lib.lib, ['--allow-origin', 'https://only.example']);
    try {
      const page = await newPage(desktop);
      const frames = watchFrames(page);
      await page.goto(`${pages.url}events.html`);
      await page.evaluate((ws) => {
        const v = document.createElement('btf-viewer');
        Object.assign(v, {material: 'knit', src: ws, loading: 'eager'});
        document.body.append(v);
      }, strict.ws);
      const err = await waitFor(page, () => window.__events.find((e) => e.type === 'error' &&
        /origin/.test(e.detail.reason)), null, 'the origin error');
      assert.match(err.detail.reason, /refuses this page's origin \(origin_not_allowed\)/);
      await new Promise((r) => setTimeout(r, 1000));
      assert.equal(frames.sockets, 2, 'one socket each to the two servers: no reconnects');
      // the poster's GET /materials is refused by CORS too (the browser logs it): expected here
      ctxProblemsWithout(desktop, /unknown_material|blocked by CORS policy|net::ERR_FAILED/);
      assertClean(desktop);
    } finally {
      await strict.stop();
    }
  });

  it('a stream closed with nothing subscribed reconnects for the next viewer', async () => {
    const page = await newPage(desktop);
    const frames = watchFrames(page);
    await page.goto(`${pages.url}one.html`);
    await waitFor(page, () => window.__btf?.viewers()[0]?.drawnChunks === 3, null, 'drawn');
    await page.evaluate(() => {
      const v = document.querySelector('btf-viewer');
      window.__stream = v.stream;
      v.remove();
      window.__stream.ws.close();
    });
    await waitFor(page, () => !window.__stream.open, null, 'closed');
    await page.evaluate(() => {
      const v = document.createElement('btf-viewer');
      Object.assign(v, {material: 'tiles', light: 'fixed', loading: 'eager'});
      document.body.append(v);
    });
    await waitFor(page, () => window.__btf.viewers()[0]?.drawnChunks > 0, null, 'the new viewer drawn');
    assert.equal(frames.sockets, 2, 'a second connection');
    assertClean(desktop);
  });

  it('prefers-reduced-motion keeps an orbiting light still', async () => {
    const page = await newPage(desktop);
    const count = async () => {
      await waitFor(page, () => window.__btf?.viewers()[0]?.drawnChunks === 3, null, 'drawn');
      const f0 = (await page.evaluate(() => window.__btf.viewers()[0])).frames;
      await new Promise((r) => setTimeout(r, 2000));
      return (await page.evaluate(() => window.__btf.viewers()[0])).frames - f0;
    };
    await page.emulateMedia({reducedMotion: 'reduce'});
    await page.goto(`${pages.url}one.html`);
    await page.evaluate(() => document.querySelector('btf-viewer').setAttribute('light', 'orbit'));
    const still = await count();
    await page.emulateMedia({reducedMotion: 'no-preference'});
    await page.goto(`${pages.url}one.html`);
    await page.evaluate(() => document.querySelector('btf-viewer').setAttribute('light', 'orbit'));
    const moving = await count();
    assert.ok(still === 0 && moving > 0, `frames in 2 s: reduced ${still}, animated ${moving}: ` +
      JSON.stringify(await page.evaluate(() => window.__btf.viewers()[0])));
    assertClean(desktop);
  });
});

function ctxProblemsWithout(ctx, re) {
  ctx.problems = ctx.problems.filter((p) => !re.test(p));
}

describe('loading="lazy"', () => {
  it('opens no socket, fetches nothing and creates no context until scrolled near', async () => {
    const page = await newPage(desktop);
    await page.setViewportSize({width: 800, height: 600});
    const sockets = [], requests = [];
    page.on('websocket', (ws) => sockets.push(ws.url()));
    page.on('request', (r) => requests.push(r.url()));
    await page.goto(`${pages.url}lazy.html`);
    await waitFor(page, () => window.__btf?.viewers().length === 1, null, 'the element defined');
    await new Promise((r) => setTimeout(r, 1000));
    const gl = await page.evaluate(() => window.__btf.gl());
    const early = requests.filter((u) => /\/shaders\/|\/materials/.test(u));
    assert.deepEqual([sockets.length, early.length, gl.contexts], [0, 0, 0],
      `before scrolling: sockets ${sockets}, requests ${early}, contexts ${gl.contexts}`);
    await page.evaluate(() => window.scrollTo(0, 3500));
    // the poster (tiles' thumbnail from btfd) shows until the first frame, then hides
    await waitFor(page, () => window.__btf.viewers()[0].frames > 0, null, 'drawn after scrolling near');
    const shown = (await page.evaluate(() => window.__btf.viewers()[0])).posterShown;
    assert.match(String(shown), /\/materials\/tiles\/thumbnail\.png$/);
    assert.equal((await page.evaluate(() => window.__btf.viewers()[0])).poster, null, 'poster hidden once drawn');
    assert.equal(sockets.length, 1);
    assert.ok(requests.some((u) => u.includes('/shaders/')));
    assertClean(desktop);
  });
});

describe('a good guest on a phone', () => {
  it('vertical swipes over viewers scroll the page, with and without camera-controls', async () => {
    const phone = await launch({viewport: {width: 390, height: 700}, deviceScaleFactor: 2, isMobile: true,
      hasTouch: true});
    try {
      const page = await newPage(phone);
      await page.goto(`${pages.url}scroll.html`);
      await waitFor(page, () => window.__btf?.viewers()[0]?.frames > 0, null, 'first viewer drawn');
      const cdp = await phone.newCDPSession(page);
      const swipe = async (y0) => {
        await cdp.send('Input.dispatchTouchEvent', {type: 'touchStart', touchPoints: [{x: 200, y: y0}]});
        for (let i = 1; i <= 10; i++)
          await cdp.send('Input.dispatchTouchEvent', {type: 'touchMove', touchPoints: [{x: 200, y: y0 - 20 * i}]});
        await cdp.send('Input.dispatchTouchEvent', {type: 'touchEnd', touchPoints: []});
        await new Promise((r) => setTimeout(r, 300));
        return page.evaluate(() => window.scrollY);
      };
      const y1 = await swipe(250); // on the first viewer (no camera-controls)
      assert.ok(y1 > 50, `the page scrolled over a plain viewer: scrollY ${y1}`);
      // bring the camera-controls viewer under the finger
      await page.evaluate(() => window.scrollTo(0, 1500 - 100));
      const yc0 = await page.evaluate(() => window.scrollY);
      const cam0 = await page.evaluate(() => window.__btf.viewers()[1].camera);
      const y2 = await swipe(300);
      assert.ok(y2 > yc0 + 50, `the page scrolled over a camera-controls viewer: ${yc0} -> ${y2}`);
      const v = await page.evaluate(() => ({touch: getComputedStyle(document.querySelectorAll('btf-viewer')[1]
        .shadowRoot.querySelector('canvas')).touchAction, cam: window.__btf.viewers()[1].camera}));
      assert.equal(v.touch, 'pan-y');
      assert.deepEqual(v.cam, cam0, 'a vertical swipe does not orbit');
      assertClean(phone);
    } finally {
      await phone.close();
    }
  });

  it('wheel zooms only once engaged, arrow keys orbit, alt labels', async () => {
    const page = await newPage(desktop);
    await page.setViewportSize({width: 800, height: 600});
    await page.goto(`${pages.url}scroll.html`);
    await waitFor(page, () => window.__btf?.viewers()[0]?.frames > 0, null, 'drawn');
    await page.evaluate(() => window.scrollTo(0, 1500 - 100));
    await waitFor(page, () => window.__btf.viewers()[1].frames > 0, null, 'second viewer drawn');
    const at = await page.evaluate(() => {
      const r = document.querySelectorAll('btf-viewer')[1].getBoundingClientRect();
      return {x: r.left + 100, y: r.top + 100, scroll: window.scrollY};
    });
    await page.mouse.move(at.x, at.y);
    const d0 = (await page.evaluate(() => window.__btf.viewers()[1].camera))[2];
    await page.mouse.wheel(0, 300);
    await new Promise((r) => setTimeout(r, 300));
    const s1 = await page.evaluate(() => ({scroll: window.scrollY, d: window.__btf.viewers()[1].camera[2]}));
    assert.ok(s1.scroll > at.scroll && s1.d === d0, `not engaged: the page scrolls (${at.scroll} -> ${s1.scroll})`);
    await page.evaluate((y) => window.scrollTo(0, y), at.scroll);
    await page.mouse.click(at.x, at.y);
    const before = await page.evaluate(() => window.scrollY);
    await page.mouse.wheel(0, 300);
    await new Promise((r) => setTimeout(r, 300));
    const s2 = await page.evaluate(() => ({scroll: window.scrollY, d: window.__btf.viewers()[1].camera[2]}));
    assert.ok(s2.d > d0 && s2.scroll === before, `engaged: zoom ${d0} -> ${s2.d}, scroll ${before} -> ${s2.scroll}`);
    const az0 = (await page.evaluate(() => window.__btf.viewers()[1].camera))[0];
    await page.keyboard.press('ArrowLeft');
    const az1 = (await page.evaluate(() => window.__btf.viewers()[1].camera))[0];
    assert.equal(az1, az0 + 5, 'ArrowLeft orbits by 5 degrees');
    const aria = await page.evaluate(() => {
      const v = document.querySelectorAll('btf-viewer')[1];
      v.alt = 'Stone tiles';
      return [v.getAttribute('role'), v.getAttribute('aria-label'), v.tabIndex];
    });
    assert.deepEqual(aria, ['img', 'Stone tiles', 0]);
    assertClean(desktop);
  });
});

describe('many viewers', () => {
  it('40 viewers on one page share one WebGL2 context and all draw', async () => {
    const page = await newPage(desktop);
    await page.setViewportSize({width: 1000, height: 700});
    await page.goto(`${pages.url}forty.html`);
    await waitFor(page, () => window.__btf?.viewers().length === 40 &&
      window.__btf.viewers().every((v) => v.drawnChunks === 1 && v.frames > 0), null, '40 viewers drawn', 120000);
    const gl = await page.evaluate(() => window.__btf.gl());
    assert.equal(gl.contexts, 1);
    assert.equal(gl.packages, 40);
    const cov = [];
    for (let i = 0; i < 40; i++) cov.push(await coverage(page, i));
    assert.ok(cov.every((c) => c > 0.1), `every viewer covers > 10%: ${cov.map((c) => c.toFixed(2))}`);
    // what the page shows: the viewers' own 2D canvases hold the frames (not only the shared one)
    const shown = await page.evaluate(() => [...document.querySelectorAll('btf-viewer')].map((v) => {
      const c = v.shadowRoot.querySelector('canvas'), d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
      let fg = 0;
      for (let p = 0; p < d.length; p += 4) if (Math.abs(d[p] - d[0]) > 8) fg++;
      return fg / (c.width * c.height);
    }));
    assert.ok(shown.every((c) => c > 0.1), `every canvas shows its frame: ${shown.map((c) => c.toFixed(2))}`);
    assertClean(desktop);
  });
});

describe('a second visit', () => {
  // One visit in a browser profile: the bytes the server streamed (binary frames as the
  // browser's network layer saw them) and whether the server resumed from the kept chunks.
  const visit = async (profile) => {
    const ctx = await launch({}, profile);
    try {
      const page = await newPage(ctx);
      const frames = watchFrames(page);
      await page.goto(`${pages.url}one.html`);
      await waitFor(page, () => window.__btf?.viewers()[0]?.drawnChunks === 3, null, 'three chunks drawn');
      assert.ok(await coverage(page, 0) > 0.1, 'drawn');
      // the chunks are kept after they are drawn: closing the browser before the last
      // write lands would test the timing of this script, not the resume
      await waitFor(page, (url) => import(url).then((c) => c.cacheIndex()).then((ix) =>
        Object.values(ix.entries).some((e) => e.chunks.length === 3 && e.manifest > 0)), `${server.url}btf-cache.js`,
      'three chunks and the manifest kept');
      const m = frames.text.find((x) => x.type === 'manifest');
      assertClean(ctx);
      return {bytes: frames.binary, text: frames.textBytes, resumed: m.resumed, held: m.held, etag: m.etag,
        manifest: 'manifest' in m};
    } finally {
      await ctx.close();
    }
  };

  it('keeps at most chunkCache.limit bytes, evicting the least recently used material', async () => {
    const ctx = await launch();
    try {
      const page = await newPage(ctx);
      await page.goto(`${pages.url}lru.html`);
      await waitFor(page, () => window.__btf?.viewers()[0]?.drawnChunks === 3, null, 'knit drawn');
      const index = () => page.evaluate(() => window.__cache.cacheIndex());
      const keys = (ix) => Object.keys(ix.entries).map((k) => k.split('|')[1]).sort();
      await waitFor(page, () => window.__cache.cacheIndex().then((ix) => Object.values(ix.entries)
        .some((e) => e.chunks.length === 3)), null, 'knit kept');
      const one = await index();
      assert.deepEqual(keys(one), ['knit']);
      await page.evaluate(() => { document.querySelector('btf-viewer').material = 'tiles'; });
      await waitFor(page, () => window.__btf.viewers()[0].material === 'tiles' &&
        window.__btf.viewers()[0].drawnChunks === 3, null, 'tiles drawn');
      await waitFor(page, () => window.__cache.cacheIndex().then((ix) => Object.keys(ix.entries).join() !== '' &&
        Object.values(ix.entries).every((e) => e.chunks.length === 3)), null, 'tiles kept');
      const two = await index();
      const total = Object.values(two.entries).reduce((a, e) => a + e.bytes, 0);
      assert.ok(Object.values(one.entries)[0].bytes + total > 250000, 'both do not fit');
      assert.deepEqual(keys(two), ['tiles'], `knit (least recently used) evicted: ${JSON.stringify(two)}`);
      assert.ok(total <= 250000, `kept ${total} bytes`);
      assertClean(ctx);
    } finally {
      await ctx.close();
    }
  });

  it('draws from the kept chunks, streams nothing again, and refetches a new etag', async () => {
    const profile = fs.mkdtempSync(path.join(os.tmpdir(), 'btf-profile-'));
    try {
      const first = await visit(profile);
      const second = await visit(profile);
      assert.ok(first.bytes > 100000 && !first.resumed, JSON.stringify(first));
      assert.ok(second.resumed && second.held === 3, `the server resumed: ${JSON.stringify(second)}`);
      assert.ok(second.bytes < 1000, `second visit streamed ${second.bytes} of ${first.bytes} bytes`);
      // nor the manifest: the page kept it with the chunks ("manifest_kept")
      assert.ok(first.manifest && !second.manifest, `the manifest came once: ${JSON.stringify([first, second])}`);
      const all = (v) => v.bytes + v.text;
      assert.ok(all(second) <= 0.01 * all(first), `second visit: ${all(second)} of ${all(first)} stream bytes`);
      console.log(`# second visit: ${first.bytes} -> ${second.bytes} chunk bytes, ${all(first)} -> ${all(second)} ` +
        `stream bytes with the messages over the network (${(100 * (1 - all(second) / all(first))).toFixed(1)}% saved)`);
      // the package is replaced (new etag): everything streams again
      const dir = path.join(lib.dir, 'knit-new');
      const src = path.join(lib.dir, 'knit2.btf');
      for (const args of [['gen', 'knit', src, '--size', '32', '--format', 'btf', '--components', '16', '--seed', '7'],
        ['compress', src, dir, '--k', '3', '--components', '5', '--plain', '--quiet']]) {
        const r = spawnSync(BTF, args, {encoding: 'utf8'});
        assert.equal(r.status, 0, r.stderr);
      }
      fs.renameSync(path.join(lib.lib, 'knit'), path.join(lib.dir, 'knit-old'));
      fs.renameSync(dir, path.join(lib.lib, 'knit'));
      await fetch(`${server.url}materials`); // rescans the library
      const third = await visit(profile);
      assert.ok(!third.resumed && third.etag !== first.etag && third.bytes > 100000 && third.manifest,
        JSON.stringify(third));
    } finally {
      fs.rmSync(profile, {recursive: true, force: true});
    }
  });
});

describe('lossless WebP textures in the field', () => {
  it('a phone on another origin behind a 1.6 Mbit/s, 150 ms link draws the WebP package as its PNG twin', async () => {
    const files = (m) => fs.readdirSync(path.join(lib.lib, m));
    assert.ok(files('lap').some((f) => f.endsWith('.webp')), `lap has WebP textures: ${files('lap')}`);
    // (textures: either package's 8-bit weights may be wt-JJ-8.webp, package-format.md 5.2)
    assert.ok(!files('lap-png').some((f) => f.startsWith('tex-') && f.endsWith('.webp')), 'lap-png has none');
    const bytes = files('lap').reduce((a, f) => a + fs.statSync(path.join(lib.lib, 'lap', f)).size, 0);
    const link = await startThrottle({target: server.port, bps: 1.6e6, delayMs: 75});
    const phone = await launch({viewport: {width: 390, height: 700}, deviceScaleFactor: 2, isMobile: true,
      hasTouch: true});
    try {
      const page = await newPage(phone);
      await page.goto(`${pages.url}twins.html?link=${link.port}`);
      assert.notEqual(new URL(pages.url).origin, `http://127.0.0.1:${link.port}`);
      await waitFor(page, () => {
        const vs = window.__btf?.viewers() || [];
        return vs.length === 2 && vs.every((v) => v.complete && v.drawnChunks === v.ownLimit && v.frames > 0);
      }, null, 'both packages streamed through the link and drawn', 120000);
      const vs = await viewers(page);
      assert.deepEqual(vs.map((v) => v.error), [null, null]);
      assert.equal(vs[0].drawnChunks, vs[1].drawnChunks);
      const streamed = vs[0].streamBytes + vs[1].streamBytes;
      assert.ok(vs[0].streamBytes > 0 && streamed <= link.down.bytes,
        `both streams came over the link: ${streamed} of its ${link.down.bytes} bytes (WebP package ${bytes})`);
      const d = meanAbsDiff(await capture(page, 0), await capture(page, 1));
      console.log(`# WebP vs PNG twin on a phone, 1.6 Mbit/s: ${vs[0].drawnChunks} chunks each, ` +
        `${link.down.bytes} bytes over the link, mean |difference| ${d.toFixed(4)} of 255`);
      assert.ok(d < 0.01, `the same pixels (${d})`);
      assert.ok(await coverage(page, 0) > 0.1, 'the WebP package covers > 10% of its canvas');
      assertClean(phone);
    } finally {
      await phone.close();
      await link.close();
    }
  });
});

describe('a slow link', () => {
  it('takes the stream at >= 90% of a 4 Mbit/s, 40 ms (RTT) link', async () => {
    // measured on an otherwise idle host: the pages earlier tests left open are closed
    for (const p of desktop.pages()) await p.close();
    const bps = 4e6;
    // the best of up to 3 loads, each a fresh browser (no cache): a stall of the shared
    // host (another process on the cores, the page's main thread held up) can only lower
    // a load's share, so the best one is what the client and server reach; a page that
    // under-fills the link fails all three
    let r = null;
    for (let i = 0; i < 3 && !(r?.streamUtilisation >= 0.9); i++) {
      const ctx = await launch();
      try {
        const m = await measureLink(ctx, {btfdPort: server.port, pagesUrl: pages.url, page: 'slow', bps, delayMs: 20});
        console.log(`# 4 Mbit/s, 40 ms RTT, load ${i + 1}: stream ${(100 * m.streamUtilisation).toFixed(1)}% of the ` +
          `link (${(100 * m.streamFromOpen).toFixed(1)}% from the socket's open), whole load ${(100 * m.utilisation).toFixed(1)}% (${m.bytes} bytes, first frame ` +
          `${m.firstFrameMs.toFixed(0)} ms, complete ${m.completeMs.toFixed(0)} ms)`);
        if (!r || m.streamUtilisation > r.streamUtilisation) r = m;
        assertClean(ctx);
      } finally {
        await ctx.close();
      }
    }
    assert.ok(r.bytes > 500000, `a package long enough to measure: ${r.bytes} bytes`);
    assert.ok(r.streamUtilisation >= 0.9 && r.streamUtilisation < 1.1, `stream: ${r.streamUtilisation}`);
    // the whole load (script, modules, shaders, stream) also pays round trips and CPU time
    // (91-97% on an idle machine, bench/bench_link.sh); bounded loosely: a shared CI host
    assert.ok(r.utilisation >= 0.5 && r.utilisation < 1.1, `whole load (script, shaders, stream): ${r.utilisation}`);
  });
});
