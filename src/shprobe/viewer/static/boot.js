// Starts the page's first requests while the module scripts (three.js) load and parse; viewer.js
// picks the responses up (window.__boot). The first design request carries the saved edit state.
(function () {
  const api = window.__shprobe = { lastError: null };
  window.addEventListener('error', (e) => { api.lastError = String(e.message || e); });
  const saved = (() => { try { return localStorage.getItem('shprobe-view-state'); } catch (e) { return null; } })();
  const EMPTY = { lmax: 2, weight: 1, blends: [], directional: [], cone: [], sky: null,
                  scale: {}, scale_band: {}, rotation: null, window: null };
  let state = EMPTY;
  if (saved) { try { state = Object.assign({}, EMPTY, JSON.parse(saved)); } catch (e) { state = EMPTY; } }
  const body = JSON.stringify(state);
  window.__boot = {
    shaders: fetch('/api/shaders'),
    init: fetch('/api/init'),
    mesh: fetch('/api/mesh'),
  };
  window.__boot['design:' + body] = fetch('/api/design', { method: 'POST', body });
  // The object's WebGL context, made now (with the attributes three.js's WebGLRenderer asks
  // for) and drawn to once: a software GL's start-up, a few tenths of a second, then runs
  // while three.js downloads and compiles. viewer.js puts this canvas in place of #view.
  try {
    const c = document.createElement('canvas');
    c.id = 'view'; c.width = 512; c.height = 512;
    const gl = c.getContext('webgl2', { alpha: true, depth: true, stencil: false, antialias: false,
      premultipliedAlpha: true, preserveDrawingBuffer: true, powerPreference: 'default',
      failIfMajorPerformanceCaveat: false });
    if (gl) {
      gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
      // flushed, not read back (a GPU stall): the GPU process runs it while the page loads;
      // a benchmark (&bench=1) waits for it, as it waits for every frame it times
      if (new URLSearchParams(window.location.search).has('bench')) gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, new Uint8Array(4));
      else gl.flush();
      window.__boot.canvas = c; window.__boot.gl = gl;
    }
  } catch (e) { /* viewer.js makes its own */ }
})();
