// The page of `vis5d view` (src/cli/view.rs): draws the scene with
// three.js, flies the camera, and each frame asks the server which objects
// the loaded tree answers for the camera's view, hiding the rest.
//
// URL parameters: pos=x,y,z and dir=x,y,z place the camera; fly=x,y,z,dx,dy,dz;...
// flies those views one after the other (with check=1, each checked for
// popping) and writes what was drawn per frame into <pre id="log"> and
// window.vis5dFrames (the viewer's test reads them); tree=k picks a tree.

import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';

const $ = (id) => document.getElementById(id);
const params = new URLSearchParams(location.search);

function fail(message) {
  $('title').innerHTML = '';
  $('title').append('vis5d view: ' + message);
  $('title').className = 'warn';
  $('log').textContent = JSON.stringify({ error: String(message) });
  document.title = 'vis5d view: failed';
}
window.addEventListener('error', (e) => fail(e.message));
window.addEventListener('unhandledrejection', (e) => fail(e.reason));

async function getJson(url) {
  const r = await fetch(url);
  if (!r.ok) throw new Error(url + ': ' + r.status + ' ' + (await r.text()));
  return r.json();
}

const info = await getJson('/api/info');
const count = info.objects.length;
const up = new THREE.Vector3(...info.up);
const bounds = new THREE.Box3(new THREE.Vector3(...info.bounds.min), new THREE.Vector3(...info.bounds.max));
const diag = bounds.min.distanceTo(bounds.max) || 1;

// Renderer, scene, lights.
const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio);
renderer.setSize(window.innerWidth, window.innerHeight, false);
document.body.prepend(renderer.domElement);
const scene = new THREE.Scene();
const sky = new THREE.Color(0xdde4ea);
scene.background = sky;
const hemi = new THREE.HemisphereLight(0xffffff, 0x8a8f85, 2.4);
hemi.position.copy(up);
scene.add(hemi);
const sun = new THREE.DirectionalLight(0xffffff, 1.4);
sun.position.copy(up).multiplyScalar(3).add(new THREE.Vector3(1, 0.6, 0.8));
scene.add(sun);

const camera = new THREE.PerspectiveCamera(60, window.innerWidth / window.innerHeight,
  Math.max(diag * 1e-5, 1e-3), diag * 4);
camera.up.copy(up);

// The scene: node i of the glb is object i (its extras hold the index).
const gltf = await new GLTFLoader().loadAsync('/api/scene.glb');
scene.add(gltf.scene);
const meshes = new Array(count).fill(null);
gltf.scene.traverse((o) => {
  if (o.isMesh && Number.isInteger(o.userData.index)) meshes[o.userData.index] = o;
});
const shade = [];
const idMaterial = [];
const red = new THREE.MeshBasicMaterial({ color: 0xff0000, side: THREE.DoubleSide });
for (let i = 0; i < count; i++) {
  const m = meshes[i];
  const color = new THREE.Color().setHSL((i * 0.6180339887) % 1, 0.32 + 0.18 * (i % 3) / 2, 0.52 + 0.16 * (i % 5) / 4);
  shade.push(new THREE.MeshLambertMaterial({ color, side: THREE.DoubleSide }));
  const id = i + 1;
  idMaterial.push(new THREE.MeshBasicMaterial({
    color: new THREE.Color().setRGB((id & 255) / 255, ((id >> 8) & 255) / 255, ((id >> 16) & 255) / 255,
      THREE.LinearSRGBColorSpace),
    side: THREE.DoubleSide,
  }));
  if (m) {
    m.geometry.computeVertexNormals();
    m.material = shade[i];
  }
}

// The camera's place: from the URL, else the middle of the first tree's
// view box (or of the scene), looking along the longer horizontal axis.
const upAxis = info.up.findIndex((c) => c !== 0);
const start = (info.pvs[0] ? new THREE.Box3(new THREE.Vector3(...info.pvs[0].view_box.min),
  new THREE.Vector3(...info.pvs[0].view_box.max)) : bounds).getCenter(new THREE.Vector3());
const forward = new THREE.Vector3();
{
  const size = bounds.getSize(new THREE.Vector3());
  const a = (upAxis + 1) % 3, b = (upAxis + 2) % 3;
  forward.setComponent(size.getComponent(a) >= size.getComponent(b) ? a : b, 1);
}
const vec = (s) => {
  const v = (s || '').split(',').map(Number);
  return v.length === 3 && v.every(Number.isFinite) ? new THREE.Vector3(...v) : null;
};
camera.position.copy(vec(params.get('pos')) || start);
forward.copy(vec(params.get('dir')) || forward).normalize();

// The canvas fills the page (headless browsers settle the page's size
// after the script starts, so it is checked before each render).
function fit() {
  const w = renderer.domElement.clientWidth, h = renderer.domElement.clientHeight;
  const size = renderer.getSize(new THREE.Vector2());
  if (w > 0 && h > 0 && (size.x !== w || size.y !== h)) {
    renderer.setSize(w, h, false);
    camera.aspect = w / h;
    camera.updateProjectionMatrix();
  }
}

function aim() {
  fit();
  // Everything in front stays in the frustum, however far the camera flies.
  const far = Math.max(diag * 4, 1.05 * Math.max(...[0, 1, 2, 3, 4, 5, 6, 7].map((k) => camera.position.distanceTo(
    new THREE.Vector3(k & 1 ? bounds.max.x : bounds.min.x, k & 2 ? bounds.max.y : bounds.min.y,
      k & 4 ? bounds.max.z : bounds.min.z)))));
  if (far !== camera.far) {
    camera.far = far;
    camera.updateProjectionMatrix();
  }
  camera.up.copy(Math.abs(forward.dot(up)) > 0.999999 ? new THREE.Vector3().crossVectors(rightOf(forward), forward) : up);
  camera.lookAt(camera.position.clone().add(forward));
  camera.updateMatrixWorld();
}
aim();

// The tree list.
let tree = Math.min(Math.max(Math.trunc(Number(params.get('tree'))) || 0, 0), Math.max(info.pvs.length - 1, 0));
for (const [k, t] of info.pvs.entries()) {
  const o = document.createElement('option');
  o.value = k;
  o.textContent = t.name.split('/').pop() + (t.conservative ? ' (conservative)' : '');
  $('tree').append(o);
}
$('tree').value = tree;
if (info.pvs.length === 0) {
  $('tree').hidden = true;
  $('tree-note').textContent = 'none: start with --pvs FILE.v5d to cull';
}

// What a view's answer does to the page.
const fmt = (x) => x.toLocaleString('en');
const pct = (a, b) => (b ? (100 * a / b).toFixed(1) : '0') + '%';
let inSet = new Uint8Array(count).fill(1);
let lastLeaf;
const cellBox = new THREE.Box3Helper(new THREE.Box3(), 0x1b4fd8);
cellBox.visible = false;
scene.add(cellBox);

// The camera's right: across the forward direction and the scene's up, or
// (looking straight along up) across another axis.
function rightOf(f) {
  const r = new THREE.Vector3().crossVectors(f, up);
  if (r.lengthSq() < 1e-12) r.crossVectors(f, new THREE.Vector3(up.z, up.x, up.y));
  return r.normalize();
}

function pose() {
  const right = rightOf(forward);
  const camUp = new THREE.Vector3().crossVectors(right, forward).normalize();
  return { pos: camera.position.clone(), dir: forward.clone(), up: camUp, fov: camera.fov, aspect: camera.aspect };
}
// (A '+' of an exponent would read as a space in a query string.)
const xyz = (v) => `${v.x},${v.y},${v.z}`.replace(/\+/g, '%2B');
const queryUrl = (p) => `/api/query?pos=${xyz(p.pos)}&dir=${xyz(p.dir)}&up=${xyz(p.up)}` +
  `&fov=${p.fov}&aspect=${p.aspect}&pvs=${tree}`;

function apply(answer) {
  inSet = new Uint8Array(count);
  for (const i of answer.visible) inSet[i] = 1;
  const all = $('all').checked;
  for (let i = 0; i < count; i++) {
    if (!meshes[i]) continue;
    meshes[i].visible = all || inSet[i] === 1;
    meshes[i].material = shade[i];
  }
  $('objects').textContent = `${fmt(answer.visible.length)} of ${fmt(count)} (${pct(answer.visible.length, count)})`;
  $('triangles').textContent = `${fmt(answer.triangles)} of ${fmt(info.triangles)} (${pct(answer.triangles, info.triangles)})`;
  $('leaf').textContent = answer.leaf === null ? 'none' : answer.leaf;
  $('where').textContent = answer.answer === 'everything'
    ? 'outside the view box: every object in the frustum' : '';
}

async function showCell(p, leaf) {
  if (leaf === lastLeaf) return;
  lastLeaf = leaf;
  if (leaf === null) {
    cellBox.visible = false;
    return;
  }
  const c = await getJson(`/api/cell?pos=${xyz(p.pos)}&dir=${xyz(p.dir)}&pvs=${tree}`);
  if (c.leaf === null) return;
  cellBox.box.set(new THREE.Vector3(...c.min), new THREE.Vector3(...c.max));
  cellBox.visible = $('cellbox').checked;
}

// The popping check: every object drawn in its id colour from the pose
// the answer is for; objects seen there that the set lacks turn red.
const target = new THREE.WebGLRenderTarget(1, 1);
let pixels = new Uint8Array(4);
function check(p) {
  const size = renderer.getDrawingBufferSize(new THREE.Vector2());
  const w = Math.min(size.x, 1024), h = Math.max(1, Math.round(size.y * w / size.x));
  if (target.width !== w || target.height !== h) {
    target.setSize(w, h);
    pixels = new Uint8Array(4 * w * h);
  }
  const cam = camera.clone();
  cam.position.copy(p.pos);
  cam.lookAt(p.pos.clone().add(p.dir));
  cam.updateMatrixWorld();
  const saved = meshes.map((m) => m && m.visible);
  for (let i = 0; i < count; i++) {
    if (meshes[i]) {
      meshes[i].visible = true;
      meshes[i].material = idMaterial[i];
    }
  }
  const boxShown = cellBox.visible;
  cellBox.visible = false;
  scene.background = null;
  renderer.setClearColor(0x000000, 0);
  renderer.setRenderTarget(target);
  renderer.clear();
  renderer.render(scene, cam);
  renderer.readRenderTargetPixels(target, 0, 0, w, h, pixels);
  renderer.setRenderTarget(null);
  scene.background = sky;
  cellBox.visible = boxShown;
  const seen = new Map();
  for (let k = 0; k < pixels.length; k += 4) {
    const id = pixels[k] | (pixels[k + 1] << 8) | (pixels[k + 2] << 16);
    if (id > 0 && id <= count) seen.set(id - 1, (seen.get(id - 1) || 0) + 1);
  }
  const missing = [];
  let missingPixels = 0;
  for (let i = 0; i < count; i++) {
    if (!meshes[i]) continue;
    meshes[i].material = shade[i];
    meshes[i].visible = saved[i];
    if (seen.has(i) && !inSet[i]) {
      missing.push(i);
      missingPixels += seen.get(i);
      meshes[i].material = red;
      meshes[i].visible = true;
    }
  }
  let hiddenDrawn = 0;
  for (let i = 0; i < count; i++) if (inSet[i] && !seen.has(i)) hiddenDrawn++;
  $('popping').innerHTML = '';
  $('popping').className = missing.length ? 'warn' : 'dim';
  $('popping').append(missing.length
    ? `popping: ${missing.length} visible objects missing from the set (${fmt(missingPixels)} of ${fmt(w * h)} pixels, red)`
    : `no popping: every one of the ${seen.size} objects seen is in the set`);
  $('popping').append(document.createElement('br'),
    `${hiddenDrawn} objects of the set are hidden in this view`);
  return { seen: seen.size, seenPixels: [...seen].sort((a, b) => a[0] - b[0]), missing, missingPixels,
    hiddenDrawn, width: w, height: h };
}

// One query for a pose, applied.
async function answerFor(p) {
  const answer = await getJson(queryUrl(p));
  if ($('title').className === 'warn') {
    $('title').className = '';
    $('title').textContent = 'vis5d view: ' + info.scene.split('/').pop();
  }
  apply(answer);
  showCell(p, answer.leaf).catch(fail);
  const result = { answer };
  if ($('check').checked) result.check = check(p);
  return result;
}

const drawn = () => meshes.flatMap((m, i) => (m && m.visible && m.material !== red ? [i] : []));

// Scripted flight (tests, screenshots): each view in turn, then the log.
if (params.has('fly')) {
  $('check').checked = params.get('check') === '1';
  $('title').textContent = 'vis5d view: ' + info.scene.split('/').pop();
  const frames = [];
  const views = params.get('fly').split(';').filter((s) => s.trim());
  for (const [k, s] of views.entries()) {
    const v = s.split(',').map(Number);
    if (v.length !== 6 || !v.every(Number.isFinite)) throw new Error(`fly: view ${k} is not x,y,z,dx,dy,dz`);
    camera.position.set(v[0], v[1], v[2]);
    forward.set(v[3], v[4], v[5]).normalize();
    aim();
    const frame = { frame: k };
    if (info.pvs.length) {
      const p = pose();
      const r = await answerFor(p);
      Object.assign(frame, { url: queryUrl(p), leaf: r.answer.leaf, answer: r.answer.answer, set: r.answer.visible.length,
        triangles: r.answer.triangles, drawn: drawn() });
      if (r.check) Object.assign(frame, r.check);
    }
    renderer.render(scene, camera);
    frames.push(frame);
  }
  window.vis5dFrames = frames;
  $('log').textContent = JSON.stringify(frames);
  document.title = 'vis5d view: flown';
} else {
  interactive();
}

function interactive() {
  $('title').textContent = 'vis5d view: ' + info.scene.split('/').pop();
  const keys = new Set();
  let speed = diag / 25;
  window.addEventListener('keydown', (e) => {
    if (e.target.tagName === 'SELECT') return;
    keys.add(e.code);
    if (e.code === 'KeyC') { $('check').checked = !$('check').checked; requery(); }
    if (e.code === 'KeyB') { $('cellbox').checked = !$('cellbox').checked; cellBox.visible = $('cellbox').checked && lastLeaf !== null && lastLeaf !== undefined; }
    if (e.code === 'KeyV') { $('all').checked = !$('all').checked; requery(); }
    if (e.code === 'KeyT' && info.pvs.length > 1) { tree = (tree + 1) % info.pvs.length; $('tree').value = tree; requery(); }
  });
  window.addEventListener('keyup', (e) => keys.delete(e.code));
  window.addEventListener('blur', () => keys.clear());
  $('tree').addEventListener('change', () => { tree = Number($('tree').value); requery(); });
  for (const id of ['check', 'all']) $(id).addEventListener('change', requery);
  $('cellbox').addEventListener('change', () => { cellBox.visible = $('cellbox').checked && lastLeaf != null; });
  window.addEventListener('wheel', (e) => { speed *= e.deltaY > 0 ? 0.8 : 1.25; }, { passive: true });
  let dragging = null;
  renderer.domElement.addEventListener('pointerdown', (e) => { dragging = [e.clientX, e.clientY]; renderer.domElement.setPointerCapture(e.pointerId); });
  renderer.domElement.addEventListener('pointerup', () => { dragging = null; });
  renderer.domElement.addEventListener('pointermove', (e) => {
    if (!dragging) return;
    const [dx, dy] = [e.clientX - dragging[0], e.clientY - dragging[1]];
    dragging = [e.clientX, e.clientY];
    forward.applyAxisAngle(up, -dx * 0.004);
    const turned = forward.clone().applyAxisAngle(rightOf(forward), -dy * 0.004);
    // Never over the top; a step away from straight up or down always goes.
    const steep = (v) => Math.abs(v.dot(up));
    if (steep(turned) < 0.995 || steep(turned) < steep(forward)) forward.copy(turned);
    forward.normalize();
  });

  let busy = false;
  let asked = '';
  function requery() { asked = ''; lastLeaf = undefined; }
  if (info.pvs.length === 0) {
    $('objects').textContent = `${fmt(count)} of ${fmt(count)}`;
    $('triangles').textContent = `${fmt(info.triangles)} of ${fmt(info.triangles)}`;
  }
  let last = performance.now();
  function frame(now) {
    const dt = Math.min((now - last) / 1000, 0.1);
    last = now;
    const right = rightOf(forward);
    const move = new THREE.Vector3();
    const k = (a, b) => (keys.has(a) || keys.has(b) ? 1 : 0);
    move.addScaledVector(forward, k('KeyW', 'ArrowUp') - k('KeyS', 'ArrowDown'));
    move.addScaledVector(right, k('KeyD', 'ArrowRight') - k('KeyA', 'ArrowLeft'));
    move.addScaledVector(up, k('KeyE', 'PageUp') - k('KeyQ', 'PageDown'));
    const fast = keys.has('ShiftLeft') || keys.has('ShiftRight') ? 4 : 1;
    if (move.lengthSq() > 0) camera.position.addScaledVector(move.normalize(), speed * fast * dt);
    aim();
    const p = pose();
    const key = queryUrl(p) + $('check').checked + $('all').checked;
    if (info.pvs.length && !busy && key !== asked) {
      busy = true;
      asked = key;
      answerFor(p).catch(fail).finally(() => { busy = false; });
    }
    renderer.render(scene, camera);
    requestAnimationFrame(frame);
  }
  requestAnimationFrame(frame);
}
