#!/usr/bin/env python
"""Make the README's picture of the weights pane (the paper's Fig. 9).

Usage::

    python docs/make_weights_picture.py       # writes docs/images/weights.png

The command-line demo's handles on the bundled panorama, warped at 1024 wide: the adaptive
mesh coloured by the window line's weights and by the armchair cage's
(:func:`omniwidget.viz.pane.render_weights`, off-screen), and the line's weights over the
output panorama (:func:`omniwidget.viz.pane.weights_overlay`).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

import omniwidget as ow
from omniwidget.app.cli import DEMO_HANDLES
from omniwidget.viz import pane

OUT = Path(__file__).resolve().parent / "images" / "weights.png"


def main() -> None:
    """Render and write the picture."""
    result = ow.warp(ow.sample_image(), ow.Handles.from_dict(DEMO_HANDLES), width=1024, warn=False)
    size = 400
    spheres = np.concatenate([pane.render_weights(result, i, window_size=(size, size)) for i in (0, 2)], axis=1)
    flat = pane.weights_overlay(result, 0, width=2 * size)
    OUT.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(OUT), np.concatenate([spheres, flat], axis=0)[..., ::-1])
    print(f"wrote {OUT} ({len(result.vertices)} mesh vertices)")


if __name__ == "__main__":
    main()
