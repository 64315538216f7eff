// gltf-fixtures.mjs - small glTF files for the model tests: a .glb writer, a model that
// exercises what the stool does not (no NORMAL: flat normals; no TEXCOORD_0; a
// mirroring node matrix; normalized u8 and u16 uvs; non-indexed triangles; a uv seam
// where the handedness flips, so generated tangents split vertices), and the hostile
// set (each file with the reason both loaders must give).

// A .glb of a JSON document and a binary chunk (both padded to 4 bytes).
export function glb(doc, bin = new Uint8Array(0), fix = (text) => text) {
  const json = Buffer.from(fix(JSON.stringify(doc)));
  const jp = (json.length + 3) & ~3, bp = (bin.length + 3) & ~3;
  const total = 12 + 8 + jp + (bin.length ? 8 + bp : 0);
  const b = Buffer.alloc(total, 0);
  b.write('glTF', 0, 'ascii');
  b.writeUInt32LE(2, 4);
  b.writeUInt32LE(total, 8);
  b.writeUInt32LE(jp, 12);
  b.write('JSON', 16, 'ascii');
  json.copy(b, 20);
  b.fill(0x20, 20 + json.length, 20 + jp);
  if (bin.length) {
    b.writeUInt32LE(bp, 20 + jp);
    b.write('BIN\0', 24 + jp, 'latin1');
    Buffer.from(bin.buffer, bin.byteOffset, bin.length).copy(b, 28 + jp);
  }
  return b;
}

// Builds a document's accessors over one growing buffer.
export class Doc {
  constructor() {
    this.parts = [];
    this.size = 0;
    this.doc = {asset: {version: '2.0'}, buffers: [{byteLength: 0}], bufferViews: [], accessors: [], meshes: [],
      nodes: [], materials: [], scenes: [{nodes: []}], scene: 0};
  }

  // typed: a typed array; type: 'VEC3' ...; extra: accessor fields (normalized, ...)
  accessor(typed, type, extra = {}) {
    const bytes = new Uint8Array(typed.buffer, typed.byteOffset, typed.byteLength);
    const ct = typed instanceof Float32Array ? 5126 : typed instanceof Uint8Array ? 5121 : typed instanceof Uint16Array
      ? 5123 : 5125;
    const n = {SCALAR: 1, VEC2: 2, VEC3: 3, VEC4: 4}[type];
    this.doc.bufferViews.push({buffer: 0, byteOffset: this.size, byteLength: bytes.length});
    this.doc.accessors.push({bufferView: this.doc.bufferViews.length - 1, componentType: ct,
      count: typed.length / n, type, ...extra});
    this.parts.push(bytes);
    this.size += bytes.length;
    const pad = (4 - (this.size % 4)) % 4;
    if (pad) {
      this.parts.push(new Uint8Array(pad));
      this.size += pad;
    }
    return this.doc.accessors.length - 1;
  }

  material(name, color) {
    this.doc.materials.push({name, pbrMetallicRoughness: {baseColorFactor: color}});
    return this.doc.materials.length - 1;
  }

  mesh(primitives) {
    this.doc.meshes.push({primitives});
    return this.doc.meshes.length - 1;
  }

  node(n, root = false) {
    this.doc.nodes.push(n);
    const i = this.doc.nodes.length - 1;
    if (root) this.doc.scenes[0].nodes.push(i);
    return i;
  }

  bin() {
    const out = new Uint8Array(this.size);
    let o = 0;
    for (const p of this.parts) {
      out.set(p, o);
      o += p.length;
    }
    this.doc.buffers[0].byteLength = this.size;
    return out;
  }

  glb() {
    const bin = this.bin();
    return glb(this.doc, bin);
  }

  // The .gltf text with its buffer as a data URI.
  gltf() {
    const bin = this.bin();
    const doc = structuredClone(this.doc);
    doc.buffers[0].uri = `data:application/octet-stream;base64,${Buffer.from(bin).toString('base64')}`;
    return Buffer.from(JSON.stringify(doc));
  }
}

// A grid of (n+1)^2 vertices over [0,1]^2 in the x-z plane (y = a bump), uv = (x, z),
// except that the uv's u runs backwards on the right half (a mirrored seam: triangles
// of both handednesses meet at x = 0.5, so generated tangents split those vertices).
function grid(n) {
  const pos = [], uv = [], idx = [];
  for (let j = 0; j <= n; j++)
    for (let i = 0; i <= n; i++) {
      const x = i / n, z = j / n;
      pos.push(x, 0.1 * Math.sin(3 * x) * Math.cos(2 * z), z);
      uv.push(x <= 0.5 ? x : 1 - x, z);
    }
  for (let j = 0; j < n; j++)
    for (let i = 0; i < n; i++) {
      const a = j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
      idx.push(a, c, b, b, c, d);
    }
  return {pos: new Float32Array(pos), uv: new Float32Array(uv), idx: new Uint16Array(idx)};
}

// The variety model: see the file's comment. Materials "Skin" (grid), "Bare" (no uv),
// "Flat" (no NORMAL, non-indexed, u8 normalized uv), "Cap" (u16 normalized uv).
export function varietyModel() {
  const d = new Doc();
  const g = grid(6);
  const skin = d.material('Skin', [0.9, 0.5, 0.3, 1]), bare = d.material('Bare', [0.1, 0.7, 0.2, 1]);
  const flat = d.material('Flat', [0.3, 0.3, 0.9, 1]), cap = d.material('Cap', [1.5, -2, 0.5, 1]);
  const nrm = new Float32Array(g.pos.length);
  for (let i = 0; i < nrm.length; i += 3) nrm.set([0, 2, 0.1], i); // not unit: the loaders normalise
  const pos = d.accessor(g.pos, 'VEC3'), n = d.accessor(nrm, 'VEC3'), uv = d.accessor(g.uv, 'VEC2');
  const ix = d.accessor(g.idx, 'SCALAR');
  const m0 = d.mesh([{attributes: {POSITION: pos, NORMAL: n, TEXCOORD_0: uv}, indices: ix, material: skin},
    {attributes: {POSITION: pos, NORMAL: n}, indices: ix, material: bare}]);
  // flat: three triangles, no indices, no normals, u8 normalized uv
  const fp = new Float32Array([0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 0, 0, 1, 1, 0.2, 0, 1, 0, 0, 0, 0, 0, 1, 0, 0, 0, 1]);
  const fu = new Uint8Array([0, 0, 255, 0, 0, 255, 255, 0, 255, 255, 0, 255, 0, 0, 0, 255, 128, 128]);
  const m1 = d.mesh([{attributes: {POSITION: d.accessor(fp, 'VEC3'), TEXCOORD_0: d.accessor(fu, 'VEC2',
    {normalized: true})}, material: flat}]);
  // cap: a quad with u16 normalized uv, u32 indices
  const cp = new Float32Array([0, 0, 0, 1, 0, 0, 1, 0, 1, 0, 0, 1]);
  const cn = new Float32Array([0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0]);
  const cu = new Uint16Array([0, 0, 65535, 0, 65535, 65535, 0, 65535]);
  const m2 = d.mesh([{attributes: {POSITION: d.accessor(cp, 'VEC3'), NORMAL: d.accessor(cn, 'VEC3'),
    TEXCOORD_0: d.accessor(cu, 'VEC2', {normalized: true})}, indices: d.accessor(new Uint32Array([0, 2, 1, 0, 3, 2]),
    'SCALAR'), material: cap}]);
  const root = d.node({name: 'root', translation: [0.2, -0.1, 0.3], rotation: [0.1, 0.3, -0.2, 0.9], scale: [1, 1.5, 0.8],
    children: []}, true);
  // a mirroring matrix (det < 0), a shared mesh under two nodes, a deeper child
  const mirror = d.node({mesh: m0, matrix: [-1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0.5, 0, 0, 1]});
  const plain = d.node({mesh: m0, translation: [1.2, 0, 0], children: []});
  const deep = d.node({mesh: m1, rotation: [0, 0.7071068, 0, 0.7071068], translation: [0, 0.5, 0]});
  const capn = d.node({mesh: m2, scale: [2, 2, 2], translation: [0, -0.5, 0]});
  d.doc.nodes[root].children.push(mirror, plain, capn);
  d.doc.nodes[plain].children.push(deep);
  return d;
}

// Hostile and unsupported files: [name, bytes, a pattern the reason must match].
export function hostileModels(stoolBytes) {
  const out = [];
  const stool = Buffer.from(stoolBytes);
  const jlen = stool.readUInt32LE(12);
  const doc = JSON.parse(stool.subarray(20, 20 + jlen).toString());
  const bin = stool.subarray(28 + jlen);
  const edit = (name, f, why, fix) => {
    const d = structuredClone(doc);
    f(d);
    out.push([name, glb(d, bin, fix), why]);
  };
  out.push(['truncated.glb', stool.subarray(0, stool.length - 1000), /truncated/]);
  out.push(['header-only.glb', stool.subarray(0, 16), /truncated|not a valid glTF/]);
  out.push(['empty.glb', Buffer.alloc(0), /not a glTF file/]);
  out.push(['garbage.glb', Buffer.from('glTF\u0002\u0000\u0000\u0000garbage-garbage-garbage'), /not a valid glTF/]);
  out.push(['not-json.gltf', Buffer.from('{"asset": {"version": "2.0"}, '), /not a valid glTF/]);
  edit('index-out-of-bounds.glb', (d) => {
    // the legs' u8 indices point at vertex 200 of 98: rewrite through a new accessor
    // reading the same bytes as u8 but claiming a smaller POSITION count
    const leg = d.meshes[1].primitives[0];
    d.accessors[leg.attributes.POSITION].count = 10;
    for (const k of ['NORMAL', 'TEXCOORD_0']) d.accessors[leg.attributes[k]].count = 10;
  }, /index \d+ at \d+ is out of bounds/);
  edit('accessor-past-view.glb', (d) => {
    d.accessors[d.meshes[0].primitives[0].attributes.NORMAL].byteOffset = 64;
  }, /reads past its buffer view/);
  edit('view-past-buffer.glb', (d) => {
    d.bufferViews[0].byteLength = 1 << 30;
  }, /lies outside its buffer|byteLength/);
  edit('lines.glb', (d) => { d.meshes[1].primitives[0].mode = 1; }, /mode 1 \(only triangles/);
  edit('strip.glb', (d) => { d.meshes[0].primitives[1].mode = 5; }, /mode 5 \(only triangles/);
  edit('sparse.glb', (d) => {
    d.accessors[d.meshes[0].primitives[0].attributes.POSITION].sparse = {count: 1, indices: {bufferView: 0,
      componentType: 5123}, values: {bufferView: 0}};
  }, /sparse/);
  edit('draco.glb', (d) => {
    d.extensionsRequired = ['KHR_draco_mesh_compression'];
    d.extensionsUsed = ['KHR_draco_mesh_compression'];
  }, /required extension KHR_draco_mesh_compression/);
  edit('cycle.glb', (d) => { d.nodes[1].children = [0]; }, /deeper than 64|node instances/);
  edit('huge-count.glb', (d) => {
    d.accessors[d.meshes[0].primitives[0].attributes.POSITION].count = 3999999;
  }, /reads past its buffer view|elements/);
  edit('too-many-vertices.glb', (d) => {
    d.accessors[d.meshes[0].primitives[0].attributes.POSITION].count = 4000001;
  }, /vertices \(1\.\.4000000\)/);
  edit('no-triangles.glb', (d) => { d.scenes[0].nodes = []; }, /draws no triangles/);
  edit('bad-node.glb', (d) => { d.nodes[0].children.push(99); }, /node 99 does not exist/);
  edit('beyond-float.glb', (d) => {
    d.nodes[0].scale = [1e38, 1e38, 1e38];
    d.nodes[2].scale = [1e3, 1e3, 1e3];
  }, /a vertex is not finite under its node's transform/);
  edit('infinite-transform.glb', (d) => { d.nodes[2].translation = [0, 'INF', 0]; }, /number overflow/,
    (text) => text.replace('"INF"', '1e999'));
  return out;
}
