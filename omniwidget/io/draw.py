"""Drawing handles over a panorama, as the great-circle arcs they are (curved, wrapping at the seam).

Used by the command line's demo and by figures; the widget draws in the browser instead.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._lazy import lazy
from ..document.handles import Handles
from ..method.kinds import kind_of
from ..sphere import coords

if TYPE_CHECKING:
    import cv2
else:
    cv2 = lazy("cv2")

__all__ = ["display_rgb", "draw_handles", "draw_polyline"]

RGB = tuple[int, int, int]
COLOURS: dict[str, RGB] = {"line": (230, 40, 40), "point": (220, 40, 220), "cage": (255, 255, 255)}
ARC_SAMPLES = 64


def _split_at_seam(px: NDArray[np.float64], width: int) -> list[NDArray[np.float64]]:
    """Cut a pixel polyline where it jumps across the ±180° seam."""
    jumps = np.flatnonzero(np.abs(np.diff(px[:, 0])) > width / 2) + 1
    return [part for part in np.split(px, jumps) if len(part) > 1]


def _dashes(px: NDArray[np.float64], on: float, off: float) -> list[NDArray[np.float64]]:
    """The pieces of a pixel polyline (shape (n, 2)) drawn by a dash pattern: ``on`` pixels drawn, ``off`` skipped, from its start."""
    steps = np.hypot(*np.diff(px, axis=0).T)
    along = np.concatenate([[0.0], np.cumsum(steps)])
    pieces = []
    for s0 in np.arange(0.0, along[-1], on + off):
        s1 = min(s0 + on, along[-1])
        inside = (along > s0) & (along < s1)
        s = np.concatenate([[s0], along[inside], [s1]])
        piece = np.stack([np.interp(s, along, px[:, 0]), np.interp(s, along, px[:, 1])], axis=1)
        if s1 > s0:
            pieces.append(piece)
    return pieces


def draw_polyline(
    image: NDArray[np.uint8], lonlat: ArrayLike, colour: RGB, thickness: int = 2, *, dash: tuple[float, float] | None = None
) -> None:
    """Draw a polyline given by ``[lon, lat]`` vertices (shape (n, 2)) onto ``image`` in place.

    ``dash=(on, off)`` draws it dashed: ``on`` pixels drawn, then ``off`` pixels left out, along
    the polyline from its first vertex; None (the default) draws it solid.
    """
    width = image.shape[1]
    px = coords.lonlat_to_px(np.asarray(lonlat, dtype=np.float64), width)
    px[:, 0] = np.mod(px[:, 0] + 0.5, width) - 0.5
    shift = 4  # sub-pixel precision for cv2 (coordinates in 1/16 px)
    parts = _split_at_seam(px, width)
    if dash is not None:
        on, off = (float(d) for d in dash)
        if not (on > 0 and off >= 0):
            raise ValueError(f"dash must be (on, off) pixels with on > 0 and off >= 0, got {dash!r}")
        parts = [piece for part in parts for piece in _dashes(part, on, off)]
    for part in parts:
        pts = np.round((part + 0.5) * (1 << shift)).astype(np.int32)
        cv2.polylines(image, [pts], False, colour, thickness, cv2.LINE_AA, shift)


def _arc(start: ArrayLike, end: ArrayLike) -> NDArray[np.float64]:
    return coords.geodesic(start, end, np.linspace(0.0, 1.0, ARC_SAMPLES))


def _dot(image: NDArray[np.uint8], lonlat: ArrayLike, colour: RGB, radius: int) -> None:
    x, y = coords.lonlat_to_px(np.asarray(lonlat, dtype=np.float64), image.shape[1])
    cv2.circle(image, (int(round(x)), int(round(y))), radius, colour, -1, cv2.LINE_AA)


def draw_handles(
    image: NDArray,
    handles: Handles,
    *,
    stage: str = "input",
    thickness: int = 2,
    colour: RGB | None = None,
    dash: tuple[float, float] | None = None,
    dots: bool = True,
) -> NDArray[np.uint8]:
    """A copy of ``image`` (as RGB uint8) with the handles drawn on it.

    Parameters
    ----------
    image : ndarray, shape (H, W[, C])
        The panorama; other depths are scaled to uint8 for display.
    handles : Handles
    stage : {"input", "output"}
        ``"input"`` draws the handles where they were marked; ``"output"`` draws their images
        under their own Möbius maps (a rectified line's image is straight).
    thickness : int
        Line width in pixels.
    colour : (int, int, int), optional
        One RGB colour for every handle (suggested lines, say), instead of the colour of each
        kind (``COLOURS``: lines red, points magenta, cages white).
    dash : (float, float), optional
        ``(on, off)`` in pixels: the arcs drawn dashed (as the editor shows suggestions);
        solid by default.
    dots : bool
        Draw the control points (a line's ends and middle, a point's centre, a cage's
        vertices); False draws the arcs alone.

    Returns
    -------
    ndarray of uint8, shape (H, W, 3)
    """
    if stage not in ("input", "output"):
        raise ValueError(f"stage must be 'input' or 'output', got {stage!r}")
    canvas = display_rgb(image)
    radius = max(2, thickness + 1)
    for h in handles.handles:
        rgb = COLOURS[h.kind] if colour is None else colour
        outline = kind_of(h).outline(h, stage, _arc)
        for curve in outline.arcs:
            draw_polyline(canvas, curve, rgb, thickness, dash=dash)
        for p in outline.dots if dots else ():
            _dot(canvas, p, rgb, radius)
        for p in outline.big_dots if dots else ():
            _dot(canvas, p, rgb, radius + 1)
    return canvas


def display_rgb(image: NDArray) -> NDArray[np.uint8]:
    """An RGB uint8 copy of any supported panorama, for display.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, C)
        uint8, uint16 (the high byte is kept) or float (0..1, clipped; NaN shows black);
        gray and gray+alpha become gray RGB, alpha is dropped.

    Returns
    -------
    ndarray of uint8, shape (H, W, 3)
    """
    img = np.asarray(image)
    if img.dtype == np.uint16:
        img = (img >> 8).astype(np.uint8)
    elif img.dtype.kind == "f":
        img = (np.clip(np.nan_to_num(img), 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
    else:
        img = img.astype(np.uint8, copy=True)
    if img.ndim == 2:
        img = img[..., None]
    channels = img.shape[2]
    if channels in (1, 2):
        img = np.repeat(img[..., :1], 3, axis=2)
    return np.ascontiguousarray(img[..., :3])
