// shprobe view --grid: the probe-grid page. Every number comes from the server (the shprobe
// library): the probes' irradiance coefficients E_lm = Â_l L_lm (summed per pixel by the
// library's generated GLSL, R&H 2001 eq. 7) and the object's per-vertex irradiance
// (ProbeGrid.irradiance, leak control on or off). The page only draws.
import * as THREE from 'three';  // the parts of three.js the pages use (tools/js/entry.js)
import { OrbitControls } from 'three';
import { $, api, call, clearError, showError } from './api.js';
import { ROW, boxEdges, cages, edges, lineMaterial, meshGeometry, objectMaterial, probeMaterial,
  probeSpheres, sceneMaterial } from './gridscene.js';

window.addEventListener('error', (e) => { api.lastError = String(e.message || e); });
let W = 720, H = 540;  // the canvas's drawing buffer: its size on the page (fit())

// ------------------------------------------------------------------ the page
let renderer, scene, camera, controls, data, head;
let probes, probeMat, objMesh, objMat, boxMesh, sceneMesh, cageMesh, moveMesh;
const place = { position: [0, 0, 0], size: 1, leak_control: true };

// the drawing buffer follows the canvas's size on the page (CSS pixels one for one: the
// pointer and the tests' pixel reads map to it directly); → true when it changed
function fit() {
  const c = $('view'), w = Math.max(1, c.clientWidth), h = Math.max(1, c.clientHeight);
  if (w === W && h === H && renderer.domElement.width === w) return false;
  W = w; H = h; renderer.setSize(W, H, false);
  if (camera) { camera.aspect = W / H; camera.updateProjectionMatrix(); }
  return true;
}
new ResizeObserver(() => { if (renderer && fit() && scene) draw(); }).observe($('viewwrap'));
function draw() {
  if (!scene) return;
  renderer.render(scene, camera);
  api.frames = (api.frames || 0) + 1;
}
function exposure() { return Number($('exposure').value); }
function setExposure(v) {
  $('exposure').value = v; $('expval').textContent = Number(v).toFixed(2);
  probeMat.uniforms.uExposure.value = Number(v); objMat.uniforms.uExposure.value = Number(v);
  // the legend: E (albedo 1) at 0, ½ and 1 of the bar (sRGB values 0, 0.5, 1)
  const lin = (s) => (s <= 0.04045 ? s / 12.92 : ((s + 0.055) / 1.055) ** 2.4);
  const e = (s) => Math.PI * lin(s) * 2 ** -Number(v);
  $('tick1').textContent = `E = ${e(0.5).toPrecision(3)}`;
  $('tick2').textContent = `E = ${e(1).toPrecision(3)} (white)`;
  draw();
}
function autoExposure() {  // the brightest probe irradiance (the library's) maps to white
  const b = head.brightest;
  return b > 0 ? Math.floor(4 * Math.log2(Math.PI / b)) / 4 : 0;
}

// the object's shading: one request in flight, the latest placement next
let busy = false, again = false;
async function shade() {
  if (busy) { again = true; return; }
  busy = true;
  try {
    do {
      again = false;
      const body = JSON.stringify(place);
      const r = await call('/api/grid/shade', { method: 'POST', body });
      const a = objMesh.geometry.getAttribute('irradiance');
      a.array.set(r.irradiance); a.needsUpdate = true;
      api.lastShade = { ...r.head, request: JSON.parse(body) };
      api.objectIrradiance = Array.from(r.irradiance);
      // both settings, so that what leak control does shows without touching the toggle
      const rgb = (m) => `(${m.map((v) => v.toPrecision(3)).join(', ')})`;
      const on = r.head.leak_control, other = r.head.mean_other;
      $('objmean').textContent = other
        ? `leak control on ${rgb(on ? r.head.mean : other)} · off (plain trilinear) ${rgb(on ? other : r.head.mean)}; drawn: ${on ? 'on' : 'off'}`
        : `${rgb(r.head.mean)} (plain trilinear)`;
      $('shadeinfo').textContent = `${objMesh.geometry.getAttribute('position').count} vertices lit by the library in ${r.head.ms.toFixed(1)} ms`;
      clearError();
      draw();
    } while (again);
  } catch (e) { showError(e); }
  busy = false;
}
api.settled = () => new Promise((res) => {
  const poll = () => (busy || again ? setTimeout(poll, 10) : res(true)); poll();
});
function placeObject() {
  objMesh.position.set(...place.position); objMesh.scale.setScalar(place.size);
  draw(); shade();
}
api.setPlacement = (p) => { Object.assign(place, p); refreshSliders(); placeObject(); };

function sliders() {
  const [lo, hi] = head.bounds, box = $('possliders');
  const rows = [['X', 0], ['Y', 1], ['Z', 2]].map(([n, a]) => [n, lo[a], hi[a], () => place.position[a], (v) => { place.position[a] = v; }]);
  const minSp = Math.min(...head.spacing), ext = Math.min(...hi.map((h, a) => h - lo[a]));
  rows.push(['size', minSp * 0.05, ext / 2, () => place.size, (v) => { place.size = v; }]);
  for (const [name, a, b, get, set] of rows) {
    const lab = document.createElement('label'); lab.textContent = name === 'size' ? 'radius' : name;
    const inp = document.createElement('input');
    Object.assign(inp, { type: 'range', min: a, max: b, step: (b - a) / 400, value: get() });
    inp.id = `pos${name}`;
    const val = document.createElement('span');
    const show = () => { val.textContent = get().toFixed(3); };
    inp.addEventListener('input', () => { set(Number(inp.value)); show(); placeObject(); });
    inp.refresh = () => { inp.value = get(); show(); };
    show(); box.append(lab, inp, val);
  }
}
// shift-drag on the view: the object follows the pointer in the plane through it that faces
// the camera (clamped to the volume); the orbit controls rest meanwhile
function dragObject() {
  const canvas = $('view');
  let plane = null;
  const hit = (e) => {
    const r = canvas.getBoundingClientRect();
    const ndc = new THREE.Vector3((e.clientX - r.left) / r.width * 2 - 1, 1 - (e.clientY - r.top) / r.height * 2, 0.5);
    const d = ndc.unproject(camera).sub(camera.position).normalize();
    const t = plane.n.dot(plane.p.clone().sub(camera.position)) / plane.n.dot(d);
    return camera.position.clone().addScaledVector(d, t);
  };
  canvas.parentElement.addEventListener('pointerdown', (e) => {
    if (!e.shiftKey || e.target !== canvas) return;
    controls.enabled = false;
    const n = new THREE.Vector3(); camera.getWorldDirection(n);
    plane = { n, p: new THREE.Vector3(...place.position) };
    plane.off = plane.p.clone().sub(hit(e));
  }, true);
  window.addEventListener('pointermove', (e) => {
    if (!plane) return;
    const [lo, hi] = head.bounds, q = hit(e).add(plane.off);
    place.position = [0, 1, 2].map((a) => Math.min(hi[a], Math.max(lo[a], q.getComponent(a))));
    refreshSliders(); placeObject();
  });
  window.addEventListener('pointerup', () => { if (plane) { plane = null; controls.enabled = true; } });
}
function refreshSliders() { for (const n of ['X', 'Y', 'Z', 'size']) $(`pos${n}`).refresh(); }

function gridInfo() {
  const rows = [
    ['resolution', head.resolution.join(' × ') + ` (${head.probes} probes)`], ['lmax', head.lmax],
    ['bounds', head.bounds.map((c) => `(${c.map((v) => v.toFixed(3)).join(', ')})`).join(' – ')],
    ['cell size', head.spacing.map((v) => v.toFixed(3)).join(' × ')],
    ['invalid probes', head.invalid], ['relocated probes', head.relocated],
    ['depth data', head.has_depth ? 'yes (leak control available)' : 'no (plain trilinear only)'],
    ['brightest probe E', head.brightest.toPrecision(4)],
    ['scene', head.scene || '(none: --scene)'], ['object', head.object],
    // the bake settings, less what the rows above already give
    ...Object.entries(head.meta).filter(([k]) => !['lmax', 'moved', 'invalid'].includes(k))
      .map(([k, v]) => [['scene', 'object'].includes(k) ? `${k} (bake)` : k, Array.isArray(v) ? v.join(', ') : String(v)]),
  ];
  const t = $('gridinfo');
  for (const [k, v] of rows) {
    const tr = t.insertRow(), text = String(v);
    tr.insertCell().textContent = k;
    const td = tr.insertCell();
    td.textContent = text.length > 28 && !/\s/.test(text) ? `${text.slice(0, 12)}…${text.slice(-12)}` : text;
    td.title = text;  // a long word (a hash) whole on hover
  }
}

// the first view of a grid with depth data: the camera ``d`` from the object, on the side
// of the volume it is on, along the clearest line of sight (the farthest from every probe
// sphere), so that the object shows with the probes and walls around it
function firstView(d) {
  const o = new THREE.Vector3(...place.position), mid = controls.target.clone();
  const out = o.clone().sub(mid); out.y = 0;
  const r = probeMat.uniforms.uRadius.value, n = head.probes, pos = data.probe_position;
  let best = null;
  for (let a = 0; a < 24; a++) {
    for (const el of [15, 30, 45]) {
      const az = 2 * Math.PI * a / 24, e = el * Math.PI / 180;
      const dir = new THREE.Vector3(Math.cos(e) * Math.cos(az), Math.sin(e), Math.cos(e) * Math.sin(az));
      if (out.lengthSq() > 0 && dir.x * out.x + dir.z * out.z < 0) continue;  // the object's side
      let clear = Infinity;
      for (let p = 0; p < n; p++) {  // distance from each probe to the line of sight
        const q = new THREE.Vector3(pos[3 * p], pos[3 * p + 1], pos[3 * p + 2]).sub(o);
        const t = Math.min(Math.max(q.dot(dir), place.size), d);
        clear = Math.min(clear, q.distanceTo(dir.clone().multiplyScalar(t)) - r);
      }
      if (!best || clear > best.clear + 1e-9) best = { clear, dir };
    }
  }
  controls.target.copy(o);
  camera.position.copy(o).addScaledVector(best.dir, d);
  controls.update(); draw();
}

function radiusCells(v) {
  $('radval').textContent = Number(v).toFixed(2);
  const r = Number(v) * Math.min(...head.spacing);
  probeMat.uniforms.uRadius.value = r; cageMesh.material.uniforms.uScale.value = 1.5 * r;
  cageMesh.userData.moved.uniforms.uScale.value = 1.3 * r;
  draw();
}

// where probe i's sphere centre lands on the canvas (pixels from the top left) and the normal
// seen there (towards the eye), for tests
api.probeScreen = (i) => {
  const c = new THREE.Vector3(...Array.from(data.probe_position.slice(3 * i, 3 * i + 3)));
  const n = camera.position.clone().sub(c).normalize();
  const s = c.clone().project(camera);
  const x = Math.round((s.x + 1) / 2 * W - 0.5), y = Math.round((1 - s.y) / 2 * H - 0.5);
  // the normal of the (exact) sphere where the ray through that pixel's centre meets it
  const d = new THREE.Vector3((x + 0.5) / W * 2 - 1, 1 - (y + 0.5) / H * 2, 0.5).unproject(camera)
    .sub(camera.position).normalize();
  const oc = camera.position.clone().sub(c), b = oc.dot(d);
  const disc = b * b - oc.lengthSq() + probeMat.uniforms.uRadius.value ** 2;
  if (disc >= 0) n.copy(oc.addScaledVector(d, -b - Math.sqrt(disc))).normalize();
  return { x, y, normal: [n.x, n.y, n.z], depth: camera.position.distanceTo(c) };
};
api.objectScreen = () => {  // the object's centre on the canvas (pixels from the top left)
  const s = new THREE.Vector3(...place.position).project(camera);
  return { x: (s.x + 1) / 2 * W, y: (1 - s.y) / 2 * H };
};
api.readPixel = (x, y) => {  // (x, y) from the top left
  draw();
  const gl = renderer.getContext(), px = new Uint8Array(4);
  gl.readPixels(x, H - 1 - y, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px);
  return Array.from(px);
};
api.canvasSize = () => [W, H];
api.state = () => ({
  probesDrawn: probes.visible ? probes.geometry.index.count / probes.geometry.userData.indicesPerSphere : 0,
  probes: head.probes, exposure: exposure(), radius: probeMat.uniforms.uRadius.value,
  eye: camera.position.toArray(), placement: structuredClone(place),
  leakControl: $('leak').checked, hasDepth: head.has_depth,
});

async function main() {
  renderer = new THREE.WebGLRenderer({ canvas: $('view'), antialias: false, preserveDrawingBuffer: true });
  renderer.setPixelRatio(1); fit();
  renderer.outputColorSpace = THREE.LinearSRGBColorSpace;  // the shaders write sRGB themselves
  renderer.setClearColor(new THREE.Color(0.11, 0.12, 0.13), 1);
  data = await call('/api/grid');
  head = data.head; api.head = head;
  $('gridname').textContent = head.name; $('objname').textContent = head.object;
  scene = new THREE.Scene();
  const [lo, hi] = head.bounds, n = head.probes, K = (head.lmax + 1) ** 2;
  const mid = lo.map((v, a) => (v + hi[a]) / 2), rad = Math.hypot(...hi.map((h, a) => h - lo[a])) / 2;
  camera = new THREE.PerspectiveCamera(40, W / H, rad * 0.01, rad * 20);
  const dist = rad / Math.sin(20 * Math.PI / 180) * 0.9;  // the box, not its bounding sphere, fills the view
  // from above, on the side of the volume where the object starts (the server places it
  // where leak control matters: seen in front of the scene, not behind it)
  const side = (a) => (head.defaults.position[a] < mid[a] ? -1 : 1);
  camera.position.set(mid[0] + dist * 0.55 * side(0), mid[1] + dist * 0.5, mid[2] + dist * 0.67 * side(2));
  controls = new OrbitControls(camera, $('view'));
  controls.target.set(...mid); controls.update();
  controls.addEventListener('change', draw);

  // the probes: E_lm per probe in a float texture, K texels a probe, ROW probes a row
  const rows = Math.ceil(n / ROW), tex = new Float32Array(ROW * K * rows * 4);
  for (let p = 0; p < n; p++) {
    for (let k = 0; k < K; k++) {
      const o = (((p / ROW) | 0) * ROW * K + (p % ROW) * K + k) * 4;
      for (let c = 0; c < 3; c++) tex[o + c] = data.probe_e[(p * K + k) * 3 + c];
      tex[o + 3] = 1;
    }
  }
  const eTex = new THREE.DataTexture(tex, ROW * K, rows, THREE.RGBAFormat, THREE.FloatType);
  eTex.needsUpdate = true;
  probeMat = probeMaterial(head.glsl, K);
  probeMat.uniforms.uE.value = eTex;
  const [seg, rings] = n > 4096 ? [10, 6] : [24, 16];
  probes = new THREE.Mesh(probeSpheres(data.probe_position, n, seg, rings), probeMat);
  probes.frustumCulled = false;
  scene.add(probes);

  // marks: invalid probes caged, relocated probes tied to their cell centres
  const invalid = [], moved = [];
  for (let p = 0; p < n; p++) {
    if (data.validity[p] < 0.5) invalid.push(p);
    const d = [0, 1, 2].map((a) => data.probe_position[3 * p + a] - data.probe_centre[3 * p + a]);
    if (Math.hypot(...d) > 1e-6 * Math.min(...head.spacing)) moved.push(p);
  }
  cageMesh = new THREE.Mesh(cages(data.probe_position, invalid), lineMaterial([1.0, 0.3, 0.3]));
  const movedCages = new THREE.Mesh(cages(data.probe_position, moved), lineMaterial([0.95, 0.9, 0.25]));
  movedCages.frustumCulled = false;
  cageMesh.add(movedCages); cageMesh.userData.moved = movedCages.material;
  const mpts = [];
  moved.forEach((p) => mpts.push(...data.probe_centre.slice(3 * p, 3 * p + 3), ...data.probe_position.slice(3 * p, 3 * p + 3)));
  moveMesh = new THREE.Mesh(edges(mpts, null, moved.map((_, i) => [2 * i, 2 * i + 1])), lineMaterial([0.95, 0.9, 0.25]));
  boxMesh = new THREE.Mesh(boxEdges(lo, hi), lineMaterial([0.6, 0.6, 0.6]));
  for (const m of [cageMesh, moveMesh, boxMesh]) { m.frustumCulled = false; scene.add(m); }

  // the object, in its unit bounding sphere: placed by position and scale
  objMat = objectMaterial();
  const nv = data.object_position.length / 3;
  objMesh = new THREE.Mesh(meshGeometry(data.object_position, data.object_normal, data.object_index,
    { albedo: new Float32Array(data.object_albedo), irradiance: new Float32Array(nv * 3) }), objMat);
  objMesh.frustumCulled = false;
  scene.add(objMesh);
  if (data.scene_position) {
    sceneMesh = new THREE.Mesh(meshGeometry(data.scene_position, data.scene_normal, data.scene_index), sceneMaterial());
    sceneMesh.frustumCulled = false; sceneMesh.renderOrder = 1;
    scene.add(sceneMesh);
  } else { $('showscene').disabled = true; }

  // controls
  Object.assign(place, structuredClone(head.defaults));
  sliders();
  $('leak').checked = head.has_depth;
  $('leak').disabled = !head.has_depth;
  place.leak_control = head.has_depth;
  $('leaknote').textContent = head.has_depth
    ? 'on: each probe weighted by whether it sees the point (depth moments); off: three.js\'s plain trilinear blend'
    : 'this grid has no depth data: the interpolation is plain trilinear (three.js\'s LightProbeGrid sampling)';
  $('leak').addEventListener('change', () => { place.leak_control = $('leak').checked; shade(); });
  $('exposure').addEventListener('input', () => setExposure($('exposure').value));
  $('autoexp').addEventListener('click', () => setExposure(autoExposure()));
  $('radius').addEventListener('input', () => radiusCells($('radius').value));
  const vis = [['showprobes', [() => probes, () => cageMesh, () => moveMesh]], ['showbox', [() => boxMesh]],
    ['showscene', [() => sceneMesh]], ['showobject', [() => objMesh]]];
  for (const [id, objs] of vis) {
    $(id).addEventListener('change', () => { for (const o of objs) if (o()) o().visible = $(id).checked; draw(); });
  }
  // the camera framed on the volume, or brought to the object (same direction)
  const frame = (target, d) => {
    const dir = camera.position.clone().sub(controls.target).normalize();
    controls.target.set(...target); camera.position.copy(controls.target).addScaledVector(dir, d);
    controls.update(); draw();
  };
  const objDist = () => place.size / Math.sin(20 * Math.PI / 180) * 1.6;
  $('frameobj').addEventListener('click', () => frame(place.position, objDist()));
  $('framevol').addEventListener('click', () => frame(mid, dist));
  // the first view: the object and the probes and walls around it (a few cells), seen from
  // the volume's side it is on — where leak control on and off light it differently
  gridInfo();
  dragObject();
  radiusCells($('radius').value);
  if (head.has_depth) firstView(2.2 * place.size / Math.sin(20 * Math.PI / 180) * 1.6);
  setExposure(autoExposure());
  placeObject();
  await api.settled();
  api.ready = true;
  api.readyMs = performance.now();
  $('status').textContent = `ready in ${api.readyMs.toFixed(0)} ms`;
}
main().catch((e) => { showError(e); });
