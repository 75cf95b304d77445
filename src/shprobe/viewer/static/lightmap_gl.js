// shprobe view --lightmap: the three.js side. One ShaderMaterial per (encoding, material):
// the normal map's texel decoded into the tangent-space normal n, the lightmap's coefficient
// textures sampled at TEXCOORD_1 and evaluated at n by the library's generated GLSL
// (shprobe.lightmaps.shaders, Habel & Wimmer 2010 eq. 15; the lightmap shares the normal
// map's tangent frame, so no matrix is needed), times the base colour / π.
import * as THREE from 'three';

const LINEAR = 1006, LINEAR_MIPMAP_LINEAR = 1008, NEAREST = 1003, UNSIGNED_BYTE = 1009;
// what each debug output writes (the tests read floats back): 0 = the picture
export const DEBUG = { picture: 0, irradiance: 1, uv1: 2, normal: 3, albedo: 4 };

const VERTEX = `in vec2 a_uv0;
in vec2 a_uv1;
out vec2 vUv0;
out vec2 vUv1;
void main() {
  vUv0 = a_uv0;
  vUv1 = a_uv1;
  gl_Position = projectionMatrix * modelViewMatrix * vec4(position, 1.0);
}`;

function fragment(glsl, encoding, k) {
  const ts = Array.from({ length: k }, (_, i) => `t${i}`);
  return `precision highp float;
const float PI = 3.141592653589793;
uniform sampler2D baseMap;
uniform sampler2D normalMap;
uniform vec4 baseFactor;
uniform float normalScale;
uniform bool useNormalMap;
uniform bool albedoOn;
uniform bool gridOn;
uniform float lmScale;
uniform float exposure;
uniform vec2 lmSize;
uniform int debugOut;
${ts.map((t) => `uniform sampler2D ${t};`).join('\n')}
in vec2 vUv0;
in vec2 vUv1;
out vec4 fragColor;
vec3 srgbToLinear(vec3 c) {
  return mix(c / 12.92, pow((c + 0.055) / 1.055, vec3(2.4)), step(vec3(0.04045), c));
}
vec3 srgb(vec3 v) { v = clamp(v, 0.0, 1.0);
  return mix(12.92 * v, 1.055 * pow(v, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), v)); }
${glsl}
void main() {
  vec3 n = useNormalMap ? shprobe_lightmap_normal(texture(normalMap, vUv0).rgb, normalScale)
                        : vec3(0.0, 0.0, 1.0);
  vec3 E = lmScale * shprobe_lightmap_${encoding}_sample(${ts.join(', ')}, vUv1, n);
  vec3 a = baseFactor.rgb * srgbToLinear(texture(baseMap, vUv0).rgb);
  vec3 c = (albedoOn ? a : vec3(1.0)) / PI * E * exp2(exposure);
  if (gridOn) {  // the lightmap's texel edges, one pixel wide
    vec2 p = vUv1 * lmSize, f = min(fract(p), 1.0 - fract(p)) / max(fwidth(p), 1e-6);
    c = mix(c, vec3(0.0, 0.55, 1.0) * max(max(c.r, c.g), max(c.b, 0.25)),
            0.6 * (1.0 - clamp(min(f.x, f.y), 0.0, 1.0)));
  }
  if (debugOut == 1) fragColor = vec4(E, 1.0);
  else if (debugOut == 2) fragColor = vec4(vUv1, 0.0, 1.0);
  else if (debugOut == 3) fragColor = vec4(n, 1.0);
  else if (debugOut == 4) fragColor = vec4(a, 1.0);
  else fragColor = vec4(srgb(c), 1.0);
}`;
}

export function halfTexture(data, width, height) {
  const t = new THREE.DataTexture(data, width, height, THREE.RGBAFormat, THREE.HalfFloatType);
  t.magFilter = LINEAR; t.minFilter = LINEAR; t.generateMipmaps = false;
  t.wrapS = t.wrapT = THREE.ClampToEdgeWrapping;
  t.flipY = false;
  t.needsUpdate = true;
  return t;
}

export function byteTexture(img, mipmaps = true) {
  const t = new THREE.DataTexture(img.data, img.width, img.height, THREE.RGBAFormat, UNSIGNED_BYTE);
  t.wrapS = t.wrapT = THREE.RepeatWrapping;
  t.magFilter = LINEAR;
  t.minFilter = mipmaps ? LINEAR_MIPMAP_LINEAR : LINEAR;
  t.generateMipmaps = mipmaps;
  t.flipY = false;
  t.needsUpdate = true;
  return t;
}

const WHITE = { width: 1, height: 1, data: new Uint8Array([255, 255, 255, 255]) };
const FLAT = { width: 1, height: 1, data: new Uint8Array([128, 128, 255, 255]) };

export function lightmapMaterial(glsl, encoding, coeffTextures, mat, maps, lm) {
  const uniforms = {
    baseMap: { value: maps.base ?? byteTexture(WHITE, false) },
    normalMap: { value: maps.normal ?? byteTexture(FLAT, false) },
    baseFactor: { value: mat.baseColor },
    normalScale: { value: mat.normalScale },
    useNormalMap: { value: maps.normal != null && encoding !== 'plain' },
    albedoOn: { value: true }, gridOn: { value: false },
    lmScale: { value: lm.scale }, exposure: { value: lm.exposure },
    lmSize: { value: [lm.width, lm.height] }, debugOut: { value: 0 },
  };
  coeffTextures.forEach((t, i) => { uniforms[`t${i}`] = { value: t }; });
  return new THREE.ShaderMaterial({
    glslVersion: THREE.GLSL3, uniforms, vertexShader: VERTEX,
    fragmentShader: fragment(glsl, encoding, coeffTextures.length),
  });
}

export function primitiveGeometry(p) {
  const geo = new THREE.BufferGeometry();
  geo.setAttribute('position', new THREE.BufferAttribute(p.position, 3));
  geo.setAttribute('a_uv0', new THREE.BufferAttribute(p.uv0 ?? new Float32Array(p.uv1.length), 2));
  geo.setAttribute('a_uv1', new THREE.BufferAttribute(p.uv1, 2));
  geo.setIndex(new THREE.BufferAttribute(p.index, 1));
  geo.computeBoundingSphere();
  return geo;
}

// a float render target of the canvas's size, for reading a debug output back
export function floatTarget(width, height) {
  const rt = new THREE.WebGLRenderTarget(width, height, { type: THREE.FloatType,
    format: THREE.RGBAFormat, depthBuffer: true });
  rt.texture.minFilter = rt.texture.magFilter = NEAREST;
  rt.texture.generateMipmaps = false;
  return rt;
}
