// The consumers that live in a browser, run in headless Chromium by
// tests/lighting/test_export_consumers.py (served under tests/support/browser.ORIGIN, node_modules at
// /node_modules/, resolved by the import map of browser.html):
//   babylon(cases, normals, rightHanded): Babylon.js (WebGL2 Engine) loads each `gltf` export
//     through its glTF loader (EXT_lights_image_based) and we evaluate the environment's
//     spherical harmonics the way its PBR shader does (harmonicsFunctions.fx,
//     pbrBlockReflection.fx): world normal -> reflection matrix -> REFLECTIONMAP_OPPOSITEZ /
//     INVERTCUBICMAP -> polynomial.
//   webgl2(glsl, normals, complete): each GLSL export compiled as GLSL ES 3.00 by WebGL2 and run
//     in a fragment shader over a float framebuffer; the normal each fragment used is read back
//     too. complete = true takes a whole fragment shader (the HLSL export after glslang's HLSL
//     front end and SPIRV-Cross).
//   webgpu(wgsl, normals): each WGSL export compiled by Chromium's WebGPU (Tint):
//     getCompilationInfo of the bare export, then run in a compute shader.
import { Engine } from "@babylonjs/core/Engines/engine.js";
import { Scene } from "@babylonjs/core/scene.js";
import { AppendSceneAsync } from "@babylonjs/core/Loading/sceneLoader.js";
import { Matrix, Vector3 } from "@babylonjs/core/Maths/math.vector.js";
import "@babylonjs/core/Loading/loadingScreen.js";
import "@babylonjs/core/Materials/Textures/baseTexture.polynomial.js";
import "@babylonjs/loaders/glTF/2.0/index.js";
import "@babylonjs/loaders/glTF/glTFFileLoader.js";

function evalHarmonics(h, x, y, z) {  // harmonicsFunctions.fx, SPHERICAL_HARMONICS branch
  const terms = [[h.l00, 1], [h.l1_1, y], [h.l10, z], [h.l11, x], [h.l2_2, y * x],
    [h.l2_1, y * z], [h.l20, 3 * z * z - 1], [h.l21, z * x], [h.l22, x * x - y * y]];
  const o = [0, 0, 0];
  for (const [c, p] of terms) { o[0] += c.x * p; o[1] += c.y * p; o[2] += c.z * p; }
  return o;
}

function evalPolynomial(P, x, y, z) {  // harmonicsFunctions.fx, polynomial branch
  const o = [0, 0, 0];
  for (const [i, k] of [[0, "x"], [1, "y"], [2, "z"]]) {
    const C1 = P.zz[k], Cx = P.x[k], Cy = P.y[k], Cz = P.z[k], Cxx_zz = P.xx[k] - P.zz[k],
      Cyy_zz = P.yy[k] - P.zz[k], Cxy = P.xy[k], Cyz = P.yz[k], Czx = P.zx[k];
    const a2 = Cyz * z + (Cyy_zz * y + Cy);
    const b3 = Cxx_zz * x + (Cxy * y + (Czx * z + Cx));
    o[i] = b3 * x + (a2 * y + (Cz * z + C1));
  }
  return o;
}

export async function babylon(cases, normals, rightHanded) {
  const canvas = document.createElement("canvas");
  const engine = new Engine(canvas, false);
  const out = { version: Engine.Version, webgl: engine.webGLVersion, cases: {} };
  for (const c of cases) {
    const scene = new Scene(engine);
    scene.useRightHandedSystem = rightHanded;
    await AppendSceneAsync("data:" + c.text, scene, { pluginExtension: ".gltf" });
    const tex = scene.environmentTexture;
    const root = scene.getMeshByName("__root__");
    const W = root ? root.computeWorldMatrix(true) : Matrix.Identity();
    const R = tex.getReflectionTextureMatrix();
    // materialHelper.functions.js: REFLECTIONMAP_OPPOSITEZ and INVERTCUBICMAP
    const oppositeZ = rightHanded ? !tex.invertZ : tex.invertZ;
    const invertY = tex.coordinatesMode === 6;
    const poly = tex.sphericalPolynomial;
    // Babylon's irradiance convention: PBR materials multiply computeEnvironmentIrradiance
    // by albedo directly (it holds E / pi); scale by pi to compare with E.
    const sh = poly.preScaledHarmonics;
    const harm = [], pol = [];
    for (let i = 0; i < normals.length; i += 3) {
      const v = Vector3.TransformNormal(new Vector3(normals[i], normals[i + 1], normals[i + 2]), W);
      const r = Vector3.TransformNormal(v, R);
      if (oppositeZ) r.z *= -1;
      if (invertY) r.y *= -1;
      harm.push(...evalHarmonics(sh, r.x, r.y, r.z).map((e) => e * Math.PI));
      pol.push(...evalPolynomial(poly, r.x, r.y, r.z).map((e) => e * Math.PI));
    }
    // the specular cube as Babylon decoded it (RGBD PNG -> float texture), every mip and face
    const cube = [];
    const mips = JSON.parse(c.text).extensions.EXT_lights_image_based.lights[0].specularImages;
    for (let level = 0; level < mips.length; level++) {
      for (let f = 0; f < 6; f++) cube.push(Array.from(await tex.readPixels(f, level)));
    }
    out.cases[c.name] = {
      harmonics: harm, polynomial: pol, cube, level: tex.level, root: Array.from(W.m),
      reflection: Array.from(R.m), oppositeZ, invertY, name: tex.name,
    };
    scene.dispose();
  }
  engine.dispose();
  return out;
}

function glCompile(gl, type, src) {
  const s = gl.createShader(type);
  gl.shaderSource(s, src);
  gl.compileShader(s);
  if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
  return s;
}

export function webgl2(glsl, normals, complete = false) {
  // complete: `glsl` is a whole GLSL ES 3.00 fragment shader (the HLSL export cross-compiled),
  // writing irradiance, poly and the normal to locations 0, 1, 2; its one sampler is the normals
  const N = normals.length / 3, Wd = 64, H = Math.ceil(N / Wd);
  const canvas = document.createElement("canvas");
  const gl = canvas.getContext("webgl2");
  if (!gl) throw new Error("no WebGL2 context");
  if (!gl.getExtension("EXT_color_buffer_float")) throw new Error("no EXT_color_buffer_float");
  const info = { renderer: gl.getParameter(gl.RENDERER), version: gl.getParameter(gl.VERSION) };
  const dbg = gl.getExtension("WEBGL_debug_renderer_info");
  if (dbg) info.unmasked = gl.getParameter(dbg.UNMASKED_RENDERER_WEBGL);
  const vs = glCompile(gl, gl.VERTEX_SHADER, `#version 300 es
void main() { vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
  gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0); }`);
  const fs = glCompile(gl, gl.FRAGMENT_SHADER, complete ? glsl : `#version 300 es
precision highp float;
precision highp int;
uniform highp sampler2D normals;
layout(location = 0) out vec4 outIrr;
layout(location = 1) out vec4 outPoly;
layout(location = 2) out vec4 outNormal;
${glsl}
void main() {
  vec3 n = texelFetch(normals, ivec2(gl_FragCoord.xy), 0).xyz;
  outIrr = vec4(shprobe_irradiance(n), 1.0);
  outPoly = vec4(shprobe_irradiance_poly(n), 1.0);
  outNormal = vec4(n, 1.0);
}`);
  const prog = gl.createProgram();
  gl.attachShader(prog, vs); gl.attachShader(prog, fs); gl.linkProgram(prog);
  if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(prog));
  const data = new Float32Array(Wd * H * 4);
  for (let i = 0; i < N; i++) data.set(normals.slice(3 * i, 3 * i + 3), 4 * i);
  const tex = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_2D, tex);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, Wd, H, 0, gl.RGBA, gl.FLOAT, data);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
  const fb = gl.createFramebuffer();
  gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
  const targets = [0, 1, 2].map((i) => {
    const t = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, t);
    gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA32F, Wd, H);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0 + i, gl.TEXTURE_2D, t, 0);
    return t;
  });
  gl.drawBuffers([gl.COLOR_ATTACHMENT0, gl.COLOR_ATTACHMENT1, gl.COLOR_ATTACHMENT2]);
  gl.viewport(0, 0, Wd, H);
  gl.useProgram(prog);
  gl.activeTexture(gl.TEXTURE0);
  gl.bindTexture(gl.TEXTURE_2D, tex);
  for (let u = 0; u < gl.getProgramParameter(prog, gl.ACTIVE_UNIFORMS); u++) {
    const a = gl.getActiveUniform(prog, u);
    if (a.type === gl.SAMPLER_2D) gl.uniform1i(gl.getUniformLocation(prog, a.name), 0);
  }
  gl.drawArrays(gl.TRIANGLES, 0, 3);
  const read = (i) => {
    gl.readBuffer(gl.COLOR_ATTACHMENT0 + i);
    const px = new Float32Array(Wd * H * 4);
    gl.readPixels(0, 0, Wd, H, gl.RGBA, gl.FLOAT, px);
    const o = [];
    for (let j = 0; j < N; j++) o.push(px[4 * j], px[4 * j + 1], px[4 * j + 2]);
    return o;
  };
  const res = { irradiance: read(0), poly: read(1), normals: read(2), info };
  targets.forEach((t) => gl.deleteTexture(t));
  return res;
}

export async function webgpu(wgsl, normals) {
  if (!navigator.gpu) throw new Error("no navigator.gpu");
  const adapter = await navigator.gpu.requestAdapter();
  if (!adapter) throw new Error("WebGPU gave no adapter");
  const device = await adapter.requestDevice();
  const bare = device.createShaderModule({ code: wgsl });
  const msgs = (await bare.getCompilationInfo()).messages.map(
    (m) => ({ type: m.type, message: m.message, line: m.lineNum }));
  const N = normals.length / 3;
  const code = `${wgsl}
@group(0) @binding(0) var<storage, read> normals: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read_write> result: array<vec4<f32>>;
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
  let i = id.x;
  if (i >= arrayLength(&normals)) { return; }
  let n = normals[i].xyz;
  result[3u * i] = vec4<f32>(shprobe_irradiance(n), 0.0);
  result[3u * i + 1u] = vec4<f32>(shprobe_irradiance_poly(n), 0.0);
  result[3u * i + 2u] = vec4<f32>(n, 0.0);
}`;
  const mod = device.createShaderModule({ code });
  const wrapMsgs = (await mod.getCompilationInfo()).messages.filter((m) => m.type === "error");
  if (wrapMsgs.length) throw new Error(wrapMsgs.map((m) => m.message).join("; "));
  const pipeline = device.createComputePipeline({ layout: "auto", compute: { module: mod, entryPoint: "main" } });
  const inData = new Float32Array(N * 4);
  for (let i = 0; i < N; i++) inData.set(normals.slice(3 * i, 3 * i + 3), 4 * i);
  const inBuf = device.createBuffer({ size: inData.byteLength, usage: GPUBufferUsage.STORAGE | GPUBufferUsage.COPY_DST });
  device.queue.writeBuffer(inBuf, 0, inData);
  const size = N * 3 * 16;
  const outBuf = device.createBuffer({ size, usage: GPUBufferUsage.STORAGE | GPUBufferUsage.COPY_SRC });
  const readBuf = device.createBuffer({ size, usage: GPUBufferUsage.MAP_READ | GPUBufferUsage.COPY_DST });
  const bind = device.createBindGroup({ layout: pipeline.getBindGroupLayout(0), entries: [
    { binding: 0, resource: { buffer: inBuf } }, { binding: 1, resource: { buffer: outBuf } }] });
  const enc = device.createCommandEncoder();
  const pass = enc.beginComputePass();
  pass.setPipeline(pipeline); pass.setBindGroup(0, bind);
  pass.dispatchWorkgroups(Math.ceil(N / 64)); pass.end();
  enc.copyBufferToBuffer(outBuf, 0, readBuf, 0, size);
  device.queue.submit([enc.finish()]);
  await readBuf.mapAsync(GPUMapMode.READ);
  const f = new Float32Array(readBuf.getMappedRange().slice(0));
  readBuf.unmap();
  const pick = (k) => { const o = []; for (let i = 0; i < N; i++) o.push(f[12 * i + 4 * k], f[12 * i + 4 * k + 1], f[12 * i + 4 * k + 2]); return o; };
  const ai = adapter.info || {};
  device.destroy();
  return { messages: msgs, irradiance: pick(0), poly: pick(1), normals: pick(2),
    adapter: [ai.vendor, ai.architecture, ai.device, ai.description].join(" ") };
}
