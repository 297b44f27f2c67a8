// The live result while a handle is dragged: eq. (2) evaluated per pixel on the GPU (WebGL2).
//
// The kernel sends, once per drag, the basis of omniwidget/raster/live.py for the dragged
// handle: per preview pixel of the region the handle weighs in, the other controls' part
// of eq. (2)'s sum F(p) and the handle's own weights W_j(p), as half floats in layers of
// four channels (F_x, F_y, F_z, W_0 | W_1 ... W_4 | ...), then the harmonic fill's affine form at the
// pixel, s(p) and o(p) (1 and 0 where nothing is filled). Outside the region the kernel's
// result is already right; the canvas holds the region only. Every frame the handle's maps are rebuilt from its control
// points (moebius.js) and the fragment shader sums
//     T(p) = normalize(F(p) + Σ_j W_j(p) M_j⁻¹(p)),   then   s(p) T(p) + o(p)
// and samples the panorama there, bilinearly, wrapping across the ±180° seam.

// Controls a basis may hold: two vec4 uniforms each.
export const MAX_CONTROLS = 32;
// Channels of a basis besides the controls' weights: F (3), then the fill's s (1) and o (3).
export const BASIS_CHANNELS = 7;
// Pixels a frame computes while the mouse moves (an eighth of the 1024 x 512 preview): a larger
// region is drawn from every second (or fourth) pixel until the mouse rests, then in full.
export const MOVING_PIXELS = 256 * 256;

const VERTEX = `#version 300 es
in vec2 corner;
void main() { gl_Position = vec4(corner, 0.0, 1.0); }`;

const FRAGMENT = `#version 300 es
precision highp float;
precision highp int;
uniform highp sampler2D basis;
uniform sampler2D source;
uniform int count;
uniform int width;  // the region's
uniform int height;
uniform int step;  // the frame's pixel is the region's pixel (step x, step y) + step / 2
uniform ivec2 origin;  // the region's top left pixel (row, column) in the whole grid
uniform int size;  // the whole grid's width
uniform vec4 maps[${2 * MAX_CONTROLS}];
out vec4 color;
const float PI = 3.141592653589793;
vec2 cmul(vec2 p, vec2 q) { return vec2(p.x * q.x - p.y * q.y, p.x * q.y + p.y * q.x); }
void main() {
  int col = min(int(gl_FragCoord.x) * step + step / 2, width - 1);
  int row = min((int(ceil(float(height) / float(step))) - 1 - int(gl_FragCoord.y)) * step + step / 2, height - 1);
  float lon = (float((origin.y + col) % size) + 0.5) / float(size) * 2.0 * PI - PI;
  float lat = 0.5 * PI - (float(origin.x + row) + 0.5) / float(size / 2) * PI;
  vec3 p = vec3(cos(lat) * cos(lon), cos(lat) * sin(lon), sin(lat));
  vec2 u = p.z <= 0.0 ? p.xy : vec2(1.0 + p.z, 0.0);  // [u : v] as coords.xyz_to_homogeneous
  vec2 v = p.z <= 0.0 ? vec2(1.0 - p.z, 0.0) : vec2(p.x, -p.y);
  vec3 sum = texelFetch(basis, ivec2(col, row), 0).xyz;
  for (int j = 0; j < ${MAX_CONTROLS}; j++) {
    if (j >= count) break;
    int channel = 3 + j;
    float w = texelFetch(basis, ivec2(col, row + (channel / 4) * height), 0)[channel % 4];
    vec4 ab = maps[2 * j];
    vec4 cd = maps[2 * j + 1];
    vec2 big_u = cmul(ab.xy, u) + cmul(ab.zw, v);
    vec2 big_v = cmul(cd.xy, u) + cmul(cd.zw, v);
    float uu = dot(big_u, big_u);
    float vv = dot(big_v, big_v);
    float share = w / (uu + vv);
    sum += vec3(2.0 * share * (big_u.x * big_v.x + big_u.y * big_v.y), 2.0 * share * (big_u.y * big_v.x - big_u.x * big_v.y), share * (uu - vv));
  }
  float fill[4];
  for (int k = 0; k < 4; k++) {
    int channel = 3 + count + k;
    fill[k] = texelFetch(basis, ivec2(col, row + (channel / 4) * height), 0)[channel % 4];
  }
  vec3 shown = fill[0] * normalize(sum) + vec3(fill[1], fill[2], fill[3]);
  float source_lon = atan(shown.y, shown.x);
  float source_lat = atan(shown.z, length(shown.xy));
  color = vec4(texture(source, vec2((source_lon + PI) / (2.0 * PI), (0.5 * PI - source_lat) / PI)).rgb, 1.0);
}`;

function compile(gl, type, text) {
  const shader = gl.createShader(type);
  gl.shaderSource(shader, text);
  gl.compileShader(shader);
  if (!gl.getShaderParameter(shader, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(shader));
  return shader;
}

// The renderer on a canvas of its own, or null where WebGL2 is not available.
export function createLive(canvas) {
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
  const at = (name) => gl.getUniformLocation(program, name);
  const uniforms = {};
  for (const name of ["basis", "source", "count", "width", "height", "step", "origin", "size", "maps"]) uniforms[name] = at(name);
  gl.uniform1i(uniforms.basis, 0);
  gl.uniform1i(uniforms.source, 1);

  const texture = (unit, filter, wrapS) => {
    const t = gl.createTexture();
    gl.activeTexture(gl.TEXTURE0 + unit);
    gl.bindTexture(gl.TEXTURE_2D, t);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, filter);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, filter);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, wrapS);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
    return t;
  };
  const basisTexture = texture(0, gl.NEAREST, gl.CLAMP_TO_EDGE);
  const sourceTexture = texture(1, gl.LINEAR, gl.REPEAT); // the panorama wraps at the seam
  let basis = null; // the header of the basis held: {width, height, controls, origin, size}
  let hasSource = false;

  return {
    canvas,
    // The panorama shown (an ImageBitmap), uploaded once per image.
    setSource(image) {
      gl.activeTexture(gl.TEXTURE1);
      gl.bindTexture(gl.TEXTURE_2D, sourceTexture);
      gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA8, gl.RGBA, gl.UNSIGNED_BYTE, image);
      hasSource = true;
    },
    // A basis from the kernel: its header and its half floats, (layers * height) x width x 4.
    setBasis(header, buffer) {
      const { width, height, controls } = header;
      const layers = Math.ceil((BASIS_CHANNELS + controls) / 4);
      if (!width || !height || controls > MAX_CONTROLS || layers * height > gl.getParameter(gl.MAX_TEXTURE_SIZE)) return false;
      const data = new Uint16Array(buffer.buffer, buffer.byteOffset, buffer.byteLength / 2);
      if (data.length !== layers * height * width * 4) return false;
      gl.activeTexture(gl.TEXTURE0);
      gl.bindTexture(gl.TEXTURE_2D, basisTexture);
      gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
      gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA16F, width, layers * height, 0, gl.RGBA, gl.HALF_FLOAT, data);
      basis = header;
      return true;
    },
    // Draw the result for the handle's inverse maps (one {a, b, c, d} per control) from at most
    // `pixels` pixels of the region; the canvas shows it, scaled down by the step returned (0: nothing drawn).
    render(inverses, pixels = Infinity) {
      if (!basis || !hasSource || inverses.length !== basis.controls) return 0;
      let step = 1;
      while ((basis.width / step) * (basis.height / step) > pixels) step *= 2;
      const [w, h] = [Math.ceil(basis.width / step), Math.ceil(basis.height / step)];
      if (canvas.width !== w || canvas.height !== h) [canvas.width, canvas.height] = [w, h];
      const maps = new Float32Array(8 * MAX_CONTROLS);
      inverses.forEach((m, j) => maps.set([...m.a, ...m.b, ...m.c, ...m.d], 8 * j));
      gl.viewport(0, 0, w, h);
      gl.uniform1i(uniforms.step, step);
      gl.uniform1i(uniforms.count, basis.controls);
      gl.uniform1i(uniforms.width, basis.width);
      gl.uniform1i(uniforms.height, basis.height);
      gl.uniform2i(uniforms.origin, ...basis.origin);
      gl.uniform1i(uniforms.size, basis.size);
      gl.uniform4fv(uniforms.maps, maps);
      gl.drawArrays(gl.TRIANGLES, 0, 3);
      return step;
    },
  };
}
