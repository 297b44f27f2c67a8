// The look-around view's camera (omniwidget/widget/static/look.js): the rays of
// omniwidget/raster/perspective.py's model, where directions appear, a drag and the wheel.
import { test } from "node:test";
import assert from "node:assert/strict";
import * as l from "../../omniwidget/widget/static/look.js";
import { DEG, distance, lonlatToXYZ } from "../../omniwidget/widget/static/sphere.js";

function near(actual, expected, tol, what) {
  const [a, e] = [[actual].flat(2), [expected].flat(2)];
  assert.equal(a.length, e.length, what);
  a.forEach((x, i) => assert.ok(Math.abs(x - e[i]) <= tol, `${what}: ${JSON.stringify(actual)} vs ${JSON.stringify(expected)}`));
}

const LOOKS = [
  { yaw: 0, pitch: 0, fov: 90 },
  { yaw: 30, pitch: 10, fov: 100 },
  { yaw: -179.5, pitch: -20, fov: 70 }, // looking at the seam
  { yaw: 45, pitch: 90, fov: 60 }, // straight up
  { yaw: -60, pitch: -90, fov: 120 }, // straight down
];

test("camera: forward, east and north are orthonormal, east x north = forward", () => {
  for (const look of LOOKS) {
    const { forward, east, north } = l.camera(look);
    const d = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    near([d(forward, forward), d(east, east), d(north, north), d(forward, east), d(forward, north), d(east, north)], [1, 1, 1, 0, 0, 0], 1e-12, "orthonormal");
    const cross = [east[1] * north[2] - east[2] * north[1], east[2] * north[0] - east[0] * north[2], east[0] * north[1] - east[1] * north[0]];
    near(cross, forward, 1e-12, "east x north");
  }
});

test("ray: the middle pixel of an odd view shows [yaw, pitch]; its neighbours are 1 / f radians away", () => {
  for (const look of LOOKS) {
    const [w, h] = [641, 401];
    assert.ok(distance(l.lonlatAt(look, w, h, 320, 200), [look.yaw, look.pitch]) < 1e-9, JSON.stringify(look));
    const f = l.focal(look.fov, w);
    near(distance(l.lonlatAt(look, w, h, 321, 200), l.lonlatAt(look, w, h, 320, 200)), Math.atan(1 / f) / DEG, 1e-9, "one pixel right");
    near(distance(l.lonlatAt(look, w, h, 320, 199), l.lonlatAt(look, w, h, 320, 200)), Math.atan(1 / f) / DEG, 1e-9, "one pixel up");
  }
});

test("focal: the view's edges are fov / 2 from its centre", () => {
  near(l.focal(90, 640), 320, 1e-9, "90 degrees");
  near(l.focal(60, 100), 50 / Math.tan(30 * DEG), 1e-9, "60 degrees");
  const look = { yaw: 10, pitch: 0, fov: 80 };
  const edge = l.ray(look, 400, 300, -0.5, 149.5); // the left edge of the middle row
  near(distance([10, 0], [Math.atan2(edge[1], edge[0]) / DEG, 0]), 40, 1e-9, "half the field of view");
});

test("east is right and north is up: a position 20 degrees east at cx + f tan 20, 15 degrees north at cy - f tan 15", () => {
  const look = { yaw: 0, pitch: 0, fov: 90 };
  const f = l.focal(90, 401);
  near(l.project(look, 401, 301, [20, 0]), [200 + f * Math.tan(20 * DEG), 150], 1e-9, "east");
  near(l.project(look, 401, 301, [0, 15]), [200, 150 - f * Math.tan(15 * DEG)], 1e-9, "north");
  assert.equal(l.project(look, 401, 301, [180, 0]), null); // behind the camera
  assert.equal(l.project(look, 401, 301, [95, 0]), null); // behind its plane
});

test("project and lonlatAt are inverse over the whole view, across the seam and at the poles", () => {
  for (const look of LOOKS) {
    for (let i = 0; i < 40; i++) {
      const [x, y] = [((i * 0.6180339887) % 1) * 500 - 0.5, ((i * 0.4142135623) % 1) * 300 - 0.5];
      near(l.project(look, 500, 300, l.lonlatAt(look, 500, 300, x, y)), [x, y], 1e-7, JSON.stringify(look));
    }
  }
});

test("dragLook: the view turns by dx / f and dy / f radians, against the drag; the pitch stops at the poles; the yaw wraps", () => {
  const start = { yaw: 170, pitch: 10, fov: 90 };
  const f = l.focal(90, 600); // 300 CSS px
  const dragged = l.dragLook(start, 100, -50, 600); // right and up: the camera turns left and down
  near([dragged.yaw, dragged.pitch, dragged.fov], [170 - 100 / f / DEG, 10 - 50 / f / DEG, 90], 1e-9, "turned");
  near(l.dragLook(start, -100, 0, 600).yaw, 170 + 100 / f / DEG - 360, 1e-9, "across the seam");
  assert.equal(l.dragLook(start, 0, 5000, 600).pitch, 90);
  assert.equal(l.dragLook(start, 0, -5000, 600).pitch, -90);
  assert.deepEqual(l.dragLook(start, 0, 0, 600), start);
  // the scene under the pointer follows it: the position at the centre moves to where the pointer went (to first order)
  const small = l.dragLook({ yaw: 0, pitch: 0, fov: 90 }, 2, 0, 600);
  near(l.project(small, 601, 400, [0, 0])[0], 300 + 2, 1e-2, "followed");
});

test("zoomLook: the wheel widens (down) and narrows (up) the field of view within FOV_RANGE", () => {
  const look = { yaw: 5, pitch: 6, fov: 90 };
  assert.ok(l.zoomLook(look, 100).fov > 90 && l.zoomLook(look, -100).fov < 90);
  near(l.zoomLook(l.zoomLook(look, 100), -100).fov, 90, 1e-9, "back");
  assert.equal(l.zoomLook(look, 1e6).fov, l.FOV_RANGE[1]);
  assert.equal(l.zoomLook(look, -1e6).fov, l.FOV_RANGE[0]);
  assert.deepEqual([l.zoomLook(look, 100).yaw, l.zoomLook(look, 100).pitch], [5, 6]);
  assert.deepEqual(l.FOV_RANGE, [20, 120]);
});

test("lookText: degrees with two decimals", () => {
  assert.equal(l.lookText({ yaw: -12.345, pitch: 0, fov: 90 }), "yaw -12.35°, pitch 0.00°, 90.00° across");
});

test("ray: unit directions of positions agree with sphere.js", () => {
  const look = { yaw: -100, pitch: 35, fov: 75 };
  const r = l.ray(look, 300, 200, 17, 150);
  const n = Math.hypot(...r);
  const back = lonlatToXYZ(l.lonlatAt(look, 300, 200, 17, 150));
  near(r.map((v) => v / n), back, 1e-12, "the same direction");
});
