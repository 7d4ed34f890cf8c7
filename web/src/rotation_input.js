// Rotations as the public API takes them (Matrix3, Matrix4, Quaternion, Euler or 9 numbers) made row-major 3x3 arrays.
import * as THREE from 'three';

/** Row-major 3x3 (9 numbers) of a THREE.Matrix3, Matrix4 (its upper 3x3), Quaternion, Euler or 9 numbers. */
export function rotationRows(rotation) {
  if (rotation && rotation.isQuaternion) return rotationRows(new THREE.Matrix4().makeRotationFromQuaternion(rotation));
  if (rotation && rotation.isEuler) return rotationRows(new THREE.Matrix4().makeRotationFromEuler(rotation));
  if (rotation && rotation.isMatrix4) {
    const e = rotation.elements;
    return [e[0], e[4], e[8], e[1], e[5], e[9], e[2], e[6], e[10]];
  }
  if (rotation && rotation.isMatrix3) {
    const e = rotation.elements;
    return [e[0], e[3], e[6], e[1], e[4], e[7], e[2], e[5], e[8]];
  }
  const rows = Array.from(rotation || []);
  if (rows.length !== 9 || !rows.every(Number.isFinite)) {
    throw new TypeError('a lighting rotation is a THREE.Matrix3, Matrix4, Quaternion, Euler or 9 numbers (row-major)');
  }
  return rows;
}

/** The 3-vector d turned by the row-major 3x3 r. */
export function turned(r, d) {
  return [
    r[0] * d[0] + r[1] * d[1] + r[2] * d[2],
    r[3] * d[0] + r[4] * d[1] + r[5] * d[2],
    r[6] * d[0] + r[7] * d[1] + r[8] * d[2],
  ];
}
