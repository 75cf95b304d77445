// shprobe view: the designer page. Every number it shows comes from the server (the shprobe
// library); the page draws: per-pixel irradiance with shprobe's own GLSL (shaders.js), lookups
// of the library's irradiance tables by normal (compare.js), and PRT relighting (prt.js). This
// module holds the page's state (``P``), the design requests, the drawing and the start-up;
// api.js the server calls, history.js undo, rotation.js the maths, edits.js the controls,
// files.js uploads and exports.
import * as THREE from 'three';  // the parts of three.js this page uses (tools/js/entry.js)
import { $, api, call, clearError, finishFrame, first, setStatus, showError } from './api.js';
import { loadCompare, redrawHBasis, showLegend, updateHBasis } from './compare.js';
import { showForMode } from './controls.js';
import { Edits } from './edits.js';
import { exportFormat, loadBackground, probeLabel } from './files.js';
import { EMPTY, History } from './history.js';
import { loadTransfer, relightPRT } from './prt.js';
import { dragRotation, mul, rotateLow, stateRotation, toAxisAngle } from './rotation.js';
import { Programs, setE, srgbJS } from './shaders.js';
import { View3D, readLibraryView } from './view3d.js';

const t0 = performance.now();
api.marks = {};
const mark = (name) => { api.marks[name] = Math.round(performance.now()); };  // ms since navigation start

// the page: what its modules share
const P = {
  history: null, edits: null, programs: null,
  coeffs: null,      // current L_lm (K, 3) from the server
  irrE: null,        // its E_lm = Â_l L_lm (library, lighting.glsl.glsl_uniform_values)
  lastDesign: null, cmp: null, prt: null, bgTex: null, lookTex: {},
  renderer: null, scene: null, camera: null, view3d: null, meshObj: null, bgMesh: null, bgMat: null,
};
P.history = new History(() => { P.edits.refresh(); requestDesign(); updateHBasis(P); });
P.edits = new Edits(P);
Object.assign(P, {
  draw: () => draw(), requestDesign: () => requestDesign(), onMode: () => onMode(),
  setGeometry: (g, cam) => setGeometry(g, cam), showLegend: () => showLegend(P),
  updateHBasis: () => updateHBasis(P), loadTransfer: (m, b) => loadTransfer(P, m, b),
  blendOptions: (a, b) => P.edits.blendOptions(a, b), wirePRT: (t) => P.edits.wirePRT(t),
});
api.getState = () => structuredClone(P.history.state);
api.setState = (s) => P.history.commit({ ...structuredClone(EMPTY), ...structuredClone(s) });
api.rotationMatrix = () => stateRotation(P.history.state);
api.rotateInPage = (L, R) => rotateLow(L, R);
api.dragRotation = (dx, dy) => dragRotation(dx, dy, 512, 256);
api.exportFormat = (fmt) => exportFormat(P, fmt);

// ------------------------------------------------------------------ design (library, server)
function localDesign() {  // during a drag: the last server answer turned in the page
  const d = P.lastDesign, state = P.history.state;
  if (!d || !d.unrotated || d.unrotated.length > 9) return false;
  if (JSON.stringify({ ...d.state, rotation: null }) !== JSON.stringify({ ...state, rotation: null })) return false;
  let L = rotateLow(d.unrotated, stateRotation(state));
  const f = d.factors;
  if (f) L = L.map((c, k) => c.map((v) => v * f[Math.floor(Math.sqrt(k))]));
  P.coeffs = L; api.coeffs = L; api.localFrames = (api.localFrames || 0) + 1;
  draw();
  return true;
}
let designBusy = false, designAgain = false;
async function requestDesign() {
  if (designBusy) { designAgain = true; return; }
  designBusy = true;
  try {
    do {
      designAgain = false;
      const tc = performance.now();
      const sent = P.history.state, body = JSON.stringify(sent);
      const r = await first(`design:${body}`, () => call('/api/design', { method: 'POST', body }));
      api.lastDesignMs = performance.now() - tc;
      r.state = sent; P.lastDesign = r;
      // a stale answer (the drag moved on meanwhile) is turned to the current rotation
      if (JSON.stringify(P.history.state) === body || !localDesign()) { P.coeffs = r.coeffs; api.coeffs = r.coeffs; P.irrE = r.irradiance; }
      clearError();
      showDesign(r);
      draw();
    } while (designAgain);
  } catch (e) { showError(e); }
  designBusy = false;
}
api.settled = () => new Promise((res) => {   // resolves when no design request is pending
  const poll = () => (designBusy || designAgain ? setTimeout(poll, 10) : res(true)); poll();
});
function showDesign(r) {
  const m = r.min_e.map((v) => v.toPrecision(4)).join(', ');
  $('mine').textContent = `min E over the sphere = (${m}) [${r.min_exact ? 'certified' : 'numerical'}, ${r.min_method}]` + (r.window ? `; window ${r.window}` : '');
  $('cli').textContent = 'shprobe edit ' + JSON.stringify(r.source) + ' ' + r.cli.map((a) => (/^[\w.,:=+\-]+$/.test(a) ? a : JSON.stringify(a))).join(' ') + ' --format FMT -o FILE';
  const rot = P.history.state.rotation;
  $('rotinfo').textContent = rot ? `rotation ${rot.degrees.toFixed(1)}° about (${rot.axis.map((v) => v.toFixed(2)).join(', ')})` : 'no rotation';
}

// ------------------------------------------------------------------ drawing
let panel, panelScene, panelCam, probeMat, irrMats, irrMesh, panelRenderer2, irrScene;
function clearToGrey() {  // the background pass's colour without a probe texture, as a clear
  const g = srgbJS(0.18 * 2 ** Number($('exposure').value));
  P.renderer.setClearColor(new THREE.Color().setRGB(g, g, g, THREE.LinearSRGBColorSpace), 1);
}
const highLmax = () => !!(P.coeffs && P.coeffs.length > 9 && P.irrE);
const designLmax = () => (highLmax() ? Math.sqrt(P.coeffs.length) - 1 : 2);
function setLightingUniforms(u) {
  if (P.coeffs) for (let k = 0; k < 9; k++) {
    const c = P.coeffs[k] || [0, 0, 0]; u.SHPROBE_L.value[k].set(c[0], c[1], c[2]);
  }
  // above l = 2 there is no quadratic form: the generated function, with the library's E_lm
  if (highLmax()) setE(u, P.irrE, Math.sqrt(P.coeffs.length) - 1);
  u.uExposure.value = Number($('exposure').value);
  const R = stateRotation(P.history.state);  // R⁻¹ = Rᵀ: the rotated lighting at ω is the probe at R⁻¹ω
  u.uRotInv.value.set(R[0][0], R[1][0], R[2][0], R[0][1], R[1][1], R[2][1], R[0][2], R[1][2], R[2][2]);
  u.uBg.value = P.bgTex; u.uHasBg.value = P.bgTex ? 1 : 0;
}

const MODES = { design: 0, sh1: 1, sh2: 1, sh3: 1, sh4: 1, exact: 2, error: 3, prt: 4 };
const frameTimes = [];
let booting = true;  // until the first frame's data is in: one draw then, none before
let moveAt = null;  // when the last drag move arrived (for the move → frame time)
function draw() {
  if (!P.renderer || !P.coeffs || booting) return;
  const tf = performance.now();
  const mode = $('mode').value, pr = P.programs;
  if (mode === 'prt') relightPRT(P);
  const m = MODES[mode];
  if (P.meshObj) P.meshObj.material = pr.object(m === 4 ? 'prt' : m === 2 ? 'exact' : m === 3 ? 'error'
    : m === 1 ? 'sh' : pr.eKind(designLmax()));
  for (const u of [P.meshObj ? P.meshObj.material.uniforms : pr.obj, P.bgMat.uniforms]) setLightingUniforms(u);
  if (P.cmp && m === 1) setE(pr.obj, P.cmp.irradiance, Number(mode.slice(2)));
  if (P.cmp && m === 3) pr.obj.uA.value = P.lookTex['sh' + $('errlmax').value];
  if (P.cmp) { pr.obj.uRef.value = P.lookTex.reference; }
  cameraUniforms(P.camera);
  P.renderer.render(P.scene, P.camera);
  // benchmarks only (&bench=1): wait for the frame, so that the times below are of finished
  // frames; a normal session never reads back (a GPU stall every frame)
  finishFrame(P.renderer.getContext());
  api.mainFrameMs = performance.now() - tf;
  // the first lit frame: the object drawn with the lighting (the panels follow)
  if (!api.firstFrameMs && P.meshObj) { api.firstFrameMs = performance.now() - t0; api.firstFrameAt = Date.now(); }
  drawPanels();
  const dt = performance.now() - tf;
  if (moveAt !== null) { (api.moveToFrame = api.moveToFrame || []).push(performance.now() - moveAt); moveAt = null; }
  frameTimes.push(dt); if (frameTimes.length > 200) frameTimes.shift();
  api.frames = (api.frames || 0) + 1;
}
function cameraUniforms(cam) {  // the background pass seen from ``cam``
  cam.updateMatrixWorld();
  P.bgMat.uniforms.uInvVP.value.multiplyMatrices(cam.matrixWorld, cam.projectionMatrixInverse);
  P.bgMat.uniforms.uEye.value.setFromMatrixPosition(cam.matrixWorld);
  // until the probe's texture is here the background is the flat grey the pass would draw
  // (radiance 0.18, same tone mapping): a clear, not a full-screen pass
  P.bgMesh.visible = !!P.bgTex;
  if (!P.bgTex) clearToGrey();
}
function drawPanels() {  // the probe and the irradiance map (made after the first frame)
  if (!panel) return;
  irrMesh.material = irrMats[P.programs.eKind(designLmax())];
  setLightingUniforms(probeMat.uniforms); setLightingUniforms(irrMesh.material.uniforms);
  panel.render(panelScene, panelCam);
  panelRenderer2.render(irrScene, panelCam);
}
function makePanels() {  // two more WebGL contexts: after the object's first frame
  const pr = P.programs;
  panel = new THREE.WebGLRenderer({ canvas: $('probe'), antialias: false });
  panel.setPixelRatio(1); panel.setSize(512, 256, false); panel.outputColorSpace = THREE.LinearSRGBColorSpace;
  panelRenderer2 = new THREE.WebGLRenderer({ canvas: $('irrmap'), antialias: false });
  panelRenderer2.setPixelRatio(1); panelRenderer2.setSize(512, 256, false); panelRenderer2.outputColorSpace = THREE.LinearSRGBColorSpace;
  panelCam = new THREE.OrthographicCamera(-1, 1, 1, -1, 0, 1);
  probeMat = pr.panel('probe');
  const u = pr.uniforms();
  irrMats = { poly: pr.panel('poly', u), sh: pr.panel('sh', u), shd: pr.panel('shd', pr.uniforms(pr.designLmax)) };
  irrMesh = new THREE.Mesh(new THREE.PlaneGeometry(2, 2), irrMats.poly);
  panelScene = new THREE.Scene(); panelScene.add(new THREE.Mesh(new THREE.PlaneGeometry(2, 2), probeMat));
  irrScene = new THREE.Scene(); irrScene.add(irrMesh);
}
api.draw = draw;
api.frameTimes = () => frameTimes.slice();
// the object seen by the library's camera (shprobe.scene.Camera(512, 512) fitted to the
// object), 512×512 RGBA rows from the top, as the library's images: what the pixel tests
// compare with shprobe.scene.render (the view on screen is the orbit camera's); a read-back
// only a test asks for
function libraryView() {
  draw();
  const out = readLibraryView(P.renderer, P.scene, P.view3d.libraryCamera(), cameraUniforms);
  draw();
  return out;
}
api.readAll = () => {  // base64 of libraryView()
  const out = libraryView();
  return btoa(Array.from({ length: 512 }, (_, y) => String.fromCharCode.apply(null, out.subarray(y * 2048, (y + 1) * 2048))).join(''));
};
api.readPixel = (x, y) => Array.from(libraryView().subarray(4 * (512 * y + x), 4 * (512 * y + x) + 4));
api.cameraState = () => P.view3d.state();
api.resetView = () => P.view3d.reset();

function setGeometry(g, cam) {
  const geo = new THREE.BufferGeometry();
  geo.setAttribute('position', new THREE.BufferAttribute(g.position, 3));
  geo.setAttribute('normal', new THREE.BufferAttribute(g.normal, 3));
  const nv = g.position.length / 3;
  geo.setAttribute('albedo', new THREE.BufferAttribute(g.albedo || new Float32Array(nv * 3).fill(1), 3));
  geo.setAttribute('prtColor', new THREE.BufferAttribute(new Float32Array(nv * 3), 3));
  geo.setIndex(new THREE.BufferAttribute(g.index, 1));
  if (P.meshObj) { P.scene.remove(P.meshObj); P.meshObj.geometry.dispose(); }
  P.meshObj = new THREE.Mesh(geo, P.programs.object('poly'));  // draw() picks the view's program
  P.meshObj.frustumCulled = false;
  P.scene.add(P.meshObj);
  // the orbit camera starts from the server's view (the library Camera fitted to the
  // object's bounding sphere, above the horizon); the library's own camera is kept for reads
  P.view3d.frame(g.head.view || cam, cam);
  api.camera = cam; api.viewCamera = g.head.view || cam;
  api.objectBounds = { center: g.head.center, radius: g.head.radius, ground: g.head.ground_vertices || 0 };
}

// ------------------------------------------------------------------ views
const VIEW_LABELS = {
  design: "Object: radiance = albedo · E(n) / π per pixel, E from shprobe's GLSL (lmax ≤ 2: the export's R&H eq. 13; lmax 3–8: lighting.glsl's generated function; above 4, e.g. a PRT transfer's degree, with a second program to lmax 8)",
  sh: "Object: radiance = albedo · E(n) / π, E of the probe (edits not applied) truncated at this lmax, per pixel by shprobe's generated GLSL (lighting.glsl) with the library's E_lm = Â_l L_lm",
  exact: 'Object: radiance = albedo · E(n) / π, E the brute-force irradiance of the probe (library reference_irradiance, edits not applied), looked up by normal',
  error: 'Object: error of SH irradiance against the exact one per normal, on the heat scale below (% of ∫L dω)',
  hbasis: 'H-basis normal mapping: the panels below, each labelled',
  prt: 'Object: PRT exit radiance per vertex = transfer · rotated lighting (LH §4), computed in the page',
};
async function onMode() {
  const mode = $('mode').value;
  $('viewlabel').textContent = VIEW_LABELS[mode.startsWith('sh') ? 'sh' : mode];
  try {
    if (mode === 'error' || mode === 'exact' || mode.startsWith('sh')) await loadCompare(P);
    if (mode === 'prt' && !P.prt) await loadTransfer(P, $('prtmode').value, $('prtbounces').value);
    clearError();
  } catch (e) { showError(e); $('mode').value = 'design'; }
  showForMode(mode, $('prtmode').value);
  if (mode === 'hbasis') updateHBasis(P);
  showLegend(P); draw();
}
function wireView() {  // the view's own controls and the drag on the probe panel
  $('exposure').oninput = () => { $('expval').textContent = $('exposure').value; draw(); redrawHBasis(); };
  $('mode').onchange = onMode; $('errlmax').onchange = () => { showLegend(P); draw(); };
  $('resetview').onclick = () => P.view3d.reset();
  const c = $('probe'), H = P.history; let start = null;
  c.onpointerdown = (e) => { c.setPointerCapture(e.pointerId); start = { x: e.offsetX, y: e.offsetY, R: stateRotation(H.state), before: JSON.stringify(H.state) }; };
  c.onpointermove = (e) => {
    if (!start) return;
    moveAt = performance.now();
    const R = mul(dragRotation(e.offsetX - start.x, e.offsetY - start.y, c.clientWidth, c.clientHeight), start.R);
    H.state = { ...H.state, rotation: toAxisAngle(R) };
    localDesign();    // drawn at once, in the page (lmax ≤ 2)
    requestDesign();  // then the library's coefficients and certificate
  };
  c.onpointerup = () => { if (!start) return; H.record(start.before); start = null; requestDesign(); updateHBasis(P); };
}

// ------------------------------------------------------------------ start
async function main() {
  mark('script');
  // the shaders need no file: WebGL and the programs are set up while the server loads them
  const boot = window.__boot || {};  // boot.js's context, if it made one
  if (boot.gl) $('view').replaceWith(boot.canvas);
  const renderer = P.renderer = new THREE.WebGLRenderer({ canvas: $('view'), context: boot.gl || null, antialias: false, preserveDrawingBuffer: true });
  renderer.setPixelRatio(1);
  renderer.outputColorSpace = THREE.LinearSRGBColorSpace;  // our shaders write sRGB themselves
  const pr = P.programs = new Programs(await first('shaders', () => call('/api/shaders')));
  P.scene = new THREE.Scene();
  P.view3d = new View3D(renderer, $('view'), $('viewwrap'), () => draw());
  P.camera = P.view3d.camera;
  P.bgMat = pr.background();
  P.bgMesh = new THREE.Mesh(new THREE.PlaneGeometry(2, 2), P.bgMat); P.bgMesh.frustumCulled = false; P.bgMesh.renderOrder = -1;
  P.bgMesh.visible = false;  // drawn once the probe's texture is here (draw())
  P.scene.add(P.bgMesh);
  // compile the program of the first frame now (the saved edit state's degree picks it; a
  // stand-in triangle carries it)
  const saved = History.saved();   // the edit state survives a reload
  const stand = new THREE.Mesh(new THREE.BufferGeometry(), pr.object(pr.eKind(saved ? saved.lmax : 2)));
  for (const [n, k] of [['position', 3], ['normal', 3], ['albedo', 3], ['prtColor', 3]]) stand.geometry.setAttribute(n, new THREE.BufferAttribute(new Float32Array([0, 0, -1, 0.01, 0, -1, 0, 0.01, -1]), k));
  stand.geometry.setIndex(new THREE.BufferAttribute(new Uint32Array([0, 1, 2]), 1));
  stand.frustumCulled = false;
  P.scene.add(stand);
  renderer.compile(P.scene, P.camera);
  // and draw it once: a software GL (SwiftShader) translates and builds its pipeline at the
  // first draw, ~0.2 s that would otherwise come after the files (flushed, not read back:
  // it runs in the GPU process while the page waits for the server)
  clearToGrey();
  renderer.render(P.scene, P.camera);
  if (!finishFrame(renderer.getContext())) renderer.getContext().flush();
  P.scene.remove(stand); stand.geometry.dispose();
  renderer.clear();  // the view stays the background's grey until the first frame
  mark('gl');
  const init = await first('init', () => call('/api/init'));
  mark('init');
  api.init = init;
  $('source').textContent = init.source.name; probeLabel(init.source);
  if (saved) P.history.state = saved;
  else if (init.transfer) P.history.state.lmax = init.transfer.design_lmax;  // the baked degree, at most design.DESIGN_LMAX
  P.edits.wire(init); wireView(); P.edits.refresh();
  const jobs = [requestDesign().then(() => mark('design'))];
  showForMode($('mode').value, $('prtmode').value);
  if (init.transfer) {
    $('mode').value = 'prt'; $('viewlabel').textContent = VIEW_LABELS.prt;
    showForMode('prt', $('prtmode').value);
    jobs.push(loadTransfer(P, $('prtmode').value, $('prtbounces').value));
  } else {
    jobs.push(first('mesh', () => call('/api/mesh')).then((g) => { mark('mesh'); setGeometry(g, g.head.camera); $('meshname').textContent = g.head.name; }));
  }
  try { await Promise.all(jobs); } finally { booting = false; }  // a failed load still draws later
  mark('data');
  draw();
  mark('frame');
  makePanels(); drawPanels();  // the probe and irradiance panels follow the object's frame
  mark('panels');
  // the first lit frame needs the lighting and the mesh; the background follows (the server
  // has the loader send the decoded probe now)
  if (init.source.has_env) { await loadBackground(P); mark('background'); draw(); }
  if (init.hbasis) { $('mode').value = 'hbasis'; await onMode(); }  // --hbasis FILE: its view
  api.ready = true;
  setStatus(`ready in ${(performance.now() - t0).toFixed(0)} ms`);
}
main().catch((e) => {  // the error first: making the panels fails too when WebGL does
  booting = false; showError(e);
  try { if (!panel) makePanels(); } catch (e2) { /* the error above says why */ }
});

// three.js LightProbe driven by shprobe's `three` export: its irradiance vs the library's
api.threeCheck = async () => {
  const body = JSON.stringify(P.history.state);
  const text = await (await call('/api/export/three', { method: 'POST', body })).text();
  const doc = JSON.parse(text);
  const probe = new THREE.LightProbe(new THREE.SphericalHarmonics3().fromArray(doc.coefficients));
  const lib = await call('/api/irradiance', { method: 'POST', body });
  const three = lib.normals.map((n) => { const c = probe.sh.getIrradianceAt(new THREE.Vector3(...n), new THREE.Vector3()); return [c.x, c.y, c.z]; });
  return { three, library: lib.irradiance };
};
