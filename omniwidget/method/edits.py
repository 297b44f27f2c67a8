"""Edits of a handles document that need the method: rectify one line and hold the rest (the paper's "rectify current line").

Kept apart from the Sec. 3.4 solve (:mod:`.rectify`), which the controls (:mod:`.constraints`)
use: this edit builds the controls itself, so it sits above both.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from ..document.handles import Handles, LineHandle, LonLat
from ..sphere.moebius import Moebius
from .constraints import build_constraints

__all__ = ["rectify_line"]


def rectify_line(handles: Handles, index: int, *, samples: int = 50) -> Handles:
    """Rectify one line and leave every other handle as it is (the paper's "rectify current line").

    The line at ``index`` is placed by the least squares of this module with every other
    handle held where its map puts it now, and gets the solved control points as explicit
    ``targets``. Lines that were rectified before keep their current output: their solved
    control points are written into the document as explicit targets too (a line that was
    split at a crossing keeps ``rectify`` instead, and may move a little).

    Parameters
    ----------
    handles : Handles
    index : int
        Position of a line handle in ``handles.handles``.
    samples : int
        Samples per line in the relative-position terms.

    Returns
    -------
    Handles
        A new document; ``handles`` is not changed.
    """
    items = list(handles.handles)
    if isinstance(index, bool) or not isinstance(index, (int, np.integer)) or not -len(items) <= index < len(items):
        raise IndexError(f"handles[{index}]: there are {len(items)} handles")
    index = int(index) % len(items)
    chosen = items[index]
    if not isinstance(chosen, LineHandle):
        raise ValueError(f"handles[{index}] is a {chosen.kind} handle, not a line")
    current = build_constraints(handles, samples=samples)
    pieces: dict[int, list[Moebius]] = {}
    for control in current.controls:
        pieces.setdefault(control.handle, []).append(control.moebius)
    for i, h in enumerate(items):  # freeze the other lines where they are now
        if i != index and isinstance(h, LineHandle) and h.targets is None and h.rectify and len(pieces[i]) == 1:
            items[i] = replace(h, rectify=False, targets=_as_targets(pieces[i][0](h.control_points())))
    frozen = [replace(h, rectify=False) if isinstance(h, LineHandle) and i != index else h for i, h in enumerate(items)]
    line = replace(chosen, rectify=True, targets=None)
    frozen[index] = line
    alone = build_constraints(replace(handles, handles=tuple(frozen), options=replace(handles.options, rectify="all")), samples=samples)
    maps = [c.moebius for c in alone.controls if c.handle == index]
    if len(maps) == 1:  # not split by a crossing: write its solved control points
        line = replace(line, rectify=False, targets=_as_targets(maps[0](line.control_points())))
    items[index] = line
    return replace(handles, handles=tuple(items))


def _as_targets(points: NDArray[np.float64]) -> tuple[LonLat, LonLat, LonLat]:
    start, middle, end = ((float(lon), float(lat)) for lon, lat in points)  # a line's three control points
    return (start, middle, end)
