// Hit testing (omniwidget/widget/static/hit.js): the nearest control point within HIT pixels,
// an arc within HIT_EDGE pixels, nothing farther; across the seam too.
import { test } from "node:test";
import assert from "node:assert/strict";
import { HIT, HIT_EDGE, hitTest, onCurve, onRing, pointDistance, segmentDistance } from "../../omniwidget/widget/static/hit.js";
import { controlPoints, curves } from "../../omniwidget/widget/static/handles.js";
import { fitView, toScreen } from "../../omniwidget/widget/static/view.js";

const VIEW = fitView(800, 400); // k = 800: 1° is 20/9 px both ways; [0, 0] is at (400, 200)
const point = (lon, lat) => ({ kind: "point", position: [lon, lat], target: [lon, lat], rotation: 0, scale: 1 });
const HANDLES = [
  point(0, 0), // centre (400, 200), arrow tips 17.19° (38.2 px) east and west
  point(5, 0), // centre (411.1, 200)
  point(179.9, 30), // by the seam: (799.78, 133.3), and (-0.22, 133.3) in the copy to the left
  { kind: "cage", vertices: [[-90, -20], [-60, -20], [-60, -40], [-90, -40]] },
  { kind: "line", start: [60, 50], end: [120, 50], rectify: false },
];
const POSITIONS = HANDLES.map(controlPoints);
const at = (x, y, selected = -1) => hitTest(VIEW, HANDLES, POSITIONS, x, y, selected);
const strip = (hit) => hit && { index: hit.index, part: hit.part };

test("segmentDistance: to the inside, to the ends, to a segment of no length", () => {
  assert.equal(segmentDistance(5, 3, 0, 0, 10, 0), 3);
  assert.equal(segmentDistance(-3, 4, 0, 0, 10, 0), 5);
  assert.equal(segmentDistance(13, -4, 0, 0, 10, 0), 5);
  assert.equal(segmentDistance(3, 4, 0, 0, 0, 0), 5);
});

test("pointDistance measures to the nearest copy of the point", () => {
  const [x, y] = toScreen(VIEW, [179.9, 30]);
  assert.ok(Math.abs(pointDistance(VIEW, [179.9, 30], 1, y) - (1 - (x - 800))) < 1e-9);
  assert.ok(Math.abs(pointDistance(VIEW, [179.9, 30], x + 3, y + 4) - 5) < 1e-9);
});

test("the nearest control point within HIT pixels", () => {
  assert.deepEqual(at(404, 200), { index: 0, part: 0, d: 4 });
  assert.deepEqual(strip(at(407, 200)), { index: 1, part: 0 }); // 7 px from the first, 4.1 from the second
  assert.deepEqual(strip(at(400 + 38.2, 203)), { index: 0, part: 1 }); // the east arrow tip
  assert.deepEqual(strip(at(400 - 38.2, 197)), { index: 0, part: 2 }); // the west arrow tip
  assert.deepEqual(strip(at(400, 200 + HIT)), { index: 0, part: 0 }); // at the tolerance
});

test("another handle's point wins only when more than half a pixel nearer", () => {
  assert.deepEqual(strip(at(405.6, 200)), { index: 0, part: 0 }); // 5.6 px vs 5.5 px
  assert.deepEqual(strip(at(406, 200)), { index: 1, part: 0 }); // 6 px vs 5.1 px
});

test("the selected handle's points come first", () => {
  assert.deepEqual(strip(at(404, 200, 1)), { index: 1, part: 0 }); // 7.1 px, within HIT
  assert.deepEqual(strip(at(396, 200, 1)), { index: 0, part: 0 }); // 15.1 px from the selected one: the nearest
});

test("on an arc, away from the control points: the handle itself (part -1)", () => {
  assert.deepEqual(at(425, 200 + HIT_EDGE), { index: 0, part: -1 }); // on the east arrow
  assert.deepEqual(at(-75 * (20 / 9) + 400, (90 + 20) * (20 / 9) + 4), { index: 3, part: -1 }); // the cage's top edge bulges up: 4 px inside
  const [qx, qy] = toScreen(VIEW, curves(HANDLES[4], POSITIONS[4])[0][15]); // on the line, 11° from its start
  assert.deepEqual(at(qx, qy + 4), { index: 4, part: -1 });
  const [cx, cy] = toScreen(VIEW, [90, 50]); // the chord between its ends on screen, 8.9 px below the arc
  assert.equal(at(cx + 10, cy), null);
});

test("nothing beyond the tolerances", () => {
  assert.equal(at(400, 200 + HIT + 0.5), null); // 9.5 px below the centre, 9.5 below the arrows
  assert.equal(at(425, 200 + HIT_EDGE + 1), null); // 7 px below the arrow
  assert.equal(at(600, 50), null);
  assert.equal(hitTest(VIEW, [], [], 400, 200, -1), null);
});

test("across the seam: the point at lon 179.9 is hit from the left edge of the canvas", () => {
  const [, y] = toScreen(VIEW, [179.9, 30]);
  assert.deepEqual(strip(at(1, y)), { index: 2, part: 0 });
  assert.deepEqual(strip(at(799, y)), { index: 2, part: 0 });
  assert.deepEqual(strip(at(1 + 800, y)), { index: 2, part: 0 }); // in the copy to the right
  assert.equal(at(12, y + 10), null); // 12.2 px right of it, 10 px below its east arrow
});

test("onCurve: a line's arc within HIT_EDGE pixels", () => {
  const line = HANDLES[4];
  const pts = POSITIONS[4];
  const [mx, my] = toScreen(VIEW, pts[1]);
  assert.ok(onCurve(VIEW, line, pts, mx, my + HIT_EDGE - 0.1));
  assert.ok(!onCurve(VIEW, line, pts, mx, my + HIT_EDGE + 0.5));
  assert.ok(onCurve(VIEW, line, pts, mx, my + 10, 12)); // a tolerance of its own
});

test("onRing: on the reach's ring within HIT_EDGE pixels, not inside it nor at its centre, across the seam too", () => {
  const view = fitView(720, 360); // 2 px a degree
  const [x, y] = toScreen(view, [30, 35]); // 15° north of (30, 20)
  assert.ok(onRing(view, [30, 20], 15, x, y));
  assert.ok(onRing(view, [30, 20], 15, x, y - HIT_EDGE + 1));
  assert.ok(!onRing(view, [30, 20], 15, x, y + 3 * HIT_EDGE));
  assert.ok(!onRing(view, [30, 20], 15, ...toScreen(view, [30, 20])));
  const [sx, sy] = toScreen(view, [-172, 0]); // 8° east of 180, seen across the seam
  assert.ok(onRing(view, [180, 0], 8, sx, sy));
});
