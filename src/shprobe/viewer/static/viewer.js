// shprobe view: the page. Every number it shows comes from the server (the shprobe library);
// the page draws: per-pixel irradiance with shprobe's own GLSL export (R&H 2001 eq. 13, the
// coefficients as uniforms), lookups of the library's irradiance tables by normal, and PRT
// relighting (transfer · lighting per vertex, Lisle & Huang §4).
import * as THREE from 'three';  // the parts of three.js this page uses (tools/js/entry.js)
import { unpack } from './wire.js';
import { View3D, readLibraryView } from './view3d.js';
import { buildSliders, fillSelect, showForMode } from './controls.js';
import { HEAT_GLSL, drawHBasis, showCompareLegend } from './legend.js';

const $ = (id) => document.getElementById(id);
const api = window.__shprobe || {};  // exposed for tests and benchmarks
window.__shprobe = api;
const t0 = performance.now();
api.marks = {};
const mark = (name) => { api.marks[name] = Math.round(performance.now()); };  // ms since navigation start

// ------------------------------------------------------------------ server calls
async function call(path, opts = {}) { return handle(await fetch(path, opts)); }
async function handle(r) {
  const type = r.headers.get('content-type') || '';
  if (!r.ok) {
    let msg = `${r.status} ${r.statusText}`;
    if (type.includes('json')) msg = (await r.json()).error || msg;
    else msg = (await r.text()) || msg;
    throw new Error(msg);
  }
  if (type.includes('json')) return r.json();
  if (type.includes('octet-stream')) return unpack(await r.arrayBuffer());
  return r;
}
function showError(e) {
  const el = $('error');
  el.textContent = String(e && e.message ? e.message : e);
  el.hidden = false;
  api.lastError = el.textContent;
}
function clearError() { $('error').hidden = true; }
function setStatus(s) { $('status').textContent = s; }

// the first requests were started by boot.js while three.js was loading
function first(name, fallback) {
  const b = window.__boot && window.__boot[name];
  if (b) { window.__boot[name] = null; return b.then((r) => (r instanceof Response ? handle(r) : r)); }
  return fallback();
}

// ------------------------------------------------------------------ edit state and history
const EMPTY = { lmax: 2, weight: 1, blends: [], directional: [], cone: [], sky: null,
                scale: {}, scale_band: {}, rotation: null, window: null };
let state = structuredClone(EMPTY);
let history = [], future = [];
const KEY = 'shprobe-view-state';
function saveLocal() { try { localStorage.setItem(KEY, JSON.stringify(state)); } catch (e) { /* private mode */ } }
function commit(next) {   // an edit: undoable, persisted, recomputed
  history.push(JSON.stringify(state)); future = [];
  state = next; saveLocal(); refreshControls(); requestDesign(); updateHBasis();
}
function undo() { if (!history.length) return; future.push(JSON.stringify(state)); state = JSON.parse(history.pop()); saveLocal(); refreshControls(); requestDesign(); updateHBasis(); }
function redo() { if (!future.length) return; history.push(JSON.stringify(state)); state = JSON.parse(future.pop()); saveLocal(); refreshControls(); requestDesign(); updateHBasis(); }
api.getState = () => structuredClone(state);
api.setState = (s) => commit({ ...structuredClone(EMPTY), ...structuredClone(s) });

// ------------------------------------------------------------------ rotations (3×3, row major)
function rotAxis(axis, deg) {
  const n = Math.hypot(...axis), [x, y, z] = axis.map((v) => v / n), t = deg * Math.PI / 180;
  const c = Math.cos(t), s = Math.sin(t), C = 1 - c;
  return [[c + x * x * C, x * y * C - z * s, x * z * C + y * s],
          [y * x * C + z * s, c + y * y * C, y * z * C - x * s],
          [z * x * C - y * s, z * y * C + x * s, c + z * z * C]];
}
function mul(A, B) { return A.map((r) => [0, 1, 2].map((j) => r[0] * B[0][j] + r[1] * B[1][j] + r[2] * B[2][j])); }
function toAxisAngle(R) {  // via the quaternion (robust near 180°)
  const tr = R[0][0] + R[1][1] + R[2][2];
  let w, x, y, z;
  if (tr > 0) { const s = 2 * Math.sqrt(tr + 1); w = s / 4; x = (R[2][1] - R[1][2]) / s; y = (R[0][2] - R[2][0]) / s; z = (R[1][0] - R[0][1]) / s; }
  else if (R[0][0] > R[1][1] && R[0][0] > R[2][2]) { const s = 2 * Math.sqrt(1 + R[0][0] - R[1][1] - R[2][2]); w = (R[2][1] - R[1][2]) / s; x = s / 4; y = (R[0][1] + R[1][0]) / s; z = (R[0][2] + R[2][0]) / s; }
  else if (R[1][1] > R[2][2]) { const s = 2 * Math.sqrt(1 + R[1][1] - R[0][0] - R[2][2]); w = (R[0][2] - R[2][0]) / s; x = (R[0][1] + R[1][0]) / s; y = s / 4; z = (R[1][2] + R[2][1]) / s; }
  else { const s = 2 * Math.sqrt(1 + R[2][2] - R[0][0] - R[1][1]); w = (R[1][0] - R[0][1]) / s; x = (R[0][2] + R[2][0]) / s; y = (R[1][2] + R[2][1]) / s; z = s / 4; }
  if (w < 0) { w = -w; x = -x; y = -y; z = -z; }
  const sn = Math.hypot(x, y, z);
  if (sn < 1e-12) return null;
  return { axis: [x / sn, y / sn, z / sn], degrees: 2 * Math.atan2(sn, w) * 180 / Math.PI };
}
function stateRotation(s) { return s.rotation ? rotAxis(s.rotation.axis, s.rotation.degrees) : [[1, 0, 0], [0, 1, 0], [0, 0, 1]]; }
api.rotationMatrix = () => stateRotation(state);

// Rotation of lmax ≤ 2 lighting in the page (no server round trip while dragging), exact:
// band 1 is a vector a with f(ω) = a·ω (R&H order y, z, x), turned as a' = R a; band 2 is a
// traceless quadratic form f(ω) = ωᵀQω, turned as Q' = R Q Rᵀ; f∘R⁻¹ as the library's
// rotate_lighting (the server's answer replaces this one when it arrives).
const K1 = 1.092548430592079, K0 = 0.3153915652525200, K2 = 0.5462742152960396;
function rotateLow(L, R) {  // L: (K ≤ 9, 3) → the coefficients of L∘R⁻¹
  const out = L.map((c) => c.slice());
  for (let ch = 0; ch < 3; ch++) {
    if (L.length >= 4) {
      const a = [L[3][ch], L[1][ch], L[2][ch]];  // (x, y, z)
      const b = [0, 1, 2].map((i) => R[i][0] * a[0] + R[i][1] * a[1] + R[i][2] * a[2]);
      out[1][ch] = b[1]; out[2][ch] = b[2]; out[3][ch] = b[0];
    }
    if (L.length >= 9) {
      const [m2, m1, z0, p1, p2] = [L[4][ch], L[5][ch], L[6][ch], L[7][ch], L[8][ch]];
      const Q = [[-K0 * z0 + K2 * p2, K1 * m2 / 2, K1 * p1 / 2],
                 [K1 * m2 / 2, -K0 * z0 - K2 * p2, K1 * m1 / 2],
                 [K1 * p1 / 2, K1 * m1 / 2, 2 * K0 * z0]];
      const RQ = mul(R, Q);
      const Qr = [0, 1, 2].map((i) => [0, 1, 2].map((j) => RQ[i][0] * R[j][0] + RQ[i][1] * R[j][1] + RQ[i][2] * R[j][2]));
      out[4][ch] = 2 * Qr[0][1] / K1; out[5][ch] = 2 * Qr[1][2] / K1; out[7][ch] = 2 * Qr[0][2] / K1;
      out[6][ch] = Qr[2][2] / (2 * K0); out[8][ch] = (Qr[0][0] - Qr[1][1]) / (2 * K2);
    }
  }
  return out;
}
api.rotateInPage = (L, R) => rotateLow(L, R);
function localDesign() {  // during a drag: the last server answer turned in the page
  if (!lastDesign || !lastDesign.unrotated || lastDesign.unrotated.length > 9) return false;
  if (JSON.stringify({ ...lastDesign.state, rotation: null }) !== JSON.stringify({ ...state, rotation: null })) return false;
  let L = rotateLow(lastDesign.unrotated, stateRotation(state));
  const f = lastDesign.factors;
  if (f) L = L.map((c, k) => c.map((v) => v * f[Math.floor(Math.sqrt(k))]));
  coeffs = L; api.coeffs = L; api.localFrames = (api.localFrames || 0) + 1;
  draw();
  return true;
}

// ------------------------------------------------------------------ design (library, server)
let designBusy = false, designAgain = false;
let coeffs = null;           // current L_lm (K, 3) from the server
let irrE = null;             // its E_lm = Â_l L_lm (library, lighting.glsl.glsl_uniform_values)
let lastDesign = null;
async function requestDesign() {
  if (designBusy) { designAgain = true; return; }
  designBusy = true;
  try {
    do {
      designAgain = false;
      const tc = performance.now();
      const body = JSON.stringify(state), sent = state;
      const r = await first(`design:${body}`, () => call('/api/design', { method: 'POST', body }));
      api.lastDesignMs = performance.now() - tc;
      r.state = sent; lastDesign = r;
      // a stale answer (the drag moved on meanwhile) is turned to the current rotation
      if (JSON.stringify(state) === body || !localDesign()) { coeffs = r.coeffs; api.coeffs = r.coeffs; irrE = r.irradiance; }
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
  const rot = state.rotation;
  $('rotinfo').textContent = rot ? `rotation ${rot.degrees.toFixed(1)}° about (${rot.axis.map((v) => v.toFixed(2)).join(', ')})` : 'no rotation';
}

// ------------------------------------------------------------------ shaders
const PI = 'const float PI = 3.141592653589793;\n';
const SRGB = `out vec4 fragColor;
vec3 srgb(vec3 v) { v = clamp(v, 0.0, 1.0);
  return mix(12.92 * v, 1.055 * pow(v, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), v)); }
vec2 dirToUV(vec3 d) {  // shprobe lat-long: row 0 = +Y, u = 0.5 -> -Z, u = 0.75 -> +X
  float th = acos(clamp(d.y, -1.0, 1.0));
  float psi = atan(-d.x, d.z); if (psi < 0.0) psi += 2.0 * PI;
  return vec2(psi / (2.0 * PI), th / PI); }
vec3 uvToDir(vec2 uv) { float psi = 2.0 * PI * uv.x, th = PI * uv.y;
  return vec3(-sin(psi) * sin(th), cos(th), cos(psi) * sin(th)); }
vec3 rgbe(sampler2D t, vec2 uv) { return texture(t, uv).rgb; }
` + HEAT_GLSL;
let SHPROBE_GLSL = '';   // shprobe's export, constants turned into uniforms
let SHPROBE_GLSL_SH = '';  // shprobe's generated any-lmax function (lighting.glsl), uniform E_lm
function shaderFromExport(text) {
  return text
    .replace(/const mat4 (SHPROBE_M_[RGB]) = mat4\([^;]*\);/g, 'uniform mat4 $1;')
    .replace(/const vec3 SHPROBE_L\[9\] = vec3\[9\]\([\s\S]*?\n\);/, 'uniform vec3 SHPROBE_L[9];');
}
let SH_LMAX = 4;  // the degree of the library's generated per-pixel function (init.glsl_sh)
let SHPROBE_GLSL_SH_DESIGN = '', SH_DESIGN_LMAX = 8;  // the same to a design's highest degree
// E(n) per pixel: R&H eq. 13 (the export) at lmax <= 2, the library's generated GLSL above it.
// One program per case (a define picks it), not a branch on a uniform: a software GL
// (SwiftShader) pays for every branch of a program, ~2× the frame time and the first draw.
// 'poly': eq. 13; 'sh': the generated function to SH_LMAX; 'shd': to SH_DESIGN_LMAX (a design
// above SH_LMAX, e.g. a PRT transfer's degree)
const irradianceGLSL = (kind) => ({ poly: SHPROBE_GLSL, sh: SHPROBE_GLSL_SH, shd: SHPROBE_GLSL_SH_DESIGN }[kind]
  + `vec3 shprobe_E(vec3 n) { return shprobe_irradiance_${kind === 'poly' ? 'poly' : 'sh'}(n); }\n`);
const eKind = (lmax) => (lmax <= 2 ? 'poly' : lmax <= SH_LMAX ? 'sh' : 'shd');
const commonUniforms = (lmaxE = SH_LMAX) => ({
  SHPROBE_L: { value: Array.from({ length: 9 }, () => new THREE.Vector3()) },
  SHPROBE_E: { value: Array.from({ length: (lmaxE + 1) ** 2 }, () => new THREE.Vector3()) },
  SHPROBE_M_R: { value: new THREE.Matrix4() }, SHPROBE_M_G: { value: new THREE.Matrix4() },
  SHPROBE_M_B: { value: new THREE.Matrix4() },
  uExposure: { value: 0 }, uRotInv: { value: new THREE.Matrix3() },
  uBg: { value: null }, uHasBg: { value: 0 },
});

// ------------------------------------------------------------------ three.js scene
let renderer, scene, camera, view3d, meshObj, bgMesh, objUniforms, bgMat;
let panel, panelScene, panelCam, probeMat, irrMats, irrMesh, panelRenderer2, irrScene, objUniformsD;
const objMats = {};  // the object's programs, one per view (OBJ_VIEWS), made on first use
let bgTex = null, cmp = null, prt = null;
const lookTex = {};

// the object's views: albedo · E/π per pixel with E from eq. 13 | from the generated function
// (a design above lmax 2, compare "SH lmax l") | from it to a design's highest degree | the
// library's brute force | the error heat map | PRT vertex colours
const OBJ_VIEWS = { poly: 0, sh: 0, shd: 0, exact: 2, error: 3, prt: 4 };
function objectMaterial(view) {
  if (objMats[view]) return objMats[view];
  objUniforms = objUniforms || { ...commonUniforms(), uA: { value: null }, uRef: { value: null },
                                 uTot: { value: new THREE.Vector3(1, 1, 1) }, uErrMax: { value: 1 } };
  if (view === 'shd') objUniformsD = objUniformsD || { ...commonUniforms(SH_DESIGN_LMAX) };
  const v = OBJ_VIEWS[view];
  return (objMats[view] = new THREE.ShaderMaterial({
    glslVersion: THREE.GLSL3,
    uniforms: view === 'shd' ? objUniformsD : objUniforms,  // shared by the other views
    defines: { OBJ_VIEW: v },
    vertexShader: `in vec3 albedo; in vec3 prtColor; out vec3 vN; out vec3 vAlb; out vec3 vPrt;
      void main() { vN = normal; vAlb = albedo; vPrt = prtColor;
        gl_Position = projectionMatrix * modelViewMatrix * vec4(position, 1.0); }`,
    fragmentShader: PI + SRGB + (v === 0 ? irradianceGLSL(view) : '') + `
      uniform float uExposure; uniform sampler2D uA; uniform sampler2D uRef;
      uniform vec3 uTot; uniform float uErrMax;
      in vec3 vN; in vec3 vAlb; in vec3 vPrt;
      void main() {
        vec3 n = normalize(vN);
      #if OBJ_VIEW == 0
        fragColor = vec4(srgb(vAlb * shprobe_E(n) / PI * exp2(uExposure)), 1.0);  // per pixel
      #elif OBJ_VIEW == 2
        fragColor = vec4(srgb(vAlb * texture(uRef, dirToUV(n)).rgb / PI * exp2(uExposure)), 1.0);
      #elif OBJ_VIEW == 3
        vec3 d = abs(texture(uA, dirToUV(n)).rgb - texture(uRef, dirToUV(n)).rgb) / uTot;
        fragColor = vec4(heat(max(d.r, max(d.g, d.b)) / uErrMax), 1.0);
      #else
        fragColor = vec4(srgb(vPrt * exp2(uExposure)), 1.0);
      #endif
      }`,
  }));
}
function makeBgMaterial() {  // full-screen pass: the probe seen along each camera ray
  return new THREE.ShaderMaterial({
    glslVersion: THREE.GLSL3, depthWrite: false, depthTest: false,
    uniforms: { ...commonUniforms(), uInvVP: { value: new THREE.Matrix4() }, uEye: { value: new THREE.Vector3() } },
    vertexShader: `out vec2 vNdc; void main() { vNdc = position.xy; gl_Position = vec4(position.xy, 1.0, 1.0); }`,
    fragmentShader: PI + SRGB + `uniform sampler2D uBg; uniform int uHasBg; uniform float uExposure;
      uniform mat3 uRotInv; uniform mat4 uInvVP; uniform vec3 uEye; in vec2 vNdc;
      void main() { vec4 p = uInvVP * vec4(vNdc, 1.0, 1.0); vec3 d = normalize(p.xyz / p.w - uEye);
        vec3 c = uHasBg == 1 ? rgbe(uBg, dirToUV(uRotInv * d)) : vec3(0.18);
        fragColor = vec4(srgb(c * exp2(uExposure)), 1.0); }`,
  });
}
function makePanelMaterial(kind, uniforms) {  // lat-long panels: the probe, or E/π (eq. 13 | sh)
  return new THREE.ShaderMaterial({
    glslVersion: THREE.GLSL3, depthTest: false,
    uniforms: uniforms || commonUniforms(),
    vertexShader: `out vec2 vUv; void main() { vUv = vec2(uv.x, 1.0 - uv.y); gl_Position = vec4(position.xy, 0.0, 1.0); }`,
    fragmentShader: PI + SRGB + (kind === 'probe' ? '' : irradianceGLSL(kind)) + `uniform sampler2D uBg; uniform int uHasBg; uniform float uExposure;
      uniform mat3 uRotInv; in vec2 vUv;
      void main() { vec3 d = uvToDir(vUv);
        vec3 c = ${kind === 'probe' ? 'uHasBg == 1 ? rgbe(uBg, dirToUV(uRotInv * d)) : vec3(0.18)' : 'shprobe_E(d) / PI'};
        fragColor = vec4(srgb(c * exp2(uExposure)), 1.0); }`,
  });
}
function floatTex(data, h, w) {  // (h, w, 3) float32 → RGBA float texture, row 0 = +Y
  const rgba = new Float32Array(h * w * 4);
  for (let i = 0; i < h * w; i++) { rgba[4 * i] = data[3 * i]; rgba[4 * i + 1] = data[3 * i + 1]; rgba[4 * i + 2] = data[3 * i + 2]; rgba[4 * i + 3] = 1; }
  const t = new THREE.DataTexture(rgba, w, h, THREE.RGBAFormat, THREE.FloatType);
  t.wrapS = THREE.RepeatWrapping; t.wrapT = THREE.ClampToEdgeWrapping;
  t.magFilter = THREE.LinearFilter; t.minFilter = THREE.LinearFilter; t.needsUpdate = true;
  return t;
}

function setE(u, E, lmax) {  // E_lm = Â_l L_lm of the library, zero above lmax
  const K = (lmax + 1) ** 2;
  u.SHPROBE_E.value.forEach((v, k) => { const c = (k < K && E && E[k]) || [0, 0, 0]; v.set(c[0], c[1], c[2]); });
}
// above l = 2 there is no quadratic form: the generated function, with the library's E_lm
// the background pass's colour without a probe texture (radiance 0.18, tone mapped), as a clear
function clearToGrey() {
  const g = srgbJS(0.18 * 2 ** Number($('exposure').value));
  renderer.setClearColor(new THREE.Color().setRGB(g, g, g, THREE.LinearSRGBColorSpace), 1);
}
const srgbJS = (v) => { v = Math.min(Math.max(v, 0), 1); return v < 0.0031308 ? 12.92 * v : 1.055 * v ** (1 / 2.4) - 0.055; };  // SRGB's srgb()
const highLmax = () => !!(coeffs && coeffs.length > 9 && irrE);
const designLmax = () => (highLmax() ? Math.sqrt(coeffs.length) - 1 : 2);
function setLightingUniforms(u) {
  if (coeffs) for (let k = 0; k < 9; k++) {
    const c = coeffs[k] || [0, 0, 0]; u.SHPROBE_L.value[k].set(c[0], c[1], c[2]);
  }
  if (highLmax()) setE(u, irrE, Math.sqrt(coeffs.length) - 1);
  u.uExposure.value = Number($('exposure').value);
  const R = stateRotation(state);  // R⁻¹ = Rᵀ: the rotated lighting at ω is the probe at R⁻¹ω
  u.uRotInv.value.set(R[0][0], R[1][0], R[2][0], R[0][1], R[1][1], R[2][1], R[0][2], R[1][2], R[2][2]);
  u.uBg.value = bgTex; u.uHasBg.value = bgTex ? 1 : 0;
}

const MODES = { design: 0, sh1: 1, sh2: 1, sh3: 1, sh4: 1, exact: 2, error: 3, prt: 4 };
let frameTimes = [];
let booting = true;  // until the first frame's data is in: one draw then, none before
let moveAt = null;  // when the last drag move arrived (for the move → frame time)
function draw() {
  if (!renderer || !coeffs || booting) return;
  const tf = performance.now();
  const mode = $('mode').value;
  if (mode === 'prt') relightPRT();
  const m = MODES[mode];
  if (meshObj) meshObj.material = objectMaterial(m === 4 ? 'prt' : m === 2 ? 'exact' : m === 3 ? 'error'
    : m === 1 ? 'sh' : eKind(designLmax()));
  for (const u of [meshObj ? meshObj.material.uniforms : objUniforms, bgMat.uniforms]) setLightingUniforms(u);
  if (cmp && m === 1) setE(objUniforms, cmp.irradiance, Number(mode.slice(2)));
  if (cmp && m === 3) objUniforms.uA.value = lookTex['sh' + $('errlmax').value];
  if (cmp) { objUniforms.uRef.value = lookTex.reference; }
  cameraUniforms(camera);
  renderer.render(scene, camera);
  const gl = renderer.getContext(); const px = new Uint8Array(4);
  gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px);  // waits for the frame
  api.mainFrameMs = performance.now() - tf;
  // the first lit frame: the object drawn with the lighting, finished (the panels follow)
  if (!api.firstFrameMs && meshObj) { api.firstFrameMs = performance.now() - t0; api.firstFrameAt = Date.now(); }
  drawPanels();
  const dt = performance.now() - tf;
  if (moveAt !== null) { (api.moveToFrame = api.moveToFrame || []).push(performance.now() - moveAt); moveAt = null; }
  frameTimes.push(dt); if (frameTimes.length > 200) frameTimes.shift();
  api.frames = (api.frames || 0) + 1;
}
function cameraUniforms(cam) {  // the background pass seen from ``cam``
  cam.updateMatrixWorld();
  bgMat.uniforms.uInvVP.value.multiplyMatrices(cam.matrixWorld, cam.projectionMatrixInverse);
  bgMat.uniforms.uEye.value.setFromMatrixPosition(cam.matrixWorld);
  // until the probe's texture is here the background is the flat grey the pass would draw
  // (radiance 0.18, same tone mapping): a clear, not a full-screen pass
  bgMesh.visible = !!bgTex;
  if (!bgTex) clearToGrey();
}
function drawPanels() {  // the probe and the irradiance map (made after the first frame)
  if (!panel) return;
  irrMesh.material = irrMats[eKind(designLmax())];
  setLightingUniforms(probeMat.uniforms); setLightingUniforms(irrMesh.material.uniforms);
  panel.render(panelScene, panelCam);
  panelRenderer2.render(irrScene, panelCam);
}
function makePanels() {  // two more WebGL contexts: after the object's first frame
  panel = new THREE.WebGLRenderer({ canvas: $('probe'), antialias: false });
  panel.setPixelRatio(1); panel.setSize(512, 256, false); panel.outputColorSpace = THREE.LinearSRGBColorSpace;
  panelRenderer2 = new THREE.WebGLRenderer({ canvas: $('irrmap'), antialias: false });
  panelRenderer2.setPixelRatio(1); panelRenderer2.setSize(512, 256, false); panelRenderer2.outputColorSpace = THREE.LinearSRGBColorSpace;
  panelCam = new THREE.OrthographicCamera(-1, 1, 1, -1, 0, 1);
  probeMat = makePanelMaterial('probe');
  const u = commonUniforms();
  irrMats = { poly: makePanelMaterial('poly', u), sh: makePanelMaterial('sh', u),
              shd: makePanelMaterial('shd', commonUniforms(SH_DESIGN_LMAX)) };
  irrMesh = new THREE.Mesh(new THREE.PlaneGeometry(2, 2), irrMats.poly);
  panelScene = new THREE.Scene(); panelScene.add(new THREE.Mesh(new THREE.PlaneGeometry(2, 2), probeMat));
  irrScene = new THREE.Scene(); irrScene.add(irrMesh);
}
api.draw = draw;
api.frameTimes = () => frameTimes.slice();
// the object seen by the library's camera (shprobe.scene.Camera(512, 512) fitted to the
// object), 512×512 RGBA rows from the top, as the library's images: what the pixel tests
// compare with shprobe.scene.render (the view on screen is the orbit camera's)
function libraryView() {
  draw();
  const out = readLibraryView(renderer, scene, view3d.libraryCamera(), cameraUniforms);
  draw();
  return out;
}
api.readAll = () => {  // base64 of libraryView()
  const out = libraryView();
  return btoa(Array.from({ length: 512 }, (_, y) => String.fromCharCode.apply(null, out.subarray(y * 2048, (y + 1) * 2048))).join(''));
};
api.readPixel = (x, y) => Array.from(libraryView().subarray(4 * (512 * y + x), 4 * (512 * y + x) + 4));
api.cameraState = () => view3d.state();
api.resetView = () => view3d.reset();

// ------------------------------------------------------------------ geometry
function setGeometry(g, cam) {
  const geo = new THREE.BufferGeometry();
  geo.setAttribute('position', new THREE.BufferAttribute(g.position, 3));
  geo.setAttribute('normal', new THREE.BufferAttribute(g.normal, 3));
  const nv = g.position.length / 3;
  geo.setAttribute('albedo', new THREE.BufferAttribute(g.albedo || new Float32Array(nv * 3).fill(1), 3));
  geo.setAttribute('prtColor', new THREE.BufferAttribute(new Float32Array(nv * 3), 3));
  geo.setIndex(new THREE.BufferAttribute(g.index, 1));
  if (meshObj) { scene.remove(meshObj); meshObj.geometry.dispose(); }
  meshObj = new THREE.Mesh(geo, objectMaterial('poly'));  // draw() picks the view's program
  meshObj.frustumCulled = false;
  scene.add(meshObj);
  // the orbit camera starts from the server's view (the library Camera fitted to the
  // object's bounding sphere, above the horizon); the library's own camera is kept for reads
  view3d.frame(g.head.view || cam, cam);
  api.camera = cam; api.viewCamera = g.head.view || cam;
  api.objectBounds = { center: g.head.center, radius: g.head.radius, ground: g.head.ground_vertices || 0 };
}

// ------------------------------------------------------------------ PRT
async function loadTransfer(mode, bounces) {
  const q = new URLSearchParams(); if (mode) q.set('mode', mode); if (bounces !== '' && bounces != null && mode === 'interreflected') q.set('bounces', bounces);
  setStatus('loading transfer…');
  const r = await call('/api/transfer?' + q);
  const h = r.head, nv = r.position.length / 3;
  const kfull = (h.lmax + 1) ** 2, per = r.transfer.length / (nv * kfull);
  prt = { T: r.transfer, nv, kfull, coloured: per === 3, lmax: h.lmax, out: new Float32Array(nv * 3), head: h };
  if (!meshObj || meshObj.geometry.attributes.position.count !== nv) setGeometry(r, h.camera);
  const ls = $('prtlmax'); if (ls.options.length !== h.lmax + 1) fillSelect(ls, Array.from({ length: h.lmax + 1 }, (_, l) => l), h.lmax);
  $('meshname').textContent = `${h.name} (PRT)`;
  $('prtinfo').textContent = `${h.name}: ${nv} vertices, baked lmax ${h.lmax}, ${h.mode}${h.max_bounces ? `, up to ${h.max_bounces} bounces` : ''}`;
  setStatus('');
  api.prt = prt;
}
function relightPRT() {  // radiance_v,c = Σ_k T[v,k(,c)] L[k,c], the lighting already rotated
  if (!prt || !coeffs) return;
  const tp = performance.now();
  const l = Math.min(Number($('prtlmax').value), prt.lmax, Math.sqrt(coeffs.length) - 1);
  const K = (l + 1) ** 2, { T, nv, kfull, out } = prt;
  const L = new Float64Array(K * 3);
  for (let k = 0; k < K; k++) for (let c = 0; c < 3; c++) L[3 * k + c] = coeffs[k][c];
  if (prt.coloured) {
    for (let v = 0; v < nv; v++) {
      let r = 0, g = 0, b = 0; const o = v * kfull * 3;
      for (let k = 0; k < K; k++) { r += T[o + 3 * k] * L[3 * k]; g += T[o + 3 * k + 1] * L[3 * k + 1]; b += T[o + 3 * k + 2] * L[3 * k + 2]; }
      out[3 * v] = r; out[3 * v + 1] = g; out[3 * v + 2] = b;
    }
  } else {
    for (let v = 0; v < nv; v++) {
      let r = 0, g = 0, b = 0; const o = v * kfull;
      for (let k = 0; k < K; k++) { const t = T[o + k]; r += t * L[3 * k]; g += t * L[3 * k + 1]; b += t * L[3 * k + 2]; }
      out[3 * v] = r; out[3 * v + 1] = g; out[3 * v + 2] = b;
    }
  }
  const a = meshObj.geometry.attributes.prtColor; a.array.set(out); a.needsUpdate = true;
  api.prtRelightMs = performance.now() - tp; api.prtLmax = l;
}
api.prtRadiance = (v) => (prt ? Array.from(prt.out.slice(3 * v, 3 * v + 3)) : null);

// ------------------------------------------------------------------ compare (library numbers)
async function loadCompare() {
  if (cmp) return;
  $('progress').hidden = false;
  for (;;) {
    const r = await call('/api/compare');
    if (r.head) {  // done: binary tables
      const [h, w] = r.head.grid;
      lookTex.reference = floatTex(r.reference, h, w);
      for (let l = 1; l <= 4; l++) if (r['sh' + l]) lookTex['sh' + l] = floatTex(r['sh' + l], h, w);
      cmp = r.head;
      objUniforms.uTot.value.set(...cmp.total_intensity);
      break;
    }
    if (r.status === 'error') { $('progress').hidden = true; throw new Error(r.error); }
    $('progressbar').style.width = `${(100 * r.done).toFixed(0)}%`;
    $('progresstext').textContent = `exact irradiance (brute force, library): ${(100 * r.done).toFixed(0)}%`;
    await new Promise((res) => setTimeout(res, 150));
  }
  $('progress').hidden = true;
  api.compare = cmp;
}
function showLegend() {  // legend.js: the heat scale in % of ∫L dω, the table in the same unit
  const row = showCompareLegend($('mode').value, cmp, Number($('errlmax').value));
  if (row && $('mode').value === 'error') objUniforms.uErrMax.value = row.max_frac;
}
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
    if (mode === 'error' || mode === 'exact' || mode.startsWith('sh')) await loadCompare();
    if (mode === 'prt' && !prt) await loadTransfer($('prtmode').value, $('prtbounces').value);
    clearError();
  } catch (e) { showError(e); $('mode').value = 'design'; }
  showForMode(mode, $('prtmode').value);
  if (mode === 'hbasis') updateHBasis();
  showLegend(); draw();
}
let hbBusy = false, hbAgain = false, hbLast = null;
async function updateHBasis() {  // the library's render (server), after each settled edit
  if ($('mode').value !== 'hbasis') return;
  if (hbBusy) { hbAgain = true; return; }
  hbBusy = true;
  try {
    do {
      hbAgain = false;
      setStatus('H-basis render…');
      const r = await call('/api/hbasis', { method: 'POST', body: JSON.stringify(state) });
      hbLast = r;
      $('hblabel').innerHTML = r.head.baked
        ? `H-basis bake <code>${api.init.hbasis ? api.init.hbasis.name : ''}</code> (<code>shprobe hbasis bake</code>): its per-vertex coefficients under the lighting they were baked for (edits do not apply: bake again), as <code>shprobe hbasis render MESH FILE.npz</code>; E/π of a white surface with a procedural bump`
        : `Irradiance normal mapping (Habel &amp; Wimmer 2010, as <code>shprobe hbasis render</code>): E/π of a white surface with a procedural bump, per-vertex bases baked from the current lighting (lmax 4, edits and rotation applied) against ${r.head.reference === 'brute force over the probe' ? 'the exact E(n′), brute force over the probe (turned)' : 'E(n′) of the edited lighting\'s SH expansion'}; recomputed by the library after each edit`;
      api.hbasisErrMax = drawHBasis(r, Number($('exposure').value));
      api.hbasis = r.head.rel_rms; api.hbasisHead = r.head;
      setStatus('');
    } while (hbAgain);
  } catch (e) { showError(e); }
  hbBusy = false;
}

// ------------------------------------------------------------------ controls
// the degrees a design may have (0..design.DESIGN_LMAX, from /api/init) and the
// transfer's baked degree (marked in the menu)
let designDegrees = 8, bakedLmax = null;
function refreshControls() {
  const range = (n) => Array.from({ length: n + 1 }, (_, l) => l);
  fillSelect($('lmax'), range(designDegrees), state.lmax, (l) => (l === bakedLmax ? `${l} (the transfer's)` : String(l)));
  buildSliders(state,
    (l, v) => { const s = structuredClone(state); s.scale_band[l] = v; commit(s); },
    (l, m, v) => { const s = structuredClone(state); s.scale[`${l},${m}`] = v; commit(s); });
  const ul = $('lights'); ul.innerHTML = '';
  const item = (text, drop) => { const li = document.createElement('li'); li.textContent = text + ' '; const b = document.createElement('button'); b.textContent = 'remove'; b.onclick = drop; li.append(b); ul.append(li); };
  state.directional.forEach((d, i) => item(`directional (${d.dir.map((v) => v.toFixed(2))}) rgb ${d.rgb}`, () => { const s = structuredClone(state); s.directional.splice(i, 1); commit(s); }));
  state.cone.forEach((d, i) => item(`cone (${d.dir.map((v) => v.toFixed(2))}) ${d.aperture_deg}° rgb ${d.rgb}`, () => { const s = structuredClone(state); s.cone.splice(i, 1); commit(s); }));
  if (state.sky) item(`hemisphere sky ${state.sky.sky} ground ${state.sky.ground}`, () => { const s = structuredClone(state); s.sky = null; commit(s); });
  state.blends.forEach((b, i) => item(`blend ${b.preset ? 'preset ' + b.preset : 'probe ' + (probeNames[b.probe] || b.probe)} × ${b.weight}`, () => { const s = structuredClone(state); s.blends.splice(i, 1); commit(s); }));
  $('weight').value = state.weight;
  const w = state.window || ''; $('window').value = w.includes(':') ? w.split(':')[0] : w;
  if (w.includes(':')) $('wstrength').value = Number(w.split(':')[1]);
}
// blend sources: the presets and every probe this server loaded (command line, uploads), by id
let probeNames = {}, presetNames = [];
function blendOptions(presets, probes) {
  if (presets) presetNames = presets;
  const sel = $('bpreset'), keep = sel.value; sel.innerHTML = '';
  for (const p of presetNames) sel.add(new Option(`preset ${p}`, `preset:${p}`));
  probeNames = {};
  for (const p of probes || []) { probeNames[p.id] = p.name; sel.add(new Option(`probe ${p.name}`, `probe:${p.id}`)); }
  if ([...sel.options].some((o) => o.value === keep)) sel.value = keep;
}
function nums(id, n) {
  const v = $(id).value.split(',').map(Number);
  if (v.length !== n || v.some((x) => !Number.isFinite(x))) throw new Error(`${id}: expected ${n} comma-separated numbers`);
  return v;
}
// a light placed in the world frame is stored unrotated (the CLI rotates after adding lights)
function unrotate(d) { const R = stateRotation(state); return [0, 1, 2].map((i) => R[0][i] * d[0] + R[1][i] * d[1] + R[2][i] * d[2]); }
function wire(init) {
  $('undo').onclick = undo; $('redo').onclick = redo;
  $('reset').onclick = () => commit({ ...structuredClone(EMPTY), lmax: state.lmax });
  $('exposure').oninput = () => {
    $('expval').textContent = $('exposure').value; draw();
    if (hbLast && $('mode').value === 'hbasis') drawHBasis(hbLast, Number($('exposure').value));
  };
  $('mode').onchange = onMode; $('errlmax').onchange = () => { showLegend(); draw(); };
  $('resetview').onclick = () => view3d.reset();
  designDegrees = init.design_lmax ?? designDegrees;
  fillSelect($('errlmax'), Array.from({ length: init.compare_lmax ?? 4 }, (_, i) => i + 1), $('errlmax').value);
  $('lmax').onchange = () => {  // the design's degree (scales above it are dropped)
    const s = structuredClone(state); s.lmax = Number($('lmax').value);
    for (const k of Object.keys(s.scale)) if (Number(k.split(',')[0]) > s.lmax) delete s.scale[k];
    for (const k of Object.keys(s.scale_band)) if (Number(k) > s.lmax) delete s.scale_band[k];
    commit(s);
  };
  const guard = (f) => () => { try { f(); clearError(); } catch (e) { showError(e); } };
  $('adddir').onclick = guard(() => { const s = structuredClone(state); s.directional.push({ dir: unrotate(nums('ldir', 3)), rgb: nums('lrgb', 3) }); commit(s); });
  $('addcone').onclick = guard(() => { const s = structuredClone(state); s.cone.push({ dir: unrotate(nums('ldir', 3)), aperture_deg: nums('lap', 1)[0], rgb: nums('lrgb', 3) }); commit(s); });
  $('addsky').onclick = guard(() => { const s = structuredClone(state); s.sky = { sky: nums('lrgb', 3), ground: [0, 0, 0], up: unrotate(nums('ldir', 3)) }; commit(s); });
  $('weight').onchange = () => { const s = structuredClone(state); s.weight = Number($('weight').value); commit(s); };
  for (const p of init.presets) $('srcpreset').add(new Option(p, p));
  blendOptions(init.presets, init.probes);
  $('addblend').onclick = () => {
    const s = structuredClone(state), [kind, name] = $('bpreset').value.split(/:(.*)/s);
    s.blends.push({ [kind]: name, weight: Number($('bweight').value) }); commit(s);
  };
  for (const w of init.windows) $('window').add(new Option(w, w));
  const setWindow = () => { const s = structuredClone(state); const k = $('window').value; s.window = !k ? null : k === 'auto' ? 'auto' : `${k}:${Number($('wstrength').value)}`; commit(s); };
  $('window').onchange = setWindow; $('wstrength').onchange = setWindow;
  for (const f of init.formats) {
    const b = document.createElement('button'); b.textContent = f; b.id = 'export-' + f;
    b.onclick = () => exportFormat(f).catch(showError); $('exports').append(b);
  }
  $('upprobe').onchange = () => upload('probe', $('upprobe'));
  $('upblend').onchange = () => upload('blend', $('upblend'));
  $('loadcube').onclick = uploadCube;
  $('upmesh').onchange = () => upload('mesh', $('upmesh'));
  $('upcoeffs').onchange = () => upload('coeffs', $('upcoeffs'));
  $('uptransfer').onchange = () => upload('transfer', $('uptransfer'));
  $('uphbasis').onchange = () => upload('hbasis', $('uphbasis'));
  $('srcpreset').onchange = async () => {
    if (!$('srcpreset').value) return;
    try { const r = await call('/api/upload/preset?name=' + $('srcpreset').value, { method: 'POST' }); await newSource(r.source); } catch (e) { showError(e); }
  };
  if (init.transfer) wirePRT(init.transfer);
  wireDrag();
}
function wirePRT(t) {
  const o = $('mode').querySelector('option[value=prt]'); o.disabled = false;
  $('prtmode').innerHTML = '';
  for (const m of t.modes) $('prtmode').add(new Option(m, m));
  $('prtmode').value = t.mode; $('prtbounces').value = t.max_bounces || 0;
  $('prtbounces').max = t.max_bounces || 0;
  bakedLmax = t.lmax; refreshControls();
  const reload = async () => { showForMode($('mode').value, $('prtmode').value); try { await loadTransfer($('prtmode').value, $('prtbounces').value); clearError(); draw(); } catch (e) { showError(e); } };
  $('prtmode').onchange = reload; $('prtbounces').onchange = reload; $('prtlmax').onchange = () => draw();
}
async function exportFormat(fmt) {  // the server's export of the same state: a download
  const r = await call('/api/export/' + fmt, { method: 'POST', body: JSON.stringify(state) });
  const blob = await r.blob();
  const name = (r.headers.get('content-disposition') || '').match(/filename="([^"]+)"/)?.[1] || 'shprobe.txt';
  const a = document.createElement('a'); a.href = URL.createObjectURL(blob); a.download = name;
  document.body.append(a); a.click(); a.remove();
  api.lastExport = await blob.text();
}
api.exportFormat = exportFormat;
async function upload(kind, input) {
  const f = input.files[0]; if (!f) return;
  setStatus(`loading ${f.name}…`);
  try {
    const r = await call('/api/upload/' + kind, { method: 'POST', body: f, headers: { 'X-Filename': f.name } });
    if (r.probes) blendOptions(null, r.probes);
    if (kind === 'blend') {  // blend the uploaded probe in at the weight given
      const s = structuredClone(state); s.blends.push({ probe: r.probe_id, weight: Number($('bweight').value) }); commit(s);
    }
    if (kind === 'probe' || kind === 'coeffs') await newSource(r.source);
    if (kind === 'transfer') { prt = null; wirePRT(r.transfer); $('mode').value = 'prt'; await onMode(); }
    if (kind === 'hbasis') { api.init.hbasis = r.hbasis; $('mode').value = 'hbasis'; await onMode(); await updateHBasis(); }
    if (kind === 'mesh') { const g = await call('/api/mesh'); setGeometry(g, g.head.camera); $('meshname').textContent = g.head.name; draw(); }
    clearError();
  } catch (e) { showError(e); }  // the edit state and the current source are kept
  setStatus(''); input.value = '';
}
async function uploadCube() {  // six faces +X −X +Y −Y +Z −Z in one request (wire.unpack_files)
  const files = [0, 1, 2, 3, 4, 5].map((i) => $('face' + i).files[0]).filter(Boolean);
  const head = new TextEncoder().encode(JSON.stringify({ files: files.map((f) => ({ name: f.name, size: f.size })) }));
  const len = new Uint8Array(4); new DataView(len.buffer).setUint32(0, head.length, true);
  setStatus('loading cube faces…');
  try {
    const r = await call('/api/upload/cube', { method: 'POST', body: new Blob([len, head, ...files]) });
    await newSource(r.source);
    clearError();
  } catch (e) { showError(e); }  // the edit state and the current source are kept
  setStatus('');
}
function probeLabel(src) {  // a preset or coefficients have no picture: the panel says so
  $('probelabel').textContent = src.has_env ? 'Probe (lat-long, +Y up, centre −Z; drag to rotate the lighting)'
    : `Probe: ${src.name} has no image (grey here); drag to rotate the lighting, which the irradiance map below shows`;
}
async function newSource(src) {
  $('source').textContent = src.name; probeLabel(src);
  cmp = null; bgTex = null;
  if (src.has_env) await loadBackground();
  if ($('mode').value !== 'design' && $('mode').value !== 'prt') $('mode').value = 'design';
  showLegend(); await requestDesign();
}
async function loadBackground() {  // linear float radiance, bilinear (Env.sample's filter)
  const r = await first('background', () => call('/api/background'));
  const [h, w] = r.head.arrays.radiance.shape;  // RGBA half floats, row 0 = +Y
  const t = new THREE.DataTexture(r.radiance, w, h, THREE.RGBAFormat, THREE.HalfFloatType);
  t.wrapS = THREE.RepeatWrapping; t.wrapT = THREE.ClampToEdgeWrapping;
  t.magFilter = THREE.LinearFilter; t.minFilter = THREE.LinearFilter; t.needsUpdate = true;
  bgTex = t;
}

// drag on the probe: horizontal = about +Y (features follow the cursor in azimuth), vertical =
// about +X (features at the centre column, −Z, follow the cursor in elevation)
function dragRotation(dx, dy, w, h) {
  return mul(rotAxis([1, 0, 0], -180 * dy / h), rotAxis([0, 1, 0], -360 * dx / w));
}
api.dragRotation = (dx, dy) => dragRotation(dx, dy, 512, 256);
function wireDrag() {
  const c = $('probe'); let start = null;
  c.onpointerdown = (e) => { c.setPointerCapture(e.pointerId); start = { x: e.offsetX, y: e.offsetY, R: stateRotation(state), before: JSON.stringify(state) }; };
  c.onpointermove = (e) => {
    if (!start) return;
    moveAt = performance.now();
    const R = mul(dragRotation(e.offsetX - start.x, e.offsetY - start.y, c.clientWidth, c.clientHeight), start.R);
    state = { ...state, rotation: toAxisAngle(R) };
    localDesign();    // drawn at once, in the page (lmax ≤ 2)
    requestDesign();  // then the library's coefficients and certificate
  };
  c.onpointerup = () => { if (!start) return; history.push(start.before); future = []; start = null; saveLocal(); requestDesign(); updateHBasis(); };
}

// ------------------------------------------------------------------ start
async function main() {
  mark('script');
  // the shaders need no file: WebGL and the programs are set up while the server loads them
  const boot = window.__boot || {};  // boot.js's context, if it made one
  if (boot.gl) $('view').replaceWith(boot.canvas);
  renderer = new THREE.WebGLRenderer({ canvas: $('view'), context: boot.gl || null, antialias: false, preserveDrawingBuffer: true });
  renderer.setPixelRatio(1);
  renderer.outputColorSpace = THREE.LinearSRGBColorSpace;  // our shaders write sRGB themselves
  const sh = await first('shaders', () => call('/api/shaders'));
  SHPROBE_GLSL = shaderFromExport(sh.glsl);
  SHPROBE_GLSL_SH = sh.glsl_sh; SH_LMAX = sh.max_lmax;
  SHPROBE_GLSL_SH_DESIGN = sh.glsl_sh_design; SH_DESIGN_LMAX = sh.design_lmax;
  scene = new THREE.Scene();
  view3d = new View3D(renderer, $('view'), $('viewwrap'), () => draw());
  camera = view3d.camera;
  bgMat = makeBgMaterial();
  bgMesh = new THREE.Mesh(new THREE.PlaneGeometry(2, 2), bgMat); bgMesh.frustumCulled = false; bgMesh.renderOrder = -1;
  bgMesh.visible = false;  // drawn once the probe's texture is here (draw())
  scene.add(bgMesh);
  // compile the program of the first frame now (the saved edit state's degree picks it; a
  // stand-in triangle carries it)
  let lmax0 = 2;
  try { lmax0 = JSON.parse(localStorage.getItem(KEY) || '{}').lmax ?? 2; } catch (e) { /* default */ }
  const stand = new THREE.Mesh(new THREE.BufferGeometry(), objectMaterial(eKind(lmax0)));
  for (const [n, k] of [['position', 3], ['normal', 3], ['albedo', 3], ['prtColor', 3]]) stand.geometry.setAttribute(n, new THREE.BufferAttribute(new Float32Array([0, 0, -1, 0.01, 0, -1, 0, 0.01, -1]), k));
  stand.geometry.setIndex(new THREE.BufferAttribute(new Uint32Array([0, 1, 2]), 1));
  stand.frustumCulled = false;
  scene.add(stand);
  renderer.compile(scene, camera);
  // and draw it once: a software GL (SwiftShader) translates and builds its pipeline at the
  // first draw, ~0.2 s that would otherwise come after the files
  clearToGrey();
  renderer.render(scene, camera);
  { const gl = renderer.getContext(); gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, new Uint8Array(4)); }
  scene.remove(stand); stand.geometry.dispose();
  renderer.clear();  // the view stays the background's grey until the first frame
  mark('gl');
  const init = await first('init', () => call('/api/init'));
  mark('init');
  api.init = init;
  $('source').textContent = init.source.name; probeLabel(init.source);
  const saved = localStorage.getItem(KEY);   // the edit state survives a reload
  if (saved) { try { state = { ...structuredClone(EMPTY), ...JSON.parse(saved) }; } catch (e) { /* ignore */ } }
  else if (init.transfer) state.lmax = init.transfer.design_lmax;  // the baked degree, at most design.DESIGN_LMAX
  wire(init); refreshControls();
  const jobs = [requestDesign().then(() => mark('design'))];
  showForMode($('mode').value, $('prtmode').value);
  if (init.transfer) {
    $('mode').value = 'prt'; $('viewlabel').textContent = VIEW_LABELS.prt;
    showForMode('prt', $('prtmode').value);
    jobs.push(loadTransfer($('prtmode').value, $('prtbounces').value));
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
  if (init.source.has_env) { await loadBackground(); mark('background'); draw(); }
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
  const text = await (await call('/api/export/three', { method: 'POST', body: JSON.stringify(state) })).text();
  const doc = JSON.parse(text);
  const probe = new THREE.LightProbe(new THREE.SphericalHarmonics3().fromArray(doc.coefficients));
  const lib = await call('/api/irradiance', { method: 'POST', body: JSON.stringify(state) });
  const three = lib.normals.map((n) => { const c = probe.sh.getIrradianceAt(new THREE.Vector3(...n), new THREE.Vector3()); return [c.x, c.y, c.z]; });
  return { three, library: lib.irradiance };
};
