// The editor's view of the equirectangular panorama: where a [lon, lat] is on a canvas and
// back, zoom and pan. Pure functions over a View, no DOM; tested by tests/js/view.test.mjs.
//
// On screen the panorama is `k` CSS pixels wide (k / 2 high) with its left edge (lon -180)
// at x = `tx` and its top (lat 90) at y = `ty`; it repeats every `k` pixels to both sides,
// so handles and drags wrap across the ±180° seam.

import { wrapLon } from "./sphere.js";

/** @typedef {import("./sphere.js").LonLat} LonLat */
/** @typedef {number[]} XY [x, y] in CSS pixels from a canvas's top left corner */
/**
 * @typedef {{k: number, tx: number, ty: number}} View the panorama's width `k` on screen and
 *   the top left corner (tx, ty) of its copy whose left edge is lon -180, in CSS pixels
 */

const ZOOM_RATE = 0.0015; // per unit of a wheel event's deltaY
const ZOOM_RANGE = [0.5, 64]; // times the fitted width

const clamp = (x, lo, hi) => Math.min(hi, Math.max(lo, x));

/**
 * The view that shows the whole panorama centred on a canvas (as wide as it fits).
 * @param {number} width the canvas's width, CSS pixels
 * @param {number} height the canvas's height, CSS pixels
 * @returns {View}
 */
export function fitView(width, height) {
  const k = Math.min(width, 2 * height);
  return { k, tx: (width - k) / 2, ty: (height - k / 2) / 2 };
}

/**
 * Where a position is on screen, in the copy of the panorama whose left edge is at tx.
 * @param {View} view
 * @param {LonLat} lonlat [lon, lat] in degrees
 * @returns {XY}
 */
export function toScreen(view, [lon, lat]) {
  const { k, tx, ty } = view;
  return [tx + ((lon + 180) / 360) * k, ty + ((90 - lat) / 180) * (k / 2)];
}

/**
 * The position under a screen point, in any copy of the panorama (the inverse of toScreen);
 * above or below the panorama the latitude stops at ±90.
 * @param {View} view
 * @param {number} x CSS pixels
 * @param {number} y CSS pixels
 * @returns {LonLat} [lon, lat] in degrees, lon in [-180, 180)
 */
export function screenToLonLat(view, x, y) {
  const { k, tx, ty } = view;
  return [wrapLon(((x - tx) / k) * 360 - 180), clamp(90 - ((y - ty) / (k / 2)) * 180, -90, 90)];
}

/**
 * The screen x of the copy of a point nearest to the screen x `near` (a whole number of
 * panorama widths from `x`).
 * @param {View} view
 * @param {number} x a point's screen x, CSS pixels
 * @param {number} near CSS pixels
 * @returns {number} CSS pixels
 */
export function nearestX(view, x, near) {
  return x + Math.round((near - x) / view.k) * view.k;
}

/**
 * The horizontal offsets of the copies of the panorama a canvas shows (each a multiple of k).
 * @param {View} view
 * @param {number} width the canvas's width, CSS pixels
 * @returns {number[]} CSS pixels, from left to right
 */
export function copies(view, width) {
  const { k, tx } = view;
  const out = [];
  for (let j = Math.floor(-tx / k); j <= Math.floor((width - tx) / k); j++) out.push(j * k);
  return out;
}

/**
 * A path of positions on screen, each point in the copy nearest to the one before it, so the
 * path runs on across the seam instead of jumping back a panorama's width.
 * @param {View} view
 * @param {LonLat[]} lonlats [lon, lat] in degrees
 * @returns {XY[]} starting in the copy whose left edge is at tx
 */
export function screenPath(view, lonlats) {
  const pts = lonlats.map((q) => toScreen(view, q));
  for (let i = 1; i < pts.length; i++) pts[i][0] = nearestX(view, pts[i][0], pts[i - 1][0]);
  return pts;
}

/**
 * The view zoomed about a screen point by a wheel event: what is under (x, y) stays there;
 * the width stays between half and 64 times the fitted one.
 * @param {View} view
 * @param {number} x CSS pixels
 * @param {number} y CSS pixels
 * @param {number} deltaY the wheel event's deltaY (> 0 zooms out)
 * @param {number} width the canvas's width, CSS pixels
 * @param {number} height the canvas's height, CSS pixels
 * @returns {View} a new view
 */
export function zoomAt(view, x, y, deltaY, width, height) {
  const { k, tx, ty } = view;
  const fitK = Math.min(width, 2 * height);
  const k2 = clamp(k * Math.exp(-deltaY * ZOOM_RATE), fitK * ZOOM_RANGE[0], fitK * ZOOM_RANGE[1]);
  const s = k2 / k;
  return { k: k2, tx: x - (x - tx) * s, ty: y - (y - ty) * s };
}

/**
 * The view moved by a drag of (dx, dy) screen pixels.
 * @param {View} view
 * @param {number} dx CSS pixels
 * @param {number} dy CSS pixels
 * @returns {View} a new view
 */
export function panBy(view, dx, dy) {
  return { ...view, tx: view.tx + dx, ty: view.ty + dy };
}
