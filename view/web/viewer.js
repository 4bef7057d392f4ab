// The page of `incise view` (docs/view.md): draws the boundary the server streams and sends the
// mouse's blade and probe (live), or the frame picked on the time slider (look mode: the server
// says which in each frame's figures, `mode`). It simulates nothing: every figure comes from the
// server.
import * as THREE from 'three';
import { OrbitControls } from './OrbitControls.js';

// ---- wire format (view/wire_format.h) ---------------------------------------------------
const Kind = { BladeStart: 1, BladeMove: 2, BladeEnd: 3, ProbeGrab: 4, ProbeMove: 5, ProbeRelease: 6,
               Pause: 7, Resume: 8, Step: 9, Reset: 10, Colour: 11, Ack: 12, Frame: 13, Record: 14, Clip: 15 };
const TRI_CUT = 1, TRI_FIXED = 2, TRI_WORST = 4, TRI_LOADED = 8, TRI_INTERFACE = 16;

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
// What the page holds and draws, for the browser tests (tests/view/browser_*test.py).
const view = window.inciseView = { triangles: 0, cutTriangles: 0, worstTriangles: 0, interfaceTriangles: 0, frame: -1,
                                   messages: 0, bytes: 0, fps: 0, bytesPerFrame: 0, errors: [], connected: false,
                                   mode: null, positionSum: 0,
                                   normals: 'vertex', facets: false, splitVertices: 0, legend: null, section: 0,
                                   blade: null, probe: null, lastPress: null, drags: 0, noCut: 0, lastDragTetsCut: null,
                                   flash: '' };

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
  orderLabels();
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
scene.add(new THREE.HemisphereLight(0xffffff, 0x403838, 0.9));
const sun = new THREE.DirectionalLight(0xfff6ee, 2.2);
camera.add(sun); sun.position.set(0.3, 0.5, 1);
scene.add(camera);
const controls = new OrbitControls(camera, renderer.domElement);
controls.mouseButtons = { LEFT: null, MIDDLE: THREE.MOUSE.DOLLY, RIGHT: THREE.MOUSE.ROTATE };

// Colours are sRGB (what the legend's CSS shows); THREE.Color turns them into the linear values
// the lighting works in, so a swatch and the lit body it names agree (up to the shading).
const linear = (hex) => { const c = new THREE.Color(hex); return [c.r, c.g, c.b]; };
const cssColour = (hex) => '#' + hex.toString(16).padStart(6, '0');
const TISSUE_HEX = 0xd98a7c, CUT_HEX = 0xa8123a, FIXED_HEX = 0x6f8fd8, LOADED_HEX = 0x7cc46a;
// The worst elements (look mode) and the clip view's tets (live): magenta, a colour no label,
// tag, tissue or scale uses (the scale's top is red).
const WORST_HEX = 0xff00ff, TOOL_HEX = 0xdfe4ea;
const TISSUE = linear(TISSUE_HEX), FIXED = linear(FIXED_HEX), LOADED = linear(LOADED_HEX);

const geometry = new THREE.BufferGeometry();
// Two materials, by geometry groups: the organ's surface (vertex colours: tissue, fixed,
// loaded, or the colouring's) and the cut surface, inner tissue: darker, more saturated and
// wet (glossy, a clear coat), whatever the colouring.
const tissueMaterial = new THREE.MeshStandardMaterial({
  vertexColors: true, side: THREE.DoubleSide, roughness: 0.45, metalness: 0.0 });
const cutMaterial = new THREE.MeshPhysicalMaterial({
  color: CUT_HEX, side: THREE.DoubleSide, roughness: 0.32, metalness: 0.0, clearcoat: 0.7, clearcoatRoughness: 0.15 });
const surface = new THREE.Mesh(geometry, [tissueMaterial, cutMaterial]);
const wireMaterial = new THREE.MeshBasicMaterial({ color: 0x101010, wireframe: true });
const wire = new THREE.Mesh(geometry, wireMaterial);
wire.visible = false;
// Look mode's worst elements: drawn over everything (they are mostly inside the body).
const worstGeometry = new THREE.BufferGeometry();
const worstMesh = new THREE.Mesh(worstGeometry, new THREE.MeshBasicMaterial({
  color: WORST_HEX, side: THREE.DoubleSide, depthTest: false, transparent: true, opacity: 0.85 }));
worstMesh.renderOrder = 1;
scene.add(surface, wire, worstMesh);
let triangleSlots = 0, fitted = false;
const box = new THREE.Box3(), center = new THREE.Vector3();
let bodySize = 1;

function colourmap(t) {  // blue -> green -> red, sRGB
  t = Math.min(1, Math.max(0, t));
  return [Math.min(1, Math.max(0, 2 * t - 0.5)), 1 - Math.abs(2 * t - 1) * 0.8, Math.min(1, Math.max(0, 1.5 - 2 * t))];
}
// The scale in 256 steps, linear (vertex colours), so a frame converts no colour.
const SCALE = Array.from({ length: 256 }, (_, i) => {
  const [r, g, b] = colourmap(i / 255);
  const c = new THREE.Color().setRGB(r, g, b, THREE.SRGBColorSpace);
  return [c.r, c.g, c.b];
});
const scaleCss = (t) => { const [r, g, b] = colourmap(t).map((x) => Math.round(255 * x)); return `rgb(${r},${g},${b})`; };

// Labels and boundary tags (look mode's colours 3 and 4) are categories, not a scale. The
// palette has no red or magenta (the worst elements') and starts with the tissue's colour:
// the largest label (the organ, as a rule) is drawn as tissue, the others in the palette's
// order by size (85, 127, 255 would otherwise share colours).
const PALETTE_HEX = [TISSUE_HEX, 0xf2c84b, 0x58a6e8, 0x66c27a, 0xf08a3c, 0x46c2b4, 0xb39ddb, 0xc8c8c8];
const PALETTE_NAMES = ['tissue', 'yellow', 'blue', 'green', 'orange', 'teal', 'lavender', 'grey'];
const PALETTE = PALETTE_HEX.map(linear);
// Boundary tags: 1 surface (tissue), 2 cut (drawn with the cut's material), 0 exposed by removal.
const TAG_HEX = { 0: 0x8fa3bf, 1: TISSUE_HEX, 2: CUT_HEX }, TAG_NAMES = { 0: 'exposed by removal', 1: 'surface', 2: 'cut' };
const TAG_COLOURS = Object.fromEntries(Object.entries(TAG_HEX).map(([k, h]) => [k, linear(h)]));
let labelOrder = [];  // labels by tets, largest first: a label's palette index
function orderLabels() {
  const labels = stats.labels || [], tets = stats.label_tets || [];
  labelOrder = labels.map((l, i) => [l, tets[i] || 0]).sort((a, b) => b[1] - a[1] || a[0] - b[0]).map((x) => x[0]);
}
function labelIndex(label) {
  const i = labelOrder.indexOf(label);
  return i < 0 ? PALETTE.length - 1 : i % PALETTE.length;
}
function categoryColour(x) {
  const k = Math.round(x);
  if (stats.colour === 3) return PALETTE[labelIndex(k)];
  return TAG_COLOURS[k] || PALETTE[PALETTE.length - 1];
}

// ---- smooth shading -------------------------------------------------------------------------
// Normals per corner from the streamed triangles, every frame (the body deforms): a corner's
// normal is the area-weighted sum of the normals of the triangles at its vertex that are of its
// kind (outer surface, cut face, label interface) and within kCrease of its own triangle. The
// organ is smooth; a cut's rim and sharp edges (a blade's wedge, the walls a removal leaves)
// stay crisp: a vertex there gets one normal per side (it is "split", view.splitVertices). The
// worst elements' faces and the clip view's tets keep their own normal and are left out of
// their neighbours'. O(triangles x valence) a frame, in arrays kept between frames.
const kCreaseCos = Math.cos(40 * Math.PI / 180);
const FLAT = 254, DEAD = 255;
let faceN = new Float32Array(0), faceU = new Float32Array(0), faceKind = new Uint8Array(0);
let vStart = new Uint32Array(0), vFill = new Uint32Array(0), vTris = new Uint32Array(0), splitMark = new Uint8Array(0);

function faceNormals(n) {
  if (faceKind.length < n) {
    faceN = new Float32Array(6 * n); faceU = new Float32Array(6 * n); faceKind = new Uint8Array(2 * n);
    vTris = new Uint32Array(6 * n);
  }
  const nv = pos.length / 3;
  if (vStart.length < nv + 1) {
    vStart = new Uint32Array(2 * nv + 2); vFill = new Uint32Array(2 * nv + 2); splitMark = new Uint8Array(2 * nv + 2);
  }
  vStart.fill(0, 0, nv + 1);
  splitMark.fill(0, 0, nv);
  for (let s = 0; s < n; ++s) {
    if (!tris[5 * s + 4]) { faceKind[s] = DEAD; continue; }
    const a = 3 * tris[5 * s], b = 3 * tris[5 * s + 1], c = 3 * tris[5 * s + 2], flags = tris[5 * s + 3];
    const ux = pos[b] - pos[a], uy = pos[b + 1] - pos[a + 1], uz = pos[b + 2] - pos[a + 2];
    const vx = pos[c] - pos[a], vy = pos[c + 1] - pos[a + 1], vz = pos[c + 2] - pos[a + 2];
    const nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
    const len = Math.hypot(nx, ny, nz), inv = len > 0 ? 1 / len : 0;
    faceN[3 * s] = nx; faceN[3 * s + 1] = ny; faceN[3 * s + 2] = nz;
    faceU[3 * s] = nx * inv; faceU[3 * s + 1] = ny * inv; faceU[3 * s + 2] = nz * inv;
    faceKind[s] = flags & TRI_WORST ? FLAT : (flags & TRI_CUT ? 1 : 0) | (flags & TRI_INTERFACE ? 2 : 0);
    if (faceKind[s] !== FLAT) { ++vStart[a / 3 + 1]; ++vStart[b / 3 + 1]; ++vStart[c / 3 + 1]; }
  }
  for (let v = 0; v < nv; ++v) vStart[v + 1] += vStart[v];
  vFill.set(vStart.subarray(0, nv));
  for (let s = 0; s < n; ++s) {
    if (faceKind[s] >= FLAT) continue;
    for (let k = 0; k < 3; ++k) { const v = tris[5 * s + k]; vTris[vFill[v]++] = s; }
  }
}

// The normal of slot s's corner at vertex v into out[at..at+2].
function cornerNormal(s, v, out, at) {
  const ux = faceU[3 * s], uy = faceU[3 * s + 1], uz = faceU[3 * s + 2], kind = faceKind[s];
  let x = 0, y = 0, z = 0;
  if (kind !== FLAT) {
    for (let j = vStart[v], end = vStart[v + 1]; j < end; ++j) {
      const t = vTris[j];
      if (faceKind[t] !== kind || faceU[3 * t] * ux + faceU[3 * t + 1] * uy + faceU[3 * t + 2] * uz < kCreaseCos) {
        splitMark[v] = 1;
        continue;
      }
      x += faceN[3 * t]; y += faceN[3 * t + 1]; z += faceN[3 * t + 2];
    }
  }
  let len = Math.hypot(x, y, z);
  if (!(len > 0)) { x = ux; y = uy; z = uz; len = Math.hypot(x, y, z); }
  if (!(len > 0)) { x = 0; y = 0; z = 1; len = 1; }
  out[at] = x / len; out[at + 1] = y / len; out[at + 2] = z / len;
}

function rebuild() {
  const n = triangleSlots;
  faceNormals(n);
  let count = 0, cut = 0, worst = 0, iface = 0, sum = 0;
  for (let s = 0; s < n; ++s) {
    if (!tris[5 * s + 4]) continue;
    ++count;
    const flags = tris[5 * s + 3];
    if (flags & TRI_CUT) ++cut;
    if (flags & TRI_WORST) ++worst;
    if (flags & TRI_INTERFACE) ++iface;
  }
  // Cut faces last: the cut material's group.
  const p = new Float32Array(9 * count), nrm = new Float32Array(9 * count), c = new Float32Array(9 * count);
  const wp = new Float32Array(9 * worst);
  let at = 0, atCut = count - cut, atWorst = 0;
  for (let s = 0; s < n; ++s) {
    if (!tris[5 * s + 4]) continue;
    const flags = tris[5 * s + 3];
    let col = flags & TRI_FIXED ? FIXED : flags & TRI_LOADED ? LOADED : TISSUE;
    if (scalars && s < scalars.length && !(flags & TRI_CUT)) {
      if (stats.colour >= 3) col = categoryColour(scalars[s]);
      else col = SCALE[Math.round(255 * Math.min(1, Math.max(0, (scalars[s] - scalarLo) / Math.max(1e-30, scalarHi - scalarLo))))];
    }
    const o = 9 * (flags & TRI_CUT ? atCut++ : at++);
    for (let k = 0; k < 3; ++k) {
      const v = tris[5 * s + k], q = o + 3 * k;
      const x = pos[3 * v], y = pos[3 * v + 1], z = pos[3 * v + 2];
      p[q] = x; p[q + 1] = y; p[q + 2] = z;
      c[q] = col[0]; c[q + 1] = col[1]; c[q + 2] = col[2];
      cornerNormal(s, v, nrm, q);
      sum += x + y + z;
      if (flags & TRI_WORST) { wp[atWorst++] = x; wp[atWorst++] = y; wp[atWorst++] = z; }
    }
  }
  let split = 0;
  for (let v = 0; v < pos.length / 3; ++v) split += splitMark[v];
  view.splitVertices = split;
  worstGeometry.setAttribute('position', new THREE.BufferAttribute(wp, 3));
  worstGeometry.computeBoundingSphere();
  view.worstTriangles = worst;
  view.interfaceTriangles = iface;
  view.positionSum = sum;
  geometry.setAttribute('position', new THREE.BufferAttribute(p, 3));
  geometry.setAttribute('normal', new THREE.BufferAttribute(nrm, 3));
  geometry.setAttribute('color', new THREE.BufferAttribute(c, 3));
  geometry.clearGroups();
  geometry.addGroup(0, 3 * (count - cut), 0);
  geometry.addGroup(3 * (count - cut), 3 * cut, 1);
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

// The section plane (look mode): faces the camera and hides the body nearer to it than the
// slider's fraction of the body's depth along the view, so what is inside shows: the faces
// between labels (streamed while colouring by label), the far side's inner surface, the worst
// elements (drawn over everything anyway). Only the boundary and those faces are streamed, so
// the section shows no cap over the cut-through tets. Kept facing the camera as it orbits.
const sectionPlane = new THREE.Plane();
renderer.localClippingEnabled = true;
function setSection(fraction) {
  view.section = fraction;
  const planes = fraction > 0 ? [sectionPlane] : [];
  for (const m of [tissueMaterial, cutMaterial, wireMaterial]) { m.clippingPlanes = planes; m.needsUpdate = true; }
}
const viewDir = new THREE.Vector3();
function placeSection() {
  if (!(view.section > 0) || !geometry.boundingSphere) return;
  const { center: c, radius: r } = geometry.boundingSphere;
  camera.getWorldDirection(viewDir);
  // Kept: dot(dir, p) >= near + fraction * 2r, near = the sphere's nearest depth.
  sectionPlane.normal.copy(viewDir);
  sectionPlane.constant = -(viewDir.dot(c) - r + view.section * 2 * r);
}

function resize() {
  renderer.setSize(container.clientWidth, container.clientHeight);
  camera.aspect = container.clientWidth / Math.max(1, container.clientHeight);
  camera.updateProjectionMatrix();
  // The overlay sits below the button bar, which wraps on narrow windows.
  document.getElementById('overlay').style.top = (document.getElementById('bar').offsetHeight + 12) + 'px';
  placeBanners();
}
window.addEventListener('resize', resize);
renderer.setAnimationLoop(() => { controls.update(); placeSection(); renderer.render(scene, camera); });

// ---- banners: errors (dismissable) and the "no cut" flash ----------------------------------
// At the bottom centre, above the help line and the run panel, so neither covers them.
const errorBox = document.getElementById('error'), errorText = document.getElementById('error-text');
const flashBox = document.getElementById('flash');
let shownError = '', dismissedError = '', flashTimer = null;
function placeBanners() {
  let top = document.getElementById('help').getBoundingClientRect().top;
  const run = document.getElementById('run');
  if (run.style.display !== 'none') top = Math.min(top, run.getBoundingClientRect().top);
  const bottom = window.innerHeight - top + 8;
  errorBox.style.bottom = bottom + 'px';
  flashBox.style.bottom = (bottom + (shownError ? errorBox.offsetHeight + 8 : 0)) + 'px';
}
function showError(e) {
  if (e === shownError) return;
  shownError = e;
  errorText.textContent = e;
  errorBox.style.display = e ? 'flex' : 'none';
  placeBanners();
}
document.getElementById('error-close').onclick = () => { dismissedError = shownError; showError(''); };
function flash(text) {
  view.flash = text;
  flashBox.textContent = text;
  flashBox.classList.add('on');
  placeBanners();
  clearTimeout(flashTimer);
  flashTimer = setTimeout(() => flashBox.classList.remove('on'), 2500);
}
resize();

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
    showError(e);
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
  showLegend();
  if (s.mode) return showLookStats(s);
  checkDrag(s);
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
  if (s.clip_deg) overlay.textContent += `\nclip: ${s.clip_tets} tets below ${s.clip_deg} deg (magenta, rest shape${s.clip_tets >= s.clip_max ? `; the worst ${s.clip_max}` : ''})`;
  if (s.recording) overlay.textContent += `\nrecording ${s.recording}`;
  else if (s.last_take) overlay.textContent += `\nlast take: ${s.last_take} (incise simulate ${s.last_take}/scene.json -o DIR replays it)`;
  if (s.error && s.error !== dismissedError) showError(s.error);
}

// ---- the colour bar and the legend ----------------------------------------------------------
// Scalar colourings (von Mises, min dihedral) get a bar with the scale's ends; the categories
// (label, boundary tag; look mode) a legend of their colours. Plain colours: none. Rebuilt only
// when what it shows changes.
const legendBox = document.getElementById('legend');
let legendKey = '';
const esc = (x) => String(x).replace(/[&<>"]/g, (c) => ({ '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;' })[c]);
const swatch = (hex) => `<span class="swatch" style="background:${cssColour(hex)}"></span>`;
function showLegend() {
  const c = stats.colour;
  let legend = null;
  if ((c === 1 || c === 2) && scalars) {
    const num = (x) => Number(x).toPrecision(3);
    legend = { kind: 'scale', title: c === 1 ? 'von Mises stress' : 'min dihedral angle (deg)', lo: num(scalarLo),
               mid: num((scalarLo + scalarHi) / 2), hi: num(scalarHi),
               note: view.mode === 'live' || stats.colour === 1 ? 'ends: 2nd and 98th percentile; beyond: clamped' : 'ends: smallest and largest' };
  } else if (c === 3 && scalars) {
    const tets = Object.fromEntries((stats.labels || []).map((l, i) => [l, (stats.label_tets || [])[i]]));
    legend = { kind: 'category', title: 'label', items: labelOrder.map((l) => ({
      name: `${l}${tets[l] !== undefined ? ` (${tets[l]} tets)` : ''}`, colour: PALETTE_HEX[labelIndex(l)] })) };
  } else if (c === 4 && scalars) {
    legend = { kind: 'category', title: 'boundary tag', items: [1, 2, 0].map((t) => ({ name: `${t} ${TAG_NAMES[t]}`, colour: TAG_HEX[t] })) };
  }
  if (legend && legend.kind === 'category') {
    if (view.mode !== 'live') legend.items.push({ name: 'worst elements', colour: WORST_HEX });
    if (c === 3 && (stats.labels || []).length > 1)
      legend.note = 'faces between labels: in the smaller label\'s colour (the section uncovers them)';
  }
  const key = JSON.stringify(legend);
  if (key === legendKey) return;
  legendKey = key;
  view.legend = legend;
  if (!legend) { legendBox.style.display = 'none'; legendBox.innerHTML = ''; return; }
  let html = `<div class="title">${esc(legend.title)}</div>`;
  if (legend.kind === 'scale') {
    const stops = Array.from({ length: 11 }, (_, i) => scaleCss(i / 10)).join(', ');
    html += `<div class="scale"><div class="bar" style="background: linear-gradient(to top, ${stops})"></div>` +
            `<div class="ticks"><span class="hi">${legend.hi}</span><span>${legend.mid}</span>` +
            `<span class="lo">${legend.lo}</span></div></div>`;
  } else {
    html += legend.items.map((it) => `<div class="item">${swatch(it.colour)}${esc(it.name)}</div>`).join('');
  }
  if (legend.note) html += `<div class="note">${esc(legend.note)}</div>`;
  legendBox.innerHTML = html;
  legendBox.style.display = 'block';
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
document.getElementById('reset').onclick = () => { dismissedError = ''; showError(''); send(encodeInput(Kind.Reset)); };
document.getElementById('wire').onclick = (e) => { wire.visible = !wire.visible; e.target.classList.toggle('on', wire.visible); };
// Facets: flat shading (the shader's own face normals), to see the mesh's triangles; the
// smooth normals stay computed, so switching back is immediate.
document.getElementById('facets').onclick = (e) => {
  view.facets = !view.facets;
  view.normals = view.facets ? 'face' : 'vertex';
  tissueMaterial.flatShading = cutMaterial.flatShading = view.facets;
  tissueMaterial.needsUpdate = cutMaterial.needsUpdate = true;
  e.target.classList.toggle('on', view.facets);
};
document.getElementById('section').oninput = (e) => setSection(Number(e.target.value));
document.getElementById('colour').onchange = (e) => send(encodeInput(Kind.Colour, [], Number(e.target.value)));
window.addEventListener('keydown', (e) => {
  if (e.key === ' ') send(encodeInput(stats.paused ? Kind.Resume : Kind.Pause));
  else if (e.key === 's') send(encodeInput(Kind.Step));
  else if (e.key === 'w') document.getElementById('wire').click();
  else if (e.key === 'f') document.getElementById('facets').click();
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
let drag = null;  // {kind: "blade", plane, farPlane, entryAt, drags} or {kind: "probe", point, plane}
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
// Where a ray that misses the body passes nearest to it: the drawn vertex nearest to the ray
// (by distance from it, in front of the camera), its distance along the ray. A scan of the
// vertices of the live triangles (a removed part's slots may hold old positions), once per
// press; null when nothing is drawn.
function nearestAlong(ray) {
  let best = Infinity, along = null;
  const o = ray.origin, d = ray.direction;
  for (let s = 0; s < triangleSlots; ++s) {
    if (!tris[5 * s + 4]) continue;
    for (let k = 0; k < 3; ++k) {
      const v = 3 * tris[5 * s + k];
      const x = pos[v] - o.x, y = pos[v + 1] - o.y, z = pos[v + 2] - o.z;
      const t = x * d.x + y * d.y + z * d.z;
      const d2 = x * x + y * y + z * z - t * t;
      if (t > 0 && d2 < best) { best = d2; along = t; }
    }
  }
  return along;
}

// What the tools look like (drawn over the body: they are mostly inside it). The blade: its
// segment as a thin silver shaft with a darker handle at the near end, and the drag's path at
// the depth where it entered (seen from the camera the blade is on the mouse's ray, so it shows
// end-on at the pointer; the path shows where it has been). The probe: a small sphere at the
// grabbed point moved by the drag, inside a faint one of the grab's radius.
const toolMaterial = new THREE.MeshStandardMaterial({ color: TOOL_HEX, emissive: 0x3c4048, metalness: 0.35,
                                                      roughness: 0.3, depthTest: false, transparent: true, opacity: 0.95 });
const handleMaterial = new THREE.MeshStandardMaterial({ color: 0x4a525e, metalness: 0.3, roughness: 0.5,
                                                        depthTest: false, transparent: true });
const unitCylinder = new THREE.CylinderGeometry(1, 1, 1, 16), unitSphere = new THREE.SphereGeometry(1, 24, 16);
const bladeShaft = new THREE.Mesh(unitCylinder, toolMaterial), bladeHandle = new THREE.Mesh(unitCylinder, handleMaterial);
const trailGeometry = new THREE.BufferGeometry();
const bladeTrail = new THREE.Mesh(trailGeometry, new THREE.MeshBasicMaterial({
  color: TOOL_HEX, side: THREE.DoubleSide, depthTest: false, transparent: true, opacity: 0.8 }));
const probeTip = new THREE.Mesh(unitSphere, toolMaterial);
const probeReach = new THREE.Mesh(unitSphere, new THREE.MeshBasicMaterial({
  color: TOOL_HEX, depthTest: false, depthWrite: false, transparent: true, opacity: 0.18 }));
for (const m of [bladeTrail, bladeShaft, bladeHandle, probeReach, probeTip]) { m.visible = false; m.renderOrder = 2; scene.add(m); }
const yAxis = new THREE.Vector3(0, 1, 0);
function placeRod(mesh, a, b, radius) {
  const d = new THREE.Vector3().subVectors(b, a), len = d.length();
  mesh.position.addVectors(a, b).multiplyScalar(0.5);
  mesh.quaternion.setFromUnitVectors(yAxis, d.divideScalar(Math.max(len, 1e-30)));
  mesh.scale.set(radius, len, radius);
}
function drawBlade(seg) {
  const a = new THREE.Vector3(seg[0], seg[1], seg[2]), b = new THREE.Vector3(seg[3], seg[4], seg[5]);
  placeRod(bladeShaft, a, b, 0.004 * bodySize);
  placeRod(bladeHandle, a, a.clone().lerp(b, 0.2), 0.007 * bodySize);
  drag.trail.push(a.clone().lerp(b, drag.entryAt));
  // The path as a ribbon facing the camera (lines are one pixel wide in WebGL).
  const t = drag.trail, w = 0.0035 * bodySize, q = [];
  camera.getWorldDirection(viewDir);
  for (let i = 0; i + 1 < t.length; ++i) {
    const side = new THREE.Vector3().subVectors(t[i + 1], t[i]).cross(viewDir);
    if (!(side.length() > 0)) continue;
    side.setLength(w);
    const p0 = t[i].clone().sub(side), p1 = t[i].clone().add(side), p2 = t[i + 1].clone().add(side), p3 = t[i + 1].clone().sub(side);
    for (const p of [p0, p1, p2, p0, p2, p3]) q.push(p.x, p.y, p.z);
  }
  trailGeometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(q), 3));
  trailGeometry.computeBoundingSphere();
  bladeShaft.visible = bladeHandle.visible = bladeTrail.visible = true;
  view.blade = { a: seg.slice(0, 3), b: seg.slice(3, 6), path: t.length, screen: [toScreen(a), toScreen(b)] };
}
function drawProbe(p) {
  probeTip.position.copy(p); probeTip.scale.setScalar(0.012 * bodySize);
  probeReach.position.copy(p); probeReach.scale.setScalar(drag.radius);
  probeTip.visible = probeReach.visible = true;
  view.probe = { point: [p.x, p.y, p.z], screen: toScreen(p) };
}
function toScreen(p) {  // page pixels (the tests compare them with the pointer)
  const r = renderer.domElement.getBoundingClientRect(), q = p.clone().project(camera);
  return [r.left + (q.x + 1) / 2 * r.width, r.top + (1 - q.y) / 2 * r.height];
}
function hideTools() {
  for (const m of [bladeTrail, bladeShaft, bladeHandle, probeReach, probeTip]) m.visible = false;
  view.blade = view.probe = null;
}
function sendBlade(kind, seg) {
  if (!seg) return;
  send(encodeInput(kind, seg));
  drawBlade(seg);
}
function sendProbeMove(ray) {
  const p = ray.intersectPlane(drag.plane, new THREE.Vector3());
  if (!p) return;
  drawProbe(p);
  p.sub(drag.point);
  send(encodeInput(Kind.ProbeMove, [p.x, p.y, p.z]));
}

renderer.domElement.addEventListener('pointerdown', (ev) => {
  if (ev.button !== 0 || mode === 'orbit' || !fitted || drag) return;
  const ray = rayAt(ev);
  const hit = raycaster.intersectObject(surface, false)[0];
  if (mode === 'probe' || ev.shiftKey) {
    if (!hit) return;
    const normal = camera.getWorldDirection(new THREE.Vector3());
    drag = { kind: 'probe', point: hit.point.clone(), radius: 0.04 * bodySize,
             plane: new THREE.Plane().setFromNormalAndCoplanarPoint(normal, hit.point) };
    send(encodeInput(Kind.ProbeGrab, [hit.point.x, hit.point.y, hit.point.z, drag.radius]));
    drawProbe(hit.point);
  } else {
    // The near end starts in front of the whole body (so no part of it nearer to the camera
    // escapes the blade as it moves); the far end reaches `depth` below where the ray enters,
    // or, for a press beside the body, below the depth where the ray passes nearest to it: a
    // drag started beside the body and moved across it cuts it as deep as one started on it.
    const depth = Number(document.getElementById('depth').value) * bodySize;
    const toCenter = ray.origin.distanceTo(center);
    const near = hit ? null : nearestAlong(ray);
    const entry = hit ? hit.distance : near !== null ? near : toCenter - 0.5 * bodySize;
    const t0 = Math.max(camera.near, toCenter - 0.6 * bodySize);
    const length = Math.max(entry + depth - t0, 0.01 * bodySize);
    const a = ray.at(t0, new THREE.Vector3());
    const b = ray.at(t0 + length, new THREE.Vector3());
    const facing = camera.getWorldDirection(new THREE.Vector3());
    // The server counts the drags it has ended (blade_drags): this one is the one after those
    // sent so far, counting one still waited for.
    const drags = pendingDrag ? pendingDrag.drags + 1 : stats.blade_drags || 0;
    drag = { kind: 'blade', plane: new THREE.Plane().setFromNormalAndCoplanarPoint(facing, a),
             farPlane: new THREE.Plane().setFromNormalAndCoplanarPoint(facing, b),
             entryAt: Math.min(1, Math.max(0, (entry - t0) / length)), trail: [], drags };
    view.lastPress = { hit: !!hit, entry, nearest: near };
    view.lastDragTetsCut = null;
    sendBlade(Kind.BladeStart, bladeAt(ray));
  }
  renderer.domElement.setPointerCapture(ev.pointerId);
});
renderer.domElement.addEventListener('pointermove', (ev) => {
  if (!drag) return;
  pendingMove = { clientX: ev.clientX, clientY: ev.clientY };
});
// Moves go at most once per animation frame (the server takes one blade step per frame anyway).
function flushMove() {
  if (drag && pendingMove) flushMoveOnce();
  requestAnimationFrame(flushMove);
}
requestAnimationFrame(flushMove);
function flushMoveOnce() {
  const ray = rayAt(pendingMove);
  if (drag.kind === 'blade') sendBlade(Kind.BladeMove, bladeAt(ray));
  else sendProbeMove(ray);
  pendingMove = null;
}
function endDrag(ev) {
  if (!drag) return;
  if (pendingMove) flushMoveOnce();
  if (drag.kind === 'blade') {
    send(encodeInput(Kind.BladeEnd));
    view.drags++;
    pendingDrag = { drags: drag.drags, until: performance.now() + 5000 };
  } else {
    send(encodeInput(Kind.ProbeRelease));
  }
  drag = null;
  hideTools();
  try { renderer.domElement.releasePointerCapture(ev.pointerId); } catch (e) { /* already released */ }
}
renderer.domElement.addEventListener('pointerup', endDrag);
renderer.domElement.addEventListener('pointercancel', endDrag);

// "no cut": a drag whose blade met no tet says so. The server counts the drags it has ended
// (blade_drags) and the tets the last one cut (drag_tets_cut: its blade steps' and its
// finish's), so the first frame counting this drag carries its answer, whatever the scene's
// own blade did meanwhile. Given up after a while (a reset starts the count over).
let pendingDrag = null;
function checkDrag(s) {
  if (!pendingDrag) return;
  if ((s.blade_drags || 0) > pendingDrag.drags) {
    view.lastDragTetsCut = s.drag_tets_cut;
    if (s.drag_tets_cut === 0) { view.noCut++; flash('no cut: the blade did not meet the body'); }
    pendingDrag = null;
  } else if (performance.now() > pendingDrag.until) {
    pendingDrag = null;
  }
}

// ---- look mode (incise view MESH | REPORT | RUN_DIR) -------------------------------------------
// Nothing plays: the live controls go, colours by label and boundary tag come, and a run
// directory gets a time slider and its stats.csv curves (from /status, once).
let runStats = null;
function setViewMode(m) {
  view.mode = m;
  if (m === 'live') return;
  for (const id of ['mode-cut', 'mode-probe', 'pause', 'step', 'reset', 'record', 'clip-label', 'depth-label'])
    document.getElementById(id).style.display = 'none';
  document.getElementById('section-label').style.display = '';
  setMode('orbit');
  resize();
  const sel = document.getElementById('colour');
  sel.innerHTML = '<option value="0">plain</option><option value="3">label</option>' +
                  '<option value="4">boundary tag</option><option value="2">element quality (min dihedral)</option>' +
                  (stats.von_mises ? '<option value="1">von Mises stress (the run\'s)</option>' : '');
  document.getElementById('help').textContent = 'drag: orbit · right drag: orbit · Shift+right drag: pan · wheel: zoom · magenta: the worst elements';
  if ((stats.labels || []).length > 1) { sel.value = '3'; send(encodeInput(Kind.Colour, [], 3)); }
  if (m === 'run') {
    document.getElementById('run').style.display = 'block';
    placeBanners();
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
// A run's frame is read with its inverted tets flipped (docs/scene.md#inverted-tets), so the
// reader counts none; stats.csv's `inverted` column has the count in the deformed shape.
function invertedText(s) {
  const col = runStats && s.mode === 'run' ? runStats.columns.indexOf('inverted') : -1;
  const timeCol = col >= 0 ? runStats.columns.indexOf('time') : -1;
  const row = timeCol >= 0 ? runStats.rows.find((r) => Math.abs(r[timeCol] - s.time) <= 1e-9 * Math.max(1, Math.abs(s.time))) : null;
  return row ? `${row[col]} inverted in the deformed shape (stats.csv)` : `${s.inverted} inverted`;
}
function showLookStats(s) {
  const colourName = { 2: 'min dihedral', 3: 'label', 4: 'boundary tag' }[s.colour];
  overlay.textContent =
    `${s.file}${s.mode === 'run' ? `   frame ${s.frame + 1} of ${s.frames}, t = ${Number(s.time).toPrecision(4)}` : ''}\n` +
    `${s.tets} tets, ${s.vertices} vertices, ${s.triangles} triangles drawn (${s.cut_triangles} cut, ` +
    `${view.worstTriangles} of the worst elements)\n` +
    `labels ${(s.labels || []).map((l) => (s.colour === 3 ? `${l} (${PALETTE_NAMES[labelIndex(l)]})` : l)).join(', ')}` +
    `${s.interfaces ? `; ${s.interfaces} faces between labels` : ''}\n` +
    `min dihedral ${f(s.min_dihedral, 1)} deg, ${s.slivers} slivers, ${invertedText(s)}\n` +
    `worst ${(s.worst || []).length} (magenta; ${s.worst_from}): tets ${(s.worst || []).slice(0, 10).join(' ')}` +
    (colourName ? `\ncolour ${colourName}: ${Number(s.scalar_lo).toPrecision(3)} .. ${Number(s.scalar_hi).toPrecision(3)}` : '');
  if (s.mode === 'run') {
    document.getElementById('frame-label').textContent = `frame ${s.frame + 1}/${s.frames}`;
    document.getElementById('frame').value = String(s.frame);
    plot();
  }
}
