#!/usr/bin/env python
"""Make the picture of the paper's Fig. 13: the same lines given to [10] and to ours.

Usage::

    python docs/make_rival_picture.py       # writes docs/images/rival_fig13.png

The courtyard panorama of the gallery (``docs/gallery/courtyard.jpg``, CC0, 1024 x 512) and
its handles file (``docs/gallery/courtyard.json``: the house's eave, a window lintel, a
pillar and the garage's eave). From top to bottom: the input with the lines; ours in the
paper's mode (``Options(rectify="all", anchor=None)``) and in the default mode
(``Options()``), the lines drawn where they land; and [10], the content-preserving
projection of Carroll, Agrawala and Agarwala
(:func:`omniwidget.evaluate.content_preserving.content_preserving`), its irregular border
black and the largest rectangle inside it (what [10] crops its results to) in white. The
figures on each caption are measured when the script runs
(:class:`omniwidget.evaluate.baselines.Comparison`).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from omniwidget.document.handles import Handles, load_handles
from omniwidget.evaluate.baselines import RIVALS, compare
from omniwidget.io.draw import display_rgb, draw_handles
from omniwidget.io.images import read_image
from omniwidget.sphere import coords

DOCS = Path(__file__).resolve().parent
SOURCE = DOCS / "gallery" / "courtyard.jpg"
HANDLES = DOCS / "gallery" / "courtyard.json"
OUT = DOCS / "images" / "rival_fig13.png"
SHOWN = 640  # width of each picture in the figure, pixels
BAND = 26  # caption band height, pixels
LINE_RGB = (230, 40, 40)


def _caption(width: int, text: str) -> NDArray[np.uint8]:
    band = np.full((BAND, width, 3), 24, dtype=np.uint8)
    cv2.putText(band, text, (6, BAND - 8), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (235, 235, 235), 1, cv2.LINE_AA)
    return band


def _shrink(picture: NDArray[np.uint8]) -> NDArray[np.uint8]:
    height = round(picture.shape[0] * SHOWN / picture.shape[1])
    return np.asarray(cv2.resize(picture, (SHOWN, height), interpolation=cv2.INTER_AREA))


def _figures(s) -> str:  # type: ignore[no-untyped-def]
    text = f"lines within {s.straightness:.2f} px, distortion {s.distortion_mean:.3f} (p99 {s.distortion_p99:.2f}), folds {100 * s.fold_over:.2g}%"
    lost = getattr(s, "cropped_loss", None)
    return text + (f", {100 * lost:.0f}% lost to the crop" if lost is not None else f", moved {s.displacement:.1f} deg")


def main() -> None:
    """Compare the three methods on the courtyard and write the picture."""
    image = read_image(SOURCE)
    doc = load_handles(HANDLES)
    doc = Handles(doc.handles, doc.options)
    table = compare(image, doc, RIVALS)
    rows = [_caption(SHOWN, "input, with the four marked lines"), _shrink(draw_handles(image, doc, thickness=2))]
    for name, label in (("paper", "ours, the paper's mode"), ("default", "ours, default mode")):
        result = table.results[name]
        drawn = draw_handles(result.image, Handles(doc.handles, result.handles.options), stage="output", thickness=2)  # type: ignore[union-attr]
        rows += [_caption(SHOWN, f"{label}: {_figures(table[name])}"), _shrink(drawn)]
    theirs = table.results["content_preserving"]
    picture = display_rgb(theirs.image).copy()
    for handle in doc.handles:
        px = theirs.forward_points(coords.geodesic(handle.start, handle.end, np.linspace(0.0, 1.0, 200)))  # type: ignore[union-attr]
        cv2.polylines(picture, [np.round(px).astype(np.int32)], False, LINE_RGB, 2, cv2.LINE_AA)
    top, left, height, width = table["content_preserving"].crop  # type: ignore[attr-defined]
    cv2.rectangle(picture, (left, top), (left + width - 1, top + height - 1), (255, 255, 255), 2)
    rows += [_caption(SHOWN, f"[10] content-preserving: {_figures(table['content_preserving'])}"), _shrink(picture)]
    out = np.concatenate(rows, axis=0)
    OUT.parent.mkdir(parents=True, exist_ok=True)
    ok, data = cv2.imencode(".png", out[:, :, ::-1], [cv2.IMWRITE_PNG_COMPRESSION, 9])
    if not ok:
        raise RuntimeError("could not encode the picture")
    OUT.write_bytes(data.tobytes())
    print(f"wrote {OUT} ({out.shape[1]} x {out.shape[0]}, {len(data) // 1024} KB)")
    print(table.to_markdown())


if __name__ == "__main__":
    main()
