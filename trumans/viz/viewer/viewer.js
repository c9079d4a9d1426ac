// The viewer page of `trumans view --html` (trumans/viz/html.py writes the data it reads).
// Axes: the data is in metres, z-up world (trumans' frame); three.js is y-up. Overlays live under a group
// rotated -90 deg about x, (x, y, z) -> (x, z, -y), the same turn as the .glb's root node.
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';

const CUT_HEIGHT = 1.1;      // m: static meshes are clipped above this while "cut walls" is on
const PATH_WIDTH = 0.04;     // m: the pelvis path ribbon on the floor (z = 0)
const PATH_Z = 0.01;         // m above the floor
const CONTACT_RADIUS = 0.05; // m
const GOAL_RADIUS = 0.06;    // m

const S = window.__trumans;
const report = window.__trumansReport;
const DATA = JSON.parse(document.getElementById('trumans-data').textContent);
const NJ = DATA.joint_names.length;
const PELVIS = DATA.joint_names.indexOf('pelvis');

function bytes(b64) {
  const s = atob(b64);
  const a = new Uint8Array(s.length);
  for (let i = 0; i < s.length; i++) a[i] = s.charCodeAt(i);
  return a;
}
function zupGroup() { const g = new THREE.Group(); g.rotation.x = -Math.PI / 2; return g; }
function labelColor(label) { return DATA.palette[label] ?? DATA.palette['']; }

// ---- renderer, camera, lights
const view = document.getElementById('view');
const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio || 1);
renderer.localClippingEnabled = true;
view.insertBefore(renderer.domElement, view.firstChild);
const scene = new THREE.Scene();
scene.background = new THREE.Color('#efece6');
scene.add(new THREE.HemisphereLight(0xffffff, 0x808080, 2.2));
const sun = new THREE.DirectionalLight(0xffffff, 1.5);
sun.position.set(4, 10, 7);
scene.add(sun);
const camera = new THREE.PerspectiveCamera(35, 1, 0.05, 1000);
const controls = new OrbitControls(camera, renderer.domElement);
const cutPlane = new THREE.Plane(new THREE.Vector3(0, -1, 0), CUT_HEIGHT);  // clips y > CUT_HEIGHT

// ---- one entry per sequence: its .glb, animation, overlays and timeline row
const loader = new GLTFLoader();
const seqs = [];

function pathRibbon(joints, T, colors) {
  // a flat strip along the pelvis path, one vertex pair per frame, coloured by the frame's action
  const pos = new Float32Array(T * 2 * 3), col = new Float32Array(T * 2 * 3), idx = [];
  let nx = 0, ny = 1;
  for (let f = 0; f < T; f++) {
    const a = Math.max(f - 1, 0), b = Math.min(f + 1, T - 1);
    const dx = joints[(b * NJ + PELVIS) * 3] - joints[(a * NJ + PELVIS) * 3];
    const dy = joints[(b * NJ + PELVIS) * 3 + 1] - joints[(a * NJ + PELVIS) * 3 + 1];
    const n = Math.hypot(dx, dy);
    if (n > 1e-6) { nx = -dy / n; ny = dx / n; }
    const x = joints[(f * NJ + PELVIS) * 3], y = joints[(f * NJ + PELVIS) * 3 + 1];
    for (let s = 0; s < 2; s++) {
      const k = (2 * f + s) * 3, h = (s ? 0.5 : -0.5) * PATH_WIDTH;
      pos[k] = x + h * nx; pos[k + 1] = y + h * ny; pos[k + 2] = PATH_Z;
      col[k] = colors[f].r; col[k + 1] = colors[f].g; col[k + 2] = colors[f].b;
    }
    if (f > 0) idx.push(2 * f - 2, 2 * f - 1, 2 * f, 2 * f - 1, 2 * f + 1, 2 * f);
  }
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.BufferAttribute(pos, 3));
  g.setAttribute('color', new THREE.BufferAttribute(col, 3));
  g.setIndex(idx);
  return new THREE.Mesh(g, new THREE.MeshBasicMaterial({ vertexColors: true, side: THREE.DoubleSide }));
}

async function addSequence(d, k) {
  const holder = new THREE.Group();
  holder.position.set(d.offset[0], d.offset[2], -d.offset[1]);
  scene.add(holder);
  const gltf = await loader.parseAsync(bytes(d.glb).buffer, '');
  holder.add(gltf.scene);
  gltf.scene.traverse((o) => {
    if (o.isMesh && o.material.name === 'static') o.material.clippingPlanes = [cutPlane];
  });
  let mixer = null, action = null;
  if (gltf.animations.length) {
    mixer = new THREE.AnimationMixer(gltf.scene);
    action = mixer.clipAction(gltf.animations[0]);
    action.setLoop(THREE.LoopOnce, 1);
    action.clampWhenFinished = true;
    action.play();
  }
  const T = d.frames;
  const joints = new Float32Array(bytes(d.joints).buffer);
  const contacts = d.contacts ? bytes(d.contacts) : null;
  // the label of every frame
  const frameLabel = new Array(T).fill('');
  for (const [s, e, lab] of d.segments) for (let f = s; f < e && f < T; f++) frameLabel[f] = lab;
  const overlay = zupGroup();
  holder.add(overlay);
  const path = pathRibbon(joints, T, frameLabel.map((l) => new THREE.Color(labelColor(l))));
  overlay.add(path);
  const here = new THREE.Mesh(new THREE.RingGeometry(0.1, 0.14, 32),
    new THREE.MeshBasicMaterial({ color: 0x333333, side: THREE.DoubleSide }));
  overlay.add(here);
  const contactMat = new THREE.MeshBasicMaterial({ color: 0xe8141c, transparent: true, opacity: 0.9, depthTest: false });
  const contactBalls = [];
  if (contacts) {
    const geo = new THREE.SphereGeometry(CONTACT_RADIUS, 16, 12);
    for (let j = 0; j < NJ; j++) {
      const m = new THREE.Mesh(geo, contactMat);
      m.renderOrder = 10; m.visible = false;
      overlay.add(m); contactBalls.push(m);
    }
  }
  const goals = d.goals.map(([f, x, y, z, joint]) => {
    const g = new THREE.Group();
    const ball = new THREE.Mesh(new THREE.SphereGeometry(GOAL_RADIUS, 16, 12),
      new THREE.MeshBasicMaterial({ color: 0x1a9e3a, transparent: true, opacity: 1 }));
    ball.position.set(x, y, z);
    const stem = new THREE.Line(new THREE.BufferGeometry().setFromPoints([new THREE.Vector3(x, y, 0), new THREE.Vector3(x, y, z)]),
      new THREE.LineBasicMaterial({ color: 0x1a9e3a }));
    g.add(ball, stem);
    overlay.add(g);
    return { frame: f, joint, ball };
  });
  seqs[k] = { d, T, holder, overlay, mixer, action, joints, contacts, frameLabel, path, here, contactBalls, goals,
              duration: (T - 1) / d.fps, frame: 0 };
}

// ---- time
let t = 0, playing = true, speed = 1, dirty = true;  // dirty: the view must be drawn again
const slider = document.getElementById('time'), clock = document.getElementById('clock');
const playBtn = document.getElementById('play'), speedSel = document.getElementById('speed');
slider.max = String(Math.max(DATA.duration, 1e-6));

function joint(s, f, j) {
  const i = (f * NJ + j) * 3;
  return new THREE.Vector3(s.joints[i], s.joints[i + 1], s.joints[i + 2]);
}

function apply(time) {
  dirty = true;
  t = Math.min(Math.max(time, 0), DATA.duration);
  for (const s of seqs) {
    const tl = Math.min(t, s.duration);
    if (s.mixer) {
      s.action.enabled = true; s.action.paused = false; s.action.time = tl;
      s.mixer.update(0);
    }
    const f = Math.min(s.T - 1, Math.round(tl * s.d.fps));
    s.frame = f;
    const p = joint(s, f, PELVIS);
    s.here.position.set(p.x, p.y, PATH_Z + 0.001);
    if (s.contacts) {
      for (let j = 0; j < NJ; j++) {
        const on = s.contacts[f * NJ + j] !== 0;
        s.contactBalls[j].visible = on;
        if (on) s.contactBalls[j].position.copy(joint(s, f, j));
      }
    }
    for (const g of s.goals) g.ball.material.opacity = g.frame >= f ? 1.0 : 0.25;
  }
  slider.value = String(t);
  clock.textContent = `${t.toFixed(2)} / ${DATA.duration.toFixed(2)} s`;
  for (const c of document.querySelectorAll('.cursor')) c.style.left = `${100 * t / Math.max(DATA.duration, 1e-9)}%`;
  seqs.forEach((s, k) => {
    const on = s.contacts ? DATA.joint_names.filter((_, j) => s.contacts[s.frame * NJ + j]) : [];
    document.getElementById(`name${k}`).textContent =
      `${s.d.title}: ${s.frameLabel[s.frame] || '-'}` + (on.length ? ` | contact: ${on.join(', ')}` : '');
  });
}

function setPlaying(p) { playing = p; playBtn.textContent = p ? 'Pause' : 'Play'; dirty = true; }

function hashParams() { return new URLSearchParams(location.hash.replace(/^#/, '')); }

// `size=WxH` in the URL hash: a fixed canvas size in CSS px (reproducible screenshots), else the window's
function fixedSize() {
  const m = /^(\d+)x(\d+)$/.exec(hashParams().get('size') || '');
  return m ? [Number(m[1]), Number(m[2])] : null;
}

function applyHash() {
  const h = hashParams();
  if (h.has('speed')) {
    const v = Number(h.get('speed'));
    if (v > 0) { speed = v; speedSel.value = String(v); }
  }
  if (h.has('t')) apply(Number(h.get('t')) || 0);
  setPlaying(!h.has('paused'));
}

// ---- timeline rows: one bar per sequence, its action segments laid out on the shared time axis
function buildTimeline() {
  const tl = document.getElementById('timeline');
  const D = Math.max(DATA.duration, 1e-9);
  seqs.forEach((s, k) => {
    const row = document.createElement('div'); row.className = 'row';
    const name = document.createElement('div'); name.className = 'name'; name.id = `name${k}`;
    const bar = document.createElement('div'); bar.className = 'bar';
    for (const [a, b, lab] of s.d.segments) {
      const seg = document.createElement('div'); seg.className = 'seg';
      const t0 = a / s.d.fps, t1 = Math.min(b / s.d.fps, D);
      seg.style.left = `${100 * t0 / D}%`; seg.style.width = `${100 * Math.max(t1 - t0, 0) / D}%`;
      seg.style.background = labelColor(lab);
      seg.textContent = lab; seg.title = `${lab || '(no action)'}: ${t0.toFixed(2)}-${t1.toFixed(2)} s`;
      bar.appendChild(seg);
    }
    const cur = document.createElement('div'); cur.className = 'cursor'; bar.appendChild(cur);
    bar.addEventListener('pointerdown', (e) => {
      const r = bar.getBoundingClientRect();
      apply(D * (e.clientX - r.left) / r.width);
    });
    row.append(name, bar); tl.appendChild(row);
  });
  const legend = document.getElementById('legend');
  for (const [lab, c] of Object.entries(DATA.palette)) {
    if (!lab) continue;
    const it = document.createElement('span');
    it.innerHTML = `<i style="background:${c}"></i>`;
    it.append(lab);
    legend.appendChild(it);
  }
  const h = 40 + 20 + 22 * seqs.length + 8;
  document.documentElement.style.setProperty('--panel-h', `${h}px`);
}

// ---- camera: look at everything from the front (-y of the z-up world), 50 deg above the horizon
function frameAll() {
  const box = new THREE.Box3();
  for (const s of seqs) {
    const [lo, hi] = s.d.bounds;
    box.expandByPoint(new THREE.Vector3(lo[0], lo[2], -hi[1]));
    box.expandByPoint(new THREE.Vector3(hi[0], 2.0, -lo[1]));  // 2 m up: a body; walls are cut lower
  }
  const c = box.getCenter(new THREE.Vector3());
  const dir = new THREE.Vector3(0, Math.sin(0.87), Math.cos(0.87));
  const corners = [];
  for (let i = 0; i < 8; i++) corners.push(new THREE.Vector3(i & 1 ? box.max.x : box.min.x, i & 2 ? box.max.y : box.min.y, i & 4 ? box.max.z : box.min.z));
  let lo = 0.1, hi = 1000;
  for (let it = 0; it < 40; it++) {  // the nearest distance at which every corner is inside 92% of the view
    const dist = 0.5 * (lo + hi);
    camera.position.copy(c).addScaledVector(dir, dist);
    camera.lookAt(c); camera.updateMatrixWorld();
    const fits = corners.every((p) => { const q = p.clone().project(camera); return q.z < 1 && Math.abs(q.x) <= 0.92 && Math.abs(q.y) <= 0.92; });
    if (fits) hi = dist; else lo = dist;
  }
  camera.position.copy(c).addScaledVector(dir, hi);
  controls.target.copy(c);
  controls.update();
}

function resize() {
  dirty = true;
  const [w, h] = fixedSize() ?? [view.clientWidth, view.clientHeight];
  renderer.setSize(w, h);
  camera.aspect = w / Math.max(h, 1);
  camera.updateProjectionMatrix();
}

// ---- status for scripts and tests: the time, the frames, what is shown, where the pelvis is on screen
const titles = document.getElementById('titles');
function updateStatus() {
  const w = renderer.domElement.clientWidth, h = renderer.domElement.clientHeight;
  camera.updateMatrixWorld();
  S.t = Number(t.toFixed(4)); S.playing = playing; S.speed = speed;
  S.frames = seqs.map((s) => s.frame);
  S.actions = seqs.map((s) => s.frameLabel[s.frame]);
  S.contacts = seqs.map((s) => (s.contacts ? DATA.joint_names.filter((_, j) => s.contacts[s.frame * NJ + j]) : []));
  S.pelvis_px = seqs.map((s) => {
    const p = s.overlay.localToWorld(joint(s, s.frame, PELVIS)).project(camera);
    return [Math.round((p.x + 1) / 2 * w), Math.round((1 - p.y) / 2 * h)];
  });
  S.goals = seqs.map((s) => s.goals.filter((g) => g.frame >= s.frame).length);  // goals still ahead
  S.canvas_px = [w, h];
  seqs.forEach((s, k) => {
    const [lo, hi] = s.d.bounds;
    const p = new THREE.Vector3(0.5 * (lo[0] + hi[0]), Math.max(hi[2], 2.0) + 0.3, -0.5 * (lo[1] + hi[1])).project(camera);
    const el = titles.children[k];
    el.style.left = `${(p.x + 1) / 2 * w}px`; el.style.top = `${(1 - p.y) / 2 * h}px`;
    el.style.display = p.z < 1 ? '' : 'none';
  });
  report();
}

// ---- main loop
// a frame is drawn only when something changed (playing, a seek, the camera moved, a resize): a paused
// page costs nothing, which matters in software-rendering (headless) browsers
let last = performance.now();
function loop(now) {
  const dt = Math.min(Math.max((now - last) / 1000, 0), 0.25);  // s; a rAF stamp may precede `last`
  last = now;
  if (playing) apply(t + dt * speed > DATA.duration ? 0 : t + dt * speed);
  if (dirty) {
    dirty = false;
    renderer.render(scene, camera);
    updateStatus();
  }
  requestAnimationFrame(loop);
}

async function main() {
  await Promise.all(DATA.sequences.map((d, k) => addSequence(d, k)));
  for (const s of seqs) {
    const el = document.createElement('div');
    el.textContent = s.d.title;
    titles.appendChild(el);
  }
  buildTimeline();
  resize();
  frameAll();
  apply(0);
  applyHash();
  controls.addEventListener('change', () => { dirty = true; });
  playBtn.addEventListener('click', () => setPlaying(!playing));
  speedSel.addEventListener('change', () => { speed = Number(speedSel.value); });
  slider.addEventListener('input', () => { setPlaying(false); apply(Number(slider.value)); });
  document.getElementById('cut').addEventListener('change', (e) => { cutPlane.constant = e.target.checked ? CUT_HEIGHT : 1e6; dirty = true; });
  document.getElementById('showpath').addEventListener('change', (e) => { for (const s of seqs) s.path.visible = e.target.checked; dirty = true; });
  let size = String(fixedSize());
  window.addEventListener('resize', () => { resize(); });
  window.addEventListener('hashchange', () => {
    if (String(fixedSize()) !== size) { size = String(fixedSize()); resize(); frameAll(); }
    applyHash();
  });
  window.addEventListener('keydown', (e) => {
    if (e.target.tagName === 'SELECT') return;
    const step = 1 / seqs[0].d.fps;
    if (e.code === 'Space') { setPlaying(!playing); e.preventDefault(); }
    else if (e.code === 'ArrowRight') { setPlaying(false); apply(t + step); e.preventDefault(); }
    else if (e.code === 'ArrowLeft') { setPlaying(false); apply(t - step); e.preventDefault(); }
  });
  renderer.render(scene, camera);
  S.ready = true;
  S.sequences = seqs.length;
  S.three = THREE.REVISION;
  S.duration = DATA.duration;
  updateStatus();
  requestAnimationFrame(loop);
}

main().catch((e) => { S.errors.push(String(e && e.stack || e)); report(); });
