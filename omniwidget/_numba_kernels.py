"""The compiled per-pixel kernels themselves (numba), imported by :mod:`omniwidget.raster._kernels` on first use.

They are module-level functions, so numba's on-disk cache (``cache=True``) finds them again
in every new process: a kernel is compiled once per installation and signature, not once
per process, and its cache files are rewritten in place rather than added to. Where the
package's own folder cannot be written (a read-only site-packages), numba keeps the cache
in the user's cache folder instead (or in ``NUMBA_CACHE_DIR``); and in omniwidget's own
user cache when that folder is not the user's alone (:func:`omniwidget._native.secure_numba_cache`,
which :mod:`omniwidget._native` calls when it imports this module, before any kernel runs:
numba unpickles its index files). Importing this module
imports numba; nothing else in omniwidget does (but :mod:`omniwidget._native` when it
compiles a kernel's native copy, in a process that has just run it through numba). No
kernel allocates (scratch arrays are passed in): their native copies run without numba's
runtime.
"""

from __future__ import annotations

import math

from numba import njit

#: Weights at most this are skipped (the numpy path skips a control only where it is below
#: :data:`omniwidget.raster.blend.NEGLIGIBLE` over a whole block of rows; both are far below
#: what a pixel can show).
_NEGLIGIBLE = 1e-9


@njit(nogil=True, cache=True, inline="always")
def corner_shares(planes, f, x, y, z):  # pragma: no cover
    """Barycentric coordinates of (x, y, z) in face f: b_i ∝ max(p · planes[f, i + 1], 0)."""
    s0 = max(planes[f, 0, 0] * x + planes[f, 0, 1] * y + planes[f, 0, 2] * z, 0.0)
    s1 = max(planes[f, 1, 0] * x + planes[f, 1, 1] * y + planes[f, 1, 2] * z, 0.0)
    s2 = max(planes[f, 2, 0] * x + planes[f, 2, 1] * y + planes[f, 2, 2] * z, 0.0)
    total = s0 + s1 + s2
    if total <= 0.0:
        total = 1.0
    return s1 / total, s2 / total, s0 / total


@njit(nogil=True, cache=True, inline="always")
def homogeneous(x, y, z):  # pragma: no cover
    """[u : v] of the unit vector (x, y, z) as coords.xyz_to_homogeneous chooses it: (ur, ui, vr, vi)."""
    if z <= 0.0:
        return x, y, 1.0 - z, 0.0
    return 1.0 + z, 0.0, x, -y


@njit(nogil=True, cache=True, inline="always")
def weighted_image(mats, j, w, ur, ui, vr, vi):  # pragma: no cover
    """``w`` times the unit vector M_j([u : v]): one term of eq. (2)'s sum, (x, y, z)."""
    ar, ai, br, bi = mats[j, 0], mats[j, 1], mats[j, 2], mats[j, 3]
    cr, ci, dr, di = mats[j, 4], mats[j, 5], mats[j, 6], mats[j, 7]
    big_ur = ar * ur - ai * ui + br * vr - bi * vi
    big_ui = ar * ui + ai * ur + br * vi + bi * vr
    big_vr = cr * ur - ci * ui + dr * vr - di * vi
    big_vi = cr * ui + ci * ur + dr * vi + di * vr
    uu = big_ur * big_ur + big_ui * big_ui
    vv = big_vr * big_vr + big_vi * big_vi
    share = w / (uu + vv)  # the unit vector (2 U V̄, |U|² - |V|²) / (|U|² + |V|²)
    return 2.0 * share * (big_ur * big_vr + big_ui * big_vi), 2.0 * share * (big_ui * big_vr - big_ur * big_vi), share * (uu - vv)


@njit(nogil=True, cache=True, inline="always")
def blend_pixel(f, x, y, z, planes, corners, weights, mats):  # pragma: no cover
    """Eq. (2) at the unit vector (x, y, z) in face f: the source's (lon, lat) in radians."""
    b0, b1, b2 = corner_shares(planes, f, x, y, z)
    i0, i1, i2 = corners[f, 0], corners[f, 1], corners[f, 2]
    ur, ui, vr, vi = homogeneous(x, y, z)
    sum_r = 0.0
    sum_i = 0.0
    sum_z = 0.0
    for j in range(weights.shape[1]):
        w = b0 * weights[i0, j] + b1 * weights[i1, j] + b2 * weights[i2, j]
        if w <= _NEGLIGIBLE:
            continue
        tx, ty, tz = weighted_image(mats, j, w, ur, ui, vr, vi)
        sum_r += tx
        sum_i += ty
        sum_z += tz
    return math.atan2(sum_i, sum_r), math.atan2(sum_z, math.sqrt(sum_r * sum_r + sum_i * sum_i))


@njit(nogil=True, cache=True)
def blend_rows(r0, r1, face, planes, corners, weights, mats, cos_lon, sin_lon, cos_lat, sin_lat, kx, x0, y0, out):  # pragma: no cover
    for r in range(r0, r1):
        for c in range(face.shape[1]):
            lon, lat = blend_pixel(
                face[r, c], cos_lat[r] * cos_lon[c], cos_lat[r] * sin_lon[c], sin_lat[r], planes, corners, weights, mats
            )
            out[r, c, 0] = lon * kx + x0
            out[r, c, 1] = y0 - lat * kx


@njit(nogil=True, cache=True, inline="always")
def walk_to(g, x, y, z, planes, slack, neighbours, steps):  # pragma: no cover
    """The face holding (x, y, z), walked to from face g across the edges it lies beyond; -1 after ``steps`` faces.

    A visibility walk: on a Delaunay mesh of the sphere (a convex hull, as the adaptive
    mesh is) it cannot cycle, and from a nearby pixel's face it takes a step or two.
    """
    for n in range(steps + 1):
        worst, across = 0.0, -1
        for e in range(3):
            s = planes[g, e, 0] * x + planes[g, e, 1] * y + planes[g, e, 2] * z + slack[g, e]
            if s < worst:
                worst, across = s, e
        if across < 0:
            return g
        if n == steps:
            break
        g = neighbours[g, across]
    return -1


@njit(nogil=True, cache=True)
def walk_blend_rows(
    r0,
    r1,
    seed,
    planes,
    slack,
    neighbours,
    walk,
    corners,
    weights,
    mats,
    cos_lon,
    sin_lon,
    cos_lat,
    sin_lat,
    kx,
    x0,
    y0,
    out,
    face,
    missed,
):  # pragma: no cover
    first = walk_to(seed, cos_lat[r0] * cos_lon[0], cos_lat[r0] * sin_lon[0], sin_lat[r0], planes, slack, neighbours, planes.shape[0])
    for r in range(r0, r1):
        g = first
        for c in range(face.shape[1]):
            x = cos_lat[r] * cos_lon[c]
            y = cos_lat[r] * sin_lon[c]
            z = sin_lat[r]
            f = walk_to(g, x, y, z, planes, slack, neighbours, walk) if g >= 0 else -1
            face[r, c] = f
            if f < 0:
                missed[r, c] = True
                continue
            if c == 0:
                first = f  # the next row starts from here
            g = f
            lon, lat = blend_pixel(f, x, y, z, planes, corners, weights, mats)
            out[r, c, 0] = lon * kx + x0
            out[r, c, 1] = y0 - lat * kx


@njit(nogil=True, cache=True)
def blend_cells(
    n0,
    n1,
    cell_r,
    cell_c,
    step,
    samples,
    planes,
    slack,
    neighbours,
    walk,
    corners,
    weights,
    mats,
    cos_lon,
    sin_lon,
    cos_lat,
    sin_lat,
    kx,
    x0,
    y0,
    out,
    missed,
):  # pragma: no cover
    for n in range(n0, n1):
        i, j = cell_r[n], cell_c[n]
        g = samples[i, j]
        for r in range(i * step, (i + 1) * step):
            for c in range(j * step, (j + 1) * step):
                x = cos_lat[r] * cos_lon[c]
                y = cos_lat[r] * sin_lon[c]
                z = sin_lat[r]
                f = walk_to(g, x, y, z, planes, slack, neighbours, walk)
                if f < 0:
                    missed[r, c] = True
                    continue
                g = f  # the next pixel starts from its neighbour's face
                lon, lat = blend_pixel(f, x, y, z, planes, corners, weights, mats)
                out[r, c, 0] = lon * kx + x0
                out[r, c, 1] = y0 - lat * kx


@njit(nogil=True, cache=True)
def interpolate_rows(
    r0, r1, shift, step, exact, column, part, base_x, src_width, per_degree, lat, pad, out, row_x, row_y
):  # pragma: no cover
    """``row_x`` and ``row_y``: scratch of ``shift.shape[1]`` float64 each (no kernel allocates: :mod:`omniwidget._native`)."""
    rows_c, cols_c = exact.shape
    for r in range(r0, r1):
        yc = min(max((r + 0.5) / step - 0.5, 0.0), rows_c - 1.0)
        i0 = min(int(yc), rows_c - 2) if rows_c > 1 else 0
        fy = yc - i0
        for j in range(shift.shape[1]):  # the samples' displacements interpolated to this row
            row_x[j] = shift[i0, j, 0] + fy * (shift[i0 + 1, j, 0] - shift[i0, j, 0])
            row_y[j] = shift[i0, j, 1] + fy * (shift[i0 + 1, j, 1] - shift[i0, j, 1])
        base_y = (90.0 - lat[r]) * per_degree - 0.5 + pad
        skip = exact[r // step]
        for c in range(out.shape[1]):
            if skip[c // step]:
                continue
            j0, fx = column[c], part[c]
            x = base_x[c] + row_x[j0] + fx * (row_x[j0 + 1] - row_x[j0])  # x + 0.5 of the unpadded source
            if x >= src_width:
                x -= src_width
            elif x < 0.0:
                x += src_width
            out[r, c, 0] = x - 0.5 + pad
            out[r, c, 1] = base_y + row_y[j0] + fx * (row_y[j0 + 1] - row_y[j0])


@njit(nogil=True, cache=True)
def fold_rows(r0, r1, coordinates, src_width, offset, top, bottom, mask):  # pragma: no cover
    width = coordinates.shape[1]
    half = 0.5 * src_width
    for r in range(max(r0, 1), min(r1, coordinates.shape[0] - 1)):
        for c in range(width):
            east = c + 1 if c + 1 < width else 0
            west = c - 1 if c > 0 else width - 1
            dx_e = coordinates[r, east, 0] - coordinates[r, west, 0]
            if dx_e > half:  # longitudes wrap
                dx_e -= src_width
            elif dx_e < -half:
                dx_e += src_width
            dy_e = coordinates[r, east, 1] - coordinates[r, west, 1]
            dx_n = coordinates[r - 1, c, 0] - coordinates[r + 1, c, 0]
            if dx_n > half:
                dx_n -= src_width
            elif dx_n < -half:
                dx_n += src_width
            dy_n = coordinates[r - 1, c, 1] - coordinates[r + 1, c, 1]
            y = coordinates[r, c, 1] - offset
            # lon grows with x, lat against y: the determinant in [lon, lat] is minus this one
            mask[r, c] = (dx_e * dy_n - dx_n * dy_e >= 0.0) and top < y < bottom


@njit(nogil=True, cache=True)
def paint_runs(run_face, flat_start, length, out):  # pragma: no cover
    for i in range(run_face.shape[0]):
        start = flat_start[i]
        for j in range(start, start + length[i]):
            out[j] = run_face[i]


@njit(nogil=True, cache=True)
def strongest(rows, cols, face, planes, corners, weights, cos_lon, sin_lon, cos_lat, sin_lat, out):  # pragma: no cover
    for n in range(rows.shape[0]):
        r, c = rows[n], cols[n]
        f = face[r, c]
        x = cos_lat[r] * cos_lon[c]
        y = cos_lat[r] * sin_lon[c]
        z = sin_lat[r]
        b0, b1, b2 = corner_shares(planes, f, x, y, z)
        i0, i1, i2 = corners[f, 0], corners[f, 1], corners[f, 2]
        for j in range(weights.shape[1]):
            w = b0 * weights[i0, j] + b1 * weights[i1, j] + b2 * weights[i2, j]
            if w > out[j]:
                out[j] = w


@njit(nogil=True, cache=True)
def split_rows(r0, r1, face, planes, corners, weights, mats, slot, cos_lon, sin_lon, cos_lat, sin_lat, fixed, moving):  # pragma: no cover
    """Eq. (2)'s sum split for a live drag: the fixed controls' terms summed, the moving controls' weights apart.

    ``slot[j]`` is control j's column in ``moving`` or -1 for a fixed control; ``fixed`` gets
    the un-normalised sum of the fixed controls' terms.
    """
    for r in range(r0, r1):
        for c in range(face.shape[1]):
            f = face[r, c]
            x = cos_lat[r] * cos_lon[c]
            y = cos_lat[r] * sin_lon[c]
            z = sin_lat[r]
            b0, b1, b2 = corner_shares(planes, f, x, y, z)
            i0, i1, i2 = corners[f, 0], corners[f, 1], corners[f, 2]
            ur, ui, vr, vi = homogeneous(x, y, z)
            sum_r = 0.0
            sum_i = 0.0
            sum_z = 0.0
            for j in range(weights.shape[1]):
                w = b0 * weights[i0, j] + b1 * weights[i1, j] + b2 * weights[i2, j]
                if slot[j] >= 0:
                    moving[r, c, slot[j]] = w
                    continue
                if w <= _NEGLIGIBLE:
                    continue
                tx, ty, tz = weighted_image(mats, j, w, ur, ui, vr, vi)
                sum_r += tx
                sum_i += ty
                sum_z += tz
            fixed[r, c, 0] = sum_r
            fixed[r, c, 1] = sum_i
            fixed[r, c, 2] = sum_z



@njit(nogil=True, cache=True)
def fill_rows(r0, r1, coordinates, held, filled, blend, i0, fx, j0, fy, src_width, offset):  # pragma: no cover
    """The harmonic fill (:meth:`omniwidget.method.harmonic.HarmonicFill.apply`) on rows r0..r1 of source pixel coordinates, in place."""
    nodes = held.shape[1]
    kx = 2.0 * math.pi / src_width
    x0 = 0.5 * src_width - 0.5 + offset
    y0 = 0.25 * src_width - 0.5 + offset
    for r in range(r0, r1):
        ja = j0[r]
        jb = ja + 1
        b_row = fy[r]
        a_row = 1.0 - b_row
        for c in range(coordinates.shape[1]):
            ia = i0[c]
            ib = ia + 1 if ia + 1 < nodes else 0
            if held[ja, ia] and held[ja, ib] and held[jb, ia] and held[jb, ib]:
                continue  # every node round it held: the blend as it is
            b_col = fx[c]
            a_col = 1.0 - b_col
            w00, w01, w10, w11 = a_row * a_col, a_row * b_col, b_row * a_col, b_row * b_col
            share = w00 * held[ja, ia] + w01 * held[ja, ib] + w10 * held[jb, ia] + w11 * held[jb, ib]
            lon = (coordinates[r, c, 0] - x0) * kx
            lat = (y0 - coordinates[r, c, 1]) * kx
            cos_lat = math.cos(lat)
            p0 = share * cos_lat * math.cos(lon)
            p1 = share * cos_lat * math.sin(lon)
            p2 = share * math.sin(lat)
            for k in range(3):
                f = w00 * filled[ja, ia, k] + w01 * filled[ja, ib, k] + w10 * filled[jb, ia, k] + w11 * filled[jb, ib, k]
                g = w00 * blend[ja, ia, k] + w01 * blend[ja, ib, k] + w10 * blend[jb, ia, k] + w11 * blend[jb, ib, k]
                if k == 0:
                    p0 += f - share * g
                elif k == 1:
                    p1 += f - share * g
                else:
                    p2 += f - share * g
            coordinates[r, c, 0] = math.atan2(p1, p0) / kx + x0
            coordinates[r, c, 1] = y0 - math.atan2(p2, math.sqrt(p0 * p0 + p1 * p1)) / kx
