// The object's view: an orbit camera framed on the object (the server's `view` camera: the
// library Camera fitted to the object's bounding sphere, from above the horizon), zoom and
// pan, a reset; the canvas follows the space the page gives it. The library's own camera
// (`camera`, elevation 0, 512×512) stays available for reads that compare pixels with
// shprobe.scene.render (readLibraryView).
import * as THREE from 'three';
import { OrbitControls } from 'three';

export class View3D {
  constructor(renderer, canvas, wrap, onChange) {
    this.renderer = renderer; this.canvas = canvas; this.wrap = wrap; this.onChange = onChange;
    this.camera = new THREE.PerspectiveCamera(40, 1, 0.01, 100);
    this.controls = new OrbitControls(this.camera, canvas);
    this.controls.screenSpacePanning = true;
    this.controls.addEventListener('change', onChange);
    this.start = null;      // the server's view camera (wire.camera_json)
    this.library = null;    // the server's library camera
    this.fov = 40;          // the vertical fov of a square view; wider for a tall one
    this.size = [0, 0];
    new ResizeObserver(() => { if (this.fit()) onChange(); }).observe(wrap);
    this.fit();
  }

  // the drawing buffer follows the canvas's size on the page (its content box, CSS pixels ×
  // devicePixelRatio, at most 2; the canvas fills its wrapper); → true when it changed
  fit() {
    const r = Math.min(window.devicePixelRatio || 1, 2);
    const w = Math.max(1, Math.round(this.canvas.clientWidth * r)), h = Math.max(1, Math.round(this.canvas.clientHeight * r));
    if (w === this.size[0] && h === this.size[1]) return false;
    this.size = [w, h];
    this.renderer.setPixelRatio(1); this.renderer.setSize(w, h, false);
    this.aspect();
    return true;
  }

  // the library's framing holds the bounding sphere in the narrower of the two directions: a
  // view taller than wide widens the vertical fov so that the object still fits across
  aspect() {
    const a = this.size[0] / this.size[1], c = this.camera;
    c.aspect = a;
    const t = Math.tan(this.fov * Math.PI / 360);
    c.fov = a >= 1 ? this.fov : 360 / Math.PI * Math.atan(t / a);
    c.updateProjectionMatrix();
  }

  // frame the object: ``view`` and ``library`` are the server's cameras (wire.camera_json)
  frame(view, library) {
    this.start = view; this.library = library || view;
    this.reset();
  }

  reset() {
    const v = this.start; if (!v) return;
    const c = this.camera;
    this.fov = v.fov; c.near = v.near; c.far = v.far;
    c.position.set(...v.eye); c.up.set(...v.up);
    this.controls.target.set(...v.target); c.lookAt(...v.target);
    const d = Math.hypot(...v.eye.map((x, i) => x - v.target[i]));
    this.controls.minDistance = 0.05 * d; this.controls.maxDistance = 20 * d;
    this.aspect();
    this.controls.update();
    this.onChange();
  }

  // what tests and benchmarks read back: the camera now and where it started
  state() {
    const c = this.camera, t = this.controls.target;
    const d = c.position.clone().sub(t);
    return {
      position: c.position.toArray(), target: t.toArray(), up: c.up.toArray(), fov: c.fov,
      aspect: c.aspect, near: c.near, far: c.far, width: this.size[0], height: this.size[1],
      elevation: Math.asin(d.y / d.length()) * 180 / Math.PI,
      view: c.matrixWorldInverse.toArray(), projection: c.projectionMatrix.toArray(),
      clientWidth: this.canvas.clientWidth, clientHeight: this.canvas.clientHeight,
    };
  }

  // the library camera as a three.js camera (for reads compared with shprobe.scene.render)
  libraryCamera() {
    const v = this.library, c = new THREE.PerspectiveCamera(v.fov, v.width / v.height, v.near, v.far);
    c.position.set(...v.eye); c.up.set(...v.up); c.lookAt(...v.target);
    c.updateMatrixWorld(); c.updateProjectionMatrix();
    return c;
  }
}

// render ``scene`` with the library camera at 512×512 (the drawing buffer resized for the
// read; the caller draws its own view again after); → RGBA rows from the top
export function readLibraryView(renderer, scene, cam, before) {
  const el = renderer.domElement, size = { x: el.width, y: el.height };
  renderer.setSize(512, 512, false);
  before(cam);
  renderer.render(scene, cam);
  const gl = renderer.getContext(), px = new Uint8Array(512 * 512 * 4);
  gl.readPixels(0, 0, 512, 512, gl.RGBA, gl.UNSIGNED_BYTE, px);
  renderer.setSize(size.x, size.y, false);
  const out = new Uint8Array(512 * 512 * 4);
  for (let y = 0; y < 512; y++) out.set(px.subarray((511 - y) * 2048, (512 - y) * 2048), y * 2048);
  return out;
}
