// The handles' shapes for the editor: their control points and the arcs drawn between them,
// as omniwidget/document/handles.py defines them. Pure functions, no DOM; tested by
// tests/js/handles.test.mjs.

import { alongEast, circleArc, geodesic, midpoint } from "./sphere.js";

/** @typedef {import("./sphere.js").LonLat} LonLat */

/**
 * A point handle: `position` goes to `target`, magnified by `scale` and turned by
 * `rotation` degrees counter-clockwise there.
 * @typedef {{kind: "point", position: LonLat, target?: LonLat, rotation?: number, scale?: number, reach?: number | null}} PointHandle
 */
/**
 * A line handle from `start` to `end`; `rectify` to straighten it, `targets` its three
 * control points' outputs when moved by hand.
 * @typedef {{kind: "line", start: LonLat, end: LonLat, rectify?: boolean, targets?: LonLat[]}} LineHandle
 */
/**
 * A cage handle: a polygon of `vertices`, `targets` their outputs when moved.
 * @typedef {{kind: "cage", vertices: LonLat[], targets?: LonLat[]}} CageHandle
 */
/** @typedef {PointHandle | LineHandle | CageHandle} Handle */
/**
 * The handles document, as in a handles file (Handles.to_dict): other fields
 * ("format", "version", "options") pass through every edit unchanged.
 * @typedef {{handles: Handle[], [field: string]: any}} HandlesDocument
 */

/** Radians from a point handle's centre to its arrow tips (handles.ARROW_LENGTH). */
export const ARROW_LENGTH = 0.3;

/**
 * A handle's control points on the input (its `control_points()`): a point's centre, east
 * arrow tip and west arrow tip; a line's start, geodesic midpoint and end; a cage's vertices.
 * @param {Handle} h
 * @returns {LonLat[]}
 */
export function controlPoints(h) {
  if (h.kind === "point") return [h.position, alongEast(h.position, 1, ARROW_LENGTH), alongEast(h.position, -1, ARROW_LENGTH)];
  if (h.kind === "line") return [h.start, midpoint(h.start, h.end), h.end];
  return h.vertices;
}

/**
 * The arcs drawn for a handle whose control points are `pts` (on the input or the result):
 * a point's two arrows, a line's circle through its three points, a cage's edges.
 * @param {Handle} h
 * @param {LonLat[]} pts its control points, as controlPoints gives them
 * @returns {LonLat[][]} each arc sampled at most 0.75° apart
 */
export function curves(h, pts) {
  if (h.kind === "point") return [geodesic(pts[0], pts[1]), geodesic(pts[0], pts[2])];
  if (h.kind === "line") return [circleArc(pts[0], pts[1], pts[2])];
  return pts.map((p, i) => geodesic(p, pts[(i + 1) % pts.length]));
}
