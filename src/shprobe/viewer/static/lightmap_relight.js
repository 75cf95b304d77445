// shprobe view --lightmap: live relighting from the transfer (SHPROBE_lightmap "transfer",
// Lisle & Huang 2007 §4 per texel). The sky's SH (lmax 2, per colour) is turned by the
// page's exact lmax ≤ 2 rotation (rotation.js, tested against the library's Wigner rotation)
// and scaled per band; then one GPU pass per coefficient texture writes, per texel,
// Σ_j T_j L_j (the 9 transfer textures of that texture's packing, texelFetch'ed) into a float
// render target that the lightmap material samples in place of the stored texture.
import * as THREE from 'three';
import { mul, rotAxis, rotateLow } from './rotation.js';

const NEAREST = 1003, LINEAR = 1006;

const VERTEX = `void main() { gl_Position = vec4(position.xy, 0.0, 1.0); }`;
const FRAGMENT = `precision highp float;
${Array.from({ length: 9 }, (_, j) => `uniform sampler2D T${j};`).join('\n')}
uniform vec4 w[9];
out vec4 fragColor;
void main() {
  ivec2 p = ivec2(gl_FragCoord.xy);
  vec4 s = vec4(0.0);
${Array.from({ length: 9 }, (_, j) => `  s += w[${j}] * texelFetch(T${j}, p, 0);`).join('\n')}
  fragColor = s;
}`;

function fromHalf(h) {  // IEEE half bits → number
  const e = (h >> 10) & 31, m = h & 1023, s = h & 32768 ? -1 : 1;
  if (e === 0) return s * m * 2 ** -24;
  return e === 31 ? (m ? NaN : s * Infinity) : s * (1 + m / 1024) * 2 ** (e - 15);
}

// the sky's rotation: about the up axis (+Y) by azimuth, then tilted about +X by elevation
export function skyRotation(azimuth, elevation) {
  return mul(rotAxis([1, 0, 0], elevation), rotAxis([0, 1, 0], azimuth));
}

// the sky SH (9 × [r, g, b]) under the sky controls: bands scaled, ×2^stops, turned
export function turnedSky(sky, s) {
  const band = (k) => (k === 0 ? s.l0 : k < 4 ? s.l1 : s.l2);
  const f = 2 ** s.stops;
  const L = sky.map((c, k) => c.map((v) => v * band(k) * f));
  return rotateLow(L, skyRotation(s.azimuth, s.elevation));
}

// Relighter: `sets` = 9 arrays (one per sky coefficient j) of the transfer's textures (packed
// like the stored ones, `layout` their [coefficient, colour] per channel); `tscale` the
// transfer's scale, `scale` the lightmap's (the material multiplies by it).
export class Relighter {
  constructor(renderer, sets, layout, size, tscale, scale) {
    this.renderer = renderer;
    this.layout = layout;
    this.ratio = tscale / scale;
    this.width = size[0]; this.height = size[1];
    const linear = renderer.extensions.has('OES_texture_float_linear');
    this.type = linear ? THREE.FloatType : THREE.HalfFloatType;
    this.camera = new THREE.OrthographicCamera(-1, 1, 1, -1, 0, 1);
    this.quad = new THREE.Mesh(new THREE.PlaneGeometry(2, 2));
    this.quad.frustumCulled = false;
    this.scene = new THREE.Scene();
    this.scene.add(this.quad);
    this.targets = layout.map(() => {
      const rt = new THREE.WebGLRenderTarget(this.width, this.height,
        { type: this.type, format: THREE.RGBAFormat, depthBuffer: false });
      rt.texture.minFilter = rt.texture.magFilter = LINEAR;
      rt.texture.generateMipmaps = false;
      rt.texture.wrapS = rt.texture.wrapT = THREE.ClampToEdgeWrapping;
      return rt;
    });
    this.materials = layout.map((_, t) => {
      const uniforms = { w: { value: new Float32Array(36) } };  // vec4 w[9], flat
      for (let j = 0; j < 9; j++) {
        sets[j][t].minFilter = sets[j][t].magFilter = NEAREST;
        uniforms[`T${j}`] = { value: sets[j][t] };
      }
      return new THREE.ShaderMaterial({ glslVersion: THREE.GLSL3, uniforms,
        vertexShader: VERTEX, fragmentShader: FRAGMENT, depthTest: false, depthWrite: false });
    });
  }

  get textures() { return this.targets.map((rt) => rt.texture); }

  // write the coefficient textures under sky SH L (9 × [r, g, b], world frame)
  relight(L) {
    const r = this.renderer, prev = r.getRenderTarget();
    const scissor = r.getScissorTest();
    r.setScissorTest(false);
    this.layout.forEach((chans, t) => {
      const m = this.materials[t];
      for (let j = 0; j < 9; j++) {
        const c = chans.map((ic) => (ic === null ? 0 : L[j][ic[1]] * this.ratio));
        m.uniforms.w.value.set(c, 4 * j);
      }
      this.quad.material = m;
      r.setRenderTarget(this.targets[t]);
      r.setViewport(0, 0, this.width, this.height);
      r.render(this.scene, this.camera);
    });
    r.setRenderTarget(prev);
    r.setScissorTest(scissor);
  }

  // the relit coefficient texture t as floats (H·W·4, row 0 at v = 0), × scale = stored units
  read(t) {
    const n = this.width * this.height * 4;
    if (this.type === THREE.FloatType) {
      const out = new Float32Array(n);
      this.renderer.readRenderTargetPixels(this.targets[t], 0, 0, this.width, this.height, out);
      return out;
    }
    const half = new Uint16Array(n);
    this.renderer.readRenderTargetPixels(this.targets[t], 0, 0, this.width, this.height, half);
    return Float32Array.from(half, fromHalf);
  }

  dispose() {
    this.targets.forEach((rt) => rt.dispose());
    this.materials.forEach((m) => m.dispose());
    this.quad.geometry.dispose();
  }
}
