// Rotations of the designer page (3×3, row major) and the turning of lmax ≤ 2 lighting in the
// page while dragging. The page's rotation is the library's: tests/test_viewer.py compares
// rotateLow with shprobe.lighting.design.rotate_lighting (the Wigner rotation) at random
// rotations, and the drag's matrices with shprobe.sh.rotation.from_axis_angle.

export const IDENTITY = [[1, 0, 0], [0, 1, 0], [0, 0, 1]];

export function rotAxis(axis, deg) {
  const n = Math.hypot(...axis), [x, y, z] = axis.map((v) => v / n), t = deg * Math.PI / 180;
  const c = Math.cos(t), s = Math.sin(t), C = 1 - c;
  return [[c + x * x * C, x * y * C - z * s, x * z * C + y * s],
          [y * x * C + z * s, c + y * y * C, y * z * C - x * s],
          [z * x * C - y * s, z * y * C + x * s, c + z * z * C]];
}
export function mul(A, B) { return A.map((r) => [0, 1, 2].map((j) => r[0] * B[0][j] + r[1] * B[1][j] + r[2] * B[2][j])); }

// the edit state's {axis, degrees} of R, via the quaternion (robust near 180°); null: none
export function toAxisAngle(R) {
  const tr = R[0][0] + R[1][1] + R[2][2];
  let w, x, y, z;
  if (tr > 0) { const s = 2 * Math.sqrt(tr + 1); w = s / 4; x = (R[2][1] - R[1][2]) / s; y = (R[0][2] - R[2][0]) / s; z = (R[1][0] - R[0][1]) / s; }
  else if (R[0][0] > R[1][1] && R[0][0] > R[2][2]) { const s = 2 * Math.sqrt(1 + R[0][0] - R[1][1] - R[2][2]); w = (R[2][1] - R[1][2]) / s; x = s / 4; y = (R[0][1] + R[1][0]) / s; z = (R[0][2] + R[2][0]) / s; }
  else if (R[1][1] > R[2][2]) { const s = 2 * Math.sqrt(1 + R[1][1] - R[0][0] - R[2][2]); w = (R[0][2] - R[2][0]) / s; x = (R[0][1] + R[1][0]) / s; y = s / 4; z = (R[1][2] + R[2][1]) / s; }
  else { const s = 2 * Math.sqrt(1 + R[2][2] - R[0][0] - R[1][1]); w = (R[1][0] - R[0][1]) / s; x = (R[0][2] + R[2][0]) / s; y = (R[1][2] + R[2][1]) / s; z = s / 4; }
  if (w < 0) { w = -w; x = -x; y = -y; z = -z; }
  const sn = Math.hypot(x, y, z);
  if (sn < 1e-12) return null;
  return { axis: [x / sn, y / sn, z / sn], degrees: 2 * Math.atan2(sn, w) * 180 / Math.PI };
}
export function stateRotation(s) { return s.rotation ? rotAxis(s.rotation.axis, s.rotation.degrees) : IDENTITY; }

// a direction given in the world frame, unrotated (lights are stored before the rotation: the
// CLI rotates after adding them)
export function unrotate(s, d) { const R = stateRotation(s); return [0, 1, 2].map((i) => R[0][i] * d[0] + R[1][i] * d[1] + R[2][i] * d[2]); }

// Rotation of lmax ≤ 2 lighting in the page (no server round trip while dragging), exact:
// band 1 is a vector a with f(ω) = a·ω (R&H order y, z, x), turned as a' = R a; band 2 is a
// traceless quadratic form f(ω) = ωᵀQω, turned as Q' = R Q Rᵀ; f∘R⁻¹ as the library's
// rotate_lighting (the server's answer replaces this one when it arrives).
const K1 = 1.092548430592079, K0 = 0.3153915652525200, K2 = 0.5462742152960396;
export function rotateLow(L, R) {  // L: (K ≤ 9, 3) → the coefficients of L∘R⁻¹
  const out = L.map((c) => c.slice());
  for (let ch = 0; ch < 3; ch++) {
    if (L.length >= 4) {
      const a = [L[3][ch], L[1][ch], L[2][ch]];  // (x, y, z)
      const b = [0, 1, 2].map((i) => R[i][0] * a[0] + R[i][1] * a[1] + R[i][2] * a[2]);
      out[1][ch] = b[1]; out[2][ch] = b[2]; out[3][ch] = b[0];
    }
    if (L.length >= 9) {
      const [m2, m1, z0, p1, p2] = [L[4][ch], L[5][ch], L[6][ch], L[7][ch], L[8][ch]];
      const Q = [[-K0 * z0 + K2 * p2, K1 * m2 / 2, K1 * p1 / 2],
                 [K1 * m2 / 2, -K0 * z0 - K2 * p2, K1 * m1 / 2],
                 [K1 * p1 / 2, K1 * m1 / 2, 2 * K0 * z0]];
      const RQ = mul(R, Q);
      const Qr = [0, 1, 2].map((i) => [0, 1, 2].map((j) => RQ[i][0] * R[j][0] + RQ[i][1] * R[j][1] + RQ[i][2] * R[j][2]));
      out[4][ch] = 2 * Qr[0][1] / K1; out[5][ch] = 2 * Qr[1][2] / K1; out[7][ch] = 2 * Qr[0][2] / K1;
      out[6][ch] = Qr[2][2] / (2 * K0); out[8][ch] = (Qr[0][0] - Qr[1][1]) / (2 * K2);
    }
  }
  return out;
}

// drag on the probe: horizontal = about +Y (features follow the cursor in azimuth), vertical =
// about +X (features at the centre column, −Z, follow the cursor in elevation)
export function dragRotation(dx, dy, w, h) {
  return mul(rotAxis([1, 0, 0], -180 * dy / h), rotAxis([0, 1, 0], -360 * dx / w));
}
