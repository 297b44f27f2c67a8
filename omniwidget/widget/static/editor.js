// omniwidget editor: the front end of omniwidget.widget.Editor, a plain ES module that
// anywidget loads as it is (no build step).
//
// Everything the browser tells the kernel is in [lon, lat] degrees, the conventions of
// omniwidget/core/coords.py: longitude in [-180, 180) growing to the right, latitude in
// [-90, 90] growing upwards, unit vector (cos lat cos lon, cos lat sin lon, sin lat),
// east (-sin lon, cos lon, 0). On screen the panorama's width is `k` CSS pixels and its
// left edge (lon = -180) is at `tx`; it repeats every `k` pixels, so handles and drags
// wrap across the ±180° seam.
//
// Drags happen here at display frame rate; only their end reaches the kernel, as a new
// handles document or a command ({op: ...}) the kernel applies (undo, rectify, arrows).
// While a control point is dragged on the result, the result follows it live (live.js):
// the kernel sends the dragged handle's share of eq. (2) once, the GPU redoes the sum each
// frame with the handle's maps rebuilt here (moebius.js), and the kernel's exact result
// replaces the live frame once it arrives.

import { arrowTip, dragMaps, inverse } from "./moebius.js";
import { createLive, MOVING_PIXELS } from "./live.js";

const DEG = Math.PI / 180;
const LIVE_REST_MS = 120; // the mouse this long at rest: the live frame is drawn in full
const ARROW_LENGTH = 0.3; // radians from a point's centre to its arrow tips (handles.ARROW_LENGTH)
const HIT = 9; // px: how close a click must be to a control point
const HIT_EDGE = 6; // px: ... to a line or cage edge
const MIN_LINE = 0.05; // degrees: shorter drags do not make a line
const COLORS = { point: "#22c7ff", line: "#ff453a", cage: "#ffffff", selected: "#ffd60a", conflict: "#ff9f0a", kept: "#30d158" };
const DASHES = { conflict: [6, 4], kept: [10, 4, 2, 4] }; // a line kept as it is (over a pole): dash-dot
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
  ["Esc", "cancel the handle being drawn, the drag in progress or this help; else back to the notebook"],
  ["wheel", "zoom about the cursor"],
  ["Space + drag, middle drag", "pan (wraps across the ±180° seam)"],
  ["F", "fit the panorama to the view"],
  ["H", "show or hide the handles"],
  ["A / S / R", "rectify all lines / rectify the selected line / reset the selected handle"],
  ["?", "this help"],
  ["Ctrl+S", "save the notebook (passed on to JupyterLab)"],
  ["Shift+Enter / Ctrl+Enter / Alt+Enter", "run the cell and select the next / run it / run it, insert a cell (passed on to JupyterLab)"],
];

// --- the sphere (mirrors omniwidget/core/coords.py) ------------------------------------
const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const scaled = (a, s) => [a[0] * s, a[1] * s, a[2] * s];
const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
const norm = (a) => Math.hypot(a[0], a[1], a[2]);
const unit = (a) => scaled(a, 1 / (norm(a) || 1));
const clamp = (x, lo, hi) => Math.min(hi, Math.max(lo, x));

function toXYZ([lon, lat]) {
  const c = Math.cos(lat * DEG);
  return [c * Math.cos(lon * DEG), c * Math.sin(lon * DEG), Math.sin(lat * DEG)];
}

function toLonLat(p) {
  const [x, y, z] = unit(p);
  const lon = Math.atan2(y, x) / DEG;
  return [lon >= 180 ? lon - 360 : lon, Math.asin(clamp(z, -1, 1)) / DEG];
}

function wrapLon(lon) {
  return ((((lon + 180) % 360) + 360) % 360) - 180;
}

function angle(a, b) {
  return Math.atan2(norm(cross(a, b)), dot(a, b));
}

// The point `angle` radians from `lonlat` heading east (sign +1) or west (-1): handles._exp.
function alongEast(lonlat, sign, ang) {
  const p = toXYZ(lonlat);
  const east = [-Math.sin(lonlat[0] * DEG), Math.cos(lonlat[0] * DEG), 0];
  return toLonLat(add(scaled(p, Math.cos(ang)), scaled(east, sign * Math.sin(ang))));
}

// Rotate v about the unit axis by `ang` radians (Rodrigues).
function rotate(v, axis, ang) {
  const c = Math.cos(ang);
  const s = Math.sin(ang);
  return add(add(scaled(v, c), scaled(cross(axis, v), s)), scaled(axis, dot(axis, v) * (1 - c)));
}

// The rotation that carries `from` to `to` along their great circle, applied to [lon, lat] points.
function carry(points, from, to) {
  const a = toXYZ(from);
  const b = toXYZ(to);
  const axis = cross(a, b);
  const n = norm(axis);
  if (n < 1e-12) return points.map((p) => [...p]);
  const ang = Math.atan2(n, dot(a, b));
  return points.map((p) => toLonLat(rotate(toXYZ(p), scaled(axis, 1 / n), ang)));
}

// Samples of the circle through three points of the sphere, from a through b to c: a
// geodesic when b is its midpoint, and a line's output (a Möbius image of a great circle).
function circleArc(a, b, c) {
  const [pa, pb, pc] = [toXYZ(a), toXYZ(b), toXYZ(c)];
  const n = cross(sub(pb, pa), sub(pc, pa));
  if (norm(n) < 1e-12) return [a, b, c];
  const nu = unit(n);
  const o = scaled(nu, dot(pa, nu));
  const ra = sub(pa, o);
  const r = norm(ra);
  const e1 = scaled(ra, 1 / r);
  const e2 = cross(nu, e1);
  const at = (p) => {
    const t = Math.atan2(dot(sub(p, o), e2), dot(sub(p, o), e1));
    return t < 0 ? t + 2 * Math.PI : t;
  };
  const tb = at(pb);
  let tc = at(pc);
  if (tb > tc) tc -= 2 * Math.PI; // go the other way round, still through b
  const steps = Math.max(2, Math.ceil((Math.abs(tc) * r) / (0.75 * DEG)));
  const out = [];
  for (let i = 0; i <= steps; i++) {
    const t = (tc * i) / steps;
    out.push(toLonLat(add(o, add(scaled(e1, r * Math.cos(t)), scaled(e2, r * Math.sin(t))))));
  }
  return out;
}

function geodesic(a, b) {
  const pa = toXYZ(a);
  const pb = toXYZ(b);
  return circleArc(a, toLonLat(add(pa, pb)), b);
}

const copy = (value) => JSON.parse(JSON.stringify(value));

// --- the handles' control points -------------------------------------------------------
// Input positions (draw stage) come from the document; output positions from the kernel
// (`outputs`, one list per handle), overridden locally while a drag is in progress.
function inputPoints(h) {
  if (h.kind === "point") return [h.position, alongEast(h.position, 1, ARROW_LENGTH), alongEast(h.position, -1, ARROW_LENGTH)];
  if (h.kind === "line") return [h.start, toLonLat(add(toXYZ(h.start), toXYZ(h.end))), h.end];
  return h.vertices;
}

function curves(h, pts) {
  // Great-circle arcs (curved on the panorama) to draw for a handle whose control points are `pts`.
  if (h.kind === "point") return [geodesic(pts[0], pts[1]), geodesic(pts[0], pts[2])];
  if (h.kind === "line") return [circleArc(pts[0], pts[1], pts[2])];
  return pts.map((p, i) => geodesic(p, pts[(i + 1) % pts.length]));
}

// --- the widget ---------------------------------------------------------------------------
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

async function decode(view, type) {
  if (!view || view.byteLength === 0) return null;
  return createImageBitmap(new Blob([view], { type }));
}

function render({ model, el: host }) {
  const state = {
    tool: "select",
    view: null, // {k, tx, ty}
    source: null,
    preview: null,
    folds: null,
    showFolds: true,
    showHandles: true,
    split: false,
    splitAt: 0.5,
    drag: null, // a drag in progress
    drawing: null, // a line or cage being drawn
    localOutputs: null, // outputs as the last drag left them, until the kernel's arrive
    space: false,
    help: false,
    released: null, // performance.now() of the last edit, for the latency figure
    cursor: null,
    liveWanted: "", // "generation:index" of the live basis last asked for
    liveBasis: null, // the header of the basis the GPU holds: {index, generation, controls, carry, ...}
    liveMaps: null, // the dragged handle's inverse maps, to render at the next frame
    liveShown: false, // the result pane shows the live frame (until the kernel's result arrives)
    liveDrawn: null, // the basis header of the live frame drawn, and its step
    dragSolve: 0, // performance.now() of the drag's solve on its way, 0 if none
    liveLast: null, // the maps of the last live frame drawn
    liveFine: false, // the next live frame in full (the mouse rests), not from every second pixel
    liveRest: 0, // the timer that draws it
  };

  const root = el("div", {
    class: "ow-editor",
    tabindex: "0",
    // JupyterLab's key bindings ignore keys typed in here (Lumino's CommandRegistry stops at
    // this attribute), but for the few the keyboard section hands on to it (Ctrl+S, Shift+Enter...)
    "data-lm-suppress-shortcuts": "true",
    "data-busy": "false",
    "data-generation": "0",
  });
  const toolbar = el("div", { class: "ow-toolbar" });
  const stageGroup = el("div", { class: "ow-group" });
  for (const [name, label, key, what] of STAGES) {
    stageGroup.append(el("button", { "data-stage": name, title: `${label} (${key}): ${what}`, onclick: () => setStage(name) }, label));
  }
  const toolGroup = el("div", { class: "ow-group" });
  for (const [name, label, key, what] of TOOLS) {
    toolGroup.append(el("button", { "data-tool": name, title: `${label} (${key}): ${what}`, onclick: () => setTool(name) }, label));
  }
  const button = (action, label, title, onclick) => el("button", { "data-action": action, title, onclick }, label);
  const editGroup = el(
    "div",
    { class: "ow-group" },
    button("undo", "Undo", "Undo (Ctrl+Z)", () => command("undo")),
    button("redo", "Redo", "Redo (Ctrl+Shift+Z)", () => command("redo")),
    button("delete", "Delete", "Delete the selected handle (Delete)", () => deleteSelected()),
  );
  const solveGroup = el(
    "div",
    { class: "ow-group" },
    button("rectify-all", "Rectify all lines", "Straighten every line together (A)", () => command("rectify_all")),
    button("rectify-line", "Rectify selected line", "Straighten the selected line, hold the rest (S)", () =>
      commandSelected("rectify_line"),
    ),
    button("reset", "Reset selected", "Undo the selected handle's transformation (R)", () => commandSelected("reset")),
  );
  const fileInput = el("input", { type: "file", accept: ".json,application/json", style: "display:none" });
  const viewGroup = el(
    "div",
    { class: "ow-group" },
    button("fit", "Fit", "Fit the panorama to the view (F)", () => fit()),
    button("split", "Split", "Compare: the input left of a slider, the result right of it", () => {
      state.split = !state.split;
      draw();
    }),
    button("folds", "Folds", "Show where the result folds over", () => {
      state.showFolds = !state.showFolds;
      draw();
    }),
    button("handles", "Handles", "Show or hide the handles (H)", () => toggleHandles()),
  );
  const fileGroup = el(
    "div",
    { class: "ow-group" },
    button("save", "Save", "Write the handles file next to the notebook", () => command("save")),
    button("download", "Download", "Download the handles file", () => download()),
    button("load", "Load", "Load a handles file", () => fileInput.click()),
    button("full", "Full size", "Compute the result at the panorama's full size", () => command("full")),
    button(
      "save-image",
      "Save image",
      "Write the full-size result next to the panorama (room.jpg: room-rectified.jpg) and download it",
      () => command("save_image"),
    ),
    button("help", "?", "Keyboard shortcuts (?)", () => toggleHelp()),
    fileInput,
  );
  const spinner = el("span", { class: "ow-spinner", title: "computing" });
  toolbar.append(stageGroup, toolGroup, editGroup, solveGroup, viewGroup, fileGroup, spinner);

  const panesBox = el("div", { class: "ow-panes" });
  const panes = ["input", "result"].map((kind) => {
    const canvas = el("canvas", { class: "ow-canvas", "data-pane": kind });
    const label = el("div", { class: "ow-pane-label" }, kind === "input" ? "input: draw handles" : "result: move control points");
    const box = el("div", { class: "ow-pane", "data-pane": kind }, canvas, label);
    return { kind, canvas, box, ctx: canvas.getContext("2d"), w: 0, h: 0 };
  });
  panesBox.append(...panes.map((p) => p.box));
  const message = el("div", { class: "ow-message" });
  const cursorInfo = el("span", { class: "ow-cursor" });
  const statusBar = el("div", { class: "ow-status" }, message, cursorInfo);
  const helpBox = el(
    "div",
    { class: "ow-help", hidden: "" },
    el("h3", {}, "Keyboard and mouse"),
    el("table", {}, ...SHORTCUTS.map(([k, what]) => el("tr", {}, el("th", {}, k), el("td", {}, what)))),
    el("p", {}, "Positions are [lon, lat] in degrees whatever the zoom. Draw on the input; move control points on the result."),
    el(
      "p",
      {},
      "While the editor has the keyboard, other keys do nothing (none reaches the notebook's command mode: 'd d' deletes no cell); " +
        "Esc or a click outside the editor gives it back to the notebook.",
    ),
  );
  root.append(toolbar, panesBox, statusBar, helpBox);
  host.append(root);

  // --- the live result while dragging (live.js) -----------------------------------------------
  const liveCanvas = el("canvas", { class: "ow-live", hidden: "" });
  root.append(liveCanvas);
  let live = null;
  try {
    live = createLive(liveCanvas);
  } catch (err) {
    console.warn("omniwidget: the result will not follow drags live:", err);
  }
  root.dataset.live = live ? "ready" : "off";
  root.dataset.liveFrames = "0";

  // Ask the kernel for the basis of a live drag of handle i, once per result on screen.
  function requestLive(i) {
    const want = `${status().generation}:${i}`;
    if (!live || i < 0 || state.liveWanted === want) return;
    state.liveWanted = want;
    model.send({ op: "live", index: i });
  }

  function onLiveBasis(content, buffer) {
    if (!live || content.generation !== status().generation || !live.setBasis(content, buffer)) return; // a newer result is on screen
    state.liveBasis = content;
    root.dataset.liveBasis = `${content.generation}:${content.index}`;
    root.dataset.liveRegion = JSON.stringify({ origin: content.origin, width: content.width, height: content.height, size: content.size });
    const d = state.drag;
    if (d && d.type === "move" && d.pane === "result" && d.moved) liveFrame(d);
  }

  // The live result of the drag d, rendered at the next frame when its basis is there.
  function liveFrame(d) {
    const b = state.liveBasis;
    if (!b || b.generation !== status().generation) requestLive(d.index); // a newer solve's basis: asked for, the last one drawn meanwhile
    if (!b || b.index !== d.index) return;
    let maps;
    try {
      maps = dragMaps(items()[d.index], d.points, d.part, b.carry);
    } catch (err) {
      return; // control points on top of each other: no map, the last frame stays
    }
    if (maps.length === 1 && b.controls > 1) maps = Array(b.controls).fill(maps[0]); // a line's pieces share its map
    if (maps.length !== b.controls) return;
    state.liveMaps = maps.map(inverse);
    state.liveFine = false;
    clearTimeout(state.liveRest);
    state.liveRest = setTimeout(() => {
      if (state.drag === d) solveDuringDrag(d); // the mouse rests: the kernel's turn
      if (!state.liveShown) return; // the kernel's result came first
      state.liveMaps = state.liveLast;
      state.liveFine = true; // every pixel of the region
      draw();
    }, LIVE_REST_MS);
    draw();
  }

  // --- model access ----------------------------------------------------------------------
  const doc = () => model.get("handles") || { handles: [] };
  const items = () => doc().handles || [];
  const outputs = () => state.localOutputs || model.get("outputs") || [];
  const selected = () => model.get("selected");
  const status = () => model.get("status") || {};

  // A command the kernel is still applying may change the handles (undo, rectify, load, ...):
  // an edit made meanwhile would start from the handles before it and undo it, so none starts
  // until the kernel says the command is done ("done" message, sent after any change of the handles).
  const CHANGES_HANDLES = new Set(["undo", "redo", "rectify_all", "rectify_line", "reset", "arrow", "load"]);
  let pendingSince = 0; // performance.now() of the oldest command not yet done, 0 if none
  let pendingCount = 0;
  function setPending(n) {
    pendingCount = n;
    root.dataset.pending = String(n); // for a glance in the inspector (and the real-browser tests)
  }
  function waitingForKernel() {
    if (pendingCount > 0 && performance.now() - pendingSince > 10000) setPending(0); // a kernel that never answers
    if (pendingCount === 0) return false;
    showLocal("one moment: the kernel is applying the last command");
    return true;
  }

  function commit(handles) {
    if (waitingForKernel()) return false;
    const next = { ...doc(), handles };
    if (JSON.stringify(next) === JSON.stringify(doc())) return false;
    state.released = performance.now();
    model.set("handles", next);
    model.save_changes();
    return true;
  }

  function command(op, content = {}) {
    if (op !== "save") state.released = performance.now(); // every other command changes the result
    if (CHANGES_HANDLES.has(op)) {
      if (pendingCount === 0) pendingSince = performance.now();
      setPending(pendingCount + 1);
    }
    model.send({ op, ...content });
  }
  function onMessage(content, buffers) {
    if (content && content.op === "live" && buffers && buffers.length) {
      onLiveBasis(content, buffers[0]);
      return;
    }
    if (content && content.op === "image_file" && buffers && buffers.length) {
      downloadImage(content, buffers[0]);
      return;
    }
    if (content && content.done !== undefined && CHANGES_HANDLES.has(content.done) && pendingCount > 0) {
      setPending(pendingCount - 1);
      if (pendingCount === 0 && localNote.startsWith("one moment")) showLocal("");
    }
  }

  function commandSelected(op) {
    const i = selected();
    if (i < 0 || i >= items().length) return showLocal("select a handle first");
    if (op === "rectify_line" && items()[i].kind !== "line") return showLocal("the selected handle is not a line");
    command(op, { index: i });
  }

  function select(i) {
    if (selected() !== i) {
      model.set("selected", i);
      model.save_changes();
    }
  }

  function deleteSelected() {
    const i = selected();
    if (i < 0 || i >= items().length) return;
    const next = items().filter((_, j) => j !== i);
    model.set("selected", -1);
    commit(next);
  }

  function download() {
    const blob = new Blob([JSON.stringify(doc(), null, 2) + "\n"], { type: "application/json" });
    const a = el("a", { href: URL.createObjectURL(blob), download: "handles.json" });
    a.click();
    setTimeout(() => URL.revokeObjectURL(a.href), 1000);
  }

  // The full-size result Save image wrote, sent by the kernel: offered as a download too.
  function downloadImage(content, buffer) {
    const blob = new Blob([buffer], { type: content.mime || "application/octet-stream" });
    const a = el("a", { href: URL.createObjectURL(blob), download: content.name || "panorama-rectified.png" });
    root.append(a); // some browsers click only links in the document
    a.click();
    a.remove();
    root.dataset.savedImage = content.name || "";
    setTimeout(() => URL.revokeObjectURL(a.href), 10000);
  }

  fileInput.addEventListener("change", async () => {
    const file = fileInput.files && fileInput.files[0];
    if (!file) return;
    command("load", { name: file.name, text: await file.text() });
    fileInput.value = "";
  });

  let localNote = "";
  function showLocal(text) {
    localNote = text;
    updateStatus();
  }

  // --- layout and view --------------------------------------------------------------------
  const visible = () => panes.filter((p) => model.get("stage") === "side" || (p.kind === "input") === (model.get("stage") === "draw"));

  function layout() {
    const shown = visible();
    for (const p of panes) p.box.hidden = !shown.includes(p);
    const width = Math.max(200, panesBox.clientWidth || root.clientWidth || 800);
    const height = model.get("height");
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
    if (!state.view || state.fitted) fit();
    else draw();
  }

  function fit() {
    const p = visible()[0];
    const k = Math.min(p.w || 800, 2 * (p.h || 400));
    state.view = { k, tx: ((p.w || 800) - k) / 2, ty: ((p.h || 400) - k / 2) / 2 };
    state.fitted = true;
    draw();
  }

  const toScreen = ([lon, lat]) => {
    const { k, tx, ty } = state.view;
    return [tx + ((lon + 180) / 360) * k, ty + ((90 - lat) / 180) * (k / 2)];
  };

  function toLonLatAt(x, y) {
    const { k, tx, ty } = state.view;
    return [wrapLon(((x - tx) / k) * 360 - 180), clamp(90 - ((y - ty) / (k / 2)) * 180, -90, 90)];
  }

  // Screen x of `lonlat` in the copy of the panorama nearest to screen x `near`.
  function nearestX(x, near) {
    const k = state.view.k;
    return x + Math.round((near - x) / k) * k;
  }

  function copies(p) {
    const { k, tx } = state.view;
    const out = [];
    for (let j = Math.floor(-tx / k); j <= Math.floor((p.w - tx) / k); j++) out.push(j * k);
    return out;
  }

  // --- drawing ----------------------------------------------------------------------------
  function positions(i, kind) {
    if (kind === "input") {
      if (state.drag && state.drag.pane === "input" && state.drag.index === i) return state.drag.points;
      return inputPoints(items()[i]);
    }
    if (state.drag && state.drag.pane === "result" && state.drag.index === i) return state.drag.points;
    return outputs()[i] || inputPoints(items()[i]);
  }

  function strokePath(p, lonlats, offsets) {
    if (lonlats.length < 2) return;
    const pts = lonlats.map(toScreen);
    for (let i = 1; i < pts.length; i++) pts[i][0] = nearestX(pts[i][0], pts[i - 1][0]); // continuous across the seam
    const ctx = p.ctx;
    for (const dx of offsets) {
      ctx.beginPath();
      ctx.moveTo(pts[0][0] + dx, pts[0][1]);
      for (let i = 1; i < pts.length; i++) ctx.lineTo(pts[i][0] + dx, pts[i][1]);
      ctx.stroke();
    }
  }

  function dotAt(p, lonlat, offsets, radius, fill, shape = "circle") {
    const [x, y] = toScreen(lonlat);
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

  function drawImageCopies(p, image, offsets) {
    const { k, ty } = state.view;
    const tx = state.view.tx;
    for (const dx of offsets) p.ctx.drawImage(image, tx + dx, ty, k, k / 2);
  }

  // The live frame over the result, where the dragged handle weighs (its region wraps across the seam).
  function drawLive(p, offsets) {
    const { k, tx, ty } = state.view;
    const { origin, size, step } = state.liveDrawn;
    const scale = k / size;
    const [w, h] = [liveCanvas.width * step * scale, liveCanvas.height * step * scale];
    for (const dx of [offsets[0] - k, ...offsets]) p.ctx.drawImage(liveCanvas, tx + dx + origin[1] * scale, ty + origin[0] * scale, w, h);
  }

  function drawPane(p) {
    const ctx = p.ctx;
    ctx.save();
    ctx.fillStyle = "#1e1e1e";
    ctx.fillRect(0, 0, p.w, p.h);
    const offsets = copies(p);
    const image = p.kind === "input" ? state.source : state.preview || state.source;
    if (image) drawImageCopies(p, image, offsets);
    if (p.kind === "result" && state.liveShown) drawLive(p, offsets);
    if (p.kind === "result" && state.split && state.source) {
      const at = state.splitAt * p.w;
      ctx.save();
      ctx.beginPath();
      ctx.rect(0, 0, at, p.h);
      ctx.clip();
      drawImageCopies(p, state.source, offsets);
      ctx.restore();
      ctx.strokeStyle = "#ffd60a";
      ctx.lineWidth = 2;
      ctx.beginPath();
      ctx.moveTo(at, 0);
      ctx.lineTo(at, p.h);
      ctx.stroke();
    }
    if (p.kind === "result" && state.showFolds && state.folds) drawImageCopies(p, state.folds, offsets);
    ctx.strokeStyle = "rgba(255, 255, 255, 0.5)"; // the ±180° seam between copies of the panorama
    ctx.lineWidth = 1;
    ctx.setLineDash([2, 4]);
    for (const dx of offsets) {
      ctx.beginPath();
      ctx.moveTo(state.view.tx + dx, state.view.ty);
      ctx.lineTo(state.view.tx + dx, state.view.ty + state.view.k / 2);
      ctx.stroke();
    }
    ctx.setLineDash([]);
    if (state.showHandles) drawHandles(p, offsets);
    ctx.restore();
    const { k, tx, ty } = state.view;
    p.canvas.dataset.view = JSON.stringify({ x0: tx, y0: ty, w: k, h: k / 2 });
  }

  function drawHandles(p, offsets) {
    const ctx = p.ctx;
    const conflicts = new Set(status().conflicts || []);
    const kept = new Set(status().kept || []);
    const sel = selected();
    items().forEach((h, i) => {
      const pts = positions(i, p.kind);
      const isSel = i === sel;
      const look = conflicts.has(i) ? "conflict" : kept.has(i) ? "kept" : null;
      ctx.lineWidth = isSel ? 3 : 2;
      ctx.strokeStyle = look ? COLORS[look] : COLORS[h.kind];
      ctx.setLineDash(look ? DASHES[look] : []);
      for (const c of curves(h, pts)) strokePath(p, c, offsets);
      ctx.setLineDash([]);
      ctx.lineWidth = 1.5;
      ctx.strokeStyle = "#000";
      const fill = isSel ? COLORS.selected : COLORS[h.kind];
      pts.forEach((q, j) => {
        const tip = h.kind === "point" && j > 0;
        dotAt(p, q, offsets, tip ? 4 : 5, fill, tip ? "square" : "circle");
      });
    });
    if (state.drawing && p.kind === "input") {
      ctx.strokeStyle = COLORS.selected;
      ctx.lineWidth = 2;
      ctx.setLineDash([5, 4]);
      const pts = state.drawing.points;
      const ends = state.drawing.cursor ? [...pts, state.drawing.cursor] : pts;
      for (let i = 1; i < ends.length; i++) strokePath(p, geodesic(ends[i - 1], ends[i]), offsets);
      ctx.setLineDash([]);
      ctx.strokeStyle = "#000";
      pts.forEach((q) => dotAt(p, q, offsets, 5, COLORS.selected));
    }
  }

  let frame = 0;
  function draw() {
    if (frame) return;
    frame = requestAnimationFrame(() => {
      frame = 0;
      if (!state.view) return;
      const started = performance.now();
      const rendered = state.liveMaps && live.render(state.liveMaps, state.liveFine ? Infinity : MOVING_PIXELS);
      if (rendered) [state.liveShown, state.liveLast, state.liveDrawn] = [true, state.liveMaps, { ...state.liveBasis, step: rendered }];
      state.liveMaps = null;
      for (const p of visible()) drawPane(p);
      if (rendered) {
        root.dataset.liveFrames = String(Number(root.dataset.liveFrames) + 1);
        root.dataset.liveMs = (performance.now() - started).toFixed(1); // the frame's cost, for bench/bench_live.py
        root.dataset.liveStep = String(rendered);
      }
    });
  }

  function updateStatus() {
    const s = status();
    const busy = s.state === "busy";
    root.dataset.busy = String(busy);
    root.dataset.state = s.state || "";
    spinner.hidden = !busy;
    const parts = [];
    if (busy) parts.push("computing...");
    else if (s.state === "idle" && s.message) parts.push(`result ${s.message}`);
    if (s.error) parts.push(s.error);
    if (s.notice) parts.push(s.notice);
    if (state.latency !== undefined && s.state === "idle") parts.push(`shown ${state.latency.toFixed(0)} ms after the edit`);
    if (s.fold_area > 0) parts.push(`fold-over ${(100 * s.fold_area).toPrecision(2)}% of the sphere (magenta)`);
    if (localNote) parts.push(localNote);
    message.textContent = parts.join(" · ");
    message.classList.toggle("ow-error", Boolean(s.error));
    message.title = (s.warnings || []).join("\n");
    if (s.quality && s.state === "idle") message.append(el("div", { class: "ow-quality" }, s.quality));
    for (const w of s.warnings || []) {
      message.append(el("div", { class: "ow-warning" }, `⚠ ${w}`));
    }
    const history = model.get("history") || {};
    toolbar.querySelector('[data-action="undo"]').disabled = !history.undo;
    toolbar.querySelector('[data-action="redo"]').disabled = !history.redo;
    const h = items()[selected()];
    toolbar.querySelector('[data-action="rectify-line"]').disabled = !h || h.kind !== "line";
    toolbar.querySelector('[data-action="reset"]').disabled = !h;
    toolbar.querySelector('[data-action="delete"]').disabled = !h;
    toolbar.querySelector('[data-action="split"]').classList.toggle("ow-on", state.split);
    toolbar.querySelector('[data-action="folds"]').classList.toggle("ow-on", state.showFolds);
    toolbar.querySelector('[data-action="handles"]').classList.toggle("ow-on", state.showHandles);
    for (const b of toolbar.querySelectorAll("[data-tool]")) b.classList.toggle("ow-on", b.dataset.tool === state.tool);
    for (const b of toolbar.querySelectorAll("[data-stage]")) b.classList.toggle("ow-on", b.dataset.stage === model.get("stage"));
  }

  function setTool(name) {
    cancelDrawing();
    state.tool = name;
    if (name !== "select" && model.get("stage") === "transform") setStage("draw");
    updateStatus();
  }

  function setStage(name) {
    model.set("stage", name);
    model.save_changes();
  }

  function toggleHandles() {
    state.showHandles = !state.showHandles;
    updateStatus();
    draw();
  }

  function toggleHelp() {
    state.help = !state.help;
    helpBox.hidden = !state.help;
  }

  // --- hit testing --------------------------------------------------------------------------
  function hit(p, x, y) {
    let best = null;
    const order = items().map((_, i) => i);
    const sel = selected();
    if (sel >= 0) order.unshift(sel); // the selected handle's points first
    for (const i of order) {
      const pts = positions(i, p.kind);
      pts.forEach((q, j) => {
        const [qx, qy] = toScreen(q);
        const d = Math.hypot(nearestX(qx, x) - x, qy - y);
        if (d <= HIT && (!best || d < best.d - 0.5)) best = { index: i, part: j, d };
      });
      if (best && best.index === sel) return best;
    }
    if (best) return best;
    for (const i of order) {
      if (onCurve(p, i, x, y)) return { index: i, part: -1 };
    }
    return null;
  }

  // Whether (x, y) is within HIT_EDGE of handle i's line, arrows or cage edges on pane p.
  function onCurve(p, i, x, y) {
    for (const c of curves(items()[i], positions(i, p.kind))) {
      const s = c.map(toScreen);
      for (let j = 1; j < s.length; j++) {
        const ax = nearestX(s[j - 1][0], x);
        const bx = ax + (nearestX(s[j][0], ax) - ax);
        if (segmentDistance(x, y, ax, s[j - 1][1], bx, s[j][1]) <= HIT_EDGE) return true;
      }
    }
    return false;
  }

  // Over a line the kernel keeps as it is, the canvas's tooltip gives the warnings naming it.
  function hover(p, x, y) {
    if (p.kind === "result" && state.showHandles) {
      const near = hit(p, x, y); // about to be dragged, perhaps: have the live basis ready
      if (near) requestLive(near.index);
    }
    const kept = state.showHandles ? status().kept || [] : [];
    const i = kept.find((j) => j < items().length && onCurve(p, j, x, y));
    const title = i === undefined ? "" : (status().warnings || []).filter((w) => w.includes(`handles[${i}]`)).join("\n");
    if (p.canvas.title !== title) p.canvas.title = title;
  }

  function segmentDistance(px, py, ax, ay, bx, by) {
    const dx = bx - ax;
    const dy = by - ay;
    const t = clamp(((px - ax) * dx + (py - ay) * dy) / (dx * dx + dy * dy || 1), 0, 1);
    return Math.hypot(px - ax - t * dx, py - ay - t * dy);
  }

  // --- pointer ---------------------------------------------------------------------------------
  const local = (p, e) => {
    const r = p.canvas.getBoundingClientRect();
    return [e.clientX - r.left, e.clientY - r.top];
  };

  function onDown(p, e) {
    root.focus({ preventScroll: true });
    if (e.button === 0 && !state.space && waitingForKernel()) return;
    const [x, y] = local(p, e);
    const at = toLonLatAt(x, y);
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
      commit([...items(), { kind: "point", position: at, target: at, rotation: 0, scale: 1 }]);
      select(items().length - 1);
      return;
    }
    if (p.kind === "input" && state.tool === "line") {
      state.drawing = { kind: "line", points: [at], cursor: at };
      draw();
      return;
    }
    if (p.kind === "input" && state.tool === "cage") {
      cageClick(p, x, y, at, e.detail >= 2);
      return;
    }
    const found = state.showHandles ? hit(p, x, y) : null;
    if (!found) {
      select(-1);
      state.drag = { type: "pan", x, y, view: { ...state.view } };
      return;
    }
    select(found.index);
    const h = items()[found.index];
    state.drag = {
      type: "move",
      pane: p.kind,
      index: found.index,
      part: found.part,
      grab: at,
      original: copy(positions(found.index, p.kind)),
      points: copy(positions(found.index, p.kind)),
      kind: h.kind,
      moved: false,
    };
    if (p.kind === "result") requestLive(found.index);
  }

  function onMove(p, e) {
    const [x, y] = local(p, e);
    const at = toLonLatAt(x, y);
    state.cursor = at;
    cursorInfo.textContent = `lon ${at[0].toFixed(2)}°, lat ${at[1].toFixed(2)}°`;
    const d = state.drag;
    if (d && d.type === "pan") {
      state.view = { ...d.view, tx: d.view.tx + x - d.x, ty: d.view.ty + y - d.y };
      state.fitted = false;
      draw();
      return;
    }
    if (d && d.type === "split") {
      state.splitAt = clamp(x / p.w, 0, 1);
      draw();
      return;
    }
    if (d && d.type === "move") {
      d.moved = true;
      d.points = moved(d, at);
      if (d.pane === "result") liveFrame(d);
      draw();
      return;
    }
    if (state.drawing) {
      state.drawing.cursor = at;
      draw();
      return;
    }
    hover(p, x, y);
  }

  // Control points of the dragged handle with the grabbed part at `at`.
  function moved(d, at) {
    const pts = copy(d.original);
    if (d.pane === "result" && d.kind === "point") {
      if (d.part <= 0) return carry(d.original, d.part === 0 ? d.original[0] : d.grab, at); // the arrows ride along
      const c = toXYZ(pts[0]);
      const t = toXYZ(at);
      pts[d.part] = at;
      pts[3 - d.part] = toLonLat(sub(scaled(c, 2 * dot(c, t)), t)); // the opposite arrow follows
      return pts;
    }
    if (d.pane === "input" && d.kind === "point") return carry(d.original, d.part === 0 ? d.original[0] : d.grab, at);
    if (d.part === -1 || (d.pane === "input" && d.kind === "line" && d.part === 1)) return carry(d.original, d.grab, at);
    pts[d.part] = at;
    if (d.pane === "input" && d.kind === "line") pts[1] = toLonLat(add(toXYZ(pts[0]), toXYZ(pts[2])));
    return pts;
  }

  function onUp(p, e) {
    if (p.canvas.hasPointerCapture(e.pointerId)) p.canvas.releasePointerCapture(e.pointerId);
    const d = state.drag;
    state.drag = null;
    if (state.drawing && state.drawing.kind === "line" && e.button === 0) {
      const [start] = state.drawing.points;
      const [x, y] = local(p, e);
      const end = toLonLatAt(x, y);
      state.drawing = null;
      if (angle(toXYZ(start), toXYZ(end)) / DEG >= MIN_LINE) {
        commit([...items(), { kind: "line", start, end, rectify: false }]);
        select(items().length - 1);
      }
      draw();
      return;
    }
    if (!d || d.type !== "move" || !d.moved) {
      draw();
      return;
    }
    finishMove(d);
  }

  function finishMove(d) {
    const all = copy(items());
    const h = all[d.index];
    const pts = d.points;
    if (d.pane === "input") {
      if (h.kind === "point") {
        const unmoved = !h.target || (h.target[0] === h.position[0] && h.target[1] === h.position[1]);
        h.position = pts[0];
        if (unmoved) h.target = pts[0];
      } else if (h.kind === "line") {
        h.start = pts[0];
        h.end = pts[2];
      } else {
        h.vertices = pts;
      }
      commit(all);
      return;
    }
    state.localOutputs = copy(outputs());
    state.localOutputs[d.index] = pts;
    if (h.kind === "point" && d.part > 0) {
      command("arrow", { index: d.index, which: d.part === 1 ? "east" : "west", tip: pts[d.part] });
      return;
    }
    // an unchanged document after solves of the drag's way: the result of the handles as they are
    if (!commit(draggedHandles(d)) && d.solved) command("refresh");
  }

  // The handles as the drag d on the result leaves them (an arrow tip: the scale and turn it gives).
  function draggedHandles(d) {
    const all = copy(items());
    const h = all[d.index];
    const pts = d.points;
    if (h.kind === "point") {
      h.target = pts[0];
      if (d.part > 0) Object.assign(h, arrowTip(pts[0], pts[d.part], d.part === 1 ? "east" : "west") || {});
    } else if (h.kind === "line") {
      h.rectify = false;
      h.targets = pts;
    } else h.targets = pts;
    return all;
  }

  // When the mouse rests during a drag on the result, the kernel solves the handles as they
  // are, one solve at a time (no edit: nothing to undo until the release); while it moves the
  // cores are the browser's. The live frame then draws from the newest weights, so the region
  // the handle reaches grows with the drag.
  function solveDuringDrag(d) {
    if (state.dragSolve && performance.now() - state.dragSolve < 5000) return; // one is on its way
    if (status().state === "busy" || pendingCount > 0) return;
    state.dragSolve = performance.now();
    d.solved = true;
    model.send({ op: "drag", handles: { ...doc(), handles: draggedHandles(d) } });
  }

  function cageClick(p, x, y, at, double) {
    const dr = state.drawing;
    if (!dr) {
      state.drawing = { kind: "cage", points: [at], cursor: at };
      draw();
      return;
    }
    const [fx, fy] = toScreen(dr.points[0]);
    const onFirst = Math.hypot(nearestX(fx, x) - x, fy - y) <= HIT;
    if (onFirst || double) {
      closeCage();
      return;
    }
    dr.points.push(at);
    draw();
  }

  function closeCage() {
    const dr = state.drawing;
    if (!dr || dr.kind !== "cage") return;
    state.drawing = null;
    // a double-click's second click added a vertex on top of the last one: drop it
    const pts = dr.points.filter((q, i) => i === 0 || angle(toXYZ(q), toXYZ(dr.points[i - 1])) > 1e-3);
    if (pts.length >= 3) {
      commit([...items(), { kind: "cage", vertices: pts }]);
      select(items().length - 1);
    } else showLocal("a cage needs at least three vertices");
    draw();
  }

  function cancelDrawing() {
    if (state.drawing) {
      state.drawing = null;
      draw();
    }
  }

  function onWheel(p, e) {
    e.preventDefault();
    const [x, y] = local(p, e);
    const { k, tx, ty } = state.view;
    const fitK = Math.min(p.w, 2 * p.h);
    const k2 = clamp(k * Math.exp(-e.deltaY * 0.0015), fitK * 0.5, fitK * 64);
    const s = k2 / k;
    state.view = { k: k2, tx: x - (x - tx) * s, ty: y - (y - ty) * s };
    state.fitted = false;
    draw();
  }

  for (const p of panes) {
    p.canvas.addEventListener("pointerdown", (e) => onDown(p, e));
    p.canvas.addEventListener("pointermove", (e) => onMove(p, e));
    p.canvas.addEventListener("pointerup", (e) => onUp(p, e));
    p.canvas.addEventListener("dblclick", (e) => {
      if (state.drawing && state.drawing.kind === "cage") {
        e.preventDefault();
        closeCage();
      }
    });
    p.canvas.addEventListener("wheel", (e) => onWheel(p, e), { passive: false });
    p.canvas.addEventListener("contextmenu", (e) => e.preventDefault());
    p.canvas.addEventListener("auxclick", (e) => e.preventDefault());
  }

  // --- keyboard -------------------------------------------------------------------------------
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

  function onWindowKeydown(e) {
    if (!root.isConnected) return listenToWindow(false);
    if (!(e.target instanceof Element && root.contains(e.target))) return;
    const holders = [root, e.target];
    if (passesToJupyter(e)) {
      for (const node of holders) node.removeAttribute(SUPPRESS);
      setTimeout(() => holders.forEach((node) => node.setAttribute(SUPPRESS, "true"))); // after the document's listener
    } else for (const node of holders) node.setAttribute(SUPPRESS, "true");
  }
  // A click outside the editor takes the keyboard from it: JupyterLab would leave the focus
  // here after a click on the cell's prompt (the editor is inside the cell it makes active).
  function onWindowPointerdown(e) {
    if (!root.isConnected) return listenToWindow(false);
    const focused = document.activeElement;
    if (e.target instanceof Node && !root.contains(e.target) && root.contains(focused)) focused.blur();
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
    state.space = false; // its keyup goes elsewhere
  });

  // Esc with nothing to cancel gives the keyboard back to the notebook, as Esc in a cell's
  // editor does: the focus goes to the cell, which puts the notebook in command mode.
  function escape() {
    const d = state.drag;
    if (!d && !state.drawing && !state.help) return releaseFocus();
    if (d) {
      state.drag = null;
      if (d.type === "pan") state.view = d.view; // back where the drag started
      if (d.type === "move") state.liveShown = false; // the kernel's result again, not the dropped drag's live frame
    }
    cancelDrawing();
    if (state.help) toggleHelp();
    draw();
  }
  function releaseFocus() {
    const home = root.closest(".jp-Cell") || (root.parentElement && root.parentElement.closest("[tabindex]"));
    if (root.contains(document.activeElement)) document.activeElement.blur();
    if (home) home.focus({ preventScroll: true });
  }

  // Tools and stages switched by a key are named in the status bar, as their buttons' titles
  // name them.
  function keyTool([name, label, key, what]) {
    const stage = model.get("stage");
    setTool(name);
    const moved = model.get("stage") !== stage ? ` · stage ${STAGES[0][1]} (${STAGES[0][2]})` : "";
    showLocal(`tool ${label} (${key}): ${what}${moved}`);
  }
  function keyStage([name, label, key, what]) {
    setStage(name);
    const others = STAGES.filter((s) => s[0] !== name).map(([, l, k]) => `${k} ${l.toLowerCase()}`);
    showLocal(`stage ${label} (${key}): ${what} · ${others.join(", ")}`);
  }

  root.addEventListener("keydown", (e) => {
    if (passesToJupyter(e)) return; // on to JupyterLab's listener on the document
    const key = e.key;
    const mod = e.ctrlKey || e.metaKey;
    let used = true;
    if (mod && !e.altKey && (key === "z" || key === "Z")) command(e.shiftKey ? "redo" : "undo");
    else if (mod && !e.altKey && (key === "y" || key === "Y")) command("redo");
    else if (mod || e.altKey) used = false;
    else if (key === " ") state.space = true;
    else if (key === "Escape") escape();
    else if (key === "Enter") closeCage();
    else if (key === "Delete" || key === "Backspace") deleteSelected();
    else if (key === "f" || key === "F") fit();
    else if (key === "?") toggleHelp();
    else if (key === "h" || key === "H") toggleHandles();
    else if (key === "a" || key === "A") command("rectify_all");
    else if (key === "s" || key === "S") commandSelected("rectify_line");
    else if (key === "r" || key === "R") commandSelected("reset");
    else {
      const tool = TOOLS.find(([, , k]) => k.toLowerCase() === key.toLowerCase());
      const stage = STAGES.find(([, , k]) => k.toLowerCase() === key.toLowerCase());
      if (tool) keyTool(tool);
      else if (stage) keyStage(stage);
      else used = false;
    }
    if (used) {
      e.preventDefault();
      e.stopPropagation();
    }
  });
  root.addEventListener("keyup", (e) => {
    if (e.key === " ") {
      state.space = false;
      e.stopPropagation();
    }
  });

  // --- the kernel's changes -----------------------------------------------------------------
  const images = { source: null, preview: null, folds: null };
  function onImage(name) {
    images[name] = (async () => {
      state[name] = await decode(model.get(name), name === "folds" ? "image/png" : "image/jpeg");
      if (name === "source" && state.source && live) live.setSource(state.source);
      if (name === "preview") state.liveShown = false; // the kernel's result replaces the live frame
      if (name === "source" && !state.view) layout();
      draw();
    })();
  }

  // A result is on screen once its image (when it changed) is decoded and drawn: then the
  // root's data-generation names the edit it answers, and the last edit's latency is taken.
  async function onStatus() {
    localNote = "";
    updateStatus();
    draw();
    const s = status();
    if (s.state !== "busy") state.dragSolve = 0; // the next solve of a drag may go
    if (s.state === "error") state.liveShown = false; // the last good result, not a frame of a drag that failed
    if (s.state !== "idle") return;
    await null; // an image changed by the same message has started decoding by now
    await Promise.all([images.preview, images.folds]);
    if (!state.drag) state.liveShown = false; // the kernel's result, even when its image did not change
    await new Promise((resolve) => requestAnimationFrame(resolve));
    if (status() !== s) return; // superseded meanwhile
    root.dataset.generation = String(s.generation);
    if (state.released !== null) {
      state.latency = performance.now() - state.released;
      root.dataset.latencyMs = state.latency.toFixed(1);
      state.released = null;
    }
    updateStatus();
  }
  const listeners = [
    ["change:source", () => onImage("source")],
    ["change:preview", () => onImage("preview")],
    ["change:folds", () => onImage("folds")],
    [
      "change:handles",
      () => {
        showHandlesDocument();
        draw();
      },
    ],
    [
      "change:outputs",
      () => {
        state.localOutputs = null;
        draw();
      },
    ],
    ["change:status", () => onStatus()],
    [
      "change:selected",
      () => {
        updateStatus();
        draw();
      },
    ],
    ["change:history", () => updateStatus()],
    [
      "change:stage",
      () => {
        if (model.get("stage") === "transform") setTool("select"); // nothing is drawn on the result
        layout();
        updateStatus();
      },
    ],
    ["change:height", () => layout()],
  ];
  for (const [event, fn] of listeners) model.on(event, fn);
  model.on("msg:custom", onMessage);

  // The handles drawn, for a glance in the page's inspector (and the real-browser tests).
  function showHandlesDocument() {
    root.dataset.handles = JSON.stringify(doc());
  }

  const resize = new ResizeObserver(() => layout());
  resize.observe(panesBox);
  onImage("source");
  onImage("preview");
  onImage("folds");
  layout();
  showHandlesDocument();
  onStatus();

  return () => {
    resize.disconnect();
    for (const [event, fn] of listeners) model.off(event, fn);
    model.off("msg:custom", onMessage);
  };
}

export default { render };
