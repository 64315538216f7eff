// bench/lossy_browser.mjs - does the browser decode a lossy grey WebP texture to the
// bytes the C side measures? Decodes each DIR/qQ.webp that `LOSSY_DUMP=DIR
// build/bench/bench_lossy` wrote in headless Chromium the way the client does
// (client/btf-decode.js: createImageBitmap without colour conversion or
// premultiplication, an OffscreenCanvas 2D context, getImageData; the texture is the
// R byte, client/btf-gl.js readAtlas) and compares it with libwebp's decode
// (WebPDecodeRGB's R, DIR/qQ.grey): pixels that differ, the largest difference, and
// the pixels where the browser's G differs from its R.
//
//   LOSSY_DUMP=/tmp/lossy-dump LOSSY_MATERIALS=tiles64=gen:tiles:64:3621 build/bench/bench_lossy
//   node bench/lossy_browser.mjs /tmp/lossy-dump
import fs from 'node:fs';
import path from 'node:path';
import {CHROMIUM_ARGS, launch} from '../tests/e2e/util.mjs';

const dir = process.argv[2];
if (!dir) {
  console.error('usage: node bench/lossy_browser.mjs DIR (written by LOSSY_DUMP=DIR bench_lossy)');
  process.exit(2);
}
const files = fs.readdirSync(dir).filter((f) => f.endsWith('.webp')).sort();
const ctx = await launch({args: CHROMIUM_ARGS});
const page = await ctx.newPage();
await page.setContent('<!doctype html><title>lossy</title>');
console.log(`# chromium ${ctx.browser()?.version() ?? '(persistent context)'}`);
let bad = 0;
for (const f of files) {
  const webp = fs.readFileSync(path.join(dir, f));
  const ref = fs.readFileSync(path.join(dir, f.replace(/\.webp$/, '.grey')));
  const got = await page.evaluate(async (b64) => {
    const buf = Uint8Array.from(atob(b64), (c) => c.charCodeAt(0));
    const bm = await createImageBitmap(new Blob([buf], {type: 'image/webp'}),
      {premultiplyAlpha: 'none', colorSpaceConversion: 'none'});
    const c = new OffscreenCanvas(bm.width, bm.height);
    const g = c.getContext('2d', {willReadFrequently: true, alpha: false});
    g.drawImage(bm, 0, 0);
    const d = g.getImageData(0, 0, bm.width, bm.height).data;
    const r = new Array(bm.width * bm.height);
    let rg = 0;
    for (let i = 0; i < r.length; i++) {
      r[i] = d[4 * i];
      rg += d[4 * i + 1] !== d[4 * i];
    }
    return {w: bm.width, h: bm.height, r, rg};
  }, webp.toString('base64'));
  let diff = 0, max = 0;
  for (let i = 0; i < ref.length; i++) {
    const e = Math.abs(got.r[i] - ref[i]);
    diff += e !== 0;
    max = Math.max(max, e);
  }
  bad += diff !== 0 || got.r.length !== ref.length;
  const name = f.replace(/\.webp$/, '');
  console.log(`lossy_browser_${name}_pixels ${ref.length} px`);
  console.log(`lossy_browser_${name}_differ ${diff} px`);
  console.log(`lossy_browser_${name}_max_diff ${max} q`);
  console.log(`lossy_browser_${name}_g_not_r ${got.rg} px`);
}
await ctx.close();
if (ctx.problems.length) console.error(ctx.problems.join('\n'));
process.exit(bad ? 1 : 0);
