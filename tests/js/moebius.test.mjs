// The live drag's maps (omniwidget/widget/static/moebius.js) against the Python they mirror.
// Run by tests/test_moebius_js.py, which writes the cases (Python's own results) to the JSON
// file named by OMNIWIDGET_JS_CASES; `node --test` alone needs no other package.
import { test } from "node:test";
import assert from "node:assert/strict";
import { readFileSync } from "node:fs";
import * as m from "../../omniwidget/widget/static/moebius.js";

const cases = JSON.parse(readFileSync(process.env.OMNIWIDGET_JS_CASES, "utf8"));
const probes = cases.probes.map(m.lonlatToXYZ);

function close(actual, expected, tol, what) {
  const worst = Math.max(...actual.flat(2).map((x, i) => Math.abs(x - expected.flat(2)[i])));
  assert.ok(worst <= tol, `${what}: off by ${worst}`);
}

// A map compared by the images of the probe directions (a matrix is defined up to sign).
const images = (map) => probes.map((p) => m.applyXYZ(map, p));

test("pointMap is Moebius.point_map", () => {
  for (const c of cases.point_map) close(images(m.pointMap(...c.args)), c.images, 1e-9, JSON.stringify(c.args));
});

test("fromPoints is Moebius.from_points", () => {
  for (const c of cases.from_points) close(images(m.fromPoints(c.src, c.dst)), c.images, 1e-9, JSON.stringify(c.src));
});

test("the inverse undoes the map", () => {
  for (const c of cases.point_map) {
    const map = m.pointMap(...c.args);
    close(probes.map((p) => m.applyXYZ(m.inverse(map), m.applyXYZ(map, p))), probes, 1e-9, "inverse");
  }
});

test("arrowTip is PointHandle.with_arrow_tip", () => {
  for (const c of cases.arrow_tip) {
    const got = m.arrowTip(c.final, c.tip, c.which);
    close([[got.scale, got.rotation]], [[c.scale, c.rotation]], 1e-9, JSON.stringify(c));
  }
});

test("bestRotation is coords.best_rotation", () => {
  for (const c of cases.best_rotation) close(m.bestRotation(c.source, c.target), c.rotation, 1e-9, "rotation");
});

test("dragMaps are the handles' maps as the kernel builds them", () => {
  for (const c of cases.drag_maps) {
    const maps = m.dragMaps(c.handle, c.points, c.part, c.carry);
    assert.equal(maps.length, c.images.length, c.what);
    maps.forEach((map, i) => close(images(map), c.images[i], 1e-9, `${c.what}, map ${i}`));
  }
});
