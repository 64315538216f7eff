/* btf-viewer.css - shadow-DOM style of <btf-viewer> (loaded by btf-viewer.js). */
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
