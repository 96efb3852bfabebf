// conica viewer: the deforming surface of the body, the probes with their force arrows and the
// server's loop statistics, from the bridge's WebSocket (viewer/bridge.py documents the messages).
//
// Frames are conflated twice: the bridge sends only the newest state, and the page keeps only the
// newest positions message it has received and applies it once per displayed frame, so it never
// lags behind the simulation; with a large body it shows fewer frames instead.
//
// URL parameters: ws=URL (default: this host's /ws), up=z|y (default z), force_scale=m per N.
// window.conica exposes the page's state (tests read it).
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';

const params = new URLSearchParams(location.search);
const wsUrl = params.get('ws') || `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/ws`;
const upAxis = params.get('up') === 'y' ? 'y' : 'z';
const POSITIONS = 1, MESH = 2;

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

let renderer = null;
try {
  renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(Math.min(window.devicePixelRatio, 2));
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
scene.add(new THREE.HemisphereLight(0xffffff, 0x404050, 1.4));
const headlight = new THREE.DirectionalLight(0xffffff, 1.6);
headlight.position.set(0.3, 0.6, 1);
camera.add(headlight);

const controls = renderer ? new OrbitControls(camera, renderer.domElement) : null;
if (controls) {
  controls.enableDamping = true;
  controls.dampingFactor = 0.15;
}

const material = new THREE.MeshStandardMaterial({
  // flat shading: normals come from screen-space derivatives, so a frame costs no normal pass
  vertexColors: true, flatShading: true, side: THREE.DoubleSide, roughness: 0.65, metalness: 0.0,
  polygonOffset: true, polygonOffsetFactor: 1, polygonOffsetUnits: 1,
});
const wireMaterial = new THREE.MeshBasicMaterial({
  color: 0x000000, wireframe: true, transparent: true, opacity: 0.18,
});

let geometry = null, surface = null, wire = null, grid = null;
let posAttr = null, colAttr = null, rest = null, meshSize = 0.05;
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
  const tris = new Uint32Array(buf.slice(16 + 12 * n, 16 + 12 * n + 12 * t));
  if (surface) {
    scene.remove(surface, wire);
    geometry.dispose();
  }
  geometry = new THREE.BufferGeometry();
  posAttr = new THREE.BufferAttribute(new Float32Array(rest), 3).setUsage(THREE.DynamicDrawUsage);
  colAttr = new THREE.BufferAttribute(new Float32Array(3 * n), 3).setUsage(THREE.DynamicDrawUsage);
  for (let i = 0; i < n; ++i) colour(0, colAttr.array, 3 * i);
  geometry.setAttribute('position', posAttr);
  geometry.setAttribute('color', colAttr);
  geometry.setIndex(new THREE.BufferAttribute(tris, 1));
  geometry.computeBoundingSphere();
  surface = new THREE.Mesh(geometry, material);
  wire = new THREE.Mesh(geometry, wireMaterial);
  surface.frustumCulled = wire.frustumCulled = false;  // the body deforms
  scene.add(surface, wire);
  state.numNodes = n;
  state.numTriangles = t;
  state.meshes += 1;
  state.peakDisplacement = state.maxDisplacement = 0;
  pending = null;
  const first = meshSize === 0.05 && state.meshes === 1;
  meshSize = 2 * geometry.boundingSphere.radius || 0.05;
  if (first) resetView();
  addGrid();
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

function applyPending() {
  if (!pending || !posAttr) return;
  const buf = pending;
  pending = null;
  const dv = new DataView(buf);
  const n = dv.getUint32(4, true);
  if (n * 3 !== posAttr.array.length) return;  // a frame of another scene: wait for its mesh
  const t0 = performance.now();
  state.tick = dv.getFloat64(8, true);
  state.time = dv.getFloat64(16, true);
  const p = posAttr.array, col = colAttr.array;
  p.set(new Float32Array(buf, 24, 3 * n));
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
  colAttr.needsUpdate = true;
  state.maxDisplacement = maxd;
  state.peakDisplacement = Math.max(state.peakDisplacement, maxd);
  state.framesApplied += 1;
  state.applyMs = performance.now() - t0;
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
    `display ${fmt(state.fps, 0)} fps   apply ${fmt(state.applyMs, 2)} ms`,
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
      const m = JSON.parse(ev.data);
      if (m.type === 'status') {
        setStatus(m.server === 'connected' ? 'connected' : 'waiting');
      } else if (m.type === 'state') {
        setStatus('connected');
        state.stats = m.stats;
        state.bridge = m.bridge;
        state.probes = m.probes;
        updateProbes(m.probes, m.bridge.probe_radius);
      }
      return;
    }
    const kind = new DataView(ev.data).getUint32(0, true);
    if (kind === POSITIONS) onPositions(ev.data);
    else if (kind === MESH) onMesh(ev.data);
  };
  ws.onclose = () => {
    setStatus('disconnected');
    setTimeout(connect, retryMs);
    retryMs = Math.min(retryMs * 2, 4000);
  };
}

// ---- frame loop --------------------------------------------------------------------------------

let fpsFrames = 0, fpsStart = performance.now();
function frame(now) {
  applyPending();
  if (controls) controls.update();
  if (renderer) renderer.render(scene, camera);
  ++fpsFrames;
  if (now - fpsStart >= 1000) {
    state.fps = (fpsFrames * 1000) / (now - fpsStart);
    fpsFrames = 0;
    fpsStart = now;
  }
  updateHud(now);
  requestAnimationFrame(frame);
}

window.addEventListener('resize', () => {
  camera.aspect = window.innerWidth / window.innerHeight;
  camera.updateProjectionMatrix();
  if (renderer) renderer.setSize(window.innerWidth, window.innerHeight);
});
window.addEventListener('keydown', (e) => {
  if (e.key === '+' || e.key === '=') state.forceScale = forceScale() * 1.5;
  else if (e.key === '-') state.forceScale = forceScale() / 1.5;
  else if (e.key === 'w' && wire) wire.visible = !wire.visible;
  else if (e.key === 'r') resetView();
});

connect();
requestAnimationFrame(frame);
