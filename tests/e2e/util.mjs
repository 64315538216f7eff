// util.mjs - helpers of the browser tests: the built tools, a small material library
// made by them, btfd on a free loopback port, Chromium (playwright-core, Debian's
// /usr/bin/chromium at nice 10 through chromium-nice.sh, with CHROMIUM_ARGS: no sandbox,
// software GL through SwiftShader, no network side traffic; a fresh profile), page error collection, PNG read/write (node:zlib) and image differences.
import assert from 'node:assert/strict';
import {spawn, spawnSync} from 'node:child_process';
import {createHash} from 'node:crypto';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import zlib from 'node:zlib';
import {fileURLToPath} from 'node:url';

export const ROOT = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '../..');
export const BUILD = path.resolve(ROOT, process.env.BTF_BUILD || 'build');
export const BTF = path.join(BUILD, 'btf');
export const BTFD = path.join(BUILD, 'btfd');
export const CHROMIUM = process.env.CHROMIUM || path.join(ROOT, 'tests/e2e/chromium-nice.sh');

export const CHROMIUM_ARGS = ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
  '--disable-quic', '--no-first-run', '--disable-background-networking', '--disable-component-update',
  '--disable-sync', '--no-proxy-server'];

function run(cmd, args) {
  const r = spawnSync(cmd, args, {encoding: 'utf8', cwd: ROOT});
  if (r.status !== 0)
    throw new Error(`${path.basename(cmd)} ${args.join(' ')} failed (${r.status}): ${r.stderr || r.error}`);
  return r.stdout;
}

export function requireBuild() {
  for (const f of [BTF, BTFD])
    if (!fs.existsSync(f)) throw new Error(`${f} is missing: run \`make build\` first (or set BTF_BUILD)`);
}

// true when build/btf has the `render` subcommand (tools/cmd_render.c).
export function hasRender() {
  const r = spawnSync(BTF, ['render', '--help'], {encoding: 'utf8'});
  const text = `${r.stdout}${r.stderr}`;
  return !r.error && /render/.test(text) && !/unknown (sub)?command/i.test(text);
}

// Library of small packages in a temp dir: name -> [generator kind, components,
// optional spatial levels (a version-2 package, doc/package-format.md section 10),
// optional further `btf compress` arguments, optional further `btf gen` arguments];
// without {thumbnails: true} the packages have no thumbnail.png (no poster).
//
// The test files share packages: one made with the same name, generator and compress
// arguments by the same build/btf (its bytes hashed) is copied from BUILD/e2e-cache/,
// where the first file to need it left it (a file given as an argument counts by its
// content). btf compress is deterministic, so the copy is the package this run's btf
// writes; a rebuilt btf has another hash, and its first makeLibrary drops the old cache.
// BTF_E2E_CACHE=0: every package made afresh.
let cacheRoot;
function packageCache() {
  if (cacheRoot !== undefined) return cacheRoot;
  cacheRoot = null;
  if (process.env.BTF_E2E_CACHE === '0') return cacheRoot;
  if (!fs.existsSync(BTF)) return cacheRoot;
  const top = path.join(BUILD, 'e2e-cache'), id = createHash('sha256').update(fs.readFileSync(BTF)).digest('hex').slice(0, 16);
  fs.mkdirSync(top, {recursive: true});
  for (const e of fs.readdirSync(top))
    if (e !== id) fs.rmSync(path.join(top, e), {recursive: true, force: true});
  cacheRoot = path.join(top, id);
  fs.mkdirSync(cacheRoot, {recursive: true});
  return cacheRoot;
}

function cacheKey(parts) {
  const withFiles = parts.map((a) => (typeof a === 'string' && path.isAbsolute(a) && fs.existsSync(a) &&
    fs.statSync(a).isFile() ? ['file', fs.readFileSync(a, 'base64')] : a));
  return createHash('sha256').update(JSON.stringify(withFiles)).digest('hex').slice(0, 32);
}

export function makeLibrary(materials, {thumbnails = false} = {}) {
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'btf-e2e-'));
  const lib = path.join(dir, 'lib');
  fs.mkdirSync(lib);
  const cache = packageCache();
  for (const [name, [kind, comps, levels, extra = [], genExtra = []]] of Object.entries(materials)) {
    const src = path.join(dir, `${name}.btf`), out = path.join(lib, name);
    const genArgs = ['--size', '32', '--format', 'btf', '--components', '16', ...genExtra];
    const compressArgs = ['--k', '3', '--components', String(comps), '--quiet',
      ...(levels ? ['--levels', String(levels)] : []), ...(thumbnails ? [] : ['--no-thumbnail']), ...extra];
    const cached = cache && path.join(cache, cacheKey([name, kind, ...genArgs, '|', ...compressArgs]));
    if (cached && fs.existsSync(cached)) {
      fs.cpSync(cached, out, {recursive: true});
      continue;
    }
    run(BTF, ['gen', kind, src, ...genArgs]);
    run(BTF, ['compress', src, out, ...compressArgs]);
    fs.rmSync(src);
    if (cached) { // written whole beside it, then renamed: a reader never sees a half package
      const tmp = `${cached}.tmp-${process.pid}`;
      fs.cpSync(out, tmp, {recursive: true});
      try { fs.renameSync(tmp, cached); } catch { fs.rmSync(tmp, {recursive: true, force: true}); }
    }
  }
  return {dir, lib, remove: () => fs.rmSync(dir, {recursive: true, force: true})};
}

// A direction list (doc/data-model.md): n directions on a golden-angle spiral down to
// 80 degrees, rotated by rot degrees, written as JSON to a temp file; returns its path.
export function writeSpiralList(n, rot) {
  const dirs = Array.from({length: n}, (_, i) => {
    const z = 1 - (i + 0.5) / n * (1 - Math.cos(80 * Math.PI / 180));
    return {theta: Math.acos(z) * 180 / Math.PI, phi: (i * 137.50776 + rot) % 360};
  });
  const file = path.join(fs.mkdtempSync(path.join(os.tmpdir(), 'btf-list-')), 'spiral.json');
  fs.writeFileSync(file, JSON.stringify({directions: dirs}));
  return file;
}

// Starts btfd on a free loopback port, or `port` (extra: more options); resolves {port,
// url, ws, pagesUrl, stop()}. It serves client/ (the source modules) unless extra has a
// --client; pagesUrl: where the demo pages are, client/pages/ in the source tree, the
// root in a bundle (tools/bundle.mjs).
export function startServer(lib, extra = [], port = 0) {
  const pagesUrl = (url) => (extra.includes('--client') ? url : `${url}pages/`);
  return new Promise((resolve, reject) => {
    const p = spawn(BTFD, ['--library', lib, '--port', String(port), '--client', path.join(ROOT, 'client'),
      '--shaders', path.join(ROOT, 'shaders'), ...extra], {cwd: ROOT, stdio: ['ignore', 'pipe', 'pipe']});
    let out = '', err = '';
    const timer = setTimeout(() => {
      p.kill();
      reject(new Error(`btfd did not start: ${out} ${err}`));
    }, 10000);
    p.stderr.on('data', (d) => { err += d; });
    p.stdout.on('data', (d) => {
      out += d;
      const m = /listening on http:\/\/[\d.]+:(\d+)\//.exec(out);
      if (m) {
        clearTimeout(timer);
        const port = +m[1];
        const url = `http://127.0.0.1:${port}/`;
        resolve({port, url, ws: `ws://127.0.0.1:${port}/stream`, pagesUrl: pagesUrl(url), proc: p,
          stop: () => new Promise((res) => {
            if (p.exitCode !== null) return res();
            p.once('exit', res);
            p.kill('SIGTERM');
          })});
      }
    });
    p.once('exit', (code) => reject(new Error(`btfd exited (${code}): ${err}`)));
  });
}

// A child process serving HTTP on `port` (polled until it answers, any status); resolves {stop()}.
export async function serveProcess(cmd, args, port, opts = {}) {
  const http = await import('node:http');
  const p = spawn(cmd, args, {stdio: ['ignore', 'ignore', 'pipe'], ...opts});
  let err = '';
  p.stderr.on('data', (d) => { err += d; });
  for (let t = 0; ; t += 50) {
    const ok = await new Promise((r) => http.get(`http://127.0.0.1:${port}/`, (res) => { res.resume(); r(true); })
      .on('error', () => r(false)));
    if (ok) break;
    if (t > 10000 || p.exitCode !== null) throw new Error(`${cmd} did not start: ${err}`);
    await new Promise((r) => setTimeout(r, 50));
  }
  return {stop: () => new Promise((r) => (p.exitCode !== null ? r() : (p.once('exit', r), p.kill('SIGTERM'))))};
}

// nginx (Debian's) serving the folder `root` as a static host on `port`: files as they are,
// Access-Control-Allow-Origin: * added and nothing else; its prefix a new folder under
// `tmp`, which is made readable to nginx's workers (they run as another user under root).
export async function startNginx(root, port, tmp) {
  const bin = ['/usr/sbin/nginx', '/usr/bin/nginx'].find((f) => fs.existsSync(f));
  if (!bin) throw new Error('nginx is missing: run `make setup` (nginx-light)');
  fs.chmodSync(tmp, 0o755);
  const prefix = fs.mkdtempSync(path.join(tmp, 'nginx-'));
  fs.writeFileSync(path.join(prefix, 'nginx.conf'), `daemon off; worker_processes 1; pid ${prefix}/nginx.pid;
error_log ${prefix}/error.log;
events { worker_connections 256; }
http {
  access_log off;
  types { text/html html; text/javascript js; application/json json; image/png png; image/webp webp;
    image/avif avif; }
  default_type application/octet-stream;
  client_body_temp_path ${prefix}/body; proxy_temp_path ${prefix}/proxy; fastcgi_temp_path ${prefix}/fcgi;
  uwsgi_temp_path ${prefix}/uwsgi; scgi_temp_path ${prefix}/scgi;
  server {
    listen 127.0.0.1:${port};
    root ${root};
    add_header Access-Control-Allow-Origin *;
  }
}
`);
  return serveProcess(bin, ['-p', prefix, '-c', path.join(prefix, 'nginx.conf'), '-e', path.join(prefix, 'error.log')],
    port);
}

// A fresh browser context (own profile dir) with page errors and console errors
// collected in ctx.problems. Options as playwright's launchPersistentContext. With
// keepProfile (a directory) that profile is used and kept (a second visit).
export async function launch(options = {}, keepProfile = null) {
  const {chromium} = await import('playwright-core');
  const profile = keepProfile || fs.mkdtempSync(path.join(os.tmpdir(), 'btf-chromium-'));
  const ctx = await chromium.launchPersistentContext(profile, {
    executablePath: CHROMIUM, headless: true, args: CHROMIUM_ARGS, viewport: {width: 1000, height: 700},
    ...options,
  });
  watchProblems(ctx);
  const close = ctx.close.bind(ctx);
  ctx.close = async () => {
    await close();
    if (!keepProfile) fs.rmSync(profile, {recursive: true, force: true});
  };
  return ctx;
}

// Collects the page errors and console errors of ctx's pages in ctx.problems.
function watchProblems(ctx) {
  ctx.problems = [];
  const watch = (page) => {
    page.on('pageerror', (e) => ctx.problems.push(`page error: ${e.message}`));
    page.on('console', (m) => {
      if (m.type() === 'error') ctx.problems.push(`console error: ${m.text()}`);
    });
  };
  ctx.pages().forEach(watch);
  ctx.on('page', watch);
}

// One Chromium for the tests of a file (its after() closes it), where each test takes a
// fresh context of it (freshContext): a file's tests pay for one browser start, not one each.
export async function launchBrowser(options = {}) {
  const {chromium} = await import('playwright-core');
  return chromium.launch({executablePath: CHROMIUM, headless: true, args: CHROMIUM_ARGS, ...options});
}

// A new context of browser (launchBrowser): its own cookies, storage and HTTP cache, as a
// fresh profile of launch() has; problems collected as launch() does.
export async function freshContext(browser, options = {}) {
  const ctx = await browser.newContext({viewport: {width: 1000, height: 700}, ...options});
  watchProblems(ctx);
  return ctx;
}

// Fails when the context's pages reported errors since the last check (and forgets them).
export function assertClean(ctx) {
  const p = ctx.problems.splice(0);
  assert.deepEqual(p, [], `the page reported errors:\n${p.join('\n')}`);
}

export async function newPage(ctx) {
  return ctx.pages()[0] || ctx.newPage();
}

// Polls fn (evaluated in the page) until it returns a truthy value.
export async function waitFor(page, fn, arg, what, timeout = 60000) {
  const t0 = Date.now();
  for (;;) {
    const v = await page.evaluate(fn, arg);
    if (v) return v;
    if (Date.now() - t0 > timeout) {
      const st = await page.evaluate(() => window.__btf && window.__btf.viewers()).catch(() => null);
      throw new Error(`timed out waiting for ${what}; viewers: ${JSON.stringify(st)}`);
    }
    await new Promise((r) => setTimeout(r, 100));
  }
}

export const viewers = (page) => page.evaluate(() => window.__btf.viewers());

// Canvas pixels of viewer i: {width, height, data: Uint8Array RGBA top-down}.
export async function capture(page, i = 0) {
  const c = await page.evaluate((k) => window.__btf.capture(k), i);
  return {width: c.width, height: c.height, chunks: c.chunks, data: new Uint8Array(Buffer.from(c.rgba, 'base64'))};
}

// Mean absolute difference over RGB, 0..255.
export function meanAbsDiff(a, b) {
  if (a.width !== b.width || a.height !== b.height) throw new Error('image sizes differ');
  let s = 0;
  for (let i = 0; i < a.data.length; i += 4)
    s += Math.abs(a.data[i] - b.data[i]) + Math.abs(a.data[i + 1] - b.data[i + 1]) + Math.abs(a.data[i + 2] - b.data[i + 2]);
  return s / (3 * a.width * a.height);
}

// Largest channel difference per pixel over the pixels where either image shows the
// object; `inner`: the worst over pixels whose 3 x 3 neighbourhood is the object in both
// (the silhouette's pixels depend on each rasteriser's coverage rule).
export function compareCovered(img, ref) {
  assert.deepEqual([img.width, img.height], [ref.width, ref.height]);
  const W = img.width, H = img.height, bg = (a, i) => a[i] === 31 && a[i + 1] === 31 && a[i + 2] === 31;
  const diffs = [];
  let inner = 0, innerN = 0, innerOk = 0;
  for (let y = 0; y < H; y++)
    for (let x = 0; x < W; x++) {
      const i = 4 * (y * W + x);
      if (bg(ref.data, i) && bg(img.data, i)) continue; // the background (0.12 grey) in both
      const d = Math.max(...[0, 1, 2].map((c) => Math.abs(img.data[i + c] - ref.data[i + c])));
      diffs.push(d);
      let edge = x === 0 || y === 0 || x === W - 1 || y === H - 1;
      for (let dy = -1; dy <= 1 && !edge; dy++)
        for (let dx = -1; dx <= 1; dx++) {
          const k = i + 4 * (dy * W + dx);
          if (bg(ref.data, k) || bg(img.data, k)) edge = true;
        }
      if (!edge) {
        inner = Math.max(inner, d);
        innerN++;
        innerOk += d <= 2;
      }
    }
  diffs.sort((a, b) => a - b);
  const within = (t) => diffs.filter((d) => d <= t).length / diffs.length;
  return {covered: diffs.length, worst: diffs[diffs.length - 1] ?? 0, inner, innerWithin2: innerOk / innerN,
    p999: diffs[Math.floor(0.999 * (diffs.length - 1))] ?? 0, within1: within(1), within2: within(2),
    mean: diffs.reduce((a, d) => a + d, 0) / diffs.length};
}

// ------------------------------------------------------------------ PNG

const CRC = new Int32Array(256).map((_, n) => {
  let c = n;
  for (let k = 0; k < 8; k++) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
  return c;
});

function crc32(buf) {
  let c = -1;
  for (const b of buf) c = CRC[(c ^ b) & 255] ^ (c >>> 8);
  return (c ^ -1) >>> 0;
}

function chunk(type, data) {
  const len = Buffer.alloc(4);
  len.writeUInt32BE(data.length);
  const td = Buffer.concat([Buffer.from(type, 'ascii'), data]);
  const crc = Buffer.alloc(4);
  crc.writeUInt32BE(crc32(td));
  return Buffer.concat([len, td, crc]);
}

// Writes RGBA8 pixels (top-down) as an RGB PNG through a temp name + rename.
export function writePng(file, img) {
  const {width, height, data} = img;
  const raw = Buffer.alloc((3 * width + 1) * height);
  for (let y = 0; y < height; y++) {
    raw[y * (3 * width + 1)] = 0;
    for (let x = 0; x < width; x++)
      for (let c = 0; c < 3; c++) raw[y * (3 * width + 1) + 1 + 3 * x + c] = data[4 * (y * width + x) + c];
  }
  const ihdr = Buffer.alloc(13);
  ihdr.writeUInt32BE(width, 0);
  ihdr.writeUInt32BE(height, 4);
  ihdr.set([8, 2, 0, 0, 0], 8);
  const png = Buffer.concat([Buffer.from([137, 80, 78, 71, 13, 10, 26, 10]), chunk('IHDR', ihdr),
    chunk('IDAT', zlib.deflateSync(raw, {level: 9})), chunk('IEND', Buffer.alloc(0))]);
  const tmp = `${file}.tmp-${process.pid}`;
  fs.writeFileSync(tmp, png);
  fs.renameSync(tmp, file);
}

// Reads an 8-bit non-interlaced PNG (grey, grey+alpha, RGB, RGBA) into RGBA8.
export function readPng(file) {
  const buf = fs.readFileSync(file);
  let off = 8, width = 0, height = 0, depth = 0, type = 0, interlace = 0;
  const idat = [];
  while (off < buf.length) {
    const len = buf.readUInt32BE(off), t = buf.toString('ascii', off + 4, off + 8);
    const d = buf.subarray(off + 8, off + 8 + len);
    if (t === 'IHDR') [width, height, depth, type, interlace] = [d.readUInt32BE(0), d.readUInt32BE(4), d[8], d[9], d[12]];
    if (t === 'IDAT') idat.push(d);
    off += 12 + len;
  }
  const ch = {0: 1, 4: 2, 2: 3, 6: 4}[type];
  if (depth !== 8 || !ch || interlace) throw new Error(`${file}: unsupported PNG (depth ${depth}, type ${type})`);
  const raw = zlib.inflateSync(Buffer.concat(idat));
  const stride = width * ch, px = new Uint8Array(stride * height);
  for (let y = 0; y < height; y++) {
    const f = raw[y * (stride + 1)], line = raw.subarray(y * (stride + 1) + 1, (y + 1) * (stride + 1));
    for (let x = 0; x < stride; x++) {
      const a = x >= ch ? px[y * stride + x - ch] : 0, b = y ? px[(y - 1) * stride + x] : 0;
      const c = x >= ch && y ? px[(y - 1) * stride + x - ch] : 0;
      let p = line[x];
      if (f === 1) p += a;
      else if (f === 2) p += b;
      else if (f === 3) p += (a + b) >> 1;
      else if (f === 4) {
        const q = a + b - c, pa = Math.abs(q - a), pb = Math.abs(q - b), pc = Math.abs(q - c);
        p += pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
      }
      px[y * stride + x] = p & 255;
    }
  }
  const data = new Uint8Array(4 * width * height);
  for (let i = 0; i < width * height; i++) {
    const s = px.subarray(i * ch, i * ch + ch);
    data.set(ch < 3 ? [s[0], s[0], s[0]] : [s[0], s[1], s[2]], 4 * i);
    data[4 * i + 3] = ch === 2 || ch === 4 ? s[ch - 1] : 255;
  }
  return {width, height, data};
}

// Side-by-side image of several captures (same height), 8-pixel dark gaps.
export function sideBySide(images) {
  const gap = 8, h = Math.max(...images.map((i) => i.height));
  const w = images.reduce((s, i) => s + i.width, 0) + gap * (images.length - 1);
  const data = new Uint8Array(4 * w * h).fill(24);
  let x0 = 0;
  for (const img of images) {
    for (let y = 0; y < img.height; y++)
      data.set(img.data.subarray(4 * y * img.width, 4 * (y + 1) * img.width), 4 * (y * w + x0));
    x0 += img.width + gap;
  }
  return {width: w, height: h, data};
}

const TYPES = {'.js': 'text/javascript', '.json': 'application/json', '.html': 'text/html'};

// A page server on another loopback port (another origin than btfd): GET /NAME.html
// answers pages[NAME] (HTML text); with statics {'/prefix/': directory}, GET /prefix/FILE
// answers that directory's plain file (a static host: no CORS header); hook(req, res)
// may answer a request first (returns true). Resolves {url, port, close()}.
export async function servePages(pages, {statics = {}, hook = null} = {}) {
  const http = await import('node:http');
  const srv = http.createServer((req, res) => {
    if (hook && hook(req, res)) return;
    const pathname = new URL(req.url, 'http://x').pathname;
    for (const [prefix, dir] of Object.entries(statics)) {
      const file = pathname.startsWith(prefix) ? pathname.slice(prefix.length) : null;
      if (file === null || !/^[A-Za-z0-9_.-]+$/.test(file) || file[0] === '.') continue;
      const full = path.join(dir, file);
      if (!fs.existsSync(full)) break;
      res.writeHead(200, {'content-type': TYPES[path.extname(file)] || 'text/plain', 'cache-control': 'no-cache'});
      res.end(fs.readFileSync(full));
      return;
    }
    const name = pathname.replace(/^\/|\.html$/g, '');
    if (!(name in pages)) {
      res.writeHead(404).end();
      return;
    }
    res.writeHead(200, {'content-type': 'text/html; charset=utf-8', 'cache-control': 'no-store'});
    res.end(typeof pages[name] === 'function' ? pages[name](req) : pages[name]);
  });
  await new Promise((r) => srv.listen(0, '127.0.0.1', r));
  return {url: `http://127.0.0.1:${srv.address().port}/`, port: srv.address().port,
    close: () => new Promise((r) => {
      srv.closeAllConnections?.();
      srv.close(r);
    })};
}

// Every text frame the server sent on the page's WebSockets, parsed (frames.text), and
// the binary payload bytes (frames.binary), as the browser's network layer saw them.
// A loopback port nothing listens on now (for a server started later, or never).
export async function freePort() {
  const net = await import('node:net');
  const srv = net.createServer();
  await new Promise((r) => srv.listen(0, '127.0.0.1', r));
  const {port} = srv.address();
  await new Promise((r) => srv.close(r));
  return port;
}

export function watchFrames(page) {
  const frames = {text: [], binary: 0, textBytes: 0, sockets: 0};
  page.on('websocket', (ws) => {
    frames.sockets++;
    ws.on('framereceived', (f) => {
      if (typeof f.payload === 'string') {
        frames.text.push(JSON.parse(f.payload));
        frames.textBytes += Buffer.byteLength(f.payload);
      } else frames.binary += f.payload.length;
    });
  });
  return frames;
}
