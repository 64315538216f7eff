// btf-context.js - one WebGL2 context for every <btf-viewer> of the page. Browsers
// allow only a few live contexts per page (Chromium: 16), so a page of 40 viewers
// cannot give each its own. Each viewer draws into the bottom-left of one shared,
// unattached canvas and copies that region into its own 2D canvas (drawImage) in
// the same task; each variant of the program "render" is compiled once per shader base.
import {loadShaders} from './btf-gl.js';
import {MeshRenderer} from './btf-render.js';

let shared;
const SHOWN_POLL_MS = 8; // how often a frame whose picture is awaited asks whether the GPU passed it

function rendererName(gl) {
  const ext = gl.getExtension('WEBGL_debug_renderer_info');
  return String(gl.getParameter(ext ? ext.UNMASKED_RENDERER_WEBGL : gl.RENDERER) || '');
}

class SharedGl {
  constructor() {
    this.canvas = document.createElement('canvas');
    this.canvas.width = this.canvas.height = 1;
    this.gl = this.canvas.getContext('webgl2', {antialias: false, premultipliedAlpha: false, alpha: false});
    this.lost = false;
    // a software rasteriser (SwiftShader, llvmpipe): viewers start at fewer pixels and draw with the loop variant
    this.software = this.gl ? /swiftshader|llvmpipe|software/i.test(rendererName(this.gl)) : false;
    this.users = new Set();      // viewers: contextLost(), contextRestored()
    this.renderers = new Map();  // shader base URL -> Promise of MeshRenderer
    this.drawnFns = [];          // afterFrame callbacks of this animation frame's draws (its fence not in yet)
    this.fenceFns = [];          // afterFrame callbacks of the fence in flight
    this.canvas.addEventListener('webglcontextlost', (e) => {
      e.preventDefault();
      this.lost = true;
      this.fence = null;
      this.drawnFns = []; // their pictures never showed
      this.fenceFns = [];
      this.renderers.clear();
      for (const u of this.users) u.contextLost();
    });
    this.canvas.addEventListener('webglcontextrestored', () => {
      this.lost = false;
      for (const u of this.users) u.contextRestored();
    });
  }

  // The renderer of the program "render" of the shader files at base (only that
  // program's files are fetched, unless `files` gives them; its variants compile once
  // per context).
  renderer(base, files = null) {
    if (!this.renderers.has(base)) {
      const p = (files || loadShaders(base, 'render')).then((sh) => new MeshRenderer(this.gl, sh));
      p.catch(() => this.renderers.get(base) === p && this.renderers.delete(base));
      this.renderers.set(base, p);
    }
    return this.renderers.get(base);
  }

  // Grows the drawing buffer to at least w x h (a viewer draws into its bottom-left).
  fit(w, h) {
    const c = this.canvas;
    if (c.width < w || c.height < h) {
      c.width = Math.max(c.width, w);
      c.height = Math.max(c.height, h);
    }
  }

  // Copies the w x h frame just drawn into a viewer's 2D context.
  present(ctx2d, w, h) {
    ctx2d.drawImage(this.canvas, 0, this.canvas.height - h, w, h, 0, 0, w, h);
  }

  // Frames are paced by the GPU: after the draws of one animation frame (tick: its rAF
  // time) a fence goes in, and no viewer draws again until the GPU has passed it, so on
  // software GL or a slow GPU frames never queue up behind each other (new chunks and
  // the user's input show in the next frame the GPU can take). gpuMs: how long the GPU
  // took for the last fenced frame. The afterFrame callbacks of these draws wait on the
  // fence (one of this animation frame already in, another viewer's: these draws follow
  // it in the same task); without fences they run at once.
  drewIn(tick) {
    const gl = this.gl, fns = this.drawnFns;
    this.drawnFns = [];
    if (typeof gl.fenceSync !== 'function') {
      const now = performance.now();
      for (const fn of fns) fn(now);
      return;
    }
    if (!this.fence) {
      this.fence = gl.fenceSync(gl.SYNC_GPU_COMMANDS_COMPLETE, 0);
      gl.flush();
      this.fenceAt = performance.now();
      this.fenceTick = tick;
    }
    this.fenceFns.push(...fns);
    if (fns.length) this.pollShown();
  }

  // fn(ms since navigation start) once the GPU has passed the draws just made (the
  // fence drewIn puts after them): when their picture can reach the screen, which on a
  // slow GPU is well after the draw call.
  afterFrame(fn) {
    this.drawnFns.push(fn);
  }

  // Asks every SHOWN_POLL_MS whether the fence in flight has passed, while callbacks wait on it.
  pollShown() {
    clearTimeout(this.shownTimer);
    this.shownTimer = setTimeout(() => {
      if (this.fenceFns.length && !this.passed()) this.pollShown();
    }, SHOWN_POLL_MS);
  }

  // True when no fence is in flight or the GPU has passed it (then retired: gpuMs, frameNo, callbacks).
  passed() {
    if (!this.fence) return true;
    const gl = this.gl;
    if (!gl.isContextLost() && gl.getSyncParameter(this.fence, gl.SYNC_STATUS) !== gl.SIGNALED) return false;
    const now = performance.now(), fns = this.fenceFns;
    this.gpuMs = now - this.fenceAt;
    gl.deleteSync(this.fence);
    this.fence = null;
    this.fenceFns = [];
    this.frameNo = (this.frameNo || 0) + 1;
    for (const fn of fns) fn(now);
    return true;
  }

  // True when a viewer may draw in animation frame `tick`.
  idle(tick) {
    if (!this.fence || this.fenceTick === tick) return true;
    return this.passed();
  }

  stats() {
    return {contexts: this.gl ? 1 : 0, users: this.users.size, renderers: this.renderers.size, lost: this.lost,
            software: this.software, gpuMs: this.gpuMs ?? null,
            size: [this.canvas.width, this.canvas.height]};
  }
}

// The page's shared context, created on first use; null without WebGL2.
export function sharedGl() {
  if (!shared) shared = new SharedGl();
  return shared.gl ? shared : null;
}

// Test hook: null until a viewer created the context.
export function sharedStats() {
  return shared ? shared.stats() : {contexts: 0, users: 0, renderers: 0, lost: false, size: [0, 0]};
}
