// orbit.js - orbit camera control from pointer events: one pointer (mouse button
// or one finger) drags the azimuth/elevation, two fingers pinch to zoom, the wheel
// zooms. onChange() is called after every change. The element needs the CSS
// `touch-action: none` so the browser does not scroll instead.

export class Orbit {
  constructor(el, {az = 0, el: elev = 25, dist = 3.2, minDist = 1.6, maxDist = 8, onChange = () => {},
                   onPointer = null} = {}) {
    this.az = az;
    this.el = elev;
    this.dist = dist;
    this.minDist = minDist;
    this.maxDist = maxDist;
    this.onChange = onChange;
    this.onPointer = onPointer; // (x, y) in 0..1 over the element, for light-follows-pointer
    this.target = el;
    this.pointers = new Map(); // id -> {x, y}
    this.pinch = 0;
    this.drags = 0;            // completed drag gestures (test hook)
    this.handlers = {
      pointerdown: (e) => this.down(e), pointermove: (e) => this.move(e), pointerup: (e) => this.up(e),
      pointercancel: (e) => this.up(e), wheel: (e) => this.wheel(e),
    };
    for (const [k, f] of Object.entries(this.handlers)) el.addEventListener(k, f, {passive: k !== 'wheel'});
  }

  down(e) {
    this.pointers.set(e.pointerId, {x: e.clientX, y: e.clientY, moved: 0});
    try { this.target.setPointerCapture(e.pointerId); } catch (_) { /* synthetic pointer */ }
    if (this.pointers.size === 2) this.pinch = this.spread();
  }

  spread() {
    const [a, b] = [...this.pointers.values()];
    return Math.hypot(a.x - b.x, a.y - b.y);
  }

  move(e) {
    if (this.onPointer) {
      const r = this.target.getBoundingClientRect();
      if (r.width && r.height) this.onPointer((e.clientX - r.left) / r.width, (e.clientY - r.top) / r.height);
    }
    const p = this.pointers.get(e.pointerId);
    if (!p) return;
    const dx = e.clientX - p.x, dy = e.clientY - p.y;
    p.x = e.clientX;
    p.y = e.clientY;
    p.moved += Math.abs(dx) + Math.abs(dy);
    if (this.pointers.size === 1) {
      const h = this.target.clientHeight || 300;
      this.az -= (dx / h) * 180;
      this.el = Math.max(-85, Math.min(85, this.el + (dy / h) * 180));
      this.onChange();
    } else if (this.pointers.size === 2) {
      const s = this.spread();
      if (this.pinch > 0 && s > 0) this.zoom(this.pinch / s);
      this.pinch = s;
    }
  }

  up(e) {
    const p = this.pointers.get(e.pointerId);
    if (p && p.moved > 2) this.drags++;
    this.pointers.delete(e.pointerId);
    this.pinch = this.pointers.size === 2 ? this.spread() : 0;
  }

  wheel(e) {
    e.preventDefault();
    this.zoom(Math.exp(e.deltaY * 0.001));
  }

  zoom(f) {
    this.dist = Math.max(this.minDist, Math.min(this.maxDist, this.dist * f));
    this.onChange();
  }

  dispose() {
    for (const [k, f] of Object.entries(this.handlers)) this.target.removeEventListener(k, f);
  }
}
