// The grid page's WebGL pieces: the programs (each probe a sphere lit by its own SH through
// the library's generated GLSL, the object lit per vertex by the library's irradiance, edges,
// the translucent bake scene) and the geometry they draw (merged probe spheres, the volume's
// box, cages around marked probes, meshes from the server's arrays).
import * as THREE from 'three';

const DOUBLE_SIDE = 2;  // three.js's DoubleSide (a constant the bundle does not export)
export const ROW = 256;  // probes per row of the coefficient texture

// ------------------------------------------------------------------ shaders
const COMMON = `const float PI = 3.141592653589793;
out vec4 fragColor;
vec3 srgb(vec3 v) { v = clamp(v, 0.0, 1.0);
  return mix(12.92 * v, 1.055 * pow(v, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), v)); }
`;
export function probeMaterial(glsl, K) {
  // the library's E(n) with its uniform array made a global, filled per fragment from the
  // probe's row of the coefficient texture
  const fn = glsl.replace(/uniform vec3 SHPROBE_E\[(\d+)\];/, 'vec3 SHPROBE_E[$1];');
  return new THREE.ShaderMaterial({
    glslVersion: THREE.GLSL3,
    uniforms: { uE: { value: null }, uRadius: { value: 0.1 }, uExposure: { value: 0 } },
    defines: { K, ROW },
    vertexShader: `in float probe; in vec3 centre; uniform float uRadius;
      flat out int vProbe; out vec3 vN;
      void main() { vProbe = int(probe + 0.5); vN = normal;
        gl_Position = projectionMatrix * modelViewMatrix * vec4(centre + uRadius * normal, 1.0); }`,
    fragmentShader: COMMON + fn + `
      uniform sampler2D uE; uniform float uExposure; flat in int vProbe; in vec3 vN;
      void main() {
        for (int k = 0; k < K; k++)
          SHPROBE_E[k] = texelFetch(uE, ivec2((vProbe % ROW) * K + k, vProbe / ROW), 0).rgb;
        vec3 e = max(shprobe_irradiance_sh(normalize(vN)), 0.0);  // clamped as the engines do
        fragColor = vec4(srgb(e / PI * exp2(uExposure)), 1.0);
      }`,
  });
}
export function objectMaterial() {  // albedo · E/π, E the library's per-vertex irradiance
  return new THREE.ShaderMaterial({
    glslVersion: THREE.GLSL3,
    uniforms: { uExposure: { value: 0 } },
    vertexShader: `in vec3 albedo; in vec3 irradiance; out vec3 vC;
      void main() { vC = albedo * irradiance;
        gl_Position = projectionMatrix * modelViewMatrix * vec4(position, 1.0); }`,
    fragmentShader: COMMON + `uniform float uExposure; in vec3 vC;
      void main() { fragColor = vec4(srgb(vC / PI * exp2(uExposure)), 1.0); }`,
  });
}
export function lineMaterial(rgb) {  // edges drawn as wireframe of (a, b, b) triangles
  return new THREE.ShaderMaterial({
    glslVersion: THREE.GLSL3, wireframe: true,
    uniforms: { uScale: { value: 1 } },
    vertexShader: `in vec3 offset; uniform float uScale;
      void main() { gl_Position = projectionMatrix * modelViewMatrix * vec4(position + uScale * offset, 1.0); }`,
    fragmentShader: `out vec4 fragColor; void main() { fragColor = vec4(${rgb.join(', ')}, 1.0); }`,
  });
}
export function sceneMaterial() {  // the bake scene, translucent so that the probes inside show
  return new THREE.ShaderMaterial({
    glslVersion: THREE.GLSL3, transparent: true, depthWrite: false, side: DOUBLE_SIDE,
    vertexShader: `out vec3 vN; void main() { vN = normal;
        gl_Position = projectionMatrix * modelViewMatrix * vec4(position, 1.0); }`,
    fragmentShader: `out vec4 fragColor; in vec3 vN;
      void main() { float g = 0.45 + 0.25 * abs(normalize(vN).y); fragColor = vec4(vec3(g), 0.22); }`,
  });
}

// ------------------------------------------------------------------ geometry
function attr(g, name, data, k) { g.setAttribute(name, new THREE.BufferAttribute(data, k)); }
export function probeSpheres(pos, n, seg, rings) {  // one UV sphere per probe, merged
  const vs = (seg + 1) * (rings + 1), is = seg * rings * 6;
  const centre = new Float32Array(n * vs * 3), normal = new Float32Array(n * vs * 3);
  const probe = new Float32Array(n * vs), index = new Uint32Array(n * is);
  const unit = [];
  for (let r = 0; r <= rings; r++) {
    const th = Math.PI * r / rings;
    for (let s = 0; s <= seg; s++) {
      const ph = 2 * Math.PI * s / seg;
      unit.push([Math.sin(th) * Math.cos(ph), Math.cos(th), Math.sin(th) * Math.sin(ph)]);
    }
  }
  for (let p = 0; p < n; p++) {
    for (let v = 0; v < vs; v++) {
      const o = (p * vs + v) * 3;
      for (let a = 0; a < 3; a++) { centre[o + a] = pos[3 * p + a]; normal[o + a] = unit[v][a]; }
      probe[p * vs + v] = p;
    }
    let o = p * is;
    for (let r = 0; r < rings; r++) {
      for (let s = 0; s < seg; s++) {
        const a = p * vs + r * (seg + 1) + s, b = a + seg + 1;
        index.set([a, a + 1, b, a + 1, b + 1, b], o); o += 6;  // counter-clockwise from outside
      }
    }
  }
  const g = new THREE.BufferGeometry();
  attr(g, 'position', centre, 3); attr(g, 'centre', centre, 3); attr(g, 'normal', normal, 3);
  attr(g, 'probe', probe, 1); g.setIndex(new THREE.BufferAttribute(index, 1));
  g.userData.indicesPerSphere = is;
  return g;
}
export function edges(points, offsets, pairs) {  // segments as degenerate triangles (a, b, b)
  const g = new THREE.BufferGeometry();
  attr(g, 'position', new Float32Array(points), 3);
  attr(g, 'offset', new Float32Array(offsets || points.map(() => 0)), 3);
  const idx = [];
  for (const [a, b] of pairs) idx.push(a, b, b);
  g.setIndex(new THREE.BufferAttribute(new Uint32Array(idx), 1));
  return g;
}
export function boxEdges(lo, hi) {
  const pts = [];
  for (let i = 0; i < 8; i++) pts.push(i & 1 ? hi[0] : lo[0], i & 2 ? hi[1] : lo[1], i & 4 ? hi[2] : lo[2]);
  const pairs = [];
  for (let i = 0; i < 8; i++) for (const bit of [1, 2, 4]) if (!(i & bit)) pairs.push([i, i | bit]);
  return edges(pts, null, pairs);
}
export function cages(pos, which) {  // an octahedron around each marked probe (its size: uScale)
  const pts = [], off = [], pairs = [];
  const dirs = [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]];
  for (const p of which) {
    const b = pts.length / 3;
    for (const d of dirs) { pts.push(pos[3 * p], pos[3 * p + 1], pos[3 * p + 2]); off.push(...d); }
    for (const [i, j] of [[0, 2], [0, 3], [0, 4], [0, 5], [1, 2], [1, 3], [1, 4], [1, 5], [2, 4], [2, 5], [3, 4], [3, 5]]) pairs.push([b + i, b + j]);
  }
  return edges(pts, off, pairs);
}
export function meshGeometry(pos, nrm, idx, extra) {
  const g = new THREE.BufferGeometry();
  attr(g, 'position', new Float32Array(pos), 3); attr(g, 'normal', new Float32Array(nrm), 3);
  for (const [k, v] of Object.entries(extra || {})) attr(g, k, v, 3);
  g.setIndex(new THREE.BufferAttribute(new Uint32Array(idx), 1));
  return g;
}
