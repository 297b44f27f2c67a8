"""The live drag: what the browser needs to redraw the result itself while a handle is dragged (:mod:`omniwidget.raster.live`)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from ..raster import live
from ._latest import Latest
from .preview import PreviewJob

__all__ = ["LiveDrag"]


class LiveDrag:
    """Sends the basis of the result on screen for a handle being dragged, in a worker of its own.

    Parameters
    ----------
    preview : PreviewJob
        Whose result on screen the basis is of.
    on_message : callable
        ``on_message(content, buffers)``: the basis, for the browser.
    """

    def __init__(self, preview: PreviewJob, on_message: Callable[[dict, list], None]) -> None:
        self.preview = preview
        self._on_message = on_message
        self.worker = Latest("omniwidget-editor-live")

    def request(self, index: Any) -> None:
        """Send handle ``index``'s basis once the worker gets to it (only the newest request is served)."""
        self.worker.submit(lambda: self.send_basis(index))

    def send_basis(self, index: Any) -> None:
        """Send the browser what it needs to redraw the result live while handle ``index`` is dragged.

        The basis of the result on screen: the other controls' part of eq. (2) and the
        handle's own weights per preview pixel, as half floats. Nothing is sent when no
        result is on screen or the handle has no control in it (a handle drawn meanwhile);
        the browser then shows the drag as before, the kernel's result on release.
        """
        board = self.preview.board
        with board.lock:
            result, generation = self.preview.result, board.status.get("generation")
        if result is None or not isinstance(index, int) or not 0 <= index < len(result.handles):
            return
        try:
            basis = live.live_basis(result, index)
        except ValueError:
            return
        height, width = basis.fixed.shape[:2]
        header = {
            "op": "live",
            "index": index,
            "generation": generation,
            "controls": len(basis.controls),
            "carry": result.handles.options.anchor is not None,
            "turn": None if (turn := result.handles.options.levelling()) is None else turn.as_dict(),
            "width": width,
            "height": height,
            "origin": list(basis.origin),
            "size": basis.size,
        }
        self._on_message(header, [basis.packed().view(np.uint16).tobytes()])
