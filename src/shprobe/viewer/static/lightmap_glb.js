// shprobe view --lightmap: the .glb read in the page, as the SHPROBE_lightmap extension
// (shprobe.lightmaps.format) lays it out. Geometry (POSITION, NORMAL, TEXCOORD_0, TEXCOORD_1,
// indices, node transforms applied), materials (base colour factor and texture, normal
// texture and its scale) and the stored coefficient textures (RGBA16F, row 0 at v = 0, as
// uint16 half-float bit patterns: uploaded as they are, no flip).
const GLB = 0x46546c67, JSON_CHUNK = 0x4e4f534a, BIN_CHUNK = 0x004e4942;
const COMPONENTS = { SCALAR: 1, VEC2: 2, VEC3: 3, VEC4: 4, MAT4: 16 };
const TYPES = { 5120: Int8Array, 5121: Uint8Array, 5122: Int16Array, 5123: Uint16Array,
  5125: Uint32Array, 5126: Float32Array };
export const EXTENSION = 'SHPROBE_lightmap';

export function parseGlb(buf) {
  const dv = new DataView(buf);
  if (buf.byteLength < 20 || dv.getUint32(0, true) !== GLB) throw new Error('not a binary glTF');
  const jlen = dv.getUint32(12, true);
  if (dv.getUint32(16, true) !== JSON_CHUNK) throw new Error('glb has no JSON chunk first');
  const json = JSON.parse(new TextDecoder().decode(new Uint8Array(buf, 20, jlen)));
  let bin = new Uint8Array(0);
  const at = 20 + jlen;
  if (at + 8 <= buf.byteLength && dv.getUint32(at + 4, true) === BIN_CHUNK) {
    bin = new Uint8Array(buf, at + 8, dv.getUint32(at, true));
  }
  return { json, bin };
}

function viewBytes(g, index) {
  const v = g.json.bufferViews[index];
  return { offset: g.bin.byteOffset + (v.byteOffset || 0), length: v.byteLength,
    stride: v.byteStride || 0 };
}

// an accessor as a tightly packed typed array (copied when strided or unaligned)
export function accessor(g, index) {
  const a = g.json.accessors[index];
  const T = TYPES[a.componentType], n = COMPONENTS[a.type];
  const v = viewBytes(g, a.bufferView);
  const start = v.offset + (a.byteOffset || 0), size = T.BYTES_PER_ELEMENT;
  if ((!v.stride || v.stride === n * size) && start % size === 0) {
    return new T(g.bin.buffer, start, a.count * n);
  }
  const out = new T(a.count * n), dv = new DataView(g.bin.buffer);
  const get = { 1: 'getInt8', 2: a.componentType === 5122 ? 'getInt16' : 'getUint16',
    4: a.componentType === 5126 ? 'getFloat32' : 'getUint32' }[size];
  const s = v.stride || n * size;
  for (let i = 0; i < a.count; i++) {
    for (let k = 0; k < n; k++) out[i * n + k] = dv[get](start + i * s + k * size, true);
  }
  return out;
}

function mul4(a, b) {  // column-major 4×4 product a·b
  const o = new Array(16).fill(0);
  for (let c = 0; c < 4; c++) for (let r = 0; r < 4; r++) {
    for (let k = 0; k < 4; k++) o[c * 4 + r] += a[k * 4 + r] * b[c * 4 + k];
  }
  return o;
}

function nodeMatrix(node) {
  if (node.matrix) return node.matrix.slice();
  const [x, y, z, w] = node.rotation || [0, 0, 0, 1];
  const [sx, sy, sz] = node.scale || [1, 1, 1];
  const [tx, ty, tz] = node.translation || [0, 0, 0];
  return [(1 - 2 * (y * y + z * z)) * sx, 2 * (x * y + z * w) * sx, 2 * (x * z - y * w) * sx, 0,
    2 * (x * y - z * w) * sy, (1 - 2 * (x * x + z * z)) * sy, 2 * (y * z + x * w) * sy, 0,
    2 * (x * z + y * w) * sz, 2 * (y * z - x * w) * sz, (1 - 2 * (x * x + y * y)) * sz, 0,
    tx, ty, tz, 1];
}

function transform(m, arr, w) {  // points (w = 1) or normals (w = 0, then renormalised)
  const out = new Float32Array(arr.length);
  for (let i = 0; i < arr.length; i += 3) {
    const x = arr[i], y = arr[i + 1], z = arr[i + 2];
    let a = m[0] * x + m[4] * y + m[8] * z + w * m[12];
    let b = m[1] * x + m[5] * y + m[9] * z + w * m[13];
    let c = m[2] * x + m[6] * y + m[10] * z + w * m[14];
    if (!w) { const l = Math.hypot(a, b, c) || 1; a /= l; b /= l; c /= l; }
    out[i] = a; out[i + 1] = b; out[i + 2] = c;
  }
  return out;
}

// every triangle primitive of the default scene, in world space
export function primitives(g) {
  const out = [], json = g.json, scene = json.scenes?.[json.scene || 0];
  const walk = (i, parent) => {
    const node = json.nodes[i], m = mul4(parent, nodeMatrix(node));
    if (node.mesh !== undefined) {
      json.meshes[node.mesh].primitives.forEach((p, pi) => {
        if ((p.mode ?? 4) !== 4 || p.attributes.TEXCOORD_1 === undefined) return;
        const at = p.attributes, pos = accessor(g, at.POSITION);
        const idx = p.indices !== undefined ? accessor(g, p.indices)
          : Uint32Array.from({ length: pos.length / 3 }, (_, k) => k);
        out.push({ mesh: node.mesh, primitive: pi, material: p.material,
          position: transform(m, pos, 1),
          normal: at.NORMAL !== undefined ? transform(m, accessor(g, at.NORMAL), 0) : null,
          uv0: at.TEXCOORD_0 !== undefined ? Float32Array.from(accessor(g, at.TEXCOORD_0)) : null,
          uv1: Float32Array.from(accessor(g, at.TEXCOORD_1)),
          index: Uint32Array.from(idx) });
      });
    }
    (node.children || []).forEach((c) => walk(c, m));
  };
  const identity = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1];
  (scene ? scene.nodes : json.nodes.map((_, i) => i)).forEach((i) => walk(i, identity));
  return out;
}

// an image of the file as RGBA bytes (decoded by the browser, no colour conversion)
export async function imagePixels(g, index) {
  const im = g.json.images[index];
  if (im.bufferView === undefined) throw new Error(`image ${index} is not inside the .glb`);
  const v = viewBytes(g, im.bufferView);
  const blob = new Blob([new Uint8Array(g.bin.buffer, v.offset, v.length)],
    { type: im.mimeType || 'image/png' });
  const bmp = await createImageBitmap(blob, { colorSpaceConversion: 'none',
    premultiplyAlpha: 'none' });
  const c = new OffscreenCanvas(bmp.width, bmp.height);
  const ctx = c.getContext('2d', { colorSpace: 'srgb' });
  ctx.drawImage(bmp, 0, 0);
  const d = ctx.getImageData(0, 0, bmp.width, bmp.height).data;
  return { width: bmp.width, height: bmp.height, data: new Uint8Array(d.buffer) };
}

// the materials' maps: {baseColor: [r, g, b, a], baseTexture, normalTexture, normalScale}
export function materials(g) {
  return (g.json.materials || []).map((m) => {
    const pbr = m.pbrMetallicRoughness || {}, tex = (t) => (t === undefined ? null
      : g.json.textures[t.index].source);
    return { baseColor: pbr.baseColorFactor || [1, 1, 1, 1],
      baseImage: tex(pbr.baseColorTexture), normalImage: tex(m.normalTexture),
      normalScale: m.normalTexture?.scale ?? 1 };
  });
}

function halfViews(g, ext, list) {  // RGBA16F bufferViews as Uint16Array (H·W·4)
  const n = ext.width * ext.height * 4;
  return list.map((t) => {
    const v = viewBytes(g, t.bufferView);
    if (v.length !== n * 2) throw new Error('a lightmap texture has the wrong size');
    return v.offset % 2 === 0 ? new Uint16Array(g.bin.buffer, v.offset, n)
      : new Uint16Array(g.bin.slice(v.offset - g.bin.byteOffset, v.offset - g.bin.byteOffset + 2 * n).buffer);
  });
}

// the stored coefficient textures: {ext, textures: [Uint16Array (H·W·4)], layout}
export function lightmapTextures(g) {
  const ext = g.json.extensions?.[EXTENSION];
  if (!ext) throw new Error(`the file has no ${EXTENSION} extension`);
  return { ext, textures: halfViews(g, ext, ext.textures),
    layout: ext.textures.map((t) => t.components) };
}

// the transfer's textures, one array per sky SH coefficient j (9), packed like the stored
// ones (format.py: "Transfer"); null when the file has none
export function transferTextures(g) {
  const ext = g.json.extensions?.[EXTENSION], tr = ext?.transfer;
  if (!tr) return null;
  if (!Array.isArray(tr.sets) || tr.sets.length !== 9) throw new Error('the transfer needs 9 sets');
  return tr.sets.map((s) => {
    if (s.textures?.length !== ext.textures.length) throw new Error('a transfer set has the wrong textures');
    return halfViews(g, ext, s.textures);
  });
}
