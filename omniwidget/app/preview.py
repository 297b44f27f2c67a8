"""The preview of an editing session: the newest edit's result computed in a worker, shown, and its quality measured.

Every edit (or frame, or drag) is a new generation; a result is shown only if no newer
generation was asked for meanwhile, so that a drag never shows a stale frame. What is shown
is a :class:`Rendered` result (the JPEG, the folds' overlay, the handles' outputs) and its
:class:`ResultStatus` (the status line's fields).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .._lazy import lazy
from ..document.handles import Handles, PointHandle
from ..io.draw import display_rgb
from ..method import reach
from ..method.kinds import output_points
from ..method.problems import Kind
from ..raster import pipeline
from ._latest import Latest
from .source import DISPLAY_WIDTH, Source, jpeg
from .status import Board, Status, exception_text

if TYPE_CHECKING:
    import cv2

    from ..raster.pipeline import Result
else:
    cv2 = lazy("cv2")

__all__ = ["QUALITY_DELAY", "PreviewJob", "Rendered", "ResultStatus", "render"]

#: Seconds a result stays on screen before its quality figures are measured (a drag may go on).
QUALITY_DELAY = 0.3


def _display_rgb8(image: NDArray, width: int) -> NDArray[np.uint8]:
    """An RGB uint8 copy of ``image`` at most ``width`` wide, for the browser."""
    if image.shape[1] > width:
        image = cv2.resize(image, (width, width // 2), interpolation=cv2.INTER_AREA)
    return display_rgb(image)


def _fold_overlay(mask: NDArray[np.bool_]) -> bytes:
    """A PNG, transparent but where the output folds over (magenta), or b"" when it does not."""
    if not mask.any():
        return b""
    rgba = np.zeros(mask.shape + (4,), np.uint8)
    rgba[mask] = (255, 0, 255, 150)  # BGRA: magenta
    ok, data = cv2.imencode(".png", rgba)
    return data.tobytes() if ok else b""


def _reaches(handles: Any) -> list[float | None]:
    """Per handle, a point's reach in degrees (its ``reach``, or the default the method takes), None for the others.

    The editor draws it as the ring round a selected point (:mod:`omniwidget.method.reach`).
    """
    return [
        (h.reach if h.reach is not None else reach.default_reach(handles, i)) if isinstance(h, PointHandle) else None
        for i, h in enumerate(handles.handles)
    ]


def _kept_lines(result: Any) -> list[int]:
    """Rectified lines over or close to a pole that the still background keeps as they are (identity map)."""
    if result.handles.options.anchor is None:
        return []  # the paper's method rectifies them all the same (and warns: a conflict)
    return sorted(int(i) for i, _ in result.constraints.near_pole)


def _conflicts(result: Any, kept: list[int]) -> list[int]:
    """The handles the result's problems name (a kept line's problem says why it is kept: no conflict)."""
    still = set(kept)
    return sorted({h for p in result.problems if not (p.kind == Kind.POLE_LINE and set(p.handles) <= still) for h in p.handles})


@dataclass(frozen=True)
class Rendered:
    """A result as the browser shows it: the JPEG, the folds' overlay (PNG, or b"") and the handles' outputs ``[lon, lat]``."""

    preview: bytes
    folds: bytes
    outputs: list[list[list[float]]]


def render(result: Result, doc: Handles) -> Rendered:
    """``result`` (of ``doc``) for the browser; FloatingPointError when its outputs or pixels are not finite numbers."""
    outputs = output_points(doc, result.constraints)
    if not all(np.isfinite(points).all() for points in outputs if points):
        raise FloatingPointError("the handles' outputs are not finite numbers")
    if result.image.dtype.kind == "f" and not np.isfinite(result.image).all():  # the input is finite (check_panorama)
        raise FloatingPointError("the result has pixels that are not finite numbers")
    return Rendered(jpeg(_display_rgb8(result.image, DISPLAY_WIDTH)), _fold_overlay(result.folds.mask), outputs)


@dataclass(frozen=True)
class ResultStatus:
    """The status line's fields of a result shown: its size and time, its warnings grouped, the handles in conflict."""

    width: int
    height: int
    seconds: float
    generation: int
    warnings: tuple[str, ...]
    warning_kinds: tuple[str, ...]
    conflicts: tuple[int, ...]
    kept: tuple[int, ...]
    reaches: tuple[float | None, ...]
    fold_area: float

    @classmethod
    def of(cls, result: Result, seconds: float, generation: int) -> ResultStatus:
        """The fields of ``result``, computed in ``seconds`` for edit ``generation``."""
        kept = _kept_lines(result)
        return cls(
            width=int(result.image.shape[1]),
            height=int(result.image.shape[0]),
            seconds=seconds,
            generation=generation,
            warnings=tuple(result.warnings),
            warning_kinds=tuple(p.kind for p in result.problems),
            conflicts=tuple(_conflicts(result, kept)),
            kept=tuple(kept),
            reaches=tuple(_reaches(result.handles)),
            fold_area=float(result.folds.area),
        )

    def to_message(self, status: Status) -> Status:
        """``status`` with this result's fields: the status the front end is sent (its quality line to come)."""
        said = f"{self.width} x {self.height} in {self.seconds:.2f} s"
        return {
            **status,
            "state": "idle",
            "error": status.get("error", ""),
            "message": said,
            "result": said,
            "warnings": list(self.warnings),
            "warning_kinds": list(self.warning_kinds),
            "conflicts": list(self.conflicts),
            "kept": list(self.kept),
            "reaches": list(self.reaches),
            "fold_area": self.fold_area,
            "seconds": self.seconds,
            "width": self.width,
            "generation": self.generation,
            "quality": "",
        }


class PreviewJob:
    """The newest edit's result, computed in a worker and shown on ``board``; the full-size result kept for the next ask.

    Parameters
    ----------
    source : Source
        The panorama warped (the preview from its downscaled copy, the full result from it whole).
    board : Board
        Where results, errors and the quality line are shown.
    measure : bool
        Measure the quality figures of each result shown, in a worker of their own.
    """

    def __init__(self, source: Source, board: Board, measure: bool = True) -> None:
        self.source = source
        self.board = board
        self.measure = bool(measure)
        self.generation = 0
        self.result: Result | None = None  # the Result on screen
        self._full: tuple[str, Result] | None = None
        self.worker = Latest("omniwidget-editor")
        self.quality = Latest("omniwidget-editor-quality")

    def schedule(self, job: Callable[[int], None], notice: str = "") -> None:
        """A new generation: the status says it is computing (with the autosave's ``notice``), ``job(generation)`` runs in the worker."""
        with self.board.lock:
            self.generation += 1
            generation = self.generation
            self.board.set_status(state="busy", message="computing...", error="", notice=notice, newest=generation)
        self.worker.submit(lambda: job(generation))

    def forget_full(self) -> None:
        """The panorama changed (another frame): the full-size result kept is of the one before."""
        self._full = None

    def full(self, doc: Handles, key: str, warn: bool) -> Result:
        """The full-size result of ``doc`` (whose cache key is ``key``), kept for the next ask."""
        cached = self._full
        if cached is not None and cached[0] == key:
            return cached[1]
        result = pipeline.warp(self.source.image, doc, warn=warn, previous=self.result)  # the preview's weights, when they are these
        self._full = (key, result)
        return result

    def _warp(self, doc: Handles, key: str, full: bool) -> Result:
        source = self.source
        if full or source.preview_width == source.width:
            return self.full(doc, key, warn=False)
        # the last preview's weights start the solver: a drag changes them little
        return pipeline.warp(source.preview_source, doc, width=source.preview_width, warn=False, previous=self.result)

    def compute(self, doc: Handles, key: str, generation: int, full: bool) -> Result | None:
        """Compute and show the result of ``doc``; return it (None when it failed, which is shown)."""
        start = time.perf_counter()
        try:
            result = self._warp(doc, key, full)
            rendered = render(result, doc)
        except Exception as exc:  # noqa: BLE001 - shown in the widget; the handles and the last good image stay
            self._failed(exc, generation)
            return None
        said = ResultStatus.of(result, time.perf_counter() - start, generation)
        with self.board.lock:
            if generation != self.generation:
                return result  # a newer edit is on its way: this result is stale
            self.result = result
            board = self.board
            board.publish({"preview": rendered.preview, "folds": rendered.folds, "outputs": rendered.outputs, "status": said.to_message(board.status)})
        if self.measure and result.weights is not None:
            self.quality.submit(lambda: self._measure_quality(result, generation))
        return result

    def _failed(self, exc: BaseException, generation: int) -> None:
        with self.board.lock:
            if generation == self.generation:
                self.board.last_error = exc
                message = f"could not compute the result ({exception_text(exc)}); the handles are kept and the last good result stays"
                self.board.set_status(state="error", message=message, error=message)

    def _measure_quality(self, result: Result, generation: int) -> None:
        """The quality figures of a result on screen, in a line of the status (measured after it is shown)."""
        time.sleep(QUALITY_DELAY)  # a drag goes on: let the next edit's computation have the cores
        if generation != self.generation:
            return
        try:
            line = result.quality.line()
        except Exception as exc:  # noqa: BLE001 - a figure that cannot be measured is said, not raised
            line = f"could not measure the quality ({exception_text(exc)})"
        with self.board.lock:
            if generation == self.generation:
                self.board.set_status(quality=line)
