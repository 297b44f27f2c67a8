"""Exceptions that carry a message fit to show a person as it is."""

from __future__ import annotations

__all__ = ["OmniwidgetError", "HandlesError", "ImageError", "LevelError", "VideoError"]


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
