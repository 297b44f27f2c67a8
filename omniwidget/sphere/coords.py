"""The one place that owns omniwidget's coordinate conventions.

Every other module converts through these functions; none repeats the formulas.

Conventions
-----------
**Longitude and latitude** (``lonlat``) are in degrees: longitude in ``[-180, 180)``,
increasing eastwards (to the right in the image); latitude in ``[-90, 90]``, increasing
northwards (up in the image). Every public boundary of the toolkit (files, command line,
widget, Python API) speaks ``[lon, lat]`` pairs in degrees, in that order.

**Equirectangular pixels** (``px``): an image of width ``W`` and height ``H = W / 2``.
The centre of column ``i`` is at longitude ``-180 + (i + 0.5) * 360 / W``; the centre of
row ``j`` is at latitude ``90 - (j + 0.5) * 180 / H``. Pixel coordinates are ``(x, y)`` =
(column, row), as floats, so ``x = 0`` is the centre of the first column, and the left
edge of the image is at ``x = -0.5``.

**Unit vectors** (``xyz``): the direction of ``(lon, lat)`` is
``(cos lat cos lon, cos lat sin lon, sin lat)``; the north pole is ``+z``.

**Stereographic projection** (``z``): from the north pole onto the equatorial plane,
``z = (x + i y) / (1 - z_3)``, so the south pole is ``0`` and the north pole is ``∞``.
omniwidget never divides: a point of the extended complex plane is held in homogeneous
coordinates ``[u : v]`` (``z = u / v``, ``∞ = [1 : 0]``), and Möbius maps act on them as
2 x 2 complex matrices. Each sphere point has two exact homogeneous forms,
``[x + i y : 1 - z_3]`` and ``[1 + z_3 : x - i y]``; :func:`xyz_to_homogeneous` picks the
one that is well conditioned, so no pole, seam or projection point needs a special case.

**Local frame** at ``(lon, lat)``: *east* ``(-sin lon, cos lon, 0)`` and *north*
``(-sin lat cos lon, -sin lat sin lon, cos lat)``. With ``east x north = xyz`` they are
defined everywhere, poles included (there they follow the given longitude). Angles "as
seen in the image" are counter-clockwise from east towards north.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "angular_distance",
    "arc_max_abs_lat",
    "best_rotation",
    "geodesic",
    "geodesic_midpoint",
    "grid_lonlat",
    "homogeneous_to_xyz",
    "local_frame",
    "lonlat_to_px",
    "lonlat_to_xyz",
    "px_to_lonlat",
    "stereographic",
    "inverse_stereographic",
    "unwrap_lon",
    "wrap_lon",
    "xyz_to_homogeneous",
    "xyz_to_lonlat",
]

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]


def _lonlat(lonlat: ArrayLike) -> FloatArray:
    arr = np.asarray(lonlat, dtype=np.float64)
    if arr.shape[-1:] != (2,):
        raise ValueError(f"expected [lon, lat] pairs in the last axis, got shape {arr.shape}")
    return arr


def _xyz(xyz: ArrayLike) -> FloatArray:
    arr = np.asarray(xyz, dtype=np.float64)
    if arr.shape[-1:] != (3,):
        raise ValueError(f"expected unit vectors (..., 3), got shape {arr.shape}")
    return arr


def wrap_lon(lon: ArrayLike) -> FloatArray:
    """Wrap longitudes in degrees into ``[-180, 180)``.

    Parameters
    ----------
    lon : array_like of float
        Longitudes in degrees, any shape.

    Returns
    -------
    ndarray of float64
        Same shape, in ``[-180, 180)``.
    """
    lon = np.asarray(lon, dtype=np.float64)
    wrapped = np.mod(lon + 180.0, 360.0) - 180.0
    # np.mod can round a tiny negative number up to exactly 360.
    return np.where(wrapped >= 180.0, wrapped - 360.0, wrapped)


def unwrap_lon(lon: ArrayLike, reference: ArrayLike) -> FloatArray:
    """Shift longitudes by multiples of 360 to lie within 180 degrees of ``reference``.

    Used wherever positions across the ±180° seam are compared or averaged.

    Parameters
    ----------
    lon, reference : array_like of float
        Longitudes in degrees; broadcast together.

    Returns
    -------
    ndarray of float64
        ``lon + 360 k`` with ``|result - reference| <= 180``.
    """
    reference = np.asarray(reference, dtype=np.float64)
    return reference + wrap_lon(np.asarray(lon, dtype=np.float64) - reference)


def lonlat_to_xyz(lonlat: ArrayLike) -> FloatArray:
    """Unit vectors of ``[lon, lat]`` positions.

    Parameters
    ----------
    lonlat : array_like, shape (..., 2)
        Longitude and latitude in degrees.

    Returns
    -------
    ndarray of float64, shape (..., 3)
        ``(cos lat cos lon, cos lat sin lon, sin lat)``.
    """
    lonlat = _lonlat(lonlat)
    lon = np.radians(lonlat[..., 0])
    lat = np.radians(lonlat[..., 1])
    cos_lat = np.cos(lat)
    return np.stack([cos_lat * np.cos(lon), cos_lat * np.sin(lon), np.sin(lat)], axis=-1)


def xyz_to_lonlat(xyz: ArrayLike) -> FloatArray:
    """``[lon, lat]`` in degrees of (not necessarily unit) direction vectors.

    Latitude comes from ``atan2`` rather than ``asin``, so it keeps full precision
    near the poles; at a pole the longitude is 0.

    Parameters
    ----------
    xyz : array_like, shape (..., 3)
        Nonzero direction vectors.

    Returns
    -------
    ndarray of float64, shape (..., 2)
        Longitude in ``[-180, 180)``, latitude in ``[-90, 90]``.
    """
    xyz = _xyz(xyz)
    x, y, z = xyz[..., 0], xyz[..., 1], xyz[..., 2]
    lon = wrap_lon(np.degrees(np.arctan2(y, x)))
    lat = np.degrees(np.arctan2(z, np.hypot(x, y)))
    return np.stack([lon, lat], axis=-1)


def px_to_lonlat(px: ArrayLike, width: int) -> FloatArray:
    """``[lon, lat]`` of pixel coordinates ``(x, y)`` in an equirectangular image.

    Parameters
    ----------
    px : array_like, shape (..., 2)
        Column and row, as floats; integer values are pixel centres.
    width : int
        Image width ``W``; the height is ``W / 2``.

    Returns
    -------
    ndarray of float64, shape (..., 2)
        ``lon = -180 + (x + 0.5) * 360 / W``, ``lat = 90 - (y + 0.5) * 180 / H``
        (not wrapped, so that positions outside the image stay continuous).
    """
    px = np.asarray(px, dtype=np.float64)
    step = 360.0 / width
    return np.stack([-180.0 + (px[..., 0] + 0.5) * step, 90.0 - (px[..., 1] + 0.5) * step], axis=-1)


def lonlat_to_px(lonlat: ArrayLike, width: int) -> FloatArray:
    """Pixel coordinates ``(x, y)`` of ``[lon, lat]`` in an image of width ``width``.

    The inverse of :func:`px_to_lonlat`; longitudes are not wrapped.

    Parameters
    ----------
    lonlat : array_like, shape (..., 2)
        Longitude and latitude in degrees.
    width : int
        Image width ``W``.

    Returns
    -------
    ndarray of float64, shape (..., 2)
    """
    lonlat = _lonlat(lonlat)
    scale = width / 360.0
    return np.stack([(lonlat[..., 0] + 180.0) * scale - 0.5, (90.0 - lonlat[..., 1]) * scale - 0.5], axis=-1)


def row_area(height: int) -> FloatArray:
    """The area of one pixel in each row of a ``2 height`` x ``height`` equirectangular grid, as a share of the sphere.

    Parameters
    ----------
    height : int

    Returns
    -------
    ndarray of float64, shape (height,)
        Summed over all ``2 height`` pixels of every row, 1.
    """
    edges = np.radians(np.linspace(90.0, -90.0, height + 1))
    return (np.sin(edges[:-1]) - np.sin(edges[1:])) / (2 * (2 * height))


def grid_lonlat(width: int) -> tuple[FloatArray, FloatArray]:
    """Longitudes of the columns and latitudes of the rows of a ``width x width/2`` image.

    Parameters
    ----------
    width : int
        Image width; must be even and positive.

    Returns
    -------
    lon : ndarray of float64, shape (W,)
    lat : ndarray of float64, shape (W / 2,)
    """
    if width < 2 or width % 2:
        raise ValueError(f"an equirectangular width must be even and at least 2, got {width}")
    step = 360.0 / width
    lon = -180.0 + (np.arange(width, dtype=np.float64) + 0.5) * step
    lat = 90.0 - (np.arange(width // 2, dtype=np.float64) + 0.5) * step
    return lon, lat


def xyz_to_homogeneous(xyz: ArrayLike) -> tuple[ComplexArray, ComplexArray]:
    """Stereographic projection of unit vectors, as homogeneous ``[u : v]``.

    For ``z_3 <= 0`` the pair is ``[x + i y : 1 - z_3]``, otherwise ``[1 + z_3 : x - i y]``;
    both equal ``(x + i y) / (1 - z_3)`` and the chosen one has ``max(|u|, |v|) >= 1``,
    so the north pole (``∞``) and south pole (``0``) are ordinary values.

    Parameters
    ----------
    xyz : array_like, shape (..., 3)
        Unit vectors.

    Returns
    -------
    u, v : ndarray of complex128, shape (...)
    """
    xyz = _xyz(xyz)
    x, y, z = xyz[..., 0], xyz[..., 1], xyz[..., 2]
    south = z <= 0.0
    u = np.where(south, x + 1j * y, 1.0 + z)
    v = np.where(south, 1.0 - z, x - 1j * y)
    return u.astype(np.complex128), v.astype(np.complex128)


def homogeneous_to_xyz(u: ArrayLike, v: ArrayLike) -> FloatArray:
    """Inverse stereographic projection of homogeneous ``[u : v]``.

    ``xyz = (2 Re(u v̄), 2 Im(u v̄), |u|² - |v|²) / (|u|² + |v|²)``, finite for every pair
    but ``[0 : 0]``.

    Parameters
    ----------
    u, v : array_like of complex
        Same shape; not both zero.

    Returns
    -------
    ndarray of float64, shape (..., 3)
        Unit vectors.
    """
    uc = np.asarray(u, dtype=np.complex128)
    vc = np.asarray(v, dtype=np.complex128)
    # Scale each pair so that the larger entry has modulus 1: no overflow or underflow.
    scale = np.maximum(np.abs(uc), np.abs(vc))
    if np.any(scale == 0):
        raise ValueError("[0 : 0] is not a point of the extended complex plane")
    uc = uc / scale
    vc = vc / scale
    uv = uc * np.conj(vc)
    uu = uc.real**2 + uc.imag**2
    vv = vc.real**2 + vc.imag**2
    norm = uu + vv
    return np.stack([2 * uv.real / norm, 2 * uv.imag / norm, (uu - vv) / norm], axis=-1)


def stereographic(lonlat: ArrayLike) -> ComplexArray:
    """Stereographic projection ``z`` of ``[lon, lat]`` (north pole to ``inf + 0j``).

    A convenience for teaching and plotting; computations use the homogeneous form.

    Parameters
    ----------
    lonlat : array_like, shape (..., 2)

    Returns
    -------
    ndarray of complex128, shape (...)
    """
    u, v = xyz_to_homogeneous(lonlat_to_xyz(lonlat))
    out = np.full(u.shape, complex(np.inf, 0.0), dtype=np.complex128)
    finite = v != 0
    out[finite] = u[finite] / v[finite]
    return out


def inverse_stereographic(z: ArrayLike) -> FloatArray:
    """``[lon, lat]`` of points ``z`` of the extended complex plane (``inf`` is the north pole).

    Parameters
    ----------
    z : array_like of complex

    Returns
    -------
    ndarray of float64, shape (..., 2)
    """
    z = np.asarray(z, dtype=np.complex128)
    infinite = ~np.isfinite(z)
    u = np.where(infinite, 1.0, z)
    v = np.where(infinite, 0.0, 1.0)
    return xyz_to_lonlat(homogeneous_to_xyz(u, v))


def local_frame(lonlat: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """The image's east and north directions at ``[lon, lat]`` as unit tangent vectors.

    Parameters
    ----------
    lonlat : array_like, shape (..., 2)

    Returns
    -------
    east, north : ndarray of float64, shape (..., 3)
        Orthonormal, with ``east x north`` the position's unit vector, at the poles too.
    """
    lonlat = _lonlat(lonlat)
    lon = np.radians(lonlat[..., 0])
    lat = np.radians(lonlat[..., 1])
    zero = np.zeros_like(lon)
    east = np.stack([-np.sin(lon), np.cos(lon), zero], axis=-1)
    north = np.stack([-np.sin(lat) * np.cos(lon), -np.sin(lat) * np.sin(lon), np.cos(lat)], axis=-1)
    return east, north


def angular_distance(a: ArrayLike, b: ArrayLike) -> FloatArray:
    """Great-circle distance in degrees between ``[lon, lat]`` positions.

    Parameters
    ----------
    a, b : array_like, shape (..., 2)
        Broadcast together.

    Returns
    -------
    ndarray of float64, shape (...)
    """
    pa, pb = lonlat_to_xyz(a), lonlat_to_xyz(b)
    cross = np.linalg.norm(np.cross(pa, pb), axis=-1)
    return np.degrees(np.arctan2(cross, np.sum(pa * pb, axis=-1)))


def geodesic(start: ArrayLike, end: ArrayLike, t: ArrayLike) -> FloatArray:
    """Points of the spherical bone of eq. (3): ``normalize((1 - t) P1 + t P3)``.

    Parameters
    ----------
    start, end : array_like, shape (2,)
        ``[lon, lat]`` of the endpoints; not antipodal.
    t : array_like of float, shape (n,)
        Parameters in ``[0, 1]``.

    Returns
    -------
    ndarray of float64, shape (n, 2)
        ``[lon, lat]`` of the points. (The parameter is the paper's: equal steps in ``t``
        are not equal steps of arc length.)
    """
    p1, p3 = lonlat_to_xyz(start), lonlat_to_xyz(end)
    t = np.asarray(t, dtype=np.float64)[..., None]
    points = (1.0 - t) * p1 + t * p3
    norms = np.linalg.norm(points, axis=-1, keepdims=True)
    if np.any(norms < 1e-12):
        raise ValueError("the geodesic between antipodal points is not unique")
    return xyz_to_lonlat(points / norms)


def geodesic_midpoint(start: ArrayLike, end: ArrayLike) -> FloatArray:
    """The geodesic midpoint ``P2 = SB(1/2)`` of a spherical bone, ``[lon, lat]``."""
    return geodesic(start, end, [0.5])[0]


def arc_max_abs_lat(start: ArrayLike, end: ArrayLike) -> float:
    """The largest ``|latitude|`` in degrees anywhere on the geodesic arc from ``start`` to ``end``.

    An arc can climb higher than both its ends: besides them, the highest and lowest points
    of its whole great circle count where they lie on the arc. ``90 -`` this is how close
    the arc comes to a pole.

    Parameters
    ----------
    start, end : array_like, shape (2,)
        ``[lon, lat]`` in degrees; not antipodal.

    Returns
    -------
    float
    """
    p, q = lonlat_to_xyz(start), lonlat_to_xyz(end)
    normal = np.cross(p, q)
    size = float(np.linalg.norm(normal))
    if size < 1e-12:
        return float(np.max(np.abs([_lonlat(start)[1], _lonlat(end)[1]])))
    normal /= size
    candidates = [p, q]
    top = np.array([0.0, 0.0, 1.0]) - normal[2] * normal  # the north pole projected onto the circle's plane
    if np.linalg.norm(top) > 1e-12:  # else the circle is the equator
        top /= np.linalg.norm(top)
        candidates += [c for c in (top, -top) if np.dot(np.cross(p, c), normal) >= 0 and np.dot(np.cross(c, q), normal) >= 0]
    return float(np.max(np.abs(xyz_to_lonlat(np.array(candidates))[:, 1])))


def best_rotation(source: ArrayLike, target: ArrayLike) -> NDArray[np.float64]:
    """The rotation of the sphere that best sends points onto others (Kabsch: least squares, never a reflection).

    Parameters
    ----------
    source, target : array_like, shape (n, 2)
        ``[lon, lat]`` in degrees, ``n >= 2``, matched in order.

    Returns
    -------
    ndarray of float64, shape (3, 3)
        The proper rotation ``R`` (``det R = +1``) minimising ``sum |R a_i - b_i|²`` over the
        points' unit vectors ``a_i``, ``b_i``; ``R @ a`` acts on column vectors.
    """
    a = np.asarray(source, dtype=np.float64)
    b = np.asarray(target, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 2 or len(a) < 2 or a.shape != b.shape:
        raise ValueError(f"expected source and target of one shape (n >= 2, 2), got {a.shape} and {b.shape}")
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        raise ValueError("source and target must be finite [lon, lat] positions")
    u, _, vt = np.linalg.svd(lonlat_to_xyz(a).T @ lonlat_to_xyz(b))
    d = np.sign(np.linalg.det(vt.T @ u.T)) or 1.0
    return vt.T @ np.diag([1.0, 1.0, d]) @ u.T
