// The editor's status area (omniwidget/widget/static/status.js): warnings grouped by the
// kernel's kinds and folded after three, the headline, the jobs' messages, the time from a
// person's action to its image, and the cursor over the panes.
import { test } from "node:test";
import assert from "node:assert/strict";
import {
  FOLD_AFTER,
  actionOnDone,
  actionOnStatus,
  cursorFor,
  duration,
  fold,
  groupWarnings,
  headline,
  jobMessages,
  latencyText,
  startAction,
  warningView,
} from "../../omniwidget/widget/static/status.js";

const SAME = "constraints on the same point";
const CROSS = "lines crossing in the output";
// as after Suggest lines, Accept all, Level on the hotel room: 6 crossings, 7 on the same point, a fold-over
const WARNINGS = [
  ...Array.from({ length: 6 }, (_, i) => [`handles[${i}] (line) and handles[${i + 20}] (line) cross each other in the output`, CROSS]),
  ...Array.from({ length: 7 }, (_, i) => [`constraints of handles[${i}] (line), handles[${i + 30}] (line) fall on the same point`, SAME]),
  ["the warp folds over near handles[0] (line)", "fold-overs"],
];
const TEXTS = WARNINGS.map(([w]) => w);
const KINDS = WARNINGS.map(([, k]) => k);

test("warnings are grouped by the kind the kernel gives, in the order each kind first comes", () => {
  const groups = groupWarnings(TEXTS, KINDS);
  assert.deepEqual(groups.map((g) => [g.kind, g.items.length]), [[CROSS, 6], [SAME, 7], ["fold-overs", 1]]);
  assert.deepEqual(groups[1].items, TEXTS.slice(6, 13));
  // the text is never read: the same text under two kinds is two groups, and a warning without a kind is a conflict
  assert.deepEqual(groupWarnings(["a", "a", "b"], ["x", "y"]).map((g) => [g.kind, g.items]), [["x", ["a"]], ["y", ["a"]], ["conflicts", ["b"]]]);
  assert.deepEqual(groupWarnings(undefined, undefined), []);
});

test("a list longer than three shows three and says how many more", () => {
  assert.equal(FOLD_AFTER, 3);
  assert.deepEqual(fold([1, 2, 3, 4, 5], false), { shown: [1, 2, 3], more: 2 });
  assert.deepEqual(fold([1, 2, 3, 4, 5], true), { shown: [1, 2, 3, 4, 5], more: 0 });
  assert.deepEqual(fold([1, 2, 3], false), { shown: [1, 2, 3], more: 0 });
  assert.deepEqual(fold([], false), { shown: [], more: 0 });
});

test("the warnings area: a row a group with its count, opened to three warnings and a toggle for the rest", () => {
  const closed = warningView(TEXTS, KINDS);
  assert.deepEqual(closed.groups.map((g) => g.title), [`6 ${CROSS}`, `7 ${SAME}`, "the warp folds over near handles[0] (line)"]);
  assert.equal(closed.more, 0);
  assert.ok(closed.groups.every((g) => !g.open && g.items.length === 0 && g.more === 0), "closed groups list nothing");
  const open = warningView(TEXTS, KINDS, { open: new Set([SAME]) });
  assert.deepEqual(open.groups[1].items, TEXTS.slice(6, 9));
  assert.equal(open.groups[1].more, 4);
  const all = warningView(TEXTS, KINDS, { open: new Set([SAME]), all: new Set([SAME]) });
  assert.deepEqual(all.groups[1].items, TEXTS.slice(6, 13));
  assert.equal(all.groups[1].more, 0);
  // a group of one is its warning, never opened
  assert.equal(warningView(TEXTS, KINDS, { open: new Set(["fold-overs"]) }).groups[2].open, false);
});

test("more than three kinds: three groups and a toggle for the others", () => {
  const kinds = ["a", "b", "c", "d", "e"];
  const view = warningView(kinds.map((k) => `${k} warning`), kinds);
  assert.deepEqual(view.groups.map((g) => g.kind), ["a", "b", "c"]);
  assert.equal(view.more, 2);
  assert.equal(warningView(kinds.map((k) => `${k} warning`), kinds, { groups: true }).groups.length, 5);
  // fifteen warnings of one kind take one row
  const many = Array.from({ length: 15 }, (_, i) => `constraints fall on the same point (mesh vertex ${5800 + i})`);
  const one = warningView(many, many.map(() => SAME));
  assert.equal(one.groups.length, 1);
  assert.equal(one.groups[0].title, `15 ${SAME}`);
});

test("durations read as a person says them", () => {
  assert.equal(duration(28.4), "28 ms");
  assert.equal(duration(999.4), "999 ms");
  assert.equal(duration(4420), "4.4 s");
  assert.equal(duration(12600), "13 s");
  assert.equal(latencyText(4420, "click"), "image 4.4 s after the click");
  assert.equal(latencyText(310, "release"), "image 310 ms after the mouse release");
  assert.equal(latencyText(null, "click"), "");
});

test("the latency runs from the action to the first image newer than every edit asked for before it", () => {
  // the kernel shows generation 3 and computes 4 (an edit before the click) when the person clicks Level
  let action = startAction(1000, "click", { state: "busy", generation: 3, newest: 4 });
  assert.equal(action.after, 4);
  // Level's job reports while it runs (no new edit yet), then generation 4, the edit before the click, is shown
  for (const s of [{ state: "busy", generation: 3, newest: 4, level: { state: "running" } }, { state: "idle", generation: 4, newest: 4 }]) {
    const r = actionOnStatus(action, s, 1100);
    assert.equal(r.latency, null, "no image of the click's yet");
    action = r.action;
  }
  assert.equal(action.busy, false);
  // the rotation is applied (edit 5), computed, and shown 4.4 s after the click
  action = actionOnStatus(action, { state: "busy", generation: 4, newest: 5 }, 1500).action;
  assert.equal(action.busy, true);
  assert.equal(actionOnDone(action, { newest: 5 }), action, "Level's done comes after its edit: the action still waits");
  const shown = actionOnStatus(action, { state: "idle", generation: 5, newest: 5 }, 5420);
  assert.deepEqual(shown, { action: null, latency: 4420 });
});

test("an action that computes nothing, or fails, waits for no image", () => {
  const action = startAction(0, "click", { state: "idle", generation: 7, newest: 7 });
  assert.equal(actionOnDone(action, { state: "idle", generation: 7, newest: 7 }), null, "a refused command");
  const busy = actionOnStatus(action, { state: "busy", generation: 7, newest: 8 }, 10).action;
  assert.deepEqual(actionOnStatus(busy, { state: "error", generation: 7, newest: 8 }, 20), { action: null, latency: null });
  assert.deepEqual(actionOnStatus(null, { state: "idle", generation: 9 }, 30), { action: null, latency: null });
});

test("the headline: the result and the time from the action, or what is going on", () => {
  const latency = { ms: 4420, cause: "click" };
  assert.equal(headline({ state: "idle", result: "1024 x 512 in 1.73 s", message: "saved 3 handles" }, latency), "result 1024 x 512 in 1.73 s · image 4.4 s after the click");
  assert.equal(headline({ state: "idle", message: "1024 x 512 in 1.73 s" }, null), "result 1024 x 512 in 1.73 s");
  assert.equal(headline({ state: "busy", result: "1024 x 512 in 1.73 s" }, latency), "computing...");
  assert.equal(headline({ state: "error", error: "could not compute the result" }, latency), "could not compute the result");
});

test("the jobs' messages: each one the kernel still says, an error said once", () => {
  const s = {
    error: "could not level the panorama: too few vertical edges",
    suggest: { state: "done", message: "" }, // the prompt cleared: no suggestion left
    level: { state: "error", message: "could not level the panorama: too few vertical edges" },
    save: { state: "done", message: "saved 3 handles to room.handles.json" },
  };
  assert.deepEqual(jobMessages(s), ["saved 3 handles to room.handles.json"]);
  assert.deepEqual(jobMessages({ suggest: { state: "running", message: "finding straight edges..." } }), ["finding straight edges..."]);
  assert.deepEqual(jobMessages(undefined), []);
  const straightened = "straightened in 2.4 s: levelled by pitch +0.13°, roll -0.04°; 27 lines straightened (undo to take it back)";
  assert.deepEqual(jobMessages({ straighten: { state: "done", message: straightened } }), [straightened], "Straighten's message");
});

test("the cursor shows what a press would do", () => {
  assert.equal(cursorFor({ hit: { index: 0, part: 1 } }), "grab", "a control point");
  assert.equal(cursorFor({ hit: { index: 0, part: -1 } }), "move", "a handle's arc");
  assert.equal(cursorFor({ dragging: "move" }), "grabbing");
  assert.equal(cursorFor({ dragging: "reach" }), "grabbing");
  assert.equal(cursorFor({ dragging: "pan" }), "grabbing");
  assert.equal(cursorFor({ dragging: "split" }), "ew-resize");
  assert.equal(cursorFor({ ring: true }), "grab");
  assert.equal(cursorFor({ suggestion: true }), "pointer");
  assert.equal(cursorFor({ tool: "line", pane: "input", hit: { part: 0 } }), "crosshair", "a drawing tool draws");
  assert.equal(cursorFor({ tool: "select", pane: "input" }), "crosshair");
  assert.equal(cursorFor({ space: true }), "grab");
});
