// Hit testing for the editor: which handle, and which of its control points, is under the
// pointer. Distances are in screen pixels, measured to the nearest copy of the panorama (so
// a handle at lon 179.9 is hit from the left edge too). Pure functions, no DOM; tested by
// tests/js/hit.test.mjs.

import { curves } from "./handles.js";
import { circle } from "./sphere.js";
import { nearestX, toScreen } from "./view.js";

/** @typedef {import("./sphere.js").LonLat} LonLat */
/** @typedef {import("./view.js").View} View */
/** @typedef {import("./handles.js").Handle} Handle */
/**
 * What the pointer is on: handle `index`'s control point `part`, `d` pixels away, or the
 * handle itself (part -1: on one of its arcs, away from its control points).
 * @typedef {{index: number, part: number, d?: number}} Hit
 */

/** CSS pixels: how close a click must be to a control point. */
export const HIT = 9;
/** CSS pixels: how close a click must be to a line, an arrow or a cage edge. */
export const HIT_EDGE = 6;

const clamp = (x, lo, hi) => Math.min(hi, Math.max(lo, x));

/**
 * The distance from a point to a segment of the plane.
 * @param {number} px the point's x
 * @param {number} py the point's y
 * @param {number} ax the segment's start x
 * @param {number} ay the segment's start y
 * @param {number} bx the segment's end x
 * @param {number} by the segment's end y
 * @returns {number} in the same unit
 */
export function segmentDistance(px, py, ax, ay, bx, by) {
  const dx = bx - ax;
  const dy = by - ay;
  const t = clamp(((px - ax) * dx + (py - ay) * dy) / (dx * dx + dy * dy || 1), 0, 1);
  return Math.hypot(px - ax - t * dx, py - ay - t * dy);
}

/**
 * The screen distance from (x, y) to the nearest copy of a position.
 * @param {View} view
 * @param {LonLat} lonlat [lon, lat] in degrees
 * @param {number} x CSS pixels
 * @param {number} y CSS pixels
 * @returns {number} CSS pixels
 */
export function pointDistance(view, lonlat, x, y) {
  const [qx, qy] = toScreen(view, lonlat);
  return Math.hypot(nearestX(view, qx, x) - x, qy - y);
}

/**
 * Whether (x, y) is within `tolerance` pixels of one of a handle's arcs (a line, its arrows,
 * the cage's edges) with the control points `pts`.
 * @param {View} view
 * @param {Handle} h
 * @param {LonLat[]} pts its control points as they are on the pane
 * @param {number} x CSS pixels
 * @param {number} y CSS pixels
 * @param {number} [tolerance] CSS pixels
 * @returns {boolean}
 */
export function onCurve(view, h, pts, x, y, tolerance = HIT_EDGE) {
  for (const c of curves(h, pts)) {
    const s = c.map((q) => toScreen(view, q));
    for (let j = 1; j < s.length; j++) {
      const ax = nearestX(view, s[j - 1][0], x);
      const bx = nearestX(view, s[j][0], ax);
      if (segmentDistance(x, y, ax, s[j - 1][1], bx, s[j][1]) <= tolerance) return true;
    }
  }
  return false;
}

/**
 * The handle under (x, y): the nearest control point within HIT pixels (the selected
 * handle's first, and a point of another handle only when more than half a pixel nearer),
 * else the first handle with an arc within HIT_EDGE pixels (part -1), else null.
 * @param {View} view
 * @param {Handle[]} handles the document's handles
 * @param {LonLat[][]} positions each handle's control points as they are on the pane
 * @param {number} x CSS pixels
 * @param {number} y CSS pixels
 * @param {number} selected the selected handle's index, -1 if none
 * @returns {Hit | null}
 */
export function hitTest(view, handles, positions, x, y, selected) {
  let best = null;
  const order = handles.map((_, i) => i);
  if (selected >= 0 && selected < handles.length) order.unshift(selected); // the selected handle's points first
  for (const i of order) {
    positions[i].forEach((q, j) => {
      const d = pointDistance(view, q, x, y);
      if (d <= HIT && (!best || d < best.d - 0.5)) best = { index: i, part: j, d };
    });
    if (best && best.index === selected) return best;
  }
  if (best) return best;
  for (const i of order) {
    if (onCurve(view, handles[i], positions[i], x, y)) return { index: i, part: -1 };
  }
  return null;
}

/**
 * Whether (x, y) is within `tolerance` pixels of the ring `radius` degrees round `centre`
 * (a selected point handle's reach).
 * @param {View} view
 * @param {LonLat} centre [lon, lat] in degrees
 * @param {number} radius degrees
 * @param {number} x CSS pixels
 * @param {number} y CSS pixels
 * @param {number} [tolerance] CSS pixels
 * @returns {boolean}
 */
export function onRing(view, centre, radius, x, y, tolerance = HIT_EDGE) {
  const s = circle(centre, radius).map((q) => toScreen(view, q));
  for (let j = 1; j < s.length; j++) {
    const ax = nearestX(view, s[j - 1][0], x);
    const bx = nearestX(view, s[j][0], ax);
    if (segmentDistance(x, y, ax, s[j - 1][1], bx, s[j][1]) <= tolerance) return true;
  }
  return false;
}
