// The sphere (omniwidget/widget/static/sphere.js) against known values of coords.py's conventions.
import { test } from "node:test";
import assert from "node:assert/strict";
import * as s from "../../omniwidget/widget/static/sphere.js";

const TOL = 1e-9;

function near(actual, expected, tol = TOL, what = "") {
  const a = [actual].flat(3);
  const e = [expected].flat(3);
  assert.equal(a.length, e.length, `${what}: ${JSON.stringify(actual)} vs ${JSON.stringify(expected)}`);
  a.forEach((x, i) => assert.ok(Math.abs(x - e[i]) <= tol, `${what}: ${JSON.stringify(actual)} vs ${JSON.stringify(expected)}`));
}

// Deterministic positions all over the sphere (no poles: their longitude is arbitrary).
const SAMPLES = Array.from({ length: 40 }, (_, i) => [((i * 97) % 360) - 180, ((i * 37) % 170) - 85]);

test("lonlatToXYZ: the axes and the conventions of coords.py", () => {
  near(s.lonlatToXYZ([0, 0]), [1, 0, 0], TOL, "lon 0");
  near(s.lonlatToXYZ([90, 0]), [0, 1, 0], TOL, "lon 90 (east)");
  near(s.lonlatToXYZ([-180, 0]), [-1, 0, 0], TOL, "lon -180");
  near(s.lonlatToXYZ([0, 90]), [0, 0, 1], TOL, "north pole");
  near(s.lonlatToXYZ([45, 45]), [0.5, 0.5, Math.SQRT1_2], TOL, "[45, 45]");
});

test("xyzToLonLat inverts lonlatToXYZ, takes any length, and puts the seam at -180", () => {
  for (const p of SAMPLES) near(s.xyzToLonLat(s.lonlatToXYZ(p)), p, TOL, JSON.stringify(p));
  near(s.xyzToLonLat([0, 3, 0]), [90, 0], TOL, "length 3");
  near(s.xyzToLonLat([-2, 0, 2]), [180 - 360, 45], TOL, "lon 180 is -180");
  near(s.xyzToLonLat([0, 0, -5]), [0, -90], TOL, "south pole");
});

test("wrapLon brings longitudes into [-180, 180)", () => {
  const cases = [[0, 0], [179.9, 179.9], [180, -180], [-180, -180], [190, -170], [-190, 170], [540, -180], [-359.5, 0.5], [720.25, 0.25]];
  for (const [lon, wrapped] of cases) near(s.wrapLon(lon), wrapped, TOL, `wrapLon(${lon})`);
});

test("distance: across the seam, along a meridian, pole to pole, and symmetric", () => {
  near(s.distance([179.9, 0], [-179.9, 0]), 0.2, 1e-9, "across the seam");
  near(s.distance([179.9, 10], [-179.9, 10]), (Math.acos(Math.cos(0.2 * s.DEG) * Math.cos(10 * s.DEG) ** 2 + Math.sin(10 * s.DEG) ** 2)) / s.DEG, 1e-9, "at lat 10");
  near(s.distance([30, -20], [30, 40]), 60, TOL, "meridian");
  near(s.distance([0, 90], [0, -90]), 180, TOL, "poles");
  near(s.distance([0, 90], [123, 90]), 0, TOL, "the pole, any lon");
  near(s.distance([10, 0], [100, 0]), 90, TOL, "equator");
  near(s.distance([12, 34], [-56, 7]), s.distance([-56, 7], [12, 34]), TOL, "symmetric");
});

test("midpoint is halfway along the shorter arc, across the seam too", () => {
  near(s.midpoint([0, 0], [90, 0]), [45, 0], TOL, "equator");
  near(s.midpoint([170, 0], [-170, 0]), [-180, 0], TOL, "across the seam");
  near(s.midpoint([0, 0], [0, 90]), [0, 45], TOL, "meridian");
  for (let i = 1; i < SAMPLES.length; i++) {
    const [a, b] = [SAMPLES[i - 1], SAMPLES[i]];
    if (s.distance(a, b) > 179) continue;
    const m = s.midpoint(a, b);
    near(s.distance(a, m), s.distance(a, b) / 2, 1e-9, "half");
    near(s.distance(m, b), s.distance(a, b) / 2, 1e-9, "half");
  }
});

test("alongEast: an arrow tip ARROW_LENGTH radians east or west of its centre", () => {
  near(s.alongEast([0, 0], 1, 0.3), [0.3 / s.DEG, 0], TOL, "east on the equator");
  near(s.alongEast([0, 0], -1, 0.3), [-0.3 / s.DEG, 0], TOL, "west on the equator");
  near(s.alongEast([179, 0], 1, 2 * s.DEG), [-179, 0], TOL, "east across the seam");
  for (const p of SAMPLES) {
    near(s.distance(p, s.alongEast(p, 1, 0.3)), 0.3 / s.DEG, 1e-9, "distance");
    near(s.midpoint(s.alongEast(p, 1, 0.3), s.alongEast(p, -1, 0.3)), p, 1e-9, "centred");
  }
});

test("rotate: a quarter turn about z, and about x", () => {
  near(s.rotate([1, 0, 0], [0, 0, 1], Math.PI / 2), [0, 1, 0], TOL, "about z");
  near(s.rotate([0, 1, 0], [1, 0, 0], Math.PI / 2), [0, 0, 1], TOL, "about x");
  near(s.rotate([0, 0, 1], [0, 0, 1], 1.234), [0, 0, 1], TOL, "the axis stays");
});

test("carry moves points rigidly: `from` onto `to`, distances kept, input untouched", () => {
  const points = [[0, 0], [10, 0], [0, 10]];
  const before = structuredClone(points);
  near(s.carry(points, [0, 0], [20, 0]), [[20, 0], [30, 0], [20, 10]], 1e-9, "along the equator");
  near(s.carry(points, [0, 0], [0, 0]), points, 0, "no move");
  assert.deepEqual(points, before);
  const moved = s.carry(SAMPLES, SAMPLES[0], SAMPLES[7]);
  near(moved[0], SAMPLES[7], 1e-9, "from onto to");
  for (let i = 1; i < SAMPLES.length; i++) near(s.distance(moved[i - 1], moved[i]), s.distance(SAMPLES[i - 1], SAMPLES[i]), 1e-9, "rigid");
});

test("mirror: the half turn about the centre", () => {
  near(s.mirror([0, 0], [10, 0]), [-10, 0], TOL, "on the equator");
  near(s.mirror([0, 0], [0, 10]), [0, -10], TOL, "on the meridian");
  near(s.mirror([179, 0], [-179, 0]), [177, 0], TOL, "across the seam");
  for (const p of SAMPLES) near(s.mirror(p, s.alongEast(p, 1, 0.3)), s.alongEast(p, -1, 0.3), 1e-9, "the opposite arrow");
});

test("geodesic: samples of the great circle from a to b, at most 0.75° apart", () => {
  const arc = s.geodesic([0, 0], [90, 0]);
  near(arc[0], [0, 0], TOL, "start");
  near(arc.at(-1), [90, 0], TOL, "end");
  assert.equal(arc.length, 121); // 90° in steps of 0.75°
  for (const q of arc) near(q[1], 0, 1e-9, "on the equator");
  const seam = s.geodesic([179, 10], [-179, 10]);
  for (let i = 1; i < seam.length; i++) assert.ok(s.distance(seam[i - 1], seam[i]) <= 0.75 + 1e-9);
  near(s.distance(seam[0], seam.at(-1)), s.distance([179, 10], [-179, 10]), 1e-9, "the short way across the seam");
});

test("circleArc: through b, from a to c, on one circle of the sphere", () => {
  const [a, b, c] = [[-20, 0], [0, 10], [20, 0]];
  const arc = s.circleArc(a, b, c);
  near(arc[0], a, 1e-9, "start");
  near(arc.at(-1), c, 1e-9, "end");
  assert.ok(arc.some((q) => s.distance(q, b) < 0.75), "passes b");
  // on one plane: every sample at the same distance from the circle's centre on the sphere
  const centre = s.xyzToLonLat(s.cross(s.sub(s.lonlatToXYZ(b), s.lonlatToXYZ(a)), s.sub(s.lonlatToXYZ(c), s.lonlatToXYZ(a))));
  const radius = s.distance(centre, a);
  for (const q of arc) near(s.distance(centre, q), radius, 1e-9, "one circle");
  assert.deepEqual(s.circleArc([0, 0], [0, 0], [10, 0]), [[0, 0], [0, 0], [10, 0]]); // no circle: the points as they are
});

test("circle: every point the radius from the centre, closed, at the poles and across the seam too", () => {
  for (const [centre, radius] of [[[30, 20], 15], [[0, 90], 10], [[45, -90], 25], [[179.5, -40], 8]]) {
    const ring = s.circle(centre, radius);
    assert.equal(ring.length, 97);
    for (const q of ring) assert.ok(Math.abs(s.distance(q, centre) - radius) < 1e-9, `${q} from ${centre}`);
    assert.ok(s.distance(ring[0], ring.at(-1)) < 1e-9, "closed");
    for (let i = 1; i < ring.length; i++) assert.ok(s.distance(ring[i - 1], ring[i]) < (2 * Math.PI * radius) / 96 + 1e-9);
  }
});
