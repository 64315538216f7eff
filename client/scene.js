// scene.js - camera, light and surfaces of the viewer: a port of the scene
// conventions of `btf render` (shaders/host/btf_render.c, shaders/README.md), so the
// browser and the headless C harness draw the same picture from the same numbers.
//
// World: right-handed, +z up, angles in degrees; a direction (theta, phi) is
// (sin t cos p, sin t sin p, cos t). Camera at target + dist * dir(theta, phi) looking
// at the target (the origin, or a model's centre), up = -d(dir)/d(theta); the field of
// view `fov` spans the narrower side of the view (vertical when width >= height,
// horizontal when taller than wide, so the object stays framed in portrait); near
// 0.05 * dist, far dist + 2 * extent (the built-in objects: extent 2, far dist + 4).
//   plane    [-1,1]^2 at z = 0, normal +z, uv = ((x+1)/2, (1-y)/2)
//   sphere   radius 1, longitude from +x towards +y, u = (lon - 90)/360, v = colatitude/180
//   cylinder along x (length 2), radius 2/pi, u = (x+1)/2, v = 0.5 + angle/360 from the top line
// uv is scaled by the geometry's base repeats (1x1, 2x1, 1x2) times `repeat`.
// No DOM, no GL: usable in node.

export const GEOMETRIES = ['plane', 'sphere', 'cylinder'];
const BASE_REPEAT = {plane: [1, 1], sphere: [2, 1], cylinder: [1, 2]};

// Defaults of btf_render_defaults() per geometry: each object inside the view in any
// aspect; the light 28 to 35 degrees off the camera, up and to the right, so the lit
// side faces the camera (sphere: 97% of its visible pixels lit) and relief shows.
export function sceneDefaults(geometry) {
  return {cameraTheta: geometry === 'plane' ? 30 : geometry === 'sphere' ? 60 : 50, cameraPhi: -90,
    cameraDist: geometry === 'plane' ? 3.5 : 3.6, lightTheta: 45, lightPhi: -50, fov: 40, repeat: 1,
    background: [0.12, 0.12, 0.12]};
}

// tan(half the vertical field of view) of a view width / height = aspect: fov spans
// the narrower side (btf_render_camera_make).
function tanHalfFovY(fov, aspect) {
  return Math.tan(fov * Math.PI / 360) / Math.min(aspect, 1);
}

// Device pixels per world unit at the origin's distance (the object's scale on
// screen) in a width x height view of {cameraDist, fov}: min(width, height) /
// (2 dist tan(fov/2)). Twin of btf_render_pixels_per_unit.
export function pixelsPerUnit(s, width, height) {
  return Math.min(width, height) / (2 * s.cameraDist * Math.tan(s.fov * Math.PI / 360));
}

export function dir(thetaDeg, phiDeg) {
  const t = thetaDeg * Math.PI / 180, p = phiDeg * Math.PI / 180;
  return [Math.sin(t) * Math.cos(p), Math.sin(t) * Math.sin(p), Math.cos(t)];
}

const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];

// Port of btf_render_camera_make: {viewProj (column-major Float32Array), eye, light,
// uvScale, wrap} for {geometry, cameraTheta, cameraPhi, cameraDist, lightTheta,
// lightPhi, fov, repeat, target (default the origin), extent (default 2)} and the
// aspect width / height.
export function cameraMake(s, aspect) {
  const t = s.cameraTheta * Math.PI / 180, ph = s.cameraPhi * Math.PI / 180, d = s.cameraDist;
  const dv = dir(s.cameraTheta, s.cameraPhi), target = s.target || [0, 0, 0];
  const up0 = [-Math.cos(t) * Math.cos(ph), -Math.cos(t) * Math.sin(ph), Math.sin(t)];
  const eye = dv.map((c, i) => target[i] + d * c), fwd = dv.map((c) => -c);
  let right = cross(fwd, up0);
  const n = Math.hypot(...right);
  right = right.map((c) => c / n);
  const up = cross(right, fwd);
  const view = [right[0], up[0], -fwd[0], 0, right[1], up[1], -fwd[1], 0, right[2], up[2], -fwd[2], 0,
    -dot(right, eye), -dot(up, eye), dot(fwd, eye), 1];
  const th = tanHalfFovY(s.fov, aspect), zn = 0.05 * d, zf = d + 2 * (s.extent > 0 ? s.extent : 2);
  const proj = [1 / (th * aspect), 0, 0, 0, 0, 1 / th, 0, 0, 0, 0, -(zf + zn) / (zf - zn), -1, 0, 0,
    (-2 * zf * zn) / (zf - zn), 0];
  const vp = new Float32Array(16);
  for (let col = 0; col < 4; col++)
    for (let row = 0; row < 4; row++) {
      let sum = 0;
      for (let k = 0; k < 4; k++) sum += proj[k * 4 + row] * view[col * 4 + k];
      vp[col * 4 + row] = sum;
    }
  const base = BASE_REPEAT[s.geometry] || BASE_REPEAT.plane;
  return {viewProj: vp, eye: new Float32Array(eye), light: new Float32Array(dir(s.lightTheta, s.lightPhi)),
    uvScale: [base[0] * s.repeat, base[1] * s.repeat], wrap: s.geometry !== 'plane' || s.repeat !== 1 ? 1 : 0};
}

// An orbiting light that keeps its angle to the camera: the light of s turned by
// angleDeg about the camera direction (counter-clockwise as the camera sees it).
// Returns {lightTheta, lightPhi}. An orbit about +z instead swings the default light
// behind a sphere, darkening about two thirds of what the camera sees. Browser only
// (btf render draws one fixed light).
export function orbitLight(s, angleDeg) {
  const k = dir(s.cameraTheta, s.cameraPhi), l = dir(s.lightTheta, s.lightPhi);
  const a = angleDeg * Math.PI / 180, c = Math.cos(a), sn = Math.sin(a), kl = cross(k, l), kd = dot(k, l);
  const v = [0, 1, 2].map((i) => l[i] * c + kl[i] * sn + k[i] * kd * (1 - c));
  const z = Math.max(-1, Math.min(1, v[2] / Math.hypot(...v)));
  return {lightTheta: Math.acos(z) * 180 / Math.PI, lightPhi: Math.atan2(v[1], v[0]) * 180 / Math.PI};
}

// Port of btf_render_mesh_create: interleaved position 3, normal 3, tangent 4, uv 2
// per vertex (attribute locations 0..3 of btf_render.vert) and triangle indices.
export function buildMesh(geometry, segments = 64) {
  const nu = geometry === 'sphere' ? segments : 1;
  let nv = geometry === 'plane' ? 1 : geometry === 'sphere' ? Math.floor(segments / 2) : segments;
  if (nv < 2 && geometry !== 'plane') nv = 2;
  const v = new Float32Array((nu + 1) * (nv + 1) * 12);
  for (let j = 0; j <= nv; j++)
    for (let i = 0; i <= nu; i++) v.set(gridVertex(geometry, i / nu, j / nv), (j * (nu + 1) + i) * 12);
  const idx = new Uint32Array(nu * nv * 6);
  let k = 0;
  for (let j = 0; j < nv; j++)
    for (let i = 0; i < nu; i++) {
      const a = j * (nu + 1) + i, b = a + 1, c = a + nu + 1, d = c + 1;
      idx.set([a, c, b, b, c, d], k);
      k += 6;
    }
  return {vertices: v, indices: idx};
}

function gridVertex(g, s, t) {
  let pos, n, tan = [1, 0, 0, 1];
  if (g === 'sphere') {
    const lon = 2 * Math.PI * s + Math.PI / 2, colat = Math.PI * t;
    n = [Math.sin(colat) * Math.cos(lon), Math.sin(colat) * Math.sin(lon), Math.cos(colat)];
    pos = n;
    tan = [-Math.sin(lon), Math.cos(lon), 0, 1];
  } else if (g === 'cylinder') {
    const r = 2 / Math.PI, a = 2 * Math.PI * (t - 0.5);
    n = [0, -Math.sin(a), Math.cos(a)];
    pos = [2 * s - 1, r * n[1], r * n[2]];
  } else {
    pos = [2 * s - 1, 1 - 2 * t, 0];
    n = [0, 0, 1];
  }
  return [...pos, ...n, ...tan, s, t];
}
