// "Copy as Python", beside the equivalent command: the library code that reproduces the page's
// current edit (POST /api/snippet, made by shprobe.lighting.snippet), shown under the command
// and copied to the clipboard. While shown, it follows the edits (the command's text changes
// with each design).
import { api, call } from './api.js';

function setup() {
  const cli = document.getElementById('cli');
  if (!cli || document.getElementById('copy-python')) return;
  const row = document.createElement('div'); row.className = 'row';
  const button = document.createElement('button'); button.id = 'copy-python';
  button.textContent = 'Copy as Python';
  button.title = 'The same lighting with the shprobe library: resolve_lighting, EditSpec, edit_lighting';
  const note = document.createElement('span'); note.id = 'python-note';
  row.append(button, note);
  const pre = document.createElement('pre'); pre.id = 'python'; pre.hidden = true;
  cli.after(row, pre);

  async function fetchSnippet() {
    const state = api.getState ? api.getState() : {};
    const r = await call('/api/snippet', { method: 'POST', body: JSON.stringify(state) });
    const text = await r.text();
    pre.textContent = text; pre.hidden = false;
    api.lastSnippet = text;
    return text;
  }
  async function copy(text) {
    try { await navigator.clipboard.writeText(text); return true; } catch (e) { /* below */ }
    const sel = window.getSelection(), range = document.createRange();
    range.selectNodeContents(pre); sel.removeAllRanges(); sel.addRange(range);
    try { return document.execCommand('copy'); } catch (e) { return false; }
  }
  button.onclick = async () => {
    try {
      const text = await fetchSnippet();
      note.textContent = (await copy(text)) ? 'copied' : 'select the code below and copy it';
    } catch (e) { note.textContent = String(e.message || e); }
  };
  let pending = false;
  new MutationObserver(() => {  // a new design: refresh the code shown
    if (pre.hidden || pending) return;
    pending = true;
    setTimeout(() => { pending = false; fetchSnippet().catch((e) => { note.textContent = String(e.message || e); }); }, 50);
  }).observe(cli, { childList: true, characterData: true, subtree: true });
  api.copyPython = () => button.onclick();
}

if (document.readyState === 'loading') document.addEventListener('DOMContentLoaded', setup);
else setup();
