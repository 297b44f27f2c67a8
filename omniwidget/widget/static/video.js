// A video in the editor: the frame slider's label and Save video's line in the status bar.
// Pure functions, no DOM; tested by tests/js/video.test.mjs.

/**
 * Save video's state, as the kernel's status says it (status.video).
 * @typedef {{state?: "map" | "running" | "done" | "cancelled" | "error", done?: number, total?: number, fps?: number, path?: string, message?: string}} VideoJob
 */

/**
 * The slider's label: the frame (counted from 1, as a person counts), of how many, and its time.
 * @param {number} frame the frame's index, from 0
 * @param {number} count frames in the video
 * @param {number} interval seconds between frames
 * @returns {string} e.g. "frame 4 / 12 · 0.25 s"
 */
export function frameLabel(frame, count, interval) {
  const seconds = frame * interval;
  const time = seconds < 60 ? `${seconds.toFixed(2)} s` : `${Math.floor(seconds / 60)}:${(seconds % 60).toFixed(2).padStart(5, "0")}`;
  return `frame ${frame + 1} / ${count} · ${time}`;
}

/**
 * Whether Save video is still at work (its map or its frames): Cancel is offered then.
 * @param {VideoJob | undefined} job
 * @returns {boolean}
 */
export function videoRunning(job) {
  return Boolean(job) && (job.state === "map" || job.state === "running");
}

/**
 * Save video's line in the status bar: its progress while it runs, then its outcome.
 * @param {VideoJob | undefined} job
 * @returns {string} "" when no video was saved
 */
export function videoStatusText(job) {
  if (!job || !job.state) return "";
  if (job.state === "running") {
    const share = job.total ? ` (${Math.floor((100 * (job.done || 0)) / job.total)}%)` : "";
    return `saving the video: ${job.done || 0} / ${job.total || "?"} frames${share}, ${(job.fps || 0).toFixed(1)} fps`;
  }
  return job.message || "";
}
