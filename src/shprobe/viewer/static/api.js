// The pages' one client of the server, shared by the designer page (viewer.js) and the grid
// page (grid.js): requests whose failures are the server's one-line {"error": ...}, binary
// answers read by wire.js, the error line and the status shown on the page, and the object
// tests and benchmarks read (window.__shprobe).
import { unpack } from './wire.js';

export const $ = (id) => document.getElementById(id);
export const api = window.__shprobe || (window.__shprobe = { lastError: null });

// `&bench=1` in the URL: the page times its frames by reading a pixel back (the frame is then
// finished), which stalls the GPU; a normal session never reads back (Chromium would log "GPU
// stall due to ReadPixels" and the page would wait for every frame)
export const BENCH = new URLSearchParams(window.location.search).has('bench');
api.readback = BENCH;

// wait for the frame just drawn to be finished, only when benchmarking; → whether it did
export function finishFrame(gl) {
  if (!BENCH) return false;
  gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, new Uint8Array(4));
  return true;
}

export async function call(path, opts = {}) { return handle(await fetch(path, opts)); }

// a response: its JSON, its binary message unpacked, or the response itself (text, blobs);
// an error status throws the server's one line
export async function handle(r) {
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

export function showError(e) {
  const el = $('error');
  el.textContent = String(e && e.message ? e.message : e);
  el.hidden = false;
  api.lastError = el.textContent;
}
export function clearError() { $('error').hidden = true; }
export function setStatus(s) { $('status').textContent = s; }

// a request boot.js started while three.js was loading (window.__boot), else a new one
export function first(name, fallback) {
  const b = window.__boot && window.__boot[name];
  if (b) { window.__boot[name] = null; return b.then((r) => (r instanceof Response ? handle(r) : r)); }
  return fallback();
}
