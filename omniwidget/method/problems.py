"""What a solve or a warp found wrong with a handles document, as data: a :class:`Problem` per conflict.

The method (:func:`~omniwidget.method.deformation.deform`) and the per-pixel engine
(:func:`~omniwidget.raster.pipeline.warp`) report conflicts between handles (the paper's
Fig. 15) as records, so that every layer above reads which handles are in conflict and what
kind of conflict it is from the record, never from the message's words. The message is what
a person reads (``Result.warnings``, the command line's stderr, the editor's status).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

__all__ = ["KINDS", "Kind", "Problem"]


class Kind:
    """The kinds of problem, each a short phrase (the editor's group title, ``BlendWarning.kind``)."""

    #: A rectified line over or close to a pole: kept as it is (the still background), or twisting the panorama.
    POLE_LINE: Final = "lines over a pole"
    #: A handle moving what a cage that holds its inside still holds.
    CAGE: Final = "handles moving a still cage's inside"
    #: Two lines whose output images cross each other.
    CROSSING: Final = "lines crossing in the output"
    #: Constraints of several handles on one mesh vertex, their weights averaged.
    SAME_POINT: Final = "constraints on the same point"
    #: Handles whose maps give way where the blend folded (their lines not straight there).
    GIVE_WAY: Final = "handles giving way"
    #: Where the blend folded over: untangled, or still shown turned over.
    FOLD: Final = "fold-overs"


#: Every kind a :class:`Problem` may have, in the order the method and the warp find them.
KINDS: Final = (Kind.POLE_LINE, Kind.CAGE, Kind.CROSSING, Kind.SAME_POINT, Kind.GIVE_WAY, Kind.FOLD)


@dataclass(frozen=True)
class Problem:
    """One conflict between handles, found while solving or warping.

    Attributes
    ----------
    kind : str
        One of :data:`KINDS` (the attributes of :class:`Kind`).
    handles : tuple of int
        Indices into the document's ``handles`` that the problem is about, each once, in
        the order the message names them; empty when it names none (the still background
        alone, say).
    message : str
        The problem in words, naming those handles as ``handles[i] (kind)``.
    """

    kind: str
    handles: tuple[int, ...]
    message: str

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"Problem.kind must be one of {', '.join(map(repr, KINDS))}; got {self.kind!r}")
        if not isinstance(self.handles, tuple) or any(isinstance(h, bool) or not isinstance(h, int) or h < 0 for h in self.handles):
            raise ValueError(f"Problem.handles must be a tuple of handle indices (ints >= 0); got {self.handles!r}")
        if len(set(self.handles)) != len(self.handles):
            raise ValueError(f"Problem.handles names a handle twice: {self.handles!r}")
        if not isinstance(self.message, str) or not self.message:
            raise ValueError(f"Problem.message must be a non-empty str; got {self.message!r}")
