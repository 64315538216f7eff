// btf-render.js - draws a package on a surface with the program "render" of
// shaders/manifest.json (btf_render.vert, btf_dirs.glsl, btf_decode.glsl,
// btf_light.glsl, btf_render.frag): the very program `btf render` draws with in the headless C
// harness, with the same mesh, camera and uniforms (scene.js ports shaders/host/btf_render.c);
// and a model's parts (btf-model.js) with their packages, the unbound ones with the
// program "flat" (btf_flat.frag), as btf_scene_draw (shaders/host/btf_scene.c) does.

import {FixedLight} from './btf-fixed.js';
import {buildProgram, decodeDefines, finishProgram, programReady, startProgram} from './btf-gl.js';
import {buildMesh, cameraMake} from './scene.js';

// MeshRenderer uses the program "render" (btf_render.vert, btf_dirs.glsl,
// btf_decode.glsl, btf_light.glsl, btf_render.frag), the one `btf render` draws with: a triangle
// mesh of the surface (scene.js buildMesh) and the decoder per fragment, compiled
// once per specialisation (decodeDefines: filter, levels, 4-slot layers in use, lights), and
// only the ones drawn: start() sends a variant to the driver as soon as it is known
// (the page goes on meanwhile), ready() says whether using it would wait, draw()
// waits for it where it must.
const FLAT_AMBIENT = 0.25; // BTF_SCENE_FLAT_AMBIENT: u_flat_ambient, the share of full light an unlit side keeps
const IDENTITY = new Float32Array([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]);
// The lights of a view without `lighting`: the point light alone, as measured.
export const POINT_LIGHT = {point: true, env: null, exposure: 1, tone: 0};

// Sets the uniforms of shaders/btf_light.glsl on p (in use) for lights {point, env
// (btf-env.js envUniforms) | null, exposure, tone}, as btf_render_light_uniforms does.
function setLights(gl, p, lights) {
  gl.uniform1i(p.loc('u_point_off'), lights.point ? 0 : 1);
  gl.uniform1i(p.loc('u_env_on'), lights.env ? 1 : 0);
  gl.uniform1f(p.loc('u_exposure'), lights.exposure);
  gl.uniform1i(p.loc('u_tone'), lights.tone);
  if (!lights.env) return;
  gl.uniform3fv(p.loc('u_env_c0'), lights.env.c0);
  gl.uniformMatrix3fv(p.loc('u_env_a'), false, lights.env.a);
  gl.uniformMatrix3fv(p.loc('u_env_q'), false, lights.env.q);
}

export class MeshRenderer {
  constructor(gl, shaders) {
    this.gl = gl;
    this.shaders = {manifest: {...shaders.manifest, programs: {...shaders.manifest.programs}}, files: new Map(shaders.files)};
    this.flat = null; // the linked program "flat" (drawScene), once a model drew
    this.progs = new Map(); // defines key -> linked program
    this.pending = new Map(); // defines key -> startProgram's compile in flight
    this.meshes = new Map(); // geometry -> {vao, count, buffers}
    this.fixed = null; // FixedLight of the package draw() last blended a plane's light for
  }

  static key(defines) {
    return defines.map((d) => d.join('=')).join(',');
  }

  // Adds the programs and files of more shader files (a model's viewer adds "flat" to a
  // renderer a viewer of one material made with "render" only).
  include(shaders) {
    Object.assign(this.shaders.manifest.programs, shaders.manifest.programs);
    for (const [k, v] of shaders.files) this.shaders.files.set(k, v);
  }

  // Starts compiling a variant (the GPU process compiles it while the page goes on).
  start(defines) {
    const key = MeshRenderer.key(defines);
    if (!this.progs.has(key) && !this.pending.has(key))
      this.pending.set(key, startProgram(this.gl, this.shaders, 'render', defines));
  }

  // True when the variant can be used without waiting on the driver (started if it was
  // not; with KHR_parallel_shader_compile checked without blocking, else at once).
  ready(defines) {
    const key = MeshRenderer.key(defines);
    if (this.progs.has(key)) return true;
    this.start(defines);
    if (!programReady(this.pending.get(key))) return false;
    this.program(defines); // a broken shader throws here, with its report
    return true;
  }

  // The linked variant for defines (compiled now, or finished now if it was started).
  program(defines) {
    const key = MeshRenderer.key(defines);
    if (!this.progs.has(key)) {
      const started = this.pending.get(key) || startProgram(this.gl, this.shaders, 'render', defines);
      this.pending.delete(key);
      this.progs.set(key, finishProgram(started));
    }
    return this.progs.get(key);
  }

  // The variant pkg (a GpuPackage) is drawn with: `quads` 4-slot layers (default: every
  // slot the package has room for; unused slots have zero weights, so one compile per
  // package, not one per 4 slots as chunks stream in; -1: a loop over the slots in use),
  // the light terms of `lights` ({point, env}) only.
  static defines(pkg, filter, quads = 0, lights = POINT_LIGHT) {
    const l = {point: !!lights.point, env: !!lights.env};
    if (quads < 0) return decodeDefines(pkg.pkg, filter, 4, l).filter(([name]) => name !== 'BTF_QUADS');
    return decodeDefines(pkg.pkg, filter, quads > 0 ? 4 * quads : Math.max(pkg.capacity, 1), l);
  }

  mesh(geometry) {
    if (this.meshes.has(geometry)) return this.meshes.get(geometry);
    const gl = this.gl, m = buildMesh(geometry);
    const vao = gl.createVertexArray();
    gl.bindVertexArray(vao);
    const vb = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, vb);
    gl.bufferData(gl.ARRAY_BUFFER, m.vertices, gl.STATIC_DRAW);
    [[3, 0], [3, 3], [4, 6], [2, 10]].forEach(([size, off], loc) => {
      gl.enableVertexAttribArray(loc);
      gl.vertexAttribPointer(loc, size, gl.FLOAT, false, 48, off * 4);
    });
    const ib = gl.createBuffer();
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, ib);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, m.indices, gl.STATIC_DRAW);
    gl.bindVertexArray(null);
    const r = {vao, count: m.indices.length, buffers: [vb, ib]};
    this.meshes.set(geometry, r);
    return r;
  }

  // Clears to the background and draws a model's parts for the scene `view` (as draw(),
  // plus target and extent: scene.js cameraMake): each layer ({gpu, chunks, quads,
  // groups: [{uvScale, meshes: [{vao, count}]}]}, btf-model.js layers()) with the render
  // program of its package, tiled (wrap) with each group's repeats; then each flat part
  // ({mesh, color}) with the program "flat" in its base colour, all into one depth buffer.
  drawScene({layers, flats}, view, w, h) {
    const gl = this.gl;
    gl.viewport(0, 0, w, h);
    gl.clearColor(...view.background, 1);
    gl.clearDepth(1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    const cam = cameraMake(view, w / h), lights = view.lighting || POINT_LIGHT;
    gl.enable(gl.DEPTH_TEST);
    for (const l of layers) {
      const p = this.program(MeshRenderer.defines(l.gpu, 1, l.quads, lights));
      gl.useProgram(p.program);
      l.gpu.bind(p, 0, {chunks: l.chunks, filter: 1, wrap: 1});
      setLights(gl, p, lights);
      gl.uniformMatrix4fv(p.loc('u_model'), false, IDENTITY);
      gl.uniformMatrix4fv(p.loc('u_view_proj'), false, cam.viewProj);
      gl.uniform3fv(p.loc('u_camera'), cam.eye);
      gl.uniform4f(p.loc('u_light'), cam.light[0], cam.light[1], cam.light[2], 0);
      gl.uniform1i(p.loc('u_horizon_fade'), view.horizonFade === false ? 0 : 1);
      for (const g of l.groups) {
        gl.uniform2f(p.loc('u_uv_scale'), g.uvScale[0], g.uvScale[1]);
        for (const m of g.meshes) {
          gl.bindVertexArray(m.vao);
          gl.drawElements(gl.TRIANGLES, m.count, gl.UNSIGNED_INT, 0);
        }
      }
    }
    if (flats.length) {
      if (!this.flat) this.flat = buildProgram(gl, this.shaders, 'flat');
      const p = this.flat;
      gl.useProgram(p.program);
      gl.uniformMatrix4fv(p.loc('u_model'), false, IDENTITY);
      gl.uniformMatrix4fv(p.loc('u_view_proj'), false, cam.viewProj);
      gl.uniform4f(p.loc('u_light'), cam.light[0], cam.light[1], cam.light[2], 0);
      gl.uniform1f(p.loc('u_flat_ambient'), FLAT_AMBIENT);
      setLights(gl, p, lights); // the flat parts get the same lights, exposure and tone curve
      for (const f of flats) {
        gl.uniform4f(p.loc('u_base_color'), f.color[0], f.color[1], f.color[2], f.color[3]);
        gl.bindVertexArray(f.mesh.vao);
        gl.drawElements(gl.TRIANGLES, f.mesh.count, gl.UNSIGNED_INT, 0);
      }
    }
    gl.bindVertexArray(null);
    gl.disable(gl.DEPTH_TEST);
  }

  // Clears to the background and draws pkg (a GpuPackage) for the scene `view`
  // ({geometry, camera/light angles, fov, repeat, background, chunks, horizonFade,
  // filter: 0 nearest, else bilinear, quads: the variant's layers, see defines;
  // lighting: {point, env, exposure, tone}, default POINT_LIGHT; fixedLight: false keeps
  // the run-time light path on the plane}), as btf_renderer_draw does.
  draw(pkg, view, w, h) {
    const gl = this.gl;
    gl.viewport(0, 0, w, h);
    gl.clearColor(...view.background, 1);
    gl.clearDepth(1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    if (!pkg || !pkg.uploaded || !view.chunks) return;
    const cam = cameraMake(view, w / h), lights = view.lighting || POINT_LIGHT;
    const filter = view.filter === 0 ? 0 : 1;
    const defines = MeshRenderer.defines(pkg, filter, view.quads, lights);
    // a distant light on the plane: one local direction (cam.light, the plane's frame is the
    // world's), blended once per draw (btf-fixed.js), once that variant compiled: started by
    // the first such draw, which (like every draw until it is ready) takes the run-time
    // path, so a first frame never waits on its compile, with KHR_parallel_shader_compile or not
    const fixed = view.geometry === 'plane' && lights.point && view.fixedLight !== false
      ? [...defines, ['BTF_FIXED_LIGHT', 1]] : null;
    const fixedKey = fixed && MeshRenderer.key(fixed);
    const useFixed = !!fixed && (this.progs.has(fixedKey) || (this.pending.has(fixedKey) && this.ready(fixed)));
    if (fixed && !useFixed) this.start(fixed);
    const p = this.program(useFixed ? fixed : defines);
    gl.useProgram(p.program);
    pkg.bind(p, 0, {chunks: view.chunks, filter, wrap: cam.wrap});
    if (useFixed) {
      if (!this.fixed || this.fixed.gpu !== pkg) {
        if (this.fixed) this.fixed.free();
        this.fixed = new FixedLight(gl, pkg);
      }
      const used = pkg.pkg.version >= 2 ? (view.chunks > 0 ? pkg.slots : 0) : Math.min(view.chunks, pkg.uploaded);
      this.fixed.bind(p, 5, cam.light, used);
    }
    setLights(gl, p, lights);
    gl.uniformMatrix4fv(p.loc('u_model'), false, new Float32Array([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]));
    gl.uniformMatrix4fv(p.loc('u_view_proj'), false, cam.viewProj);
    gl.uniform3fv(p.loc('u_camera'), cam.eye);
    gl.uniform4f(p.loc('u_light'), cam.light[0], cam.light[1], cam.light[2], 0);
    gl.uniform2f(p.loc('u_uv_scale'), cam.uvScale[0], cam.uvScale[1]);
    gl.uniform1i(p.loc('u_horizon_fade'), view.horizonFade === false ? 0 : 1);
    gl.enable(gl.DEPTH_TEST);
    const m = this.mesh(view.geometry);
    gl.bindVertexArray(m.vao);
    gl.drawElements(gl.TRIANGLES, m.count, gl.UNSIGNED_INT, 0);
    gl.bindVertexArray(null);
    gl.disable(gl.DEPTH_TEST);
  }

  free() {
    const gl = this.gl;
    for (const p of this.progs.values()) gl.deleteProgram(p.program);
    if (this.flat) gl.deleteProgram(this.flat.program);
    this.flat = null;
    for (const p of this.pending.values()) {
      [p.vs, p.fs].forEach((sh) => gl.deleteShader(sh));
      gl.deleteProgram(p.program);
    }
    this.progs.clear();
    this.pending.clear();
    for (const m of this.meshes.values()) {
      gl.deleteVertexArray(m.vao);
      m.buffers.forEach((b) => gl.deleteBuffer(b));
    }
    this.meshes.clear();
    if (this.fixed) this.fixed.free();
    this.fixed = null;
  }
}

