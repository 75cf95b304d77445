// shprobe view --grid: the probe-grid page. Every number comes from the server (the shprobe
// library): the probes' irradiance coefficients E_lm = Â_l L_lm (summed per pixel by the
// library's generated GLSL, R&H 2001 eq. 7) and the object's per-vertex irradiance
// (ProbeGrid.irradiance, leak control on or off). The page only draws.
import * as THREE from 'three';  // the parts of three.js the pages use (tools/js/entry.js)
import { unpack } from './wire.js';
import { OrbitControls } from 'three';

const $ = (id) => document.getElementById(id);
const api = window.__shprobe = { lastError: null };  // exposed for tests
window.addEventListener('error', (e) => { api.lastError = String(e.message || e); });
const W = 720, H = 540;
const DOUBLE_SIDE = 2;  // three.js's DoubleSide (a constant the bundle does not export)
const ROW = 256;        // probes per row of the coefficient texture

// ------------------------------------------------------------------ server calls
async function call(path, opts = {}) {
  const r = await fetch(path, opts);
  const type = r.headers.get('content-type') || '';
  if (!r.ok) {
    let msg = `${r.status} ${r.statusText}`;
    if (type.includes('json')) msg = (await r.json()).error || msg;
    throw new Error(msg);
  }
  return unpack(await r.arrayBuffer());
}
function showError(e) {
  const el = $('error');
  el.textContent = String(e && e.message ? e.message : e);
  el.hidden = false;
  api.lastError = el.textContent;
}

// ------------------------------------------------------------------ shaders
const COMMON = `const float PI = 3.141592653589793;
out vec4 fragColor;
vec3 srgb(vec3 v) { v = clamp(v, 0.0, 1.0);
  return mix(12.92 * v, 1.055 * pow(v, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), v)); }
`;
function probeMaterial(glsl, K) {
  // the library's E(n) with its uniform array made a global, filled per fragment from the
  // probe's row of the coefficient texture
  const fn = glsl.replace(/uniform vec3 SHPROBE_E\[(\d+)\];/, 'vec3 SHPROBE_E[$1];');
  return new THREE.ShaderMaterial({
    glslVersion: THREE.GLSL3,
    uniforms: { uE: { value: null }, uRadius: { value: 0.1 }, uExposure: { value: 0 } },
    defines: { K, ROW },
    vertexShader: `in float probe; in vec3 centre; uniform float uRadius;
      flat out int vProbe; out vec3 vN;
      void main() { vProbe = int(probe + 0.5); vN = normal;
        gl_Position = projectionMatrix * modelViewMatrix * vec4(centre + uRadius * normal, 1.0); }`,
    fragmentShader: COMMON + fn + `
      uniform sampler2D uE; uniform float uExposure; flat in int vProbe; in vec3 vN;
      void main() {
        for (int k = 0; k < K; k++)
          SHPROBE_E[k] = texelFetch(uE, ivec2((vProbe % ROW) * K + k, vProbe / ROW), 0).rgb;
        vec3 e = max(shprobe_irradiance_sh(normalize(vN)), 0.0);  // clamped as the engines do
        fragColor = vec4(srgb(e / PI * exp2(uExposure)), 1.0);
      }`,
  });
}
function objectMaterial() {  // albedo · E/π, E the library's per-vertex irradiance
  return new THREE.ShaderMaterial({
    glslVersion: THREE.GLSL3,
    uniforms: { uExposure: { value: 0 } },
    vertexShader: `in vec3 albedo; in vec3 irradiance; out vec3 vC;
      void main() { vC = albedo * irradiance;
        gl_Position = projectionMatrix * modelViewMatrix * vec4(position, 1.0); }`,
    fragmentShader: COMMON + `uniform float uExposure; in vec3 vC;
      void main() { fragColor = vec4(srgb(vC / PI * exp2(uExposure)), 1.0); }`,
  });
}
function lineMaterial(rgb) {  // edges drawn as wireframe of (a, b, b) triangles
  return new THREE.ShaderMaterial({
    glslVersion: THREE.GLSL3, wireframe: true,
    uniforms: { uScale: { value: 1 } },
    vertexShader: `in vec3 offset; uniform float uScale;
      void main() { gl_Position = projectionMatrix * modelViewMatrix * vec4(position + uScale * offset, 1.0); }`,
    fragmentShader: `out vec4 fragColor; void main() { fragColor = vec4(${rgb.join(', ')}, 1.0); }`,
  });
}
function sceneMaterial() {  // the bake scene, translucent so that the probes inside show
  return new THREE.ShaderMaterial({
    glslVersion: THREE.GLSL3, transparent: true, depthWrite: false, side: DOUBLE_SIDE,
    vertexShader: `out vec3 vN; void main() { vN = normal;
        gl_Position = projectionMatrix * modelViewMatrix * vec4(position, 1.0); }`,
    fragmentShader: `out vec4 fragColor; in vec3 vN;
      void main() { float g = 0.45 + 0.25 * abs(normalize(vN).y); fragColor = vec4(vec3(g), 0.22); }`,
  });
}

// ------------------------------------------------------------------ geometry
function attr(g, name, data, k) { g.setAttribute(name, new THREE.BufferAttribute(data, k)); }
function probeSpheres(pos, n, seg, rings) {  // one UV sphere per probe, merged
  const vs = (seg + 1) * (rings + 1), is = seg * rings * 6;
  const centre = new Float32Array(n * vs * 3), normal = new Float32Array(n * vs * 3);
  const probe = new Float32Array(n * vs), index = new Uint32Array(n * is);
  const unit = [];
  for (let r = 0; r <= rings; r++) {
    const th = Math.PI * r / rings;
    for (let s = 0; s <= seg; s++) {
      const ph = 2 * Math.PI * s / seg;
      unit.push([Math.sin(th) * Math.cos(ph), Math.cos(th), Math.sin(th) * Math.sin(ph)]);
    }
  }
  for (let p = 0; p < n; p++) {
    for (let v = 0; v < vs; v++) {
      const o = (p * vs + v) * 3;
      for (let a = 0; a < 3; a++) { centre[o + a] = pos[3 * p + a]; normal[o + a] = unit[v][a]; }
      probe[p * vs + v] = p;
    }
    let o = p * is;
    for (let r = 0; r < rings; r++) {
      for (let s = 0; s < seg; s++) {
        const a = p * vs + r * (seg + 1) + s, b = a + seg + 1;
        index.set([a, a + 1, b, a + 1, b + 1, b], o); o += 6;  // counter-clockwise from outside
      }
    }
  }
  const g = new THREE.BufferGeometry();
  attr(g, 'position', centre, 3); attr(g, 'centre', centre, 3); attr(g, 'normal', normal, 3);
  attr(g, 'probe', probe, 1); g.setIndex(new THREE.BufferAttribute(index, 1));
  g.userData.indicesPerSphere = is;
  return g;
}
function edges(points, offsets, pairs) {  // segments as degenerate triangles (a, b, b)
  const g = new THREE.BufferGeometry();
  attr(g, 'position', new Float32Array(points), 3);
  attr(g, 'offset', new Float32Array(offsets || points.map(() => 0)), 3);
  const idx = [];
  for (const [a, b] of pairs) idx.push(a, b, b);
  g.setIndex(new THREE.BufferAttribute(new Uint32Array(idx), 1));
  return g;
}
function boxEdges(lo, hi) {
  const pts = [];
  for (let i = 0; i < 8; i++) pts.push(i & 1 ? hi[0] : lo[0], i & 2 ? hi[1] : lo[1], i & 4 ? hi[2] : lo[2]);
  const pairs = [];
  for (let i = 0; i < 8; i++) for (const bit of [1, 2, 4]) if (!(i & bit)) pairs.push([i, i | bit]);
  return edges(pts, null, pairs);
}
function cages(pos, which) {  // an octahedron around each marked probe (its size: uScale)
  const pts = [], off = [], pairs = [];
  const dirs = [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]];
  for (const p of which) {
    const b = pts.length / 3;
    for (const d of dirs) { pts.push(pos[3 * p], pos[3 * p + 1], pos[3 * p + 2]); off.push(...d); }
    for (const [i, j] of [[0, 2], [0, 3], [0, 4], [0, 5], [1, 2], [1, 3], [1, 4], [1, 5], [2, 4], [2, 5], [3, 4], [3, 5]]) pairs.push([b + i, b + j]);
  }
  return edges(pts, off, pairs);
}
function meshGeometry(pos, nrm, idx, extra) {
  const g = new THREE.BufferGeometry();
  attr(g, 'position', new Float32Array(pos), 3); attr(g, 'normal', new Float32Array(nrm), 3);
  for (const [k, v] of Object.entries(extra || {})) attr(g, k, v, 3);
  g.setIndex(new THREE.BufferAttribute(new Uint32Array(idx), 1));
  return g;
}

// ------------------------------------------------------------------ the page
let renderer, scene, camera, controls, data, head;
let probes, probeMat, objMesh, objMat, boxMesh, sceneMesh, cageMesh, moveMesh;
const place = { position: [0, 0, 0], size: 1, leak_control: true };

function draw() {
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
      $('objmean').textContent = r.head.mean.map((v) => v.toPrecision(4)).join(', ')
        + (r.head.leak_control ? ' (leak control on)' : ' (plain trilinear)');
      $('shadeinfo').textContent = `${objMesh.geometry.getAttribute('position').count} vertices lit by the library in ${r.head.ms.toFixed(1)} ms`;
      $('error').hidden = true;
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
api.state = () => ({
  probesDrawn: probes.visible ? probes.geometry.index.count / probes.geometry.userData.indicesPerSphere : 0,
  probes: head.probes, exposure: exposure(), radius: probeMat.uniforms.uRadius.value,
  eye: camera.position.toArray(), placement: structuredClone(place),
  leakControl: $('leak').checked, hasDepth: head.has_depth,
});

async function main() {
  renderer = new THREE.WebGLRenderer({ canvas: $('view'), antialias: false, preserveDrawingBuffer: true });
  renderer.setPixelRatio(1); renderer.setSize(W, H, false);
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
  camera.position.set(mid[0] + dist * 0.55, mid[1] + dist * 0.5, mid[2] + dist * 0.67);
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
  $('frameobj').addEventListener('click', () => frame(place.position, place.size / Math.sin(20 * Math.PI / 180) * 1.6));
  $('framevol').addEventListener('click', () => frame(mid, dist));
  gridInfo();
  dragObject();
  radiusCells($('radius').value);
  setExposure(autoExposure());
  placeObject();
  await api.settled();
  api.ready = true;
  api.readyMs = performance.now();
  $('status').textContent = `ready in ${api.readyMs.toFixed(0)} ms`;
}
main().catch((e) => { showError(e); });
