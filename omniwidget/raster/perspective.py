"""The perspective camera: a rectilinear (gnomonic) view of a panorama, as every 360° viewer shows it.

One camera model for the whole toolkit: :func:`view` (``omniwidget view`` and
``ow.view``) and the paper's comparison (:func:`omniwidget.evaluate.baselines.perspective`,
Fig. 2b) render through :func:`perspective`, and the editor's look-around view draws the same
rays in the browser (``omniwidget/widget/static/look.js``), so a still written by the command
shows what the editor showed for the same direction and field of view.

The camera at ``[lon, lat]`` (yaw, pitch) looks along that direction with the image's north
up and east to the right (:func:`omniwidget.sphere.coords.local_frame`): pixel ``(x, y)``
(column, row; integers are pixel centres) shows the direction
``f * forward + (x - cx) * east - (y - cy) * north``, with ``(cx, cy) = ((width - 1) / 2,
(height - 1) / 2)`` and the focal length ``f = width / (2 tan(fov / 2))`` pixels, ``fov``
the horizontal field of view.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import check_panorama, whole_number
from ..sphere import coords
from .warping import ORDERS, PAD, Order, remap_panorama

__all__ = ["FOV_RANGE", "PerspectiveView", "check_view", "perspective", "view"]

#: The fields of view :func:`view` takes, degrees, exclusive: a rectilinear view of 180° or
#: more does not exist (the focal length would be 0 or negative).
FOV_RANGE = (0.0, 180.0)


@dataclass(frozen=True, eq=False)
class PerspectiveView:
    """A rectilinear (gnomonic) view of a panorama: a planar picture, not a panorama.

    The camera looks at ``center`` with the image's north up. Pixel ``(x, y)`` (column,
    row; integers are pixel centres) shows the direction
    ``f * forward + (x - cx) * east - (y - cy) * north``, with ``forward``, ``east`` and
    ``north`` the unit vector and local frame of ``center``
    (:func:`omniwidget.sphere.coords.local_frame`), ``(cx, cy) = ((width - 1) / 2,
    (height - 1) / 2)`` and the focal length ``f = width / (2 tan(fov / 2))`` pixels. With
    odd sizes the middle pixel shows ``center`` exactly.

    Straightness on it: a plane through the viewpoint meets the image plane in a straight
    line, so every great circle, and so every straight 3D line, is exactly straight here.
    Measure it by projecting the line's samples with :meth:`project` and taking their
    largest distance from the straight line through the ends, in pixels;
    :func:`omniwidget.evaluate.quality.straightness` counts equirectangular pixels and does
    not apply.

    Attributes
    ----------
    image : ndarray, shape (height, width[, C])
        The view, in the panorama's dtype and channels.
    lonlat : ndarray of float64, shape (height, width, 2)
        The inverse map: for each pixel centre, the panorama's ``[lon, lat]`` (degrees) it
        shows.
    center : (float, float)
        ``[lon, lat]`` of the view's centre, degrees (the yaw and pitch of :func:`view`).
    fov : float
        Horizontal field of view, degrees.
    """

    image: NDArray
    lonlat: NDArray[np.float64] = field(repr=False)
    center: tuple[float, float]
    fov: float

    @property
    def focal(self) -> float:
        """The focal length in pixels, ``width / (2 tan(fov / 2))``."""
        return self.lonlat.shape[1] / (2 * math.tan(math.radians(self.fov) / 2))

    @property
    def vertical_fov(self) -> float:
        """The vertical field of view in degrees."""
        return math.degrees(2 * math.atan(self.lonlat.shape[0] / (2 * self.focal)))

    def inverse_map(self, dtype: type[np.floating] = np.float32) -> NDArray[np.floating]:
        """For each pixel centre, the panorama's ``[lon, lat]`` (degrees) it shows, (height, width, 2).

        Parameters
        ----------
        dtype : {numpy.float32, numpy.float64}
        """
        if dtype not in (np.float32, np.float64):
            raise ValueError(f"dtype must be numpy.float32 or numpy.float64, got {dtype!r}")
        return self.lonlat.astype(dtype)

    def project(self, lonlat: ArrayLike) -> NDArray[np.float64]:
        """Where directions appear in the view: pixel coordinates ``(x, y)``.

        Parameters
        ----------
        lonlat : array_like, shape (..., 2)
            ``[lon, lat]`` in degrees.

        Returns
        -------
        ndarray of float64, shape (..., 2)
            Column and row (integers are pixel centres; may lie outside the view); NaN for
            directions on or behind the camera's plane, which the view cannot show.
        """
        forward, east, north = _camera(self.center)
        xyz = coords.lonlat_to_xyz(lonlat)
        depth = xyz @ forward
        with np.errstate(divide="ignore", invalid="ignore"):
            scale = np.where(depth > 0, self.focal / depth, np.nan)
        height, width = self.lonlat.shape[:2]
        return np.stack([(width - 1) / 2 + scale * (xyz @ east), (height - 1) / 2 - scale * (xyz @ north)], axis=-1)


def _camera(center: tuple[float, float]) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """The view's forward direction and its east and north image axes (unit vectors)."""
    east, north = coords.local_frame(center)
    return coords.lonlat_to_xyz(center), east, north


def _center(value: object) -> tuple[float, float]:
    if not isinstance(value, Iterable) or isinstance(value, str | bytes):
        raise ValueError(f"center must be [lon, lat] in degrees, got {value!r}")
    try:
        lon, lat = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ValueError(f"center must be [lon, lat] in degrees, got {value!r}") from None
    if not (math.isfinite(lon) and math.isfinite(lat)):
        raise ValueError(f"center must be [lon, lat] in degrees, got {value!r}")
    if not -180 <= lon <= 180:
        raise ValueError(f"center[0] (longitude): {lon:g} is out of range [-180, 180]")
    if not -90 <= lat <= 90:
        raise ValueError(f"center[1] (latitude): {lat:g} is out of range [-90, 90]")
    return lon, lat


def _is_number(value: object) -> bool:
    return not isinstance(value, bool) and isinstance(value, int | float | np.integer | np.floating)


def perspective(image: NDArray, center: ArrayLike, fov: float, width: int, height: int, *, order: Order = "bilinear") -> PerspectiveView:
    """A rectilinear (gnomonic, "perspective") view of a panorama (the paper's Fig. 2b).

    Every straight line of the scene comes out straight, but shapes stretch towards the
    edges as the field of view widens (a small shape at angle ``t`` from the centre is
    drawn ``1 / cos(t)²`` times longer radially and ``1 / cos(t)`` times wider across), and
    no view reaches 180°.

    Parameters
    ----------
    image : ndarray, shape (H, W[, C])
        Equirectangular panorama, ``W = 2 H``; uint8, uint16, float32 or float64; 1 to 4
        channels.
    center : array_like, shape (2,)
        ``[lon, lat]`` in degrees the view looks at; north is up in the view.
    fov : float
        Horizontal field of view in degrees, in ``(0, 180)``.
    width, height : int
        Size of the view in pixels, positive.
    order : {"nearest", "bilinear", "bicubic"}

    Returns
    -------
    PerspectiveView

    Raises
    ------
    ImageError
        If ``image`` is not a panorama this toolkit reads.
    ValueError
        If ``center``, ``fov``, ``width``, ``height`` or ``order`` is out of range.
    """
    check_panorama(image)
    centre = _center(center)
    if not _is_number(fov) or not FOV_RANGE[0] < fov < FOV_RANGE[1]:
        raise ValueError(f"fov must be a number of degrees in (0, 180), got {fov!r}")
    width = whole_number(width, "width", 1)
    height = whole_number(height, "height", 1)
    if order not in ORDERS:
        raise ValueError(f"order must be one of {', '.join(ORDERS)}, got {order!r}")
    forward, east, north = _camera(centre)
    focal = width / (2 * math.tan(math.radians(fov) / 2))
    x = np.arange(width) - (width - 1) / 2
    y = np.arange(height) - (height - 1) / 2
    rays = focal * forward + x[None, :, None] * east - y[:, None, None] * north
    lonlat = coords.xyz_to_lonlat(rays)
    coordinates = (coords.lonlat_to_px(lonlat, image.shape[1]) + PAD).astype(np.float32)
    out = remap_panorama(image, coordinates, order)
    lonlat.flags.writeable = False
    return PerspectiveView(out, lonlat, centre, float(fov))


def check_view(yaw: object, pitch: object, fov: object) -> tuple[float, float, float]:
    """The camera of :func:`view` checked: ``(lon, lat, fov)`` in degrees, the yaw wrapped into ``[-180, 180)``.

    Each message starts with the argument's name and value (``"pitch 95: ..."``), so the
    command line says it as its option (``--pitch 95: ...``).

    Raises
    ------
    ValueError
        If ``yaw`` is not a finite number, ``pitch`` is not within ``[-90, 90]`` or ``fov``
        not within ``(0, 180)`` (degrees).
    """
    for name, value in (("yaw", yaw), ("pitch", pitch), ("fov", fov)):
        if not _is_number(value) or not math.isfinite(float(value)):  # type: ignore[arg-type]
            raise ValueError(f"{name} {value!r}: must be a finite number of degrees")
    yaw_, pitch_, fov_ = float(yaw), float(pitch), float(fov)  # type: ignore[arg-type]
    if not -90 <= pitch_ <= 90:
        raise ValueError(f"pitch {pitch_:g}: the latitude of the view's centre must be within [-90, 90] degrees")
    if not FOV_RANGE[0] < fov_ < FOV_RANGE[1]:
        raise ValueError(f"fov {fov_:g}: the horizontal field of view must be more than 0 and less than 180 degrees")
    return float(coords.wrap_lon(yaw_)), pitch_, fov_


def view(
    image: NDArray,
    *,
    yaw: float = 0.0,
    pitch: float = 0.0,
    fov: float = 90.0,
    width: int = 1280,
    height: int | None = None,
    order: Order = "bilinear",
) -> PerspectiveView:
    """A perspective still of a panorama, as a 360° viewer shows it looking towards ``[yaw, pitch]``.

    The camera of :func:`perspective` (and of the editor's look-around view): its centre looks
    at longitude ``yaw`` and latitude ``pitch`` (the ``[lon, lat]`` conventions of
    :mod:`omniwidget.sphere.coords`), north up, ``fov`` degrees across.

    Parameters
    ----------
    image : ndarray, shape (H, W[, C])
        Equirectangular panorama, ``W = 2 H``; uint8, uint16, float32 or float64; 1 to 4
        channels.
    yaw : float
        Longitude of the view's centre, degrees, east positive; any finite value (wrapped).
    pitch : float
        Latitude of the view's centre, degrees, in ``[-90, 90]`` (up positive).
    fov : float
        Horizontal field of view, degrees, in ``(0, 180)``.
    width : int
        Width of the still in pixels, positive.
    height : int, optional
        Height in pixels; by default ``round(width * 9 / 16)`` (at least 1).
    order : {"nearest", "bilinear", "bicubic"}

    Returns
    -------
    PerspectiveView
        ``.image`` the still, in the panorama's dtype and channels, (height, width[, C]);
        ``.project`` puts directions on it.

    Raises
    ------
    ImageError
        If ``image`` is not a panorama this toolkit reads.
    ValueError
        If ``yaw``, ``pitch``, ``fov``, ``width``, ``height`` or ``order`` is out of range.

    Examples
    --------
    >>> import omniwidget as ow
    >>> still = ow.view(ow.sample_image(), yaw=30.0, pitch=10.0, fov=90.0, width=320, height=200)
    >>> still.image.shape
    (200, 320, 3)
    """
    lon, lat, fov_ = check_view(yaw, pitch, fov)
    width = whole_number(width, "width", 1)
    height = max(1, round(width * 9 / 16)) if height is None else whole_number(height, "height", 1)
    return perspective(image, (lon, lat), fov_, width, height, order=order)
