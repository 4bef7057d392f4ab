// The page of `incise view` (docs/view.md): draws the boundary the server streams and sends the
// mouse's blade and probe (live), or the frame picked on the time slider (look mode: the server
// says which in each frame's figures, `mode`). It simulates nothing: every figure comes from the
// server.
import * as THREE from 'three';
import { OrbitControls } from './OrbitControls.js';

// ---- wire format (view/wire_format.h) ---------------------------------------------------
const Kind = { BladeStart: 1, BladeMove: 2, BladeEnd: 3, ProbeGrab: 4, ProbeMove: 5, ProbeRelease: 6,
               Pause: 7, Resume: 8, Step: 9, Reset: 10, Colour: 11, Ack: 12, Frame: 13, Record: 14, Clip: 15 };
const TRI_CUT = 1, TRI_FIXED = 2, TRI_WORST = 4, TRI_LOADED = 8;

function encodeInput(kind, floats = [], value = null) {
  const buf = new ArrayBuffer(1 + 4 * floats.length + (value === null ? 0 : 4));
  const dv = new DataView(buf);
  dv.setUint8(0, kind);
  floats.forEach((x, i) => dv.setFloat32(1 + 4 * i, x, true));
  if (value !== null) dv.setUint32(1 + 4 * floats.length, value, true);
  return buf;
}

function decodeFrame(buf) {
  const dv = new DataView(buf);
  let at = 0;
  const u8 = () => dv.getUint8(at++);
  const u16 = () => { const x = dv.getUint16(at, true); at += 2; return x; };
  const u32 = () => { const x = dv.getUint32(at, true); at += 4; return x; };
  const f32 = () => { const x = dv.getFloat32(at, true); at += 4; return x; };
  if (u8() !== 1) throw new Error('not a frame message');
  const m = { reset: (u8() & 1) === 1 };
  if (u16() !== 1) throw new Error('unknown wire version');
  m.frame = u32(); m.vertexSlots = u32(); m.triangleSlots = u32();
  m.positions = []; for (let n = u32(), i = 0; i < n; ++i) m.positions.push([u32(), f32(), f32(), f32()]);
  m.removed = []; for (let n = u32(), i = 0; i < n; ++i) m.removed.push(u32());
  m.set = []; for (let n = u32(), i = 0; i < n; ++i) m.set.push([u32(), u32(), u32(), u32(), u32()]);
  const ns = u32(); m.scalarLo = f32(); m.scalarHi = f32();
  m.scalars = ns ? new Float32Array(buf.slice(at, at + 4 * ns)) : null; at += 4 * ns;
  const nj = u32();
  m.stats = JSON.parse(new TextDecoder().decode(new Uint8Array(buf, at, nj)));
  return m;
}

// ---- state mirrored from the server ---------------------------------------------------------
let pos = new Float32Array(0);      // 3 per vertex slot
let tris = new Uint32Array(0);      // 5 per triangle slot: a, b, c, flags, alive
let scalars = null, scalarLo = 0, scalarHi = 1;
let stats = {};
const view = window.inciseView = { triangles: 0, cutTriangles: 0, worstTriangles: 0, frame: -1, messages: 0, bytes: 0,
                                   fps: 0, bytesPerFrame: 0, errors: [], connected: false, mode: null,
                                   positionSum: 0 };

function grow(a, n, Type, fill) {
  if (a.length >= n) return a;
  const b = new Type(Math.max(n, 2 * a.length)); if (fill !== undefined) b.fill(fill); b.set(a); return b;
}

function apply(m) {
  if (m.reset) { pos = new Float32Array(0); tris = new Uint32Array(0); scalars = null; fitted = false; }
  pos = grow(pos, 3 * m.vertexSlots, Float32Array);
  tris = grow(tris, 5 * m.triangleSlots, Uint32Array, 0);
  for (const [s, x, y, z] of m.positions) { pos[3 * s] = x; pos[3 * s + 1] = y; pos[3 * s + 2] = z; }
  for (const s of m.removed) tris[5 * s + 4] = 0;
  for (const [s, a, b, c, f] of m.set) tris.set([a, b, c, f, 1], 5 * s);
  for (let s = m.triangleSlots; s < tris.length / 5; ++s) tris[5 * s + 4] = 0;
  if (m.scalars) { scalars = m.scalars; scalarLo = m.scalarLo; scalarHi = m.scalarHi; }
  stats = m.stats;
  if (!stats.colour) scalars = null;
  if (view.mode === null) setViewMode(stats.mode || 'live');
  triangleSlots = m.triangleSlots;
  rebuild();
}

// ---- drawing ------------------------------------------------------------------------------
const container = document.getElementById('view');
const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio);
container.appendChild(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x1b1e23);
const camera = new THREE.PerspectiveCamera(40, 1, 0.1, 1e5);
scene.add(new THREE.HemisphereLight(0xffffff, 0x404050, 1.2));
const sun = new THREE.DirectionalLight(0xffffff, 1.6);
camera.add(sun); sun.position.set(0.3, 0.5, 1);
scene.add(camera);
const controls = new OrbitControls(camera, renderer.domElement);
controls.mouseButtons = { LEFT: null, MIDDLE: THREE.MOUSE.DOLLY, RIGHT: THREE.MOUSE.ROTATE };

const geometry = new THREE.BufferGeometry();
const surface = new THREE.Mesh(geometry, new THREE.MeshStandardMaterial({
  vertexColors: true, flatShading: true, side: THREE.DoubleSide, roughness: 0.7, metalness: 0.0 }));
const wire = new THREE.Mesh(geometry, new THREE.MeshBasicMaterial({ color: 0x101010, wireframe: true }));
wire.visible = false;
// Look mode's worst elements: drawn over everything (they are mostly inside the body).
const worstGeometry = new THREE.BufferGeometry();
const worstMesh = new THREE.Mesh(worstGeometry, new THREE.MeshBasicMaterial({
  color: 0xff3030, side: THREE.DoubleSide, depthTest: false, transparent: true, opacity: 0.85 }));
worstMesh.renderOrder = 1;
scene.add(surface, wire, worstMesh);
let triangleSlots = 0, fitted = false;
const box = new THREE.Box3(), center = new THREE.Vector3();
let bodySize = 1;

const TISSUE = [0.85, 0.47, 0.45], CUT = [0.98, 0.85, 0.30], FIXED = [0.45, 0.55, 0.85], LOADED = [0.55, 0.80, 0.45];
function colourmap(t) {  // blue -> green -> red
  t = Math.min(1, Math.max(0, t));
  return [Math.min(1, Math.max(0, 2 * t - 0.5)), 1 - Math.abs(2 * t - 1) * 0.8, Math.min(1, Math.max(0, 1.5 - 2 * t))];
}

// Labels and boundary tags (look mode's colours 3 and 4) are categories, not a scale.
const PALETTE = [[0.85, 0.47, 0.45], [0.45, 0.70, 0.90], [0.98, 0.85, 0.30], [0.55, 0.80, 0.45], [0.75, 0.55, 0.85],
                 [0.95, 0.60, 0.25], [0.40, 0.80, 0.75], [0.85, 0.85, 0.85]];
// Labels take the palette in the order the mesh has them (85, 127, 255 would otherwise share
// colours); tags are small numbers already.
function category(x) {
  const i = stats.colour === 3 ? (stats.labels || []).indexOf(Math.round(x)) : Math.round(x);
  return i < 0 ? PALETTE.length - 1 : i;
}
function rebuild() {
  const n = triangleSlots;
  const p = new Float32Array(9 * n), c = new Float32Array(9 * n), wp = [];
  let count = 0, cut = 0, worst = 0, sum = 0;
  for (let s = 0; s < n; ++s) {
    if (!tris[5 * s + 4]) continue;
    ++count;
    const flags = tris[5 * s + 3];
    if (flags & TRI_CUT) ++cut;
    let col = flags & TRI_CUT ? CUT : flags & TRI_FIXED ? FIXED : flags & TRI_LOADED ? LOADED : TISSUE;
    if (scalars && s < scalars.length && !(flags & TRI_CUT))
      col = stats.colour >= 3 ? PALETTE[category(scalars[s]) % PALETTE.length]
                              : colourmap((scalars[s] - scalarLo) / Math.max(1e-30, scalarHi - scalarLo));
    for (let k = 0; k < 3; ++k) {
      const v = tris[5 * s + k];
      p.set(pos.subarray(3 * v, 3 * v + 3), 9 * s + 3 * k);
      c.set(col, 9 * s + 3 * k);
      sum += pos[3 * v] + pos[3 * v + 1] + pos[3 * v + 2];
      if (flags & TRI_WORST) wp.push(pos[3 * v], pos[3 * v + 1], pos[3 * v + 2]);
    }
    if (flags & TRI_WORST) ++worst;
  }
  worstGeometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(wp), 3));
  worstGeometry.computeBoundingSphere();
  view.worstTriangles = worst;
  view.positionSum = sum;
  geometry.setAttribute('position', new THREE.BufferAttribute(p, 3));
  geometry.setAttribute('color', new THREE.BufferAttribute(c, 3));
  geometry.computeBoundingSphere();
  geometry.computeBoundingBox();
  view.triangles = count;
  view.cutTriangles = cut;
  document.getElementById('tri-count').textContent = String(count);
  if (!fitted && count > 0) {
    fitted = true;
    box.copy(geometry.boundingBox); box.getCenter(center);
    bodySize = box.getSize(new THREE.Vector3()).length();
    camera.near = bodySize / 100; camera.far = bodySize * 100; camera.updateProjectionMatrix();
    camera.position.copy(center).add(new THREE.Vector3(0, -0.35, 1).normalize().multiplyScalar(1.6 * bodySize));
    camera.up.set(0, 0, 1);
    controls.target.copy(center); controls.update();
  }
}

function resize() {
  renderer.setSize(container.clientWidth, container.clientHeight);
  camera.aspect = container.clientWidth / Math.max(1, container.clientHeight);
  camera.updateProjectionMatrix();
  // The overlay sits below the button bar, which wraps on narrow windows.
  document.getElementById('overlay').style.top = (document.getElementById('bar').offsetHeight + 12) + 'px';
}
window.addEventListener('resize', resize);
resize();
renderer.setAnimationLoop(() => { controls.update(); renderer.render(scene, camera); });

// ---- connection -------------------------------------------------------------------------------
const socket = new WebSocket(`ws://${location.host}/ws`);
socket.binaryType = 'arraybuffer';
const send = (buf) => { if (socket.readyState === WebSocket.OPEN) socket.send(buf); };
let windowStart = performance.now(), windowFrames = 0, windowBytes = 0;
socket.onopen = () => { view.connected = true; };
socket.onclose = () => { view.connected = false; overlay.textContent = 'disconnected (the server stopped?)'; };
socket.onmessage = (ev) => {
  if (typeof ev.data === 'string') {  // an error frame: our input was refused, nothing changed
    const e = JSON.parse(ev.data).error;
    view.errors.push(e);
    document.getElementById('error').textContent = e;
    return;
  }
  const m = decodeFrame(ev.data);
  apply(m);
  view.frame = m.frame; view.messages++; view.bytes += ev.data.byteLength;
  windowFrames++; windowBytes += ev.data.byteLength;
  const now = performance.now();
  if (now - windowStart > 1000) {
    view.fps = 1000 * windowFrames / (now - windowStart);
    view.bytesPerFrame = windowBytes / windowFrames;
    windowStart = now; windowFrames = 0; windowBytes = 0;
  }
  showStats();
  send(encodeInput(Kind.Ack, [], m.frame));  // ready for the next one
};

const overlay = document.getElementById('overlay');
const f = (x, d = 2) => (x === undefined || x === null ? '-' : Number(x).toFixed(d));
function showStats() {
  const s = stats;
  if (s.mode) return showLookStats(s);
  overlay.textContent =
    `frame ${s.frame}${s.paused ? '  (paused)' : ''}   ${f(view.fps, 1)} fps to this page, ${f(view.bytesPerFrame / 1024, 1)} KiB/frame\n` +
    `frame ${f(s.frame_ms)} ms: cut ${f(s.cut_ms - s.improve_ms)} ms, improve ${f(s.improve_ms)} ms, solve ${f(s.solve_ms)} ms\n` +
    `CG ${s.iterations} iterations, residual ${Number(s.residual).toExponential(1)}` +
    `${s.budget_exhausted ? ' (stopped by the budget)' : ''}; ${s.budget_hits} frames hit the budget\n` +
    `${s.tets} tets, ${s.vertices} vertices, ${s.triangles} boundary triangles (${s.cut_triangles} cut)\n` +
    `min dihedral ${f(s.min_dihedral, 1)} deg, ${s.below} tets below ${s.below_deg} deg (rest shape)` +
    (s.colour ? `\ncolour ${s.colour === 1 ? 'von Mises' : 'min dihedral'}: ${Number(s.scalar_lo).toPrecision(3)} .. ${Number(s.scalar_hi).toPrecision(3)}` : '');
  document.getElementById('pause').textContent = s.paused ? 'Resume' : 'Pause';
  const rec = document.getElementById('record');
  rec.disabled = !s.can_record;
  rec.title = s.can_record ? 'record a take: its frames and a scene that `incise simulate` replays'
                           : 'start incise view with --record DIR to record takes';
  rec.textContent = s.recording ? `Stop ${s.recording}` : 'Record';
  rec.classList.toggle('on', !!s.recording);
  if (s.clip_deg) overlay.textContent += `\nclip: ${s.clip_tets} tets below ${s.clip_deg} deg (red, rest shape${s.clip_tets >= s.clip_max ? `; the worst ${s.clip_max}` : ''})`;
  if (s.recording) overlay.textContent += `\nrecording ${s.recording}`;
  else if (s.last_take) overlay.textContent += `\nlast take: ${s.last_take} (incise simulate ${s.last_take}/scene.json -o DIR replays it)`;
  if (s.error) document.getElementById('error').textContent = s.error;
}

// ---- controls -------------------------------------------------------------------------------
let mode = 'cut';
function setMode(m) {
  mode = m;
  for (const k of ['cut', 'probe', 'orbit']) document.getElementById('mode-' + k).classList.toggle('on', k === m);
  controls.mouseButtons.LEFT = m === 'orbit' ? THREE.MOUSE.ROTATE : null;
}
for (const k of ['cut', 'probe', 'orbit']) document.getElementById('mode-' + k).onclick = () => setMode(k);
document.getElementById('pause').onclick = () => send(encodeInput(stats.paused ? Kind.Resume : Kind.Pause));
document.getElementById('step').onclick = () => send(encodeInput(Kind.Step));
document.getElementById('clip').onchange = (e) => {
  const deg = Math.max(0, Math.min(90, Math.round(Number(e.target.value) || 0)));
  e.target.value = String(deg);
  send(encodeInput(Kind.Clip, [], deg));
};
document.getElementById('record').onclick = () => send(encodeInput(Kind.Record, [], stats.recording ? 0 : 1));
document.getElementById('reset').onclick = () => { document.getElementById('error').textContent = ''; send(encodeInput(Kind.Reset)); };
document.getElementById('wire').onclick = (e) => { wire.visible = !wire.visible; e.target.classList.toggle('on', wire.visible); };
document.getElementById('colour').onchange = (e) => send(encodeInput(Kind.Colour, [], Number(e.target.value)));
window.addEventListener('keydown', (e) => {
  if (e.key === ' ') send(encodeInput(stats.paused ? Kind.Resume : Kind.Pause));
  else if (e.key === 's') send(encodeInput(Kind.Step));
  else if (e.key === 'w') document.getElementById('wire').click();
});

// ---- blade and probe ------------------------------------------------------------------------
// The blade is the segment of the mouse's ray from in front of the body down to `depth` x the
// body's size below where the ray enters it: dragging sweeps it through the body, each move
// one blade step on the server (on the current, deformed shape).
const raycaster = new THREE.Raycaster();
const ndc = new THREE.Vector2();
function rayAt(ev) {
  const r = renderer.domElement.getBoundingClientRect();
  ndc.set(((ev.clientX - r.left) / r.width) * 2 - 1, -((ev.clientY - r.top) / r.height) * 2 + 1);
  raycaster.setFromCamera(ndc, camera);
  return raycaster.ray;
}
let drag = null;  // {kind: "blade", plane, farPlane} or {kind: "probe", point, plane}
let pendingMove = null;
// The blade stays on the mouse's ray: its ends are where the ray meets two planes facing the
// camera, through its start's near and far ends. A straight drag sweeps a plane through the
// eye (the server keeps straight stretches exactly planar: one swept polygon), and where the
// mouse has left the body's outline so has the whole blade. (A blade that kept its start's
// direction and translated lagged behind the ray at depth, by perspective, and never left
// the body's far side: a depth-1 drag across the liver cut it but detached nothing.)
function bladeAt(ray) {
  const a = ray.intersectPlane(drag.plane, new THREE.Vector3());
  const b = ray.intersectPlane(drag.farPlane, new THREE.Vector3());
  if (!a || !b) return null;
  return [a.x, a.y, a.z, b.x, b.y, b.z];
}
renderer.domElement.addEventListener('pointerdown', (ev) => {
  if (ev.button !== 0 || mode === 'orbit' || !fitted) return;
  const ray = rayAt(ev);
  const hit = raycaster.intersectObject(surface, false)[0];
  if (mode === 'probe' || ev.shiftKey) {
    if (!hit) return;
    const normal = camera.getWorldDirection(new THREE.Vector3());
    drag = { kind: 'probe', point: hit.point.clone(), plane: new THREE.Plane().setFromNormalAndCoplanarPoint(normal, hit.point) };
    send(encodeInput(Kind.ProbeGrab, [hit.point.x, hit.point.y, hit.point.z, 0.04 * bodySize]));
  } else {
    // The near end starts in front of the whole body (so no part of it nearer to the camera
    // escapes the blade as it moves); the far end reaches `depth` below where the ray enters.
    const depth = Number(document.getElementById('depth').value) * bodySize;
    const toCenter = ray.origin.distanceTo(center);
    const entry = hit ? hit.distance : toCenter - 0.5 * bodySize;
    const t0 = Math.max(camera.near, toCenter - 0.6 * bodySize);
    const a = ray.at(t0, new THREE.Vector3());
    const b = ray.at(t0 + Math.max(entry + depth - t0, 0.01 * bodySize), new THREE.Vector3());
    const facing = camera.getWorldDirection(new THREE.Vector3());
    drag = { kind: 'blade', plane: new THREE.Plane().setFromNormalAndCoplanarPoint(facing, a),
             farPlane: new THREE.Plane().setFromNormalAndCoplanarPoint(facing, b) };
    send(encodeInput(Kind.BladeStart, bladeAt(ray)));
  }
  renderer.domElement.setPointerCapture(ev.pointerId);
});
renderer.domElement.addEventListener('pointermove', (ev) => {
  if (!drag) return;
  pendingMove = { clientX: ev.clientX, clientY: ev.clientY };
});
// Moves go at most once per animation frame (the server takes one blade step per frame anyway).
function flushMove() {
  if (drag && pendingMove) {
    const ray = rayAt(pendingMove);
    if (drag.kind === 'blade') { const s = bladeAt(ray); if (s) send(encodeInput(Kind.BladeMove, s)); }
    else {
      const p = ray.intersectPlane(drag.plane, new THREE.Vector3());
      if (p) { p.sub(drag.point); send(encodeInput(Kind.ProbeMove, [p.x, p.y, p.z])); }
    }
    pendingMove = null;
  }
  requestAnimationFrame(flushMove);
}
requestAnimationFrame(flushMove);
function endDrag(ev) {
  if (!drag) return;
  if (pendingMove) { flushMoveOnce(); }
  send(encodeInput(drag.kind === 'blade' ? Kind.BladeEnd : Kind.ProbeRelease));
  drag = null;
  try { renderer.domElement.releasePointerCapture(ev.pointerId); } catch (e) { /* already released */ }
}
function flushMoveOnce() {
  const ray = rayAt(pendingMove);
  const s = drag.kind === 'blade' ? bladeAt(ray) : null;
  if (s) send(encodeInput(Kind.BladeMove, s));
  pendingMove = null;
}
renderer.domElement.addEventListener('pointerup', endDrag);
renderer.domElement.addEventListener('pointercancel', endDrag);

// ---- look mode (incise view MESH | REPORT | RUN_DIR) -------------------------------------------
// Nothing plays: the live controls go, colours by label and boundary tag come, and a run
// directory gets a time slider and its stats.csv curves (from /status, once).
let runStats = null;
function setViewMode(m) {
  view.mode = m;
  if (m === 'live') return;
  for (const id of ['mode-cut', 'mode-probe', 'pause', 'step', 'reset', 'record', 'clip-label', 'depth-label'])
    document.getElementById(id).style.display = 'none';
  setMode('orbit');
  resize();
  const sel = document.getElementById('colour');
  sel.innerHTML = '<option value="0">plain</option><option value="3">label</option>' +
                  '<option value="4">boundary tag</option><option value="2">element quality (min dihedral)</option>' +
                  (stats.von_mises ? '<option value="1">von Mises stress (the run\'s)</option>' : '');
  document.getElementById('help').textContent = 'drag: orbit · right drag: orbit · Shift+right drag: pan · wheel: zoom · red: the worst elements';
  if ((stats.labels || []).length > 1) { sel.value = '3'; send(encodeInput(Kind.Colour, [], 3)); }
  if (m === 'run') {
    document.getElementById('run').style.display = 'block';
    const slider = document.getElementById('frame');
    slider.max = String(stats.frames - 1);
    slider.oninput = () => send(encodeInput(Kind.Frame, [], Number(slider.value)));
    fetch('/status').then((r) => r.json()).then((st) => {
      runStats = st.stats;
      const pick = document.getElementById('curve');
      if (!runStats) { pick.style.display = 'none'; return; }
      runStats.columns.forEach((name, i) => { if (name !== 'frame' && name !== 'time') pick.add(new Option(name, String(i))); });
      const preferred = runStats.columns.indexOf('max_displacement');
      if (preferred >= 0) pick.value = String(preferred);
      pick.onchange = plot;
      plot();
    });
  }
}
function plot() {
  const svg = document.getElementById('plot');
  if (!runStats || !runStats.rows.length) { svg.innerHTML = ''; return; }
  const col = Number(document.getElementById('curve').value), W = 300, H = 90;
  const ys = runStats.rows.map((r) => r[col]).filter((y) => y !== null);
  const lo = Math.min(...ys), hi = Math.max(...ys), n = runStats.rows.length;
  const x = (i) => 4 + (W - 8) * (n > 1 ? i / (n - 1) : 0.5), y = (v) => H - 12 - (H - 20) * (hi > lo ? (v - lo) / (hi - lo) : 0.5);
  const pts = runStats.rows.map((r, i) => (r[col] === null ? null : `${x(i).toFixed(1)},${y(r[col]).toFixed(1)}`)).filter(Boolean);
  // The marker is at the row of the frame shown (rows are frames in order, frames.pvd lists a subset).
  const frameCol = runStats.columns.indexOf('frame');
  const shownTime = stats.time;
  const timeCol = runStats.columns.indexOf('time');
  let at = runStats.rows.findIndex((r) => timeCol >= 0 && Math.abs(r[timeCol] - shownTime) <= 1e-9 * Math.max(1, Math.abs(shownTime)));
  if (at < 0 && frameCol >= 0) at = Math.min(n - 1, stats.frame);
  svg.innerHTML = `<polyline fill="none" stroke="#7fb3ff" stroke-width="1.5" points="${pts.join(' ')}"/>` +
    (at >= 0 ? `<line x1="${x(at)}" x2="${x(at)}" y1="2" y2="${H - 10}" stroke="#ffd54f"/>` : '') +
    `<text x="4" y="${H - 1}" fill="#9aa3b2" font-size="10">${lo.toPrecision(3)} .. ${hi.toPrecision(3)}</text>`;
}
function showLookStats(s) {
  const colourName = { 2: 'min dihedral', 3: 'label', 4: 'boundary tag' }[s.colour];
  overlay.textContent =
    `${s.file}${s.mode === 'run' ? `   frame ${s.frame + 1} of ${s.frames}, t = ${Number(s.time).toPrecision(4)}` : ''}\n` +
    `${s.tets} tets, ${s.vertices} vertices, ${s.triangles} triangles drawn (${s.cut_triangles} cut, ` +
    `${view.worstTriangles} of the worst elements)\n` +
    `labels ${(s.labels || []).map((l, i) => (s.colour === 3 ? `${l} (${['red', 'blue', 'yellow', 'green', 'violet', 'orange', 'teal', 'grey'][i % 8]})` : l)).join(', ')}\n` +
    `min dihedral ${f(s.min_dihedral, 1)} deg, ${s.slivers} slivers, ${s.inverted} inverted\n` +
    `worst ${(s.worst || []).length} (red; ${s.worst_from}): tets ${(s.worst || []).slice(0, 10).join(' ')}` +
    (colourName ? `\ncolour ${colourName}: ${Number(s.scalar_lo).toPrecision(3)} .. ${Number(s.scalar_hi).toPrecision(3)}` : '');
  if (s.mode === 'run') {
    document.getElementById('frame-label').textContent = `frame ${s.frame + 1}/${s.frames}`;
    document.getElementById('frame').value = String(s.frame);
    plot();
  }
}
