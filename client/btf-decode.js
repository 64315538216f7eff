// btf-decode.js - image files of a chunk (PNG, WebP lossless or lossy, AVIF) to their 8-bit samples,
// off the main thread: a worker decodes with createImageBitmap (no colour conversion, no
// premultiplication) and reads the pixels back from an OffscreenCanvas 2D context, so the
// page's main thread never waits on a decode or a GPU readback. Every file these
// packages hold is opaque (RGB or grey), where a 2D canvas keeps the samples exactly;
// a decode that must see the alpha (wt-JJ.webp weights: a pixel that is not opaque is
// refused) reads back from a canvas with alpha, which keeps opaque samples as exactly.
// A worker script must be same-origin with the page: on the script's own origin the
// worker is btf-decode-worker.js; embedded in a page of another origin its code travels
// inside this module (a Blob URL). Where no worker can be made (a page whose CSP
// forbids blob: workers) the same code runs on the main thread.

// The worker body (scope: the worker's global, which it then serves); also the
// main-thread decoder (scope null), so both paths share one decoder.
export function decoderBody(scope) {
  const decode = async ({buf, type, alpha}) => {
    const bm = await createImageBitmap(new Blob([buf], {type}), {premultiplyAlpha: 'none',
      colorSpaceConversion: 'none'});
    try {
      const c = new OffscreenCanvas(bm.width, bm.height);
      const g = c.getContext('2d', {willReadFrequently: true, alpha: !!alpha});
      g.drawImage(bm, 0, 0);
      const d = g.getImageData(0, 0, bm.width, bm.height);
      return {width: bm.width, height: bm.height, rgba: new Uint8Array(d.data.buffer)};
    } finally {
      bm.close();
    }
  };
  if (scope) {
    scope.onmessage = async (e) => {
      const {id} = e.data;
      try {
        const r = await decode(e.data);
        scope.postMessage({id, ...r}, [r.rgba.buffer]);
      } catch (err) {
        scope.postMessage({id, error: String(err && err.message ? err.message : err)});
      }
    };
  }
  return decode;
}

let worker = null, broken = false, nextId = 1;
const pending = new Map(); // id -> {resolve, reject}
const decodeHere = decoderBody(null);

function startWorker() {
  if (worker || broken || typeof Worker === 'undefined' || typeof OffscreenCanvas === 'undefined') return worker;
  try {
    const file = new URL('btf-decode-worker.js', import.meta.url);
    if (file.origin === location.origin) {
      worker = new Worker(file, {type: 'module'});
    } else {
      const url = URL.createObjectURL(new Blob([`(${decoderBody})(self);`], {type: 'text/javascript'}));
      worker = new Worker(url);
      URL.revokeObjectURL(url);
    }
    worker.onmessage = (e) => {
      const p = pending.get(e.data.id);
      pending.delete(e.data.id);
      if (!p) return;
      if (e.data.error) p.reject(new Error(e.data.error));
      else p.resolve({width: e.data.width, height: e.data.height, rgba: e.data.rgba});
    };
    worker.onerror = (e) => { // the worker could not start (e.g. CSP): decode here from now on
      e.preventDefault?.();
      broken = true;
      worker = null;
      for (const [id, p] of pending) {
        pending.delete(id);
        decodeHere(p.job).then(p.resolve, p.reject);
      }
    };
  } catch {
    broken = true;
    worker = null;
  }
  return worker;
}

// The MIME type of a chunk's image file by its name's extension (doc/package-format.md
// section 4.1): '.webp' and '.avif' their own, any other a PNG.
export function imageType(name) {
  const ext = /\.(webp|avif)$/.exec(name);
  return ext ? `image/${ext[1]}` : 'image/png';
}

// Decodes an image file's bytes (Uint8Array) of MIME type `type` (imageType's): a Promise
// of {width, height, rgba: Uint8Array (4 bytes a pixel, rows top-down)}; it rejects where
// the browser cannot decode the file (an AVIF in a browser without AVIF). alpha: true
// keeps the file's alpha in rgba (else every pixel reads as opaque).
export function decodeImage(bytes, type, alpha = false) {
  const w = startWorker();
  const job = {buf: bytes, type, alpha}; // copied into the worker: the stream keeps its files (cache, replays)
  if (!w) return decodeHere(job);
  return new Promise((resolve, reject) => {
    const id = nextId++;
    pending.set(id, {resolve, reject, job});
    w.postMessage({id, ...job});
  });
}

// Test hook: how decodes run ('worker', 'main thread' or 'idle' before the first).
export function decoderKind() {
  return worker ? 'worker' : broken || typeof Worker === 'undefined' ? 'main thread' : 'idle';
}
