// btf-lod.js - scene-driven chunk selection of package version 2
// (doc/package-format.md section 10): the rule of btf_lod_select in codec/btf_lod_select.c,
// checked against the same cases (tests/lod_select_cases.json) in C and in node.
// Browser-free: a manifest's chunk list in, a budget (prefix length, bytes) out.

export const LOD_THRESHOLD = 1.0; // BTF_LOD_THRESHOLD: RMS contribution on the 0..255 scale

// Texels per device pixel of a material `width` texels wide repeated `repeat` times
// across `pixels` device pixels; 0 when nothing is visible.
export function lodFootprint(width, repeat, pixels) {
  if (!(pixels > 0) || !(width > 0) || !(repeat > 0)) return 0;
  return width * repeat / pixels;
}

function contrib(chunks, c, l) {
  const ch = chunks.find((k) => k.component === c && (k.level ?? 0) === l);
  return ch && Number.isFinite(ch.contrib) ? ch.contrib : 0;
}

// m: {version, levels, chunks: [{component, level, contrib, bytes}]} (a manifest).
// view: {texelsPerPixel, threshold}. Returns {level, components, needed, limit,
// bytes, need (Uint8Array per chunk)}; limit = the chunk prefix to ask for.
export function lodSelect(m, view) {
  const chunks = m.chunks, n = chunks.length, levels = m.version >= 2 ? m.levels : 1;
  const tpp = view.texelsPerPixel, thr = view.threshold ?? LOD_THRESHOLD;
  const out = {level: 0, components: 0, needed: 0, limit: 0, bytes: 0, need: new Uint8Array(n)};
  if (!(tpp > 0)) return out; // off screen, hidden tab (or NaN): nothing
  let lev = 0;
  while (lev + 1 < levels && tpp >= 2 ** (lev + 1)) lev++;
  out.level = m.version >= 2 ? lev : 0;
  const c0 = chunks[0].component, seen = new Set();
  chunks.forEach((ch, i) => {
    const first = !seen.has(ch.component);
    seen.add(ch.component);
    const vis = m.version < 2 || ch.component === c0 || contrib(chunks, ch.component, out.level) >= thr;
    if (vis && first) out.components++;
    if (vis && (ch.level ?? 0) >= out.level) {
      out.needed++;
      out.limit = i + 1;
      out.need[i] = 1;
    }
  });
  for (let i = 0; i < out.limit; i++) out.bytes += chunks[i].bytes;
  return out;
}
