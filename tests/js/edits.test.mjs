// The edits of the handles document (omniwidget/widget/static/edits.js): each gives the
// document (or the control points) expected and leaves its arguments as they were.
import { test } from "node:test";
import assert from "node:assert/strict";
import * as e from "../../omniwidget/widget/static/edits.js";
import { ARROW_LENGTH } from "../../omniwidget/widget/static/handles.js";
import { arrowTip } from "../../omniwidget/widget/static/moebius.js";
import { DEG, distance, midpoint } from "../../omniwidget/widget/static/sphere.js";

const A = ARROW_LENGTH / DEG; // 17.19°: a point's arrows on the input

const DOC = {
  format: "omniwidget-handles",
  version: 1,
  handles: [
    { kind: "point", position: [0, 0], target: [0, 0], rotation: 0, scale: 1 },
    { kind: "point", position: [40, 10], target: [50, 12], rotation: 15, scale: 1.5 },
    { kind: "line", start: [-30, 20], end: [30, 20], rectify: true },
    { kind: "cage", vertices: [[100, 0], [110, 0], [110, 10], [100, 10]] },
    { kind: "cage", vertices: [[-100, 0], [-90, 0], [-95, 8]], targets: [[-100, 1], [-90, 1], [-95, 9]] },
  ],
  options: { rectify: "all", anchor: null },
};

function near(actual, expected, tol, what) {
  const [a, b] = [[actual].flat(3), [expected].flat(3)];
  assert.equal(a.length, b.length, what);
  a.forEach((x, i) => assert.ok(Math.abs(x - b[i]) <= tol, `${what}: ${JSON.stringify(actual)} vs ${JSON.stringify(expected)}`));
}

// An edit applied to copies of its arguments, checked to leave them as they were.
function pure(edit, ...args) {
  const before = structuredClone(args);
  const out = edit(...args);
  assert.deepEqual(args, before, `${edit.name} changed its arguments`);
  return out;
}

const drag = (pane, index, part, original, grab) => ({
  type: "move", pane, index, part, grab, original, points: structuredClone(original), kind: DOC.handles[index].kind, moved: false, solved: false,
});

test("newPoint: a point handle not yet moved", () => {
  assert.deepEqual(pure(e.newPoint, [12.5, -3]), { kind: "point", position: [12.5, -3], target: [12.5, -3], rotation: 0, scale: 1 });
});

test("newLine: a line from start to end, none under MIN_LINE", () => {
  assert.deepEqual(pure(e.newLine, [-4, 37.5], [68, 36.5]), { kind: "line", start: [-4, 37.5], end: [68, 36.5], rectify: false });
  assert.deepEqual(pure(e.newLine, [179.9, 0], [-179.9, 0]), { kind: "line", start: [179.9, 0], end: [-179.9, 0], rectify: false }); // 0.2° across the seam
  assert.equal(pure(e.newLine, [10, 10], [10.04, 10]), null);
});

test("newCage: the vertices clicked, a double-click's repeat dropped, none under three", () => {
  const cage = pure(e.newCage, [[0, 0], [10, 0], [10, 10], [10, 10.01]]);
  assert.deepEqual(cage, { kind: "cage", vertices: [[0, 0], [10, 0], [10, 10]] });
  assert.equal(pure(e.newCage, [[0, 0], [10, 0], [10, 0.001]]), null);
  assert.equal(pure(e.newCage, [[0, 0], [10, 0]]), null);
  assert.equal(pure(e.newCage, [[0, 0], [10, 0], [10, 0.1]]).vertices.length, 3); // 0.1° apart: two vertices
});

test("addHandle puts the handle last and keeps the other fields", () => {
  const line = { kind: "line", start: [1, 2], end: [3, 4], rectify: false };
  const out = pure(e.addHandle, DOC, line);
  assert.deepEqual(out, { ...DOC, handles: [...DOC.handles, line] });
  assert.deepEqual(pure(e.addHandle, { handles: [] }, line), { handles: [line] });
});

test("removeHandle drops one handle", () => {
  assert.deepEqual(pure(e.removeHandle, DOC, 2), { ...DOC, handles: [DOC.handles[0], DOC.handles[1], DOC.handles[3], DOC.handles[4]] });
  assert.deepEqual(pure(e.removeHandle, DOC, 9), DOC);
});

test("dragPoints, a point on the input: its centre or an arrow moves it whole", () => {
  const original = [[0, 0], [A, 0], [-A, 0]];
  near(pure(e.dragPoints, drag("input", 0, 0, original, [0.5, 0.5]), [10, 0]), [[10, 0], [10 + A, 0], [10 - A, 0]], 1e-9, "centre");
  near(pure(e.dragPoints, drag("input", 0, 1, original, [A, 0]), [A + 10, 0]), [[10, 0], [10 + A, 0], [10 - A, 0]], 1e-9, "by its east tip");
});

test("dragPoints, a point on the result: the centre carries the arrows; an arrow tip mirrors the other", () => {
  const original = [[0, 0], [A, 0], [-A, 0]];
  const [centre, east, west] = pure(e.dragPoints, drag("result", 0, 0, original, [0.3, 0.2]), [0, 30]);
  near(centre, [0, 30], 1e-9, "the centre where the pointer is");
  near([distance(centre, east), distance(centre, west), midpoint(east, west)], [A, A, [0, 30]], 1e-9, "the arrows carried along");
  near(pure(e.dragPoints, drag("result", 0, 1, original, [A, 0]), [0, 20]), [[0, 0], [0, 20], [0, -20]], 1e-9, "east tip up: west tip down");
  near(pure(e.dragPoints, drag("result", 0, 2, original, [-A, 0]), [-30, 0]), [[0, 0], [30, 0], [-30, 0]], 1e-9, "west tip out: east tip out");
  near(pure(e.dragPoints, drag("result", 0, -1, original, [8, 0]), [18, 0]), [[10, 0], [10 + A, 0], [10 - A, 0]], 1e-9, "by an arrow's arc: whole");
});

test("dragPoints, a line on the input: an end moves alone (the middle follows), the middle moves it whole", () => {
  const original = [[-30, 20], midpoint([-30, 20], [30, 20]), [30, 20]];
  const end = pure(e.dragPoints, drag("input", 2, 2, original, [30, 20]), [40, 0]);
  near(end, [[-30, 20], midpoint([-30, 20], [40, 0]), [40, 0]], 1e-9, "end");
  const equator = [[-30, 0], [0, 0], [30, 0]];
  near(pure(e.dragPoints, drag("input", 2, 1, equator, [0, 0]), [50, 0]), [[20, 0], [50, 0], [80, 0]], 1e-9, "whole, by its middle");
});

test("dragPoints, a line on the result: each point moves alone", () => {
  const original = [[-30, 20], [0, 25], [30, 20]];
  near(pure(e.dragPoints, drag("result", 2, 1, original, [0, 25]), [0, 21]), [[-30, 20], [0, 21], [30, 20]], 0, "the middle");
  near(pure(e.dragPoints, drag("result", 2, 0, original, [-30, 20]), [-170, 20]), [[-170, 20], [0, 25], [30, 20]], 0, "an end");
});

test("dragPoints, a cage: a vertex alone, or the whole cage by an edge, across the seam too", () => {
  const original = DOC.handles[3].vertices;
  near(pure(e.dragPoints, drag("input", 3, 2, original, [110, 10]), [115, 12]), [[100, 0], [110, 0], [115, 12], [100, 10]], 0, "a vertex");
  near(pure(e.dragPoints, drag("result", 3, -1, original, [105, 0]), [175, 0]), original.map(([lon, lat]) => [lon + 70 >= 180 ? lon + 70 - 360 : lon + 70, lat]), 1e-9, "whole, 70° east, over the seam");
});

test("moveOnInput: a point not yet moved takes its target along", () => {
  const out = pure(e.moveOnInput, DOC, 0, [[5, 5], [5 + A, 5], [5 - A, 5]]);
  assert.deepEqual(out, { ...DOC, handles: [{ ...DOC.handles[0], position: [5, 5], target: [5, 5] }, ...DOC.handles.slice(1)] });
});

test("moveOnInput: a point moved on the result keeps its target", () => {
  const out = pure(e.moveOnInput, DOC, 1, [[41, 11], [0, 0], [0, 0]]);
  assert.deepEqual(out.handles[1], { kind: "point", position: [41, 11], target: [50, 12], rotation: 15, scale: 1.5 });
  assert.deepEqual(out.handles.filter((_, i) => i !== 1), DOC.handles.filter((_, i) => i !== 1));
});

test("moveOnInput: a line's ends, a cage's vertices", () => {
  const line = pure(e.moveOnInput, DOC, 2, [[-31, 21], [0, 25], [29, 19]]);
  assert.deepEqual(line.handles[2], { kind: "line", start: [-31, 21], end: [29, 19], rectify: true });
  const cage = pure(e.moveOnInput, DOC, 3, [[101, 0], [111, 0], [111, 10], [101, 10]]);
  assert.deepEqual(cage.handles[3], { kind: "cage", vertices: [[101, 0], [111, 0], [111, 10], [101, 10]] });
  assert.deepEqual({ ...cage, handles: null }, { ...DOC, handles: null });
});

test("moveOnResult: a point's centre sets its target, its arrow tip its scale and turn", () => {
  const centre = pure(e.moveOnResult, DOC, 1, 0, [[52, 13], [60, 13], [44, 13]]);
  assert.deepEqual(centre.handles[1], { kind: "point", position: [40, 10], target: [52, 13], rotation: 15, scale: 1.5 });
  const tip = [20, 5];
  const arrow = pure(e.moveOnResult, DOC, 0, 1, [[0, 0], tip, [-20, -5]]);
  const turned = arrowTip([0, 0], tip, "east");
  assert.deepEqual(arrow.handles[0], { kind: "point", position: [0, 0], target: [0, 0], rotation: turned.rotation, scale: turned.scale });
  const bearing = Math.atan(Math.tan(5 * DEG) / Math.sin(20 * DEG)) / DEG; // the tip's direction from the centre, north of east
  const scale = Math.tan((distance([0, 0], tip) * DEG) / 2) / Math.tan(ARROW_LENGTH / 2);
  near([turned.scale, turned.rotation], [scale, bearing], 1e-9, "1.20x, turned 14.35° counter-clockwise");
});

test("moveOnResult: a line's targets (no longer rectified), a cage's targets", () => {
  const line = pure(e.moveOnResult, DOC, 2, 2, [[-30, 20], [0, 25], [30, 10]]);
  assert.deepEqual(line.handles[2], { kind: "line", start: [-30, 20], end: [30, 20], rectify: false, targets: [[-30, 20], [0, 25], [30, 10]] });
  const cage = pure(e.moveOnResult, DOC, 4, -1, [[-99, 2], [-89, 2], [-94, 10]]);
  assert.deepEqual(cage.handles[4], { kind: "cage", vertices: [[-100, 0], [-90, 0], [-95, 8]], targets: [[-99, 2], [-89, 2], [-94, 10]] });
});

test("an edit's result shares no array with its input", () => {
  const points = [[5, 5], [0, 0], [0, 0]];
  const out = e.moveOnInput(DOC, 0, points);
  points[0][0] = 99;
  assert.deepEqual(out.handles[0].position, [5, 5]);
  out.handles[3].vertices[0][0] = -1;
  assert.equal(DOC.handles[3].vertices[0][0], 100);
});

test("setReach sets a point's reach as one new document, in its range, and leaves other handles alone", () => {
  const out = pure(e.setReach, DOC, 1, 22.345);
  assert.equal(out.handles[1].reach, 22.35);
  assert.deepEqual(out.handles.filter((_, i) => i !== 1), DOC.handles.filter((_, i) => i !== 1));
  assert.equal(e.setReach(DOC, 1, 0.01).handles[1].reach, e.REACH_RANGE[0]);
  assert.equal(e.setReach(DOC, 1, 400).handles[1].reach, e.REACH_RANGE[1]);
  assert.equal(e.setReach(DOC, 2, 10), DOC); // a line has no reach
  assert.equal(e.setReach(DOC, 1, NaN), DOC);
});
