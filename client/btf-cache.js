// btf-cache.js - received chunks kept in the browser for the next visit (Cache API):
// one entry per (server, material, etag) holding a prefix of its chunks, each chunk one
// cached response (its files concatenated, sizes in a header), and the manifest (so a
// resumed subscription need not receive it again: "manifest_kept", doc/protocol.md).
// The index (entries, bytes, last use) is itself a cached JSON response. Bounded: least recently used entries go
// first once the total passes chunkCache.limit bytes. Without the Cache API (pages
// that are not secure contexts) nothing is kept. A new etag replaces the entry.

const NAME = 'btf-chunks-v1';
const BASE = 'https://btf-chunk-cache.invalid/'; // keys only, never fetched
const INDEX = `${BASE}index.json`;

export const chunkCache = {
  limit: 64 * 1024 * 1024, // bytes of chunk files kept across all materials
  enabled: typeof caches !== 'undefined' && globalThis.__btfCache !== false, // test hook: __btfCache = false
};

let queue = Promise.resolve(); // index updates run one after another

function serial(fn) {
  const p = queue.then(fn);
  queue = p.catch(() => {});
  return p;
}

const entryKey = (server, material) => `${server}|${material}`;
const chunkUrl = (key, etag, j) => `${BASE}${encodeURIComponent(key)}/${etag}/${j}`;

async function readIndex(cache) {
  const r = await cache.match(INDEX);
  return r ? r.json() : {entries: {}};
}

function writeIndex(cache, index) {
  return cache.put(INDEX, new Response(JSON.stringify(index), {headers: {'content-type': 'application/json'}}));
}

async function dropEntry(cache, index, key) {
  const e = index.entries[key];
  if (!e) return;
  await Promise.all(e.chunks.map((j) => cache.delete(chunkUrl(key, e.etag, j))));
  if (e.manifest) await cache.delete(chunkUrl(key, e.etag, 'manifest'));
  delete index.entries[key];
  mark(key, false);
}

// A synchronous note (localStorage) of which materials have kept chunks, so a first
// visit need not wait for the Cache API (slow to open in a fresh profile) before it
// subscribes: without the note nothing is kept. Absent storage: always "maybe".
const MARK = 'btf-chunks-v1|';
function mark(key, on) {
  try {
    if (on) localStorage.setItem(MARK + key, '1');
    else localStorage.removeItem(MARK + key);
  } catch { /* no storage: mayHaveChunks answers true */ }
}

// False when this page has certainly kept no chunks of the material (so loadChunks
// would answer null); true when it may have.
export function mayHaveChunks(server, material) {
  if (!chunkCache.enabled) return false;
  try {
    return localStorage.getItem(MARK + entryKey(server, material)) !== null;
  } catch {
    return true;
  }
}

// Evicts least recently used entries (never `keep`) until the total fits the limit.
async function evict(cache, index, keep) {
  const total = () => Object.values(index.entries).reduce((s, e) => s + e.bytes, 0);
  const lru = Object.entries(index.entries).filter(([k]) => k !== keep).sort((a, b) => a[1].used - b[1].used);
  while (total() > chunkCache.limit && lru.length) await dropEntry(cache, index, lru.shift()[0]);
}

// The kept manifest of an entry (the parsed object), or null.
async function readManifest(cache, key, e) {
  if (!e.manifest) return null;
  const r = await cache.match(chunkUrl(key, e.etag, 'manifest'));
  return r ? r.json().catch(() => null) : null;
}

// The kept chunks of a material: {etag, chunks: [files per chunk 0..n-1], manifest (the
// manifest of etag, or null)} or null.
export function loadChunks(server, material) {
  if (!chunkCache.enabled) return Promise.resolve(null);
  return serial(async () => {
    const cache = await caches.open(NAME), index = await readIndex(cache), key = entryKey(server, material);
    const e = index.entries[key];
    if (!e) return null;
    const chunks = [];
    for (let j = 0; e.chunks.includes(j); j++) { // a prefix only: chunks are uploaded in order
      const r = await cache.match(chunkUrl(key, e.etag, j));
      if (!r) break;
      const buf = new Uint8Array(await r.arrayBuffer()), sizes = r.headers.get('x-sizes').split(',').map(Number);
      let off = 0;
      chunks.push(sizes.map((n) => buf.subarray(off, (off += n))));
    }
    const manifest = chunks.length ? await readManifest(cache, key, e) : null;
    e.used = Date.now();
    await writeIndex(cache, index);
    return chunks.length ? {etag: e.etag, chunks, manifest} : null;
  }).catch(() => null);
}

// Keeps chunk j (its files) of a material at etag; an older etag's chunks are dropped.
// Chunks that arrive while a write is under way are written together after it (their
// responses in parallel, the index once), so a burst of chunks is kept within a few
// cache operations of its last byte: a reload right after `complete` finds them.
export function storeChunk(server, material, etag, j, files) {
  if (!chunkCache.enabled) return Promise.resolve();
  const batch = pendingStores || (pendingStores = {items: [], done: null});
  batch.items.push({key: entryKey(server, material), etag, j, files});
  if (!batch.done) batch.done = serial(() => writeBatch(batch)).catch(() => {});
  return batch.done;
}

// Keeps the manifest (object) of a material at etag beside its chunks; an older etag's
// entry is dropped.
export function storeManifest(server, material, etag, manifest) {
  if (!chunkCache.enabled) return Promise.resolve();
  return serial(async () => {
    const cache = await caches.open(NAME), index = await readIndex(cache), key = entryKey(server, material);
    if (index.entries[key] && index.entries[key].etag !== etag) await dropEntry(cache, index, key);
    const e = index.entries[key] || (index.entries[key] = {etag, chunks: [], bytes: 0, used: 0});
    if (e.manifest) return;
    const text = JSON.stringify(manifest);
    await cache.put(chunkUrl(key, etag, 'manifest'), new Response(text, {headers: {'content-type': 'application/json'}}));
    e.manifest = text.length;
    e.bytes += text.length;
    e.used = Date.now();
    await evict(cache, index, key);
    await writeIndex(cache, index);
  }).catch(() => {});
}

let pendingStores = null; // the batch the next serial write takes

async function writeBatch(batch) {
  pendingStores = null; // later chunks start the next batch
  const cache = await caches.open(NAME), index = await readIndex(cache);
  for (const {key, etag} of batch.items)
    if (index.entries[key] && index.entries[key].etag !== etag) await dropEntry(cache, index, key);
  const fresh = batch.items.filter(({key, j}) => !(index.entries[key]?.chunks.includes(j)));
  await Promise.all(fresh.map(({key, etag, j, files}) => cache.put(chunkUrl(key, etag, j),
    new Response(new Blob(files), {headers: {'x-sizes': files.map((f) => f.length).join(',')}}))));
  for (const {key, etag, j, files} of fresh) {
    const e = index.entries[key] || (index.entries[key] = {etag, chunks: [], bytes: 0, used: 0});
    if (e.etag !== etag || e.chunks.includes(j)) continue;
    e.chunks.push(j);
    e.bytes += files.reduce((s, f) => s + f.length, 0);
    e.used = Date.now();
  }
  for (const key of new Set(fresh.map((f) => f.key))) await evict(cache, index, key);
  await writeIndex(cache, index);
  for (const key of Object.keys(index.entries)) mark(key, true);
}

// Forgets a material's kept chunks (the server no longer has that etag).
export function dropChunks(server, material) {
  if (!chunkCache.enabled) return Promise.resolve();
  return serial(async () => {
    const cache = await caches.open(NAME), index = await readIndex(cache);
    await dropEntry(cache, index, entryKey(server, material));
    await writeIndex(cache, index);
  }).catch(() => {});
}

// Test hook: the index ({entries: {key: {etag, chunks, bytes, used, manifest (its bytes,
// if kept)}}}).
export function cacheIndex() {
  if (!chunkCache.enabled) return Promise.resolve({entries: {}});
  return serial(async () => readIndex(await caches.open(NAME)));
}
