// Suggested lines (omniwidget/widget/static/suggest.js): which dashed suggestion a click
// accepts, across the seam too; the status line of Suggest lines and Level.
import { test } from "node:test";
import assert from "node:assert/strict";
import { HIT_SUGGESTION, detectRunning, detectStatusText, suggestionArc, suggestionAt, suggestionDistance } from "../../omniwidget/widget/static/suggest.js";
import { fitView, toScreen } from "../../omniwidget/widget/static/view.js";

const VIEW = fitView(800, 400); // k = 800: 1° is 20/9 px both ways; [0, 0] is at (400, 200)
const SUGGESTIONS = [
  { key: 0, start: [-30, 0], end: [30, 0] }, // along the equator: y = 200 from x = 333.3 to 466.7
  { key: 3, start: [10, 20], end: [10, -20] }, // a meridian: x = 422.2
  { key: 5, start: [170, 10], end: [-170, 10] }, // across the seam
];

test("the arc of a suggestion is the great circle between its ends", () => {
  const arc = suggestionArc(SUGGESTIONS[0]);
  assert.ok(Math.abs(arc[0][0] + 30) < 1e-9 && Math.abs(arc[0][1]) < 1e-9);
  assert.ok(Math.abs(arc.at(-1)[0] - 30) < 1e-9 && Math.abs(arc.at(-1)[1]) < 1e-9);
  for (const [, lat] of arc) assert.ok(Math.abs(lat) < 1e-9, "the equator stays at latitude 0");
});

test("the distance to a suggestion is to its arc, not only its ends", () => {
  assert.ok(suggestionDistance(VIEW, SUGGESTIONS[0], 380, 203) < 3.01);
  assert.ok(Math.abs(suggestionDistance(VIEW, SUGGESTIONS[0], 300, 200) - (1000 / 3 - 300)) < 1e-6, "beyond its start");
});

test("a click accepts the nearest suggestion within HIT_SUGGESTION pixels, nothing farther", () => {
  const [x, y] = toScreen(VIEW, [10, 0]); // where the equator and the meridian cross
  assert.equal(suggestionAt(VIEW, SUGGESTIONS, x + 5, y + 2).key, 0, "nearer the equator");
  assert.equal(suggestionAt(VIEW, SUGGESTIONS, x + 4, y + 30).key, 3, "on the meridian");
  assert.equal(suggestionAt(VIEW, SUGGESTIONS, 380, 200 + HIT_SUGGESTION + 1), null);
  assert.equal(suggestionAt(VIEW, [], x, y), null);
  assert.equal(suggestionAt(VIEW, undefined, x, y), null);
});

test("a suggestion across the seam is hit from both edges of the panorama", () => {
  const [, y] = toScreen(VIEW, [0, 10]);
  assert.equal(suggestionAt(VIEW, SUGGESTIONS, 799, y).key, 5);
  assert.equal(suggestionAt(VIEW, SUGGESTIONS, 1, y).key, 5);
});

test("the spinner shows while Suggest lines or Level runs; the status line says what each did", () => {
  assert.equal(detectRunning({}), false);
  assert.equal(detectRunning(undefined), false);
  assert.equal(detectRunning({ suggest: { state: "running" } }), true);
  assert.equal(detectRunning({ suggest: { state: "done" }, level: { state: "running" } }), true);
  assert.equal(detectRunning({ suggest: { state: "done" }, level: { state: "error" } }), false);
  assert.equal(detectRunning({ level: { state: "done" }, straighten: { state: "running" } }), true, "Straighten too");
  assert.deepEqual(detectStatusText({}), []);
  assert.deepEqual(detectStatusText({ suggest: { state: "done", message: "12 suggested lines" } }), ["12 suggested lines"]);
  const error = "could not level the panorama: too few vertical edges";
  assert.deepEqual(detectStatusText({ error, level: { state: "error", message: error } }), [], "said once, as the error");
  assert.deepEqual(detectStatusText({ error: "", level: { state: "error", message: error } }), [error]);
});
