// A video in the editor: the slider's label and Save video's status line (omniwidget/widget/static/video.js).
import { test } from "node:test";
import assert from "node:assert/strict";
import { frameLabel, videoRunning, videoStatusText } from "../../omniwidget/widget/static/video.js";

test("the slider's label counts frames from 1 and gives the time", () => {
  assert.equal(frameLabel(0, 12, 1 / 12), "frame 1 / 12 · 0.00 s");
  assert.equal(frameLabel(3, 12, 1 / 12), "frame 4 / 12 · 0.25 s");
  assert.equal(frameLabel(2000, 3000, 1 / 25), "frame 2001 / 3000 · 1:20.00");
});

test("Cancel is offered while the map or the frames are at work", () => {
  assert.equal(videoRunning(undefined), false);
  assert.equal(videoRunning({ state: "map" }), true);
  assert.equal(videoRunning({ state: "running", done: 3, total: 12 }), true);
  for (const state of ["done", "cancelled", "error"]) assert.equal(videoRunning({ state }), false);
});

test("the status line shows the progress, then the kernel's message", () => {
  assert.equal(videoStatusText(undefined), "");
  assert.equal(videoStatusText({}), "");
  assert.equal(videoStatusText({ state: "running", done: 3, total: 12, fps: 24.26 }), "saving the video: 3 / 12 frames (25%), 24.3 fps");
  assert.equal(videoStatusText({ state: "running", done: 3, fps: 2 }), "saving the video: 3 / ? frames, 2.0 fps");
  assert.equal(videoStatusText({ state: "done", message: "12 frames saved to clip-rectified.mp4" }), "12 frames saved to clip-rectified.mp4");
  assert.equal(videoStatusText({ state: "map", message: "computing the map..." }), "computing the map...");
});
