// Colour scales and their legends: one heat map (the same stops for the object's error shader,
// the legend bars and the H-basis error panels), errors always in % of ∫L dω (R&H §3.1, the
// unit of `shprobe error`), and the H-basis view's labelled panels.

const $ = (id) => document.getElementById(id);

// the heat map: value 0 … 1 of the scale → linear RGB 0 … 1, piecewise linear between stops
export const HEAT_STOPS = [[0.05, 0.03, 0.2], [0.2, 0.2, 0.8], [0.1, 0.7, 0.5], [0.95, 0.85, 0.1], [1, 1, 1]];
const f = (v) => v.toFixed(3);
export const HEAT_GLSL = `vec3 heat(float x) {  // the legend's colour map (legend.js HEAT_STOPS)
  x = clamp(x, 0.0, 1.0) * ${f(HEAT_STOPS.length - 1)};
  ${HEAT_STOPS.slice(0, -1).map((c, i) => `if (x <= ${f(i + 1)}) return mix(vec3(${c.map(f)}), vec3(${HEAT_STOPS[i + 1].map(f)}), x - ${f(i)});`).join('\n  ')}
  return vec3(${HEAT_STOPS[HEAT_STOPS.length - 1].map(f)}); }
`;
export function heatRGB(x) {  // → [r, g, b] 0 … 255
  const t = Math.min(Math.max(x, 0), 1) * (HEAT_STOPS.length - 1);
  const i = Math.min(Math.floor(t), HEAT_STOPS.length - 2), u = t - i;
  return HEAT_STOPS[i].map((a, c) => Math.round(255 * (a + (HEAT_STOPS[i + 1][c] - a) * u)));
}
export const HEAT_CSS = `linear-gradient(to right, ${HEAT_STOPS.map((c) => `rgb(${c.map((v) => Math.round(255 * v)).join(',')})`).join(', ')})`;

// a fraction of ∫L dω as the page writes it everywhere (legend ticks and tables alike)
export const pct = (frac) => `${(100 * frac).toFixed(3)} %`;

// the compare views' legend: the heat bar only where the object is a heat map (error), the
// table in every compare view with the row of the degree shown marked
export function showCompareLegend(mode, cmp, errLmax) {
  const compare = mode === 'error' || mode.startsWith('sh') || mode === 'exact';
  $('legend').hidden = !compare || !cmp;
  if (!cmp || !compare) return null;
  const shown = mode === 'error' ? errLmax : mode.startsWith('sh') ? Number(mode.slice(2)) : null;
  const row = cmp.rows.find((r) => r.lmax === (shown ?? errLmax));
  $('legendscale').hidden = mode !== 'error';
  $('legendbar').style.background = HEAT_CSS;
  $('legendtitle').innerHTML = mode === 'error'
    ? `Error of SH lmax ${row.lmax}: |E<sub>SH</sub> − E<sub>exact</sub>| in % of ∫L dω (R&amp;H §3.1 metric, as <code>shprobe error</code>; max over R, G, B; the probe itself, edits not applied); colour scale 0 … the max`
    : mode === 'exact' ? 'The exact irradiance (brute force); the SH errors of each degree, in % of ∫L dω (as <code>shprobe error</code>)'
      : `SH lmax ${row.lmax} (this view): its error against the exact irradiance in the marked row, % of ∫L dω (as <code>shprobe error</code>)`;
  $('legendmid').textContent = pct(row.max_frac / 2);
  $('legendmax').textContent = pct(row.max_frac);
  const body = $('errtable').tBodies[0]; body.innerHTML = '';
  for (const r of cmp.rows) {
    const tr = body.insertRow(); tr.dataset.lmax = r.lmax;
    if (r.lmax === shown) tr.className = 'current';
    for (const v of [String(r.lmax), pct(r.mean_frac), pct(r.max_frac)]) tr.insertCell().textContent = v;
  }
  return row;
}

// ---------------------------------------------------------------- H-basis panels
const srgb8 = (v) => { v = Math.min(Math.max(v, 0), 1); return Math.round(255 * (v < 0.0031308 ? 12.92 * v : 1.055 * v ** (1 / 2.4) - 0.055)); };
function panelCanvas(id, caption) {
  const fig = document.createElement('figure');
  const c = document.createElement('canvas'); c.id = id;
  const cap = document.createElement('figcaption'); cap.textContent = caption;
  fig.append(c, cap); $('hbpanels').append(fig);
  return c;
}
function paint(c, h, w, px) {
  c.width = w; c.height = h;
  const ctx = c.getContext('2d'), img = ctx.createImageData(w, h);
  for (let i = 0; i < h * w; i++) { const p = px(i); img.data.set([p[0], p[1], p[2], 255], 4 * i); }
  ctx.putImageData(img, 0, 0);
}
// r: the server's message (views.hbasis_panel): E/π per basis, errors as fractions of ∫L dω
export function drawHBasis(r, exposure) {
  const h = r.head, [H, W] = h.size, mask = r.mask;
  const gain = 2 ** (h.stops + exposure);
  $('hbpanels').innerHTML = '';
  const bases = h.keys.filter((k) => k !== 'reference');
  const top = Math.max(...bases.map((k) => h.max_frac[k])) || 1;
  const cols = h.keys.length;
  $('hbpanels').style.gridTemplateColumns = `repeat(${cols}, minmax(0, 1fr))`;
  // the panels' exposure: the reference's own (auto) plus the page's slider, both named (a
  // total alone would not match the slider beside it)
  const sign = exposure < 0 ? '−' : '+';
  const stops = `E/π at ${(h.stops + exposure).toFixed(2)} stops (auto ${h.stops.toFixed(2)} ${sign} slider ${Math.abs(exposure).toFixed(2)})`;
  for (const k of h.keys) {
    const a = r[k];
    const label = k === 'reference' ? `${h.labels[k]} (${h.reference})` : h.labels[k];
    paint(panelCanvas(`hb-${k}`, `${label}, ${stops}`), H, W,
      (i) => (mask[i] ? [srgb8(a[3 * i] * gain), srgb8(a[3 * i + 1] * gain), srgb8(a[3 * i + 2] * gain)] : [0, 0, 0]));
  }
  const note = document.createElement('figure');  // the reference has no error panel
  note.innerHTML = '<figcaption>error panels: |basis − reference| on the heat scale below</figcaption>';
  $('hbpanels').append(note);
  for (const k of bases) {
    const e = r['err_' + k];
    paint(panelCanvas(`hb-err-${k}`, `|${k} − reference|: max ${pct(h.max_frac[k])}, mean ${pct(h.mean_frac[k])} of ∫L dω`), H, W,
      (i) => (mask[i] ? heatRGB(e[i] / top) : [0, 0, 0]));
  }
  $('hblegendtitle').innerHTML = 'Error |E<sub>basis</sub> − E<sub>reference</sub>| in % of ∫L dω (max over R, G, B; as the compare view and <code>shprobe error</code>); one scale for every error panel';
  $('hblegendbar').style.background = HEAT_CSS;
  $('hblegendmid').textContent = pct(top / 2);
  $('hblegendmax').textContent = pct(top);
  $('hbtable').innerHTML = '<caption>per basis, over the object\'s pixels</caption><tr><th>basis</th><th>max (% of ∫L dω)</th><th>mean (% of ∫L dω)</th><th>relative RMS (% of RMS E)</th></tr>'
    + bases.map((k) => `<tr><td>${k}</td><td>${pct(h.max_frac[k])}</td><td>${pct(h.mean_frac[k])}</td><td>${pct(h.rel_rms[k])}</td></tr>`).join('');
  return top;
}
