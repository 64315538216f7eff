// product.js - the product demo page: a glTF model (the stool `btf gen-model` writes,
// stool.glb next to this page; ?model=URL for another) with two library materials
// bound to its glTF materials "Seat" and "Frame" (?seat=NAME&frame=NAME, else the
// library's first two; two selects change them), the trim in its base colour; lit by the
// built-in studio unless ?light=, ?environment-image= (and -rotation, exposure, tone-mapping) say otherwise.
import '../btf-viewer.js'; // one folder up here; at the served root (the bundle, an install) '..' is the root

const $ = (id) => document.getElementById(id);
const q = new URLSearchParams(location.search);
const viewer = document.createElement('btf-viewer');
const REPEAT = {Seat: 2, Frame: 6}; // package repeats per uv unit (the stool: 1 uv unit = the seat's width)

function bind(seat, frame) {
  viewer.setAttribute('materials', `Seat:${seat}:${REPEAT.Seat},Frame:${frame}:${REPEAT.Frame}`);
  $('snippet').textContent = `<script type="module" src="${location.origin}/btf-viewer.js"></script>\n` +
    `<btf-viewer model="${viewer.getAttribute('model')}" materials="${viewer.getAttribute('materials')}">` +
    '</btf-viewer>';
}

async function main() {
  viewer.setAttribute('src', `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/`);
  viewer.setAttribute('model', q.get('model') || 'stool.glb');
  viewer.setAttribute('camera-controls', '');
  viewer.setAttribute('alt', 'A stool');
  for (const a of ['light', 'environment-image', 'environment-rotation', 'exposure', 'tone-mapping'])
    if (q.has(a)) viewer.setAttribute(a, q.get(a));
  let names = [];
  try {
    const r = await fetch('/materials');
    names = ((await r.json()).materials || []).map((m) => m.name);
  } catch (e) {
    $('snippet').textContent = `Cannot list the library: ${e.message}`;
  }
  const seat = q.get('seat') || names[0], frame = q.get('frame') || names[1] || names[0];
  if (!seat) {
    $('snippet').textContent = 'The library is empty.';
    return;
  }
  for (const [id, value] of [['seat', seat], ['frame', frame]])
    $(id).replaceChildren(...names.map((n) => Object.assign(document.createElement('option'), {value: n, textContent: n,
      selected: n === value})));
  bind(seat, frame);
  $('stage').append(viewer); // starts with its attributes set
  $('pick').addEventListener('change', () => bind($('seat').value, $('frame').value));
}

main();
