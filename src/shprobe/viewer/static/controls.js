// The edit controls that follow the data: a band slider for every l ≤ lmax, a coefficient
// slider for every L_lm grouped by band (bands above l = 2 collapsed), the degree menus
// filled with every degree the data supports, and only the controls that apply to the view.

const $ = (id) => document.getElementById(id);

function slider(parent, label, value, onchange, attrs) {
  const lab = document.createElement('span'); lab.textContent = label;
  const inp = document.createElement('input'); inp.type = 'range'; inp.min = -2; inp.max = 3; inp.step = 0.05; inp.value = value;
  Object.assign(inp.dataset, attrs); inp.title = label;
  const val = document.createElement('span'); val.textContent = Number(value).toFixed(2);
  inp.oninput = () => { val.textContent = Number(inp.value).toFixed(2); };
  inp.onchange = () => onchange(Number(inp.value));
  parent.append(lab, inp, val);
}

const OPEN_BANDS = 2;  // bands above this start collapsed (2l+1 sliders each)
const opened = {};     // a band the user opened or closed stays so across redraws

// band sliders l = 0..lmax and per-coefficient sliders L_lm grouped by band, for ``state``;
// onBand(l, v) / onCoeff(l, m, v) commit an edit
export function buildSliders(state, onBand, onCoeff) {
  const bands = $('bandsliders'), coeffs = $('sliders');
  bands.innerHTML = ''; coeffs.innerHTML = '';
  for (let l = 0; l <= state.lmax; l++) {
    slider(bands, `band ${l}`, state.scale_band[l] ?? 1, (v) => onBand(l, v), { band: l, kind: 'band' });
    const d = document.createElement('details'); d.className = 'band'; d.dataset.band = l;
    d.open = opened[l] ?? l <= OPEN_BANDS;
    d.ontoggle = () => { opened[l] = d.open; };
    const s = document.createElement('summary'); s.textContent = `band l = ${l}: ${2 * l + 1} coefficient${l ? 's' : ''} L${l},m, m = ${-l} … ${l}`;
    const grid = document.createElement('div'); grid.className = 'sliders';
    for (let m = -l; m <= l; m++) {
      slider(grid, `L${l},${m}`, state.scale[`${l},${m}`] ?? 1, (v) => onCoeff(l, m, v), { band: l, m, kind: 'coeff' });
    }
    d.append(s, grid); coeffs.append(d);
  }
}

// a <select> holding exactly ``values`` (labels via ``label``), keeping ``keep`` when offered
export function fillSelect(sel, values, keep, label = String) {
  const want = values.map(String);
  if ([...sel.options].map((o) => o.value).join() !== want.join()) {
    sel.innerHTML = '';
    for (const v of values) sel.add(new Option(label(v), String(v)));
  }
  if (want.includes(String(keep))) sel.value = String(keep);
}

// show only what applies: the design degree where the design is drawn, the error degree in
// the error view, the bounces of the interreflected model, the 3-D view outside the H-basis
// panels (which take its place)
export function showForMode(mode, prtMode) {
  const compare = mode === 'error' || mode === 'exact' || mode.startsWith('sh');
  $('lmaxlabel').hidden = compare || mode === 'hbasis';  // the H-basis view bakes at lmax 4
  $('errlmaxlabel').hidden = mode !== 'error';
  $('prtbounceslabel').hidden = prtMode !== 'interreflected';
  $('prtbox').hidden = mode !== 'prt' || $('prtmode').options.length === 0;
  $('viewwrap').hidden = mode === 'hbasis';
  $('resetview').hidden = mode === 'hbasis';
  $('hbbox').hidden = mode !== 'hbasis';
}
