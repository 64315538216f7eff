// orbit.js - orbit camera control from pointer events: one pointer (mouse button
// or one finger) drags the azimuth/elevation, two fingers pinch to zoom, the wheel
// zooms, the keyboard orbits (arrows) and zooms (+/-); one finger turns only the azimuth. onChange() is called after every
// change. attach(true) turns the controls on (the element should then have CSS
// `touch-action: pan-y` so vertical swipes still scroll the page); without controls
// only the pointer position is reported (light follows pointer) and nothing is prevented.
// canWheel(): whether a wheel event may zoom (the page scrolls otherwise).

export class Orbit {
  constructor(el, {az = 0, el: elev = 25, dist = 3.2, minDist = 1.6, maxDist = 8, onChange = () => {},
                   onPointer = null, canWheel = () => true} = {}) {
    this.az = az;
    this.el = elev;
    this.dist = dist;
    this.minDist = minDist;
    this.maxDist = maxDist;
    this.onChange = onChange;
    this.onPointer = onPointer; // (x, y) in 0..1 over the element, for light-follows-pointer
    this.canWheel = canWheel;
    this.target = el;
    this.pointers = new Map(); // id -> {x, y}
    this.pinch = 0;
    this.drags = 0;            // completed drag gestures (test hook)
    this.controls = false;
    this.handlers = {
      pointerdown: (e) => this.down(e), pointerup: (e) => this.up(e), pointercancel: (e) => this.up(e),
      wheel: (e) => this.wheel(e),
    };
    this.onMove = (e) => this.move(e);
    el.addEventListener('pointermove', this.onMove, {passive: true});
  }

  // Turns the orbit/zoom controls on or off.
  attach(on) {
    if (on === this.controls) return;
    this.controls = on;
    for (const [k, f] of Object.entries(this.handlers)) {
      if (on) this.target.addEventListener(k, f, {passive: k !== 'wheel'});
      else this.target.removeEventListener(k, f);
    }
    if (!on) this.pointers.clear();
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
      // one finger: vertical swipes belong to the page (touch-action: pan-y), so only azimuth
      this.rotate((-dx / h) * 180, e.pointerType === 'touch' ? 0 : (dy / h) * 180);
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
    if (!this.canWheel(e)) return;
    e.preventDefault();
    this.zoom(Math.exp(e.deltaY * 0.001));
  }

  // Arrow keys orbit by 5 degrees, + and - zoom; true when the key was used.
  key(e) {
    const step = {ArrowLeft: [5, 0], ArrowRight: [-5, 0], ArrowUp: [0, 5], ArrowDown: [0, -5]}[e.key];
    if (step) this.rotate(step[0], step[1]);
    else if (e.key === '+' || e.key === '=') this.zoom(1 / 1.1);
    else if (e.key === '-') this.zoom(1.1);
    else return false;
    return true;
  }

  rotate(dAz, dEl) {
    this.az += dAz;
    this.el = Math.max(-85, Math.min(85, this.el + dEl));
    this.onChange();
  }

  zoom(f) {
    this.dist = Math.max(this.minDist, Math.min(this.maxDist, this.dist * f));
    this.onChange();
  }

  dispose() {
    this.attach(false);
    this.target.removeEventListener('pointermove', this.onMove);
  }
}
