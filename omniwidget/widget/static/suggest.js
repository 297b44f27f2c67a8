// Suggested lines and levelling in the editor: which dashed suggestion is under the pointer,
// and the line the two background jobs (Suggest lines, Level) add to the status bar. Pure
// functions, no DOM; tested by tests/js/suggest.test.mjs.

import { segmentDistance } from "./hit.js";
import { geodesic } from "./sphere.js";
import { nearestX, toScreen } from "./view.js";

/** @typedef {import("./sphere.js").LonLat} LonLat */
/** @typedef {import("./view.js").View} View */
/**
 * A suggested line, as the kernel sends it (EditingSession.suggestions): `key` names it in
 * the commands, `start` and `end` are its ends (the great-circle arc between them).
 * @typedef {{key: number, start: LonLat, end: LonLat, length?: number, confidence?: number}} Suggestion
 */
/**
 * A background job's state, as the kernel's status says it (status.suggest, status.level).
 * @typedef {{state?: "running" | "done" | "error", message?: string}} DetectJob
 */

/** CSS pixels: how close a click must be to a suggestion to accept it. */
export const HIT_SUGGESTION = 7;

/**
 * The arc drawn for a suggestion (sampled at most 0.75° apart).
 * @param {Suggestion} s
 * @returns {LonLat[]}
 */
export const suggestionArc = (s) => geodesic(s.start, s.end);

/**
 * The screen distance from (x, y) to a suggestion's arc, to the nearest copy of the panorama.
 * @param {View} view
 * @param {Suggestion} s
 * @param {number} x CSS pixels
 * @param {number} y CSS pixels
 * @returns {number} CSS pixels
 */
export function suggestionDistance(view, s, x, y) {
  const pts = suggestionArc(s).map((q) => toScreen(view, q));
  let best = Infinity;
  for (let j = 1; j < pts.length; j++) {
    const ax = nearestX(view, pts[j - 1][0], x);
    const bx = nearestX(view, pts[j][0], ax);
    best = Math.min(best, segmentDistance(x, y, ax, pts[j - 1][1], bx, pts[j][1]));
  }
  return best;
}

/**
 * The suggestion under (x, y): the nearest within `tolerance` pixels, or null.
 * @param {View} view
 * @param {Suggestion[]} suggestions
 * @param {number} x CSS pixels
 * @param {number} y CSS pixels
 * @param {number} [tolerance] CSS pixels
 * @returns {Suggestion | null}
 */
export function suggestionAt(view, suggestions, x, y, tolerance = HIT_SUGGESTION) {
  let found = null;
  let best = tolerance;
  for (const s of suggestions || []) {
    const d = suggestionDistance(view, s, x, y);
    if (d <= best) [found, best] = [s, d];
  }
  return found;
}

/**
 * Whether Suggest lines, Level or Straighten is at work (the spinner shows).
 * @param {{suggest?: DetectJob, level?: DetectJob, straighten?: DetectJob}} status the kernel's status
 * @returns {boolean}
 */
export function detectRunning(status) {
  return ["suggest", "level", "straighten"].some((job) => Boolean(status && status[job]) && status[job].state === "running");
}

/**
 * The jobs' line in the status bar: each job's message while it runs or once done (an
 * error is also the status's error, shown once there).
 * @param {{suggest?: DetectJob, level?: DetectJob}} status the kernel's status
 * @returns {string[]}
 */
export function detectStatusText(status) {
  const parts = [];
  for (const job of ["suggest", "level", "straighten"]) {
    const j = status && status[job];
    if (j && j.message && (j.state === "running" || j.state === "done" || (j.state === "error" && j.message !== status.error)))
      parts.push(j.message);
  }
  return parts;
}
