"""Exceptions that carry a message fit to show a person as it is."""

from __future__ import annotations

__all__ = ["OmniwidgetError", "HandlesError", "ImageError", "LevelError", "NotRegularFileError", "VideoError"]


class OmniwidgetError(ValueError):
    """Base of the toolkit's errors: bad input, named by what and where."""


class HandlesError(OmniwidgetError):
    """A handles document is malformed; ``where`` names the handle and field, e.g. ``handles[2].target``."""

    def __init__(self, where: str, problem: str) -> None:
        self.where = where
        self.problem = problem
        super().__init__(f"{where}: {problem}" if where else problem)


class ImageError(OmniwidgetError):
    """An image cannot be read, written or used as an equirectangular panorama."""


class VideoError(ImageError):
    """A video cannot be read, warped or written: not a video, no video stream, frames not 2:1, a broken stream."""


class LevelError(OmniwidgetError):
    """A panorama cannot be levelled: too few vertical edges, or edges that disagree on where up is."""


class NotRegularFileError(OmniwidgetError):
    """An input names a FIFO, a device, a socket or a folder where a regular file must be read.

    Reading a FIFO waits for a writer that may never come; a device may never end. ``path``
    is the file, ``kind`` what it is instead (``"a FIFO (named pipe)"``, say).
    """

    def __init__(self, path: str, what: str, kind: str) -> None:
        self.path = path
        self.kind = kind
        super().__init__(f"{path}: cannot read the {what}: it is {kind}, not a regular file")

