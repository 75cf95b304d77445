// The designer page's files: exports (the server's export of the same edit state, a download
// named as `shprobe edit` names its file), uploads of probes, cube faces, blends, meshes,
// coefficients, PRT transfers and H-basis bakes, and the lighting source they replace.
import { $, api, call, clearError, first, setStatus, showError } from './api.js';
import { halfTex } from './shaders.js';

// ``P``: the page (viewer.js)
export async function exportFormat(P, fmt) {
  const r = await call('/api/export/' + fmt, { method: 'POST', body: JSON.stringify(P.history.state) });
  const blob = await r.blob();
  const name = (r.headers.get('content-disposition') || '').match(/filename="([^"]+)"/)?.[1] || 'shprobe.txt';
  const a = document.createElement('a'); a.href = URL.createObjectURL(blob); a.download = name;
  document.body.append(a); a.click(); a.remove();
  api.lastExport = await blob.text();
}

export async function upload(P, kind, input) {
  const f = input.files[0]; if (!f) return;
  setStatus(`loading ${f.name}…`);
  try {
    const r = await call('/api/upload/' + kind, { method: 'POST', body: f, headers: { 'X-Filename': f.name } });
    if (r.probes) P.blendOptions(null, r.probes);
    if (kind === 'blend') {  // blend the uploaded probe in at the weight given
      const s = P.history.edit(); s.blends.push({ probe: r.probe_id, weight: Number($('bweight').value) }); P.history.commit(s);
    }
    if (kind === 'probe' || kind === 'coeffs') await newSource(P, r.source);
    if (kind === 'transfer') { P.prt = null; P.wirePRT(r.transfer); $('mode').value = 'prt'; await P.onMode(); }
    if (kind === 'hbasis') { api.init.hbasis = r.hbasis; $('mode').value = 'hbasis'; await P.onMode(); await P.updateHBasis(); }
    if (kind === 'mesh') { const g = await call('/api/mesh'); P.setGeometry(g, g.head.camera); $('meshname').textContent = g.head.name; P.draw(); }
    clearError();
  } catch (e) { showError(e); }  // the edit state and the current source are kept
  setStatus(''); input.value = '';
}

export async function uploadCube(P) {  // six faces +X −X +Y −Y +Z −Z in one request (wire.unpack_files)
  const files = [0, 1, 2, 3, 4, 5].map((i) => $('face' + i).files[0]).filter(Boolean);
  const head = new TextEncoder().encode(JSON.stringify({ files: files.map((f) => ({ name: f.name, size: f.size })) }));
  const len = new Uint8Array(4); new DataView(len.buffer).setUint32(0, head.length, true);
  setStatus('loading cube faces…');
  try {
    const r = await call('/api/upload/cube', { method: 'POST', body: new Blob([len, head, ...files]) });
    await newSource(P, r.source);
    clearError();
  } catch (e) { showError(e); }  // the edit state and the current source are kept
  setStatus('');
}

export async function setPreset(P, name) {
  const r = await call('/api/upload/preset?name=' + encodeURIComponent(name), { method: 'POST' });
  await newSource(P, r.source);
}

export function probeLabel(src) {  // a preset or coefficients have no picture: the panel says so
  $('probelabel').textContent = src.has_env ? 'Probe (lat-long, +Y up, centre −Z; drag to rotate the lighting)'
    : `Probe: ${src.name} has no image (grey here); drag to rotate the lighting, which the irradiance map below shows`;
}

export async function newSource(P, src) {
  $('source').textContent = src.name; probeLabel(src);
  P.cmp = null; P.bgTex = null;
  if (src.has_env) await loadBackground(P);
  if ($('mode').value !== 'design' && $('mode').value !== 'prt') $('mode').value = 'design';
  P.showLegend(); await P.requestDesign();
}

export async function loadBackground(P) {  // linear float radiance, bilinear (Env.sample's filter)
  const r = await first('background', () => call('/api/background'));
  const [h, w] = r.head.arrays.radiance.shape;  // RGBA half floats, row 0 = +Y
  P.bgTex = halfTex(r.radiance, h, w);
}
