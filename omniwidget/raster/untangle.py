"""No fold-over, ever: where a blend turns the image over, the map is untangled there.

The blend of eq. (2) is not guaranteed one-to-one (the paper's Sec. 5 and Fig. 15): where
the handles' maps disagree and their weights change fast, part of the sphere is shown
turned over. :func:`untangle` finds each turned-over patch of the output grid (the same
rule as :func:`~omniwidget.raster.fold.fold_over`), takes a window around it whose rim the
blend shows one-to-one, and replaces the map inside by a piecewise-linear map on a grid of
the window's pixels that agrees with the blend on the rim and turns no triangle over: the
untangling of Garanzha, Kaporin, Kudryavtseva, Protais, Ray and Sokolov, "Foldover-free
maps in 50 lines of code" (ACM Trans. Graph. 40(4), 2021), whose regularised energy
(their eq. 2-3, with the barrier ``χ(D, ε) = (D + sqrt(ε² + D²)) / 2``) is minimised while
``ε`` shrinks until every triangle's Jacobian determinant is positive, and then once more
for the distortion. Every handle keeps its map outside the windows, and inside them too
where it can: the grid cells that a marked line, a cage's inside or a point's disk fall in
(``keep``) keep the blend's map and the window is untangled around them. Only where the
blend folds on such a pixel itself does it give way (:attr:`Patch.keeps_lines`;
:attr:`Patch.moved` says how far the map moved in the window).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from .._lazy import lazy
from ..sphere import coords
from .fold import turned_over
from .warping import PAD, GridInverse, coordinates_lonlat

if TYPE_CHECKING:
    import scipy.sparse.linalg as spla
    from scipy import ndimage, sparse
else:
    ndimage = lazy("scipy.ndimage")
    sparse = lazy("scipy.sparse")
    spla = lazy("scipy.sparse.linalg")

__all__ = ["MARGIN", "Patch", "apply_patches", "line_mask", "line_pixels", "patched_inverse", "untangle"]

#: Pixels of clean map kept around a turned-over patch at the first try (then doubled).
MARGIN = 6
#: The most vertices along a side of a window's grid; larger windows take a coarser grid.
GRID_SIDE = 32
#: A turned-over patch wider or taller than the output's width over this is not untangled.
LARGEST = 6
#: A window reaches this many times the turned-over patch's size beyond it (at least :data:`MARGIN`), so that the
#: untangled map has room to spread what it gathers.
SPREAD = 1.0
#: The regularisation ``ε`` at which the energy is a barrier: no step may turn a triangle over.
BARRIER = 1e-12
#: Stages of the untangling, ``ε`` ten times smaller each (a grid not untangled by then is given up).
EPSILON_ROUNDS = 6
#: Quasi-Newton steps per stage of the untangling.
ITERATIONS = 60
#: Weight of the area term against the shape term in the untangling energy (their ``λ``).
AREA_WEIGHT = 0.5


@dataclass(frozen=True, eq=False)
class Patch:
    """One window of the output grid where the map was untangled.

    Attributes
    ----------
    rows : slice
        Output rows of the window.
    cols : ndarray of int64, shape (w,)
        Its output columns, in order (they wrap at the seam).
    xyz : ndarray of float64, shape (h, w, 3)
        The source direction each pixel of the window shows, untangled.
    moved : float
        The largest angle between the untangled map and the blend inside the window,
        degrees: how far the handles whose maps meet there gave way.
    keeps_lines : bool
        Whether the marked lines through the window kept the blend's map (``keep``); when
        not, they give way there too.
    """

    rows: slice
    cols: NDArray[np.int64]
    xyz: NDArray[np.float64]
    moved: float
    keeps_lines: bool = True

    def covers(self, px: NDArray[np.int64]) -> NDArray[np.bool_]:
        """Which output pixels ``(x, y)`` (n, 2) lie in the window."""
        return (px[:, 1] >= self.rows.start) & (px[:, 1] < self.rows.stop) & np.isin(px[:, 0], self.cols)


def untangle(
    coordinates: NDArray[np.float32],
    mask: NDArray[np.bool_],
    src_width: int,
    keep: NDArray[np.bool_] | None = None,
) -> list[Patch]:
    """Windows that replace the map where it turns the image over, each one-to-one.

    Parameters
    ----------
    coordinates : ndarray of float32, shape (H, W, 2)
        Source pixel coordinates a warp resamples by (padded by
        :data:`~omniwidget.raster.warping.PAD`).
    mask : ndarray of bool, shape (H, W)
        Where the map turns over (``FoldOver.mask``).
    src_width : int
        Width of the source.
    keep : ndarray of bool, shape (H, W), optional
        Pixels whose map should stay the blend's (the marked lines, :func:`line_mask`, and
        what cages and points hold): the grid cells they fall in keep it, and the
        untangling works around them; a window that cannot be cleared so is untangled
        without them, and what they hold gives way there.

    Returns
    -------
    list of Patch
        One per turned-over patch (patches closer than :data:`MARGIN` are untangled
        together); empty when nothing turns over. Each is tried in windows
        :data:`SPREAD` times its size wider (at most a sixteenth of the width), then twice
        and four times that, then :data:`MARGIN`; a patch no window clears, or larger than
        a :data:`LARGEST` th of the width, is left out, and the fold check after it still
        shows it.
    """
    height, width = mask.shape
    if not mask.any():
        return []
    # work on columns shifted so that the seam runs where nothing turns over
    clear = np.flatnonzero(~mask.any(axis=0))
    shift = int(clear[0]) if len(clear) else 0
    rolled = np.roll(mask, -shift, axis=1)
    labels, _ = ndimage.label(rolled, structure=np.ones((3, 3), bool))
    boxes = [
        (slice(max(r.start - MARGIN, 0), min(r.stop + MARGIN, height)), slice(c.start - MARGIN, c.stop + MARGIN))
        for r, c in _merged([b for b in ndimage.find_objects(labels) if b is not None], MARGIN)
    ]  # each patch with MARGIN around it; the windows grow from there
    patches: list[Patch] = []
    taken = np.zeros_like(rolled)
    for box in sorted(boxes, key=lambda b: -(b[0].stop - b[0].start) * (b[1].stop - b[1].start)):
        region = taken[box[0], max(box[1].start, 0) : min(box[1].stop, width)]
        if region.size and region.all():  # inside a window already untangled
            continue
        size = max(box[0].stop - box[0].start, box[1].stop - box[1].start)
        if size > width // LARGEST:  # no window holds it (the handles give way instead: raster.pipeline)
            continue
        spread = min(max(MARGIN, round(SPREAD * size)), width // 16)
        # every window keeping the lines first; only when none clears it do the lines give way
        tries = [(margin, with_keep) for with_keep in (keep is not None, False) for margin in dict.fromkeys([spread, 2 * spread, 4 * spread, MARGIN])]
        for margin, with_keep in dict.fromkeys(tries):
            r0, r1 = max(box[0].start - margin, 1), min(box[0].stop + margin, height - 1)  # the rim never on a pole row
            c0, c1 = box[1].start - margin, box[1].stop + margin
            if c1 - c0 >= width:
                continue
            cols = (np.arange(c0, c1) + shift) % width
            folded = _window_of(mask, slice(r0, r1), cols)
            kept = _window_of(keep, slice(r0, r1), cols) if with_keep and keep is not None else None
            window = coordinates_lonlat(coordinates[r0:r1][:, cols], src_width)
            patch = _untangle_window(window, folded, slice(r0, r1), cols, width, kept)
            if patch is not None:
                patches.append(patch)
                taken[r0:r1, max(c0, 0) : min(c1, width)] = True
                break
    return patches


def _merged(boxes: list[tuple[slice, slice]], gap: int) -> list[tuple[slice, slice]]:
    """Boxes (row and column slices) with every two closer than ``gap`` pixels joined into their bounding box."""
    out = list(boxes)
    joined = True
    while joined:
        joined = False
        for a in range(len(out)):
            for b in range(a + 1, len(out)):
                (ra, ca), (rb, cb) = out[a], out[b]
                if ra.start - gap < rb.stop and rb.start - gap < ra.stop and ca.start - gap < cb.stop and cb.start - gap < ca.stop:
                    out[a] = (slice(min(ra.start, rb.start), max(ra.stop, rb.stop)), slice(min(ca.start, cb.start), max(ca.stop, cb.stop)))
                    del out[b]
                    joined = True
                    break
            if joined:
                break
    return out


def _window_of(mask: NDArray[np.bool_], rows: slice, cols: NDArray[np.int64]) -> NDArray[np.bool_]:
    """The fold mask on a window of rows and (wrapping) columns."""
    return mask[rows][:, cols]


def _untangle_window(
    window: NDArray[np.float64],
    folded: NDArray[np.bool_],
    rows: slice,
    cols: NDArray[np.int64],
    width: int,
    kept: NDArray[np.bool_] | None = None,
) -> Patch | None:
    """Untangle the map on one window (keeping the cells of ``kept`` pixels); None when its rim is not clean or it still folds."""
    h, w = rows.stop - rows.start, len(cols)
    # the rim must be shown one-to-one (poles aside: there the window ends at the grid's edge)
    rim = np.zeros((h, w), bool)
    rim[[0, -1], :], rim[:, [0, -1]] = True, True
    if (folded & _dilate(rim)).any() or h < 3 or w < 3:
        return None
    source = coords.lonlat_to_xyz(window)  # (h, w, 3)
    centre = source.reshape(-1, 3).sum(axis=0)
    centre /= np.linalg.norm(centre)
    if np.any(source @ centre <= 0.2):  # wider than a hemisphere's middle: no chart holds it
        return None
    out_lonlat = np.stack(np.meshgrid(coords.grid_lonlat(width)[0][cols], coords.grid_lonlat(width)[1][rows]), axis=-1)
    out_xyz = coords.lonlat_to_xyz(out_lonlat)
    charts = (centre, *_frame(centre)), (out_xyz[h // 2, w // 2], *_frame(out_xyz[h // 2, w // 2]))
    xyz: NDArray[np.float64] | bool | None = False
    for side in (GRID_SIDE, 2 * GRID_SIDE, 3 * GRID_SIDE):  # a finer grid when the coarse one's cells still fold a pixel
        step = max(1, math.ceil(max(h, w) / side))
        xyz = _untangle_grid(source, out_xyz, folded, kept, step, charts)
        if not isinstance(xyz, bool) or step == 1:
            break
    if not isinstance(xyz, np.ndarray):
        return None
    moved = float(np.degrees(np.arccos(np.clip(np.sum(xyz * source, axis=-1), -1.0, 1.0))).max())
    return Patch(rows, cols.astype(np.int64), xyz, moved, keeps_lines=kept is not None)


def _untangle_grid(
    source: NDArray[np.float64],
    out_xyz: NDArray[np.float64],
    folded: NDArray[np.bool_],
    kept: NDArray[np.bool_] | None,
    step: int,
    charts: tuple[tuple[NDArray, NDArray, NDArray], tuple[NDArray, NDArray, NDArray]],
) -> NDArray[np.float64] | bool | None:
    """A window's map untangled on a grid every ``step`` pixels: its pixels' source directions (h, w, 3).

    None when the grid cannot be untangled (or keep what it must); False when it was, but a
    pixel between its vertices still turns over (a finer grid may do).
    """
    h, w = source.shape[:2]
    (centre, s_east, s_north), (o_centre, o_east, o_north) = charts
    gy, gx = _grid_positions(h, step), _grid_positions(w, step)
    ref = _chart(out_xyz[np.ix_(gy, gx)], o_centre, o_east, o_north)  # (gh, gw, 2)
    start = _chart(source[np.ix_(gy, gx)], centre, s_east, s_north)
    fixed = np.zeros(start.shape[:2], bool)
    fixed[[0, -1], :], fixed[:, [0, -1]] = True, True
    cell_y, cell_x = _cells(gy, h), _cells(gx, w)
    kept_cells = np.zeros((len(gy) - 1, len(gx) - 1), bool)
    if kept is not None:
        rows_k, cols_k = np.nonzero(kept)
        kept_cells[cell_y[rows_k], cell_x[cols_k]] = True
        if kept_cells[cell_y[:, None], cell_x[None, :]][folded].any():  # the blend folds on a line itself: it must give way
            return None
        for dy in (0, 1):
            for dx in (0, 1):
                fixed[dy : dy + kept_cells.shape[0], dx : dx + kept_cells.shape[1]] |= kept_cells
    solved = _foldover_free(ref.reshape(-1, 2), start.reshape(-1, 2), _triangles(*start.shape[:2]), fixed.ravel())
    if solved is None:
        return None
    # every pixel of the window from its grid cell (the same two triangles a cell)
    uv = _interpolate(solved.reshape(start.shape), gy, gx, h, w)
    xyz = centre + uv[..., :1] * s_east + uv[..., 1:] * s_north
    xyz /= np.linalg.norm(xyz, axis=-1, keepdims=True)
    # the rows and columns of the rim keep the blend exactly (the grid interpolates between rim vertices), and so do kept cells
    xyz[[0, -1], :], xyz[:, [0, -1]] = source[[0, -1], :], source[:, [0, -1]]
    in_kept = kept_cells[cell_y[:, None], cell_x[None, :]]
    xyz[in_kept] = source[in_kept]
    return False if turned_over(coords.xyz_to_lonlat(xyz)).any() else xyz


def _dilate(mask: NDArray[np.bool_]) -> NDArray[np.bool_]:
    return np.asarray(ndimage.binary_dilation(mask, structure=np.ones((3, 3), bool)))


def _grid_positions(n: int, step: int) -> NDArray[np.int64]:
    """Grid lines every ``step`` pixels from 0 to ``n - 1``, the last one at ``n - 1``."""
    out = np.arange(0, n, step)
    return out if out[-1] == n - 1 else np.append(out, n - 1)


def _frame(centre: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Two unit tangent vectors at ``centre`` (a unit vector), east and north where they are defined."""
    up = np.array([0.0, 0.0, 1.0]) if abs(centre[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    east = np.cross(up, centre)
    east /= np.linalg.norm(east)
    return east, np.cross(centre, east)


def _chart(xyz: NDArray[np.float64], centre: NDArray, east: NDArray, north: NDArray) -> NDArray[np.float64]:
    """Gnomonic coordinates about ``centre`` (radians near it), (..., 2)."""
    depth = xyz @ centre
    return np.stack([xyz @ east, xyz @ north], axis=-1) / depth[..., None]


def _triangles(rows: int, cols: int) -> NDArray[np.int64]:
    """Two triangles per cell of a ``rows x cols`` vertex grid, counter-clockwise in (col, -row), (t, 3)."""
    i, j = np.meshgrid(np.arange(rows - 1), np.arange(cols - 1), indexing="ij")
    a, b = (i * cols + j).ravel(), (i * cols + j + 1).ravel()
    c, d = ((i + 1) * cols + j).ravel(), ((i + 1) * cols + j + 1).ravel()
    # rows grow downwards (south): (a, c, b) and (b, c, d) turn counter-clockwise east-north
    return np.concatenate([np.stack([a, c, b], 1), np.stack([b, c, d], 1)])


def _cells(grid: NDArray[np.int64], n: int) -> NDArray[np.int64]:
    """The grid cell (between grid lines ``grid[i]`` and ``grid[i + 1]``) of each of ``n`` pixels along one axis."""
    return np.clip(np.searchsorted(grid, np.arange(n), side="right") - 1, 0, len(grid) - 2)


def _interpolate(values: NDArray[np.float64], gy: NDArray, gx: NDArray, h: int, w: int) -> NDArray[np.float64]:
    """Every pixel of a window from the grid's two triangles per cell (the triangles of :func:`_triangles`)."""
    cell_y, cell_x = _cells(gy, h), _cells(gx, w)
    fy = ((np.arange(h) - gy[cell_y]) / (gy[cell_y + 1] - gy[cell_y]))[:, None, None]
    fx = ((np.arange(w) - gx[cell_x]) / (gx[cell_x + 1] - gx[cell_x]))[None, :, None]
    v00 = values[cell_y][:, cell_x]
    v01 = values[cell_y][:, cell_x + 1]
    v10 = values[cell_y + 1][:, cell_x]
    v11 = values[cell_y + 1][:, cell_x + 1]
    lower = v00 + fx * (v01 - v00) + fy * (v10 - v00)  # triangle (a, c, b): fx + fy <= 1
    upper = v11 + (1 - fx) * (v10 - v11) + (1 - fy) * (v01 - v11)  # triangle (b, c, d)
    return np.where(fx + fy <= 1, lower, upper)


def _foldover_free(
    ref: NDArray[np.float64], start: NDArray[np.float64], triangles: NDArray[np.int64], fixed: NDArray[np.bool_]
) -> NDArray[np.float64] | None:
    """Garanzha et al.'s untangling: positions with the fixed ones kept and every triangle turned positively, or None."""
    i, j, k = triangles.T
    r00, r10 = (ref[j] - ref[i]).T  # the reference edges as the columns of R (2 x 2 per triangle)
    r01, r11 = (ref[k] - ref[i]).T
    det_r = r00 * r11 - r01 * r10
    area = 0.5 * np.abs(det_r)
    if np.any(area <= 0):
        return None
    # the reference scaled to the rim's own area, so the area term asks for no zoom the blend does not make
    z00, z10, z01, z11 = _edge_parts(start, i, j, k)
    scale2 = max(float(np.abs(z00 * z11 - z01 * z10).sum()) / float(np.abs(det_r).sum()), 1e-300)
    det_b = 1.0 / (det_r * scale2)  # B = (scale R)^-1: J = Z B
    s_inv = 1.0 / math.sqrt(scale2)
    b00, b01, b10, b11 = r11 * det_b / s_inv, -r01 * det_b / s_inv, -r10 * det_b / s_inv, r00 * det_b / s_inv
    free = ~fixed
    x = start.copy()
    n, corners = len(x), np.concatenate([i, j, k])

    def energy(flat: NDArray[np.float64], eps: float) -> tuple[float, NDArray[np.float64]]:
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # a step into a fold is infinite: refused
            return _energy(flat, eps)

    def _energy(flat: NDArray[np.float64], eps: float) -> tuple[float, NDArray[np.float64]]:
        x[free] = flat.reshape(-1, 2)
        z00, z10, z01, z11 = _edge_parts(x, i, j, k)
        j00, j01 = z00 * b00 + z01 * b10, z00 * b01 + z01 * b11
        j10, j11 = z10 * b00 + z11 * b10, z10 * b01 + z11 * b11
        a = j00 * j00 + j01 * j01 + j10 * j10 + j11 * j11
        d = (z00 * z11 - z01 * z10) * det_b
        root = np.sqrt(eps * eps + d * d)
        chi = 0.5 * (d + root)
        top = a + AREA_WEIGHT * (d * d + 1.0)
        total = float(np.sum(area * top / chi))
        if not math.isfinite(total):
            return math.inf, np.zeros(2 * int(free.sum()))
        g_a = 2.0 * area / chi
        g_d = area * (2.0 * AREA_WEIGHT * d / chi - top * 0.5 * (1.0 + d / root) / (chi * chi)) * det_b
        # dF/dZ = g_a J B^T + g_d cof(Z); the columns of Z are the edges to the second and third corner
        d00 = g_a * (j00 * b00 + j01 * b01) + g_d * z11
        d01 = g_a * (j00 * b10 + j01 * b11) - g_d * z10
        d10 = g_a * (j10 * b00 + j11 * b01) - g_d * z01
        d11 = g_a * (j10 * b10 + j11 * b11) + g_d * z00
        gx = np.bincount(corners, np.concatenate([-d00 - d01, d00, d01]), minlength=n)
        gy = np.bincount(corners, np.concatenate([-d10 - d11, d10, d11]), minlength=n)
        return total, np.stack([gx, gy], axis=1)[free].ravel().astype(np.float64)

    def determinants() -> NDArray[np.float64]:
        z00, z10, z01, z11 = _edge_parts(x, i, j, k)
        return (z00 * z11 - z01 * z10) * det_b

    if determinants().min() <= 0:  # the rim's harmonic fill often turns nothing over already
        x[free] = _harmonic(x, triangles, free)
    d0 = determinants()
    eps = max(float(np.sqrt(1e-6 + 0.04 * min(float(d0.min()), 0.0) ** 2)), 1e-3) if d0.min() <= 0 else BARRIER
    flat = x[free].ravel()
    for _ in range(EPSILON_ROUNDS):
        flat = _lbfgs(partial(energy, eps=eps), flat, ITERATIONS)
        x[free] = flat.reshape(-1, 2)
        low = float(determinants().min())
        if low > 0:
            break
        eps *= 0.1
    else:
        return None
    if eps > BARRIER:  # once turned right, the barrier keeps it so while the distortion is smoothed
        flat = _lbfgs(partial(energy, eps=BARRIER), flat, ITERATIONS)
        x[free] = flat.reshape(-1, 2)
    return x if float(determinants().min()) > 0 else None


def _lbfgs(fn: Callable[[NDArray[np.float64]], tuple[float, NDArray[np.float64]]], x: NDArray[np.float64], iterations: int) -> NDArray[np.float64]:
    """Limited-memory BFGS (the two-loop recursion, 8 pairs) with a backtracking line search that refuses infinite energy.

    Written here rather than taken from ``scipy.optimize.minimize(method="L-BFGS-B")``,
    whose bounded Fortran step costs more per call on these few thousand unknowns than the
    energy itself.
    """
    f, g = fn(x)
    pairs: list[tuple[NDArray[np.float64], NDArray[np.float64], float]] = []
    for _ in range(iterations):
        q = g.copy()
        alphas = []
        for s_, y_, rho in reversed(pairs):
            a = rho * float(s_ @ q)
            alphas.append(a)
            q -= a * y_
        if pairs:
            s_, y_, _ = pairs[-1]
            q *= float(s_ @ y_) / float(y_ @ y_)
        else:
            q /= max(float(np.linalg.norm(g)), 1e-300)
        for (s_, y_, rho), a in zip(pairs, reversed(alphas), strict=True):
            q += s_ * (a - rho * float(y_ @ q))
        direction = -q
        slope = float(g @ direction)
        if slope >= 0:  # not a descent direction: start the memory again
            pairs.clear()
            direction, slope = -g, -float(g @ g)
        step = 1.0
        for _ in range(30):
            x_new = x + step * direction
            f_new, g_new = fn(x_new)
            if f_new <= f + 1e-4 * step * slope:
                break
            step *= 0.5
        else:
            return x
        s_, y_ = x_new - x, g_new - g
        sy = float(s_ @ y_)
        if sy > 1e-12:
            pairs.append((s_, y_, 1.0 / sy))
            del pairs[:-8]
        converged = f - f_new <= 1e-7 * max(abs(f), 1.0)
        x, f, g = x_new, f_new, g_new
        if converged:
            break
    return x


def _harmonic(x: NDArray[np.float64], triangles: NDArray[np.int64], free: NDArray[np.bool_]) -> NDArray[np.float64]:
    """The free vertices where the grid's graph Laplacian is zero, the others held: the rim's harmonic fill."""
    n = len(x)
    i = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    adjacency = sparse.coo_matrix((np.ones(len(i)), (i[:, 0], i[:, 1])), shape=(n, n)).tocsr()
    adjacency = ((adjacency + adjacency.T) > 0).astype(np.float64)
    laplacian = (sparse.coo_matrix((np.asarray(adjacency.sum(axis=1)).ravel(), (np.arange(n), np.arange(n))), shape=(n, n)) - adjacency).tocsr()
    inner = laplacian[free][:, free]
    rhs = -laplacian[free][:, ~free] @ x[~free]
    return np.asarray(spla.spsolve(inner.tocsc(), rhs)).reshape(-1, 2)


def _edge_parts(x: NDArray[np.float64], i: NDArray, j: NDArray, k: NDArray) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """The entries ``z00, z10, z01, z11`` of each triangle's edge matrix (columns ``x[j] - x[i]`` and ``x[k] - x[i]``)."""
    e1, e2 = x[j] - x[i], x[k] - x[i]
    return e1[:, 0], e1[:, 1], e2[:, 0], e2[:, 1]


def line_pixels(curve: NDArray[np.float64], width: int) -> NDArray[np.int64]:
    """The output pixels ``(x, y)`` (n, 2) nearest the samples of a curve ``[lon, lat]`` (n, 2) given densely."""
    x, y = np.rint(coords.lonlat_to_px(curve, width)).astype(np.int64).T
    return np.stack([x % width, np.clip(y, 0, width // 2 - 1)], axis=1)


def line_mask(pixels: Sequence[NDArray[np.int64]], width: int, radius: int = 1) -> NDArray[np.bool_]:
    """The output pixels within ``radius`` of lines' pixels (:func:`line_pixels`), for :func:`untangle`'s ``keep``.

    Parameters
    ----------
    pixels : sequence of ndarray of int64, shape (n, 2)
        Each line's output pixels ``(x, y)``, at least one per pixel along it.
    width : int
        Of the output; its height is ``width / 2``.
    radius : int
        Pixels around each.

    Returns
    -------
    ndarray of bool, shape (width / 2, width)
    """
    mask = np.zeros((width // 2, width), bool)
    for px in pixels:
        for dy in range(-radius, radius + 1):
            for dx in range(-radius, radius + 1):
                mask[np.clip(px[:, 1] + dy, 0, width // 2 - 1), (px[:, 0] + dx) % width] = True
    return mask


def apply_patches(coordinates: NDArray[np.float32], patches: Sequence[Patch], src_width: int) -> NDArray[np.float32]:
    """The source pixel coordinates with the untangled windows written in (a copy when there are any).

    Parameters
    ----------
    coordinates : ndarray of float32, shape (H, W, 2)
    patches : sequence of Patch
    src_width : int

    Returns
    -------
    ndarray of float32, shape (H, W, 2)
    """
    if not patches:
        return coordinates
    out = coordinates.copy()
    for p in patches:
        px = coords.lonlat_to_px(coords.xyz_to_lonlat(p.xyz), src_width) + PAD
        out[p.rows, p.cols] = px.astype(np.float32)
    return out


def patched_inverse(fn: GridInverse, patches: Sequence[Patch]) -> GridInverse:
    """A grid evaluator of the inverse map with the untangled windows in it (``fn`` itself when there are none)."""
    if not patches:
        return fn

    def patched(lon: NDArray[np.float64], lat: NDArray[np.float64], rows: slice) -> tuple[NDArray, NDArray]:
        src_lon, src_lat = (np.array(a, dtype=np.float64) for a in fn(lon, lat, rows))
        for p in patches:
            lo, hi = max(p.rows.start, rows.start), min(p.rows.stop, rows.stop)
            if lo >= hi:
                continue
            lonlat = np.radians(coords.xyz_to_lonlat(p.xyz[lo - p.rows.start : hi - p.rows.start]))
            src_lon[lo - rows.start : hi - rows.start, p.cols] = lonlat[..., 0]
            src_lat[lo - rows.start : hi - rows.start, p.cols] = lonlat[..., 1]
        return src_lon, src_lat

    return patched
