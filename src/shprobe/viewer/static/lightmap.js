// shprobe view --lightmap: a baked scene drawn with its normal maps and its SHPROBE_lightmap.
// The page reads the .glb itself (/api/lightmap/scene.glb: geometry, materials, the stored
// coefficient textures) and takes from the server (/api/lightmap) what the library adds: the
// generated GLSL, the encodings the stored one implies, a default exposure. Layouts: one
// encoding; Habel & Wimmer's Fig. 1 (plain · H6 without albedo · H6 with albedo); Fig. 5
// (H4 beside H6). A file with a transfer is relit live as the sky turns (lightmap_relight.js).
// window.__shprobe exposes the state and a float read-back for the tests.
import * as THREE from 'three';
import { OrbitControls } from 'three';
import { unpack } from './wire.js';
import { parseGlb, primitives, materials, imagePixels, lightmapTextures, transferTextures }
  from './lightmap_glb.js';
import { Relighter, turnedSky } from './lightmap_relight.js';
import { DEBUG, byteTexture, floatTarget, halfTexture, lightmapMaterial, primitiveGeometry }
  from './lightmap_gl.js';

const $ = (id) => document.getElementById(id);
const api = window.__shprobe = { ready: false, lastError: null };
window.addEventListener('error', (e) => { api.lastError = String(e.message || e); });
window.addEventListener('unhandledrejection', (e) => { api.lastError = String(e.reason); });
const W = 960, H = 540;
const NAMES = { plain: 'plain lightmap', hl2: 'HL2', sh4: 'L1 SH', sh9: 'L2 SH', h4: 'H4', h6: 'H6' };

function showError(e) {
  const el = $('error');
  el.textContent = String(e && e.message ? e.message : e);
  el.hidden = false;
  api.lastError = el.textContent;
}

async function fetchOk(path) {
  const r = await fetch(path);
  if (!r.ok) throw new Error(`${path}: ${r.status} ${(await r.text()).slice(0, 200)}`);
  return r.arrayBuffer();
}

const state = { layout: 'single', encoding: null, albedo: true, grid: false, exposure: 0,
  relight: false, sky: { azimuth: 0, elevation: 0, l0: 1, l1: 1, l2: 1, stops: 0 } };
let renderer, camera, controls, scene, meshes = [], head, coeff = {}, mats = [], maps = [];
let relighters = {}, baked = {};  // per relit encoding: its GPU pass; its baked textures
const cache = new Map();

function material(enc, m) {
  const key = `${enc}|${m}`;
  if (!cache.has(key)) {
    const lm = { scale: head.scale, exposure: state.exposure, width: head.width, height: head.height };
    cache.set(key, lightmapMaterial(head.glsl, enc, coeff[enc], mats[m] ?? mats.fallback,
      maps[m] ?? {}, lm));
  }
  return cache.get(key);
}

// the panels of a layout: [{encoding, albedo, label}]
function panels() {
  const has = (e) => head.encodings.includes(e);
  if (state.layout === 'fig1' && has('plain') && has('h6')) {
    return [{ encoding: 'plain', albedo: false, label: `plain lightmap (normal map ignored)${skyLabel('plain')}` },
      { encoding: 'h6', albedo: false, label: `H6, without albedo${skyLabel('h6')}` },
      { encoding: 'h6', albedo: true, label: `H6, with albedo${skyLabel('h6')}` }];
  }
  if (state.layout === 'fig5' && has('h4') && has('h6')) {
    return [{ encoding: 'h4', albedo: state.albedo, label: `H4${skyLabel('h4')}` },
      { encoding: 'h6', albedo: state.albedo, label: `H6${skyLabel('h6')}` }];
  }
  const e = state.encoding;
  return [{ encoding: e, albedo: state.albedo, label: `${NAMES[e]}${e === head.encoding ? '' : ' (implied by the stored ' + NAMES[head.encoding] + ')'}${state.albedo ? ', with albedo' : ', without albedo'}${skyLabel(e)}` }];
}

function skyLabel(e) {
  if (!head.transfer) return '';
  if (!state.relight) return ', baked sky';
  if (!relighters[e]) return ', baked sky (this encoding is not relit)';
  const k = state.sky;
  return `, sky turned ${k.azimuth.toFixed(0)}° tilted ${k.elevation.toFixed(0)}°`;
}

// the relit encodings' textures: from the transfer under the turned sky, or the bake's
function relight() {
  const L = head.transfer && state.relight ? turnedSky(head.transfer.sky, state.sky) : null;
  for (const [e, r] of Object.entries(relighters)) {
    if (L) r.relight(L);
    coeff[e] = L ? r.textures : baked[e];
  }
}

function draw(target = null, debug = DEBUG.picture) {
  const ps = panels(), w = Math.floor(W / ps.length);
  renderer.setRenderTarget(target);
  renderer.setScissorTest(true);
  renderer.setClearColor(0x202020, 1);
  ps.forEach((p, i) => {
    const x = i * w, pw = i === ps.length - 1 ? W - x : w;
    renderer.setViewport(x, 0, pw, H);
    renderer.setScissor(x, 0, pw, H);
    camera.aspect = pw / H;
    camera.updateProjectionMatrix();
    for (const mesh of meshes) {
      const m = material(p.encoding, mesh.userData.material);
      coeff[p.encoding].forEach((t, i) => { m.uniforms[`t${i}`].value = t; });
      Object.assign(m.uniforms.albedoOn, { value: p.albedo });
      m.uniforms.gridOn.value = state.grid && target === null;
      m.uniforms.exposure.value = state.exposure;
      m.uniforms.debugOut.value = debug;
      mesh.material = m;
    }
    renderer.render(scene, camera);
  });
  renderer.setScissorTest(false);
  renderer.setRenderTarget(null);
  const labels = $('panellabels');
  labels.replaceChildren(...ps.map((p) => {
    const d = document.createElement('div');
    d.textContent = p.label;
    d.style.width = `${100 / ps.length}%`;
    return d;
  }));
  api.panels = ps;
}

// float values of a debug output (DEBUG.*) at canvas pixels [[x, y], ...] (y down)
api.readback = (kind, pixels) => {
  const rt = floatTarget(W, H);
  draw(rt, DEBUG[kind]);
  const out = [], px = new Float32Array(4);
  for (const [x, y] of pixels) {
    renderer.readRenderTargetPixels(rt, x, H - 1 - y, 1, 1, px);
    out.push([px[0], px[1], px[2]]);
  }
  rt.dispose();
  draw();
  return out;
};
api.set = (s) => {
  const sky = { ...state.sky, ...(s.sky || {}) };
  Object.assign(state, s, { sky, relight: head.transfer ? (s.relight ?? state.relight) : false });
  if (s.sky || 'relight' in s) relight();
  if (s.eye) camera.position.set(...s.eye);
  if (s.target) controls.target.set(...s.target);
  controls.update();
  syncControls();
  draw();
  return { ...state, panels: api.panels };
};

function syncControls() {
  $('layout').value = state.layout;
  $('encoding').value = state.encoding;
  $('albedo').checked = state.albedo;
  $('grid').checked = state.grid;
  $('exposure').value = String(state.exposure);
  $('expval').textContent = state.exposure.toFixed(2);
  if (!head.transfer) return;
  $('relight').checked = state.relight;
  for (const k of Object.keys(state.sky)) {
    if (!$(`sky_${k}`)) continue;
    $(`sky_${k}`).value = String(state.sky[k]);
    $(`sky_${k}_val`).textContent = state.sky[k].toFixed(k === 'azimuth' || k === 'elevation' ? 0 : 2);
  }
}

// a relit coefficient texture t read back as floats (× head.scale: coefficients)
api.relitTexels = (t, e = head.encoding) => Array.from(relighters[e].read(t));
api.turnedSky = () => turnedSky(head.transfer.sky, state.sky);

function skyControls() {
  $('skybox').hidden = false;
  $('skysrc').textContent = head.transfer.sky_source === 'stored' ? 'the sky of the bake'
    : 'the sky fitted to the stored lightmap (the file does not store its sky)';
  $('relight').addEventListener('change', (ev) => api.set({ relight: ev.target.checked }));
  for (const k of Object.keys(state.sky)) {
    $(`sky_${k}`)?.addEventListener('input', (ev) => api.set({ sky: { [k]: Number(ev.target.value) } }));
  }
  $('skyreset').addEventListener('click', () => api.set({ sky: { azimuth: 0, elevation: 0, l0: 1,
    l1: 1, l2: 1, stops: 0 } }));
}

function buildScene(g) {
  scene = new THREE.Scene();
  const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
  for (const p of primitives(g)) {
    const mesh = new THREE.Mesh(primitiveGeometry(p));
    mesh.userData.material = p.material ?? -1;
    scene.add(mesh);
    meshes.push(mesh);
    for (let i = 0; i < p.position.length; i += 3) {
      for (let k = 0; k < 3; k++) {
        lo[k] = Math.min(lo[k], p.position[i + k]); hi[k] = Math.max(hi[k], p.position[i + k]);
      }
    }
  }
  if (!meshes.length) throw new Error('the file has no primitive with TEXCOORD_1');
  const size = hi.map((h, k) => h - lo[k]), diag = Math.hypot(...size);
  const target = [lo[0] + 0.55 * size[0], lo[1] + 0.25 * size[1], lo[2] + 0.6 * size[2]];
  camera = new THREE.PerspectiveCamera(60, W / H, diag * 1e-3, diag * 4);
  camera.position.set(lo[0] + 0.15 * size[0], lo[1] + 0.3 * size[1] + 0.08 * diag,
    lo[2] + 0.1 * size[2]);
  controls = new OrbitControls(camera, renderer.domElement);
  controls.target.set(...target);
  controls.update();
  controls.addEventListener('change', () => draw());
}

async function start() {
  const canvas = $('view');
  renderer = new THREE.WebGLRenderer({ canvas, antialias: false, preserveDrawingBuffer: true });
  renderer.setPixelRatio(1);
  renderer.setSize(W, H, false);
  const [msgBuf, glbBuf] = await Promise.all([fetchOk('/api/lightmap'),
    fetchOk('/api/lightmap/scene.glb')]);
  const msg = unpack(msgBuf);
  head = msg.head;
  const g = parseGlb(glbBuf);
  const stored = lightmapTextures(g);
  for (const e of head.encodings) {
    const data = e === head.encoding ? stored.textures
      : head.layouts[e].map((_, t) => msg[`${e}_${t}`]);
    coeff[e] = data.map((d) => halfTexture(d, head.width, head.height));
  }
  if (head.transfer) {
    const half = (d) => halfTexture(d, head.width, head.height);
    const relighter = (e, sets, scale) => {
      baked[e] = coeff[e];
      relighters[e] = new Relighter(renderer, sets.map((set) => set.map(half)), head.layouts[e],
        [head.width, head.height], scale, head.scale);
    };
    relighter(head.encoding, transferTextures(g), head.transfer.scale);
    for (const [e, scale] of Object.entries(head.transfer.implied)) {
      if (!head.encodings.includes(e)) continue;
      relighter(e, Array.from({ length: 9 }, (_, j) => head.layouts[e].map((_, t) =>
        msg[`${e}_T${j}_${t}`])), scale);
    }
    state.relight = true;
    relight();
  }
  mats = materials(g);
  mats.fallback = { baseColor: [1, 1, 1, 1], normalScale: 1 };
  const images = new Map();
  const image = async (i) => {
    if (i === null) return null;
    if (!images.has(i)) images.set(i, byteTexture(await imagePixels(g, i)));
    return images.get(i);
  };
  maps = await Promise.all(mats.map(async (m) => ({ base: await image(m.baseImage),
    normal: await image(m.normalImage) })));
  buildScene(g);
  state.encoding = head.encodings.includes('h6') ? 'h6' : head.encoding;
  state.exposure = head.exposure;
  const sel = $('encoding');
  sel.replaceChildren(...head.encodings.map((e) => {
    const o = document.createElement('option');
    o.value = e;
    o.textContent = NAMES[e] + (e === head.encoding ? ' (stored)' : '');
    return o;
  }));
  $('layout').querySelector('[value=fig1]').disabled = !(head.encodings.includes('h6'));
  $('layout').querySelector('[value=fig5]').disabled = !(head.encodings.includes('h4')
    && head.encodings.includes('h6'));
  $('name').textContent = head.name;
  $('info').textContent = `${NAMES[head.encoding]} · ${head.width}×${head.height} texels · scale ${head.scale}`;
  $('layout').addEventListener('change', (ev) => api.set({ layout: ev.target.value }));
  $('encoding').addEventListener('change', (ev) => api.set({ encoding: ev.target.value }));
  $('albedo').addEventListener('change', (ev) => api.set({ albedo: ev.target.checked }));
  $('grid').addEventListener('change', (ev) => api.set({ grid: ev.target.checked }));
  $('exposure').addEventListener('input', (ev) => api.set({ exposure: Number(ev.target.value) }));
  $('autoexp').addEventListener('click', () => api.set({ exposure: head.exposure }));
  if (head.transfer) skyControls();
  syncControls();
  draw();
  api.head = head;
  api.ready = true;
}

start().catch(showError);
