// The page side of shprobe.viewer.wire: one binary message (pack_binary) read into its JSON
// head and typed views of its arrays (no copy). Shared by the designer page and the grid page.
export function unpack(buf) {
  const n = new DataView(buf).getUint32(0, true);
  const head = JSON.parse(new TextDecoder().decode(new Uint8Array(buf, 4, n)));
  const base = 4 + n, out = { head };
  for (const [k, m] of Object.entries(head.arrays || {})) {
    const len = m.shape.reduce((a, b) => a * b, 1);
    const T = { f2: Uint16Array, f4: Float32Array, u4: Uint32Array }[m.dtype];
    out[k] = new T(buf, base + m.offset, len);
  }
  return out;
}
