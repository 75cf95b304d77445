// PRT relighting in the designer page (Lisle & Huang §4): the server's per-vertex transfer
// (/api/transfer, a `shprobe prt bake` file) times the current, already rotated lighting, per
// vertex, in the page — exit radiance_v,c = Σ_k T[v,k(,c)] L[k,c].
import { $, api, call, setStatus } from './api.js';
import { fillSelect } from './controls.js';

// ``P``: the page (viewer.js): its geometry is replaced by the transfer's own
export async function loadTransfer(P, mode, bounces) {
  const q = new URLSearchParams(); if (mode) q.set('mode', mode); if (bounces !== '' && bounces != null && mode === 'interreflected') q.set('bounces', bounces);
  setStatus('loading transfer…');
  const r = await call('/api/transfer?' + q);
  const h = r.head, nv = r.position.length / 3;
  const kfull = (h.lmax + 1) ** 2, per = r.transfer.length / (nv * kfull);
  P.prt = { T: r.transfer, nv, kfull, coloured: per === 3, lmax: h.lmax, out: new Float32Array(nv * 3), head: h };
  if (!P.meshObj || P.meshObj.geometry.attributes.position.count !== nv) P.setGeometry(r, h.camera);
  const ls = $('prtlmax'); if (ls.options.length !== h.lmax + 1) fillSelect(ls, Array.from({ length: h.lmax + 1 }, (_, l) => l), h.lmax);
  $('meshname').textContent = `${h.name} (PRT)`;
  $('prtinfo').textContent = `${h.name}: ${nv} vertices, baked lmax ${h.lmax}, ${h.mode}${h.max_bounces ? `, up to ${h.max_bounces} bounces` : ''}`;
  setStatus('');
  api.prt = P.prt;
}

export function relightPRT(P) {  // the lighting already rotated
  const prt = P.prt, coeffs = P.coeffs;
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
  const a = P.meshObj.geometry.attributes.prtColor; a.array.set(out); a.needsUpdate = true;
  api.prtRelightMs = performance.now() - tp; api.prtLmax = l;
}

api.prtRadiance = (v) => (api.prt ? Array.from(api.prt.out.slice(3 * v, 3 * v + 3)) : null);
