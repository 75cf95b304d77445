// The designer page's WebGL programs. E(n) per pixel is shprobe's own GLSL: the export's R&H
// eq. 13 at lmax ≤ 2 (its constants made uniforms), the library's generated any-lmax function
// (lighting.glsl) above it, fed the library's E_lm = Â_l L_lm. One program per case (a define
// picks it), not a branch on a uniform: a software GL (SwiftShader) pays for every branch of a
// program, ~2× the frame time and the first draw.
import * as THREE from 'three';
import { HEAT_GLSL } from './legend.js';

const PI = 'const float PI = 3.141592653589793;\n';
const SRGB = `out vec4 fragColor;
vec3 srgb(vec3 v) { v = clamp(v, 0.0, 1.0);
  return mix(12.92 * v, 1.055 * pow(v, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), v)); }
vec2 dirToUV(vec3 d) {  // shprobe lat-long: row 0 = +Y, u = 0.5 -> -Z, u = 0.75 -> +X
  float th = acos(clamp(d.y, -1.0, 1.0));
  float psi = atan(-d.x, d.z); if (psi < 0.0) psi += 2.0 * PI;
  return vec2(psi / (2.0 * PI), th / PI); }
vec3 uvToDir(vec2 uv) { float psi = 2.0 * PI * uv.x, th = PI * uv.y;
  return vec3(-sin(psi) * sin(th), cos(th), cos(psi) * sin(th)); }
vec3 rgbe(sampler2D t, vec2 uv) { return texture(t, uv).rgb; }
` + HEAT_GLSL;

// the shader SRGB's srgb() in JS (the grey a clear stands in for)
export const srgbJS = (v) => { v = Math.min(Math.max(v, 0), 1); return v < 0.0031308 ? 12.92 * v : 1.055 * v ** (1 / 2.4) - 0.055; };

function shaderFromExport(text) {  // shprobe's GLSL export, its constants turned into uniforms
  return text
    .replace(/const mat4 (SHPROBE_M_[RGB]) = mat4\([^;]*\);/g, 'uniform mat4 $1;')
    .replace(/const vec3 SHPROBE_L\[9\] = vec3\[9\]\([\s\S]*?\n\);/, 'uniform vec3 SHPROBE_L[9];');
}

// the object's views: albedo · E/π per pixel with E from eq. 13 | from the generated function
// (a design above lmax 2, compare "SH lmax l") | from it to a design's highest degree | the
// library's brute force | the error heat map | PRT vertex colours
const OBJ_VIEWS = { poly: 0, sh: 0, shd: 0, exact: 2, error: 3, prt: 4 };

export class Programs {
  // ``sh``: the server's /api/shaders (the export, the generated functions and their degrees)
  constructor(sh) {
    this.glsl = { poly: shaderFromExport(sh.glsl), sh: sh.glsl_sh, shd: sh.glsl_sh_design };
    this.shLmax = sh.max_lmax; this.designLmax = sh.design_lmax;
    this.objMats = {};  // the object's programs, one per view, made on first use
    this.obj = null; this.objD = null;  // their uniforms (shared; 'shd' has its own)
  }

  // 'poly': eq. 13; 'sh': the generated function to shLmax; 'shd': to designLmax (a design
  // above shLmax, e.g. a PRT transfer's degree)
  irradianceGLSL(kind) {
    return this.glsl[kind] + `vec3 shprobe_E(vec3 n) { return shprobe_irradiance_${kind === 'poly' ? 'poly' : 'sh'}(n); }\n`;
  }

  eKind(lmax) { return lmax <= 2 ? 'poly' : lmax <= this.shLmax ? 'sh' : 'shd'; }

  uniforms(lmaxE = this.shLmax) {
    return {
      SHPROBE_L: { value: Array.from({ length: 9 }, () => new THREE.Vector3()) },
      SHPROBE_E: { value: Array.from({ length: (lmaxE + 1) ** 2 }, () => new THREE.Vector3()) },
      SHPROBE_M_R: { value: new THREE.Matrix4() }, SHPROBE_M_G: { value: new THREE.Matrix4() },
      SHPROBE_M_B: { value: new THREE.Matrix4() },
      uExposure: { value: 0 }, uRotInv: { value: new THREE.Matrix3() },
      uBg: { value: null }, uHasBg: { value: 0 },
    };
  }

  object(view) {
    if (this.objMats[view]) return this.objMats[view];
    this.obj = this.obj || { ...this.uniforms(), uA: { value: null }, uRef: { value: null },
                             uTot: { value: new THREE.Vector3(1, 1, 1) }, uErrMax: { value: 1 } };
    if (view === 'shd') this.objD = this.objD || { ...this.uniforms(this.designLmax) };
    const v = OBJ_VIEWS[view];
    return (this.objMats[view] = new THREE.ShaderMaterial({
      glslVersion: THREE.GLSL3,
      uniforms: view === 'shd' ? this.objD : this.obj,  // shared by the other views
      defines: { OBJ_VIEW: v },
      vertexShader: `in vec3 albedo; in vec3 prtColor; out vec3 vN; out vec3 vAlb; out vec3 vPrt;
        void main() { vN = normal; vAlb = albedo; vPrt = prtColor;
          gl_Position = projectionMatrix * modelViewMatrix * vec4(position, 1.0); }`,
      fragmentShader: PI + SRGB + (v === 0 ? this.irradianceGLSL(view) : '') + `
        uniform float uExposure; uniform sampler2D uA; uniform sampler2D uRef;
        uniform vec3 uTot; uniform float uErrMax;
        in vec3 vN; in vec3 vAlb; in vec3 vPrt;
        void main() {
          vec3 n = normalize(vN);
        #if OBJ_VIEW == 0
          fragColor = vec4(srgb(vAlb * shprobe_E(n) / PI * exp2(uExposure)), 1.0);  // per pixel
        #elif OBJ_VIEW == 2
          fragColor = vec4(srgb(vAlb * texture(uRef, dirToUV(n)).rgb / PI * exp2(uExposure)), 1.0);
        #elif OBJ_VIEW == 3
          vec3 d = abs(texture(uA, dirToUV(n)).rgb - texture(uRef, dirToUV(n)).rgb) / uTot;
          fragColor = vec4(heat(max(d.r, max(d.g, d.b)) / uErrMax), 1.0);
        #else
          fragColor = vec4(srgb(vPrt * exp2(uExposure)), 1.0);
        #endif
        }`,
    }));
  }

  background() {  // full-screen pass: the probe seen along each camera ray
    return new THREE.ShaderMaterial({
      glslVersion: THREE.GLSL3, depthWrite: false, depthTest: false,
      uniforms: { ...this.uniforms(), uInvVP: { value: new THREE.Matrix4() }, uEye: { value: new THREE.Vector3() } },
      vertexShader: `out vec2 vNdc; void main() { vNdc = position.xy; gl_Position = vec4(position.xy, 1.0, 1.0); }`,
      fragmentShader: PI + SRGB + `uniform sampler2D uBg; uniform int uHasBg; uniform float uExposure;
        uniform mat3 uRotInv; uniform mat4 uInvVP; uniform vec3 uEye; in vec2 vNdc;
        void main() { vec4 p = uInvVP * vec4(vNdc, 1.0, 1.0); vec3 d = normalize(p.xyz / p.w - uEye);
          vec3 c = uHasBg == 1 ? rgbe(uBg, dirToUV(uRotInv * d)) : vec3(0.18);
          fragColor = vec4(srgb(c * exp2(uExposure)), 1.0); }`,
    });
  }

  panel(kind, uniforms) {  // lat-long panels: the probe, or E/π (eq. 13 | sh | shd)
    return new THREE.ShaderMaterial({
      glslVersion: THREE.GLSL3, depthTest: false,
      uniforms: uniforms || this.uniforms(),
      vertexShader: `out vec2 vUv; void main() { vUv = vec2(uv.x, 1.0 - uv.y); gl_Position = vec4(position.xy, 0.0, 1.0); }`,
      fragmentShader: PI + SRGB + (kind === 'probe' ? '' : this.irradianceGLSL(kind)) + `uniform sampler2D uBg; uniform int uHasBg; uniform float uExposure;
        uniform mat3 uRotInv; in vec2 vUv;
        void main() { vec3 d = uvToDir(vUv);
          vec3 c = ${kind === 'probe' ? 'uHasBg == 1 ? rgbe(uBg, dirToUV(uRotInv * d)) : vec3(0.18)' : 'shprobe_E(d) / PI'};
          fragColor = vec4(srgb(c * exp2(uExposure)), 1.0); }`,
    });
  }
}

export function setE(u, E, lmax) {  // E_lm = Â_l L_lm of the library, zero above lmax
  const K = (lmax + 1) ** 2;
  u.SHPROBE_E.value.forEach((v, k) => { const c = (k < K && E && E[k]) || [0, 0, 0]; v.set(c[0], c[1], c[2]); });
}

export function floatTex(data, h, w) {  // (h, w, 3) float32 → RGBA float texture, row 0 = +Y
  const rgba = new Float32Array(h * w * 4);
  for (let i = 0; i < h * w; i++) { rgba[4 * i] = data[3 * i]; rgba[4 * i + 1] = data[3 * i + 1]; rgba[4 * i + 2] = data[3 * i + 2]; rgba[4 * i + 3] = 1; }
  const t = new THREE.DataTexture(rgba, w, h, THREE.RGBAFormat, THREE.FloatType);
  t.wrapS = THREE.RepeatWrapping; t.wrapT = THREE.ClampToEdgeWrapping;
  t.magFilter = THREE.LinearFilter; t.minFilter = THREE.LinearFilter; t.needsUpdate = true;
  return t;
}

export function halfTex(data, h, w) {  // (h, w, 4) half floats → a bilinear RGBA texture
  const t = new THREE.DataTexture(data, w, h, THREE.RGBAFormat, THREE.HalfFloatType);
  t.wrapS = THREE.RepeatWrapping; t.wrapT = THREE.ClampToEdgeWrapping;
  t.magFilter = THREE.LinearFilter; t.minFilter = THREE.LinearFilter; t.needsUpdate = true;
  return t;
}
