// editor.bundle.js: editor.js and the modules it imports, one ES module for anywidget, built by esbuild
// from build.mjs at the repository's root (npm run build; npm run watch while developing).
// Generated: edit the sources, never this file; tests/test_js.py fails when it is out of date.
// sources: editor.js edits.js handles.js hit.js live.js look.js moebius.js sphere.js status.js suggest.js video.js view.js
// sources sha256: 4e8719f886b3a4767680ce47915ca8b34c9a7b93d9d8606ed75efc027d5e04d8
// sphere.js
var DEG = Math.PI / 180;
var dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
var cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
var scaled = (a, s) => [a[0] * s, a[1] * s, a[2] * s];
var add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
var sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
var norm = (a) => Math.hypot(a[0], a[1], a[2]);
var unit = (a) => scaled(a, 1 / (norm(a) || 1));
function lonlatToXYZ([lon, lat]) {
  const c = Math.cos(lat * DEG);
  return [c * Math.cos(lon * DEG), c * Math.sin(lon * DEG), Math.sin(lat * DEG)];
}
function xyzToLonLat([x, y, z]) {
  const lon = Math.atan2(y, x) / DEG;
  return [lon >= 180 ? lon - 360 : lon, Math.atan2(z, Math.hypot(x, y)) / DEG];
}
function wrapLon(lon) {
  return ((lon + 180) % 360 + 360) % 360 - 180;
}
function distance(a, b) {
  const [p, q] = [lonlatToXYZ(a), lonlatToXYZ(b)];
  return Math.atan2(norm(cross(p, q)), dot(p, q)) / DEG;
}
function midpoint(a, b) {
  return xyzToLonLat(add(lonlatToXYZ(a), lonlatToXYZ(b)));
}
function alongEast(lonlat, sign, angle) {
  const p = lonlatToXYZ(lonlat);
  const east = [-Math.sin(lonlat[0] * DEG), Math.cos(lonlat[0] * DEG), 0];
  return xyzToLonLat(add(scaled(p, Math.cos(angle)), scaled(east, sign * Math.sin(angle))));
}
function rotate(v, axis, angle) {
  const c = Math.cos(angle);
  const s = Math.sin(angle);
  return add(add(scaled(v, c), scaled(cross(axis, v), s)), scaled(axis, dot(axis, v) * (1 - c)));
}
function carry(points, from, to) {
  const a = lonlatToXYZ(from);
  const b = lonlatToXYZ(to);
  const axis = cross(a, b);
  const n = norm(axis);
  if (n < 1e-12) return points.map((p) => [...p]);
  const angle = Math.atan2(n, dot(a, b));
  return points.map((p) => xyzToLonLat(rotate(lonlatToXYZ(p), scaled(axis, 1 / n), angle)));
}
function mirror(centre, p) {
  const c = lonlatToXYZ(centre);
  const t = lonlatToXYZ(p);
  return xyzToLonLat(sub(scaled(c, 2 * dot(c, t)), t));
}
function circleArc(a, b, c) {
  const [pa, pb, pc] = [lonlatToXYZ(a), lonlatToXYZ(b), lonlatToXYZ(c)];
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
  if (tb > tc) tc -= 2 * Math.PI;
  const steps = Math.max(2, Math.ceil(Math.abs(tc) * r / (0.75 * DEG)));
  const out = [];
  for (let i = 0; i <= steps; i++) {
    const t = tc * i / steps;
    out.push(xyzToLonLat(add(o, add(scaled(e1, r * Math.cos(t)), scaled(e2, r * Math.sin(t))))));
  }
  return out;
}
function geodesic(a, b) {
  return circleArc(a, midpoint(a, b), b);
}
function circle(centre, radius, count = 96) {
  const c = lonlatToXYZ(centre);
  const a = Math.abs(c[2]) < 0.9 ? [0, 0, 1] : [1, 0, 0];
  const across = cross(a, c);
  const e1 = scaled(across, 1 / norm(across));
  const e2 = cross(c, e1);
  const r = radius * DEG;
  return Array.from({ length: count + 1 }, (_, k) => {
    const t = 2 * Math.PI * k / count;
    return xyzToLonLat(add(scaled(c, Math.cos(r)), add(scaled(e1, Math.sin(r) * Math.cos(t)), scaled(e2, Math.sin(r) * Math.sin(t)))));
  });
}

// handles.js
var ARROW_LENGTH = 0.3;
function controlPoints(h) {
  if (h.kind === "point") return [h.position, alongEast(h.position, 1, ARROW_LENGTH), alongEast(h.position, -1, ARROW_LENGTH)];
  if (h.kind === "line") return [h.start, midpoint(h.start, h.end), h.end];
  return h.vertices;
}
function curves(h, pts) {
  if (h.kind === "point") return [geodesic(pts[0], pts[1]), geodesic(pts[0], pts[2])];
  if (h.kind === "line") return [circleArc(pts[0], pts[1], pts[2])];
  return pts.map((p, i) => geodesic(p, pts[(i + 1) % pts.length]));
}

// moebius.js
var SCALE_RANGE = [1e-3, 1e3];
var cmul = (p, q) => [p[0] * q[0] - p[1] * q[1], p[0] * q[1] + p[1] * q[0]];
var csub = (p, q) => [p[0] - q[0], p[1] - q[1]];
var cneg = (p) => [-p[0], -p[1]];
var cdiv = (p, q) => {
  const n = q[0] * q[0] + q[1] * q[1];
  return [(p[0] * q[0] + p[1] * q[1]) / n, (p[1] * q[0] - p[0] * q[1]) / n];
};
function csqrt([re, im]) {
  const r = Math.hypot(re, im);
  const x = Math.sqrt((r + re) / 2);
  const y = Math.sqrt(Math.max(0, (r - re) / 2));
  return [x, im < 0 ? -y : y];
}
var matVec = (m, v) => m.map((row) => dot(row, v));
var transpose = (m) => [0, 1, 2].map((j) => m.map((row) => row[j]));
function homogeneous([x, y, z]) {
  return z <= 0 ? [[x, y], [1 - z, 0]] : [[1 + z, 0], [x, -y]];
}
function fromHomogeneous(u, v) {
  const s = Math.max(Math.hypot(...u), Math.hypot(...v));
  const [uu, vv] = [u, v].map((w) => [w[0] / s, w[1] / s]);
  const uv = cmul(uu, [vv[0], -vv[1]]);
  const a = uu[0] * uu[0] + uu[1] * uu[1];
  const b = vv[0] * vv[0] + vv[1] * vv[1];
  return [2 * uv[0] / (a + b), 2 * uv[1] / (a + b), (a - b) / (a + b)];
}
function localFrame([lon, lat]) {
  const [l, p] = [lon * DEG, lat * DEG];
  return [
    [-Math.sin(l), Math.cos(l), 0],
    [-Math.sin(p) * Math.cos(l), -Math.sin(p) * Math.sin(l), Math.cos(p)]
  ];
}
function normalised(m) {
  const r = csqrt(csub(cmul(m.a, m.d), cmul(m.b, m.c)));
  return { a: cdiv(m.a, r), b: cdiv(m.b, r), c: cdiv(m.c, r), d: cdiv(m.d, r) };
}
var identity = () => ({ a: [1, 0], b: [0, 0], c: [0, 0], d: [1, 0] });
function compose(p, q) {
  return normalised({
    a: [cmul(p.a, q.a), cmul(p.b, q.c)].reduce((s, t) => [s[0] + t[0], s[1] + t[1]]),
    b: [cmul(p.a, q.b), cmul(p.b, q.d)].reduce((s, t) => [s[0] + t[0], s[1] + t[1]]),
    c: [cmul(p.c, q.a), cmul(p.d, q.c)].reduce((s, t) => [s[0] + t[0], s[1] + t[1]]),
    d: [cmul(p.c, q.b), cmul(p.d, q.d)].reduce((s, t) => [s[0] + t[0], s[1] + t[1]])
  });
}
var inverse = (m) => ({ a: m.d, b: cneg(m.b), c: cneg(m.c), d: m.a });
function applyXYZ(m, p) {
  const [u, v] = homogeneous(p);
  const add2 = (s, t) => [s[0] + t[0], s[1] + t[1]];
  return fromHomogeneous(add2(cmul(m.a, u), cmul(m.b, v)), add2(cmul(m.c, u), cmul(m.d, v)));
}
function toZeroOneInfinity(points) {
  const [[u1, v1], [u2, v2], [u3, v3]] = points.map(homogeneous);
  const s1 = csub(cmul(v3, u2), cmul(u3, v2));
  const s3 = csub(cmul(v1, u2), cmul(u1, v2));
  return { a: cmul(s1, v1), b: cneg(cmul(s1, u1)), c: cmul(s3, v3), d: cneg(cmul(s3, u3)) };
}
function fromPointsXYZ(src, dst) {
  const h = toZeroOneInfinity(dst);
  const adjoint = { a: h.d, b: cneg(h.b), c: cneg(h.c), d: h.a };
  return compose(adjoint, normalised(toZeroOneInfinity(src)));
}
var fromPoints = (src, dst) => fromPointsXYZ(src.map(lonlatToXYZ), dst.map(lonlatToXYZ));
var fromRotation = (r) => fromPointsXYZ([[1, 0, 0], [0, 1, 0], [0, 0, 1]], transpose(r));
function rotationAbout(axis, angle) {
  const [x, y, z] = axis;
  const k = [
    [0, -z, y],
    [z, 0, -x],
    [-y, x, 0]
  ];
  const kk = k.map((row) => [0, 1, 2].map((j) => dot(row, [k[0][j], k[1][j], k[2][j]])));
  const [s, c] = [Math.sin(angle), 1 - Math.cos(angle)];
  return fromRotation([0, 1, 2].map((i) => [0, 1, 2].map((j) => (i === j ? 1 : 0) + s * k[i][j] + c * kk[i][j])));
}
function frameRotation(lonlat) {
  const [east, north] = localFrame(lonlat);
  const p = lonlatToXYZ(lonlat);
  return [east, north.map((x) => -x), p.map((x) => -x)];
}
function pointMap(position, target, scale = 1, rotation = 0) {
  const root = csqrt([scale * Math.cos(rotation * DEG), -scale * Math.sin(rotation * DEG)]);
  const stretch = { a: root, b: [0, 0], c: [0, 0], d: cdiv([1, 0], root) };
  return compose(compose(fromRotation(transpose(frameRotation(target))), stretch), fromRotation(frameRotation(position)));
}
function arrowTip(final, tip, which) {
  const [u, v] = homogeneous(applyXYZ(fromRotation(frameRotation(final)), lonlatToXYZ(tip)));
  if (Math.hypot(...v) < 1e-12 * Math.hypot(...u)) return null;
  const ratio = cdiv(u, v);
  const sign = which === "east" ? 1 : -1;
  const k = [sign * ratio[0] / Math.tan(ARROW_LENGTH / 2), sign * ratio[1] / Math.tan(ARROW_LENGTH / 2)];
  const scale = Math.min(SCALE_RANGE[1], Math.max(SCALE_RANGE[0], Math.hypot(...k)));
  return { scale, rotation: -Math.atan2(k[1], k[0]) / DEG };
}
function shortestTurn(a, b) {
  const axis = cross(a, b);
  const size = norm(axis);
  if (size < 1e-15) return dot(a, b) > 0 ? identity() : pointMap(xyzToLonLat(a), xyzToLonLat(b));
  return rotationAbout(
    axis.map((x) => x / size),
    Math.atan2(size, dot(a, b))
  );
}
function topEigenvector(n) {
  const a = n.map((row) => [...row]);
  const v = [0, 1, 2, 3].map((i) => [0, 1, 2, 3].map((j) => i === j ? 1 : 0));
  for (let sweep = 0; sweep < 50; sweep++) {
    let off = 0;
    for (let p = 0; p < 4; p++) for (let q = p + 1; q < 4; q++) off += a[p][q] * a[p][q];
    if (off < 1e-30) break;
    for (let p = 0; p < 4; p++) {
      for (let q = p + 1; q < 4; q++) {
        if (Math.abs(a[p][q]) < 1e-300) continue;
        const theta = (a[q][q] - a[p][p]) / (2 * a[p][q]);
        const t = Math.sign(theta || 1) / (Math.abs(theta) + Math.sqrt(theta * theta + 1));
        const c = 1 / Math.sqrt(t * t + 1);
        const s = t * c;
        for (let k = 0; k < 4; k++) {
          const [akp, akq] = [a[k][p], a[k][q]];
          a[k][p] = c * akp - s * akq;
          a[k][q] = s * akp + c * akq;
        }
        for (let k = 0; k < 4; k++) {
          const [apk, aqk] = [a[p][k], a[q][k]];
          a[p][k] = c * apk - s * aqk;
          a[q][k] = s * apk + c * aqk;
        }
        for (let k = 0; k < 4; k++) {
          const [vkp, vkq] = [v[k][p], v[k][q]];
          v[k][p] = c * vkp - s * vkq;
          v[k][q] = s * vkp + c * vkq;
        }
      }
    }
  }
  let best = 0;
  for (let i = 1; i < 4; i++) if (a[i][i] > a[best][best]) best = i;
  return v.map((row) => row[best]);
}
function bestRotation(source, target) {
  const s = [0, 1, 2].map(() => [0, 0, 0]);
  source.forEach((p, i) => {
    const [a, b] = [lonlatToXYZ(p), lonlatToXYZ(target[i])];
    for (let r = 0; r < 3; r++) for (let c = 0; c < 3; c++) s[r][c] += a[r] * b[c];
  });
  const [[xx, xy, xz], [yx, yy, yz], [zx, zy, zz]] = s;
  const [w, x, y, z] = topEigenvector([
    [xx + yy + zz, yz - zy, zx - xz, xy - yx],
    [yz - zy, xx - yy - zz, xy + yx, zx + xz],
    [zx - xz, xy + yx, -xx + yy - zz, yz + zy],
    [xy - yx, zx + xz, yz + zy, -xx - yy + zz]
  ]);
  return [
    [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
    [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
    [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]
  ];
}
function dragMaps(h, points, part, carry2, turn = null) {
  if (turn) return dragMaps(levelledHandle(h, turn), points, part, carry2).map((m) => compose(m, turn));
  if (h.kind === "point") {
    const final = points[0];
    let { scale = 1, rotation = 0 } = h;
    if (part > 0) {
      const turned = arrowTip(final, points[part], part === 1 ? "east" : "west");
      if (turned) ({ scale, rotation } = turned);
    }
    return [pointMap(h.position, final, scale, rotation)];
  }
  if (h.kind === "line") return [fromPoints(controlPoints(h), points)];
  if (!carry2) return h.vertices.map((v, i) => pointMap(v, points[i]));
  const r = bestRotation(h.vertices, points);
  const whole = fromRotation(r);
  return h.vertices.map((v, i) => compose(shortestTurn(matVec(r, lonlatToXYZ(v)), lonlatToXYZ(points[i])), whole));
}
function levelledHandle(h, turn) {
  const at = (p) => xyzToLonLat(applyXYZ(turn, lonlatToXYZ(p)));
  if (h.kind === "point") return { ...h, position: at(h.position) };
  if (h.kind === "line") return { ...h, start: at(h.start), end: at(h.end) };
  return { ...h, vertices: h.vertices.map(at) };
}

// edits.js
var MIN_LINE = 0.05;
var SAME_VERTEX = 1e-3;
var copy = (value) => JSON.parse(JSON.stringify(value));
var handlesOf = (doc2) => doc2.handles || [];
function newPoint(at) {
  return { kind: "point", position: [...at], target: [...at], rotation: 0, scale: 1 };
}
function newLine(start, end) {
  if (distance(start, end) < MIN_LINE) return null;
  return { kind: "line", start: [...start], end: [...end], rectify: false };
}
function newCage(clicked) {
  const vertices = clicked.filter((q, i) => i === 0 || distance(q, clicked[i - 1]) * DEG > SAME_VERTEX);
  return vertices.length >= 3 ? { kind: "cage", vertices: copy(vertices) } : null;
}
function addHandle(doc2, handle) {
  return { ...doc2, handles: [...handlesOf(doc2), copy(handle)] };
}
function removeHandle(doc2, index) {
  return { ...doc2, handles: handlesOf(doc2).filter((_, j) => j !== index) };
}
function dragPoints(drag, at) {
  const { pane, kind, part, original, grab } = drag;
  if (kind === "point" && (pane === "input" || part <= 0)) return carry(original, part === 0 ? original[0] : grab, at);
  if (kind === "point") {
    const pts2 = copy(original);
    pts2[part] = [...at];
    pts2[3 - part] = mirror(pts2[0], at);
    return pts2;
  }
  if (part === -1 || pane === "input" && kind === "line" && part === 1) return carry(original, grab, at);
  const pts = copy(original);
  pts[part] = [...at];
  if (pane === "input" && kind === "line") pts[1] = midpoint(pts[0], pts[2]);
  return pts;
}
function moveOnInput(doc2, index, points) {
  const next = copy(doc2);
  const h = next.handles[index];
  const pts = copy(points);
  if (h.kind === "point") {
    const unmoved = !h.target || h.target[0] === h.position[0] && h.target[1] === h.position[1];
    h.position = pts[0];
    if (unmoved) h.target = pts[0];
  } else if (h.kind === "line") {
    h.start = pts[0];
    h.end = pts[2];
  } else h.vertices = pts;
  return next;
}
function moveOnResult(doc2, index, part, points) {
  const next = copy(doc2);
  const h = next.handles[index];
  const pts = copy(points);
  if (h.kind === "point") {
    h.target = pts[0];
    if (part > 0) Object.assign(h, arrowTip(pts[0], pts[part], part === 1 ? "east" : "west") || {});
  } else if (h.kind === "line") {
    h.rectify = false;
    h.targets = pts;
  } else h.targets = pts;
  return next;
}
var REACH_RANGE = [0.5, 90];
function setReach(doc2, index, reach) {
  const h = doc2.handles[index];
  if (!h || h.kind !== "point" || !Number.isFinite(reach)) return doc2;
  const r = Math.round(Math.min(REACH_RANGE[1], Math.max(REACH_RANGE[0], reach)) * 100) / 100;
  return { ...doc2, handles: doc2.handles.map((x, i) => i === index ? { ...x, reach: r } : x) };
}

// view.js
var ZOOM_RATE = 15e-4;
var ZOOM_RANGE = [0.5, 64];
var clamp = (x, lo, hi) => Math.min(hi, Math.max(lo, x));
function fitView(width, height) {
  const k = Math.min(width, 2 * height);
  return { k, tx: (width - k) / 2, ty: (height - k / 2) / 2 };
}
function toScreen(view, [lon, lat]) {
  const { k, tx, ty } = view;
  return [tx + (lon + 180) / 360 * k, ty + (90 - lat) / 180 * (k / 2)];
}
function screenToLonLat(view, x, y) {
  const { k, tx, ty } = view;
  return [wrapLon((x - tx) / k * 360 - 180), clamp(90 - (y - ty) / (k / 2) * 180, -90, 90)];
}
function nearestX(view, x, near) {
  return x + Math.round((near - x) / view.k) * view.k;
}
function copies(view, width) {
  const { k, tx } = view;
  const out = [];
  for (let j = Math.floor(-tx / k); j <= Math.floor((width - tx) / k); j++) out.push(j * k);
  return out;
}
function screenPath(view, lonlats) {
  const pts = lonlats.map((q) => toScreen(view, q));
  for (let i = 1; i < pts.length; i++) pts[i][0] = nearestX(view, pts[i][0], pts[i - 1][0]);
  return pts;
}
function zoomAt(view, x, y, deltaY, width, height) {
  const { k, tx, ty } = view;
  const fitK = Math.min(width, 2 * height);
  const k2 = clamp(k * Math.exp(-deltaY * ZOOM_RATE), fitK * ZOOM_RANGE[0], fitK * ZOOM_RANGE[1]);
  const s = k2 / k;
  return { k: k2, tx: x - (x - tx) * s, ty: y - (y - ty) * s };
}
function panBy(view, dx, dy) {
  return { ...view, tx: view.tx + dx, ty: view.ty + dy };
}

// hit.js
var HIT = 9;
var HIT_EDGE = 6;
var clamp2 = (x, lo, hi) => Math.min(hi, Math.max(lo, x));
function segmentDistance(px, py, ax, ay, bx, by) {
  const dx = bx - ax;
  const dy = by - ay;
  const t = clamp2(((px - ax) * dx + (py - ay) * dy) / (dx * dx + dy * dy || 1), 0, 1);
  return Math.hypot(px - ax - t * dx, py - ay - t * dy);
}
function pointDistance(view, lonlat, x, y) {
  const [qx, qy] = toScreen(view, lonlat);
  return Math.hypot(nearestX(view, qx, x) - x, qy - y);
}
function onCurve(view, h, pts, x, y, tolerance = HIT_EDGE) {
  for (const c of curves(h, pts)) {
    const s = c.map((q) => toScreen(view, q));
    for (let j = 1; j < s.length; j++) {
      const ax = nearestX(view, s[j - 1][0], x);
      const bx = nearestX(view, s[j][0], ax);
      if (segmentDistance(x, y, ax, s[j - 1][1], bx, s[j][1]) <= tolerance) return true;
    }
  }
  return false;
}
function hitTest(view, handles, positions2, x, y, selected2) {
  let best = null;
  const order = handles.map((_, i) => i);
  if (selected2 >= 0 && selected2 < handles.length) order.unshift(selected2);
  for (const i of order) {
    positions2[i].forEach((q, j) => {
      const d = pointDistance(view, q, x, y);
      if (d <= HIT && (!best || d < best.d - 0.5)) best = { index: i, part: j, d };
    });
    if (best && best.index === selected2) return best;
  }
  if (best) return best;
  for (const i of order) {
    if (onCurve(view, handles[i], positions2[i], x, y)) return { index: i, part: -1 };
  }
  return null;
}
function onRing(view, centre, radius, x, y, tolerance = HIT_EDGE) {
  const s = circle(centre, radius).map((q) => toScreen(view, q));
  for (let j = 1; j < s.length; j++) {
    const ax = nearestX(view, s[j - 1][0], x);
    const bx = nearestX(view, s[j][0], ax);
    if (segmentDistance(x, y, ax, s[j - 1][1], bx, s[j][1]) <= tolerance) return true;
  }
  return false;
}

// live.js
var MAX_CONTROLS = 32;
var BASIS_CHANNELS = 7;
var MOVING_PIXELS = 256 * 256;
var VERTEX = `#version 300 es
in vec2 corner;
void main() { gl_Position = vec4(corner, 0.0, 1.0); }`;
var FRAGMENT = `#version 300 es
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
function createLive(canvas) {
  const gl = canvas.getContext("webgl2", { preserveDrawingBuffer: true, antialias: false, depth: false });
  if (!gl) return null;
  const program = gl.createProgram();
  gl.attachShader(program, compile(gl, gl.VERTEX_SHADER, VERTEX));
  gl.attachShader(program, compile(gl, gl.FRAGMENT_SHADER, FRAGMENT));
  gl.linkProgram(program);
  if (!gl.getProgramParameter(program, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(program));
  gl.useProgram(program);
  gl.bindBuffer(gl.ARRAY_BUFFER, gl.createBuffer());
  gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 3, -1, -1, 3]), gl.STATIC_DRAW);
  const corner = gl.getAttribLocation(program, "corner");
  gl.enableVertexAttribArray(corner);
  gl.vertexAttribPointer(corner, 2, gl.FLOAT, false, 0, 0);
  const at = (name) => gl.getUniformLocation(program, name);
  const uniforms = {};
  for (const name of ["basis", "source", "count", "width", "height", "step", "origin", "size", "maps"]) uniforms[name] = at(name);
  gl.uniform1i(uniforms.basis, 0);
  gl.uniform1i(uniforms.source, 1);
  const texture = (unit2, filter, wrapS) => {
    const t = gl.createTexture();
    gl.activeTexture(gl.TEXTURE0 + unit2);
    gl.bindTexture(gl.TEXTURE_2D, t);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, filter);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, filter);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, wrapS);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
    return t;
  };
  const basisTexture = texture(0, gl.NEAREST, gl.CLAMP_TO_EDGE);
  const sourceTexture = texture(1, gl.LINEAR, gl.REPEAT);
  let basis = null;
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
      while (basis.width / step * (basis.height / step) > pixels) step *= 2;
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
    }
  };
}

// look.js
var FOV_RANGE = [20, 120];
var START = Object.freeze({ yaw: 0, pitch: 0, fov: 90 });
var ZOOM_RATE2 = 15e-4;
var clamp3 = (x, lo, hi) => Math.min(hi, Math.max(lo, x));
function camera({ yaw, pitch }) {
  const [lon, lat] = [yaw * DEG, pitch * DEG];
  return {
    forward: lonlatToXYZ([yaw, pitch]),
    east: [-Math.sin(lon), Math.cos(lon), 0],
    north: [-Math.sin(lat) * Math.cos(lon), -Math.sin(lat) * Math.sin(lon), Math.cos(lat)]
  };
}
function focal(fov, width) {
  return width / (2 * Math.tan(fov * DEG / 2));
}
function ray(look, width, height, x, y) {
  const { forward, east, north } = camera(look);
  const f = focal(look.fov, width);
  const [dx, dy] = [x - (width - 1) / 2, y - (height - 1) / 2];
  return [0, 1, 2].map((i) => f * forward[i] + dx * east[i] - dy * north[i]);
}
function lonlatAt(look, width, height, x, y) {
  return xyzToLonLat(ray(look, width, height, x, y));
}
function dragLook(start, dx, dy, width) {
  const f = focal(start.fov, width);
  return { yaw: wrapLon(start.yaw - dx / f / DEG), pitch: clamp3(start.pitch + dy / f / DEG, -90, 90), fov: start.fov };
}
function zoomLook(look, deltaY) {
  return { ...look, fov: clamp3(look.fov * Math.exp(ZOOM_RATE2 * deltaY), FOV_RANGE[0], FOV_RANGE[1]) };
}
function lookText({ yaw, pitch, fov }) {
  return `yaw ${yaw.toFixed(2)}°, pitch ${pitch.toFixed(2)}°, ${fov.toFixed(2)}° across`;
}
var VERTEX2 = `#version 300 es
in vec2 corner;
void main() { gl_Position = vec4(corner, 0.0, 1.0); }`;
var FRAGMENT2 = `#version 300 es
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
function compile2(gl, type, text) {
  const shader = gl.createShader(type);
  gl.shaderSource(shader, text);
  gl.compileShader(shader);
  if (!gl.getShaderParameter(shader, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(shader));
  return shader;
}
function createLook(canvas) {
  const gl = canvas.getContext("webgl2", { preserveDrawingBuffer: true, antialias: false, depth: false });
  if (!gl) return null;
  const program = gl.createProgram();
  gl.attachShader(program, compile2(gl, gl.VERTEX_SHADER, VERTEX2));
  gl.attachShader(program, compile2(gl, gl.FRAGMENT_SHADER, FRAGMENT2));
  gl.linkProgram(program);
  if (!gl.getProgramParameter(program, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(program));
  gl.useProgram(program);
  gl.bindBuffer(gl.ARRAY_BUFFER, gl.createBuffer());
  gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 3, -1, -1, 3]), gl.STATIC_DRAW);
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
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.REPEAT);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
  let image = null;
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
    }
  };
}

// status.js
var FOLD_AFTER = 3;
function groupWarnings(warnings, kinds) {
  const groups = /* @__PURE__ */ new Map();
  (warnings || []).forEach((w, i) => {
    const kind = kinds && kinds[i] || "conflicts";
    if (!groups.has(kind)) groups.set(kind, []);
    groups.get(kind).push(w);
  });
  return [...groups].map(([kind, items2]) => ({ kind, items: items2 }));
}
function fold(items2, unfolded, limit = FOLD_AFTER) {
  const shown = unfolded || items2.length <= limit ? items2.slice() : items2.slice(0, limit);
  return { shown, more: items2.length - shown.length };
}
function warningView(warnings, kinds, unfolded = {}) {
  const open = unfolded.open || /* @__PURE__ */ new Set();
  const all = unfolded.all || /* @__PURE__ */ new Set();
  const { shown, more } = fold(groupWarnings(warnings, kinds), Boolean(unfolded.groups));
  const groups = shown.map(({ kind, items: items2 }) => {
    const single = items2.length === 1;
    const isOpen = !single && open.has(kind);
    const inside = isOpen ? fold(items2, all.has(kind)) : { shown: [], more: 0 };
    return { kind, count: items2.length, title: single ? items2[0] : `${items2.length} ${kind}`, open: isOpen, items: inside.shown, more: inside.more };
  });
  return { groups, more };
}
function duration(ms) {
  if (ms < 1e3) return `${Math.round(ms)} ms`;
  const s = ms / 1e3;
  return s < 10 ? `${s.toFixed(1)} s` : `${Math.round(s)} s`;
}
function startAction(now, cause, status2) {
  const s = status2 || {};
  return { at: now, cause, after: Math.max(Number(s.generation) || 0, Number(s.newest) || 0), busy: false };
}
function actionOnStatus(action, status2, now) {
  if (!action || !status2) return { action, latency: null };
  const generation = Number(status2.generation) || 0;
  const started = Number(status2.newest) > action.after;
  if (status2.state === "busy") return { action: started || action.busy ? { ...action, busy: true } : action, latency: null };
  if (status2.state === "idle" && generation > action.after) return { action: null, latency: now - action.at };
  if (status2.state === "error" && (action.busy || started)) return { action: null, latency: null };
  return { action, latency: null };
}
function actionOnDone(action, status2) {
  if (!action) return null;
  return action.busy || Number((status2 || {}).newest) > action.after ? action : null;
}
function latencyText(ms, cause) {
  if (ms === null || ms === void 0) return "";
  const what = { click: "the click", key: "the key", release: "the mouse release" }[cause] || "the edit";
  return `image ${duration(ms)} after ${what}`;
}
function headline(status2, latency) {
  const s = status2 || {};
  const parts = [];
  if (s.state === "busy") parts.push("computing...");
  else if (s.state === "error") parts.push(s.error || s.message || "the computation failed");
  else if (s.state === "idle") parts.push(`result ${s.result || s.message || ""}`.trim());
  if (s.state === "idle" && latency && latency.ms !== null) parts.push(latencyText(latency.ms, latency.cause));
  return parts.join(" · ");
}
function jobMessages(status2) {
  const s = status2 || {};
  const out = [];
  for (const name of ["suggest", "level", "straighten", "save"]) {
    const j = s[name];
    if (j && j.message && (j.state !== "error" || j.message !== s.error)) out.push(j.message);
  }
  return out;
}
function cursorFor(at) {
  if (at.dragging) return at.dragging === "split" ? "ew-resize" : "grabbing";
  if (at.space) return "grab";
  if (at.tool && at.tool !== "select" && at.pane === "input") return "crosshair";
  if (at.hit) return at.hit.part >= 0 ? "grab" : "move";
  if (at.ring) return "grab";
  if (at.suggestion) return "pointer";
  return "crosshair";
}

// suggest.js
var HIT_SUGGESTION = 7;
var suggestionArc = (s) => geodesic(s.start, s.end);
function suggestionDistance(view, s, x, y) {
  const pts = suggestionArc(s).map((q) => toScreen(view, q));
  let best = Infinity;
  for (let j = 1; j < pts.length; j++) {
    const ax = nearestX(view, pts[j - 1][0], x);
    const bx = nearestX(view, pts[j][0], ax);
    best = Math.min(best, segmentDistance(x, y, ax, pts[j - 1][1], bx, pts[j][1]));
  }
  return best;
}
function suggestionAt(view, suggestions2, x, y, tolerance = HIT_SUGGESTION) {
  let found = null;
  let best = tolerance;
  for (const s of suggestions2 || []) {
    const d = suggestionDistance(view, s, x, y);
    if (d <= best) [found, best] = [s, d];
  }
  return found;
}
function detectRunning(status2) {
  return ["suggest", "level", "straighten"].some((job) => Boolean(status2 && status2[job]) && status2[job].state === "running");
}

// video.js
function frameLabel(frame, count, interval) {
  const seconds = frame * interval;
  const time = seconds < 60 ? `${seconds.toFixed(2)} s` : `${Math.floor(seconds / 60)}:${(seconds % 60).toFixed(2).padStart(5, "0")}`;
  return `frame ${frame + 1} / ${count} · ${time}`;
}
function videoRunning(job) {
  return Boolean(job) && (job.state === "map" || job.state === "running");
}
function videoStatusText(job) {
  if (!job || !job.state) return "";
  if (job.state === "running") {
    const share = job.total ? ` (${Math.floor(100 * (job.done || 0) / job.total)}%)` : "";
    return `saving the video: ${job.done || 0} / ${job.total || "?"} frames${share}, ${(job.fps || 0).toFixed(1)} fps`;
  }
  return job.message || "";
}

// editor.js
var LIVE_REST_MS = 120;
var COLORS = {
  point: "#22c7ff",
  line: "#ff453a",
  cage: "#ffffff",
  selected: "#ffd60a",
  conflict: "#ff9f0a",
  kept: "#30d158",
  suggestion: "#bf5af2"
};
var DASHES = { conflict: [6, 4], kept: [10, 4, 2, 4], suggestion: [8, 5] };
var IMAGES = ["source", "preview", "folds"];
var TOOLS = [
  ["select", "Select", "V", "select, move, pan"],
  ["point", "Point", "P", "click to place a point handle"],
  ["line", "Line", "L", "press, drag, release to draw a line"],
  ["cage", "Cage", "C", "click the vertices; close on the first vertex, Enter or double-click"]
];
var STAGES = [
  ["draw", "Draw", "D", "the input only, to draw handles"],
  ["transform", "Transform", "T", "the result only, to move control points"],
  ["side", "Side by side", "B", "the input and the result"]
];
var SHORTCUTS = [
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
  ["Shift+Enter / Ctrl+Enter / Alt+Enter", "run the cell and select the next / run it / run it, insert a cell (passed on to JupyterLab)"]
];
var CHANGES_HANDLES = /* @__PURE__ */ new Set(["undo", "redo", "rectify_all", "rectify_line", "reset", "arrow", "load", "accept_suggestion", "accept_all", "level", "straighten"]);
var KEEPS_RESULT = /* @__PURE__ */ new Set(["save", "save_video", "cancel_video", "suggest", "drop_suggestions"]);
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
    unfolded: { open: /* @__PURE__ */ new Set(), all: /* @__PURE__ */ new Set(), groups: false },
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
    lookRenderer: void 0
  };
}
function render({ model, el: host }) {
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
    "data-generation": "0"
  });
  const spinner = el("span", { class: "ow-spinner", title: "computing" });
  const fileInput = el("input", { type: "file", accept: ".json,application/json", style: "display:none", onchange: () => loadFile(ed) });
  const toolbar = buildToolbar(ed, fileInput, spinner);
  const panes = ["input", "result"].map(buildPane);
  const panesBox = el("div", { class: "ow-panes" }, ...panes.map((p) => p.box));
  const message = el("div", { class: "ow-message" });
  const cursorInfo = el("span", { class: "ow-cursor" });
  const helpBox = buildHelp(ed);
  const liveCanvas = el("canvas", { class: "ow-live", hidden: "" });
  const frames = buildFrames(ed);
  root.append(toolbar, frames.box, panesBox, el("div", { class: "ow-status" }, message, cursorInfo), helpBox, liveCanvas);
  return { root, toolbar, spinner, fileInput, panes, panesBox, message, cursorInfo, helpBox, liveCanvas, frames };
}
function buildFrames(ed) {
  const slider = el("input", {
    type: "range",
    class: "ow-frame-slider",
    min: "0",
    max: "0",
    step: "1",
    value: "0",
    title: "The frame of the video to draw on",
    style: "flex: 1"
  });
  const label = el("span", { class: "ow-frame-label", style: "white-space: nowrap; font-variant-numeric: tabular-nums" });
  slider.addEventListener("input", () => showFrameLabel(ed, Number(slider.value)));
  slider.addEventListener("change", () => chooseFrame(ed, Number(slider.value)));
  const box = el("div", { class: "ow-frames", style: "display: flex; gap: 8px; align-items: center; margin-bottom: 4px" }, slider, label);
  return { box, slider, label };
}
function buildToolbar(ed, fileInput, spinner) {
  const group = (...buttons) => el("div", { class: "ow-group" }, ...buttons);
  const button = (action, label, title, onclick) => el("button", { "data-action": action, title, onclick }, label);
  const choice = (attr, choose) => ([name, label, key, what]) => el("button", { [attr]: name, title: `${label} (${key}): ${what}`, onclick: () => choose(ed, name) }, label);
  return el(
    "div",
    { class: "ow-toolbar" },
    group(...STAGES.map(choice("data-stage", setStage))),
    group(...TOOLS.map(choice("data-tool", setTool))),
    group(
      button("undo", "Undo", "Undo (Ctrl+Z)", () => command(ed, "undo")),
      button("redo", "Redo", "Redo (Ctrl+Shift+Z)", () => command(ed, "redo")),
      button("delete", "Delete", "Delete the selected handle (Delete)", () => deleteSelected(ed))
    ),
    group(
      button("rectify-all", "Rectify all lines", "Straighten every line together (A)", () => command(ed, "rectify_all")),
      button(
        "rectify-line",
        "Rectify selected line",
        "Straighten the selected line, hold the rest (S)",
        () => commandSelected(ed, "rectify_line")
      ),
      button("reset", "Reset selected", "Undo the selected handle's transformation (R)", () => commandSelected(ed, "reset"))
    ),
    group(
      button(
        "suggest",
        "Suggest lines",
        "Find straight edges in the panorama, shown dashed on the input: click one to add it as a line",
        () => command(ed, "suggest")
      ),
      button("accept-all", "Accept all", "Add every suggested line as a line handle (one edit)", () => command(ed, "accept_all")),
      button("drop-suggestions", "Drop", "Drop the suggested lines (Esc)", () => command(ed, "drop_suggestions")),
      button("level", "Level", "Find how the camera was tilted, from the vertical edges, and undo it (one edit)", () => command(ed, "level")),
      button(
        "straighten",
        "Straighten",
        "Level, find the room's or the street's structure (verticals, wall-floor and wall-ceiling edges) and straighten it: the lines used become the handles (one edit)",
        () => command(ed, "straighten")
      )
    ),
    group(
      button("fit", "Fit", "Fit the panorama to the view (F)", () => fit(ed)),
      button("split", "Split", "Compare: the input left of a slider, the result right of it", () => toggleLayer(ed, "split")),
      button("folds", "Folds", "Show where the result folds over", () => toggleLayer(ed, "showFolds")),
      button("handles", "Handles", "Show or hide the handles (H)", () => toggleHandles(ed)),
      button(
        "look",
        "Look around",
        "The result as a 360° viewer shows it: drag to look, the wheel to zoom (as omniwidget view draws it)",
        () => toggleLook(ed)
      )
    ),
    group(
      button("save", "Save", "Write the handles file next to the notebook", () => command(ed, "save")),
      button("download", "Download", "Download the handles file", () => download(ed)),
      button("load", "Load", "Load a handles file", () => fileInput.click()),
      button("full", "Full size", "Compute the result at the panorama's full size", () => command(ed, "full")),
      button(
        "save-video",
        "Save video",
        "Warp the whole video by these handles and write it next to it (clip.mp4: clip-rectified.mp4)",
        () => command(ed, "save_video")
      ),
      button("cancel-video", "Cancel", "Stop saving the video (nothing is written)", () => command(ed, "cancel_video")),
      button(
        "save-image",
        "Save image",
        "Write the full-size result next to the panorama (room.jpg: room-rectified.jpg) and download it",
        () => command(ed, "save_image")
      ),
      button("help", "?", "Keyboard shortcuts (?)", () => toggleHelp(ed)),
      fileInput
    ),
    spinner
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
      "While the editor has the keyboard, other keys do nothing (none reaches the notebook's command mode: 'd d' deletes no cell); Esc or a click outside the editor gives it back to the notebook."
    )
  );
}
var doc = (ed) => ed.model.get("handles") || { handles: [] };
var items = (ed) => doc(ed).handles || [];
var outputs = (ed) => ed.state.localOutputs || ed.model.get("outputs") || [];
var selected = (ed) => ed.model.get("selected");
var status = (ed) => ed.model.get("status") || {};
var suggestions = (ed) => ed.model.get("suggestions") || [];
function setPending(ed, n) {
  ed.state.pendingCount = n;
  ed.ui.root.dataset.pending = String(n);
}
function waitingForKernel(ed) {
  const { state } = ed;
  if (state.pendingCount > 0 && performance.now() - state.pendingSince > 1e4) setPending(ed, 0);
  if (state.pendingCount === 0) return false;
  showLocal(ed, "one moment: the kernel is applying the last command");
  return true;
}
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
  if (!KEEPS_RESULT.has(op)) state.action = { ...startAction(performance.now(), cause, status(ed)), op };
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
  if (content && content.done !== void 0 && state.action && state.action.op === content.done) {
    state.action = actionOnDone(state.action, status(ed));
  }
  if (content && content.done !== void 0 && CHANGES_HANDLES.has(content.done) && state.pendingCount > 0) {
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
  setTimeout(() => URL.revokeObjectURL(a.href), 1e3);
}
function downloadImage(ed, content, buffer) {
  const blob = new Blob([buffer], { type: content.mime || "application/octet-stream" });
  const a = el("a", { href: URL.createObjectURL(blob), download: content.name || "panorama-rectified.png" });
  ed.ui.root.append(a);
  a.click();
  a.remove();
  ed.ui.root.dataset.savedImage = content.name || "";
  setTimeout(() => URL.revokeObjectURL(a.href), 1e4);
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
function showHandlesDocument(ed) {
  ed.ui.root.dataset.handles = JSON.stringify(doc(ed));
}
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
    ["msg:custom", (content, buffers) => onMessage(ed, content, buffers)]
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
      if (d && d.type === "move" && d.pane === "result" && d.moved && d.solvedAt !== JSON.stringify(d.points)) liveFrame(ed, d);
      else state.liveShown = false;
    }
    if (name === "source" && !state.view) layout(ed);
    draw(ed);
  })();
}
async function onStatus(ed) {
  const { state, ui } = ed;
  state.localNote = "";
  const s = status(ed);
  if (s.state !== "idle") state.action = actionOnStatus(state.action, s, performance.now()).action;
  updateStatus(ed);
  draw(ed);
  if (s.state !== "busy") state.dragSolve = 0;
  if (s.state === "error") state.liveShown = false;
  if (s.state !== "idle") return;
  await null;
  await Promise.all([state.decoding.preview, state.decoding.folds]);
  if (!state.drag) state.liveShown = false;
  await new Promise((resolve) => requestAnimationFrame(resolve));
  if (status(ed) !== s) return;
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
  if (ed.model.get("stage") === "transform") setTool(ed, "select");
  layout(ed);
  updateStatus(ed);
}
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
function requestLive(ed, i) {
  const want = `${status(ed).generation}:${i}`;
  if (!ed.live || i < 0 || ed.state.liveWanted === want) return;
  ed.state.liveWanted = want;
  ed.model.send({ op: "live", index: i });
}
function onLiveBasis(ed, content, buffer) {
  const { state, ui } = ed;
  if (!ed.live || content.generation !== status(ed).generation || !ed.live.setBasis(content, buffer)) return;
  state.liveBasis = content;
  ui.root.dataset.liveBasis = `${content.generation}:${content.index}`;
  ui.root.dataset.liveRegion = JSON.stringify({ origin: content.origin, width: content.width, height: content.height, size: content.size });
  const d = state.drag;
  if (d && d.type === "move" && d.pane === "result" && d.moved) liveFrame(ed, d);
}
function liveFrame(ed, d) {
  const { state } = ed;
  const b = state.liveBasis;
  if (!b || b.generation !== status(ed).generation) requestLive(ed, d.index);
  if (!b || b.index !== d.index) return;
  let maps;
  try {
    maps = dragMaps(items(ed)[d.index], d.points, d.part, b.carry, b.turn);
  } catch (err) {
    return;
  }
  if (maps.length === 1 && b.controls > 1) maps = Array(b.controls).fill(maps[0]);
  if (maps.length !== b.controls) return;
  state.liveMaps = maps.map(inverse);
  state.liveFine = false;
  clearTimeout(state.liveRest);
  state.liveRest = setTimeout(() => {
    if (state.drag === d) solveDuringDrag(ed, d);
    if (!state.liveShown) return;
    state.liveMaps = state.liveLast;
    state.liveFine = true;
    draw(ed);
  }, LIVE_REST_MS);
  draw(ed);
}
function solveDuringDrag(ed, d) {
  const { state } = ed;
  if (state.dragSolve && performance.now() - state.dragSolve < 5e3) return;
  if (status(ed).state === "busy" || state.pendingCount > 0) return;
  state.dragSolve = performance.now();
  d.solved = true;
  d.solvedAt = JSON.stringify(d.points);
  ed.model.send({ op: "drag", handles: moveOnResult(doc(ed), d.index, d.part, d.points) });
}
var visible = (ed) => ed.ui.panes.filter((p) => ed.model.get("stage") === "side" || p.kind === "input" === (ed.model.get("stage") === "draw"));
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
      ui.root.dataset.liveMs = (performance.now() - started).toFixed(1);
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
function toggleLook(ed, on = !ed.state.looking) {
  const { state } = ed;
  if (on && state.lookRenderer === void 0) {
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
  if (on && ed.model.get("stage") === "draw") setStage(ed, "transform");
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
function moveLook(ed, p, x, y) {
  const { state } = ed;
  const d = state.drag;
  if (d && d.type === "look") {
    state.look = dragLook(d.look, x - d.x, y - d.y, p.w);
    draw(ed);
  }
  const [lon, lat] = lonlatAt(state.look, p.w, p.h, x - 0.5, y - 0.5);
  ed.ui.cursorInfo.textContent = `lon ${lon.toFixed(2)}°, lat ${lat.toFixed(2)}°`;
}
function drawImageCopies(ed, p, image, offsets) {
  const { k, tx, ty } = ed.state.view;
  for (const dx of offsets) p.ctx.drawImage(image, tx + dx, ty, k, k / 2);
}
function drawLive(ed, p, offsets) {
  const { k, tx, ty } = ed.state.view;
  const { origin, size, step } = ed.state.liveDrawn;
  const canvas = ed.ui.liveCanvas;
  const scale = k / size;
  const [w, h] = [canvas.width * step * scale, canvas.height * step * scale];
  for (const dx of [offsets[0] - k, ...offsets]) p.ctx.drawImage(canvas, tx + dx + origin[1] * scale, ty + origin[0] * scale, w, h);
}
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
function reachOf(ed, i) {
  const d = ed.state.drag;
  if (d && d.type === "reach" && d.index === i) return d.reach;
  const h = items(ed)[i];
  if (h && h.reach != null) return h.reach;
  const given = (status(ed).reaches || [])[i];
  return given != null ? given : 15;
}
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
  p.canvas.dataset.reach = reachOf(ed, i).toFixed(2);
}
function drawSuggestions(ed, p, offsets) {
  const ctx = p.ctx;
  ctx.lineWidth = 2;
  ctx.strokeStyle = COLORS.suggestion;
  ctx.setLineDash(DASHES.suggestion);
  for (const s of suggestions(ed)) strokePath(ed, p, suggestionArc(s), offsets);
  ctx.setLineDash([]);
}
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
  const pts = screenPath(ed.state.view, lonlats);
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
function showStatusArea(ed, s) {
  const { state, ui } = ed;
  const message = ui.message;
  const line = (cls, text) => el("div", { class: cls, title: text }, text);
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
  const toggle = (label, onclick, title = "") => el("button", { class: "ow-toggle", type: "button", title, onclick: (e) => (e.stopPropagation(), onclick(), updateStatus(ed)) }, label);
  const rows = [];
  for (const g of view.groups) {
    const all = (s.warnings || []).filter((_, i) => (kinds[i] || "conflicts") === g.kind);
    const row = el("div", { class: "ow-warning", "data-kind": g.kind, title: all.join("\n") });
    if (g.count === 1) row.append(el("span", { class: "ow-warning-text" }, `⚠ ${g.title}`));
    else {
      const flip = () => unfolded.open.has(g.kind) ? unfolded.open.delete(g.kind) : unfolded.open.add(g.kind);
      row.append(toggle(`${g.open ? "▾" : "▸"} ⚠ ${g.title}`, flip, g.open ? "fold them" : "show them"));
    }
    rows.push(row);
    for (const w of g.items) rows.push(el("div", { class: "ow-warning ow-warning-item", title: w }, el("span", { class: "ow-warning-text" }, w)));
    if (g.more > 0) rows.push(el("div", { class: "ow-warning-item" }, toggle(`show ${g.more} more`, () => unfolded.all.add(g.kind))));
    else if (g.open && unfolded.all.has(g.kind) && g.count > 3) rows.push(el("div", { class: "ow-warning-item" }, toggle("show fewer", () => unfolded.all.delete(g.kind))));
  }
  const last = rows[rows.length - 1];
  if (view.more > 0) last.append(toggle(`show ${view.more} more`, () => unfolded.groups = true, "the other kinds of warnings"));
  else if (unfolded.groups && groupCount(s) > 3) last.append(toggle("show fewer", () => unfolded.groups = false));
  return rows;
}
var groupCount = (s) => new Set(s.warning_kinds || []).size;
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
  ui.root.dataset.video = s.video && s.video.state || "";
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
function toggleLayer(ed, name) {
  ed.state[name] = !ed.state[name];
  draw(ed);
}
function toggleHandles(ed) {
  ed.state.showHandles = !ed.state.showHandles;
  updateStatus(ed);
  draw(ed);
}
var targetOf = (e) => {
  const node = typeof e.composedPath === "function" ? e.composedPath()[0] : e.target;
  return node instanceof Node ? node : null;
};
var focusedIn = (root) => {
  const home = root.getRootNode();
  return home instanceof Document || home instanceof ShadowRoot ? home.activeElement : null;
};
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
        e.stopPropagation();
        e.preventDefault();
      }
    };
    window.addEventListener("pointerdown", state.closeHelp, true);
  } else if (state.closeHelp) {
    window.removeEventListener("pointerdown", state.closeHelp, true);
    state.closeHelp = null;
  }
}
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
function showCursor(ed, p, e) {
  const { state } = ed;
  const [x, y] = pointerAt(p, e);
  const d = state.drag;
  const looking = p.kind === "result" && state.looking;
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
  p.canvas.dataset.cursor = cursor;
}
function pointerAt(p, e) {
  const r = p.canvas.getBoundingClientRect();
  return [e.clientX - r.left, e.clientY - r.top];
}
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
    command(ed, "accept_suggestion", { key: suggested.key });
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
    solvedAt: ""
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
function hover(ed, p, x, y) {
  const { state } = ed;
  if (p.kind === "result" && state.showHandles) {
    const near = hit(ed, p, x, y);
    if (near) requestLive(ed, near.index);
  }
  const all = items(ed);
  const kept = state.showHandles ? status(ed).kept || [] : [];
  const i = kept.find((j) => j < all.length && onCurve(state.view, all[j], positions(ed, j, p.kind), x, y));
  let title = i === void 0 ? "" : (status(ed).warnings || []).filter((w) => w.includes(`handles[${i}]`)).join("\n");
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
    commit(ed, setReach(doc(ed), d.index, d.reach));
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
    closeCage(ed);
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
var SUPPRESS = "data-lm-suppress-shortcuts";
var passesToJupyter = (e) => e.key === "Enter" && (e.shiftKey || e.ctrlKey || e.metaKey || e.altKey) || // run the cell
(e.ctrlKey || e.metaKey) && !e.altKey && !e.shiftKey && (e.key === "s" || e.key === "S");
function wireFocus(ed) {
  const { root } = ed.ui;
  function onWindowKeydown(e) {
    if (!root.isConnected) return listenToWindow(false);
    const target = targetOf(e);
    if (!(target instanceof Element && root.contains(target))) return;
    const holders = [root, target];
    if (passesToJupyter(e)) {
      for (const node of holders) node.removeAttribute(SUPPRESS);
      setTimeout(() => holders.forEach((node) => node.setAttribute(SUPPRESS, "true")));
    } else for (const node of holders) node.setAttribute(SUPPRESS, "true");
  }
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
    if (e.relatedTarget instanceof Node && root.contains(e.relatedTarget)) return;
    listenToWindow(false);
    ed.state.space = false;
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
  if (passesToJupyter(e)) return;
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
function escape(ed) {
  const { state } = ed;
  const d = state.drag;
  if (!d && !state.drawing && !state.help) return suggestions(ed).length ? command(ed, "drop_suggestions") : releaseFocus(ed);
  if (d) {
    state.drag = null;
    if (d.type === "pan") state.view = d.view;
    if (d.type === "move") state.liveShown = false;
  }
  cancelDrawing(ed);
  if (state.help) toggleHelp(ed);
  draw(ed);
}
function releaseFocus(ed) {
  const { root } = ed.ui;
  const home = root.closest(".jp-Cell") || root.parentElement && root.parentElement.closest("[tabindex]");
  const focused = focusedIn(root);
  if (focused && root.contains(focused)) focused.blur();
  if (home) home.focus({ preventScroll: true });
}
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
var editor_default = { render };
export {
  editor_default as default
};
