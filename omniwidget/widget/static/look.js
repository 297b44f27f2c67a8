// The look-around view of the result: the panorama seen through a perspective camera, as a
// 360° viewer shows it, drawn with WebGL2. The camera is omniwidget/raster/perspective.py's
// (`omniwidget view`, `ow.view`), so the editor and the command show the same picture:
//
//   looking at [yaw, pitch] (lon, lat in degrees, the conventions of coords.py) with north up,
//   pixel (x, y) (column, row; integers are pixel centres) shows the direction
//       f forward + (x - cx) east - (y - cy) north,
//   forward, east and north the unit vector and local frame of [yaw, pitch],
//   (cx, cy) = ((width - 1) / 2, (height - 1) / 2) and f = width / (2 tan(fov / 2)),
//   fov the horizontal field of view.
//
// The maths (the camera, its rays, where a direction appears, a drag and the wheel) are pure
// functions tested by tests/js/look.test.mjs; createLook is the WebGL part.

import { DEG, dot, lonlatToXYZ, wrapLon, xyzToLonLat } from "./sphere.js";

/** @typedef {import("./sphere.js").LonLat} LonLat */
/** @typedef {import("./sphere.js").Vec3} Vec3 */
/** @typedef {{yaw: number, pitch: number, fov: number}} Look where the camera looks (degrees) and its horizontal field of view (degrees) */

/** The fields of view the wheel allows, degrees. */
export const FOV_RANGE = [20, 120];
/** The first look: the panorama's centre, 90° across. */
export const START = Object.freeze({ yaw: 0, pitch: 0, fov: 90 });
const ZOOM_RATE = 0.0015; // per unit of a wheel event's deltaY: the field of view times exp(rate * deltaY)

const clamp = (x, lo, hi) => Math.min(hi, Math.max(lo, x));

/**
 * The camera's forward direction and its east (right) and north (up) image axes, unit vectors
 * (coords.lonlat_to_xyz and coords.local_frame of [yaw, pitch]).
 * @param {Look} look
 * @returns {{forward: Vec3, east: Vec3, north: Vec3}}
 */
export function camera({ yaw, pitch }) {
  const [lon, lat] = [yaw * DEG, pitch * DEG];
  return {
    forward: lonlatToXYZ([yaw, pitch]),
    east: [-Math.sin(lon), Math.cos(lon), 0],
    north: [-Math.sin(lat) * Math.cos(lon), -Math.sin(lat) * Math.sin(lon), Math.cos(lat)],
  };
}

/**
 * The focal length in pixels of a view `width` pixels wide.
 * @param {number} fov horizontal field of view, degrees
 * @param {number} width pixels
 * @returns {number} width / (2 tan(fov / 2))
 */
export function focal(fov, width) {
  return width / (2 * Math.tan((fov * DEG) / 2));
}

/**
 * The direction pixel (x, y) of a width x height view shows (not unit).
 * @param {Look} look
 * @param {number} width pixels
 * @param {number} height pixels
 * @param {number} x column (integers are pixel centres)
 * @param {number} y row
 * @returns {Vec3}
 */
export function ray(look, width, height, x, y) {
  const { forward, east, north } = camera(look);
  const f = focal(look.fov, width);
  const [dx, dy] = [x - (width - 1) / 2, y - (height - 1) / 2];
  return [0, 1, 2].map((i) => f * forward[i] + dx * east[i] - dy * north[i]);
}

/**
 * The panorama's position pixel (x, y) shows.
 * @returns {LonLat} [lon, lat] in degrees
 */
export function lonlatAt(look, width, height, x, y) {
  return xyzToLonLat(ray(look, width, height, x, y));
}

/**
 * Where a position appears in the view (PerspectiveView.project): column and row, or null for
 * a direction on or behind the camera's plane.
 * @param {Look} look
 * @param {number} width pixels
 * @param {number} height pixels
 * @param {LonLat} lonlat
 * @returns {number[] | null} [x, y]
 */
export function project(look, width, height, lonlat) {
  const { forward, east, north } = camera(look);
  const p = lonlatToXYZ(lonlat);
  const depth = dot(p, forward);
  if (!(depth > 0)) return null;
  const s = focal(look.fov, width) / depth;
  return [(width - 1) / 2 + s * dot(p, east), (height - 1) / 2 - s * dot(p, north)];
}

/**
 * The look after the pointer moved (dx, dy) CSS pixels from where a drag started on a view
 * `width` CSS pixels wide: the scene follows the pointer, so the camera turns the other way,
 * by the angle the move spans at the view's centre, dx / f and dy / f radians (f the focal
 * length in CSS pixels): the yaw by -dx / f (wrapped into [-180, 180)), the pitch by +dy / f,
 * held within [-90, 90].
 * @param {Look} start the look when the drag started
 * @param {number} dx CSS pixels, right positive
 * @param {number} dy CSS pixels, down positive
 * @param {number} width the view's width, CSS pixels
 * @returns {Look}
 */
export function dragLook(start, dx, dy, width) {
  const f = focal(start.fov, width);
  return { yaw: wrapLon(start.yaw - dx / f / DEG), pitch: clamp(start.pitch + dy / f / DEG, -90, 90), fov: start.fov };
}

/**
 * The look after a wheel event: the field of view times exp(0.0015 deltaY) (wheel down:
 * wider), within FOV_RANGE.
 * @param {Look} look
 * @param {number} deltaY the wheel event's deltaY
 * @returns {Look}
 */
export function zoomLook(look, deltaY) {
  return { ...look, fov: clamp(look.fov * Math.exp(ZOOM_RATE * deltaY), FOV_RANGE[0], FOV_RANGE[1]) };
}

/**
 * The look as the editor's data-look attribute and status line give it: degrees, 2 decimals.
 * @param {Look} look
 * @returns {string}
 */
export function lookText({ yaw, pitch, fov }) {
  return `yaw ${yaw.toFixed(2)}°, pitch ${pitch.toFixed(2)}°, ${fov.toFixed(2)}° across`;
}

// --- WebGL2 ------------------------------------------------------------------------------------
const VERTEX = `#version 300 es
in vec2 corner;
void main() { gl_Position = vec4(corner, 0.0, 1.0); }`;

// gl_FragCoord is (column + 0.5, height - row - 0.5): its offset from the canvas's middle is
// (x - cx, -(y - cy)), so the ray is focal forward + offset.x east + offset.y north.
const FRAGMENT = `#version 300 es
precision highp float;
uniform sampler2D source;
uniform vec3 forward;
uniform vec3 east;
uniform vec3 north;
uniform float focal;
uniform vec2 size;
out vec4 color;
const float PI = 3.141592653589793;
void main() {
  vec2 offset = gl_FragCoord.xy - 0.5 * size;
  vec3 r = focal * forward + offset.x * east + offset.y * north;
  float lon = atan(r.y, r.x);
  float lat = atan(r.z, length(r.xy));
  color = vec4(texture(source, vec2((lon + PI) / (2.0 * PI), (0.5 * PI - lat) / PI)).rgb, 1.0);
}`;

function compile(gl, type, text) {
  const shader = gl.createShader(type);
  gl.shaderSource(shader, text);
  gl.compileShader(shader);
  if (!gl.getShaderParameter(shader, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(shader));
  return shader;
}

/**
 * The look-around renderer on a canvas of its own, or null where WebGL2 is not available.
 * The panorama is sampled bilinearly (no mipmaps, as OpenCV's remap of `omniwidget view`),
 * wrapping across the ±180° seam.
 * @param {HTMLCanvasElement} canvas
 */
export function createLook(canvas) {
  const gl = canvas.getContext("webgl2", { preserveDrawingBuffer: true, antialias: false, depth: false });
  if (!gl) return null;
  const program = gl.createProgram();
  gl.attachShader(program, compile(gl, gl.VERTEX_SHADER, VERTEX));
  gl.attachShader(program, compile(gl, gl.FRAGMENT_SHADER, FRAGMENT));
  gl.linkProgram(program);
  if (!gl.getProgramParameter(program, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(program));
  gl.useProgram(program);
  gl.bindBuffer(gl.ARRAY_BUFFER, gl.createBuffer());
  gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 3, -1, -1, 3]), gl.STATIC_DRAW); // one triangle covers the view
  const corner = gl.getAttribLocation(program, "corner");
  gl.enableVertexAttribArray(corner);
  gl.vertexAttribPointer(corner, 2, gl.FLOAT, false, 0, 0);
  const uniforms = {};
  for (const name of ["source", "forward", "east", "north", "focal", "size"]) uniforms[name] = gl.getUniformLocation(program, name);
  gl.uniform1i(uniforms.source, 0);
  const texture = gl.createTexture();
  gl.activeTexture(gl.TEXTURE0);
  gl.bindTexture(gl.TEXTURE_2D, texture);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.LINEAR);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.LINEAR);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.REPEAT); // the panorama wraps at the seam
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
  let image = null; // the panorama uploaded

  return {
    canvas,
    /** The panorama shown (an ImageBitmap); uploaded when it is another one. */
    setImage(bitmap) {
      if (bitmap === image) return;
      gl.activeTexture(gl.TEXTURE0);
      gl.bindTexture(gl.TEXTURE_2D, texture);
      gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA8, gl.RGBA, gl.UNSIGNED_BYTE, bitmap);
      image = bitmap;
    },
    /** Draw `look` on a width x height canvas (device pixels); false without a panorama. */
    render(look, width, height) {
      if (!image) return false;
      if (canvas.width !== width || canvas.height !== height) [canvas.width, canvas.height] = [width, height];
      const { forward, east, north } = camera(look);
      gl.viewport(0, 0, width, height);
      gl.uniform3fv(uniforms.forward, forward);
      gl.uniform3fv(uniforms.east, east);
      gl.uniform3fv(uniforms.north, north);
      gl.uniform1f(uniforms.focal, focal(look.fov, width));
      gl.uniform2f(uniforms.size, width, height);
      gl.drawArrays(gl.TRIANGLES, 0, 3);
      return true;
    },
  };
}
