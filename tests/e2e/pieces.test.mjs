// pieces.test.mjs - a fuzz loop over the client's binary piece parser
// (BtfStream.onMessage in client/btf-stream.js), the browser-side twin of the
// readers fuzzed in fuzz/: frames with random and boundary header fields and
// payloads must never throw, never allocate a file larger than its chunk's
// manifest bytes, and complete a chunk only when every file of it has arrived
// byte for byte. Deterministic (seeded), bounded (a few thousand frames).
import assert from 'node:assert/strict';
import {describe, it} from 'node:test';

globalThis.WebSocket ??= class {}; // only needed when connecting
const {BtfStream} = await import('../../client/btf-stream.js');

const HEADER = 20;

// xorshift32: the same frames on every run.
function rng(seed) {
  let x = seed >>> 0 || 1;
  return () => ((x ^= x << 13, x ^= x >>> 17, x ^= x << 5) >>> 0);
}

// A stream that is not connected, with one subscription of `sizes[j]` = file sizes of chunk j.
function fixture(sizes) {
  const s = Object.create(BtfStream.prototype);
  Object.assign(s, {url: 'ws://fuzz.invalid/', subs: new Map(), byMid: new Map(), bytes: 0, frames: 0,
    pieces: {bytes: 0, first: null, last: null, firstBytes: 0}});
  const chunks = sizes.map((files, id) => ({id, component: id, files: files.map((_, f) => `f${id}-${f}`),
    bytes: files.reduce((a, b) => a + b, 0)}));
  const done = [];
  const sub = {material: 'm', etag: 'e', mid: 7, manifest: {chunks}, chunks: [], partial: new Map(), bytes: 0,
    received: 0, arrivedAt: [], emit: (ev, j) => ev === 'onChunk' && done.push(j)};
  s.subs.set('m', sub);
  s.byMid.set(7, sub);
  return {s, sub, chunks, done};
}

function frame(mid, chunk, file, off, total, payload) {
  const buf = new ArrayBuffer(HEADER + payload.length);
  const dv = new DataView(buf);
  [mid, chunk, file, off, total].forEach((v, i) => dv.setUint32(4 * i, v >>> 0, true));
  new Uint8Array(buf, HEADER).set(payload);
  return buf;
}

// A header field: mostly plausible, sometimes a boundary or any 32-bit value.
function field(r, plausible) {
  const k = r() % 8;
  return k < 5 ? r() % (plausible + 1) : k === 5 ? 0xffffffff : k === 6 ? plausible : r();
}

describe('client piece parser (fuzz loop)', () => {
  it('survives random frames and allocates no more than the manifest announces', () => {
    const r = rng(0xb7f5);
    const {s, sub, chunks} = fixture([[40, 16], [100], [8, 8, 8]]);
    for (let i = 0; i < 20000; i++) {
      const chunk = field(r, chunks.length - 1), c = chunks[chunk], file = field(r, c ? c.files.length - 1 : 3);
      const total = field(r, c ? c.bytes : 64), off = field(r, total), len = r() % 48;
      const payload = Uint8Array.from({length: len}, () => r() & 255);
      assert.doesNotThrow(() => s.onMessage(frame(r() % 16 === 0 ? r() : 7, chunk, file, off, total, payload)));
      if (r() % 64 === 0) s.onMessage(frame(7, chunk, file, 0, 0xffffffff, payload)); // the 4 GiB claim
      for (const [j, p] of sub.partial) {
        for (const f of p.files) if (f) assert.ok(f.length <= chunks[j].bytes, `chunk ${j}: a ${f.length}-byte file`);
      }
    }
    assert.ok(sub.bytes <= s.pieces.bytes, 'more payload counted than received');
  });

  it('refuses a piece whose file is larger than its chunk, allocating nothing', () => {
    const {s, sub} = fixture([[40, 16]]);
    s.onMessage(frame(7, 0, 0, 0, 0xffffffff, new Uint8Array(8))); // a 4 GiB claim in a 28-byte frame
    s.onMessage(frame(7, 0, 1, 0, 57, new Uint8Array(8)));         // one byte more than the chunk holds
    assert.equal(sub.partial.size, 0, 'a buffer was allocated for a file the manifest does not announce');
  });

  it('assembles a chunk from in-order pieces and only then reports it; a gap completes nothing', () => {
    const {s, sub, done} = fixture([[40, 16], [4, 0]]);
    const data = [Uint8Array.from({length: 40}, (_, i) => i), Uint8Array.from({length: 16}, (_, i) => 200 + i)];
    s.onMessage(frame(7, 0, 0, 20, 40, data[0].subarray(20, 40))); // the tail before the head: a gap
    assert.equal(done.length, 0, 'a file with a gap was taken as complete');
    const pieces = [[0, 0, 20], [0, 20, 20], [1, 0, 16]];
    pieces.forEach(([file, off, n], k) => {
      assert.equal(done.length, 0, `reported after ${k} of 3 pieces`);
      s.onMessage(frame(7, 0, file, off, data[file].length, data[file].subarray(off, off + n)));
    });
    assert.deepEqual(done, [0]);
    assert.deepEqual([...sub.chunks[0][0]], [...data[0]]);
    assert.deepEqual([...sub.chunks[0][1]], [...data[1]]);
    s.onMessage(frame(7, 0, 0, 0, 40, data[0].subarray(0, 40))); // a repeat changes nothing
    assert.deepEqual(done, [0]);
    s.onMessage(frame(7, 1, 0, 0, 4, Uint8Array.of(1, 2, 3, 4)));
    s.onMessage(frame(7, 1, 1, 0, 0, new Uint8Array(0))); // an empty file is one empty piece
    assert.deepEqual(done, [0, 1]);
  });
});
