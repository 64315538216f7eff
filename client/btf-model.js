// btf-model.js - a glTF model (btf-gltf.js) with library materials bound to its glTF
// materials, for a session of <btf-viewer model="..." materials="...">: which part
// takes which binding (the rule of btf_scene_bind, shaders/host/btf_scene.c), the
// framing of the camera (btf_scene_frame), the pixels each material covers on screen
// (its scene budget), and the parts as GPU meshes, drawn by btf-render.js
// (MeshRenderer.drawScene): one draw per part with the `render` program of its binding's
// package, or in its base colour with the `flat` program (shaders/btf_flat.frag).
//
// Loaded on demand (a dynamic import by btf-session.js) with btf-gltf.js: a page without
// models does not fetch them (the bundle makes them one chunk beside btf-viewer.js; they
// import nothing else, so the main file stays whole).
import {bindParts, loadModel} from './btf-gltf.js';

export {parseBindings} from './btf-gltf.js';

const F = 12;               // floats per vertex
const COVER_TRIANGLES = 60000; // at most this many triangles are projected per view (evenly spread)
const COVER_QUANTILE = 0.1; // a material's footprint: the one its finest-resolved tenth of pixels need

const models = new Map(); // absolute URL -> Promise of the baked model (shared by the page's viewers)

// The model at url (fetched and baked once per page; a failure is forgotten, so a
// restart tries again).
export function modelAt(url) {
  const key = new URL(url, typeof document !== 'undefined' ? document.baseURI : undefined).href;
  if (!models.has(key)) {
    const p = loadModel(key);
    p.catch(() => models.get(key) === p && models.delete(key));
    models.set(key, p);
  }
  return models.get(key);
}

// Port of btf_scene_frame (shaders/host/btf_scene.c): a model's bounds framed at
// `fov` degrees: {target: the bounds' centre, extent: half their diagonal (the radius
// of their bounding sphere), cameraDist: that sphere across the narrower side of the
// view with a 5% margin}; float32 where the C host keeps floats.
export function frameModel(min, max, fov) {
  const f = Math.fround, target = [0, 0, 0];
  let r2 = 0;
  for (let c = 0; c < 3; c++) {
    target[c] = f(0.5 * f(min[c] + max[c]));
    const h = 0.5 * (max[c] - min[c]);
    r2 += h * h;
  }
  const r = Math.sqrt(r2) > 1e-6 ? Math.sqrt(r2) : 1e-6;
  return {target, extent: f(r), cameraDist: f(1.05 * r / Math.sin(f(fov) * Math.PI / 360))};
}

// Twice the signed area of the polygon pts ([x0, y0, x1, y1, ...]).
function area2(pts) {
  let s = 0;
  for (let i = 0, n = pts.length; i < n; i += 2) {
    const j = (i + 2) % n;
    s += pts[i] * pts[j + 1] - pts[j] * pts[i + 1];
  }
  return s;
}

// pts clipped to the half-plane where coordinate k (0 x, 1 y) is >= lo (sign 1) or <= hi (sign -1).
function clip(pts, k, edge, sign) {
  const out = [];
  for (let i = 0, n = pts.length; i < n; i += 2) {
    const j = (i + 2) % n, a = sign * (pts[i + k] - edge), b = sign * (pts[j + k] - edge);
    if (a >= 0) out.push(pts[i], pts[i + 1]);
    if ((a >= 0) !== (b >= 0)) {
      const t = a / (a - b);
      out.push(pts[i] + t * (pts[j] - pts[i]), pts[i + 1] + t * (pts[j + 1] - pts[i + 1]));
    }
  }
  return out;
}

// Owned by a session; the model itself may be shared by viewers, the GPU meshes are the session's.
export class ModelScene {
  // bindings: [{name, id, repeat}] (btf-gltf.js parseBindings; repeat null: the
  // viewer's `repeat`); throws when a binding names no material of the model or binds a
  // part without texture coordinates.
  constructor(model, bindings) {
    this.model = model;
    this.bindings = bindings;
    this.partBind = bindParts(model, bindings);
    this.meshes = null; // per part {vao, count, buffers} on the GPU
    this.gl = null;
    this.cover = {key: null, byId: new Map()};
  }

  // The library materials the bindings name, once each, in binding order.
  materialIds() {
    return [...new Set(this.bindings.map((b) => b.id))];
  }

  // The camera framing (frameModel, btf_scene_frame) at fov degrees.
  frame(fov) {
    return frameModel(this.model.min, this.model.max, fov);
  }

  repeatOf(j, view) {
    const r = this.bindings[j].repeat;
    return r === null || r === undefined ? view.repeat : r;
  }

  // Per library material id: {pixels: the device pixels its parts cover (projected
  // triangles clipped to the view; occlusion not counted), ppr: device pixels one
  // repeat spans, the value COVER_QUANTILE of those pixels reach or exceed (0 when
  // none)}, for the scene `view` in a width x height view whose camera matrix is
  // viewProj(); cached per camera.
  coverage(view, width, height, viewProj) {
    const key = JSON.stringify([view.cameraTheta, view.cameraPhi, view.cameraDist, view.fov, view.repeat, view.target,
      width, height]);
    if (this.cover.key === key) return this.cover.byId;
    const vp = viewProj(), parts = this.model.parts;
    const total = parts.reduce((a, p, i) => a + (this.partBind[i] >= 0 ? p.indices.length / 3 : 0), 0);
    const stride = Math.max(1, Math.ceil(total / COVER_TRIANGLES));
    const samples = new Map(); // id -> [[ppr, pixels]]
    const sx = new Float64Array(3), sy = new Float64Array(3);
    parts.forEach((p, i) => {
      const j = this.partBind[i];
      if (j < 0) return;
      const id = this.bindings[j].id, rep = this.repeatOf(j, view), v = p.vertices, ix = p.indices;
      if (!samples.has(id)) samples.set(id, []);
      const list = samples.get(id);
      for (let t = 0; t < ix.length; t += 3 * stride) {
        let behind = false;
        for (let k = 0; k < 3; k++) {
          const o = ix[t + k] * F, x = v[o], y = v[o + 1], z = v[o + 2];
          const w = vp[3] * x + vp[7] * y + vp[11] * z + vp[15];
          if (!(w > 1e-6)) behind = true;
          sx[k] = ((vp[0] * x + vp[4] * y + vp[8] * z + vp[12]) / w * 0.5 + 0.5) * width;
          sy[k] = ((vp[1] * x + vp[5] * y + vp[9] * z + vp[13]) / w * 0.5 + 0.5) * height;
        }
        if (behind) continue;
        let poly = [sx[0], sy[0], sx[1], sy[1], sx[2], sy[2]];
        poly = clip(clip(clip(clip(poly, 0, 0, 1), 0, width, -1), 1, 0, 1), 1, height, -1);
        const px = poly.length >= 6 ? Math.abs(area2(poly)) / 2 : 0;
        const a = ix[t] * F + 10, b = ix[t + 1] * F + 10, c = ix[t + 2] * F + 10;
        const uv = Math.abs((v[b] - v[a]) * (v[c + 1] - v[a + 1]) - (v[c] - v[a]) * (v[b + 1] - v[a + 1])) / 2 * rep * rep;
        if (px > 0 && uv > 0) list.push([Math.sqrt(px / uv), px * stride]);
      }
    });
    const byId = new Map();
    for (const id of this.materialIds()) {
      const list = (samples.get(id) || []).sort((a, b) => b[0] - a[0]);
      const pixels = list.reduce((s, e) => s + e[1], 0);
      let ppr = 0, acc = 0;
      for (const [r, px] of list) {
        ppr = r;
        acc += px;
        if (acc >= COVER_QUANTILE * pixels) break;
      }
      byId.set(id, {pixels, ppr});
    }
    this.cover = {key, byId};
    return byId;
  }

  // The parts as GPU meshes (again after a context loss: dropGpu, then this).
  upload(gl) {
    if (this.meshes && this.gl === gl) return this.meshes;
    this.dropGpu();
    this.gl = gl;
    this.meshes = this.model.parts.map((p) => {
      const vao = gl.createVertexArray();
      gl.bindVertexArray(vao);
      const vb = gl.createBuffer();
      gl.bindBuffer(gl.ARRAY_BUFFER, vb);
      gl.bufferData(gl.ARRAY_BUFFER, p.vertices, gl.STATIC_DRAW);
      [[3, 0], [3, 3], [4, 6], [2, 10]].forEach(([size, off], loc) => {
        gl.enableVertexAttribArray(loc);
        gl.vertexAttribPointer(loc, size, gl.FLOAT, false, 4 * F, off * 4);
      });
      const ib = gl.createBuffer();
      gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, ib);
      gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, p.indices, gl.STATIC_DRAW);
      return {vao, count: p.indices.length, buffers: [vb, ib]};
    });
    gl.bindVertexArray(null);
    return this.meshes;
  }

  dropGpu() {
    const gl = this.gl;
    if (gl && this.meshes && !gl.isContextLost())
      for (const m of this.meshes) {
        gl.deleteVertexArray(m.vao);
        m.buffers.forEach((b) => gl.deleteBuffer(b));
      }
    this.meshes = null;
    this.gl = null;
  }

  // What MeshRenderer.drawScene draws: per library material with chunks to show, its
  // package and the meshes of each binding with their repeats ({gpu, chunks, quads,
  // groups: [{uvScale, meshes}]}); every other part in its base colour ({mesh, color}).
  // feeds: id -> {gpu, chunks, quads}.
  layers(gl, feeds, view) {
    const meshes = this.upload(gl), layers = [], flats = [], byFeed = new Map(); // feed -> {layer, groups}
    this.model.parts.forEach((p, i) => {
      const j = this.partBind[i], f = j >= 0 ? feeds.get(this.bindings[j].id) : null;
      if (!f || !f.gpu || !(f.chunks > 0)) {
        flats.push({mesh: meshes[i], color: p.baseColor});
        return;
      }
      if (!byFeed.has(f)) {
        const layer = {gpu: f.gpu, chunks: f.chunks, quads: f.quads, groups: []};
        layers.push(layer);
        byFeed.set(f, {layer, groups: new Map()});
      }
      const e = byFeed.get(f);
      if (!e.groups.has(j)) {
        const g = {uvScale: [this.repeatOf(j, view), this.repeatOf(j, view)], meshes: []};
        e.groups.set(j, g);
        e.layer.groups.push(g);
      }
      e.groups.get(j).meshes.push(meshes[i]);
    });
    return {layers, flats};
  }
}
