// gallery.js - the library page: a grid of the materials listed by GET /materials
// (thumbnail, size, chunks, final error), each opening a large viewer (#m=NAME).
import '../btf-viewer.js'; // one folder up here; at the served root (the bundle, an install) '..' is the root

const $ = (id) => document.getElementById(id);
const wsUrl = `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/`;
let materials = [];

function kb(n) {
  return n >= 1048576 ? `${(n / 1048576).toFixed(1)} MB` : `${Math.round(n / 1024)} KB`;
}

function card(m) {
  const li = document.createElement('li');
  li.className = 'card';
  const a = document.createElement('a');
  a.href = `#m=${encodeURIComponent(m.name)}`;
  a.className = 'thumb';
  if (m.thumbnail) {
    const img = document.createElement('img');
    img.src = m.thumbnail;
    img.alt = m.title || m.name;
    img.loading = 'lazy';
    a.append(img);
  } else { // no thumbnail in the package: a small live viewer; versions 1 and 3: first
    // chunk only; versions 2 and 4 (spatial levels): the viewer's scene budget (client/btf-lod.js)
    const v = document.createElement('btf-viewer');
    v.setAttribute('src', wsUrl);
    v.setAttribute('material', m.name);
    v.setAttribute('light', 'fixed');
    v.setAttribute('geometry', 'sphere');
    if (m.version !== 2 && m.version !== 4) v.setAttribute('budget-chunks', '1');
    a.append(v);
  }
  const cap = document.createElement('div');
  cap.className = 'caption';
  const title = document.createElement('strong');
  title.textContent = m.title || m.name;
  const meta = document.createElement('span');
  const err = Number.isFinite(m.error) ? ` · ${m.metric === 'lab' ? 'Lab' : m.metric} ${m.error.toFixed(2)}` : '';
  meta.textContent = `${m.width || '?'}×${m.height || '?'} texels · ${m.chunks} chunks · ${kb(m.bytes)}${err}`;
  cap.append(title, meta);
  li.append(a, cap);
  return li;
}

async function load() {
  const status = $('status');
  try {
    const r = await fetch('/materials', {cache: 'no-store'});
    if (!r.ok) throw new Error(`HTTP ${r.status}`);
    materials = (await r.json()).materials || [];
  } catch (e) {
    status.textContent = `Cannot list the library: ${e.message}`;
    status.classList.add('error');
    return;
  }
  status.textContent = materials.length ? `${materials.length} materials` : 'The library is empty.';
  $('grid').replaceChildren(...materials.map(card));
  route();
}

function route() {
  const m = /^#m=(.+)$/.exec(location.hash);
  const detail = $('detail'), host = $('detail-host');
  if (!m) {
    detail.hidden = true;
    host.replaceChildren();
    return;
  }
  const name = decodeURIComponent(m[1]);
  const info = materials.find((x) => x.name === name);
  $('detail-title').textContent = info ? info.title || name : name;
  const v = document.createElement('btf-viewer');
  v.setAttribute('src', wsUrl);
  v.setAttribute('material', name);
  v.setAttribute('geometry', $('detail-geometry').value);
  if ($('detail-light').value) v.setAttribute('light', $('detail-light').value); // none: the studio
  v.className = 'large';
  v.setAttribute('camera-controls', '');
  host.replaceChildren(v);
  detail.hidden = false;
}

for (const [id, attr] of [['detail-geometry', 'geometry'], ['detail-light', 'light']]) {
  $(id).addEventListener('change', (e) => {
    const v = $('detail-host').querySelector('btf-viewer');
    if (v && e.target.value) v.setAttribute(attr, e.target.value);
    else if (v) v.removeAttribute(attr);
  });
}
$('detail-close').addEventListener('click', (e) => {
  e.preventDefault();
  history.pushState(null, '', location.pathname + location.search);
  route();
});
window.addEventListener('hashchange', route);
load();
