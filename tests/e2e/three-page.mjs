// three-page.mjs - what the three.js tests (three.test.mjs, npm.test.mjs) draw with: a
// static file server for a folder tree, and the page script that draws one scene with
// BTFMaterial on a three.js mesh beside a <btf-viewer> of the same scene (same camera,
// light, package, size), both captured as RGBA.
import fs from 'node:fs';
import path from 'node:path';
import {servePages} from './util.mjs';

const TYPES = {'.js': 'text/javascript', '.mjs': 'text/javascript', '.json': 'application/json', '.html': 'text/html',
  '.glsl': 'text/plain', '.vert': 'text/plain', '.frag': 'text/plain', '.map': 'application/json'};

// Serves pages (name -> HTML) and, under each prefix of `mounts` ({'/prefix/': dir}), the
// files of dir and its subfolders (no dot files, nothing outside dir).
export function serveTree(pages, mounts) {
  return servePages(pages, {hook: (req, res) => {
    const p = decodeURIComponent(new URL(req.url, 'http://x').pathname);
    for (const [prefix, dir] of Object.entries(mounts)) {
      if (!p.startsWith(prefix)) continue;
      const rel = p.slice(prefix.length);
      if (rel.split('/').some((s) => !s || s.startsWith('.'))) continue;
      const full = path.join(dir, rel);
      if (!full.startsWith(path.resolve(dir) + path.sep) || !fs.existsSync(full) || !fs.statSync(full).isFile()) continue;
      res.writeHead(200, {'content-type': TYPES[path.extname(full)] || 'application/octet-stream', 'cache-control': 'no-cache'});
      res.end(fs.readFileSync(full));
      return true;
    }
    return false;
  }});
}

// The page: an import map for three (and btf-stream when installed), then `script`. The
// body holds #holder for the element and the three.js canvas.
export function pageHtml(importMap, script) {
  return `<!doctype html><html><head><meta charset="utf-8"><link rel="icon" href="data:,">
<script type="importmap">${JSON.stringify({imports: importMap})}</script>
<style>body{margin:0;background:#222} btf-viewer,canvas{display:inline-block;vertical-align:top}</style></head>
<body><div id="holder"></div><script type="module">${script}</script></body></html>`;
}

// The page script: window.__three.draw(scene) renders `scene` with BTFMaterial (imported from
// `materialModule`) and resolves once `chunks` chunks are drawn; __three.capture() reads the
// canvas; __three.state() is the material's state. scene: {src, material, geometry 'plane' |
// 'sphere', w, h, camera [theta, phi, dist], fov, chunks, repeat, light [theta, phi] | null,
// environment, environmentRotation, exposure, toneMapping}, in the project's frame (+z up).
export function threeScript(materialModule, viewerModule) {
  return `
import * as THREE from 'three';
import ${JSON.stringify(viewerModule)};
import {BTFMaterial} from ${JSON.stringify(materialModule)};
const dir = (t, p) => { t *= Math.PI / 180; p *= Math.PI / 180;
  return [Math.sin(t) * Math.cos(p), Math.sin(t) * Math.sin(p), Math.cos(t)]; };
let renderer, scene, camera, mesh, mat, changes = 0;
// The element's own mesh (scene.js buildMesh: positions, normals, exact tangents, uv with v
// along image rows) as a three.js geometry, its uv.y flipped to three's convention.
async function elementGeometry(kind) {
  const {buildMesh} = await import('/scene.js');
  const m = buildMesh(kind), n = m.vertices.length / 12, g = new THREE.BufferGeometry();
  const attr = (off, size, f = (x) => x) => {
    const a = new Float32Array(n * size);
    for (let i = 0; i < n; i++) for (let k = 0; k < size; k++) a[i * size + k] = f(m.vertices[i * 12 + off + k], k);
    return new THREE.BufferAttribute(a, size);
  };
  g.setAttribute('position', attr(0, 3));
  g.setAttribute('normal', attr(3, 3));
  g.setAttribute('tangent', attr(6, 4));
  g.setAttribute('uv', attr(10, 2, (x, k) => (k === 1 ? 1 - x : x)));
  g.setIndex(new THREE.BufferAttribute(m.indices, 1));
  return g;
}
function geometry(kind) {
  let g;
  if (kind === 'plane') g = new THREE.PlaneGeometry(2, 2); // z = 0, normal +z, uv.y up: the element's plane
  else {
    // three's sphere has +y up and its seam at -x; the element's (btf render's) +z up, seam at +y
    g = new THREE.SphereGeometry(1, 64, 32);
    g.rotateX(Math.PI / 2);
    g.rotateZ(-Math.PI / 2);
  }
  g.computeTangents();
  return g;
}
window.__three = {
  changes: () => changes,
  state: () => mat && mat.state(),
  material: () => mat,
  async draw(s) {
    if (!renderer) {
      renderer = new THREE.WebGLRenderer({antialias: false, preserveDrawingBuffer: true});
      renderer.setPixelRatio(1);
      renderer.toneMapping = THREE.NoToneMapping;
      renderer.setClearColor(new THREE.Color().setRGB(0.12, 0.12, 0.12, THREE.SRGBColorSpace), 1);
      document.getElementById('holder').append(renderer.domElement);
    }
    renderer.setSize(s.w, s.h);
    if (mat) { mesh.geometry.dispose(); mat.dispose(); }
    const aspect = s.w / s.h, fov = s.fov ?? 40, [t, p, dist] = s.camera;
    const fovy = 2 * Math.atan(Math.tan(fov * Math.PI / 360) / Math.min(aspect, 1)) * 180 / Math.PI;
    camera = new THREE.PerspectiveCamera(fovy, aspect, 0.05 * dist, dist + 4);
    camera.up.set(0, 0, 1);
    camera.position.set(...dir(t, p).map((x) => x * dist));
    camera.lookAt(0, 0, 0);
    const rep = s.repeat ?? 1, base = s.geometry === 'sphere' ? [2, 1] : [1, 1];
    mat = new BTFMaterial({src: s.src, material: s.material, budgetChunks: s.chunks, up: 'z',
      repeat: [base[0] * rep, base[1] * rep], wrap: s.geometry !== 'plane' || rep !== 1,
      light: s.light ? dir(...s.light) : null, filter: s.filter ?? 'bilinear',
      ...('environment' in s ? {environment: s.environment} : {}),
      environmentRotation: s.environmentRotation ?? 0, exposure: s.exposure ?? 1, toneMapping: s.toneMapping ?? 'auto'});
    mat.addEventListener('change', () => { changes++; renderer.render(scene, camera); });
    mat.addEventListener('error', (e) => console.error('BTFMaterial: ' + e.reason));
    mesh = new THREE.Mesh(s.mesh === 'element' ? await elementGeometry(s.geometry) : geometry(s.geometry), mat);
    scene = new THREE.Scene();
    scene.add(mesh);
    renderer.render(scene, camera);
  },
  drawn: () => { renderer.render(scene, camera); return mat.state().drawnChunks; },
  capture() {
    renderer.render(scene, camera);
    const gl = renderer.getContext(), w = gl.drawingBufferWidth, h = gl.drawingBufferHeight;
    const px = new Uint8Array(4 * w * h), out = new Uint8Array(4 * w * h);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
    for (let y = 0; y < h; y++) out.set(px.subarray(4 * w * (h - 1 - y), 4 * w * (h - y)), 4 * w * y);
    let str = '';
    for (let i = 0; i < out.length; i += 0x8000) str += String.fromCharCode.apply(null, out.subarray(i, i + 0x8000));
    return {width: w, height: h, rgba: btoa(str)};
  },
  // the same scene in a <btf-viewer> (the element draws with its own context)
  viewer(s, shaders) {
    const holder = document.getElementById('holder');
    holder.querySelector('btf-viewer')?.remove();
    const v = document.createElement('btf-viewer'), a = {src: s.src, material: s.material, geometry: s.geometry,
      'camera-theta': s.camera[0], 'camera-phi': s.camera[1], 'camera-dist': s.camera[2], fov: s.fov ?? 40,
      'budget-chunks': s.chunks, 'max-dpr': 1, loading: 'eager', repeat: s.repeat ?? 1,
      'environment-rotation': s.environmentRotation ?? 0, exposure: s.exposure ?? 1, 'tone-mapping': s.toneMapping ?? 'auto'};
    if (s.light) Object.assign(a, {light: 'fixed', 'light-theta': s.light[0], 'light-phi': s.light[1]});
    if ('environment' in s) a['environment-image'] = s.environment ?? 'none';
    if (shaders) a.shaders = shaders;
    for (const [k, x] of Object.entries(a)) v.setAttribute(k, String(x));
    v.style.width = s.w + 'px';
    v.style.height = s.h + 'px';
    holder.prepend(v);
  },
};
window.__threeReady = true;
`;
}
