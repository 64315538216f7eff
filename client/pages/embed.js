// embed.js - the embed demo page: three <btf-viewer> elements, one per material of
// the library (repeating when it has fewer), each with a different surface. The
// page only fills in names; the embed itself is the script + element shown above.
import '../btf-viewer.js'; // one folder up here; at the served root (the bundle, an install) '..' is the root

const GEOMETRIES = ['sphere', 'cylinder', 'plane'];

async function main() {
  const host = location.host;
  const snippet = document.getElementById('snippet');
  let names = [];
  try {
    const r = await fetch('/materials');
    names = (await r.json()).materials.map((m) => m.name);
  } catch (e) {
    snippet.textContent = `Cannot list the library: ${e.message}`;
    return;
  }
  const params = new URLSearchParams(location.search);
  if (params.get('materials')) names = params.get('materials').split(',');
  if (!names.length) {
    snippet.textContent = 'The library is empty.';
    return;
  }
  snippet.textContent = `<script type="module" src="${location.protocol}//${host}/btf-viewer.js"></script>\n` +
    `<btf-viewer src="ws://${host}/" material="${names[0]}" geometry="sphere"></btf-viewer>`;
  const main = document.getElementById('embeds');
  for (let i = 0; i < 3; i++) {
    const v = document.createElement('btf-viewer');
    v.setAttribute('src', `${location.protocol === 'https:' ? 'wss' : 'ws'}://${host}/`);
    v.setAttribute('material', names[i % names.length]);
    v.setAttribute('geometry', GEOMETRIES[i]);
    v.setAttribute('light', params.get('light') || 'orbit');
    v.setAttribute('camera-controls', '');
    main.append(v);
  }
}

main();
