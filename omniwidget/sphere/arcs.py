"""Great-circle arcs: where two arcs cross, which curves cross, which points a spherical polygon holds.

numpy only. Used by the method (lines split where they cross, the controls inside a cage)
and by the quality figures.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import coords

__all__ = ["arc_crossing", "crossing_pairs", "inside_polygon"]


def _cross(a: NDArray | Sequence[float], b: NDArray | Sequence[float]) -> tuple[float, float, float]:
    """``a × b`` of two 3-vectors, without ``np.cross``'s overhead (it is called for every pair of arcs)."""
    a0, a1, a2 = float(a[0]), float(a[1]), float(a[2])
    b0, b1, b2 = float(b[0]), float(b[1]), float(b[2])
    return (a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0)


def _dot(a: Sequence[float], b: Sequence[float]) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def arc_crossing(a0: NDArray, a1: NDArray, b0: NDArray, b1: NDArray, margin: float = 1e-6) -> NDArray | None:
    """The point where two great-circle arcs cross strictly inside both, or None.

    Parameters
    ----------
    a0, a1, b0, b1 : ndarray of float64, shape (3,)
        The arcs' ends, unit vectors (each arc the shorter way between its ends).
    margin : float
        Degrees: a crossing this close to an arc's end is not inside it.

    Returns
    -------
    ndarray of float64, shape (3,), or None
        None also for two arcs on one great circle (overlapping arcs do not cross).
    """
    na, nb = _cross(a0, a1), _cross(b0, b1)
    axis = _cross(na, nb)
    norm = math.sqrt(_dot(axis, axis))
    if norm < 1e-12:
        return None  # same great circle: overlapping lines are not split
    margin = math.radians(margin)
    limit_a, limit_b = margin * math.sqrt(_dot(na, na)), margin * math.sqrt(_dot(nb, nb))
    for sign in (1.0, -1.0):
        x = np.array(axis) * (sign / norm)
        inside_a = _dot(_cross(a0, x), na) > limit_a and _dot(_cross(x, a1), na) > limit_a
        inside_b = _dot(_cross(b0, x), nb) > limit_b and _dot(_cross(x, b1), nb) > limit_b
        if inside_a and inside_b:
            return x
    return None


def crossing_pairs(curves: Sequence[NDArray[np.float64]], tolerance: float = 1e-6) -> list[tuple[int, int]]:
    """Pairs of output curves (polylines in the equirectangular plane) that cross each other.

    Touching at a shared endpoint (a joint) is not a crossing; longitudes are unwrapped
    along each curve and between the two, so curves across the seam are compared where
    they meet.

    Parameters
    ----------
    curves : sequence of ndarray, shape (s, 2)
        ``[lon, lat]`` in degrees, in order along each curve.
    tolerance : float
        Degrees: segment crossings closer than this to a curve's end are not counted.

    Returns
    -------
    list of (int, int)
        Index pairs ``(a, b)`` with ``a < b``.
    """
    flat = []
    for c in curves:
        c = np.array(c, dtype=np.float64)
        c[:, 0] = np.unwrap(c[:, 0], period=360.0)
        flat.append(c)
    pairs = []
    for a in range(len(flat)):
        for b in range(a + 1, len(flat)):
            p, q = flat[a], flat[b].copy()
            q[:, 0] += 360.0 * np.round((p[:, 0].mean() - q[:, 0].mean()) / 360.0)
            if _polylines_cross(p, q, tolerance):
                pairs.append((a, b))
    return pairs


def _polylines_cross(p: NDArray, q: NDArray, tolerance: float) -> bool:
    if p[:, 0].max() < q[:, 0].min() or q[:, 0].max() < p[:, 0].min() or p[:, 1].max() < q[:, 1].min() or q[:, 1].max() < p[:, 1].min():
        return False
    a0, a1 = p[:-1, None], p[1:, None]
    b0, b1 = q[None, :-1], q[None, 1:]

    def cross(u: NDArray, v: NDArray) -> NDArray:
        return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]

    da, db = a1 - a0, b1 - b0
    denom = cross(da, db)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = cross(b0 - a0, db) / denom
        u = cross(b0 - a0, da) / denom
    len_a = np.hypot(*np.moveaxis(da, -1, 0))
    len_b = np.hypot(*np.moveaxis(db, -1, 0))
    # positions along each whole curve, to leave out crossings at the curves' own ends
    along_a = np.concatenate([[0.0], np.cumsum(len_a[:, 0])])
    along_b = np.concatenate([[0.0], np.cumsum(len_b[0])])
    at_a = along_a[:-1, None] + s * len_a
    at_b = along_b[None, :-1] + u * len_b
    inside = (s >= 0) & (s <= 1) & (u >= 0) & (u <= 1) & (denom != 0)
    inside &= (at_a > tolerance) & (at_a < along_a[-1] - tolerance) & (at_b > tolerance) & (at_b < along_b[-1] - tolerance)
    return bool(inside.any())


def inside_polygon(lonlat: ArrayLike, vertices: ArrayLike) -> NDArray[np.bool_]:
    """Whether positions lie inside a spherical polygon with great-circle edges (even-odd rule).

    In the gnomonic projection about the vertices' centre, great circles are straight lines,
    so the planar test is exact for polygons smaller than a hemisphere.

    Parameters
    ----------
    lonlat : array_like, shape (..., 2)
        Positions ``[lon, lat]`` in degrees.
    vertices : array_like, shape (n, 2)
        The polygon's corners ``[lon, lat]`` in degrees, in order (either way round), n >= 3.

    Returns
    -------
    ndarray of bool, shape (...)
    """
    corners = coords.lonlat_to_xyz(np.asarray(vertices, np.float64))
    centre = corners.sum(axis=0)
    centre /= np.linalg.norm(centre)
    east, north = coords.local_frame(coords.xyz_to_lonlat(centre))

    def project(xyz: NDArray) -> tuple[NDArray, NDArray, NDArray]:
        depth = xyz @ centre
        return xyz @ east / depth, xyz @ north / depth, depth

    px, py, depth = project(coords.lonlat_to_xyz(np.asarray(lonlat, np.float64)))
    vx, vy, _ = project(corners)
    inside = np.zeros(px.shape, dtype=bool)
    for i in range(len(vx)):
        ax, ay, bx, by = vx[i - 1], vy[i - 1], vx[i], vy[i]
        crosses = (ay > py) != (by > py)
        with np.errstate(divide="ignore", invalid="ignore"):
            at = ax + (py - ay) * (bx - ax) / (by - ay)
        inside ^= crosses & (px < at)
    return inside & (depth > 0)
