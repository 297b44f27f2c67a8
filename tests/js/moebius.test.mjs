// The live drag's maps (omniwidget/widget/static/moebius.js): known values, and the Python
// they mirror. tests/test_js.py writes Python's own results for random handles to the JSON
// file named by OMNIWIDGET_JS_CASES; without it (`node --test tests/js/` alone) the
// comparisons with Python are skipped. Node's own test runner, no other package.
import { test } from "node:test";
import assert from "node:assert/strict";
import { readFileSync } from "node:fs";
import * as m from "../../omniwidget/widget/static/moebius.js";
import { alongEast, lonlatToXYZ, xyzToLonLat } from "../../omniwidget/widget/static/sphere.js";
import { ARROW_LENGTH, controlPoints } from "../../omniwidget/widget/static/handles.js";

const file = process.env.OMNIWIDGET_JS_CASES;
const skip = file ? false : "OMNIWIDGET_JS_CASES is not set (tests/test_js.py sets it)";
const cases = file ? JSON.parse(readFileSync(file, "utf8")) : null;
const probes = cases ? cases.probes.map(lonlatToXYZ) : [];

function close(actual, expected, tol, what) {
  const worst = Math.max(...actual.flat(2).map((x, i) => Math.abs(x - expected.flat(2)[i])));
  assert.ok(worst <= tol, `${what}: off by ${worst}`);
}

// A map compared by the images of the probe directions (a matrix is defined up to sign).
const images = (map) => probes.map((p) => m.applyXYZ(map, p));
const moved = (map, lonlat) => xyzToLonLat(m.applyXYZ(map, lonlatToXYZ(lonlat)));

// --- known values ----------------------------------------------------------------------------
test("a rotation of 90° about the pole moves the longitudes by 90°", () => {
  const quarter = m.rotationAbout([0, 0, 1], Math.PI / 2);
  close([moved(quarter, [0, 0]), moved(quarter, [-120, 30]), moved(quarter, [150, -45])], [[90, 0], [-30, 30], [-120, -45]], 1e-9, "rotation");
});

test("pointMap sends the position to the target; with scale 1, no turn, from a place to itself it is the identity", () => {
  close([moved(m.pointMap([10, 20], [-50, -5], 2, 30), [10, 20])], [[-50, -5]], 1e-9, "target");
  const still = m.pointMap([10, 20], [10, 20]);
  close([[10, 20], [100, -40], [-170, 80]].map((p) => moved(still, p)), [[10, 20], [100, -40], [-170, 80]], 1e-9, "identity");
});

test("pointMap with scale 2 doubles small distances at the target", () => {
  const map = m.pointMap([0, 0], [0, 0], 2, 0);
  close([moved(map, [0.001, 0]), moved(map, [0, 0.001])], [[0.002, 0], [0, 0.002]], 1e-9, "magnified");
});

test("fromPoints sends three points to three others, and compose with the inverse is the identity", () => {
  const src = [[0, 0], [90, 0], [0, 90]];
  const dst = [[10, 10], [100, -20], [-30, 60]];
  const map = m.fromPoints(src, dst);
  close(src.map((p) => moved(map, p)), dst, 1e-9, "fromPoints");
  const back = m.compose(m.inverse(map), map);
  close([[33, -44], [-150, 5]].map((p) => moved(back, p)), [[33, -44], [-150, 5]], 1e-9, "inverse");
});

test("arrowTip: the tip where it was gives scale 1, no turn; twice as far, scale 2; on the antipode, null", () => {
  const centre = [20, -10];
  const east = alongEast(centre, 1, ARROW_LENGTH);
  const same = m.arrowTip(centre, east, "east");
  close([[same.scale, same.rotation]], [[1, 0]], 1e-9, "unmoved");
  const far = m.arrowTip([0, 0], alongEast([0, 0], 1, 2 * Math.atan(2 * Math.tan(ARROW_LENGTH / 2))), "east");
  close([[far.scale, far.rotation]], [[2, 0]], 1e-9, "scale 2");
  assert.equal(m.arrowTip(centre, [-160, 10], "west"), null);
});

test("dragMaps of a line sends its control points to the dragged ones", () => {
  const line = { kind: "line", start: [-10, 5], end: [30, 15] };
  const targets = [[-12, 7], [11, 14], [31, 10]];
  const [map] = m.dragMaps(line, targets, 2, true);
  close(controlPoints(line).map((p) => moved(map, p)), targets, 1e-9, "line");
});

test("bestRotation recovers a rotation about the pole", () => {
  const source = [[0, 0], [50, 20], [-70, -30], [120, 60]];
  const target = source.map(([lon, lat]) => [lon + 25, lat]);
  const c = Math.cos((25 * Math.PI) / 180);
  const s = Math.sin((25 * Math.PI) / 180);
  close(m.bestRotation(source, target), [[c, -s, 0], [s, c, 0], [0, 0, 1]], 1e-9, "rotation");
});

// --- the Python they mirror ------------------------------------------------------------------
test("pointMap is Moebius.point_map", { skip }, () => {
  for (const c of cases.point_map) close(images(m.pointMap(...c.args)), c.images, 1e-9, JSON.stringify(c.args));
});

test("fromPoints is Moebius.from_points", { skip }, () => {
  for (const c of cases.from_points) close(images(m.fromPoints(c.src, c.dst)), c.images, 1e-9, JSON.stringify(c.src));
});

test("the inverse undoes the map", { skip }, () => {
  for (const c of cases.point_map) {
    const map = m.pointMap(...c.args);
    close(probes.map((p) => m.applyXYZ(m.inverse(map), m.applyXYZ(map, p))), probes, 1e-9, "inverse");
  }
});

test("arrowTip is PointHandle.with_arrow_tip", { skip }, () => {
  for (const c of cases.arrow_tip) {
    const got = m.arrowTip(c.final, c.tip, c.which);
    close([[got.scale, got.rotation]], [[c.scale, c.rotation]], 1e-9, JSON.stringify(c));
  }
});

test("bestRotation is coords.best_rotation", { skip }, () => {
  for (const c of cases.best_rotation) close(m.bestRotation(c.source, c.target), c.rotation, 1e-9, "rotation");
});

test("dragMaps are the handles' maps as the kernel builds them", { skip }, () => {
  for (const c of cases.drag_maps) {
    const maps = m.dragMaps(c.handle, c.points, c.part, c.carry, c.turn || null);
    assert.equal(maps.length, c.images.length, c.what);
    maps.forEach((map, i) => close(images(map), c.images[i], 1e-9, `${c.what}, map ${i}`));
  }
});
