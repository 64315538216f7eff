// field.test.mjs - what the page shows in the field: the README's two-line embed on a
// page of another origin, on an emulated phone behind a slow link (the throttling proxy
// of throttle.mjs), judged by what was drawn and when, not by the bytes on the link:
// in every run the first frame comes with at most 2 chunks drawn, the script crosses the
// link gzipped and the poster shows first; in the median run (a stall of the shared host
// delays one run, never all) the first frame comes at most 1 s after the first chunk's
// bytes arrived, the last chunk within 1.25x the link time of what the page took through
// the link (script, list, manifest, chunks) plus 1 s of the page's request for the
// script, and the whole picture within 1.5 s of the last chunk, or of the first frame
// where every chunk came before it (every run within 3x);
// every picture drawn reaches the screen (the GPU passes its frame), the first within
// 2 s of its draw and each later one within 1 s; a reload streams at most 5% of the
// chunk bytes and takes at most 5% of the link's, nothing below the viewer moves
// (layout shift), and each failure (server down at page load, link dropped mid-stream,
// shader files failing, server stopped after complete) ends in an `error` event and, once the server is back, in a complete picture, while a
// page holding the whole package tries no connection when its budget grows. Run: node --test tests/e2e/
import assert from 'node:assert/strict';
import {after, before, describe, it} from 'node:test';
import path from 'node:path';
import {clsRecorder, startThrottle, visit, warmGpu} from './throttle.mjs';
import {BUILD, ROOT, capture, freePort, launch, makeLibrary, newPage, requireBuild, servePages, startServer, waitFor}
  from './util.mjs';

// 32x32 texels, 81 x 81 directions, 24 components at 2 spatial levels, as `btf compress`
// writes it by default (version 4 over rate-distortion steps: the viewer asks for what
// its footprint needs, 26 chunks and about 224 KB on the phone), with its thumbnail (the
// poster). FIELD_ARGS: other compress options (e.g. "--plain", the version-2 package).
const MATERIALS = {knit: ['knit', 24, 2, (process.env.FIELD_ARGS ?? '').split(' ').filter(Boolean)]};
const RUNS = Number(process.env.FIELD_RUNS || 5); // fresh visits (each with a reload) on the 4 Mbit/s link
const PHONE = {viewport: {width: 390, height: 700}, deviceScaleFactor: 2, isMobile: true, hasTouch: true};
let lib, server, pages;

// The README's two lines (script from `host`), with text above and below the viewer.
const readme = (host, attrs = '') => `<!doctype html><html><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1"><link rel="icon" href="data:,">
<script type="module" src="${host}btf-viewer.js"></script></head>
<body><h1>A knitted jumper</h1>
<btf-viewer material="knit" geometry="sphere" camera-controls alt="Knitted wool"
style="display:inline-block;width:320px;height:320px"${attrs}></btf-viewer>
<p>Soft merino, knitted in one piece. The text below the viewer must not move while it loads.</p>
<p>Care: hand wash cold, dry flat.</p></body></html>`;

// The element from a static host (the page's own origin) and btfd at `ws`, asking for
// `budget` chunks from the start.
const staticPage = (ws, shaders, budget) => `<!doctype html><html><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1"><link rel="icon" href="data:,">
<script type="module" src="/client/btf-viewer.js"></script>
<script type="module">
  window.__events = [];
  for (const t of ['load', 'complete', 'error'])
    document.addEventListener(t, (e) => window.__events.push({type: t, detail: e.detail, at: performance.now()}));
</script></head>
<body><btf-viewer material="knit" light="fixed" src="${ws}" shaders="${shaders}" budget-chunks="${budget}"
style="width:300px;height:300px" loading="eager"></btf-viewer></body></html>`;

let shaderFailures = 0; // the next this many requests for the shader manifest answer 503

before(async () => {
  requireBuild();
  lib = makeLibrary(MATERIALS, {thumbnails: true});
  // what a deployment serves: the one-file bundle (make build: BUILD/client, shaders inside)
  server = await startServer(lib.lib, ['--client', path.join(BUILD, 'client')]);
  pages = await servePages({
    // ?link=PORT: the README page with its script from btfd through the throttled link
    readme: (req) => readme(`http://127.0.0.1:${new URL(req.url, 'http://x').searchParams.get('link')}/`),
    // ?ws=URL&shaders=URL[&budget=N]: the element from this (static) origin, streaming from ws
    static: (req) => {
      const q = new URL(req.url, 'http://x').searchParams;
      return staticPage(q.get('ws'), q.get('shaders'), Number(q.get('budget') || 1000));
    },
  }, {
    statics: {'/client/': path.join(BUILD, 'client'), '/shaders/': path.join(ROOT, 'shaders')},
    hook: (req, res) => {
      if (!req.url.startsWith('/flaky-shaders/')) return false;
      if (req.url.endsWith('/manifest.json') && shaderFailures > 0) {
        shaderFailures--;
        res.writeHead(503).end();
        return true;
      }
      req.url = req.url.replace('/flaky-shaders/', '/shaders/');
      return false;
    },
  });
});

after(async () => {
  await pages?.close();
  await server?.stop();
  lib?.remove();
});

// Every run's verdicts at bps: the first frame, its chunks, load after the first chunk,
// completion against the link time of the streamed package, and a reload.
async function fieldRuns(bps, runs) {
  const out = [];
  for (let r = 0; r < runs; r++) {
    const phone = await launch(PHONE);
    const link = await startThrottle({target: server.port, bps, delayMs: 20});
    try {
      await phone.addInitScript(clsRecorder);
      const page = await newPage(phone);
      await warmGpu(page); // as a phone's browser is: its GPU process running
      const url = `${pages.url}readme.html?link=${link.port}`;
      const first = await visit(page, url);
      const linkBytes = link.down.bytes; // everything the first visit took through the link
      const reload = await visit(page, url);
      reload.linkBytes = link.down.bytes - linkBytes; // all a reload took through the link
      assert.equal(first.error, null);
      const linkMs = (linkBytes * 8 * 1000) / bps;
      out.push({first, reload, linkMs, linkBytes});
      const problems = phone.problems.splice(0);
      assert.deepEqual(problems, [], `run ${r}: the page reported errors`);
    } finally {
      await phone.close();
      await link.close();
    }
  }
  return out;
}

function report(name, runs) {
  const f = (x) => (x === null || x === undefined ? '-' : x.toFixed(0));
  for (const [i, {first, reload, linkMs, linkBytes}] of runs.entries()) {
    const t = first.times;
    console.log(`# ${name} run ${i}: first frame ${f(first.firstFrame)} ms with ${first.chunksAtFirstFrame} chunks, ` +
      `first chunk ${f(first.firstChunk)}, load - first chunk ${f(first.firstFrame - first.firstChunk)}, ` +
      `last chunk ${f(first.lastChunk)}, complete ${f(first.complete)} (${f(first.complete - first.scriptRequest)} after ` +
      `the script request at ${f(first.scriptRequest)}; link time ${f(linkMs)} of ${linkBytes} B), ` +
      `script ${first.scriptBytes[0]} B for ${first.scriptBytes[1]}, stream ${first.streamBytes} B, cls ${first.cls.toFixed(3)}, drawn ${JSON.stringify(t.drawn)}, shown ${JSON.stringify(t.shown)}; ` +
      `script ${f(t.script)} start ${f(t.start)} open ${f(t.open)} manifest ${f(t.manifest)} gl ${f(t.gl)} ` +
      `shaders ${f(t.shaders)} decoded ${f(t.decoded)} program ${f(t.program)} (${first.decoder}); ` +
      `reload ${reload.streamBytes} B of chunks, ${reload.linkBytes} B on the link, first frame ${f(reload.firstFrame)} ms`);
  }
}

// The timing verdicts of a run (ms over their bounds; <= 0 is met): the first frame after
// the first chunk, the last chunk after the script request against the link time of what
// the page took (+ the page's own requests), the complete picture after the last chunk
// (the frame in flight, then the last one: on this machine's software GL a frame of 24
// components at 640 x 640 device pixels takes 0.3-0.5 s while chunks arrive); where
// every chunk came before the first frame (a warm browser on this link: the last chunk
// 0.1-0.3 s after the first, while the first frame builds its program, 0.5-0.7 s), after
// that frame, which has its own bound (1 s after the first chunk).
// Then what reached the screen (`shown`: when the GPU had passed a picture's frame): the
// first picture within 2 s of its draw (it includes the driver's build of the program:
// 0.5-0.6 s here) and every later one within 1 s (0.2-0.25 s here; a page whose frames
// queued up behind each other would take ever longer).
const lag = (r, i) => r.first.times.shown[i][1] - r.first.times.drawn[i][1];
const TIMINGS = {
  'load within 1 s of the first chunk': [(r) => r.first.firstFrame - r.first.firstChunk, () => 1000],
  'the first picture on the screen within 2 s of its draw': [(r) => lag(r, 0), () => 2000],
  'every later picture on the screen within 1 s of its draw':
    [(r) => Math.max(0, ...r.first.times.drawn.slice(1).map((_, i) => lag(r, i + 1))), () => 1000],
  'last chunk within 1.25 x the link time + 1 s of the script request':
    [(r) => r.first.lastChunk - r.first.scriptRequest, (r) => 1.25 * r.linkMs + 1000],
  'complete within 1.5 s of the last chunk (or of the first frame, when that is later)':
    [(r) => r.first.complete - Math.max(r.first.lastChunk, r.first.firstFrame), () => 1500],
};

const median = (xs) => {
  const s = [...xs].sort((a, b) => a - b), m = s.length >> 1;
  return s.length % 2 ? s[m] : (s[m - 1] + s[m]) / 2;
};

// What every run must show (no clock in it), then the timings: the median run within
// each bound and every run within 3x it (a page that waits for the whole package, or
// stops drawing, fails every run; a host that stalls one run for a second fails none).
function judge(runs) {
  for (const [i, {first, reload, linkBytes}] of runs.entries()) {
    const run = `run ${i}: ${JSON.stringify({...first, times: undefined})}`;
    assert.ok(first.chunksAtFirstFrame >= 1 && first.chunksAtFirstFrame <= 2, `first frame with 1-2 chunks; ${run}`);
    assert.deepEqual(first.times.shown.map(([c]) => c), first.times.drawn.map(([c]) => c),
      `every picture drawn reached the screen; ${run}`);
    assert.ok(first.cls < 0.1, `layout shift ${first.cls}; ${run}`);
    const [sent, script] = first.scriptBytes; // the bundle's body as it crossed the link, and decoded
    assert.ok(sent > 0 && sent <= 0.5 * script, `the script crossed the link gzipped: ${sent} B for ${script}; ${run}`);
    assert.match(String(first.poster), /\/materials\/knit\/thumbnail\.png$/, `the package's poster showed first; ${run}`);
    assert.ok(reload.streamBytes <= 0.05 * first.streamBytes,
      `run ${i}: the reload streamed ${reload.streamBytes} of ${first.streamBytes} bytes`);
    // everything it took through the link: the script revalidated, the list, the messages
    assert.ok(reload.linkBytes <= 0.05 * linkBytes, `run ${i}: the reload took ${reload.linkBytes} of ${linkBytes} B`);
    assert.ok(reload.cls < 0.1, `reload layout shift ${reload.cls}`);
  }
  for (const [what, [value, bound]] of Object.entries(TIMINGS)) {
    const v = runs.map(value), b = runs.map(bound), f = (xs) => xs.map((x) => x.toFixed(0)).join(' ');
    assert.ok(median(v.map((x, i) => x - b[i])) <= 0, `${what} in the median run: ${f(v)} ms against ${f(b)}`);
    v.forEach((x, i) => assert.ok(x <= 3 * b[i], `${what}: run ${i} ${x.toFixed(0)} ms, over 3 x ${b[i].toFixed(0)}`));
  }
}

describe('the README embed on a phone behind a slow link', () => {
  it(`4 Mbit/s, 40 ms: the first frame from the first chunks, complete in link time, reloads from the cache (${RUNS} runs)`,
    async () => {
      const runs = await fieldRuns(4e6, RUNS);
      report('4 Mbit/s', runs);
      judge(runs);
    });

  // Refined as the chunks came: every picture with more chunks than the one before, and at
  // least 5 pictures in the median run. On this machine's software GL the first chunk's
  // frame takes 0.65-0.75 s (the driver builds the program's pipeline) and each later one
  // 0.25-0.3 s, while the chunks arrive over 3.4 s at 0.5 Mbit/s (9-14 pictures here);
  // at 1 Mbit/s they arrive within 1.4 s, room for only 2-4 pictures on this host
  // whatever the page does. A page that draws the first chunk and then the whole
  // package draws 2.
  it('0.5 Mbit/s, 40 ms: the same, refined as the chunks came (3 runs)', async () => {
    const runs = await fieldRuns(0.5e6, 3);
    report('0.5 Mbit/s', runs);
    judge(runs);
    const drawn = runs.map((r) => r.first.times.drawn);
    for (const d of drawn) assert.ok(d.every(([c], i) => i === 0 || c > d[i - 1][0]), `drawn ${JSON.stringify(d)}`);
    assert.ok(median(drawn.map((d) => d.length)) >= 5, `pictures drawn: ${JSON.stringify(drawn)}`);
  });
});

// A phone page of the static origin; events recorded in window.__events.
async function staticVisit(ctx, ws, shaders, budget = 1000) {
  const page = await newPage(ctx);
  await page.goto(`${pages.url}static.html?ws=${encodeURIComponent(ws)}&shaders=${encodeURIComponent(shaders)}` +
    `&budget=${budget}`);
  return page;
}

const events = (page, type) => page.evaluate((t) => window.__events.filter((e) => e.type === t), type);

// The picture is whole: every chunk drawn and something other than background on the canvas.
async function assertComplete(page) {
  await waitFor(page, () => {
    const v = window.__btf?.viewers()[0];
    return v && v.complete && v.drawnChunks === v.ownLimit && v.drawnChunks === v.manifestChunks;
  }, null, 'the complete picture', 60000);
  const c = await capture(page, 0);
  let fg = 0;
  for (let p = 0; p < c.data.length; p += 4) if (Math.abs(c.data[p] - c.data[0]) > 8) fg++;
  assert.ok(fg / (c.width * c.height) > 0.1, 'the material covers the canvas');
  assert.equal((await page.evaluate(() => window.__btf.viewers()[0])).message, null, 'no message left');
}

// Console lines a failure case may show: the browser's own reports of refused or cut
// connections (a request in flight when the link drops, e.g. the poster: cut before its
// headers, or within its body, ERR_CONTENT_LENGTH_MISMATCH).
const refused = (p) => /ERR_CONNECTION_(REFUSED|RESET|CLOSED)|ERR_EMPTY_RESPONSE|ERR_CONTENT_LENGTH_MISMATCH|WebSocket connection to .* failed|503 \(Service Unavailable\)/.test(p);

describe('failures a page owner can handle', () => {
  it('btfd down at page load: an error event and a message, then the picture once it is up', async () => {
    const port = await freePort();
    const ctx = await launch(PHONE);
    let late;
    try {
      const page = await staticVisit(ctx, `ws://127.0.0.1:${port}/stream`, `${pages.url}shaders/`);
      const err = await waitFor(page, () => window.__events.find((e) => e.type === 'error'), null, 'the error event');
      assert.equal(err.detail.retrying, true);
      assert.match(err.detail.reason, /cannot reach/);
      const v = (await page.evaluate(() => window.__btf.viewers()[0]));
      assert.match(String(v.message), /cannot reach .*trying again/, 'a visible message');
      assert.deepEqual(v.canvas.map((x) => x > 100), [true, true], 'the viewer has its size');
      late = await startServer(lib.lib, [], port);
      await assertComplete(page);
      assert.equal((await events(page, 'error')).length, 1, 'one error event for the outage');
      assert.deepEqual(ctx.problems.filter((p) => !refused(p)), []);
    } finally {
      await ctx.close();
      await late?.stop();
    }
  });

  it('the link dropped mid-stream: an error event, then the rest resumes and completes', async () => {
    // 0.5 Mbit/s: the default package (224 KB) takes 3.6 s, so the drop after its second
    // chunk arrived lands mid-stream however long the page takes to draw its first
    const link = await startThrottle({target: server.port, bps: 0.5e6, delayMs: 20});
    const ctx = await launch(PHONE);
    try {
      const page = await staticVisit(ctx, `ws://127.0.0.1:${link.port}/stream`, `${pages.url}shaders/`);
      await waitFor(page, () => window.__btf?.viewers()[0]?.received >= 2, null, 'two chunks arrived');
      const before = (await page.evaluate(() => window.__btf.viewers()[0])).received;
      await link.drop(1500);
      const err = await waitFor(page, () => window.__events.find((e) => e.type === 'error'), null, 'the error event');
      assert.equal(err.detail.retrying, true);
      await assertComplete(page);
      const s = (await page.evaluate(() => window.__btf.streams()))[0];
      assert.ok(s.connects >= 2, `reconnected (${s.connects} connections)`);
      assert.ok(before >= 2 && before < 24, `dropped mid-stream after ${before} chunks`);
      assert.deepEqual(ctx.problems.filter((p) => !refused(p)), []);
    } finally {
      await ctx.close();
      await link.close();
    }
  });

  it('shader files failing at first: an error event, then they load and the picture completes', async () => {
    const ctx = await launch(PHONE);
    try {
      shaderFailures = 2;
      const page = await staticVisit(ctx, server.ws, `${pages.url}flaky-shaders/`);
      const err = await waitFor(page, () => window.__events.find((e) => e.type === 'error'), null, 'the error event');
      assert.match(err.detail.reason, /shader.*503/);
      await assertComplete(page);
      assert.equal(shaderFailures, 0);
      assert.deepEqual(ctx.problems.filter((p) => !refused(p)), []);
    } finally {
      shaderFailures = 0;
      await ctx.close();
    }
  });

  it('btfd stopped after complete: no reconnects until more is asked, then an error event and the picture', async () => {
    const port = await freePort();
    let own = await startServer(lib.lib, [], port);
    const ctx = await launch(PHONE);
    try {
      // six chunks asked from the start: set after the page loaded, the budget came too
      // late for a package this small on a local link (all of it had arrived), and the
      // larger budget then needed no server
      const page = await staticVisit(ctx, `ws://127.0.0.1:${port}/stream`, `${pages.url}shaders/`, 6);
      await waitFor(page, () => window.__btf?.viewers()[0]?.complete && window.__btf.viewers()[0].drawnChunks === 6,
        null, 'six chunks');
      await own.stop();
      own = null;
      await new Promise((r) => setTimeout(r, 3000));
      const s = (await page.evaluate(() => window.__btf.streams()))[0];
      assert.equal(s.attempts, 1, 'no reconnects while nothing is missing');
      assert.deepEqual(ctx.problems, [], 'no console errors');
      assert.equal((await events(page, 'error')).length, 0);
      await page.evaluate(() => { document.querySelector('btf-viewer').budgetChunks = 1000; });
      await waitFor(page, () => window.__events.some((e) => e.type === 'error'), null, 'the error event');
      own = await startServer(lib.lib, [], port);
      await assertComplete(page);
      assert.deepEqual(ctx.problems.filter((p) => !refused(p)), []);
    } finally {
      await ctx.close();
      await own?.stop();
    }
  });

  it('btfd stopped after the whole package arrived: a larger budget asks nothing, no error', async () => {
    const port = await freePort();
    let own = await startServer(lib.lib, [], port);
    const ctx = await launch(PHONE);
    try {
      const page = await staticVisit(ctx, `ws://127.0.0.1:${port}/stream`, `${pages.url}shaders/`);
      await assertComplete(page); // every chunk of the manifest drawn
      await own.stop();
      own = null;
      await page.evaluate(() => { document.querySelector('btf-viewer').budgetChunks = 2000; });
      await new Promise((r) => setTimeout(r, 2000)); // a reconnect would be tried at once
      const s = (await page.evaluate(() => window.__btf.streams()))[0];
      assert.equal(s.attempts, 1, 'no connection for a budget that cannot bring anything');
      assert.equal((await events(page, 'error')).length, 0, 'no error event');
      assert.deepEqual(ctx.problems, [], 'no console errors');
      assert.equal((await page.evaluate(() => window.__btf.viewers()[0])).message, null, 'no message');
    } finally {
      await ctx.close();
      await own?.stop();
    }
  });
});
