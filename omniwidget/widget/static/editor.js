// omniwidget editor: the front end of omniwidget.widget.Editor, an ES module that anywidget
// loads as one module with the modules it imports, editor.bundle.js, built by esbuild
// (npm run build; npm run watch rebuilds it on every change, and anywidget's hot reload,
// ANYWIDGET_HMR=1, shows the new build in the open notebooks).
//
// Everything the browser tells the kernel is in [lon, lat] degrees, the conventions of
// omniwidget/sphere/coords.py (sphere.js). The pure parts are modules of their own, each
// tested by node --test (tests/js): the sphere (sphere.js), the handles' control points and
// arcs (handles.js), the view of the panorama on a canvas, which wraps across the ±180° seam
// (view.js), hit testing (hit.js), the edits of the handles document (edits.js), the
// handles' Möbius maps (moebius.js), a video's frame label and Save video's status line
// (video.js), the suggested lines a click accepts (suggest.js), and what the status area
// says, the warnings grouped and folded, the time from an action to its image and the
// cursor (status.js), the look-around view's camera (look.js). This file holds the
// DOM: the one state object, the canvases, the events, and the messages to and from the kernel.
//
// Drags happen here at display frame rate; only their end reaches the kernel, as a new
// handles document or a command ({op: ...}) the kernel applies (undo, rectify, arrows).
// While a control point is dragged on the result, the result follows it live (live.js):
// the kernel sends the dragged handle's share of eq. (2) once, the GPU redoes the sum each
// frame with the handle's maps rebuilt here (moebius.js), and the kernel's exact result
// replaces the live frame once it arrives.

import { addHandle, dragPoints, moveOnInput, moveOnResult, newCage, newLine, newPoint, removeHandle, setReach } from "./edits.js";
import { controlPoints, curves } from "./handles.js";
import { HIT, hitTest, onCurve, onRing, pointDistance } from "./hit.js";
import { createLive, MOVING_PIXELS } from "./live.js";
import { createLook, dragLook, lonlatAt, lookText, START, zoomLook } from "./look.js";
import { dragMaps, inverse } from "./moebius.js";
import { circle, distance, geodesic } from "./sphere.js";
import { actionOnDone, actionOnStatus, cursorFor, headline, jobMessages, startAction, warningView } from "./status.js";
import { detectRunning, suggestionArc, suggestionAt } from "./suggest.js";
import { frameLabel, videoRunning, videoStatusText } from "./video.js";
import { copies, fitView, panBy, screenPath, screenToLonLat, toScreen, zoomAt } from "./view.js";

/** @typedef {import("./sphere.js").LonLat} LonLat */
/** @typedef {import("./view.js").View} View */
/** @typedef {import("./handles.js").HandlesDocument} HandlesDocument */
/** @typedef {import("./edits.js").Drag} Drag */

const LIVE_REST_MS = 120; // the mouse this long at rest: the live frame is drawn in full
const COLORS = {
  point: "#22c7ff",
  line: "#ff453a",
  cage: "#ffffff",
  selected: "#ffd60a",
  conflict: "#ff9f0a",
  kept: "#30d158",
  suggestion: "#bf5af2",
};
// a line kept as it is (over a pole): dash-dot; a suggested line, not yet a handle: long dashes
const DASHES = { conflict: [6, 4], kept: [10, 4, 2, 4], suggestion: [8, 5] };
const IMAGES = ["source", "preview", "folds"]; // the images the kernel sends
const TOOLS = [
  ["select", "Select", "V", "select, move, pan"],
  ["point", "Point", "P", "click to place a point handle"],
  ["line", "Line", "L", "press, drag, release to draw a line"],
  ["cage", "Cage", "C", "click the vertices; close on the first vertex, Enter or double-click"],
];
// A stage's key switches to it at once and the status bar says so (the toolbar's titles and
// the help name the same keys): a letter meant for the notebook ("d d") cannot change the
// view unnoticed.
const STAGES = [
  ["draw", "Draw", "D", "the input only, to draw handles"],
  ["transform", "Transform", "T", "the result only, to move control points"],
  ["side", "Side by side", "B", "the input and the result"],
];
// Every key the editor handles while it has the focus, the ones it passes to JupyterLab too.
const SHORTCUTS = [
  ["V P L C", "select, point, line, cage tool (named in the status bar)"],
  ["D T B", "draw stage, transform stage, side by side (named in the status bar)"],
  ["Ctrl+Z / Ctrl+Shift+Z", "undo / redo (also Ctrl+Y)"],
  ["Delete, Backspace", "delete the selected handle"],
  ["Enter, double-click", "close the cage being drawn"],
  ["Esc", "cancel the handle being drawn, the drag in progress or this help; else drop the suggested lines; else back to the notebook"],
  ["wheel", "zoom about the cursor"],
  ["Space + drag, middle drag", "pan (wraps across the ±180° seam)"],
  ["F", "fit the panorama to the view"],
  ["H", "show or hide the handles"],
  ["A / S / R", "rectify all lines / rectify the selected line / reset the selected handle"],
  ["?", "this help (Esc, its × or a click outside it closes it)"],
  ["Ctrl+S", "save the notebook (passed on to JupyterLab)"],
  ["Shift+Enter / Ctrl+Enter / Alt+Enter", "run the cell and select the next / run it / run it, insert a cell (passed on to JupyterLab)"],
];
// A command the kernel is still applying may change the handles (undo, rectify, load, ...):
// an edit made meanwhile would start from the handles before it and undo it, so none starts
// until the kernel says the command is done ("done" message, sent after any change of the handles).
// Level's "done" comes once its rotation is applied, after it was found in the background.
const CHANGES_HANDLES = new Set(["undo", "redo", "rectify_all", "rectify_line", "reset", "arrow", "load", "accept_suggestion", "accept_all", "level", "straighten"]);
// Commands that leave the result as it is (no latency is taken for them).
const KEEPS_RESULT = new Set(["save", "save_video", "cancel_video", "suggest", "drop_suggestions"]);

// --- the state ------------------------------------------------------------------------------
/**
 * Everything the editor remembers between events, all of it declared here.
 * @typedef {object} State
 * @property {"select" | "point" | "line" | "cage"} tool
 * @property {View | null} view both panes' view, null until the panorama is there
 * @property {boolean} fitted the view is the fitted one (fitted again when the panes change size)
 * @property {ImageBitmap | null} source the panorama
 * @property {ImageBitmap | null} preview the kernel's result
 * @property {ImageBitmap | null} folds where the result folds over (magenta)
 * @property {{[image: string]: Promise<void> | null}} decoding each image's decoding, by name
 * @property {boolean} showFolds
 * @property {boolean} showHandles
 * @property {boolean} split the result pane shows the input left of a slider
 * @property {number} splitAt the slider, a fraction of the pane's width
 * @property {Drag | {type: "pan", x: number, y: number, view: View} | {type: "split", pane: object} | null} drag a drag in progress
 * @property {{kind: "line" | "cage", points: LonLat[], cursor: LonLat} | null} drawing a line or cage being drawn
 * @property {LonLat[][] | null} localOutputs outputs as the last drag left them, until the kernel's arrive
 * @property {boolean} space the space bar is down: a drag pans
 * @property {boolean} help the help is shown
 * @property {((e: PointerEvent) => void) | null} closeHelp the window's listener that closes the help on a click outside it
 * @property {import("./status.js").Action | null} action the person's last action that waits for its image (status.js)
 * @property {{ms: number, cause: string} | null} latency from the last action to its image on screen
 * @property {{open: Set<string>, all: Set<string>, groups: boolean}} unfolded the warning groups opened, those showing all, all groups shown
 * @property {LonLat | null} cursor the position under the mouse
 * @property {string} localNote the editor's own note in the status bar
 * @property {number} pendingCount commands that change the handles, sent and not yet done
 * @property {number} pendingSince performance.now() of the oldest of them, 0 if none
 * @property {number} frame the animation frame asked for, 0 if none
 * @property {string} liveWanted "generation:index" of the live basis last asked for
 * @property {object | null} liveBasis the header of the basis the GPU holds: {index, generation, controls, carry, ...}
 * @property {object[] | null} liveMaps the dragged handle's inverse maps, to render at the next frame
 * @property {boolean} liveShown the result pane shows the live frame (until the kernel's result arrives)
 * @property {object | null} liveDrawn the basis header of the live frame drawn, and its step
 * @property {number} dragSolve performance.now() of the drag's solve on its way, 0 if none
 * @property {object[] | null} liveLast the maps of the last live frame drawn
 * @property {boolean} liveFine the next live frame in full (the mouse rests), not from every second pixel
 * @property {number} liveRest the timer that draws it
 */

/** @returns {State} */
function initialState() {
  return {
    tool: "select",
    view: null,
    fitted: false,
    source: null,
    preview: null,
    folds: null,
    decoding: { source: null, preview: null, folds: null },
    showFolds: true,
    showHandles: true,
    split: false,
    splitAt: 0.5,
    drag: null,
    drawing: null,
    localOutputs: null,
    space: false,
    help: false,
    closeHelp: null,
    action: null,
    latency: null,
    unfolded: { open: new Set(), all: new Set(), groups: false },
    cursor: null,
    localNote: "",
    pendingCount: 0,
    pendingSince: 0,
    frame: 0,
    liveWanted: "",
    liveBasis: null,
    liveMaps: null,
    liveShown: false,
    liveDrawn: null,
    dragSolve: 0,
    liveLast: null,
    liveFine: false,
    liveRest: 0,
    looking: false,
    look: { ...START },
    lookRenderer: undefined,
  };
}

/**
 * One editor on the page: its model, state, elements and live renderer.
 * @typedef {object} Editor
 * @property {object} model the anywidget model
 * @property {State} state
 * @property {ReturnType<typeof buildUI>} ui
 * @property {ReturnType<typeof createLive> | null} live null without WebGL2
 */

/**
 * anywidget's entry point: the editor of `model` in `host`.
 * @param {{model: object, el: HTMLElement}} widget the anywidget model and the element to fill
 * @returns {() => void} the clean-up, when the view is removed
 */
function render({ model, el: host }) {
  /** @type {Editor} */
  const ed = { model, state: initialState(), ui: null, live: null };
  ed.ui = buildUI(ed);
  host.append(ed.ui.root);
  ed.live = startLive(ed.ui);
  wirePanes(ed);
  wireFocus(ed);
  wireKeys(ed);
  const unwire = wireModel(ed);
  const resize = new ResizeObserver(() => layout(ed));
  resize.observe(ed.ui.panesBox);
  for (const name of IMAGES) onImage(ed, name);
  updateFrames(ed);
  layout(ed);
  showHandlesDocument(ed);
  onStatus(ed);
  return () => {
    resize.disconnect();
    unwire();
    toggleHelp(ed, false);
  };
}

// --- the elements -------------------------------------------------------------------------------
function el(tag, attrs = {}, ...children) {
  const node = document.createElement(tag);
  for (const [key, value] of Object.entries(attrs)) {
    if (key === "class") node.className = value;
    else if (key.startsWith("on")) node.addEventListener(key.slice(2), value);
    else node.setAttribute(key, value);
  }
  for (const child of children) node.append(child);
  return node;
}

function buildUI(ed) {
  const root = el("div", {
    class: "ow-editor",
    tabindex: "0",
    // JupyterLab's key bindings ignore keys typed in here (Lumino's CommandRegistry stops at
    // this attribute), but for the few the keyboard section hands on to it (Ctrl+S, Shift+Enter...)
    "data-lm-suppress-shortcuts": "true",
    "data-busy": "false",
    "data-generation": "0",
  });
  const spinner = el("span", { class: "ow-spinner", title: "computing" });
  const fileInput = el("input", { type: "file", accept: ".json,application/json", style: "display:none", onchange: () => loadFile(ed) });
  const toolbar = buildToolbar(ed, fileInput, spinner);
  const panes = ["input", "result"].map(buildPane);
  const panesBox = el("div", { class: "ow-panes" }, ...panes.map((p) => p.box));
  const message = el("div", { class: "ow-message" });
  const cursorInfo = el("span", { class: "ow-cursor" });
  const helpBox = buildHelp(ed);
  const liveCanvas = el("canvas", { class: "ow-live", hidden: "" }); // live.js draws the live result here
  const frames = buildFrames(ed);
  root.append(toolbar, frames.box, panesBox, el("div", { class: "ow-status" }, message, cursorInfo), helpBox, liveCanvas);
  return { root, toolbar, spinner, fileInput, panes, panesBox, message, cursorInfo, helpBox, liveCanvas, frames };
}

// A video's frame slider (hidden for an image): moving it names the frame, releasing it shows it.
function buildFrames(ed) {
  const slider = el("input", {
    type: "range",
    class: "ow-frame-slider",
    min: "0",
    max: "0",
    step: "1",
    value: "0",
    title: "The frame of the video to draw on",
    style: "flex: 1",
  });
  const label = el("span", { class: "ow-frame-label", style: "white-space: nowrap; font-variant-numeric: tabular-nums" });
  slider.addEventListener("input", () => showFrameLabel(ed, Number(slider.value)));
  slider.addEventListener("change", () => chooseFrame(ed, Number(slider.value)));
  // laid out here (editor.css is the image editor's): a row above the panes, hidden for an image
  const box = el("div", { class: "ow-frames", style: "display: flex; gap: 8px; align-items: center; margin-bottom: 4px" }, slider, label);
  return { box, slider, label };
}

function buildToolbar(ed, fileInput, spinner) {
  const group = (...buttons) => el("div", { class: "ow-group" }, ...buttons);
  const button = (action, label, title, onclick) => el("button", { "data-action": action, title, onclick }, label);
  const choice = (attr, choose) => ([name, label, key, what]) =>
    el("button", { [attr]: name, title: `${label} (${key}): ${what}`, onclick: () => choose(ed, name) }, label);
  return el(
    "div",
    { class: "ow-toolbar" },
    group(...STAGES.map(choice("data-stage", setStage))),
    group(...TOOLS.map(choice("data-tool", setTool))),
    group(
      button("undo", "Undo", "Undo (Ctrl+Z)", () => command(ed, "undo")),
      button("redo", "Redo", "Redo (Ctrl+Shift+Z)", () => command(ed, "redo")),
      button("delete", "Delete", "Delete the selected handle (Delete)", () => deleteSelected(ed)),
    ),
    group(
      button("rectify-all", "Rectify all lines", "Straighten every line together (A)", () => command(ed, "rectify_all")),
      button("rectify-line", "Rectify selected line", "Straighten the selected line, hold the rest (S)", () =>
        commandSelected(ed, "rectify_line"),
      ),
      button("reset", "Reset selected", "Undo the selected handle's transformation (R)", () => commandSelected(ed, "reset")),
    ),
    group(
      button("suggest", "Suggest lines", "Find straight edges in the panorama, shown dashed on the input: click one to add it as a line", () =>
        command(ed, "suggest"),
      ),
      button("accept-all", "Accept all", "Add every suggested line as a line handle (one edit)", () => command(ed, "accept_all")),
      button("drop-suggestions", "Drop", "Drop the suggested lines (Esc)", () => command(ed, "drop_suggestions")),
      button("level", "Level", "Find how the camera was tilted, from the vertical edges, and undo it (one edit)", () => command(ed, "level")),
      button(
        "straighten",
        "Straighten",
        "Level, find the room's or the street's structure (verticals, wall-floor and wall-ceiling edges) and straighten it: the lines used become the handles (one edit)",
        () => command(ed, "straighten"),
      ),
    ),
    group(
      button("fit", "Fit", "Fit the panorama to the view (F)", () => fit(ed)),
      button("split", "Split", "Compare: the input left of a slider, the result right of it", () => toggleLayer(ed, "split")),
      button("folds", "Folds", "Show where the result folds over", () => toggleLayer(ed, "showFolds")),
      button("handles", "Handles", "Show or hide the handles (H)", () => toggleHandles(ed)),
      button("look", "Look around", "The result as a 360° viewer shows it: drag to look, the wheel to zoom (as omniwidget view draws it)", () =>
        toggleLook(ed),
      ),
    ),
    group(
      button("save", "Save", "Write the handles file next to the notebook", () => command(ed, "save")),
      button("download", "Download", "Download the handles file", () => download(ed)),
      button("load", "Load", "Load a handles file", () => fileInput.click()),
      button("full", "Full size", "Compute the result at the panorama's full size", () => command(ed, "full")),
      button("save-video", "Save video", "Warp the whole video by these handles and write it next to it (clip.mp4: clip-rectified.mp4)", () =>
        command(ed, "save_video"),
      ),
      button("cancel-video", "Cancel", "Stop saving the video (nothing is written)", () => command(ed, "cancel_video")),
      button(
        "save-image",
        "Save image",
        "Write the full-size result next to the panorama (room.jpg: room-rectified.jpg) and download it",
        () => command(ed, "save_image"),
      ),
      button("help", "?", "Keyboard shortcuts (?)", () => toggleHelp(ed)),
      fileInput,
    ),
    spinner,
  );
}

function buildPane(kind) {
  const canvas = el("canvas", { class: "ow-canvas", "data-pane": kind });
  const label = el("div", { class: "ow-pane-label" }, kind === "input" ? "input: draw handles" : "result: move control points");
  const box = el("div", { class: "ow-pane", "data-pane": kind }, canvas, label);
  return { kind, canvas, box, ctx: canvas.getContext("2d"), w: 0, h: 0 };
}

function buildHelp(ed) {
  return el(
    "div",
    { class: "ow-help", hidden: "" },
    el("button", { class: "ow-help-close", type: "button", title: "Close the help (Esc, or a click outside it)", "aria-label": "close", onclick: () => toggleHelp(ed, false) }, "×"),
    el("h3", {}, "Keyboard and mouse"),
    el("table", {}, ...SHORTCUTS.map(([k, what]) => el("tr", {}, el("th", {}, k), el("td", {}, what)))),
    el("p", {}, "Positions are [lon, lat] in degrees whatever the zoom. Draw on the input; move control points on the result."),
    el("p", {}, "Look around shows the result as a 360° viewer does (the camera of omniwidget view): drag to turn it, the wheel to zoom."),
    el(
      "p",
      {},
      "While the editor has the keyboard, other keys do nothing (none reaches the notebook's command mode: 'd d' deletes no cell); " +
        "Esc or a click outside the editor gives it back to the notebook.",
    ),
  );
}

// --- the model --------------------------------------------------------------------------------
/** @returns {HandlesDocument} */
const doc = (ed) => ed.model.get("handles") || { handles: [] };
const items = (ed) => doc(ed).handles || [];
const outputs = (ed) => ed.state.localOutputs || ed.model.get("outputs") || [];
const selected = (ed) => ed.model.get("selected");
const status = (ed) => ed.model.get("status") || {};
const suggestions = (ed) => ed.model.get("suggestions") || [];

function setPending(ed, n) {
  ed.state.pendingCount = n;
  ed.ui.root.dataset.pending = String(n); // for a glance in the inspector (and the real-browser tests)
}

function waitingForKernel(ed) {
  const { state } = ed;
  if (state.pendingCount > 0 && performance.now() - state.pendingSince > 10000) setPending(ed, 0); // a kernel that never answers
  if (state.pendingCount === 0) return false;
  showLocal(ed, "one moment: the kernel is applying the last command");
  return true;
}

// The new handles document to the kernel; false if there is no change (or none may start yet).
// `cause` names the person's action, timed to the image it brings: "release" (the mouse
// release that ended a drag or a line), "click", "key".
function commit(ed, next, cause = "release") {
  if (waitingForKernel(ed)) return false;
  if (JSON.stringify(next) === JSON.stringify(doc(ed))) return false;
  ed.state.action = { ...startAction(performance.now(), cause, status(ed)), op: "" };
  ed.model.set("handles", next);
  ed.model.save_changes();
  return true;
}

function command(ed, op, content = {}, cause = "click") {
  const { state } = ed;
  if (!KEEPS_RESULT.has(op)) state.action = { ...startAction(performance.now(), cause, status(ed)), op }; // every other command changes the result
  if (CHANGES_HANDLES.has(op)) {
    if (state.pendingCount === 0) state.pendingSince = performance.now();
    setPending(ed, state.pendingCount + 1);
  }
  ed.model.send({ op, ...content });
}

function commandSelected(ed, op, cause = "click") {
  const i = selected(ed);
  if (i < 0 || i >= items(ed).length) return showLocal(ed, "select a handle first");
  if (op === "rectify_line" && items(ed)[i].kind !== "line") return showLocal(ed, "the selected handle is not a line");
  command(ed, op, { index: i }, cause);
}

function onMessage(ed, content, buffers) {
  if (content && content.op === "live" && buffers && buffers.length) {
    onLiveBasis(ed, content, buffers[0]);
    return;
  }
  if (content && content.op === "image_file" && buffers && buffers.length) {
    downloadImage(ed, content, buffers[0]);
    return;
  }
  const { state } = ed;
  if (content && content.done !== undefined && state.action && state.action.op === content.done) {
    state.action = actionOnDone(state.action, status(ed)); // a command that computed nothing waits for no image
  }
  if (content && content.done !== undefined && CHANGES_HANDLES.has(content.done) && state.pendingCount > 0) {
    setPending(ed, state.pendingCount - 1);
    if (state.pendingCount === 0 && state.localNote.startsWith("one moment")) showLocal(ed, "");
  }
}

function select(ed, i) {
  if (selected(ed) !== i) {
    ed.model.set("selected", i);
    ed.model.save_changes();
  }
}

function deleteSelected(ed, cause = "click") {
  const i = selected(ed);
  if (i < 0 || i >= items(ed).length) return;
  const next = removeHandle(doc(ed), i);
  ed.model.set("selected", -1);
  commit(ed, next, cause);
}

function download(ed) {
  const blob = new Blob([JSON.stringify(doc(ed), null, 2) + "\n"], { type: "application/json" });
  const a = el("a", { href: URL.createObjectURL(blob), download: "handles.json" });
  a.click();
  setTimeout(() => URL.revokeObjectURL(a.href), 1000);
}

// The full-size result Save image wrote, sent by the kernel: offered as a download too.
function downloadImage(ed, content, buffer) {
  const blob = new Blob([buffer], { type: content.mime || "application/octet-stream" });
  const a = el("a", { href: URL.createObjectURL(blob), download: content.name || "panorama-rectified.png" });
  ed.ui.root.append(a); // some browsers click only links in the document
  a.click();
  a.remove();
  ed.ui.root.dataset.savedImage = content.name || "";
  setTimeout(() => URL.revokeObjectURL(a.href), 10000);
}

async function loadFile(ed) {
  const input = ed.ui.fileInput;
  const file = input.files && input.files[0];
  if (!file) return;
  command(ed, "load", { name: file.name, text: await file.text() });
  input.value = "";
}

function showLocal(ed, text) {
  ed.state.localNote = text;
  updateStatus(ed);
}

// The handles drawn, for a glance in the page's inspector (and the real-browser tests).
function showHandlesDocument(ed) {
  ed.ui.root.dataset.handles = JSON.stringify(doc(ed));
}

// --- the kernel's changes -------------------------------------------------------------------
function wireModel(ed) {
  const { model, state } = ed;
  const listeners = [
    ...IMAGES.map((name) => [`change:${name}`, () => onImage(ed, name)]),
    ["change:handles", () => {
      showHandlesDocument(ed);
      draw(ed);
    }],
    ["change:outputs", () => {
      state.localOutputs = null;
      draw(ed);
    }],
    ["change:status", () => onStatus(ed)],
    ["change:selected", () => {
      updateStatus(ed);
      draw(ed);
    }],
    ["change:history", () => updateStatus(ed)],
    ["change:suggestions", () => {
      updateStatus(ed);
      draw(ed);
    }],
    ...["frame", "frame_count", "frame_interval"].map((name) => [`change:${name}`, () => updateFrames(ed)]),
    ["change:stage", () => onStage(ed)],
    ["change:height", () => layout(ed)],
    ["msg:custom", (content, buffers) => onMessage(ed, content, buffers)],
  ];
  for (const [event, fn] of listeners) model.on(event, fn);
  return () => {
    for (const [event, fn] of listeners) model.off(event, fn);
  };
}

async function decode(view, type) {
  if (!view || view.byteLength === 0) return null;
  return createImageBitmap(new Blob([view], { type }));
}

function onImage(ed, name) {
  const { state } = ed;
  state.decoding[name] = (async () => {
    state[name] = await decode(ed.model.get(name), name === "folds" ? "image/png" : "image/jpeg");
    if (name === "source" && state.source && ed.live) ed.live.setSource(state.source);
    if (name === "preview") {
      const d = state.drag;
      // A solve of where the drag was, not where the mouse is now: the live frame goes on (and
      // the rest asks again); otherwise the kernel's result replaces the live frame.
      if (d && d.type === "move" && d.pane === "result" && d.moved && d.solvedAt !== JSON.stringify(d.points)) liveFrame(ed, d);
      else state.liveShown = false;
    }
    if (name === "source" && !state.view) layout(ed);
    draw(ed);
  })();
}

// A result is on screen once its image (when it changed) is decoded and drawn: then the
// root's data-generation names the edit it answers, and the last edit's latency is taken.
// The latency is the person's: from the click, key or mouse release (state.action) to the
// first image newer than every edit the kernel had asked for then, drawn (status.js).
async function onStatus(ed) {
  const { state, ui } = ed;
  state.localNote = "";
  const s = status(ed);
  if (s.state !== "idle") state.action = actionOnStatus(state.action, s, performance.now()).action;
  updateStatus(ed);
  draw(ed);
  if (s.state !== "busy") state.dragSolve = 0; // the next solve of a drag may go
  if (s.state === "error") state.liveShown = false; // the last good result, not a frame of a drag that failed
  if (s.state !== "idle") return;
  await null; // an image changed by the same message has started decoding by now
  await Promise.all([state.decoding.preview, state.decoding.folds]);
  if (!state.drag) state.liveShown = false; // the kernel's result, even when its image did not change
  await new Promise((resolve) => requestAnimationFrame(resolve));
  if (status(ed) !== s) return; // superseded meanwhile
  ui.root.dataset.generation = String(s.generation);
  const action = state.action;
  const { action: waiting, latency } = actionOnStatus(action, s, performance.now());
  state.action = waiting;
  if (latency !== null) {
    state.latency = { ms: latency, cause: action.cause };
    ui.root.dataset.latencyMs = latency.toFixed(1);
    ui.root.dataset.latencyCause = action.cause;
  }
  updateStatus(ed);
}

function onStage(ed) {
  if (ed.model.get("stage") === "transform") setTool(ed, "select"); // nothing is drawn on the result
  layout(ed);
  updateStatus(ed);
}

// --- the live result while dragging (live.js) -----------------------------------------------
function startLive(ui) {
  let live = null;
  try {
    live = createLive(ui.liveCanvas);
  } catch (err) {
    console.warn("omniwidget: the result will not follow drags live:", err);
  }
  ui.root.dataset.live = live ? "ready" : "off";
  ui.root.dataset.liveFrames = "0";
  return live;
}

// Ask the kernel for the basis of a live drag of handle i, once per result on screen.
function requestLive(ed, i) {
  const want = `${status(ed).generation}:${i}`;
  if (!ed.live || i < 0 || ed.state.liveWanted === want) return;
  ed.state.liveWanted = want;
  ed.model.send({ op: "live", index: i });
}

function onLiveBasis(ed, content, buffer) {
  const { state, ui } = ed;
  if (!ed.live || content.generation !== status(ed).generation || !ed.live.setBasis(content, buffer)) return; // a newer result is on screen
  state.liveBasis = content;
  ui.root.dataset.liveBasis = `${content.generation}:${content.index}`;
  ui.root.dataset.liveRegion = JSON.stringify({ origin: content.origin, width: content.width, height: content.height, size: content.size });
  const d = state.drag;
  if (d && d.type === "move" && d.pane === "result" && d.moved) liveFrame(ed, d);
}

// The live result of the drag d, rendered at the next frame when its basis is there.
function liveFrame(ed, d) {
  const { state } = ed;
  const b = state.liveBasis;
  if (!b || b.generation !== status(ed).generation) requestLive(ed, d.index); // a newer solve's basis: asked for, the last one drawn meanwhile
  if (!b || b.index !== d.index) return;
  let maps;
  try {
    maps = dragMaps(items(ed)[d.index], d.points, d.part, b.carry, b.turn);
  } catch (err) {
    return; // control points on top of each other: no map, the last frame stays
  }
  if (maps.length === 1 && b.controls > 1) maps = Array(b.controls).fill(maps[0]); // a line's pieces share its map
  if (maps.length !== b.controls) return;
  state.liveMaps = maps.map(inverse);
  state.liveFine = false;
  clearTimeout(state.liveRest);
  state.liveRest = setTimeout(() => {
    if (state.drag === d) solveDuringDrag(ed, d); // the mouse rests: the kernel's turn
    if (!state.liveShown) return; // the kernel's result came first
    state.liveMaps = state.liveLast;
    state.liveFine = true; // every pixel of the region
    draw(ed);
  }, LIVE_REST_MS);
  draw(ed);
}

// When the mouse rests during a drag on the result, the kernel solves the handles as they
// are, one solve at a time (no edit: nothing to undo until the release); while it moves the
// cores are the browser's. The live frame then draws from the newest weights, so the region
// the handle reaches grows with the drag.
function solveDuringDrag(ed, d) {
  const { state } = ed;
  if (state.dragSolve && performance.now() - state.dragSolve < 5000) return; // one is on its way
  if (status(ed).state === "busy" || state.pendingCount > 0) return;
  state.dragSolve = performance.now();
  d.solved = true;
  d.solvedAt = JSON.stringify(d.points);
  ed.model.send({ op: "drag", handles: moveOnResult(doc(ed), d.index, d.part, d.points) });
}

// --- layout and view --------------------------------------------------------------------
const visible = (ed) =>
  ed.ui.panes.filter((p) => ed.model.get("stage") === "side" || (p.kind === "input") === (ed.model.get("stage") === "draw"));

function layout(ed) {
  const { ui, state } = ed;
  const shown = visible(ed);
  for (const p of ui.panes) p.box.hidden = !shown.includes(p);
  const width = Math.max(200, ui.panesBox.clientWidth || ui.root.clientWidth || 800);
  const height = ed.model.get("height");
  const dpr = window.devicePixelRatio || 1;
  for (const p of shown) {
    p.w = Math.floor((width - (shown.length - 1) * 6) / shown.length);
    p.h = height;
    p.canvas.style.width = `${p.w}px`;
    p.canvas.style.height = `${p.h}px`;
    p.canvas.width = Math.round(p.w * dpr);
    p.canvas.height = Math.round(p.h * dpr);
    p.ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  }
  if (!state.view || state.fitted) fit(ed);
  else draw(ed);
}

function fit(ed) {
  const p = visible(ed)[0];
  ed.state.view = fitView(p.w || 800, p.h || 400);
  ed.state.fitted = true;
  draw(ed);
}

// --- drawing ----------------------------------------------------------------------------
// A handle's control points on a pane: the input's from the document, the result's from the
// kernel (`outputs`, one list per handle); the dragged handle's as the drag has them.
function positions(ed, i, kind) {
  const d = ed.state.drag;
  if (d && d.type === "move" && d.pane === kind && d.index === i) return d.points;
  if (kind === "input") return controlPoints(items(ed)[i]);
  return outputs(ed)[i] || controlPoints(items(ed)[i]);
}

function draw(ed) {
  const { state, ui } = ed;
  if (state.frame) return;
  state.frame = requestAnimationFrame(() => {
    state.frame = 0;
    if (!state.view) return;
    const started = performance.now();
    const rendered = state.liveMaps && ed.live.render(state.liveMaps, state.liveFine ? Infinity : MOVING_PIXELS);
    if (rendered) [state.liveShown, state.liveLast, state.liveDrawn] = [true, state.liveMaps, { ...state.liveBasis, step: rendered }];
    state.liveMaps = null;
    for (const p of visible(ed)) drawPane(ed, p);
    if (rendered) {
      ui.root.dataset.liveFrames = String(Number(ui.root.dataset.liveFrames) + 1);
      ui.root.dataset.liveMs = (performance.now() - started).toFixed(1); // the frame's cost, for bench/bench_live.py
      ui.root.dataset.liveStep = String(rendered);
    }
  });
}

function drawPane(ed, p) {
  const { state } = ed;
  const { k, tx, ty } = state.view;
  const ctx = p.ctx;
  ctx.save();
  ctx.fillStyle = "#1e1e1e";
  ctx.fillRect(0, 0, p.w, p.h);
  if (p.kind === "result" && state.looking) return drawLook(ed, p);
  const offsets = copies(state.view, p.w);
  const image = p.kind === "input" ? state.source : state.preview || state.source;
  if (image) drawImageCopies(ed, p, image, offsets);
  if (p.kind === "result" && state.liveShown) drawLive(ed, p, offsets);
  if (p.kind === "result" && state.split && state.source) drawSplit(ed, p, offsets);
  if (p.kind === "result" && state.showFolds && state.folds) drawImageCopies(ed, p, state.folds, offsets);
  drawSeams(ed, p, offsets);
  if (state.showHandles && p.kind === "input") drawSuggestions(ed, p, offsets);
  if (state.showHandles) drawHandles(ed, p, offsets);
  ctx.restore();
  p.canvas.dataset.view = JSON.stringify({ x0: tx, y0: ty, w: k, h: k / 2 });
}

// --- the look-around view (look.js) ---------------------------------------------------------
// The result pane shows the result through a perspective camera, the camera of `omniwidget
// view`: drawn by WebGL2 on a canvas of its own at the pane's device pixels, then copied onto
// the pane 1:1. Its look (yaw, pitch, fov in degrees) is on the pane's canvas as data-yaw,
// data-pitch and data-fov.
function toggleLook(ed, on = !ed.state.looking) {
  const { state } = ed;
  if (on && state.lookRenderer === undefined) {
    try {
      state.lookRenderer = createLook(document.createElement("canvas"));
    } catch (err) {
      console.warn("omniwidget: no look-around view:", err);
      state.lookRenderer = null;
    }
  }
  if (on && !state.lookRenderer) {
    state.localNote = "Look around needs WebGL2, which this browser does not offer.";
    updateStatus(ed);
    return;
  }
  state.looking = on;
  if (on && ed.model.get("stage") === "draw") setStage(ed, "transform"); // the result pane shown
  const label = ed.ui.panes[1].box.querySelector(".ow-pane-label");
  label.textContent = on ? "result: look around (drag to turn, wheel to zoom)" : "result: move control points";
  updateStatus(ed);
  draw(ed);
}

function drawLook(ed, p) {
  const { state } = ed;
  const image = state.preview || state.source;
  const renderer = state.lookRenderer;
  const [width, height] = [p.canvas.width, p.canvas.height];
  if (image) renderer.setImage(image);
  if (image && renderer.render(state.look, width, height)) {
    p.ctx.setTransform(1, 0, 0, 1, 0, 0);
    p.ctx.drawImage(renderer.canvas, 0, 0);
  }
  p.ctx.restore();
  const { yaw, pitch, fov } = state.look;
  Object.assign(p.canvas.dataset, { yaw: yaw.toFixed(4), pitch: pitch.toFixed(4), fov: fov.toFixed(4) });
  p.canvas.title = `${lookText(state.look)}: drag to look, the wheel to zoom`;
}

function startLook(ed, p, e) {
  const [x, y] = pointerAt(p, e);
  p.canvas.setPointerCapture(e.pointerId);
  ed.state.drag = { type: "look", x, y, look: { ...ed.state.look } };
  e.preventDefault();
}

// A drag turns the view from where it started (look.js dragLook); the status bar names the position under the pointer.
function moveLook(ed, p, x, y) {
  const { state } = ed;
  const d = state.drag;
  if (d && d.type === "look") {
    state.look = dragLook(d.look, x - d.x, y - d.y, p.w);
    draw(ed);
  }
  const [lon, lat] = lonlatAt(state.look, p.w, p.h, x - 0.5, y - 0.5); // pixel centres at half pixels
  ed.ui.cursorInfo.textContent = `lon ${lon.toFixed(2)}°, lat ${lat.toFixed(2)}°`;
}

function drawImageCopies(ed, p, image, offsets) {
  const { k, tx, ty } = ed.state.view;
  for (const dx of offsets) p.ctx.drawImage(image, tx + dx, ty, k, k / 2);
}

// The live frame over the result, where the dragged handle weighs (its region wraps across the seam).
function drawLive(ed, p, offsets) {
  const { k, tx, ty } = ed.state.view;
  const { origin, size, step } = ed.state.liveDrawn;
  const canvas = ed.ui.liveCanvas;
  const scale = k / size;
  const [w, h] = [canvas.width * step * scale, canvas.height * step * scale];
  for (const dx of [offsets[0] - k, ...offsets]) p.ctx.drawImage(canvas, tx + dx + origin[1] * scale, ty + origin[0] * scale, w, h);
}

// The input left of the split slider, over the result.
function drawSplit(ed, p, offsets) {
  const ctx = p.ctx;
  const at = ed.state.splitAt * p.w;
  ctx.save();
  ctx.beginPath();
  ctx.rect(0, 0, at, p.h);
  ctx.clip();
  drawImageCopies(ed, p, ed.state.source, offsets);
  ctx.restore();
  ctx.strokeStyle = "#ffd60a";
  ctx.lineWidth = 2;
  ctx.beginPath();
  ctx.moveTo(at, 0);
  ctx.lineTo(at, p.h);
  ctx.stroke();
}

// The ±180° seam between copies of the panorama.
function drawSeams(ed, p, offsets) {
  const { k, tx, ty } = ed.state.view;
  const ctx = p.ctx;
  ctx.strokeStyle = "rgba(255, 255, 255, 0.5)";
  ctx.lineWidth = 1;
  ctx.setLineDash([2, 4]);
  for (const dx of offsets) {
    ctx.beginPath();
    ctx.moveTo(tx + dx, ty);
    ctx.lineTo(tx + dx, ty + k / 2);
    ctx.stroke();
  }
  ctx.setLineDash([]);
}

function drawHandles(ed, p, offsets) {
  const ctx = p.ctx;
  const s = status(ed);
  const conflicts = new Set(s.conflicts || []);
  const kept = new Set(s.kept || []);
  const sel = selected(ed);
  items(ed).forEach((h, i) => {
    const pts = positions(ed, i, p.kind);
    const isSel = i === sel;
    const look = conflicts.has(i) ? "conflict" : kept.has(i) ? "kept" : null;
    ctx.lineWidth = isSel ? 3 : 2;
    ctx.strokeStyle = look ? COLORS[look] : COLORS[h.kind];
    ctx.setLineDash(look ? DASHES[look] : []);
    for (const c of curves(h, pts)) strokePath(ed, p, c, offsets);
    ctx.setLineDash([]);
    ctx.lineWidth = 1.5;
    ctx.strokeStyle = "#000";
    const fill = isSel ? COLORS.selected : COLORS[h.kind];
    pts.forEach((q, j) => {
      const tip = h.kind === "point" && j > 0;
      dotAt(ed, p, q, offsets, tip ? 4 : 5, fill, tip ? "square" : "circle");
    });
  });
  drawReach(ed, p, offsets);
  if (ed.state.drawing && p.kind === "input") drawDrawing(ed, p, offsets);
}

// A point handle's reach (degrees): as the ring's drag has it, the document's, the kernel's default, or 15.
function reachOf(ed, i) {
  const d = ed.state.drag;
  if (d && d.type === "reach" && d.index === i) return d.reach;
  const h = items(ed)[i];
  if (h && h.reach != null) return h.reach;
  const given = (status(ed).reaches || [])[i];
  return given != null ? given : 15;
}

// The selected point's reach, a dashed ring round its centre on either pane; dragged, it sets `reach`.
function drawReach(ed, p, offsets) {
  const i = selected(ed);
  const h = items(ed)[i];
  if (!h || h.kind !== "point") return;
  const ctx = p.ctx;
  ctx.lineWidth = 1.5;
  ctx.strokeStyle = COLORS.selected;
  ctx.setLineDash([6, 4]);
  strokePath(ed, p, circle(positions(ed, i, p.kind)[0], reachOf(ed, i)), offsets);
  ctx.setLineDash([]);
  p.canvas.dataset.reach = reachOf(ed, i).toFixed(2); // for the browser tests
}

// The suggested lines, dashed: none is a handle until a click accepts it.
function drawSuggestions(ed, p, offsets) {
  const ctx = p.ctx;
  ctx.lineWidth = 2;
  ctx.strokeStyle = COLORS.suggestion;
  ctx.setLineDash(DASHES.suggestion);
  for (const s of suggestions(ed)) strokePath(ed, p, suggestionArc(s), offsets);
  ctx.setLineDash([]);
}

// The line or cage being drawn, to the cursor.
function drawDrawing(ed, p, offsets) {
  const ctx = p.ctx;
  const { points, cursor } = ed.state.drawing;
  ctx.strokeStyle = COLORS.selected;
  ctx.lineWidth = 2;
  ctx.setLineDash([5, 4]);
  const ends = cursor ? [...points, cursor] : points;
  for (let i = 1; i < ends.length; i++) strokePath(ed, p, geodesic(ends[i - 1], ends[i]), offsets);
  ctx.setLineDash([]);
  ctx.strokeStyle = "#000";
  points.forEach((q) => dotAt(ed, p, q, offsets, 5, COLORS.selected));
}

function strokePath(ed, p, lonlats, offsets) {
  if (lonlats.length < 2) return;
  const pts = screenPath(ed.state.view, lonlats); // continuous across the seam
  const ctx = p.ctx;
  for (const dx of offsets) {
    ctx.beginPath();
    ctx.moveTo(pts[0][0] + dx, pts[0][1]);
    for (let i = 1; i < pts.length; i++) ctx.lineTo(pts[i][0] + dx, pts[i][1]);
    ctx.stroke();
  }
}

function dotAt(ed, p, lonlat, offsets, radius, fill, shape = "circle") {
  const [x, y] = toScreen(ed.state.view, lonlat);
  const ctx = p.ctx;
  for (const dx of offsets) {
    ctx.beginPath();
    if (shape === "square") ctx.rect(x + dx - radius, y - radius, 2 * radius, 2 * radius);
    else ctx.arc(x + dx, y, radius, 0, 2 * Math.PI);
    ctx.fillStyle = fill;
    ctx.fill();
    ctx.stroke();
  }
}

// --- the status bar and the toolbar's state -------------------------------------------------
// The status area, top to bottom: the headline (the result shown, or being computed, or the
// error that kept the last good one, and the time from the person's action to its image)
// followed by the quality line (the kernel's Summary.line()), the jobs' messages while they are current,
// the autosave's notice, the editor's own note, then the warnings grouped by kind, three
// groups and three warnings a group before a "show N more" toggle (status.js).
function showStatusArea(ed, s) {
  const { state, ui } = ed;
  const message = ui.message;
  const line = (cls, text) => el("div", { class: cls, title: text }, text);
  // the headline and the quality figures in one paragraph: what matters first, no line spent on a break
  const head = headline(s, s.state === "idle" ? state.latency : null);
  let figures = "";
  if (s.quality && s.state === "idle") figures = s.quality;
  else if (s.fold_area > 0 && s.state === "idle") figures = `fold-over ${(100 * s.fold_area).toPrecision(2)}% of the sphere (magenta)`;
  const top = el("div", { class: "ow-headline", title: figures ? `${head} · ${figures}` : head }, el("span", { class: "ow-headline-main" }, head));
  if (figures) top.append(" · ", el("span", { class: "ow-quality" }, figures));
  const rows = [top];
  if (s.error && s.state !== "error") rows.push(line("ow-error-text", s.error));
  for (const text of jobMessages(s)) rows.push(line("ow-job", text));
  const video = videoStatusText(s.video);
  if (video) rows.push(line("ow-job", video));
  if (s.notice) rows.push(line("ow-notice", s.notice));
  if (state.localNote) rows.push(line("ow-note", state.localNote));
  rows.push(...warningRows(ed, s));
  message.replaceChildren(...rows);
  message.classList.toggle("ow-error", Boolean(s.error));
  ui.root.dataset.statusLines = String(rows.length);
}

function warningRows(ed, s) {
  const { unfolded } = ed.state;
  const kinds = s.warning_kinds || [];
  const view = warningView(s.warnings || [], kinds, unfolded);
  const toggle = (label, onclick, title = "") =>
    el("button", { class: "ow-toggle", type: "button", title, onclick: (e) => (e.stopPropagation(), onclick(), updateStatus(ed)) }, label);
  const rows = [];
  for (const g of view.groups) {
    const all = (s.warnings || []).filter((_, i) => (kinds[i] || "conflicts") === g.kind);
    const row = el("div", { class: "ow-warning", "data-kind": g.kind, title: all.join("\n") });
    if (g.count === 1) row.append(el("span", { class: "ow-warning-text" }, `⚠ ${g.title}`));
    else {
      const flip = () => (unfolded.open.has(g.kind) ? unfolded.open.delete(g.kind) : unfolded.open.add(g.kind));
      row.append(toggle(`${g.open ? "▾" : "▸"} ⚠ ${g.title}`, flip, g.open ? "fold them" : "show them"));
    }
    rows.push(row);
    for (const w of g.items) rows.push(el("div", { class: "ow-warning ow-warning-item", title: w }, el("span", { class: "ow-warning-text" }, w)));
    if (g.more > 0) rows.push(el("div", { class: "ow-warning-item" }, toggle(`show ${g.more} more`, () => unfolded.all.add(g.kind))));
    else if (g.open && unfolded.all.has(g.kind) && g.count > 3) rows.push(el("div", { class: "ow-warning-item" }, toggle("show fewer", () => unfolded.all.delete(g.kind))));
  }
  // the other kinds' toggle ends the last row: no line of its own
  const last = rows[rows.length - 1];
  if (view.more > 0) last.append(toggle(`show ${view.more} more`, () => (unfolded.groups = true), "the other kinds of warnings"));
  else if (unfolded.groups && groupCount(s) > 3) last.append(toggle("show fewer", () => (unfolded.groups = false)));
  return rows;
}

const groupCount = (s) => new Set(s.warning_kinds || []).size;

function updateStatus(ed) {
  const { state, ui, model } = ed;
  const s = status(ed);
  const busy = s.state === "busy";
  ui.root.dataset.busy = String(busy);
  ui.root.dataset.state = s.state || "";
  ui.spinner.hidden = !busy && !detectRunning(s);
  ui.root.dataset.suggestions = String(suggestions(ed).length);
  showStatusArea(ed, s);
  const history = model.get("history") || {};
  const h = items(ed)[selected(ed)];
  const action = (name) => ui.toolbar.querySelector(`[data-action="${name}"]`);
  const isVideo = model.get("frame_count") > 0;
  action("save-video").hidden = !isVideo;
  action("save-video").disabled = videoRunning(s.video);
  action("cancel-video").hidden = !videoRunning(s.video);
  ui.root.dataset.video = (s.video && s.video.state) || "";
  action("undo").disabled = !history.undo;
  action("redo").disabled = !history.redo;
  action("rectify-line").disabled = !h || h.kind !== "line";
  action("reset").disabled = !h;
  action("delete").disabled = !h;
  action("suggest").disabled = Boolean(s.suggest && s.suggest.state === "running");
  action("level").disabled = Boolean(s.level && s.level.state === "running");
  action("straighten").disabled = Boolean(s.straighten && s.straighten.state === "running");
  action("accept-all").disabled = suggestions(ed).length === 0;
  action("drop-suggestions").disabled = suggestions(ed).length === 0;
  action("split").classList.toggle("ow-on", state.split);
  action("folds").classList.toggle("ow-on", state.showFolds);
  action("handles").classList.toggle("ow-on", state.showHandles);
  action("look").classList.toggle("ow-on", state.looking);
  for (const b of ui.toolbar.querySelectorAll("[data-tool]")) b.classList.toggle("ow-on", b.dataset.tool === state.tool);
  for (const b of ui.toolbar.querySelectorAll("[data-stage]")) b.classList.toggle("ow-on", b.dataset.stage === model.get("stage"));
}

// The frame slider as the kernel has it: shown for a video only, at the frame shown.
function updateFrames(ed) {
  const { model, ui } = ed;
  const count = model.get("frame_count") || 0;
  const { box, slider } = ui.frames;
  box.style.display = count === 0 ? "none" : "flex";
  slider.max = String(Math.max(count - 1, 0));
  slider.value = String(model.get("frame") || 0);
  ui.root.dataset.frame = String(model.get("frame") || 0);
  showFrameLabel(ed, model.get("frame") || 0);
  updateStatus(ed);
}

function showFrameLabel(ed, frame) {
  const { model, ui } = ed;
  ui.frames.label.textContent = frameLabel(frame, model.get("frame_count") || 0, model.get("frame_interval") || 0);
}

// The kernel reads the frame and recomputes the preview on it; the handles stay.
function chooseFrame(ed, frame) {
  if (frame !== ed.model.get("frame")) command(ed, "frame", { frame });
}

function setTool(ed, name) {
  cancelDrawing(ed);
  ed.state.tool = name;
  if (name !== "select" && ed.model.get("stage") === "transform") setStage(ed, "draw");
  updateStatus(ed);
}

function setStage(ed, name) {
  ed.model.set("stage", name);
  ed.model.save_changes();
}

// Split or Folds on or off.
function toggleLayer(ed, name) {
  ed.state[name] = !ed.state[name];
  draw(ed);
}

function toggleHandles(ed) {
  ed.state.showHandles = !ed.state.showHandles;
  updateStatus(ed);
  draw(ed);
}

// marimo renders the editor in a shadow root: a listener on the window is told the host element
// as an event's target, and document.activeElement is the host too. The node itself is the first
// of the event's composed path, and the focused one the shadow root's activeElement (in Jupyter
// both are the document's: the same as e.target and document.activeElement).
const targetOf = (e) => {
  const node = typeof e.composedPath === "function" ? e.composedPath()[0] : e.target;
  return node instanceof Node ? node : null;
};
const focusedIn = (root) => {
  const home = root.getRootNode();
  return home instanceof Document || home instanceof ShadowRoot ? home.activeElement : null;
};

// The help closes with Esc, its × or a click anywhere outside it (the click does nothing else).
function toggleHelp(ed, show = !ed.state.help) {
  const { state, ui } = ed;
  if (state.help === show) return;
  state.help = show;
  ui.helpBox.hidden = !show;
  ui.root.dataset.help = String(show);
  if (show) {
    state.closeHelp = (e) => {
      if (!ui.root.isConnected) return toggleHelp(ed, false);
      const target = targetOf(e);
      if (target && (ui.helpBox.contains(target) || ui.toolbar.querySelector('[data-action="help"]').contains(target))) return;
      toggleHelp(ed, false);
      if (target && ui.root.contains(target)) {
        e.stopPropagation(); // the click that closes the help does nothing else in the editor
        e.preventDefault();
      }
    };
    window.addEventListener("pointerdown", state.closeHelp, true);
  } else if (state.closeHelp) {
    window.removeEventListener("pointerdown", state.closeHelp, true);
    state.closeHelp = null;
  }
}

// --- the pointer -------------------------------------------------------------------------------
function wirePanes(ed) {
  for (const p of ed.ui.panes) {
    for (const [name, fn] of [["pointerdown", onDown], ["pointermove", onMove], ["pointerup", onUp]]) {
      p.canvas.addEventListener(name, (e) => {
        fn(ed, p, e);
        showCursor(ed, p, e);
      });
    }
    p.canvas.addEventListener("dblclick", (e) => {
      if (ed.state.drawing && ed.state.drawing.kind === "cage") {
        e.preventDefault();
        closeCage(ed);
      }
    });
    p.canvas.addEventListener("wheel", (e) => onWheel(ed, p, e), { passive: false });
    p.canvas.addEventListener("contextmenu", (e) => e.preventDefault());
    p.canvas.addEventListener("auxclick", (e) => e.preventDefault());
  }
}

// The cursor says what a press would do (status.js): grab a control point, move a handle by
// its arc, accept a suggestion, draw; grabbing while a drag goes on.
function showCursor(ed, p, e) {
  const { state } = ed;
  const [x, y] = pointerAt(p, e);
  const d = state.drag;
  const looking = p.kind === "result" && state.looking; // the look-around view: grab to turn it
  const at = { dragging: d ? d.type : null, tool: state.tool, pane: p.kind, space: state.space || looking, hit: null, ring: false, suggestion: false };
  if (!d && state.view && state.showHandles && !looking) {
    at.hit = hit(ed, p, x, y);
    const sel = selected(ed);
    const point = items(ed)[sel] && items(ed)[sel].kind === "point";
    at.ring = !at.hit && point && onRing(state.view, positions(ed, sel, p.kind)[0], reachOf(ed, sel), x, y);
    at.suggestion = !at.hit && p.kind === "input" && Boolean(suggestionAt(state.view, suggestions(ed), x, y));
  }
  const cursor = cursorFor(at);
  if (p.canvas.style.cursor !== cursor) p.canvas.style.cursor = cursor;
  p.canvas.dataset.cursor = cursor; // for the browser tests
}

// The pointer's position on pane p, CSS pixels from its top left corner.
function pointerAt(p, e) {
  const r = p.canvas.getBoundingClientRect();
  return [e.clientX - r.left, e.clientY - r.top];
}

// What is under (x, y) on pane p (hit.js).
function hit(ed, p, x, y) {
  const all = items(ed);
  return hitTest(ed.state.view, all, all.map((_, i) => positions(ed, i, p.kind)), x, y, selected(ed));
}

function onDown(ed, p, e) {
  const { state } = ed;
  ed.ui.root.focus({ preventScroll: true });
  if (p.kind === "result" && state.looking) {
    if (e.button === 0) startLook(ed, p, e);
    return;
  }
  if (e.button === 0 && !state.space && waitingForKernel(ed)) return;
  const [x, y] = pointerAt(p, e);
  const at = screenToLonLat(state.view, x, y);
  p.canvas.setPointerCapture(e.pointerId);
  if (e.button === 1 || state.space) {
    state.drag = { type: "pan", x, y, view: { ...state.view } };
    e.preventDefault();
    return;
  }
  if (e.button !== 0) return;
  if (p.kind === "result" && state.split && Math.abs(x - state.splitAt * p.w) < 6) {
    state.drag = { type: "split", pane: p };
    return;
  }
  if (p.kind === "input" && state.tool === "point") {
    commit(ed, addHandle(doc(ed), newPoint(at)), "click");
    select(ed, items(ed).length - 1);
    return;
  }
  if (p.kind === "input" && state.tool === "line") {
    state.drawing = { kind: "line", points: [at], cursor: at };
    draw(ed);
    return;
  }
  if (p.kind === "input" && state.tool === "cage") {
    cageClick(ed, x, y, at, e.detail >= 2);
    return;
  }
  const found = state.showHandles ? hit(ed, p, x, y) : null;
  const suggested = !found && p.kind === "input" && state.showHandles ? suggestionAt(state.view, suggestions(ed), x, y) : null;
  if (suggested) {
    command(ed, "accept_suggestion", { key: suggested.key }); // the kernel adds it as a line handle: one edit
    return;
  }
  const sel = selected(ed);
  const ringed = !found && !suggested && state.showHandles && items(ed)[sel] && items(ed)[sel].kind === "point";
  if (ringed && onRing(state.view, positions(ed, sel, p.kind)[0], reachOf(ed, sel), x, y)) {
    state.drag = { type: "reach", pane: p.kind, index: sel, centre: positions(ed, sel, p.kind)[0], reach: reachOf(ed, sel), moved: false };
    return;
  }
  if (!found) {
    select(ed, -1);
    state.drag = { type: "pan", x, y, view: { ...state.view } };
    return;
  }
  select(ed, found.index);
  const pts = positions(ed, found.index, p.kind);
  /** @type {Drag} */
  const drag = {
    type: "move",
    pane: p.kind,
    index: found.index,
    kind: items(ed)[found.index].kind,
    part: found.part,
    grab: at,
    original: pts.map((q) => [...q]),
    points: pts.map((q) => [...q]),
    moved: false,
    solved: false,
    solvedAt: "",
  };
  state.drag = drag;
  if (p.kind === "result") requestLive(ed, found.index);
}

function onMove(ed, p, e) {
  const { state } = ed;
  const [x, y] = pointerAt(p, e);
  if (p.kind === "result" && state.looking) return moveLook(ed, p, x, y);
  const at = screenToLonLat(state.view, x, y);
  state.cursor = at;
  ed.ui.cursorInfo.textContent = `lon ${at[0].toFixed(2)}°, lat ${at[1].toFixed(2)}°`;
  const d = state.drag;
  if (d && d.type === "pan") {
    state.view = panBy(d.view, x - d.x, y - d.y);
    state.fitted = false;
    draw(ed);
    return;
  }
  if (d && d.type === "split") {
    state.splitAt = Math.min(1, Math.max(0, x / p.w));
    draw(ed);
    return;
  }
  if (d && d.type === "reach") {
    d.moved = true;
    d.reach = Math.min(90, Math.max(0.5, distance(at, d.centre)));
    draw(ed);
    return;
  }
  if (d && d.type === "move") {
    d.moved = true;
    d.points = dragPoints(d, at);
    if (d.pane === "result") liveFrame(ed, d);
    draw(ed);
    return;
  }
  if (state.drawing) {
    state.drawing.cursor = at;
    draw(ed);
    return;
  }
  hover(ed, p, x, y);
}

// Over a line the kernel keeps as it is, the canvas's tooltip gives the warnings naming it.
function hover(ed, p, x, y) {
  const { state } = ed;
  if (p.kind === "result" && state.showHandles) {
    const near = hit(ed, p, x, y); // about to be dragged, perhaps: have the live basis ready
    if (near) requestLive(ed, near.index);
  }
  const all = items(ed);
  const kept = state.showHandles ? status(ed).kept || [] : [];
  const i = kept.find((j) => j < all.length && onCurve(state.view, all[j], positions(ed, j, p.kind), x, y));
  let title = i === undefined ? "" : (status(ed).warnings || []).filter((w) => w.includes(`handles[${i}]`)).join("\n");
  const suggested = !title && p.kind === "input" && state.showHandles ? suggestionAt(state.view, suggestions(ed), x, y) : null;
  if (suggested) title = `suggested line, ${(suggested.length || 0).toFixed(0)}° long, confidence ${(suggested.confidence || 0).toFixed(2)}: click to add it`;
  if (p.canvas.title !== title) p.canvas.title = title;
}

function onUp(ed, p, e) {
  const { state } = ed;
  if (p.canvas.hasPointerCapture(e.pointerId)) p.canvas.releasePointerCapture(e.pointerId);
  const d = state.drag;
  state.drag = null;
  if (state.drawing && state.drawing.kind === "line" && e.button === 0) {
    const [x, y] = pointerAt(p, e);
    finishLine(ed, screenToLonLat(state.view, x, y));
    return;
  }
  if (d && d.type === "reach" && d.moved) {
    commit(ed, setReach(doc(ed), d.index, d.reach)); // one edit: the kernel's undo brings the old reach back
    draw(ed);
    return;
  }
  if (!d || d.type !== "move" || !d.moved) {
    draw(ed);
    return;
  }
  finishMove(ed, d);
}

function finishLine(ed, end) {
  const [start] = ed.state.drawing.points;
  ed.state.drawing = null;
  const line = newLine(start, end);
  if (line) {
    commit(ed, addHandle(doc(ed), line));
    select(ed, items(ed).length - 1);
  }
  draw(ed);
}

function finishMove(ed, d) {
  if (d.pane === "input") {
    commit(ed, moveOnInput(doc(ed), d.index, d.points));
    return;
  }
  const { state } = ed;
  state.localOutputs = JSON.parse(JSON.stringify(outputs(ed)));
  state.localOutputs[d.index] = d.points;
  if (d.kind === "point" && d.part > 0) {
    command(ed, "arrow", { index: d.index, which: d.part === 1 ? "east" : "west", tip: d.points[d.part] });
    return;
  }
  // an unchanged document after solves of the drag's way: the result of the handles as they are
  if (!commit(ed, moveOnResult(doc(ed), d.index, d.part, d.points)) && d.solved) command(ed, "refresh");
}

function cageClick(ed, x, y, at, double) {
  const { state } = ed;
  const dr = state.drawing;
  if (!dr) {
    state.drawing = { kind: "cage", points: [at], cursor: at };
    draw(ed);
    return;
  }
  if (double || pointDistance(state.view, dr.points[0], x, y) <= HIT) {
    closeCage(ed); // on the first vertex
    return;
  }
  dr.points.push(at);
  draw(ed);
}

function closeCage(ed, cause = "click") {
  const dr = ed.state.drawing;
  if (!dr || dr.kind !== "cage") return;
  ed.state.drawing = null;
  const cage = newCage(dr.points);
  if (cage) {
    commit(ed, addHandle(doc(ed), cage), cause);
    select(ed, items(ed).length - 1);
  } else showLocal(ed, "a cage needs at least three vertices");
  draw(ed);
}

function cancelDrawing(ed) {
  if (ed.state.drawing) {
    ed.state.drawing = null;
    draw(ed);
  }
}

function onWheel(ed, p, e) {
  e.preventDefault();
  if (p.kind === "result" && ed.state.looking) {
    ed.state.look = zoomLook(ed.state.look, e.deltaY);
    draw(ed);
    return;
  }
  const [x, y] = pointerAt(p, e);
  ed.state.view = zoomAt(ed.state.view, x, y, e.deltaY, p.w, p.h);
  ed.state.fitted = false;
  draw(ed);
}

// --- the keyboard -------------------------------------------------------------------------------
// JupyterLab and Notebook 7 take keys from one keydown listener on the document, bubbling in
// JupyterLab (after the editor's), capturing in Notebook 7 (before it): stopping a key here
// cannot keep it from Notebook 7. What keeps the notebook's command-mode keys ("d d" deletes
// a cell, "a" inserts one, "z" undoes cell operations) off the keys typed here, in both, is
// data-lm-suppress-shortcuts: Lumino's CommandRegistry walks up from the key's target to the
// element a binding's selector names and drops the binding if it meets the attribute first.
// The command-mode bindings name ".jp-Notebook.jp-mod-commandMode :focus", the focused
// element itself, so the target (the root, or a toolbar button) carries it, not only the
// root: a capturing listener on the window, which runs before the document's in either
// phase, puts it on both (it listens only while the editor has the focus). The keys that
// should reach the notebook (save, run the cell) go with the attribute off both for the event.
const SUPPRESS = "data-lm-suppress-shortcuts";
const passesToJupyter = (e) =>
  (e.key === "Enter" && (e.shiftKey || e.ctrlKey || e.metaKey || e.altKey)) || // run the cell
  ((e.ctrlKey || e.metaKey) && !e.altKey && !e.shiftKey && (e.key === "s" || e.key === "S")); // save

function wireFocus(ed) {
  const { root } = ed.ui;
  function onWindowKeydown(e) {
    if (!root.isConnected) return listenToWindow(false);
    const target = targetOf(e);
    if (!(target instanceof Element && root.contains(target))) return;
    const holders = [root, target];
    if (passesToJupyter(e)) {
      for (const node of holders) node.removeAttribute(SUPPRESS);
      setTimeout(() => holders.forEach((node) => node.setAttribute(SUPPRESS, "true"))); // after the document's listener
    } else for (const node of holders) node.setAttribute(SUPPRESS, "true");
  }
  // A click outside the editor takes the keyboard from it: JupyterLab would leave the focus
  // here after a click on the cell's prompt (the editor is inside the cell it makes active).
  function onWindowPointerdown(e) {
    if (!root.isConnected) return listenToWindow(false);
    const focused = focusedIn(root);
    const target = targetOf(e);
    if (target && !root.contains(target) && focused && root.contains(focused)) focused.blur();
  }
  function listenToWindow(on) {
    const method = on ? "addEventListener" : "removeEventListener";
    window[method]("keydown", onWindowKeydown, true);
    window[method]("pointerdown", onWindowPointerdown, true);
  }
  root.addEventListener("focusin", () => listenToWindow(true));
  root.addEventListener("focusout", (e) => {
    if (e.relatedTarget instanceof Node && root.contains(e.relatedTarget)) return; // still in the editor
    listenToWindow(false);
    ed.state.space = false; // its keyup goes elsewhere
  });
}

function wireKeys(ed) {
  ed.ui.root.addEventListener("keydown", (e) => onKey(ed, e));
  ed.ui.root.addEventListener("keyup", (e) => {
    if (e.key === " ") {
      ed.state.space = false;
      e.stopPropagation();
    }
  });
}

function onKey(ed, e) {
  if (passesToJupyter(e)) return; // on to JupyterLab's listener on the document
  const key = e.key;
  const mod = e.ctrlKey || e.metaKey;
  let used = true;
  if (mod && !e.altKey && (key === "z" || key === "Z")) command(ed, e.shiftKey ? "redo" : "undo", {}, "key");
  else if (mod && !e.altKey && (key === "y" || key === "Y")) command(ed, "redo", {}, "key");
  else if (mod || e.altKey) used = false;
  else if (key === " ") ed.state.space = true;
  else if (key === "Escape") escape(ed);
  else if (key === "Enter") closeCage(ed, "key");
  else if (key === "Delete" || key === "Backspace") deleteSelected(ed, "key");
  else if (key === "f" || key === "F") fit(ed);
  else if (key === "?") toggleHelp(ed);
  else if (key === "h" || key === "H") toggleHandles(ed);
  else if (key === "a" || key === "A") command(ed, "rectify_all", {}, "key");
  else if (key === "s" || key === "S") commandSelected(ed, "rectify_line", "key");
  else if (key === "r" || key === "R") commandSelected(ed, "reset", "key");
  else {
    const tool = TOOLS.find(([, , k]) => k.toLowerCase() === key.toLowerCase());
    const stage = STAGES.find(([, , k]) => k.toLowerCase() === key.toLowerCase());
    if (tool) keyTool(ed, tool);
    else if (stage) keyStage(ed, stage);
    else used = false;
  }
  if (used) {
    e.preventDefault();
    e.stopPropagation();
  }
}

// Esc with nothing to cancel gives the keyboard back to the notebook, as Esc in a cell's
// editor does: the focus goes to the cell, which puts the notebook in command mode.
function escape(ed) {
  const { state } = ed;
  const d = state.drag;
  if (!d && !state.drawing && !state.help) return suggestions(ed).length ? command(ed, "drop_suggestions") : releaseFocus(ed);
  if (d) {
    state.drag = null;
    if (d.type === "pan") state.view = d.view; // back where the drag started
    if (d.type === "move") state.liveShown = false; // the kernel's result again, not the dropped drag's live frame
  }
  cancelDrawing(ed);
  if (state.help) toggleHelp(ed);
  draw(ed);
}

function releaseFocus(ed) {
  const { root } = ed.ui;
  const home = root.closest(".jp-Cell") || (root.parentElement && root.parentElement.closest("[tabindex]"));
  const focused = focusedIn(root);
  if (focused && root.contains(focused)) focused.blur();
  if (home) home.focus({ preventScroll: true });
}

// Tools and stages switched by a key are named in the status bar, as their buttons' titles
// name them.
function keyTool(ed, [name, label, key, what]) {
  const stage = ed.model.get("stage");
  setTool(ed, name);
  const moved = ed.model.get("stage") !== stage ? ` · stage ${STAGES[0][1]} (${STAGES[0][2]})` : "";
  showLocal(ed, `tool ${label} (${key}): ${what}${moved}`);
}

function keyStage(ed, [name, label, key, what]) {
  setStage(ed, name);
  const others = STAGES.filter((s) => s[0] !== name).map(([, l, k]) => `${k} ${l.toLowerCase()}`);
  showLocal(ed, `stage ${label} (${key}): ${what} · ${others.join(", ")}`);
}

export default { render };
