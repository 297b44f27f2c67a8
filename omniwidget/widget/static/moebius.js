// Möbius maps of the sphere for the editor's live drag: the JavaScript twin of
// omniwidget/sphere/moebius.py and of the handles' maps in omniwidget/document/handles.py.
//
// Same conventions as omniwidget/sphere/coords.py (sphere.js): [lon, lat] in degrees, unit
// vector (cos lat cos lon, cos lat sin lon, sin lat), stereographic homogeneous coordinates
// [u : v] chosen as coords.xyz_to_homogeneous chooses them. A map is its 2 x 2 complex
// matrix {a, b, c, d} (each [re, im]) normalised to determinant 1. tests/js/moebius.test.mjs
// checks every function here against the Python it mirrors.

import { ARROW_LENGTH, controlPoints } from "./handles.js";
import { cross, DEG, dot, lonlatToXYZ, norm, xyzToLonLat } from "./sphere.js";

/** @typedef {import("./sphere.js").LonLat} LonLat */
/** @typedef {import("./sphere.js").Vec3} Vec3 */
/** @typedef {import("./handles.js").Handle} Handle */
/** @typedef {number[]} Complex [re, im] */
/** @typedef {{a: Complex, b: Complex, c: Complex, d: Complex}} Moebius a Möbius map, determinant 1 */

const SCALE_RANGE = [1e-3, 1e3]; // handles.SCALE_RANGE

// --- complex numbers as [re, im] ---------------------------------------------------------
const cmul = (p, q) => [p[0] * q[0] - p[1] * q[1], p[0] * q[1] + p[1] * q[0]];
const csub = (p, q) => [p[0] - q[0], p[1] - q[1]];
const cneg = (p) => [-p[0], -p[1]];
const cdiv = (p, q) => {
  const n = q[0] * q[0] + q[1] * q[1];
  return [(p[0] * q[0] + p[1] * q[1]) / n, (p[1] * q[0] - p[0] * q[1]) / n];
};
function csqrt([re, im]) {
  // the principal square root, as numpy's
  const r = Math.hypot(re, im);
  const x = Math.sqrt((r + re) / 2);
  const y = Math.sqrt(Math.max(0, (r - re) / 2));
  return [x, im < 0 ? -y : y];
}

// --- the sphere ----------------------------------------------------------------------------
const matVec = (m, v) => m.map((row) => dot(row, v));
const transpose = (m) => [0, 1, 2].map((j) => m.map((row) => row[j]));

// [u : v] of a unit vector (coords.xyz_to_homogeneous).
function homogeneous([x, y, z]) {
  return z <= 0 ? [[x, y], [1 - z, 0]] : [[1 + z, 0], [x, -y]];
}

// The unit vector of [u : v] (coords.homogeneous_to_xyz).
function fromHomogeneous(u, v) {
  const s = Math.max(Math.hypot(...u), Math.hypot(...v));
  const [uu, vv] = [u, v].map((w) => [w[0] / s, w[1] / s]);
  const uv = cmul(uu, [vv[0], -vv[1]]);
  const a = uu[0] * uu[0] + uu[1] * uu[1];
  const b = vv[0] * vv[0] + vv[1] * vv[1];
  return [(2 * uv[0]) / (a + b), (2 * uv[1]) / (a + b), (a - b) / (a + b)];
}

// East and north at [lon, lat] (coords.local_frame).
function localFrame([lon, lat]) {
  const [l, p] = [lon * DEG, lat * DEG];
  return [
    [-Math.sin(l), Math.cos(l), 0],
    [-Math.sin(p) * Math.cos(l), -Math.sin(p) * Math.sin(l), Math.cos(p)],
  ];
}

// --- maps ----------------------------------------------------------------------------------
function normalised(m) {
  const r = csqrt(csub(cmul(m.a, m.d), cmul(m.b, m.c)));
  return { a: cdiv(m.a, r), b: cdiv(m.b, r), c: cdiv(m.c, r), d: cdiv(m.d, r) };
}

/** @returns {Moebius} the identity map */
export const identity = () => ({ a: [1, 0], b: [0, 0], c: [0, 0], d: [1, 0] });

/**
 * The composition (p @ q)(x) = p(q(x)), as Moebius.__matmul__.
 * @param {Moebius} p
 * @param {Moebius} q
 * @returns {Moebius}
 */
export function compose(p, q) {
  return normalised({
    a: [cmul(p.a, q.a), cmul(p.b, q.c)].reduce((s, t) => [s[0] + t[0], s[1] + t[1]]),
    b: [cmul(p.a, q.b), cmul(p.b, q.d)].reduce((s, t) => [s[0] + t[0], s[1] + t[1]]),
    c: [cmul(p.c, q.a), cmul(p.d, q.c)].reduce((s, t) => [s[0] + t[0], s[1] + t[1]]),
    d: [cmul(p.c, q.b), cmul(p.d, q.d)].reduce((s, t) => [s[0] + t[0], s[1] + t[1]]),
  });
}

/** @param {Moebius} m @returns {Moebius} the inverse map */
export const inverse = (m) => ({ a: m.d, b: cneg(m.b), c: cneg(m.c), d: m.a });

/**
 * The map applied to a unit vector (Moebius.apply_xyz).
 * @param {Moebius} m
 * @param {Vec3} p unit vector
 * @returns {Vec3} unit vector
 */
export function applyXYZ(m, p) {
  const [u, v] = homogeneous(p);
  const add = (s, t) => [s[0] + t[0], s[1] + t[1]];
  return fromHomogeneous(add(cmul(m.a, u), cmul(m.b, v)), add(cmul(m.c, u), cmul(m.d, v)));
}

// The map sending three homogeneous points to 0, 1, ∞ (moebius._to_zero_one_infinity).
function toZeroOneInfinity(points) {
  const [[u1, v1], [u2, v2], [u3, v3]] = points.map(homogeneous);
  const s1 = csub(cmul(v3, u2), cmul(u3, v2));
  const s3 = csub(cmul(v1, u2), cmul(u1, v2));
  return { a: cmul(s1, v1), b: cneg(cmul(s1, u1)), c: cmul(s3, v3), d: cneg(cmul(s3, u3)) };
}

/**
 * The map sending three unit vectors to three others (Moebius.from_points_xyz).
 * @param {Vec3[]} src three distinct unit vectors
 * @param {Vec3[]} dst three distinct unit vectors
 * @returns {Moebius}
 */
export function fromPointsXYZ(src, dst) {
  const h = toZeroOneInfinity(dst);
  const adjoint = { a: h.d, b: cneg(h.b), c: cneg(h.c), d: h.a };
  return compose(adjoint, normalised(toZeroOneInfinity(src)));
}

/**
 * The map sending three positions to three others (Moebius.from_points).
 * @param {LonLat[]} src three distinct [lon, lat] in degrees
 * @param {LonLat[]} dst three distinct [lon, lat] in degrees
 * @returns {Moebius}
 */
export const fromPoints = (src, dst) => fromPointsXYZ(src.map(lonlatToXYZ), dst.map(lonlatToXYZ));

/**
 * The map of a rotation matrix acting on column vectors (Moebius.from_rotation).
 * @param {number[][]} r 3 x 3 rotation matrix
 * @returns {Moebius}
 */
export const fromRotation = (r) => fromPointsXYZ([[1, 0, 0], [0, 1, 0], [0, 0, 1]], transpose(r));

/**
 * The rotation by `angle` radians about the unit vector `axis` (Moebius.rotation).
 * @param {Vec3} axis unit vector
 * @param {number} angle radians
 * @returns {Moebius}
 */
export function rotationAbout(axis, angle) {
  const [x, y, z] = axis;
  const k = [
    [0, -z, y],
    [z, 0, -x],
    [-y, x, 0],
  ];
  const kk = k.map((row) => [0, 1, 2].map((j) => dot(row, [k[0][j], k[1][j], k[2][j]])));
  const [s, c] = [Math.sin(angle), 1 - Math.cos(angle)];
  return fromRotation([0, 1, 2].map((i) => [0, 1, 2].map((j) => (i === j ? 1 : 0) + s * k[i][j] + c * kk[i][j])));
}

// The rotation taking [lon, lat] to the south pole, east to +x, north to -y (moebius.frame_rotation).
function frameRotation(lonlat) {
  const [east, north] = localFrame(lonlat);
  const p = lonlatToXYZ(lonlat);
  return [east, north.map((x) => -x), p.map((x) => -x)];
}

/**
 * A point handle's map (Moebius.point_map): position to target, magnified by `scale` and
 * turned by `rotation` degrees counter-clockwise at the target.
 * @param {LonLat} position [lon, lat] in degrees
 * @param {LonLat} target [lon, lat] in degrees
 * @param {number} [scale] magnification at the target, > 0
 * @param {number} [rotation] degrees
 * @returns {Moebius}
 */
export function pointMap(position, target, scale = 1, rotation = 0) {
  const root = csqrt([scale * Math.cos(rotation * DEG), -scale * Math.sin(rotation * DEG)]);
  const stretch = { a: root, b: [0, 0], c: [0, 0], d: cdiv([1, 0], root) };
  return compose(compose(fromRotation(transpose(frameRotation(target))), stretch), fromRotation(frameRotation(position)));
}

/**
 * The scale and rotation of a point handle whose output arrow tip is dragged to `tip`
 * (PointHandle.with_arrow_tip).
 * @param {LonLat} final the handle's output centre, [lon, lat] in degrees
 * @param {LonLat} tip where the arrow tip is dragged, [lon, lat] in degrees
 * @param {"east" | "west"} which the arrow dragged
 * @returns {{scale: number, rotation: number} | null} rotation in degrees; null where the tip sits on
 *   the centre's antipode (on the centre: the smallest scale, SCALE_RANGE[0])
 */
export function arrowTip(final, tip, which) {
  const [u, v] = homogeneous(applyXYZ(fromRotation(frameRotation(final)), lonlatToXYZ(tip)));
  if (Math.hypot(...v) < 1e-12 * Math.hypot(...u)) return null;
  const ratio = cdiv(u, v);
  const sign = which === "east" ? 1 : -1;
  const k = [(sign * ratio[0]) / Math.tan(ARROW_LENGTH / 2), (sign * ratio[1]) / Math.tan(ARROW_LENGTH / 2)];
  const scale = Math.min(SCALE_RANGE[1], Math.max(SCALE_RANGE[0], Math.hypot(...k)));
  return { scale, rotation: -Math.atan2(k[1], k[0]) / DEG };
}

// The rotation about a × b taking unit vector a to b (handles._shortest_turn).
function shortestTurn(a, b) {
  const axis = cross(a, b);
  const size = norm(axis);
  if (size < 1e-15) return dot(a, b) > 0 ? identity() : pointMap(xyzToLonLat(a), xyzToLonLat(b));
  return rotationAbout(
    axis.map((x) => x / size),
    Math.atan2(size, dot(a, b)),
  );
}

// The largest eigenvalue's eigenvector of a symmetric 4 x 4 matrix (cyclic Jacobi).
function topEigenvector(n) {
  const a = n.map((row) => [...row]);
  const v = [0, 1, 2, 3].map((i) => [0, 1, 2, 3].map((j) => (i === j ? 1 : 0)));
  for (let sweep = 0; sweep < 50; sweep++) {
    let off = 0;
    for (let p = 0; p < 4; p++) for (let q = p + 1; q < 4; q++) off += a[p][q] * a[p][q];
    if (off < 1e-30) break;
    for (let p = 0; p < 4; p++) {
      for (let q = p + 1; q < 4; q++) {
        if (Math.abs(a[p][q]) < 1e-300) continue;
        const theta = (a[q][q] - a[p][p]) / (2 * a[p][q]);
        const t = Math.sign(theta || 1) / (Math.abs(theta) + Math.sqrt(theta * theta + 1));
        const c = 1 / Math.sqrt(t * t + 1);
        const s = t * c;
        for (let k = 0; k < 4; k++) {
          const [akp, akq] = [a[k][p], a[k][q]];
          a[k][p] = c * akp - s * akq;
          a[k][q] = s * akp + c * akq;
        }
        for (let k = 0; k < 4; k++) {
          const [apk, aqk] = [a[p][k], a[q][k]];
          a[p][k] = c * apk - s * aqk;
          a[q][k] = s * apk + c * aqk;
        }
        for (let k = 0; k < 4; k++) {
          const [vkp, vkq] = [v[k][p], v[k][q]];
          v[k][p] = c * vkp - s * vkq;
          v[k][q] = s * vkp + c * vkq;
        }
      }
    }
  }
  let best = 0;
  for (let i = 1; i < 4; i++) if (a[i][i] > a[best][best]) best = i;
  return v.map((row) => row[best]);
}

/**
 * The rotation best sending points onto others, least squares (coords.best_rotation; Horn's
 * quaternion form of Kabsch's solution).
 * @param {LonLat[]} source [lon, lat] in degrees
 * @param {LonLat[]} target as many, [lon, lat] in degrees
 * @returns {number[][]} 3 x 3 matrix acting on column vectors
 */
export function bestRotation(source, target) {
  const s = [0, 1, 2].map(() => [0, 0, 0]);
  source.forEach((p, i) => {
    const [a, b] = [lonlatToXYZ(p), lonlatToXYZ(target[i])];
    for (let r = 0; r < 3; r++) for (let c = 0; c < 3; c++) s[r][c] += a[r] * b[c];
  });
  const [[xx, xy, xz], [yx, yy, yz], [zx, zy, zz]] = s;
  const [w, x, y, z] = topEigenvector([
    [xx + yy + zz, yz - zy, zx - xz, xy - yx],
    [yz - zy, xx - yy - zz, xy + yx, zx + xz],
    [zx - xz, xy + yx, -xx + yy - zz, yz + zy],
    [xy - yx, zx + xz, yz + zy, -xx - yy + zz],
  ]);
  return [
    [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
    [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
    [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
  ];
}

// --- the handles' maps, as the kernel builds them (omniwidget/document/handles.py) ------------------
// `h` is a handle of the document ({kind: "point" | "line" | "cage", ...}); `points` its output
// control points as a drag on the result leaves them (a point: centre, east tip, west tip; a
// line: start, middle, end; a cage: its vertices); `part` the control point dragged (-1: the
// whole handle). Returns the handle's maps, input to output: one for a point or a line, one
// per vertex for a cage (with the still background, `carry`: the cage's best rotation then
// the shortest turn onto each vertex's target, CageHandle.vertex_maps(carry=True)).
/**
 * @param {Handle} h the handle as in the document
 * @param {LonLat[]} points its output control points, [lon, lat] in degrees
 * @param {number} part the control point dragged, -1 the whole handle
 * @param {boolean} carry the still background (a cage's maps carry its best rotation)
 * @param {Moebius | null} [turn] the document's levelling (options.up): the handle's maps are made for its
 *   input positions turned by it, then start with it (omniwidget/method/deformation.py, levelled_handles and turned)
 * @returns {Moebius[]} input to output
 */
export function dragMaps(h, points, part, carry, turn = null) {
  if (turn) return dragMaps(levelledHandle(h, turn), points, part, carry).map((m) => compose(m, turn));
  if (h.kind === "point") {
    const final = points[0];
    let { scale = 1, rotation = 0 } = h;
    if (part > 0) {
      const turned = arrowTip(final, points[part], part === 1 ? "east" : "west");
      if (turned) ({ scale, rotation } = turned);
    }
    return [pointMap(h.position, final, scale, rotation)];
  }
  if (h.kind === "line") return [fromPoints(controlPoints(h), points)];
  if (!carry) return h.vertices.map((v, i) => pointMap(v, points[i]));
  const r = bestRotation(h.vertices, points);
  const whole = fromRotation(r);
  return h.vertices.map((v, i) => compose(shortestTurn(matVec(r, lonlatToXYZ(v)), lonlatToXYZ(points[i])), whole));
}

/**
 * The handle with its input positions turned by `turn` (deformation.levelled_handles): what the kernel's method sees
 * of it under options.up.
 * @param {Handle} h
 * @param {Moebius} turn
 * @returns {Handle}
 */
export function levelledHandle(h, turn) {
  const at = (p) => xyzToLonLat(applyXYZ(turn, lonlatToXYZ(p)));
  if (h.kind === "point") return { ...h, position: at(h.position) };
  if (h.kind === "line") return { ...h, start: at(h.start), end: at(h.end) };
  return { ...h, vertices: h.vertices.map(at) };
}
