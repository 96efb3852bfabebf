// conica viewer: the deforming surface of the body, the probes with their force arrows and the
// server's loop statistics, from the bridge's WebSocket (viewer/bridge.py documents the messages).
//
// Frames are conflated twice: the bridge sends a page the newest state, one positions frame at a
// time (the page acknowledges each), and the page keeps only the newest positions message it has
// received and applies it once per drawn frame, so it never lags behind the simulation; with a
// large body it shows fewer frames instead.
//
// URL parameters: ws=URL (default: this host's /ws), up=z|y (default z), force_scale=m per N.
// Profiling switches (docs/viewer.md measures them): pr=device pixels per CSS pixel (default: the
// screen's, at most 2), aa=1 (multisampling), mat=lambert|standard (three.js's per-pixel lit
// materials instead of the per-triangle light below), pdb=1 (preserveDrawingBuffer), wire=0 (no
// triangle edges; w toggles them), grid=0 (no floor grid), hud=0 (no text updates), empty=1 (draw
// nothing but the clear: the ceiling of the canvas itself), nogl=1 (no WebGL canvas: the ceiling
// of the page), sync=1 (one pixel read back after each draw, so renderMs includes the raster).
// window.conica exposes the page's state and window.conica.perf its timings (tests read them).
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';

const params = new URLSearchParams(location.search);
const wsUrl = params.get('ws') || `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/ws`;
const upAxis = params.get('up') === 'y' ? 'y' : 'z';
const POSITIONS = 1, MESH = 2;
const POSITIONS_HEADER = 32;  // bytes before the float32 positions (bridge.py)

const state = {
  status: 'connecting',   // connecting | waiting (bridge up, no server frames) | connected | disconnected
  framesReceived: 0,      // positions messages received
  framesApplied: 0,       // positions applied to the geometry (at most one per displayed frame)
  framesDropped: 0,       // received but replaced by a newer one before being shown
  meshes: 0,
  numNodes: 0,
  numTriangles: 0,
  tick: 0,
  time: 0,
  maxDisplacement: 0,     // m, largest node displacement from rest in the applied frame
  peakDisplacement: 0,    // m, the largest maxDisplacement seen since the mesh arrived
  fps: 0,
  applyMs: 0,             // cost of applying one frame (positions and colours; O(nodes))
  renderMs: 0,            // cost of renderer.render (command submission; with sync=1 the draw too)
  frameAgeMs: 0,          // ms from the bridge receiving the shown frame to the page drawing it
  forceScale: params.has('force_scale') ? Number(params.get('force_scale')) : null,  // m per N
  probes: [],
  stats: null,
  bridge: null,
  webgl: true,
};
window.conica = state;

// ---- scene -------------------------------------------------------------------------------------

const container = document.getElementById('view');
const statusEl = document.getElementById('status');
const statsEl = document.getElementById('stats');
const rangeEl = document.getElementById('range');

const opt = {
  pixelRatio: params.has('pr') ? Number(params.get('pr')) : Math.min(window.devicePixelRatio || 1, 2),
  antialias: params.get('aa') === '1',
  preserve: params.get('pdb') === '1',
  material: params.get('mat') || 'face',
  wire: params.get('wire') !== '0',
  hud: params.get('hud') !== '0',
  empty: params.get('empty') === '1',
  nogl: params.get('nogl') === '1',
  grid: params.get('grid') !== '0',
  sync: params.get('sync') === '1',
};
state.options = opt;

let renderer = null;
try {
  if (opt.nogl) throw new Error('nogl=1');
  renderer = new THREE.WebGLRenderer({ antialias: opt.antialias, preserveDrawingBuffer: opt.preserve,
    powerPreference: 'high-performance' });
  renderer.setPixelRatio(opt.pixelRatio);
  renderer.setSize(window.innerWidth, window.innerHeight);
  renderer.setClearColor(0x14161a);
  container.appendChild(renderer.domElement);
} catch (e) {
  state.webgl = false;
  renderer = null;
  console.error('WebGL unavailable:', e);
}

const scene = new THREE.Scene();
const camera = new THREE.PerspectiveCamera(40, window.innerWidth / window.innerHeight, 1e-4, 100);
if (upAxis === 'z') camera.up.set(0, 0, 1);
camera.position.set(0.1, -0.14, 0.09);
scene.add(camera);
const hemi = new THREE.HemisphereLight(0xffffff, 0x404050, 1.4);
scene.add(hemi);
const headlight = new THREE.DirectionalLight(0xffffff, 1.6);
headlight.position.set(0.3, 0.6, 1);
camera.add(headlight);

const controls = renderer ? new OrbitControls(camera, renderer.domElement) : null;
if (controls) {
  controls.enableDamping = true;
  controls.dampingFactor = 0.15;
}

// The surface is flat shaded and lit by the hemisphere light and the camera's headlight with a
// Lambert (diffuse) model. By default that light is computed per triangle on the CPU (litFaces)
// and drawn with an unlit material: a flat face's Lambert light is one value, so the picture is
// the one three.js's flat-shaded MeshLambertMaterial gives, but ~1,000 triangles are lit instead
// of ~10^5 pixels, which is what software WebGL spends its time on. mat=lambert|standard: the
// per-pixel materials, normals from screen-space derivatives.
const faceLit = !['lambert', 'standard', 'basic'].includes(opt.material);
const surfaceOptions = {
  vertexColors: true, side: THREE.DoubleSide,
  polygonOffset: true, polygonOffsetFactor: 1, polygonOffsetUnits: 1,
};
const material = opt.material === 'standard'
  ? new THREE.MeshStandardMaterial({ ...surfaceOptions, flatShading: true, roughness: 0.65, metalness: 0.0 })
  : opt.material === 'lambert' ? new THREE.MeshLambertMaterial({ ...surfaceOptions, flatShading: true })
    : new THREE.MeshBasicMaterial(surfaceOptions);
// The triangle edges, 18 % black. With per-pixel materials: a wireframe mesh over the surface
// (polygon offset keeps the surface behind it). With litFaces: in the surface's own fragment
// shader, from each fragment's barycentric coordinates (a one-pixel, antialiased line where one
// of them is near 0), applied after the sRGB encoding as the blended overlay would be; this
// saves drawing ~3 lines per triangle, which software WebGL rasterises slowly.
const WIRE_OPACITY = 0.18;
const wireMaterial = new THREE.MeshBasicMaterial({
  color: 0x000000, wireframe: true, transparent: true, opacity: WIRE_OPACITY,
});
const edgeOpacity = { value: opt.wire ? WIRE_OPACITY : 0 };
if (faceLit) {
  // the server's surface triangles are wound outward (right-hand normals), so back faces can
  // be culled: a closed body never shows them, and software WebGL does not shade them
  material.side = THREE.FrontSide;
  material.polygonOffset = false;
  material.onBeforeCompile = (shader) => {
    shader.uniforms.edgeOpacity = edgeOpacity;
    shader.vertexShader = shader.vertexShader
      .replace('#include <common>', '#include <common>\nattribute vec3 bary;\nvarying vec3 vBary;')
      .replace('#include <begin_vertex>', '#include <begin_vertex>\nvBary = bary;');
    shader.fragmentShader = shader.fragmentShader
      .replace('#include <common>', '#include <common>\nuniform float edgeOpacity;\nvarying vec3 vBary;')
      .replace('#include <colorspace_fragment>', `#include <colorspace_fragment>
        vec3 edgeDist = vBary / max(fwidth(vBary), 1e-6);  // pixels to each edge
        float edge = clamp(1.5 - 2.0 * min(min(edgeDist.x, edgeDist.y), edgeDist.z), 0.0, 1.0);
        gl_FragColor.rgb *= 1.0 - edgeOpacity * edge;`);
  };
}
function showWire(on) {
  edgeOpacity.value = on ? WIRE_OPACITY : 0;
  if (wire) wire.visible = on && !faceLit;
}

let geometry = null, surface = null, wire = null, grid = null;
let posAttr = null, colAttr = null, rest = null, meshSize = 0.05;
let faceGeometry = null, facePos = null, faceCol = null, tris = null;  // litFaces: 3 vertices a triangle
let colourRange = 1e-4;  // m, displacement at the red end of the colour bar
let pending = null;      // the newest positions message not yet applied

// a diverging blue-white-red map, t in [0, 1]
const STOPS = [[0.231, 0.298, 0.753], [0.553, 0.690, 0.996], [0.867, 0.867, 0.867],
  [0.957, 0.604, 0.482], [0.706, 0.016, 0.149]];
function colour(t, out, i) {
  const x = Math.min(Math.max(t, 0), 1) * (STOPS.length - 1);
  const k = Math.min(Math.floor(x), STOPS.length - 2), f = x - k;
  const a = STOPS[k], b = STOPS[k + 1];
  out[i] = a[0] + (b[0] - a[0]) * f;
  out[i + 1] = a[1] + (b[1] - a[1]) * f;
  out[i + 2] = a[2] + (b[2] - a[2]) * f;
}

function onMesh(buf) {
  const dv = new DataView(buf);
  const n = dv.getUint32(4, true), t = dv.getUint32(8, true);
  rest = new Float32Array(buf.slice(16, 16 + 12 * n));
  tris = new Uint32Array(buf.slice(16 + 12 * n, 16 + 12 * n + 12 * t));
  if (surface) {
    scene.remove(surface, wire);
    geometry.dispose();
    faceGeometry?.dispose();
  }
  geometry = new THREE.BufferGeometry();
  posAttr = new THREE.BufferAttribute(new Float32Array(rest), 3).setUsage(THREE.DynamicDrawUsage);
  colAttr = new THREE.BufferAttribute(new Float32Array(3 * n), 3).setUsage(THREE.DynamicDrawUsage);
  for (let i = 0; i < n; ++i) colour(0, colAttr.array, 3 * i);
  geometry.setAttribute('position', posAttr);
  geometry.setAttribute('color', colAttr);
  geometry.setIndex(new THREE.BufferAttribute(tris, 1));
  geometry.computeBoundingSphere();
  if (faceLit) {
    faceGeometry = new THREE.BufferGeometry();
    facePos = new THREE.BufferAttribute(new Float32Array(9 * t), 3).setUsage(THREE.DynamicDrawUsage);
    faceCol = new THREE.BufferAttribute(new Float32Array(9 * t), 3).setUsage(THREE.DynamicDrawUsage);
    faceGeometry.setAttribute('position', facePos);
    faceGeometry.setAttribute('color', faceCol);
    const bary = new Float32Array(9 * t);
    for (let i = 0; i < 9 * t; i += 9) bary[i] = bary[i + 4] = bary[i + 8] = 1;
    faceGeometry.setAttribute('bary', new THREE.BufferAttribute(bary, 3));
  }
  surface = new THREE.Mesh(faceLit ? faceGeometry : geometry, material);
  wire = new THREE.Mesh(geometry, wireMaterial);
  surface.frustumCulled = wire.frustumCulled = false;  // the body deforms
  scene.add(surface, wire);
  showWire(opt.wire);
  state.numNodes = n;
  state.numTriangles = t;
  state.meshes += 1;
  state.peakDisplacement = state.maxDisplacement = 0;
  pending = null;
  const first = meshSize === 0.05 && state.meshes === 1;
  meshSize = 2 * geometry.boundingSphere.radius || 0.05;
  if (first) resetView();
  addGrid();
  facesStale = redraw = true;
}

// Per-triangle Lambert light, as three.js's flat-shaded MeshLambertMaterial computes it per pixel
// (lights_lambert_pars_fragment, getHemisphereLightIrradiance): the face normal n turned towards
// the camera, light = (mix(ground, sky, (n.h + 1) / 2) + max(n.l, 0) * headlight) / pi, where h is
// the hemisphere light's direction and l the headlight's (from its world position to its target).
// Each of a face's 3 vertices gets its node's displacement colour times that light. O(triangles).
const hemiDir = new THREE.Vector3(), lightDir = new THREE.Vector3(), camPos = new THREE.Vector3();
let facesStale = true, redraw = true;
function litFaces() {
  const p = posAttr.array, col = colAttr.array, fp = facePos.array, fc = faceCol.array;
  hemiDir.setFromMatrixPosition(hemi.matrixWorld).normalize();
  lightDir.setFromMatrixPosition(headlight.matrixWorld)
    .sub(camPos.setFromMatrixPosition(headlight.target.matrixWorld)).normalize();
  camPos.setFromMatrixPosition(camera.matrixWorld);
  const sky = hemi.color, ground = hemi.groundColor, hi = hemi.intensity / Math.PI;
  const lc = headlight.color, li = headlight.intensity / Math.PI;
  const [hx, hy, hz] = [hemiDir.x, hemiDir.y, hemiDir.z], [lx, ly, lz] = [lightDir.x, lightDir.y, lightDir.z];
  const [cx, cy, cz] = [camPos.x, camPos.y, camPos.z];
  for (let f = 0, o = 0; f < tris.length; f += 3, o += 9) {
    const a = 3 * tris[f], b = 3 * tris[f + 1], c = 3 * tris[f + 2];
    const ux = p[b] - p[a], uy = p[b + 1] - p[a + 1], uz = p[b + 2] - p[a + 2];
    const vx = p[c] - p[a], vy = p[c + 1] - p[a + 1], vz = p[c + 2] - p[a + 2];
    let nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
    const len = Math.hypot(nx, ny, nz);
    const sgn = nx * (cx - p[a]) + ny * (cy - p[a + 1]) + nz * (cz - p[a + 2]) < 0 ? -1 : 1;
    const inv = len > 0 ? sgn / len : 0;
    nx *= inv; ny *= inv; nz *= inv;
    const w = 0.5 * (nx * hx + ny * hy + nz * hz) + 0.5;
    const d = Math.max(nx * lx + ny * ly + nz * lz, 0) * li;
    const r = (ground.r + (sky.r - ground.r) * w) * hi + d * lc.r;
    const g = (ground.g + (sky.g - ground.g) * w) * hi + d * lc.g;
    const bl = (ground.b + (sky.b - ground.b) * w) * hi + d * lc.b;
    for (let k = 0; k < 3; ++k) {
      const i = 3 * tris[f + k], j = o + 3 * k;
      fp[j] = p[i]; fp[j + 1] = p[i + 1]; fp[j + 2] = p[i + 2];
      fc[j] = col[i] * r; fc[j + 1] = col[i + 1] * g; fc[j + 2] = col[i + 2] * bl;
    }
  }
  facePos.needsUpdate = true;
  faceCol.needsUpdate = true;
  facesStale = false;
}

function addGrid() {
  if (grid) scene.remove(grid);
  geometry.computeBoundingBox();
  const box = geometry.boundingBox, c = new THREE.Vector3();
  box.getCenter(c);
  grid = new THREE.GridHelper(meshSize * 2, 20, 0x555a66, 0x2c3038);
  if (upAxis === 'z') {
    grid.rotation.x = Math.PI / 2;
    grid.position.set(c.x, c.y, box.min.z);
  } else {
    grid.position.set(c.x, box.min.y, c.z);
  }
  grid.visible = opt.grid;
  scene.add(grid);
}

function resetView() {
  if (!geometry) return;
  const s = geometry.boundingSphere, r = s.radius || 0.05;
  const dir = upAxis === 'z' ? new THREE.Vector3(0.9, -1.5, 1.0) : new THREE.Vector3(0.9, 1.0, 1.5);
  dir.normalize().multiplyScalar(r * 3.4);
  camera.position.copy(s.center).add(dir);
  camera.near = r / 100;
  camera.far = r * 100;
  camera.updateProjectionMatrix();
  if (controls) {
    controls.target.copy(s.center);
    controls.update();
  }
}
state.resetView = resetView;

function onPositions(buf) {
  state.framesReceived += 1;
  if (pending) state.framesDropped += 1;
  pending = buf;
}

// Applies the newest positions message; returns the bridge's receive time stamp of that frame
// (ms since the epoch) or 0 when there was nothing new.
function applyPending() {
  if (!pending || !posAttr) return 0;
  const buf = pending;
  pending = null;
  const dv = new DataView(buf);
  const n = dv.getUint32(4, true);
  if (n * 3 !== posAttr.array.length) return 0;  // a frame of another scene: wait for its mesh
  const t0 = performance.now();
  state.tick = dv.getFloat64(8, true);
  state.time = dv.getFloat64(16, true);
  const stamp = dv.getFloat64(24, true);
  const p = posAttr.array, col = colAttr.array;
  p.set(new Float32Array(buf, POSITIONS_HEADER, 3 * n));
  let max2 = 0;
  for (let i = 0; i < 3 * n; i += 3) {
    const dx = p[i] - rest[i], dy = p[i + 1] - rest[i + 1], dz = p[i + 2] - rest[i + 2];
    const d2 = dx * dx + dy * dy + dz * dz;
    if (d2 > max2) max2 = d2;
  }
  const maxd = Math.sqrt(max2);
  colourRange = Math.max(maxd, colourRange * 0.995, 1e-4);
  const inv = 1 / colourRange;
  for (let i = 0; i < 3 * n; i += 3) {
    const dx = p[i] - rest[i], dy = p[i + 1] - rest[i + 1], dz = p[i + 2] - rest[i + 2];
    colour(Math.sqrt(dx * dx + dy * dy + dz * dz) * inv, col, i);
  }
  posAttr.needsUpdate = true;
  colAttr.needsUpdate = !faceLit;
  facesStale = redraw = true;
  state.maxDisplacement = maxd;
  state.peakDisplacement = Math.max(state.peakDisplacement, maxd);
  state.framesApplied += 1;
  state.applyMs = performance.now() - t0;
  return stamp;
}

// ---- probes ------------------------------------------------------------------------------------

const probeObjects = new Map();
const probeMaterial = new THREE.MeshStandardMaterial({ color: 0xc8c8c8, roughness: 0.3, metalness: 0.4 });
const contactMaterial = new THREE.MeshStandardMaterial({ color: 0xffb000, roughness: 0.3, metalness: 0.2 });
const sphereGeometry = new THREE.SphereGeometry(1, 24, 16);

let peakForce = 0;  // N, the largest probe force seen
function forceScale() {
  // default: the largest force seen so far draws as 25 % of the body's size (at least 0.05 N)
  return state.forceScale ?? (0.25 * meshSize) / Math.max(peakForce, 0.05);
}

function updateProbes(probes, radius) {
  for (const pr of probes) {
    let o = probeObjects.get(pr.id);
    if (!o) {
      const sphere = new THREE.Mesh(sphereGeometry, probeMaterial);
      const arrow = new THREE.ArrowHelper(new THREE.Vector3(0, 0, 1), new THREE.Vector3(), 1, 0x33ddff);
      scene.add(sphere, arrow);
      o = { sphere, arrow };
      probeObjects.set(pr.id, o);
    }
    const [x, y, z] = pr.position, [fx, fy, fz] = pr.force;
    // a probe no client has moved yet sits at the origin: hide it until it is driven
    o.driven ||= x !== 0 || y !== 0 || z !== 0 || pr.contact;
    o.sphere.visible = o.driven;
    if (!o.driven) { o.arrow.visible = false; continue; }
    o.sphere.position.set(x, y, z);
    o.sphere.scale.setScalar(radius);
    o.sphere.material = pr.contact ? contactMaterial : probeMaterial;
    const f = Math.hypot(fx, fy, fz);
    peakForce = Math.max(peakForce, f);
    const len = f * forceScale();
    if (len > radius * 0.05) {
      o.arrow.visible = true;
      o.arrow.position.set(x, y, z);
      o.arrow.setDirection(new THREE.Vector3(fx / f, fy / f, fz / f));
      o.arrow.setLength(len, Math.min(len * 0.3, radius * 1.2), Math.min(len * 0.2, radius * 0.8));
    } else {
      o.arrow.visible = false;
    }
  }
}

// ---- heads-up display --------------------------------------------------------------------------

function setStatus(s) {
  if (state.status === s) return;
  state.status = s;
  statusEl.textContent = s;
  statusEl.className = s;
}

const fmt = (v, d = 1) => (v === undefined || v === null ? '-' : Number(v).toFixed(d));
let hudTime = 0;
function updateHud(now) {
  if (now - hudTime < 100) return;  // 10 Hz is plenty for text
  hudTime = now;
  const s = state.stats;
  const lines = [
    `tick ${state.tick}   t ${fmt(state.time, 3)} s`,
    `nodes ${state.numNodes}   triangles ${state.numTriangles}`,
    `frames ${state.framesReceived}  shown ${state.framesApplied}  dropped ${state.framesDropped}`,
    `display ${fmt(state.fps, 0)} fps   apply ${fmt(state.applyMs, 2)} ms   `
      + `render() ${fmt(state.renderMs, 1)} ms`,
    `frame age ${fmt(state.frameAgeMs, 0)} ms`,
    `max displacement ${fmt(state.maxDisplacement * 1e3, 3)} mm`,
  ];
  if (s) {
    lines.push(
      `loop ${fmt(s.rate_hz, 0)} Hz${s.paused ? ' (paused)' : ''}`,
      `lateness p50 ${fmt(s.lateness_p50_us)} us  p99 ${fmt(s.lateness_p99_us)} us`,
      `step p50 ${fmt(s.step_p50_us)} us  p99 ${fmt(s.step_p99_us)} us`,
      `missed ticks ${s.missed_ticks}   rollbacks ${s.rollbacks}`,
    );
  }
  for (const p of state.probes) {
    const [fx, fy, fz] = p.force;
    lines.push(`probe ${p.id}${p.contact ? ' contact' : ''}  |F| ${fmt(Math.hypot(fx, fy, fz), 3)} N`);
  }
  lines.push(`arrows: 0.1 N = ${fmt(forceScale() * 1e2, 1)} mm`);
  if (!state.webgl) lines.push('WebGL unavailable: no drawing');
  statsEl.textContent = lines.join('\n');
  rangeEl.textContent = `0 - ${fmt(colourRange * 1e3, 2)} mm`;
}

// ---- connection --------------------------------------------------------------------------------

let retryMs = 250;
function connect() {
  const ws = new WebSocket(wsUrl);
  ws.binaryType = 'arraybuffer';
  ws.onopen = () => { retryMs = 250; setStatus('waiting'); };
  ws.onmessage = (ev) => {
    if (typeof ev.data === 'string') {
      // state texts are conflated like positions: only the newest is parsed, once per frame
      if (ev.data.startsWith('{"type": "state"')) {
        pendingInfo = ev.data;
        setStatus('connected');
        return;
      }
      const m = JSON.parse(ev.data);
      if (m.type === 'status') setStatus(m.server === 'connected' ? 'connected' : 'waiting');
      return;
    }
    const kind = new DataView(ev.data).getUint32(0, true);
    if (kind === POSITIONS) {
      onPositions(ev.data);
      ws.send('ack');  // the bridge sends the next frame only now: nothing queues on the way
    }
    else if (kind === MESH) onMesh(ev.data);
  };
  ws.onclose = () => {
    setStatus('disconnected');
    setTimeout(connect, retryMs);
    retryMs = Math.min(retryMs * 2, 4000);
  };
}

let pendingInfo = null;  // the newest state text not yet parsed
function applyInfo() {
  if (!pendingInfo) return;
  const m = JSON.parse(pendingInfo);
  pendingInfo = null;
  state.stats = m.stats;
  state.bridge = m.bridge;
  state.probes = m.probes;
  updateProbes(m.probes, m.bridge.probe_radius);
  redraw = true;
}

// ---- frame loop --------------------------------------------------------------------------------

// Timings of the drawn frames for window.conica.perf: a window of the last PERF_N frames.
const PERF_N = 1024;
const perf = {
  interval: new Float64Array(PERF_N),  // ms since the previous drawn frame
  apply: new Float64Array(PERF_N),     // ms applying state, positions and light (NaN: no new frame)
  render: new Float64Array(PERF_N),    // ms in renderer.render (+ gl.finish with sync=1)
  age: new Float64Array(PERF_N),       // ms from the bridge's receipt to drawn (NaN: no new frame)
  count: 0,
  start: { t: performance.now(), received: 0, applied: 0, dropped: 0, published: 0 },
};
function quantiles(arr, n) {
  const v = Array.from(arr.subarray(0, n)).filter((x) => !Number.isNaN(x)).sort((a, b) => a - b);
  const q = (f) => (v.length ? v[Math.min(v.length - 1, Math.floor(f * v.length))] : NaN);
  return { n: v.length, p50: q(0.5), p95: q(0.95), max: v.length ? v[v.length - 1] : NaN };
}
state.perf = {
  reset() {
    perf.count = 0;
    perf.start = { t: performance.now(), received: state.framesReceived, applied: state.framesApplied,
      dropped: state.framesDropped, published: state.bridge?.frames_in ?? 0 };
  },
  // drawn frames, state frames the bridge got from the server, positions frames received / shown /
  // dropped here per second, and timing quantiles since reset()
  summary() {
    const n = Math.min(perf.count, PERF_N), s = (performance.now() - perf.start.t) / 1000;
    return {
      seconds: s, displayFps: perf.count / s,
      publishedPerS: ((state.bridge?.frames_in ?? 0) - perf.start.published) / s,
      receivedPerS: (state.framesReceived - perf.start.received) / s,
      shownPerS: (state.framesApplied - perf.start.applied) / s,
      droppedPerS: (state.framesDropped - perf.start.dropped) / s,
      intervalMs: quantiles(perf.interval, n), applyMs: quantiles(perf.apply, n),
      renderMs: quantiles(perf.render, n), ageMs: quantiles(perf.age, n),
    };
  },
};

// The cost of drawing the current scene, ms: median of n draws each waited for by reading one
// pixel back (gl.finish does not wait in Chromium). Profiling only: it blocks the page.
state.perf.drawCost = (n = 20) => {
  if (!renderer) return NaN;
  const ctx = renderer.getContext(), px = new Uint8Array(4), t = [];
  for (let i = 0; i < n; ++i) {
    const t0 = performance.now();
    if (opt.empty) renderer.clear();
    else renderer.render(scene, camera);
    ctx.readPixels(0, 0, 1, 1, ctx.RGBA, ctx.UNSIGNED_BYTE, px);
    t.push(performance.now() - t0);
  }
  return t.sort((a, b) => a - b)[n >> 1];
};

// drawCost(n) of the scene with each of its visible objects alone, and with none (the clear).
state.perf.drawCostByObject = (n = 15) => {
  const kids = scene.children, vis = kids.map((c) => c.visible), out = {};
  const name = (c) => (c === surface ? 'surface' : c === wire ? 'wireframe' : c === grid ? 'grid' : c.type);
  kids.forEach((c) => { c.visible = false; });
  out.none = state.perf.drawCost(n);
  kids.forEach((c, i) => {
    if (!vis[i] || c.isCamera || c.isLight) return;
    c.visible = true;
    out[name(c)] = state.perf.drawCost(n);
    c.visible = false;
  });
  kids.forEach((c, i) => { c.visible = vis[i]; });
  out.all = state.perf.drawCost(n);
  return out;
};

const wallNow = () => performance.timeOrigin + performance.now();  // ms since the epoch
const lastView = new Float64Array(16);
let gl = null;
const pixel = new Uint8Array(4);
let fpsFrames = 0, fpsStart = performance.now(), lastDrawn = performance.now();
// One display frame: the newest state and positions are applied, and the scene is drawn if
// anything changed (a new frame, the probes, the view); an unchanged picture is not drawn again.
function frame(now) {
  requestAnimationFrame(frame);
  const tStart = performance.now();
  applyInfo();
  const stamp = opt.empty ? 0 : applyPending();
  if (opt.empty) pending = null;
  if (controls) controls.update();
  scene.updateMatrixWorld();
  const view = camera.matrixWorld.elements;
  if (view.some((v, i) => v !== lastView[i])) {
    lastView.set(view);
    facesStale = redraw = true;
  }
  if (faceLit && facesStale && posAttr) litFaces();
  const tApplied = performance.now();
  if (!renderer) {  // nogl (or no WebGL): nothing to draw, count the display frames
    const k = perf.count % PERF_N;
    perf.interval[k] = now - lastDrawn;
    perf.apply[k] = perf.render[k] = perf.age[k] = NaN;
    perf.count += 1;
    lastDrawn = now;
    ++fpsFrames;
  }
  if (renderer && (redraw || opt.empty)) {
    if (opt.empty) renderer.clear();
    else renderer.render(scene, camera);
    if (opt.sync) (gl ??= renderer.getContext()).readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, pixel);
    redraw = false;
    const tDrawn = performance.now();
    const k = perf.count % PERF_N;
    perf.interval[k] = now - lastDrawn;
    perf.apply[k] = stamp ? tApplied - tStart : NaN;
    perf.render[k] = tDrawn - tApplied;
    perf.age[k] = stamp ? wallNow() - stamp : NaN;
    perf.count += 1;
    lastDrawn = now;
    state.renderMs = tDrawn - tApplied;
    if (stamp) state.frameAgeMs = perf.age[k];
    ++fpsFrames;
  }
  if (now - fpsStart >= 1000) {
    state.fps = (fpsFrames * 1000) / (now - fpsStart);
    fpsFrames = 0;
    fpsStart = now;
  }
  if (opt.hud) updateHud(now);
}

window.addEventListener('resize', () => {
  camera.aspect = window.innerWidth / window.innerHeight;
  camera.updateProjectionMatrix();
  if (renderer) renderer.setSize(window.innerWidth, window.innerHeight);
  redraw = true;
});
window.addEventListener('keydown', (e) => {
  if (e.key === '+' || e.key === '=') state.forceScale = forceScale() * 1.5;
  else if (e.key === '-') state.forceScale = forceScale() / 1.5;
  else if (e.key === 'w') showWire(edgeOpacity.value === 0);
  else if (e.key === 'r') resetView();
  redraw = true;
});

connect();
requestAnimationFrame(frame);
