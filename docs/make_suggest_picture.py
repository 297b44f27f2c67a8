#!/usr/bin/env python
"""Make the README's picture of suggested lines and levelling.

Usage::

    python docs/make_suggest_picture.py       # writes docs/images/suggest_level.jpg

The courtyard panorama of the gallery (``docs/gallery/courtyard.jpg``, CC0, 1024 x 512),
whose camera leaned by about 1.2°. Top: the 40 best lines :func:`omniwidget.suggest_lines`
finds (what ``omniwidget suggest`` writes), dashed as the editor shows them. Bottom: the
panorama levelled (``omniwidget.warp(image, omniwidget.level(image).handles())``, what
``omniwidget level`` writes), with the vertical edges the estimate rests on drawn where they
are now. On the right, the corner of the house (the white box) magnified, from the input and
from the levelled panorama, each with a vertical reference line through the foot of the
corner: the corner leans away from the line in the input and follows it once levelled. The
figures printed on the picture are measured when the script runs.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

import omniwidget as ow
from omniwidget.detect import level, suggest_lines, suggestions_to_handles
from omniwidget.io.draw import draw_handles, draw_polyline
from omniwidget.sphere import coords

DOCS = Path(__file__).resolve().parent
SOURCE = DOCS / "gallery" / "courtyard.jpg"
OUT = DOCS / "images" / "suggest_level.jpg"
#: The editor's colour and dashes for suggested lines, and the colour of the vertical edges used.
SUGGESTION_RGB, SUGGESTION_DASH, VERTICAL_RGB = (191, 90, 242), (8.0, 5.0), (40, 220, 255)
SHOWN = 40  # as many as omniwidget suggest writes by default
#: The magnified part: longitudes and latitudes (degrees) around the house's corner.
INSET_LON, INSET_LAT = (119.0, 133.0), (46.0, -36.0)
#: The latitude (degrees) whose point of the corner's edge the reference line goes through.
FOOT_LAT = -30.0
BAND = 30  # height of the caption band above each row, pixels


def _font(size: int):
    from PIL import ImageFont

    try:
        return ImageFont.truetype("DejaVuSans.ttf", size)
    except OSError:
        return ImageFont.load_default()


def _caption(width: int, text: str) -> NDArray[np.uint8]:
    """A dark band, ``BAND`` pixels high, with ``text`` in it."""
    from PIL import Image, ImageDraw

    band = Image.new("RGB", (width, BAND), (24, 24, 24))
    ImageDraw.Draw(band).text((8, 6), text, fill=(235, 235, 235), font=_font(16))
    return np.asarray(band)


def _lon_at(start: tuple[float, float], end: tuple[float, float], lat: float) -> float:
    """Longitude (degrees) where the great circle through ``start`` and ``end`` reaches latitude ``lat``, near them."""
    normal = np.cross(*coords.lonlat_to_xyz(np.array([start, end], dtype=np.float64)))
    lons = np.linspace(start[0] - 10.0, start[0] + 10.0, 20001)
    points = coords.lonlat_to_xyz(np.stack([lons, np.full_like(lons, lat)], axis=1))
    return float(lons[np.argmin(np.abs(points @ normal))])


def _inset(picture: NDArray[np.uint8], reference_lon: float, height: int) -> NDArray[np.uint8]:
    """The house's corner magnified to ``height`` pixels, a dotted vertical reference line through ``reference_lon``."""
    width = picture.shape[1]
    (x0, y0), (x1, y1) = coords.lonlat_to_px(np.array([[INSET_LON[0], INSET_LAT[0]], [INSET_LON[1], INSET_LAT[1]]]), width)
    crop = picture[int(round(y0)) : int(round(y1)), int(round(x0)) : int(round(x1))]
    scale = height / crop.shape[0]
    big = cv2.resize(crop, (int(round(crop.shape[1] * scale)), height), interpolation=cv2.INTER_CUBIC)
    x = int(round((coords.lonlat_to_px(np.array([reference_lon, 0.0]), width)[0] - round(x0) + 0.5) * scale - 0.5))
    for y in range(0, big.shape[0], 8):
        big[y : y + 4, x] = (255, 255, 255)
    return big


def _box(picture: NDArray[np.uint8]) -> None:
    """Outline the magnified part on the panorama, in place."""
    (l0, l1), (t, b) = INSET_LON, INSET_LAT
    outline = [[l0, t], [l1, t], [l1, b], [l0, b], [l0, t]]
    for a, c in zip(outline, outline[1:], strict=False):
        draw_polyline(picture, np.linspace(a, c, 16), (255, 255, 255), 1)


def main() -> None:
    """Find the lines, level the panorama, write the picture."""
    image = ow.read_panorama(SOURCE)
    suggestions = suggest_lines(image, max_lines=None)
    found = level(image, suggestions=suggestions)
    levelled = ow.warp(image, found.handles(), warn=False).image
    rotation = found.moebius()

    top = draw_handles(image, suggestions_to_handles(suggestions[:SHOWN]), colour=SUGGESTION_RGB, dash=SUGGESTION_DASH, dots=False)
    moved = [(tuple(map(float, rotation(np.array(e.start)))), tuple(map(float, rotation(np.array(e.end))))) for e in found.edges]
    bottom = draw_handles(
        levelled, ow.Handles(tuple(ow.LineHandle(start=a, end=b) for a, b in moved)), colour=VERTICAL_RGB, thickness=1, dots=False
    )

    # the reference line: through the foot of the corner's edge (the longest vertical edge in the inset)
    inside = [
        (e, m)
        for e, m in zip(found.edges, moved, strict=True)
        if all(INSET_LON[0] < p[0] < INSET_LON[1] and INSET_LAT[1] < p[1] < INSET_LAT[0] for p in (e.start, e.end))
    ]
    edge, edge_out = max(inside, key=lambda pair: pair[0].length)
    _box(top)
    _box(bottom)

    captions = [
        f"input: the {SHOWN} best of {len(suggestions)} suggested lines (omniwidget suggest), dashed",
        f"levelled (omniwidget level): pitch {found.pitch:+.2f}°, roll {found.roll:+.2f}°, tilt {found.tilt:.2f}°; "
        f"the {len(found.edges)} vertical edges used",
    ]
    left = np.concatenate(
        [part for picture, text in zip((top, bottom), captions, strict=True) for part in (_caption(picture.shape[1], text), picture)]
    )
    height = left.shape[0] - BAND
    insets = [_inset(image, _lon_at(edge.start, edge.end, FOOT_LAT), height), _inset(levelled, _lon_at(*edge_out, FOOT_LAT), height)]
    right = np.concatenate([insets[0], np.full((height, 4, 3), 24, np.uint8), insets[1]], axis=1)
    right = np.concatenate([_caption(right.shape[1], "the corner: input | levelled"), right])
    out = np.concatenate([left, np.full((left.shape[0], 8, 3), 24, np.uint8), right], axis=1)
    OUT.parent.mkdir(parents=True, exist_ok=True)
    ok, data = cv2.imencode(".jpg", out[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, 85])
    if not ok:
        raise RuntimeError("could not encode the picture")
    OUT.write_bytes(data.tobytes())
    print(
        f"wrote {OUT} ({out.shape[1]} x {out.shape[0]}, {len(data) // 1024} KB): {len(suggestions)} lines found, {SHOWN} drawn; "
        f"pitch {found.pitch:+.2f}°, roll {found.roll:+.2f}°, tilt {found.tilt:.2f}° from {len(found.edges)} vertical edges "
        f"({found.residual:.2f}° rms); the corner's edge {edge.start} - {edge.end}"
    )


if __name__ == "__main__":
    main()
