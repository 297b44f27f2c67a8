#!/usr/bin/env python
"""Make the README's picture of ``omniwidget straighten``: before and after, the lines it used drawn.

Usage::

    python docs/make_straighten_picture.py       # writes docs/images/straighten.jpg

The bundled hotel room (``omniwidget.sample_path()``, CC0, 1024 x 512). Top: the
input with the lines :func:`omniwidget.straighten` chose (verticals cyan, horizontals amber,
others magenta). Bottom: its result, each line drawn where its pixels landed. The line of
figures under it is measured when the script runs.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

import omniwidget as ow

DOCS = Path(__file__).resolve().parent
OUT = DOCS / "images" / "straighten.jpg"


def main() -> None:
    """Straighten the hotel room and write the picture."""
    image = ow.read_image(ow.sample_path())
    done = ow.straighten(image)
    before, after = done.pictures(image)
    gap = np.full((8, before.shape[1], 3), 255, np.uint8)
    picture = np.vstack([before, gap, after])
    ok, data = cv2.imencode(".jpg", picture[:, :, ::-1], [cv2.IMWRITE_JPEG_QUALITY, 88])
    if not ok:
        raise RuntimeError("could not encode the picture")
    OUT.write_bytes(data.tobytes())
    print(f"wrote {OUT}: {done.summary()}")


if __name__ == "__main__":
    main()
