// private.test.mjs - a private library (btfd --token-secret-file, doc/deploy.md "Private
// libraries") as a page sees it: <btf-viewer token="..."> draws every chunk over the
// WebSocket and over HTTP (btfd's file routes, ?token=); without a token, or with an
// expired one or one for another material, the viewer shows one error naming the
// refusal and draws nothing from the package. Tokens are signed here with Python's
// hmac (apart from btfd's own code).
// Run: node --test tests/e2e/private.test.mjs
import assert from 'node:assert/strict';
import {spawnSync} from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import {after, before, describe, it} from 'node:test';
import {freshContext, launchBrowser, makeLibrary, newPage, requireBuild, servePages, startServer, waitFor} from './util.mjs';

let lib, srv, pages, secret, browser;

// v1:SCOPE:EXPIRES:SIG signed by Python, expiring `ttl` seconds from now (negative: past).
function token(scope, ttl, key = secret) {
  const r = spawnSync('python3', ['-c', `import base64,hashlib,hmac,sys,time
k=open(sys.argv[1],"rb").read().rstrip(b"\\n"); s=sys.argv[2]; e=str(int(time.time())+int(sys.argv[3]))
sig=hmac.new(k,("btf-token-v1:%s:%s"%(s,e)).encode(),hashlib.sha256).digest()
print("v1:%s:%s:%s"%(s,e,base64.urlsafe_b64encode(sig).rstrip(b"=").decode()))`, key, scope, String(ttl)],
  {encoding: 'utf8'});
  assert.equal(r.status, 0, r.stderr);
  return r.stdout.trim();
}

const page = (src, tok) => `<!doctype html><html><head><meta charset="utf-8"><link rel="icon" href="data:,">
<script type="module" src="${srv.url}btf-viewer.js"></script></head><body>
<btf-viewer src="${src}" material="knit" light="fixed" loading="eager"${tok ? ` token="${tok}"` : ''}
style="display:inline-block;width:200px;height:200px"></btf-viewer>
<script>window.errors = []; document.querySelector('btf-viewer').addEventListener('error', (e) => errors.push(e.detail.reason));</script>
</body></html>`;

before(async () => {
  requireBuild();
  lib = makeLibrary({knit: ['knit', 4], tiles: ['tiles', 4]});
  secret = path.join(lib.dir, 'secret');
  fs.writeFileSync(secret, 'an e2e secret of thirty-two b!!\n', {mode: 0o600});
  srv = await startServer(lib.lib, ['--token-secret-file', secret, '--rescan-ms', '0']);
  browser = await launchBrowser();
});

after(async () => {
  await srv?.stop();
  await pages?.close();
  await browser?.close();
  lib?.remove();
});

// The page's viewer once it completed or failed: {state, errors}.
async function show(html) {
  pages = await servePages({index: html});
  const ctx = await freshContext(browser); // its own cookies, storage and cache: nothing from the test before
  try {
    const p = await newPage(ctx);
    await p.goto(`${pages.url}index.html`);
    await waitFor(p, () => {
      const v = window.__btf?.viewers()[0];
      return v && (v.complete && v.drawnChunks === v.ownLimit || window.errors.length > 0);
    }, null, 'the viewer completes or fails', 60000);
    return {state: (await p.evaluate(() => window.__btf.viewers()))[0], errors: await p.evaluate(() => window.errors),
      transport: (await p.evaluate(() => window.__btf.streams()))[0]?.transport};
  } finally {
    await ctx.close();
    await pages.close();
    pages = null;
  }
}

describe('a private library', () => {
  for (const [how, src] of [['WebSocket', () => srv.ws], ['HTTP', () => srv.url]]) {
    it(`${how}: a token for the material draws every chunk`, async () => {
      const r = await show(page(src(), token('knit', 600)));
      assert.deepEqual(r.errors, []);
      assert.ok(r.state.complete && r.state.drawnChunks === r.state.ownLimit && r.state.ownLimit >= 1,
        JSON.stringify({complete: r.state.complete, drawn: r.state.drawnChunks, limit: r.state.ownLimit}));
      assert.equal(r.transport, how === 'HTTP' ? 'http' : 'ws');
    });
    it(`${how}: a prefix token (k*) draws too`, async () => {
      const r = await show(page(src(), token('k*', 600)));
      assert.deepEqual(r.errors, []);
      assert.ok(r.state.complete);
    });
    for (const [what, tok, code] of [['no token', null, 'forbidden'], ['an expired token', () => token('knit', -5),
      how === 'HTTP' ? 'forbidden' : 'token_expired'], ['a token for another material', () => token('tiles', 600), 'forbidden']]) {
      it(`${how}: ${what} is refused with one clear error and nothing drawn`, async () => {
        const r = await show(page(src(), tok && tok()));
        assert.equal(r.errors.length, 1, JSON.stringify(r.errors));
        assert.match(r.errors[0], new RegExp(code), r.errors[0]);
        assert.equal(r.state.drawnChunks || 0, 0);
      });
    }
  }
});
