// The editor's edits of the handles document: a drag's control points as the pointer moves,
// and the new document a drag, a click or a key leaves. Pure functions: each returns a new
// document (or new points) and leaves its arguments as they were. No DOM; tested by
// tests/js/edits.test.mjs.

import { arrowTip } from "./moebius.js";
import { carry, DEG, distance, midpoint, mirror } from "./sphere.js";

/** @typedef {import("./sphere.js").LonLat} LonLat */
/** @typedef {import("./handles.js").Handle} Handle */
/** @typedef {import("./handles.js").HandlesDocument} HandlesDocument */
/**
 * A control point (or a whole handle) being dragged on a pane.
 * @typedef {object} Drag
 * @property {"move"} type
 * @property {"input" | "result"} pane the input (draw stage) or the result (transform stage)
 * @property {number} index the handle's index in the document
 * @property {"point" | "line" | "cage"} kind the handle's kind
 * @property {number} part the control point grabbed, -1 the handle itself (on one of its arcs)
 * @property {LonLat} grab where the pointer went down, [lon, lat] in degrees
 * @property {LonLat[]} original the handle's control points on the pane when the drag began
 * @property {LonLat[]} points its control points now
 * @property {boolean} moved whether the pointer has moved since it went down
 * @property {boolean} solved whether the kernel has solved the handles during the drag
 * @property {string} solvedAt the points (as JSON) of the last solve sent during the drag, "" if none
 */

/** Degrees: shorter drags make no line. */
export const MIN_LINE = 0.05;
/** Radians: a cage vertex this close to the one before it is the same click twice. */
const SAME_VERTEX = 1e-3;

const copy = (value) => JSON.parse(JSON.stringify(value));
const handlesOf = (doc) => doc.handles || [];

/**
 * A new point handle at a position, not yet moved.
 * @param {LonLat} at [lon, lat] in degrees
 * @returns {Handle}
 */
export function newPoint(at) {
  return { kind: "point", position: [...at], target: [...at], rotation: 0, scale: 1 };
}

/**
 * A new line handle drawn from `start` to `end`, or null when they are under MIN_LINE apart.
 * @param {LonLat} start [lon, lat] in degrees
 * @param {LonLat} end [lon, lat] in degrees
 * @returns {Handle | null}
 */
export function newLine(start, end) {
  if (distance(start, end) < MIN_LINE) return null;
  return { kind: "line", start: [...start], end: [...end], rectify: false };
}

/**
 * A new cage handle from the vertices clicked (a double-click's second click, on top of the
 * vertex before, is dropped), or null with fewer than three vertices.
 * @param {LonLat[]} clicked [lon, lat] in degrees, in order
 * @returns {Handle | null}
 */
export function newCage(clicked) {
  const vertices = clicked.filter((q, i) => i === 0 || distance(q, clicked[i - 1]) * DEG > SAME_VERTEX);
  return vertices.length >= 3 ? { kind: "cage", vertices: copy(vertices) } : null;
}

/**
 * The document with a handle added at the end.
 * @param {HandlesDocument} doc
 * @param {Handle} handle
 * @returns {HandlesDocument}
 */
export function addHandle(doc, handle) {
  return { ...doc, handles: [...handlesOf(doc), copy(handle)] };
}

/**
 * The document without handle `index`.
 * @param {HandlesDocument} doc
 * @param {number} index
 * @returns {HandlesDocument}
 */
export function removeHandle(doc, index) {
  return { ...doc, handles: handlesOf(doc).filter((_, j) => j !== index) };
}

/**
 * The dragged handle's control points with the part grabbed at `at`. On the input a point
 * moves whole, a line's end moves alone (its middle follows), its middle moves the whole line;
 * on the result a point's arrow tip turns and scales it (the opposite tip follows, mirrored
 * through the centre), the centre moves it whole. Grabbed on an arc (part -1), any handle
 * moves whole, turned along the great circle from `grab` to `at`.
 * @param {Drag} drag
 * @param {LonLat} at the pointer, [lon, lat] in degrees
 * @returns {LonLat[]} new control points
 */
export function dragPoints(drag, at) {
  const { pane, kind, part, original, grab } = drag;
  if (kind === "point" && (pane === "input" || part <= 0)) return carry(original, part === 0 ? original[0] : grab, at); // the arrows ride along
  if (kind === "point") {
    const pts = copy(original);
    pts[part] = [...at];
    pts[3 - part] = mirror(pts[0], at); // the opposite arrow follows
    return pts;
  }
  if (part === -1 || (pane === "input" && kind === "line" && part === 1)) return carry(original, grab, at);
  const pts = copy(original);
  pts[part] = [...at];
  if (pane === "input" && kind === "line") pts[1] = midpoint(pts[0], pts[2]);
  return pts;
}

/**
 * The document as a drag on the input leaves it: handle `index` with the control points
 * `points`. A point not yet moved on the result (target = position) keeps its target on it.
 * @param {HandlesDocument} doc
 * @param {number} index
 * @param {LonLat[]} points the handle's new input control points, as dragPoints gives them
 * @returns {HandlesDocument}
 */
export function moveOnInput(doc, index, points) {
  const next = copy(doc);
  const h = next.handles[index];
  const pts = copy(points);
  if (h.kind === "point") {
    const unmoved = !h.target || (h.target[0] === h.position[0] && h.target[1] === h.position[1]);
    h.position = pts[0];
    if (unmoved) h.target = pts[0];
  } else if (h.kind === "line") {
    h.start = pts[0];
    h.end = pts[2];
  } else h.vertices = pts;
  return next;
}

/**
 * The document as a drag on the result leaves it: handle `index` with the output control
 * points `points`. A point takes its centre as target (and, for an arrow tip dragged, the
 * scale and turn the tip gives: moebius.arrowTip); a line, its three points as targets (no
 * longer rectified); a cage, its vertices' targets.
 * @param {HandlesDocument} doc
 * @param {number} index
 * @param {number} part the control point dragged, -1 the whole handle
 * @param {LonLat[]} points the handle's new output control points, as dragPoints gives them
 * @returns {HandlesDocument}
 */
export function moveOnResult(doc, index, part, points) {
  const next = copy(doc);
  const h = next.handles[index];
  const pts = copy(points);
  if (h.kind === "point") {
    h.target = pts[0];
    if (part > 0) Object.assign(h, arrowTip(pts[0], pts[part], part === 1 ? "east" : "west") || {});
  } else if (h.kind === "line") {
    h.rectify = false;
    h.targets = pts;
  } else h.targets = pts;
  return next;
}

/** The range a point handle's `reach` may take, degrees (handles.REACH_RANGE). */
export const REACH_RANGE = [0.5, 90];

/**
 * The document with point handle `index`'s reach set (its ring dragged): `reach` degrees,
 * kept in REACH_RANGE and rounded to 0.01°; any other handle leaves the document as it is.
 * @param {HandlesDocument} doc
 * @param {number} index
 * @param {number} reach degrees
 * @returns {HandlesDocument}
 */
export function setReach(doc, index, reach) {
  const h = doc.handles[index];
  if (!h || h.kind !== "point" || !Number.isFinite(reach)) return doc;
  const r = Math.round(Math.min(REACH_RANGE[1], Math.max(REACH_RANGE[0], reach)) * 100) / 100;
  return { ...doc, handles: doc.handles.map((x, i) => (i === index ? { ...x, reach: r } : x)) };
}
