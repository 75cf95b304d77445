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
    background: fetch('/api/background'),
  };
  window.__boot['design:' + body] = fetch('/api/design', { method: 'POST', body });
})();
