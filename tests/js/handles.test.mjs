// The handles' control points and arcs (omniwidget/widget/static/handles.js).
import { test } from "node:test";
import assert from "node:assert/strict";
import { ARROW_LENGTH, controlPoints, curves } from "../../omniwidget/widget/static/handles.js";
import { DEG, distance } from "../../omniwidget/widget/static/sphere.js";

function near(actual, expected, tol, what) {
  const [a, e] = [actual.flat(2), expected.flat(2)];
  assert.equal(a.length, e.length, what);
  a.forEach((x, i) => assert.ok(Math.abs(x - e[i]) <= tol, `${what}: ${JSON.stringify(actual)} vs ${JSON.stringify(expected)}`));
}

const point = { kind: "point", position: [0, 0], target: [0, 0], rotation: 0, scale: 1 };
const line = { kind: "line", start: [170, 0], end: [-170, 0], rectify: true };
const cage = { kind: "cage", vertices: [[0, 0], [10, 0], [10, 10], [0, 10]] };

test("a point's control points: its centre, the east and the west arrow tip", () => {
  const a = ARROW_LENGTH / DEG; // 17.19°
  near(controlPoints(point), [[0, 0], [a, 0], [-a, 0]], 1e-9, "point");
});

test("a line's control points: its start, the midpoint of the shorter arc (here across the seam), its end", () => {
  near(controlPoints(line), [[170, 0], [-180, 0], [-170, 0]], 1e-9, "line");
});

test("a cage's control points are its vertices", () => {
  assert.deepEqual(controlPoints(cage), cage.vertices);
});

test("curves: a point's two arrows, a line's one arc, a cage's closed ring of edges", () => {
  const arrows = curves(point, controlPoints(point));
  assert.equal(arrows.length, 2);
  near([arrows[0][0], arrows[0].at(-1), arrows[1].at(-1)], controlPoints(point), 1e-9, "the arrows' ends");
  const [arc] = curves(line, controlPoints(line));
  near([arc[0], arc.at(-1)], [[170, 0], [-170, 0]], 1e-9, "the line's ends");
  assert.ok(arc.every((q) => distance(q, [180, 0]) <= 10 + 1e-9), "the short way, across the seam");
  const edges = curves(cage, cage.vertices);
  assert.equal(edges.length, 4);
  near(edges.map((e) => [e[0], e.at(-1)]), [[[0, 0], [10, 0]], [[10, 0], [10, 10]], [[10, 10], [0, 10]], [[0, 10], [0, 0]]], 1e-9, "edges");
});
