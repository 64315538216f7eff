// main.js - the same material twice: <btf-viewer> (import 'btf-stream' registers it) and a
// three.js sphere with BTFMaterial (import from 'btf-stream/three'), the same camera and
// lighting (the studio). The query string gives src and material.
import * as THREE from 'three';
import {OrbitControls} from 'three/addons/controls/OrbitControls.js';
import 'btf-stream';
import {BTFMaterial} from 'btf-stream/three';

const q = new URLSearchParams(location.search);
const src = q.get('src') || `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/stream`;
const material = q.get('material') || 'knit';

// the element: a package has no script origin to find btfd at, so src is given
const viewer = document.getElementById('viewer');
viewer.setAttribute('src', src);
viewer.setAttribute('material', material);

// three.js: the element's default sphere view (camera 60 degrees from the zenith, 3.6 away,
// 40 degrees across), in three's frame (+y up); the material tone maps and encodes sRGB itself
const canvas = document.getElementById('three');
const renderer = new THREE.WebGLRenderer({canvas, antialias: false, preserveDrawingBuffer: true});
renderer.setPixelRatio(Math.min(devicePixelRatio, 2));
renderer.setSize(canvas.clientWidth, canvas.clientHeight, false);
renderer.toneMapping = THREE.NoToneMapping;
renderer.setClearColor(new THREE.Color().setRGB(0.12, 0.12, 0.12, THREE.SRGBColorSpace));
const camera = new THREE.PerspectiveCamera(40, 1, 0.18, 8);
camera.position.set(0, 3.6 * Math.cos(Math.PI / 3), 3.6 * Math.sin(Math.PI / 3));
const geometry = new THREE.SphereGeometry(1, 64, 32);
geometry.computeTangents(); // BTFMaterial needs tangents
const mat = new BTFMaterial({src, material, repeat: [2, 1]});
const scene = new THREE.Scene();
scene.add(new THREE.Mesh(geometry, mat));
camera.lookAt(0, 0, 0);
const controls = new OrbitControls(camera, canvas);
const draw = () => renderer.render(scene, camera);
controls.addEventListener('change', draw);
mat.addEventListener('change', draw); // a chunk arrived: the picture refines
const status = document.getElementById('status');
mat.addEventListener('progress', (e) => { status.textContent = `three.js: ${e.chunks}/${e.chunksWanted} chunks, ${(e.bytes / 1024).toFixed(0)} KB`; });
mat.addEventListener('error', (e) => { status.textContent = `three.js: ${e.reason}`; });
draw();

// for tests and the console
window.__example = {
  material: mat,
  state: () => mat.state(),
  viewerState: () => ({drawnChunks: window.__btf?.viewers()[0]?.drawnChunks ?? 0, lighting: viewer.lighting}),
  capture() {
    draw();
    const gl = renderer.getContext(), w = gl.drawingBufferWidth, h = gl.drawingBufferHeight, px = new Uint8Array(4 * w * h);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
    let lit = 0;
    for (let i = 0; i < px.length; i += 4) if (Math.abs(px[i] - 31) > 3 || Math.abs(px[i + 2] - 31) > 3) lit++;
    return {width: w, height: h, lit};
  },
};
