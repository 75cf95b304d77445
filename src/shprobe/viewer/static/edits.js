// The designer page's edit controls wired to its history (history.js): the degree, band and
// coefficient scales (controls.js), lights, blends, window, the source's weight, exports,
// uploads and presets, PRT options; each change is one commit (undoable, recomputed).
import { $, clearError, showError } from './api.js';
import { buildSliders, fillSelect, showForMode } from './controls.js';
import { EMPTY } from './history.js';
import { exportFormat, setPreset, upload, uploadCube } from './files.js';
import { unrotate } from './rotation.js';

const nums = (id, n) => {
  const v = $(id).value.split(',').map(Number);
  if (v.length !== n || v.some((x) => !Number.isFinite(x))) throw new Error(`${id}: expected ${n} comma-separated numbers`);
  return v;
};

// ``P``: the page (viewer.js); P.history holds the state
export class Edits {
  constructor(P) {
    this.P = P;
    this.degrees = 8; this.bakedLmax = null;  // the design's degrees; a transfer's (marked)
    this.probeNames = {}; this.presetNames = [];
  }

  // the controls showing the current state
  refresh() {
    const H = this.P.history, state = H.state;
    const range = (n) => Array.from({ length: n + 1 }, (_, l) => l);
    fillSelect($('lmax'), range(this.degrees), state.lmax, (l) => (l === this.bakedLmax ? `${l} (the transfer's)` : String(l)));
    buildSliders(state,
      (l, v) => { const s = H.edit(); s.scale_band[l] = v; H.commit(s); },
      (l, m, v) => { const s = H.edit(); s.scale[`${l},${m}`] = v; H.commit(s); });
    const ul = $('lights'); ul.innerHTML = '';
    const item = (text, drop) => {
      const li = document.createElement('li'); li.textContent = text + ' ';
      const b = document.createElement('button'); b.textContent = 'remove';
      b.onclick = () => { const s = H.edit(); drop(s); H.commit(s); };
      li.append(b); ul.append(li);
    };
    state.directional.forEach((d, i) => item(`directional (${d.dir.map((v) => v.toFixed(2))}) rgb ${d.rgb}`, (s) => s.directional.splice(i, 1)));
    state.cone.forEach((d, i) => item(`cone (${d.dir.map((v) => v.toFixed(2))}) ${d.aperture_deg}° rgb ${d.rgb}`, (s) => s.cone.splice(i, 1)));
    if (state.sky) item(`hemisphere sky ${state.sky.sky} ground ${state.sky.ground}`, (s) => { s.sky = null; });
    state.blends.forEach((b, i) => item(`blend ${b.preset ? 'preset ' + b.preset : 'probe ' + (this.probeNames[b.probe] || b.probe)} × ${b.weight}`, (s) => s.blends.splice(i, 1)));
    $('weight').value = state.weight;
    const w = state.window || ''; $('window').value = w.includes(':') ? w.split(':')[0] : w;
    if (w.includes(':')) $('wstrength').value = Number(w.split(':')[1]);
  }

  // blend sources: the presets and every probe this server loaded (command line, uploads), by id
  blendOptions(presets, probes) {
    if (presets) this.presetNames = presets;
    const sel = $('bpreset'), keep = sel.value; sel.innerHTML = '';
    for (const p of this.presetNames) sel.add(new Option(`preset ${p}`, `preset:${p}`));
    this.probeNames = {};
    for (const p of probes || []) { this.probeNames[p.id] = p.name; sel.add(new Option(`probe ${p.name}`, `probe:${p.id}`)); }
    if ([...sel.options].some((o) => o.value === keep)) sel.value = keep;
  }

  wire(init) {
    const P = this.P, H = P.history;
    const change = (f) => { const s = H.edit(); f(s); H.commit(s); };
    $('undo').onclick = () => H.undo(); $('redo').onclick = () => H.redo();
    $('reset').onclick = () => H.commit({ ...structuredClone(EMPTY), lmax: H.state.lmax });
    this.degrees = init.design_lmax ?? this.degrees;
    fillSelect($('errlmax'), Array.from({ length: init.compare_lmax ?? 4 }, (_, i) => i + 1), $('errlmax').value);
    $('lmax').onchange = () => change((s) => {  // the design's degree (scales above it are dropped)
      s.lmax = Number($('lmax').value);
      for (const k of Object.keys(s.scale)) if (Number(k.split(',')[0]) > s.lmax) delete s.scale[k];
      for (const k of Object.keys(s.scale_band)) if (Number(k) > s.lmax) delete s.scale_band[k];
    });
    const guard = (f) => () => { try { f(); clearError(); } catch (e) { showError(e); } };
    $('adddir').onclick = guard(() => change((s) => s.directional.push({ dir: unrotate(H.state, nums('ldir', 3)), rgb: nums('lrgb', 3) })));
    $('addcone').onclick = guard(() => change((s) => s.cone.push({ dir: unrotate(H.state, nums('ldir', 3)), aperture_deg: nums('lap', 1)[0], rgb: nums('lrgb', 3) })));
    $('addsky').onclick = guard(() => change((s) => { s.sky = { sky: nums('lrgb', 3), ground: [0, 0, 0], up: unrotate(H.state, nums('ldir', 3)) }; }));
    $('weight').onchange = () => change((s) => { s.weight = Number($('weight').value); });
    for (const p of init.presets) $('srcpreset').add(new Option(p, p));
    this.blendOptions(init.presets, init.probes);
    $('addblend').onclick = () => change((s) => {
      const [kind, name] = $('bpreset').value.split(/:(.*)/s);
      s.blends.push({ [kind]: name, weight: Number($('bweight').value) });
    });
    for (const w of init.windows) $('window').add(new Option(w, w));
    const setWindow = () => change((s) => { const k = $('window').value; s.window = !k ? null : k === 'auto' ? 'auto' : `${k}:${Number($('wstrength').value)}`; });
    $('window').onchange = setWindow; $('wstrength').onchange = setWindow;
    for (const f of init.formats) {
      const b = document.createElement('button'); b.textContent = f; b.id = 'export-' + f;
      b.onclick = () => exportFormat(P, f).catch(showError); $('exports').append(b);
    }
    for (const kind of ['probe', 'blend', 'mesh', 'coeffs', 'transfer', 'hbasis']) {
      const input = $('up' + kind); input.onchange = () => upload(P, kind, input);
    }
    $('loadcube').onclick = () => uploadCube(P);
    $('srcpreset').onchange = async () => {
      if (!$('srcpreset').value) return;
      try { await setPreset(P, $('srcpreset').value); } catch (e) { showError(e); }
    };
    if (init.transfer) this.wirePRT(init.transfer);
  }

  wirePRT(t) {  // a transfer (command line or upload): its modes, bounces and degrees
    const P = this.P;
    const o = $('mode').querySelector('option[value=prt]'); o.disabled = false;
    $('prtmode').innerHTML = '';
    for (const m of t.modes) $('prtmode').add(new Option(m, m));
    $('prtmode').value = t.mode; $('prtbounces').value = t.max_bounces || 0;
    $('prtbounces').max = t.max_bounces || 0;
    this.bakedLmax = t.lmax; this.refresh();
    const reload = async () => {
      showForMode($('mode').value, $('prtmode').value);
      try { await P.loadTransfer($('prtmode').value, $('prtbounces').value); clearError(); P.draw(); } catch (e) { showError(e); }
    };
    $('prtmode').onchange = reload; $('prtbounces').onchange = reload; $('prtlmax').onchange = () => P.draw();
  }
}
