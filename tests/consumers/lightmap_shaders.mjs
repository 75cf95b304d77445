// The lightmap shader functions (shprobe.lightmaps.shaders) run in headless Chromium by
// tests/lightmaps/test_lightmaps_shaders.py. Every case is N texels in one row: the coefficient
// textures as RGBA16F (the file's half floats, passed as their uint16 bit patterns), one
// tangent-space normal per texel (float32); the result is E per texel (float32, RGB).
//   webgl2(src, call, k, halves, normals, complete): GLSL ES 3.00 in a fragment shader over a
//     float framebuffer; `call` names the *_sample function; complete = true takes a whole
//     fragment shader (the HLSL functions after glslang → SPIR-V → SPIRV-Cross).
//   webgpu(wgsl, call, k, halves, normals): WGSL in a compute shader (Tint).

function compile(gl, type, src) {
  const s = gl.createShader(type);
  gl.shaderSource(s, src);
  gl.compileShader(s);
  if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
  return s;
}

export function webgl2(src, call, k, halves, normals, complete) {
  const N = normals.length / 3;
  const gl = document.createElement("canvas").getContext("webgl2");
  if (!gl) throw new Error("no WebGL2 context");
  if (!gl.getExtension("EXT_color_buffer_float")) throw new Error("no EXT_color_buffer_float");
  const vs = compile(gl, gl.VERTEX_SHADER, `#version 300 es
void main() { vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
  gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0); }`);
  const ts = Array.from({ length: k }, (_, i) => `t${i}`);
  const fs = compile(gl, gl.FRAGMENT_SHADER, complete ? src : `#version 300 es
precision highp float;
precision highp int;
uniform highp sampler2D normals;
${ts.map((t) => `uniform highp sampler2D ${t};`).join("\n")}
out vec4 outE;
${src}
void main() {
  ivec2 p = ivec2(gl_FragCoord.xy);
  vec3 n = texelFetch(normals, p, 0).xyz;
  vec2 uv = (vec2(p) + 0.5) / vec2(${N}.0, 1.0);
  outE = vec4(${call}(${ts.join(", ")}, uv, n), 1.0);
}`);
  const prog = gl.createProgram();
  gl.attachShader(prog, vs); gl.attachShader(prog, fs); gl.linkProgram(prog);
  if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(prog));
  gl.useProgram(prog);
  const texture = (unit, internal, type, data) => {
    const t = gl.createTexture();
    gl.activeTexture(gl.TEXTURE0 + unit);
    gl.bindTexture(gl.TEXTURE_2D, t);
    gl.texImage2D(gl.TEXTURE_2D, 0, internal, N, 1, 0, gl.RGBA, type, data);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
  };
  const nrm = new Float32Array(N * 4);
  for (let i = 0; i < N; i++) nrm.set(normals.slice(3 * i, 3 * i + 3), 4 * i);
  texture(0, gl.RGBA32F, gl.FLOAT, nrm);
  for (let i = 0; i < k; i++) texture(i + 1, gl.RGBA16F, gl.HALF_FLOAT, new Uint16Array(halves[i]));
  for (let u = 0; u < gl.getProgramParameter(prog, gl.ACTIVE_UNIFORMS); u++) {
    const name = gl.getActiveUniform(prog, u).name;  // SPIRV-Cross: SPIRV_Cross_Combinedt3smp
    const m = /(?:^|Combined)t(\d+)/.exec(name);
    gl.uniform1i(gl.getUniformLocation(prog, name), m ? Number(m[1]) + 1 : 0);
  }
  const target = gl.createTexture();
  gl.activeTexture(gl.TEXTURE0 + k + 1);
  gl.bindTexture(gl.TEXTURE_2D, target);
  gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA32F, N, 1);
  gl.bindFramebuffer(gl.FRAMEBUFFER, gl.createFramebuffer());
  gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, target, 0);
  gl.viewport(0, 0, N, 1);
  gl.drawArrays(gl.TRIANGLES, 0, 3);
  const px = new Float32Array(N * 4);
  gl.readPixels(0, 0, N, 1, gl.RGBA, gl.FLOAT, px);
  const out = [];
  for (let i = 0; i < N; i++) out.push(px[4 * i], px[4 * i + 1], px[4 * i + 2]);
  gl.getExtension("WEBGL_lose_context")?.loseContext();
  return out;
}

export async function webgpu(wgsl, call, k, halves, normals) {
  if (!navigator.gpu) throw new Error("no navigator.gpu");
  const adapter = await navigator.gpu.requestAdapter();
  if (!adapter) throw new Error("WebGPU gave no adapter");
  const device = await adapter.requestDevice();
  const N = normals.length / 3;
  const bare = device.createShaderModule({ code: wgsl });
  const messages = (await bare.getCompilationInfo()).messages.map(
    (m) => ({ type: m.type, message: m.message, line: m.lineNum }));
  const ts = Array.from({ length: k }, (_, i) => `t${i}`);
  const code = `${wgsl}
@group(0) @binding(0) var<storage, read> normals: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read_write> result: array<vec4<f32>>;
@group(0) @binding(2) var lm_smp: sampler;
${ts.map((t, i) => `@group(0) @binding(${i + 3}) var ${t}: texture_2d<f32>;`).join("\n")}
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
  let i = id.x;
  if (i >= arrayLength(&normals)) { return; }
  let uv = vec2<f32>((f32(i) + 0.5) / ${N}.0, 0.5);
  result[i] = vec4<f32>(${call}(${ts.join(", ")}, lm_smp, uv, normals[i].xyz), 0.0);
}`;
  const mod = device.createShaderModule({ code });
  const errs = (await mod.getCompilationInfo()).messages.filter((m) => m.type === "error");
  if (errs.length) throw new Error(errs.map((m) => m.message).join("; "));
  const pipeline = device.createComputePipeline({ layout: "auto", compute: { module: mod, entryPoint: "main" } });
  const nrm = new Float32Array(N * 4);
  for (let i = 0; i < N; i++) nrm.set(normals.slice(3 * i, 3 * i + 3), 4 * i);
  const inBuf = device.createBuffer({ size: nrm.byteLength, usage: GPUBufferUsage.STORAGE | GPUBufferUsage.COPY_DST });
  device.queue.writeBuffer(inBuf, 0, nrm);
  const size = N * 16;
  const outBuf = device.createBuffer({ size, usage: GPUBufferUsage.STORAGE | GPUBufferUsage.COPY_SRC });
  const readBuf = device.createBuffer({ size, usage: GPUBufferUsage.MAP_READ | GPUBufferUsage.COPY_DST });
  const entries = [{ binding: 0, resource: { buffer: inBuf } }, { binding: 1, resource: { buffer: outBuf } },
    { binding: 2, resource: device.createSampler({ magFilter: "nearest", minFilter: "nearest" }) }];
  for (let i = 0; i < k; i++) {
    const t = device.createTexture({ size: [N, 1], format: "rgba16float",
      usage: GPUTextureUsage.TEXTURE_BINDING | GPUTextureUsage.COPY_DST });
    device.queue.writeTexture({ texture: t }, new Uint16Array(halves[i]), { bytesPerRow: N * 8 }, [N, 1]);
    entries.push({ binding: i + 3, resource: t.createView() });
  }
  const bind = device.createBindGroup({ layout: pipeline.getBindGroupLayout(0), entries });
  const enc = device.createCommandEncoder();
  const pass = enc.beginComputePass();
  pass.setPipeline(pipeline); pass.setBindGroup(0, bind);
  pass.dispatchWorkgroups(Math.ceil(N / 64)); pass.end();
  enc.copyBufferToBuffer(outBuf, 0, readBuf, 0, size);
  device.queue.submit([enc.finish()]);
  await readBuf.mapAsync(GPUMapMode.READ);
  const f = new Float32Array(readBuf.getMappedRange().slice(0));
  readBuf.unmap();
  device.destroy();
  const out = [];
  for (let i = 0; i < N; i++) out.push(f[4 * i], f[4 * i + 1], f[4 * i + 2]);
  return { messages, values: out };
}
