// SH rotation at any order (Ivanic-Ruedenberg), the port of prt_addon/core/sh/rotation.py and frames.py.
//
// Real orthonormal SH without the Condon-Shortley phase, index i = l(l+1) + m (docs/export.md).
// bandMatrices(R, n) returns the blocks of M with M c = the coefficients of f(R^-1 w): band 1 is
// R permuted to (y, z, x), band l follows from band 1 and band l-1 by the recurrence of Ivanic &
// Ruedenberg, J. Phys. Chem. 100 (1996) 6342, corrected in J. Phys. Chem. A 102 (1998) 9099.
// Matrices are row-major arrays: R[3 * row + column].

const BAND1 = [1, 2, 0]; // y, z, x

function band1(r) {
  const out = new Float64Array(9);
  for (let i = 0; i < 3; i++) {
    for (let j = 0; j < 3; j++) out[3 * i + j] = r[3 * BAND1[i] + BAND1[j]];
  }
  return out;
}

// P(i, l, a, b) of the recurrence: r1 indexed -1..1, prev (band l-1) indexed -(l-1)..l-1.
function p(i, l, a, b, r1, prev) {
  const size = 2 * l - 1;
  const at = (x, y) => prev[(x + l - 1) * size + (y + l - 1)];
  const row = (i + 1) * 3;
  if (b === l) return r1[row + 2] * at(a, l - 1) - r1[row] * at(a, -l + 1);
  if (b === -l) return r1[row + 2] * at(a, -l + 1) + r1[row] * at(a, l - 1);
  return r1[row + 1] * at(a, b);
}

function nextBand(r1, prev, l) {
  const size = 2 * l + 1;
  const out = new Float64Array(size * size);
  for (let m = -l; m <= l; m++) {
    const am = Math.abs(m);
    const d0 = m === 0 ? 1 : 0;
    for (let n = -l; n <= l; n++) {
      const denom = Math.abs(n) < l ? (l + n) * (l - n) : 2 * l * (2 * l - 1);
      const u = Math.sqrt(((l + m) * (l - m)) / denom);
      const v = 0.5 * Math.sqrt(((1 + d0) * (l + am - 1) * (l + am)) / denom) * (1 - 2 * d0);
      const w = -0.5 * Math.sqrt(Math.max(0, (l - am - 1) * (l - am)) / denom) * (1 - d0);
      let value = 0;
      if (u !== 0) value += u * p(0, l, m, n, r1, prev);
      if (v !== 0) {
        let vv;
        if (m === 0) vv = p(1, l, 1, n, r1, prev) + p(-1, l, -1, n, r1, prev);
        else if (m > 0) {
          vv = p(1, l, m - 1, n, r1, prev) * Math.sqrt(1 + (m === 1 ? 1 : 0));
          if (m !== 1) vv -= p(-1, l, -m + 1, n, r1, prev);
        } else {
          vv = p(-1, l, -m - 1, n, r1, prev) * Math.sqrt(1 + (m === -1 ? 1 : 0));
          if (m !== -1) vv += p(1, l, m + 1, n, r1, prev);
        }
        value += v * vv;
      }
      if (w !== 0) {
        const ww =
          m > 0
            ? p(1, l, m + 1, n, r1, prev) + p(-1, l, -m - 1, n, r1, prev)
            : p(1, l, m - 1, n, r1, prev) - p(-1, l, -m + 1, n, r1, prev);
        value += w * ww;
      }
      out[(m + l) * size + (n + l)] = value;
    }
  }
  return out;
}

/** Per-band blocks [1x1, 3x3, ..., (2n-1)^2] (row-major Float64Arrays) of the rotation R (3x3). */
export function bandMatrices(r, order) {
  if (!Number.isInteger(order) || order < 1) throw new Error(`SH order must be an integer >= 1, got ${order}`);
  const blocks = [Float64Array.of(1)];
  if (order === 1) return blocks;
  const r1 = band1(r);
  blocks.push(r1);
  for (let l = 2; l < order; l++) blocks.push(nextBand(r1, blocks[l - 1], l));
  return blocks;
}

/** The full (n*n) x (n*n) block-diagonal matrix, row-major Float64Array. */
export function rotationMatrix(r, order) {
  const n2 = order * order;
  const out = new Float64Array(n2 * n2);
  bandMatrices(r, order).forEach((block, l) => {
    const s = l * l;
    const size = 2 * l + 1;
    for (let i = 0; i < size; i++) {
      for (let j = 0; j < size; j++) out[(s + i) * n2 + s + j] = block[i * size + j];
    }
  });
  return out;
}

/**
 * Rotated RGB coefficients: coeffs is an array of n*n [r, g, b] rows (as in the file); returns
 * `order`*`order` rows (truncated or zero-padded) of M c, band l also negated when `parity` and l odd.
 */
export function rotateRGB(coeffs, r, order, parity = false) {
  const out = [];
  const blocks = bandMatrices(r, order);
  for (let l = 0; l < order; l++) {
    const size = 2 * l + 1;
    const s = l * l;
    const sign = parity && l % 2 ? -1 : 1;
    for (let i = 0; i < size; i++) {
      const row = [0, 0, 0];
      for (let j = 0; j < size; j++) {
        const c = coeffs[s + j];
        if (c === undefined) continue;
        const k = blocks[l][i * size + j] * sign;
        row[0] += k * c[0];
        row[1] += k * c[1];
        row[2] += k * c[2];
      }
      out.push(row);
    }
  }
  return out;
}

function det3(a) {
  return a[0] * (a[4] * a[8] - a[5] * a[7]) - a[1] * (a[3] * a[8] - a[5] * a[6]) + a[2] * (a[3] * a[7] - a[4] * a[6]);
}

function inverseTranspose3(a) {
  const d = det3(a);
  return [
    (a[4] * a[8] - a[5] * a[7]) / d,
    (a[5] * a[6] - a[3] * a[8]) / d,
    (a[3] * a[7] - a[4] * a[6]) / d,
    (a[2] * a[7] - a[1] * a[8]) / d,
    (a[0] * a[8] - a[2] * a[6]) / d,
    (a[1] * a[6] - a[0] * a[7]) / d,
    (a[1] * a[5] - a[2] * a[4]) / d,
    (a[2] * a[3] - a[0] * a[5]) / d,
    (a[0] * a[4] - a[1] * a[3]) / d,
  ];
}

/**
 * {rotation, mirrored}: the rotation part of a 3x3 matrix (row-major), as core/sh/frames.py's
 * frame_rotation: the orthogonal polar factor Q of A = Q S (Newton's iteration Q <- (Q + Q^-T) / 2,
 * quadratic convergence), R = Q when det Q > 0, else R = -Q and mirrored.
 */
export function frameRotation(a) {
  let q = Array.from(a);
  for (let it = 0; it < 100; it++) {
    const qi = inverseTranspose3(q);
    let change = 0;
    const next = q.map((x, k) => {
      const y = 0.5 * (x + qi[k]);
      change = Math.max(change, Math.abs(y - x));
      return y;
    });
    q = next;
    if (change < 1e-15) break;
  }
  if (det3(q) < 0) return { rotation: q.map((x) => -x), mirrored: true };
  return { rotation: q, mirrored: false };
}

export function transpose3(a) {
  return [a[0], a[3], a[6], a[1], a[4], a[7], a[2], a[5], a[8]];
}

export function multiply3(a, b) {
  const out = new Array(9).fill(0);
  for (let i = 0; i < 3; i++) {
    for (let j = 0; j < 3; j++) {
      for (let k = 0; k < 3; k++) out[3 * i + j] += a[3 * i + k] * b[3 * k + j];
    }
  }
  return out;
}

/**
 * The light in a node's local frame (docs/export.md, Shading steps 1-2): world RGB coefficients,
 * first turned by the user's rotation `turn` (3x3, world frame), then by R^-1 with R the rotation
 * part of the node's world matrix `linear` (3x3); odd bands negated for a mirrored node.
 */
export function lightInLocalFrame(worldCoeffs, linear, order, turn = [1, 0, 0, 0, 1, 0, 0, 0, 1]) {
  const { rotation, mirrored } = frameRotation(linear);
  return rotateRGB(worldCoeffs, multiply3(transpose3(rotation), turn), order, mirrored);
}
