// btf-material.js - BTFMaterial: a streamed BTF package on a three.js mesh (WebGLRenderer).
//
//   import {BTFMaterial} from 'btf-stream/three';
//   const mat = new BTFMaterial({src: 'wss://btf.example.org/stream', material: 'knit'});
//   geometry.computeTangents();                    // the material needs tangents
//   scene.add(new THREE.Mesh(geometry, mat));
//   mat.addEventListener('change', () => renderer.render(scene, camera)); // a chunk arrived
//
// A THREE.RawShaderMaterial (a ShaderMaterial whose source three leaves alone) with
// glslVersion GLSL3, drawn with the program "three" of shaders/manifest.json: the very
// fragment files of the element's program "render" (btf_dirs.glsl, btf_decode.glsl,
// btf_tone.glsl, btf_light.glsl, btf_render.frag), assembled as btf-gl.js assembles them,
// and btf_three.vert, btf_render.vert on three's attribute names and matrices. three adds
// only its #version line and two #define lines. The chunks come through the element's
// modules (btf-stream.js or btf-http.js, btf-feed.js, btf-upload.js, btf-gl.js GpuPackage):
// the same page-wide stream, budgets, cache and decoder, and the same GPU layout, kept in
// three's textures by ThreeStore below (DataArrayTexture, RGBAIntegerFormat; the direction
// block a UniformsGroup). Each chunk updates the texture layers it changed (needsUpdate and
// addLayerUpdate; mip levels above 0 through renderer.copyTextureToTexture, which three
// offers for them) and fires 'change'. Lighting is the element's (doc/lighting.md): a distant
// point light and an environment, exposure and tone mapping in the shader, and the output
// sRGB-encoded, as the element writes it (three's own tone mapping and output conversion
// are not applied to this material). doc/client.md "three.js" has the options and limits.
import * as THREE from 'three';
import {BtfStream} from '../btf-stream.js';
import {MaterialFeed} from '../btf-feed.js';
import {assemble, decodeDefines, loadShaders} from '../btf-gl.js';
import {SHADER_PACK} from '../btf-shader-pack.js';
import {TONE, environmentAt} from '../btf-lighting.js';
import {envQuadratic, envUniforms, matMul, rotateQuadratic, rotationZ, studioImage} from '../btf-env.js';
import {LOD_THRESHOLD} from '../btf-lod.js';

const SHADERS_URL = new URL('../shaders/', import.meta.url).href; // shaders/ next to btf-viewer.js
const PROGRAM = 'three';
const FINEST_PIXELS = 1e6; // the default footprint: every level (device pixels one repeat spans)
// The world of a y-up scene (three's, glTF's) from the project's z-up one (doc/lighting.md 2):
// d_y = Y_FROM_Z d_z, (x, y, z) -> (x, z, -y).
const Y_FROM_Z = [[1, 0, 0], [0, 0, 1], [0, -1, 0]];

let studioQuad = null;

// The shader files of the program "three" (inside the package's bundle, else fetched once
// per base URL).
function shaderFiles(base) {
  if (!base && SHADER_PACK && SHADER_PACK.manifest.programs[PROGRAM])
    return Promise.resolve({manifest: SHADER_PACK.manifest, files: new Map(Object.entries(SHADER_PACK.files))});
  return loadShaders(base || SHADERS_URL, PROGRAM);
}

function intTexture(data, width, height, depth, type, layers) {
  const t = layers ? new THREE.DataArrayTexture(data, width, height, depth) : new THREE.DataTexture(data, width, height);
  t.format = THREE.RGBAIntegerFormat;
  t.type = type;
  t.internalFormat = type === THREE.UnsignedShortType ? 'RGBA16UI' : 'RGBA32UI';
  t.minFilter = t.magFilter = THREE.NearestFilter;
  t.wrapS = t.wrapT = THREE.ClampToEdgeWrapping;
  t.generateMipmaps = false;
  t.flipY = false;
  t.unpackAlignment = 1;
  t.needsUpdate = true;
  return t;
}

// A package's GPU layout (btf-gl.js GpuPackage) in three.js objects: the direction block as
// a UniformsGroup named btf_dirs_block (one Uniform: 1024 Vector4), the tables as RGBA32UI
// DataTextures, the layers as DataArrayTextures (RGBA16UI with the package's levels as mip
// levels, RGBA32UI where GpuPackage pairs each level with the next coarser one; RGBA32UI).
// Layer updates go into the textures' data and are flagged (addLayerUpdate, needsUpdate);
// three uploads them at the next render. three uploads only level 0 of a
// DataArrayTexture, so the levels above it are written at the next render by
// flush(renderer) with renderer.copyTextureToTexture.
export class ThreeStore {
  constructor() {
    this.packageStore = true; // GpuPackage takes it in place of a WebGL context
    this.group = this.cells = this.tris = this.tex = this.wt = this.envW = null;
    this.levelPuts = new Map(); // 'h,l' -> {h, l, width, height, data}: levels above 0 to write
    this.dropped = [];          // textures replaced, disposed at the next flush
  }

  dirs(ubo, cells, tris) {
    const verts = [];
    for (let i = 0; i < ubo.length; i += 4) verts.push(new THREE.Vector4(ubo[i], ubo[i + 1], ubo[i + 2], ubo[i + 3]));
    this.group = new THREE.UniformsGroup();
    this.group.setName('btf_dirs_block');
    this.group.add(new THREE.Uniform(verts));
    this.cells = intTexture(cells.data, cells.width, cells.height, 1, THREE.UnsignedIntType, false);
    this.tris = intTexture(tris.data, tris.width, tris.height, 1, THREE.UnsignedIntType, false);
  }

  allocate({levels, paired, width, height, lights, views, layers}) {
    this.dropped.push(this.wt, this.envW);
    this.allocateTex({levels, paired, width, height, layers});
    this.wt = intTexture(new Uint32Array(4 * lights * views * layers), lights, views, layers, THREE.UnsignedIntType, true);
    this.envW = intTexture(new Uint32Array(4 * 9 * views * layers), 9, views, layers, THREE.UnsignedIntType, true);
  }

  // u_btf_tex alone, anew (GlStore.allocateTex): RGBA16UI, paired RGBA32UI.
  allocateTex({levels, paired, width, height, layers}) {
    this.dropped.push(this.tex);
    this.levelPuts.clear();
    this.texType = paired ? THREE.UnsignedIntType : THREE.UnsignedShortType;
    const Texels = paired ? Uint32Array : Uint16Array;
    this.tex = intTexture(new Texels(4 * width * height * layers), width, height, layers, this.texType, true);
    if (levels > 1) {
      this.tex.minFilter = THREE.NearestMipmapNearestFilter;
      // the mip levels three allocates (texStorage3D); their data comes by flush()
      this.tex.mipmaps = Array.from({length: levels}, (_, l) => ({data: null, width: width >> l, height: height >> l,
        depth: layers}));
    }
  }

  putLayer(t, h, width, height, data) {
    t.image.data.set(data, 4 * width * height * h);
    t.addLayerUpdate(h);
    t.needsUpdate = true;
  }

  putTex(h, l, width, height, data) {
    if (l === 0) this.putLayer(this.tex, h, width, height, data);
    else this.levelPuts.set(`${h},${l}`, {h, l, width, height, data}); // the level's latest state at flush
  }

  putWt(h, width, height, data) {
    this.putLayer(this.wt, h, width, height, data);
  }

  putEnv(h, width, height, data) {
    this.putLayer(this.envW, h, width, height, data);
  }

  // Before a draw: the mip levels above 0 into the texture (after three uploaded level 0),
  // the replaced textures disposed.
  flush(renderer) {
    for (const t of this.dropped.splice(0)) t?.dispose();
    if (!this.levelPuts.size) return;
    const at = new THREE.Vector3();
    for (const {h, l, width, height, data} of this.levelPuts.values()) {
      const src = new THREE.DataTexture(data, width, height, THREE.RGBAIntegerFormat, this.texType);
      renderer.copyTextureToTexture(src, this.tex, null, at.set(0, 0, h), 0, l);
    }
    this.levelPuts.clear();
  }

  free() {
    for (const t of [...this.dropped.splice(0), this.tex, this.wt, this.envW, this.cells, this.tris]) t?.dispose();
    this.group?.dispose();
    this.levelPuts.clear();
    this.group = this.cells = this.tris = this.tex = this.wt = this.envW = null;
  }
}

const vec3 = (v) => (Array.isArray(v) ? new THREE.Vector3(...v) : new THREE.Vector3().copy(v));

// Owned by the page; lives until dispose(). Options (all but src and material optional):
//   src            btfd's WebSocket (ws://, wss://) or a published library folder (http(s)://),
//                  relative to the page; required (a package has no script origin to default to)
//   material       the library material's name; required
//   token          a private library's access token (the element's `token`), default none
//   shaders        base URL of the shader files (default: inside the package, else shaders/
//                  next to btf-viewer.js)
//   repeat         number or [u, v]: material repeats per unit of uv (default 1)
//   wrap           true (default): tile the material; false: clamp at uv 0 and 1
//   filter         'bilinear' (default) or 'nearest'
//   flipY          true (default, three's geometries and textures): image row 0 at uv.y = 1;
//                  false for a glTF model loaded by GLTFLoader (its textures are not flipped)
//   light          direction towards a distant point light in world space (THREE.Vector3
//                  or [x, y, z]); null (default): none
//   environment    'studio', the URL of an equirectangular Radiance .hdr, or null; default
//                  'studio' without a light, else null (the element's defaults)
//   environmentRotation  degrees about the up axis (default 0)
//   up             'y' (default, three's and glTF's): the environment's top is +y, its
//                  centre faces +x; 'z': the project's own frame (btf render, <btf-viewer>)
//   exposure       default 1; toneMapping 'auto' (default: neutral with an environment,
//                  else none), 'none', 'neutral', 'aces'
//   horizonFade    true (default): lights below the outermost measured ring fade out
//   budgetChunks, budgetBytes  most chunks / bytes to stream (default: no cap)
//   pixels         device pixels one repeat of the material spans on screen: the scene
//                  budget of version-2 packages (default 1e6: every level)
//   lodThreshold   the scene budget's visibility threshold (default 1, RMS on 0..255)
// Events (this.addEventListener): 'change' (draw again: a chunk or the environment came),
// 'progress' {chunks, chunksWanted, bytes, bytesWanted, error, metric}, 'load' {chunks} (the
// first draw with a chunk), 'complete' (as progress; everything in the budget drawn),
// 'error' {reason, retrying}.
export class BTFMaterial extends THREE.RawShaderMaterial {
  constructor(options = {}) {
    super({glslVersion: THREE.GLSL3, vertexShader: 'void main() {}', fragmentShader: 'void main() {}'});
    this.type = 'BTFMaterial';
    this.isBTFMaterial = true;
    this.toneMapped = false; // tone mapping is the material's own (btf_light.glsl)
    this.visible = false;    // until the first chunk (and the environment, if any) is here
    const o = {repeat: 1, wrap: true, filter: 'bilinear', flipY: true, light: null, environmentRotation: 0, up: 'y',
      exposure: 1, toneMapping: 'auto', horizonFade: true, budgetChunks: null, budgetBytes: -1, pixels: FINEST_PIXELS,
      lodThreshold: LOD_THRESHOLD, shaders: null, ...options};
    if (!o.src || !o.material) throw new Error('BTFMaterial: the options src and material are required');
    if (!('environment' in options)) o.environment = o.light ? null : 'studio';
    this.options = o;
    this.src = new URL(o.src, globalThis.document?.baseURI ?? globalThis.location?.href).href;
    this.material = o.material;
    this.errorText = null;
    this.outage = false;
    this.loaded = false;
    this.completeFor = null;
    this.variantKey = null;
    this.variantFilter = null; // the filter of the program variant (program())
    this.store = null;
    this.shaders = null; // {manifest, files} once loaded
    this.env = {key: null, quad: null, state: 'none', error: null};
    const u = (value) => ({value});
    this.uniforms = {
      u_btf_tex: u(null), u_btf_wt: u(null), u_btf_dir_cells: u(null), u_btf_dir_tris: u(null), u_btf_env_w: u(null),
      u_btf_tq: u(new Float32Array(4)), u_btf_wq: u(new Float32Array(4)), u_btf_size: u([1, 1]),
      u_btf_atlas_cols: u(1), u_btf_outer_cos: u(0), u_btf_chunks: u(0), u_btf_levels: u(1), u_btf_lod: u(0),
      u_btf_lod_auto: u(1), u_btf_filter: u(1), u_btf_wrap: u(1), u_btf_linear: u(0), u_btf_env_s: u(new Float32Array(4)),
      u_camera: u(new THREE.Vector3()), u_light: u(new THREE.Vector4(0, 0, 1, 0)), u_uv_scale: u(new THREE.Vector2(1, 1)),
      u_horizon_fade: u(1), u_flip_y: u(1), u_point_off: u(1), u_env_on: u(0), u_exposure: u(1), u_tone: u(0),
      u_env_c0: u(new Float32Array(3)), u_env_a: u(new Float32Array(9)), u_env_q: u(new Float32Array(27)),
    };
    const mat = this;
    // the session btf-feed.js reports to (btf-session.js's part of it that one material needs)
    this.session = {
      closed: false,
      host: {asked: () => ({chunks: o.budgetChunks ?? null, bytes: o.budgetBytes ?? -1, threshold: o.lodThreshold})},
      fail: (e) => mat.fail(e),
      feedManifest: (feed) => {
        mat.recovered();
        feed.newGpu((mat.store = new ThreeStore()));
        mat.uniformsGroups = [mat.store.group];
        mat.ready();
      },
      feedChunk: (feed, j) => {
        mat.recovered();
        mat.emit('progress', feed.progress(j + 1));
      },
      feedComplete: () => mat.changed(),
      feedError: (feed, msg) => mat.fail(new Error(`${msg.message} (${msg.code})`)),
      streamError: (text, info = {}) => mat.trouble(text, info),
      streamOpen: () => mat.recovered(),
      decoded: () => mat.uploadDecoded(),
    };
    this.feed = new MaterialFeed(this.session, o.material, {pixels: () => o.pixels, policy: () => -1,
      token: () => o.token || null});
    shaderFiles(o.shaders).then((sh) => {
      this.shaders = sh;
      this.ready();
    }, (e) => this.fail(e));
    this.setLighting({});
    this.feed.subscribe(BtfStream.for(this.src));
  }

  // ------------------------------------------------------------ lighting

  // Changes the lighting (any of light, environment, environmentRotation, up, exposure,
  // toneMapping, horizonFade); the next draw uses it ('change' fires).
  setLighting(changes) {
    Object.assign(this.options, changes);
    const o = this.options;
    if (o.toneMapping !== 'auto' && !(o.toneMapping in TONE)) throw new Error(`BTFMaterial: unknown toneMapping '${o.toneMapping}'`);
    const key = o.environment ? (o.environment === 'studio' ? 'studio' : new URL(o.environment, globalThis.document?.baseURI).href) : null;
    if (key !== this.env.key) {
      const env = (this.env = {key, quad: null, state: key ? 'loading' : 'none', error: null});
      if (key) environmentAt(key).then((q) => {
        if (this.env !== env) return;
        env.quad = q;
        env.state = 'ready';
        this.ready();
      }, (e) => {
        if (this.env !== env) return;
        env.state = 'failed';
        env.error = e.message;
        this.emit('error', {reason: e.message});
        this.ready();
      });
    }
    this.ready();
  }

  // What the draws are lit by: {point: {on, direction}, environment: {image, state, error, on,
  // rotation}, exposure, toneMapping, up}.
  get lighting() {
    const o = this.options, q = this.envQuad(), t = this.tone(q);
    return {point: {on: !!o.light, direction: o.light ? vec3(o.light).toArray() : null},
      environment: {image: this.env.key, state: this.env.state, error: this.env.error, on: !!q, rotation: o.environmentRotation},
      exposure: o.exposure, toneMapping: Object.keys(TONE).find((k) => TONE[k] === t), up: o.up};
  }

  // The environment that lights the draws: the one asked for once here; the studio in place of
  // one that failed when no point light is on (something must light the mesh).
  envQuad() {
    if (this.env.state === 'ready') return this.env.quad;
    if (this.env.state === 'failed' && !this.options.light) return (studioQuad ??= envQuadratic(studioImage()));
    return null;
  }

  tone(q) {
    const t = this.options.toneMapping;
    return t === 'auto' ? (q ? TONE.neutral : TONE.none) : TONE[t];
  }

  // The light uniforms (btf-render.js setLights): point light, the environment's quadratic
  // turned by the rotation about the up axis (and into a y-up world), exposure, tone.
  lightUniforms() {
    const o = this.options, un = this.uniforms, q = this.envQuad();
    un.u_point_off.value = o.light ? 0 : 1;
    if (o.light) un.u_light.value.set(...vec3(o.light).normalize().toArray(), 0);
    un.u_env_on.value = q ? 1 : 0;
    un.u_exposure.value = Math.max(0, o.exposure);
    un.u_tone.value = this.tone(q);
    un.u_horizon_fade.value = o.horizonFade === false ? 0 : 1;
    if (q) {
      const R = rotationZ(o.environmentRotation || 0), key = `${this.env.key}|${o.environmentRotation}|${o.up}|${this.env.state}`;
      if (this.envKey !== key) {
        const e = envUniforms(rotateQuadratic(q, o.up === 'z' ? R : matMul(Y_FROM_Z, R)));
        un.u_env_c0.value = e.c0;
        un.u_env_a.value = e.a;
        un.u_env_q.value = e.q;
        this.envKey = key;
      }
    }
  }

  // ------------------------------------------------------------ program and chunks

  // The program variant (btf-gl.js decodeDefines: filter, levels, layers, lights), compiled by
  // three from the assembled source (once per variant; three keeps its programs by source).
  program() {
    const gpu = this.feed.gpu, o = this.options;
    if (!gpu || !this.shaders) return false;
    const filter = o.filter === 'nearest' ? 0 : 1;
    const defines = decodeDefines(gpu.pkg, filter, Math.max(gpu.capacity, 1), {point: !!o.light, env: !!this.envQuad()});
    const key = defines.map((d) => d.join('=')).join(',');
    if (key === this.variantKey) return true;
    this.variantFilter = filter; // the draws lay u_btf_tex out for it (onBeforeRender)
    const version = this.shaders.manifest.prefix[0];
    if (version !== '#version 300 es') throw new Error(`BTFMaterial: the shaders' prefix starts with '${version}'`);
    const stage = (s) => assemble(this.shaders, PROGRAM, s, defines).text.slice(version.length + 1); // three adds #version
    this.vertexShader = stage('vertex');
    this.fragmentShader = stage('fragment');
    this.variantKey = key;
    this.needsUpdate = true;
    return true;
  }

  // Shaders, manifest or environment arrived: the mesh shows once a chunk is in and the
  // environment (if any) is here.
  ready() {
    if (this.errorText) return;
    try {
      const waiting = this.env.state === 'loading' || !this.program() || !this.feed.gpu || !this.feed.gpu.uploaded;
      this.visible = !waiting;
    } catch (e) {
      return this.fail(e);
    }
    this.changed();
  }

  // Decoded chunks into the textures (btf-upload.js; CPU work, three uploads at the next draw).
  uploadDecoded() {
    if (this.session.closed) return;
    try {
      if (this.feed.upload(Infinity)) this.ready();
    } catch (e) {
      this.fail(e);
    }
  }

  // three calls this before each draw of a mesh with this material.
  onBeforeRender(renderer, scene, camera) {
    const gpu = this.feed.gpu;
    if (!gpu || !this.store) return;
    const filter = this.variantFilter ?? 1; // the program's: u_btf_tex paired only for nearest levels
    gpu.setFilter(filter);
    this.store.flush(renderer);
    const o = this.options, un = this.uniforms, chunks = this.feed.drawableChunks();
    for (const [name, , v] of gpu.uniforms({chunks, filter, wrap: o.wrap ? 1 : 0}))
      un[name].value = v;
    un.u_btf_tex.value = this.store.tex;
    un.u_btf_wt.value = this.store.wt;
    un.u_btf_env_w.value = this.store.envW;
    un.u_btf_dir_cells.value = this.store.cells;
    un.u_btf_dir_tris.value = this.store.tris;
    un.u_camera.value.setFromMatrixPosition(camera.matrixWorld);
    const r = Array.isArray(o.repeat) ? o.repeat : [o.repeat, o.repeat];
    un.u_uv_scale.value.set(r[0], r[1]);
    un.u_flip_y.value = o.flipY === false ? 0 : 1;
    this.lightUniforms();
    this.uniformsNeedUpdate = true;
    this.drawn(chunks);
  }

  // Events of a draw that shows chunks: load (the first), complete (all of the budget).
  drawn(chunks) {
    if (!chunks) return;
    const feed = this.feed;
    feed.drawnChunks = chunks;
    if (!this.loaded) {
      this.loaded = true;
      this.emit('load', {chunks});
    }
    const key = String(feed.ownLimit());
    if (feed.done() && this.completeFor !== key) {
      this.completeFor = key;
      queueMicrotask(() => this.emit('complete', feed.progress()));
    }
  }

  // ------------------------------------------------------------ budget, state, events

  // Changes the budget (budgetChunks, budgetBytes, pixels, lodThreshold).
  setBudget(changes) {
    Object.assign(this.options, changes);
    this.feed.budgetChanged();
    this.ready();
  }

  // {chunks, chunksWanted, bytes, bytesWanted, error, metric} (as the element's progress event).
  get progress() {
    return this.feed.progress();
  }

  // Test hook and diagnostics: the feed's state (btf-feed.js), the variant, the textures' versions.
  state() {
    const st = this.store;
    return {...this.feed.state(), visible: this.visible, variant: this.variantKey, error: this.errorText,
      textures: st && st.tex ? {tex: st.tex.version, wt: st.wt.version, env: st.envW.version} : null, lighting: this.lighting};
  }

  emit(type, detail = {}) {
    this.dispatchEvent({type, ...detail});
  }

  changed() {
    this.emit('change');
  }

  // A failure the stream recovers from: one 'error' {reason, retrying: true} per outage.
  trouble(text, info) {
    if (!info.retrying || this.outage) return;
    this.outage = true;
    this.emit('error', {reason: text, retrying: true});
  }

  recovered() {
    this.outage = false;
  }

  // A final failure: one 'error' event; the mesh keeps what it drew.
  fail(e) {
    if (this.errorText) return;
    this.errorText = String(e && e.message ? e.message : e);
    this.emit('error', {reason: this.errorText});
  }

  // Unsubscribes and frees the textures (three's dispose()).
  dispose() {
    this.session.closed = true;
    this.feed.stop();
    this.store = null;
    super.dispose();
  }
}
