// The designer page's library views: compare (the library's brute-force and SH irradiance
// tables by normal, R&H's error per degree; /api/compare, polled with its progress) and the
// H-basis panels (/api/hbasis, the library's render after each settled edit).
import { $, api, call, setStatus, showError } from './api.js';
import { drawHBasis, showCompareLegend } from './legend.js';
import { floatTex } from './shaders.js';

// ``P``: the page (viewer.js); the tables become lookup textures of its object programs
export async function loadCompare(P) {
  if (P.cmp) return;
  $('progress').hidden = false;
  for (;;) {
    const r = await call('/api/compare');
    if (r.head) {  // done: binary tables
      const [h, w] = r.head.grid;
      P.lookTex.reference = floatTex(r.reference, h, w);
      for (let l = 1; l <= 4; l++) if (r['sh' + l]) P.lookTex['sh' + l] = floatTex(r['sh' + l], h, w);
      P.cmp = r.head;
      P.programs.object('exact');  // the shared uniforms exist
      P.programs.obj.uTot.value.set(...P.cmp.total_intensity);
      break;
    }
    if (r.status === 'error') { $('progress').hidden = true; throw new Error(r.error); }
    $('progressbar').style.width = `${(100 * r.done).toFixed(0)}%`;
    $('progresstext').textContent = `exact irradiance (brute force, library): ${(100 * r.done).toFixed(0)}%`;
    await new Promise((res) => setTimeout(res, 150));
  }
  $('progress').hidden = true;
  api.compare = P.cmp;
}

export function showLegend(P) {  // legend.js: the heat scale in % of ∫L dω, the table in the same unit
  const row = showCompareLegend($('mode').value, P.cmp, Number($('errlmax').value));
  if (row && $('mode').value === 'error') P.programs.obj.uErrMax.value = row.max_frac;
}

const HB_REF = 'brute force over the probe';
let hbBusy = false, hbAgain = false, hbLast = null;
export async function updateHBasis(P) {  // the library's render (server), after each settled edit
  if ($('mode').value !== 'hbasis') return;
  if (hbBusy) { hbAgain = true; return; }
  hbBusy = true;
  try {
    do {
      hbAgain = false;
      setStatus('H-basis render…');
      const r = await call('/api/hbasis', { method: 'POST', body: JSON.stringify(P.history.state) });
      hbLast = r;
      $('hblabel').innerHTML = r.head.baked
        ? `H-basis bake <code>${api.init.hbasis ? api.init.hbasis.name : ''}</code> (<code>shprobe hbasis bake</code>): its per-vertex coefficients under the lighting they were baked for (edits do not apply: bake again), as <code>shprobe hbasis render MESH FILE.npz</code>; E/π of a white surface with a procedural bump`
        : `Irradiance normal mapping (Habel &amp; Wimmer 2010, as <code>shprobe hbasis render</code>): E/π of a white surface with a procedural bump, per-vertex bases baked from the current lighting (lmax 4, edits and rotation applied) against ${r.head.reference === HB_REF ? 'the exact E(n′), brute force over the probe (turned)' : 'E(n′) of the edited lighting\'s SH expansion'}; recomputed by the library after each edit`;
      api.hbasisErrMax = drawHBasis(r, Number($('exposure').value));
      api.hbasis = r.head.rel_rms; api.hbasisHead = r.head;
      setStatus('');
    } while (hbAgain);
  } catch (e) { showError(e); }
  hbBusy = false;
}

export function redrawHBasis() {  // the same panels at a new exposure
  if (hbLast && $('mode').value === 'hbasis') drawHBasis(hbLast, Number($('exposure').value));
}
