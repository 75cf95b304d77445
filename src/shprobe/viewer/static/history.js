// The designer page's edit state (the JSON lighting.edits.EditSpec.from_json reads), its
// undo / redo history, and its copy in localStorage (an edit state survives a reload).

export const EMPTY = { lmax: 2, weight: 1, blends: [], directional: [], cone: [], sky: null,
                       scale: {}, scale_band: {}, rotation: null, window: null };
export const KEY = 'shprobe-view-state';

export class History {
  // ``onChange()`` runs after every commit, undo and redo (recompute, refresh the controls)
  constructor(onChange) {
    this.state = structuredClone(EMPTY);
    this.past = []; this.future = [];
    this.onChange = onChange;
  }

  save() { try { localStorage.setItem(KEY, JSON.stringify(this.state)); } catch (e) { /* private mode */ } }

  // the state saved by an earlier visit (defaults filled in), or null
  static saved() {
    try { const s = localStorage.getItem(KEY); return s ? { ...structuredClone(EMPTY), ...JSON.parse(s) } : null; } catch (e) { return null; }
  }

  commit(next) {  // an edit: undoable, persisted, recomputed
    this.past.push(JSON.stringify(this.state)); this.future = [];
    this.state = next; this.save(); this.onChange();
  }

  // a change made step by step (a drag) becomes one undo step, from ``before`` (JSON)
  record(before) { this.past.push(before); this.future = []; this.save(); }

  undo() {
    if (!this.past.length) return;
    this.future.push(JSON.stringify(this.state)); this.state = JSON.parse(this.past.pop());
    this.save(); this.onChange();
  }

  redo() {
    if (!this.future.length) return;
    this.past.push(JSON.stringify(this.state)); this.state = JSON.parse(this.future.pop());
    this.save(); this.onChange();
  }

  // a copy of the current state to edit and commit
  edit() { return structuredClone(this.state); }
}
