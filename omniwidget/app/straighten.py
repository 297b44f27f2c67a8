"""One click, a straight photo: level the panorama, find its structure, rectify it, and hand back what was done.

:func:`straighten` chains what a person would otherwise assemble by hand:

1. **Level** (:func:`omniwidget.detect.level`): the true vertical from the vertical edges,
   kept in the document as ``options.up`` (the method then works on the levelled input;
   the still background stays on). A panorama with too few vertical edges is not
   levelled, and the result says so.
2. **The structure** (:func:`omniwidget.detect.structure.choose_structure`): among every
   straight edge found, the room's or the street's own edges (verticals, the edges where
   walls meet floor and ceiling, long building edges) before texture (tiles, cobbles,
   mullions), no two crossing, none running close beside another; each drop with its
   reason.
3. **Rectify** them all with the default mode (:func:`omniwidget.warp`). Lines the method
   cannot straighten (over a pole, or crossing another once both are straightened) are
   left out before; a line that still gives way in the warp (:attr:`Result.gave_way`) is
   left out and the rest warped again, once.

The answer carries the result and the handles document it used, so that the person can
open it in the editor and change it (:class:`Straightened`).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .._blas import one_blas_thread
from ..detect.level import level as find_level
from ..detect.lines import DETECT_WIDTH, Suggestion, suggest_lines, suggestions_to_handles
from ..detect.structure import Reason, choose_structure
from ..document.handles import Handles, Options
from ..errors import LevelError
from ..evaluate.quality import dense_line
from ..io.draw import display_rgb, draw_polyline
from ..method.constraints import build_constraints
from ..method.deformation import crossing_handles, levelled_handles
from ..raster import pipeline
from ..sphere import coords

if TYPE_CHECKING:
    from ..detect.level import Level
    from ..raster.pipeline import Result

__all__ = ["KIND_RGB", "MAX_LINES", "Structure", "Straightened", "find_structure", "straighten"]

#: Most lines :func:`straighten` rectifies (the best of the consistent set).
MAX_LINES = 40
#: The kinds of :class:`~omniwidget.detect.structure.Reason` this module gives, besides those of the structure's choice.
OVER_A_POLE = "over a pole"
CROSSING_IN_OUTPUT = "crossing in the output"
GAVE_WAY = "gave way in the warp"
#: The colours :meth:`Straightened.pictures` draws the lines of each kind in (RGB): verticals cyan, horizontals amber, others magenta.
KIND_RGB: dict[str, tuple[int, int, int]] = {"vertical": (40, 220, 255), "horizontal": (255, 190, 30), "other": (235, 60, 200)}


@dataclass(frozen=True)
class Structure:
    """What :func:`find_structure` found in a panorama: the handles to rectify, and what was left out.

    Attributes
    ----------
    handles : Handles
        One rectified line handle per used suggestion (ids ``"suggested-1"``, ...), the
        default mode, and ``options.up`` when the panorama was levelled.
    level : Level or None
        The levelling found, or None when the panorama could not be levelled (``notes`` says why).
    used : tuple of Suggestion
        The lines rectified, in the order of the handles, each with its kind.
    dropped : tuple of (Suggestion, Reason)
        Every other line found, with the reason it was left out (its words, and its kind).
    notes : tuple of str
        What else a person should know (not levelled, and why).
    """

    handles: Handles
    level: Level | None
    used: tuple[Suggestion, ...]
    dropped: tuple[tuple[Suggestion, Reason], ...]
    notes: tuple[str, ...] = ()

    def summary(self) -> str:
        """One line: the levelling, the lines used by kind, the lines left out by reason."""
        if self.level is not None:
            head = f"levelled by pitch {self.level.pitch:+.2f}°, roll {self.level.roll:+.2f}° from {len(self.level.edges)} vertical edges"
        else:
            head = "not levelled"
        kinds = Counter(s.kind for s in self.used)
        by_kind = ", ".join(f"{kinds[k]} {k}" for k in ("vertical", "horizontal", "other") if kinds[k])
        used = f"{len(self.used)} line{'s' * (len(self.used) != 1)} straightened" + (f" ({by_kind})" if by_kind else "")
        if not self.dropped:
            return f"{head}; {used}"
        reasons = Counter(why.kind for _, why in self.dropped)
        left = ", ".join(f"{n} {why}" for why, n in reasons.most_common())
        return f"{head}; {used}; {len(self.dropped)} left out ({left})"


@dataclass(frozen=True)
class Straightened:
    """The answer of :func:`straighten`: the warp, and the structure it rectified.

    Attributes
    ----------
    result : Result
        The warp of the panorama by :attr:`structure`'s handles (its image, map and quality).
    structure : Structure
        The handles used (to open in the editor), the levelling, the lines used and left out.
    """

    result: Result
    structure: Structure

    @property
    def image(self) -> NDArray[Any]:
        """The straightened panorama (``result.image``)."""
        return self.result.image

    @property
    def handles(self) -> Handles:
        """The handles document used: load it in the editor to change it."""
        return self.structure.handles

    def summary(self) -> str:
        """One line: what was levelled and straightened, what left out, and the result's quality headline."""
        return f"{self.structure.summary()}; {self.result.quality.line()}"

    def pictures(self, image: NDArray[Any], thickness: int = 2) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
        """Before and after, with the lines used drawn in the colour of their kind (:data:`KIND_RGB`).

        Parameters
        ----------
        image : ndarray
            The panorama :func:`straighten` was given.
        thickness : int
            Of the lines, pixels.

        Returns
        -------
        before, after : ndarray of uint8, shapes (H, W, 3) and (h, w, 3)
            The input with the lines where they were found, and the result with each line where
            its pixels landed (found densely through the map that placed them).
        """
        before, after = display_rgb(image).copy(), display_rgb(self.image).copy()
        placed = self.result.placed_map()
        lines, controls = self.result.constraints.lines, self.result.controls
        for used in self.structure.used:
            draw_polyline(before, coords.geodesic(used.start, used.end, np.linspace(0.0, 1.0, 96)), KIND_RGB[used.kind], thickness)
        for chain in self.result.constraints.chains:
            handle = controls[lines[chain[0]][0]].handle
            curve = dense_line(placed, [(lines[k][1][0], lines[k][1][-1], controls[lines[k][0]].moebius) for k in chain])
            curve = curve[np.isfinite(curve).all(axis=1)]
            if len(curve) > 1:
                draw_polyline(after, curve, KIND_RGB[self.structure.used[handle].kind], thickness)
        return before, after


@one_blas_thread
def find_structure(image: NDArray[Any], *, max_lines: int | None = MAX_LINES, level: bool = True) -> Structure:
    """Level a panorama and choose the structural lines to rectify (steps 1 and 2 of :func:`straighten`).

    Parameters
    ----------
    image : ndarray, shape (H, 2H) or (H, 2H, C)
        Equirectangular panorama (as :func:`omniwidget.suggest_lines` takes it); one wider
        than :data:`~omniwidget.detect.lines.DETECT_WIDTH` is analysed reduced to it.
    max_lines : int or None
        Most lines used (the best of the consistent set); None: all of them.
    level : bool
        Level the panorama first (``options.up``); False leaves it as it is.

    Returns
    -------
    Structure

    Raises
    ------
    ImageError
        If ``image`` is not a usable panorama.
    """
    if max_lines is not None and (isinstance(max_lines, bool) or not isinstance(max_lines, int | np.integer) or max_lines < 1):
        raise ValueError(f"max_lines must be a positive integer or None, got {max_lines!r}")
    every = suggest_lines(image, max_lines=None, structure=False)  # once: the levelling and the choice look among the same lines
    found: Level | None = None
    notes: list[str] = []
    if level:
        try:
            found = find_level(image, suggestions=every)
        except LevelError as exc:
            notes.append(f"not levelled: {exc}")
    width = min(int(image.shape[1]), DETECT_WIDTH)  # the width the lines were found at
    choice = choose_structure(every, None if found is None else found.up, width=width, max_lines=max_lines, image=image)
    options = Options() if found is None else Options(up=found.up)
    return _uncrossed(Structure(suggestions_to_handles(choice.kept, options), found, tuple(choice.kept), tuple(choice.dropped), tuple(notes)))


def _uncrossed(found: Structure, rounds: int = 3) -> Structure:
    """The structure without the lines the method could not straighten: over a pole, or crossing a better one once straightened.

    A line passing near a pole is kept as it is by the method (an arc over a pole cannot be
    straight in the panorama): it is left out. Lines that do not cross in the input may
    cross once each is straightened (Sec. 3.4 moves their ends): the method would fold
    between them, so the later of each pair goes. The solve is made again without them,
    at most ``rounds`` times.
    """
    for _ in range(rounds):
        constraints = build_constraints(levelled_handles(found.handles), upright=found.handles.options.up is not None)
        reasons = {
            h: Reason(f"passes {90 - abs(lat):.0f}° from the {'north' if lat > 0 else 'south'} pole: it cannot be straight", OVER_A_POLE)
            for h, lat in constraints.near_pole
        }
        for a, b in crossing_handles(constraints):  # best first: a line crossing one already left out stays
            if a not in reasons and b not in reasons:
                reasons[b] = Reason(f"crosses straightened line {a + 1} in the output", CROSSING_IN_OUTPUT)
        if not reasons:
            break
        found = _without(found, reasons)
    return found


def _without(found: Structure, reasons: dict[int, Reason]) -> Structure:
    """The structure with the used lines of the given indices left out, each with its reason."""
    used = tuple(s for i, s in enumerate(found.used) if i not in reasons)
    dropped = found.dropped + tuple((found.used[i], why) for i, why in sorted(reasons.items()))
    return replace(found, handles=suggestions_to_handles(used, found.handles.options), used=used, dropped=dropped)


def straighten(
    image: NDArray[Any],
    *,
    max_lines: int | None = MAX_LINES,
    level: bool = True,
    width: int | None = None,
    structure: Structure | None = None,
) -> Straightened:
    """Level a panorama, find its structural lines, rectify them all, and hand back what was done.

    Parameters
    ----------
    image : ndarray, shape (H, 2H) or (H, 2H, C)
        Equirectangular panorama, as :func:`omniwidget.warp` takes it.
    max_lines : int or None
        Most lines rectified (the best of the consistent set); None: all of them.
    level : bool
        Level the panorama first (the default); False leaves its vertical as it is.
    width : int, optional
        Output width (even); the input's by default.
    structure : Structure, optional
        What :func:`find_structure` found already (on this image or a smaller copy of it),
        to warp without looking again.

    Returns
    -------
    Straightened
        The result, and the handles it used with the lines used and left out. A line that
        gives way in the warp (:attr:`Result.gave_way`: where the blend folded beyond
        untangling) is left out and the rest warped again, once; the one-to-one warp of the
        default mode never folds.

    Raises
    ------
    ImageError
        If ``image`` is not a usable panorama.

    Examples
    --------
    >>> import omniwidget as ow
    >>> done = ow.straighten(ow.sample_image())
    >>> done.image.shape
    (512, 1024, 3)
    >>> done.handles.options.up is not None  # levelled: the document says where up was
    True
    """
    found = structure if structure is not None else find_structure(image, max_lines=max_lines, level=level)
    result = pipeline.warp(image, found.handles, width=width, warn=False)
    if result.gave_way:  # where the blend folded beyond untangling: those lines are not straight there
        found = _without(found, dict.fromkeys(result.gave_way, Reason("gave way in the warp, where the blend folded beyond untangling", GAVE_WAY)))
        result = pipeline.warp(image, found.handles, width=width, warn=False, previous=result)
    return Straightened(result, found)

