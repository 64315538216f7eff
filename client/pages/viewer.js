// viewer.js - one full-page viewer configured by the query string, e.g.
//   viewer.html?material=wool&geometry=sphere&light=fixed&budget-chunks=2
//   viewer.html?model=stool.glb&materials=Seat:wool,Frame:impalla:2
// Every <btf-viewer> attribute may be given; width/height (CSS pixels) fix the size.
import '../btf-viewer.js'; // one folder up here; at the served root (the bundle, an install) '..' is the root

const ATTRS = ['material', 'model', 'materials', 'src', 'geometry', 'light', 'light-theta', 'light-phi', 'camera-theta', 'camera-phi',
               'camera-dist', 'fov', 'repeat', 'budget-chunks', 'budget-bytes', 'max-dpr', 'shaders', 'lod-threshold', 'loading',
               'poster', 'alt', 'environment-image', 'environment-rotation', 'exposure', 'tone-mapping'];
const q = new URLSearchParams(location.search);
const v = document.createElement('btf-viewer');
v.setAttribute('src', `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/`);
for (const a of ATTRS) if (q.has(a)) v.setAttribute(a, q.get(a));
v.className = 'solo';
if (!q.has('camera-controls') || q.get('camera-controls') !== '0') v.setAttribute('camera-controls', '');
if (q.has('width')) v.style.width = `${parseFloat(q.get('width'))}px`;
if (q.has('height')) v.style.height = `${parseFloat(q.get('height'))}px`;
document.getElementById('solo').append(v);
