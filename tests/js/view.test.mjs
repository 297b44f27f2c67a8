// The view of the panorama on a canvas (omniwidget/widget/static/view.js): round trips, the
// seam, zoom and pan.
import { test } from "node:test";
import assert from "node:assert/strict";
import * as v from "../../omniwidget/widget/static/view.js";

const VIEW = { k: 1000, tx: 37.25, ty: -12.5 }; // a canvas showing part of three copies
const WIDE = { k: 123456.789, tx: -98765.4321, ty: -4000.5 }; // zoomed in far

function near(actual, expected, tol, what) {
  const [a, e] = [[actual].flat(2), [expected].flat(2)];
  assert.equal(a.length, e.length, what);
  a.forEach((x, i) => assert.ok(Math.abs(x - e[i]) <= tol, `${what}: ${JSON.stringify(actual)} vs ${JSON.stringify(expected)}`));
}

// Deterministic screen points inside the copy whose left edge is at tx.
const inside = (view) =>
  Array.from({ length: 50 }, (_, i) => [view.tx + ((i * 0.6180339887) % 1) * view.k, view.ty + ((i * 0.4142135623) % 1) * (view.k / 2)]);

test("fitView: the whole panorama, centred, as wide as the canvas allows", () => {
  assert.deepEqual(v.fitView(800, 400), { k: 800, tx: 0, ty: 0 });
  assert.deepEqual(v.fitView(1000, 300), { k: 600, tx: 200, ty: 0 }); // height-bound
  assert.deepEqual(v.fitView(600, 440), { k: 600, tx: 0, ty: 70 }); // width-bound
});

test("toScreen: the corners and the centre of the panorama", () => {
  near(v.toScreen(VIEW, [-180, 90]), [37.25, -12.5], 1e-9, "top left");
  near(v.toScreen(VIEW, [0, 0]), [537.25, 237.5], 1e-9, "centre");
  near(v.toScreen(VIEW, [180, -90]), [1037.25, 487.5], 1e-9, "bottom right");
});

test("screen -> [lon, lat] -> screen within 1e-9 px, at any zoom", () => {
  for (const view of [VIEW, WIDE, v.fitView(917, 440)]) {
    for (const [x, y] of inside(view)) near(v.toScreen(view, v.screenToLonLat(view, x, y)), [x, y], 1e-9, JSON.stringify(view));
  }
});

test("[lon, lat] -> screen -> [lon, lat] within 1e-9 degrees", () => {
  for (let i = 0; i < 60; i++) {
    const lonlat = [((i * 71.3) % 360) - 180, ((i * 23.9) % 180) - 90];
    near(v.screenToLonLat(VIEW, ...v.toScreen(VIEW, lonlat)), lonlat, 1e-9, JSON.stringify(lonlat));
  }
});

test("the seam: every copy of the panorama gives the same [lon, lat]; 179.9 and -179.9 are 0.2° apart on screen", () => {
  const [x, y] = v.toScreen(VIEW, [30, 20]);
  for (const j of [-2, -1, 1, 3]) near(v.screenToLonLat(VIEW, x + j * VIEW.k, y), [30, 20], 1e-9, `copy ${j}`);
  near(v.screenToLonLat(VIEW, VIEW.tx + VIEW.k + 1e-6, 0)[0], -180 + 360e-9, 1e-9, "just right of the right edge");
  near(v.screenToLonLat(VIEW, VIEW.tx - 1e-6, 0)[0], 180 - 360e-9, 1e-9, "just left of the left edge");
  const [east] = v.toScreen(VIEW, [179.9, 0]);
  const [west] = v.toScreen(VIEW, [-179.9, 0]);
  near(Math.abs(east - west), (359.8 / 360) * VIEW.k, 1e-9, "in one copy: almost a panorama apart");
  near(v.nearestX(VIEW, west, east) - east, (0.2 / 360) * VIEW.k, 1e-9, "the nearest copies: 0.2° apart");
});

test("nearestX: the copy of x nearest to another x", () => {
  assert.equal(v.nearestX(VIEW, 100, 2100), 2100);
  assert.equal(v.nearestX(VIEW, 100, 2499), 2100);
  assert.equal(v.nearestX(VIEW, 100, 2601), 3100);
  assert.equal(v.nearestX(VIEW, 100, -700), -900);
});

test("latitude stops at the poles above and below the panorama", () => {
  assert.equal(v.screenToLonLat(VIEW, 300, VIEW.ty - 50)[1], 90);
  assert.equal(v.screenToLonLat(VIEW, 300, VIEW.ty + VIEW.k)[1], -90);
});

test("copies: the offsets of every copy the canvas shows", () => {
  assert.deepEqual(v.copies(VIEW, 800), [-1000, 0]); // the copy left of tx shows in the first 37 px
  assert.deepEqual(v.copies({ k: 300, tx: 100, ty: 0 }, 800), [-300, 0, 300, 600]);
  assert.deepEqual(v.copies({ k: 1000, tx: -1500, ty: 0 }, 800), [1000, 2000]);
});

test("screenPath runs on across the seam instead of jumping back", () => {
  const path = v.screenPath(VIEW, [[179, 0], [179.9, 0], [-179.9, 0], [-179, 0]]);
  const step = VIEW.k / 360;
  near(path.map((p) => p[0] - path[0][0]), [0, 0.9 * step, 1.1 * step, 2 * step], 1e-9, "x");
  near(path.map((p) => p[1]), [237.5, 237.5, 237.5, 237.5], 1e-9, "y");
});

test("zoomAt keeps what is under the cursor there, within 0.5x to 64x the fitted width", () => {
  const view = v.fitView(800, 400);
  const under = v.screenToLonLat(view, 250, 120);
  const zoomed = v.zoomAt(view, 250, 120, -300, 800, 400);
  near(zoomed.k, 800 * Math.exp(0.45), 1e-9, "k");
  near(v.screenToLonLat(zoomed, 250, 120), under, 1e-9, "the cursor's place");
  assert.equal(v.zoomAt(view, 250, 120, -1e6, 800, 400).k, 800 * 64);
  assert.equal(v.zoomAt(view, 250, 120, 1e6, 800, 400).k, 400);
  assert.deepEqual(view, v.fitView(800, 400)); // a new view
});

test("panBy moves the panorama with the drag", () => {
  const view = { k: 800, tx: 10, ty: 20 };
  assert.deepEqual(v.panBy(view, 5, -7), { k: 800, tx: 15, ty: 13 });
  assert.deepEqual(view, { k: 800, tx: 10, ty: 20 });
  const under = v.screenToLonLat(view, 100, 100);
  near(v.screenToLonLat(v.panBy(view, 30, 40), 130, 140), under, 1e-9, "the place under the pointer follows it");
});
