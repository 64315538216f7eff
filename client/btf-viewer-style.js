// btf-viewer-style.js - the shadow-DOM style of <btf-viewer>, inside the script: the
// element has its size and its placeholder from the moment it is defined (no
// stylesheet request for the page to wait on, so nothing below it shifts later).

export const VIEWER_CSS = `
:host {
  display: inline-block;
  position: relative;
  width: 320px;
  height: 320px;
  background: #222224;
  overflow: hidden;
  contain: content;
  font: 12px/1.3 system-ui, sans-serif;
  color: #ddd;
}
canvas {
  display: block;
  width: 100%;
  height: 100%;
}
/* camera-controls: horizontal drags and pinches orbit and zoom, vertical swipes still scroll */
:host([camera-controls]) canvas { touch-action: pan-y; cursor: grab; }
:host([camera-controls]) canvas:active { cursor: grabbing; }
:host(:focus-visible) { outline: 2px solid #4da3ff; outline-offset: -2px; }
.poster {
  position: absolute;
  inset: 0;
  width: 100%;
  height: 100%;
  object-fit: cover;
  pointer-events: none;
}
.poster[hidden] { display: none; }
.bar {
  position: absolute;
  left: 0;
  bottom: 0;
  height: 3px;
  width: 0;
  background: #4da3ff;
  transition: width 0.2s;
}
.bar.done { background: #5fc46a; }
.label {
  position: absolute;
  left: 6px;
  bottom: 6px;
  padding: 1px 5px;
  border-radius: 3px;
  background: rgba(0, 0, 0, 0.55);
  pointer-events: none;
  white-space: nowrap;
  max-width: calc(100% - 12px);
  overflow: hidden;
  text-overflow: ellipsis;
}
.label:empty { display: none; }
/* the placeholder until the first frame: the box at its size with a slow sweep */
.wait {
  position: absolute;
  inset: 0;
  background: linear-gradient(100deg, transparent 30%, rgba(255, 255, 255, 0.06) 50%, transparent 70%) #222224;
  background-size: 300% 100%;
  animation: btf-sweep 1.6s linear infinite;
  pointer-events: none;
}
.wait[hidden] { display: none; }
@keyframes btf-sweep { from { background-position: 100% 0; } to { background-position: -200% 0; } }
@media (prefers-reduced-motion: reduce) { .wait { animation: none !important; } }
.msg.soft {
  inset: auto 0 0 0;
  padding: 6px 10px 10px;
  background: rgba(20, 20, 24, 0.8);
  color: #ddd;
}
.msg {
  position: absolute;
  inset: 0;
  display: flex;
  align-items: center;
  justify-content: center;
  padding: 12px;
  text-align: center;
  background: rgba(30, 10, 10, 0.85);
  color: #ffb4a8;
}
.msg[hidden] { display: none; }
`;

let sheet = null;

// The shared constructed stylesheet (adoptedStyleSheets), or null where the browser
// has none (the caller falls back to a <style> element).
export function viewerSheet() {
  if (sheet === null && typeof CSSStyleSheet !== 'undefined' && 'replaceSync' in CSSStyleSheet.prototype) {
    sheet = new CSSStyleSheet();
    sheet.replaceSync(VIEWER_CSS);
  }
  return sheet;
}
