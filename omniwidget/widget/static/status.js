// The editor's status area: what it says and in what order, the warnings grouped by kind and
// folded, the time from a person's action to the image it brought, and the cursor over the
// panes. Pure functions, no DOM; tested by tests/js/status.test.mjs.
//
// The kernel's status (EditingSession.status) gives the facts: the result shown (`result`,
// `generation`), the quality line (`quality`, Summary.line(): the lines asked to be straight
// measured, the ones kept as they are named apart), the warnings and their kinds
// (`warnings`, `warning_kinds`, one kind per warning from its BlendWarning class), the jobs'
// messages (`suggest`, `level`, `straighten`, `save`; the kernel clears a finished job's message when it
// goes stale). This module only arranges them.

/** Groups, and warnings in a group, shown before a "show N more" toggle. */
export const FOLD_AFTER = 3;

/**
 * The warnings grouped by kind, in the order each kind first comes.
 * @param {string[]} warnings the kernel's status.warnings
 * @param {string[]} [kinds] status.warning_kinds, one per warning ("conflicts" where missing)
 * @returns {{kind: string, items: string[]}[]}
 */
export function groupWarnings(warnings, kinds) {
  const groups = new Map();
  (warnings || []).forEach((w, i) => {
    const kind = (kinds && kinds[i]) || "conflicts";
    if (!groups.has(kind)) groups.set(kind, []);
    groups.get(kind).push(w);
  });
  return [...groups].map(([kind, items]) => ({ kind, items }));
}

/**
 * The first `limit` items of a list unless it is unfolded, and how many are left out.
 * @template T
 * @param {T[]} items
 * @param {boolean} unfolded show them all
 * @param {number} [limit]
 * @returns {{shown: T[], more: number}}
 */
export function fold(items, unfolded, limit = FOLD_AFTER) {
  const shown = unfolded || items.length <= limit ? items.slice() : items.slice(0, limit);
  return { shown, more: items.length - shown.length };
}

/**
 * What the warnings area shows: a row per group, three groups unless unfolded; a group of
 * one warning is that warning, a larger one its kind and count, opened on a click to three
 * of its warnings and a toggle for the rest.
 * @param {string[]} warnings
 * @param {string[]} [kinds]
 * @param {{open?: Set<string>, all?: Set<string>, groups?: boolean}} [unfolded] the kinds opened, the kinds showing all their warnings, all the groups shown
 * @returns {{groups: {kind: string, count: number, title: string, open: boolean, items: string[], more: number}[], more: number}}
 */
export function warningView(warnings, kinds, unfolded = {}) {
  const open = unfolded.open || new Set();
  const all = unfolded.all || new Set();
  const { shown, more } = fold(groupWarnings(warnings, kinds), Boolean(unfolded.groups));
  const groups = shown.map(({ kind, items }) => {
    const single = items.length === 1;
    const isOpen = !single && open.has(kind);
    const inside = isOpen ? fold(items, all.has(kind)) : { shown: [], more: 0 };
    return { kind, count: items.length, title: single ? items[0] : `${items.length} ${kind}`, open: isOpen, items: inside.shown, more: inside.more };
  });
  return { groups, more };
}

/**
 * Milliseconds as a person reads them: "280 ms", "4.4 s", "12 s".
 * @param {number} ms
 * @returns {string}
 */
export function duration(ms) {
  if (ms < 1000) return `${Math.round(ms)} ms`;
  const s = ms / 1000;
  return s < 10 ? `${s.toFixed(1)} s` : `${Math.round(s)} s`;
}

/**
 * A person's action waiting for its image: when it happened, what it was, and the newest
 * result the kernel had then (its image cannot be the answer).
 * @typedef {{at: number, cause: string, after: number, busy: boolean}} Action
 */

/**
 * The action a click, a key or a mouse release starts, as the kernel's status stands then.
 * @param {number} now performance.now()
 * @param {string} cause "click", "key" or "release"
 * @param {{generation?: number, newest?: number}} status the kernel's status
 * @returns {Action}
 */
export function startAction(now, cause, status) {
  const s = status || {};
  return { at: now, cause, after: Math.max(Number(s.generation) || 0, Number(s.newest) || 0), busy: false };
}

/**
 * What a new status does to the action waiting: a computation started for it (busy), its
 * result on screen (the latency, from the action to now), or its end without an image (an error).
 * @param {Action | null} action
 * @param {{state?: string, generation?: number, newest?: number}} status
 * @param {number} now performance.now(), once the image is on screen
 * @returns {{action: Action | null, latency: number | null}}
 */
export function actionOnStatus(action, status, now) {
  if (!action || !status) return { action, latency: null };
  const generation = Number(status.generation) || 0;
  const started = Number(status.newest) > action.after;
  if (status.state === "busy") return { action: started || action.busy ? { ...action, busy: true } : action, latency: null };
  if (status.state === "idle" && generation > action.after) return { action: null, latency: now - action.at };
  if (status.state === "error" && (action.busy || started)) return { action: null, latency: null };
  return { action, latency: null };
}

/**
 * The kernel says the command of the action is done: an action that started no computation
 * (a command refused, or one that changed nothing) waits for no image.
 * @param {Action | null} action
 * @param {{newest?: number}} status
 * @returns {Action | null}
 */
export function actionOnDone(action, status) {
  if (!action) return null;
  return action.busy || Number((status || {}).newest) > action.after ? action : null;
}

/**
 * The latency as the status area says it.
 * @param {number | null} ms
 * @param {string} cause
 * @returns {string}
 */
export function latencyText(ms, cause) {
  if (ms === null || ms === undefined) return "";
  const what = { click: "the click", key: "the key", release: "the mouse release" }[cause] || "the edit";
  return `image ${duration(ms)} after ${what}`;
}

/**
 * The first line of the status area: the result shown (or being computed, or the error
 * that kept the last good one) and how long it took to come after the action that asked for it.
 * @param {{state?: string, result?: string, message?: string, error?: string}} status
 * @param {{ms: number | null, cause: string} | null} latency
 * @returns {string}
 */
export function headline(status, latency) {
  const s = status || {};
  const parts = [];
  if (s.state === "busy") parts.push("computing...");
  else if (s.state === "error") parts.push(s.error || s.message || "the computation failed");
  else if (s.state === "idle") parts.push(`result ${s.result || s.message || ""}`.trim());
  if (s.state === "idle" && latency && latency.ms !== null) parts.push(latencyText(latency.ms, latency.cause));
  return parts.join(" · ");
}

/**
 * The jobs' messages (Suggest lines, Level, Straighten, Save, Save image), each while it runs or once
 * done, until the kernel clears it; an error that is the status's error is said once, there.
 * @param {{suggest?: object, level?: object, save?: object, error?: string}} status
 * @returns {string[]}
 */
export function jobMessages(status) {
  const s = status || {};
  const out = [];
  for (const name of ["suggest", "level", "straighten", "save"]) {
    const j = s[name];
    if (j && j.message && (j.state !== "error" || j.message !== s.error)) out.push(j.message);
  }
  return out;
}

/**
 * The pointer's cursor on a pane: what a press there would do.
 * @param {{dragging?: string | null, hit?: {part: number} | null, ring?: boolean, suggestion?: boolean, tool?: string, pane?: string, space?: boolean}} at
 *   `dragging` the drag in progress ("move", "reach", "pan", "split"), `hit` the handle under the pointer (part -1: its arc),
 *   `ring` on the selected point's reach ring, `suggestion` on a suggested line
 * @returns {string} a CSS cursor
 */
export function cursorFor(at) {
  if (at.dragging) return at.dragging === "split" ? "ew-resize" : "grabbing";
  if (at.space) return "grab";
  if (at.tool && at.tool !== "select" && at.pane === "input") return "crosshair";
  if (at.hit) return at.hit.part >= 0 ? "grab" : "move";
  if (at.ring) return "grab";
  if (at.suggestion) return "pointer";
  return "crosshair";
}
