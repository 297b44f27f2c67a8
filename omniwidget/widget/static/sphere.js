// The unit sphere for the editor: the JavaScript twin of omniwidget/sphere/coords.py (and of
// the arcs the editor draws). Pure functions, no DOM; tests/js/sphere.test.mjs checks them.
//
// Conventions of coords.py: [lon, lat] in degrees, longitude in [-180, 180) growing to the
// right (east), latitude in [-90, 90] growing upwards; unit vector
// (cos lat cos lon, cos lat sin lon, sin lat); east at [lon, lat] is (-sin lon, cos lon, 0).

/** @typedef {number[]} LonLat [lon, lat] in degrees */
/** @typedef {number[]} Vec3 [x, y, z] */

/** Radians per degree. */
export const DEG = Math.PI / 180;

/** @param {Vec3} a @param {Vec3} b @returns {number} a · b */
export const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
/** @param {Vec3} a @param {Vec3} b @returns {Vec3} a × b */
export const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
/** @param {Vec3} a @param {number} s @returns {Vec3} s a */
export const scaled = (a, s) => [a[0] * s, a[1] * s, a[2] * s];
/** @param {Vec3} a @param {Vec3} b @returns {Vec3} a + b */
export const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
/** @param {Vec3} a @param {Vec3} b @returns {Vec3} a - b */
export const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
/** @param {Vec3} a @returns {number} |a| */
export const norm = (a) => Math.hypot(a[0], a[1], a[2]);
/** @param {Vec3} a @returns {Vec3} a / |a| (the zero vector stays zero) */
export const unit = (a) => scaled(a, 1 / (norm(a) || 1));

/**
 * The unit vector of a position (coords.lonlat_to_xyz).
 * @param {LonLat} lonlat [lon, lat] in degrees
 * @returns {Vec3}
 */
export function lonlatToXYZ([lon, lat]) {
  const c = Math.cos(lat * DEG);
  return [c * Math.cos(lon * DEG), c * Math.sin(lon * DEG), Math.sin(lat * DEG)];
}

/**
 * The position of a direction (coords.xyz_to_lonlat); the vector need not be unit.
 * @param {Vec3} p any non-zero vector ([0, 0, 0] gives [0, 0])
 * @returns {LonLat} [lon, lat] in degrees, lon in [-180, 180)
 */
export function xyzToLonLat([x, y, z]) {
  const lon = Math.atan2(y, x) / DEG;
  return [lon >= 180 ? lon - 360 : lon, Math.atan2(z, Math.hypot(x, y)) / DEG];
}

/**
 * A longitude brought into [-180, 180) (the ±180° seam).
 * @param {number} lon degrees, any
 * @returns {number} degrees in [-180, 180)
 */
export function wrapLon(lon) {
  return ((((lon + 180) % 360) + 360) % 360) - 180;
}

/**
 * The great-circle distance between two positions.
 * @param {LonLat} a [lon, lat] in degrees
 * @param {LonLat} b [lon, lat] in degrees
 * @returns {number} degrees in [0, 180]
 */
export function distance(a, b) {
  const [p, q] = [lonlatToXYZ(a), lonlatToXYZ(b)];
  return Math.atan2(norm(cross(p, q)), dot(p, q)) / DEG;
}

/**
 * The midpoint of the shorter great-circle arc from a to b (a line's middle control point).
 * @param {LonLat} a [lon, lat] in degrees
 * @param {LonLat} b [lon, lat] in degrees
 * @returns {LonLat}
 */
export function midpoint(a, b) {
  return xyzToLonLat(add(lonlatToXYZ(a), lonlatToXYZ(b)));
}

/**
 * The point `angle` radians from `lonlat` along the great circle heading east (sign +1) or
 * west (sign -1): a point handle's arrow tip (handles._exp).
 * @param {LonLat} lonlat [lon, lat] in degrees
 * @param {number} sign +1 east, -1 west
 * @param {number} angle radians
 * @returns {LonLat}
 */
export function alongEast(lonlat, sign, angle) {
  const p = lonlatToXYZ(lonlat);
  const east = [-Math.sin(lonlat[0] * DEG), Math.cos(lonlat[0] * DEG), 0];
  return xyzToLonLat(add(scaled(p, Math.cos(angle)), scaled(east, sign * Math.sin(angle))));
}

/**
 * A vector turned about a unit axis, counter-clockwise seen from the axis's tip (Rodrigues).
 * @param {Vec3} v
 * @param {Vec3} axis unit vector
 * @param {number} angle radians
 * @returns {Vec3}
 */
export function rotate(v, axis, angle) {
  const c = Math.cos(angle);
  const s = Math.sin(angle);
  return add(add(scaled(v, c), scaled(cross(axis, v), s)), scaled(axis, dot(axis, v) * (1 - c)));
}

/**
 * Positions moved by the rotation that carries `from` to `to` along their great circle (a
 * whole handle dragged by one of its points); fresh arrays, the input is left as it is.
 * @param {LonLat[]} points [lon, lat] in degrees
 * @param {LonLat} from [lon, lat] in degrees
 * @param {LonLat} to [lon, lat] in degrees
 * @returns {LonLat[]}
 */
export function carry(points, from, to) {
  const a = lonlatToXYZ(from);
  const b = lonlatToXYZ(to);
  const axis = cross(a, b);
  const n = norm(axis);
  if (n < 1e-12) return points.map((p) => [...p]);
  const angle = Math.atan2(n, dot(a, b));
  return points.map((p) => xyzToLonLat(rotate(lonlatToXYZ(p), scaled(axis, 1 / n), angle)));
}

/**
 * The mirror image of `p` through the axis of `centre` (the half turn about it): a point
 * handle's opposite arrow tip when one is dragged.
 * @param {LonLat} centre [lon, lat] in degrees
 * @param {LonLat} p [lon, lat] in degrees
 * @returns {LonLat}
 */
export function mirror(centre, p) {
  const c = lonlatToXYZ(centre);
  const t = lonlatToXYZ(p);
  return xyzToLonLat(sub(scaled(c, 2 * dot(c, t)), t));
}

/**
 * Samples, at most 0.75° apart, of the circle of the sphere through three points, from a
 * through b to c: a geodesic when b is its midpoint, and a line's output (a Möbius image of
 * a great circle). Three points on one straight line of space give [a, b, c].
 * @param {LonLat} a [lon, lat] in degrees
 * @param {LonLat} b [lon, lat] in degrees
 * @param {LonLat} c [lon, lat] in degrees
 * @returns {LonLat[]} from a to c
 */
export function circleArc(a, b, c) {
  const [pa, pb, pc] = [lonlatToXYZ(a), lonlatToXYZ(b), lonlatToXYZ(c)];
  const n = cross(sub(pb, pa), sub(pc, pa));
  if (norm(n) < 1e-12) return [a, b, c];
  const nu = unit(n);
  const o = scaled(nu, dot(pa, nu));
  const ra = sub(pa, o);
  const r = norm(ra);
  const e1 = scaled(ra, 1 / r);
  const e2 = cross(nu, e1);
  const at = (p) => {
    const t = Math.atan2(dot(sub(p, o), e2), dot(sub(p, o), e1));
    return t < 0 ? t + 2 * Math.PI : t;
  };
  const tb = at(pb);
  let tc = at(pc);
  if (tb > tc) tc -= 2 * Math.PI; // go the other way round, still through b
  const steps = Math.max(2, Math.ceil((Math.abs(tc) * r) / (0.75 * DEG)));
  const out = [];
  for (let i = 0; i <= steps; i++) {
    const t = (tc * i) / steps;
    out.push(xyzToLonLat(add(o, add(scaled(e1, r * Math.cos(t)), scaled(e2, r * Math.sin(t))))));
  }
  return out;
}

/**
 * Samples of the shorter great-circle arc from a to b.
 * @param {LonLat} a [lon, lat] in degrees
 * @param {LonLat} b [lon, lat] in degrees
 * @returns {LonLat[]} from a to b
 */
export function geodesic(a, b) {
  return circleArc(a, midpoint(a, b), b);
}

/**
 * The circle of points `radius` degrees from `centre`, closed (the first point again at the
 * end): a point handle's reach, drawn as a ring. Well defined at the poles.
 * @param {LonLat} centre [lon, lat] in degrees
 * @param {number} radius degrees
 * @param {number} [count] points on the circle
 * @returns {LonLat[]}
 */
export function circle(centre, radius, count = 96) {
  const c = lonlatToXYZ(centre);
  const a = Math.abs(c[2]) < 0.9 ? [0, 0, 1] : [1, 0, 0];
  const across = cross(a, c);
  const e1 = scaled(across, 1 / norm(across));
  const e2 = cross(c, e1);
  const r = radius * DEG;
  return Array.from({ length: count + 1 }, (_, k) => {
    const t = (2 * Math.PI * k) / count;
    return xyzToLonLat(add(scaled(c, Math.cos(r)), add(scaled(e1, Math.sin(r) * Math.cos(t)), scaled(e2, Math.sin(r) * Math.sin(t)))));
  });
}
