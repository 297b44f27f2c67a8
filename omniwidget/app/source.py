"""What an editing session warps: a panorama (an array or a file, a large JPEG opened reduced) or a frame of a video."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .. import detect
from .._checks import whole_number
from .._lazy import lazy
from ..errors import ImageError
from ..io import large
from ..io import video as io_video
from ..io.draw import display_rgb
from ..io.images import check_panorama, image_header, read_image

if TYPE_CHECKING:
    import cv2

    from ..io.video import VideoReader
else:
    cv2 = lazy("cv2")

__all__ = ["DISPLAY_WIDTH", "LAZY_WIDTH", "PREVIEW_WIDTH", "Source", "jpeg"]

#: Width of the result computed after every edit (about 1024 x 512).
PREVIEW_WIDTH = 1024
#: Largest width of the panorama sent to the browser; larger panoramas are sent downscaled.
DISPLAY_WIDTH = 2048
#: A JPEG panorama wider than this is opened reduced (decoded at 1/2 to 1/8 by libjpeg, at
#: least as wide as the display, the preview's source and the detector need): its full size
#: is read only when a full-size result is asked for (Save image, ``full=True``).
LAZY_WIDTH = 8192


def jpeg(rgb: NDArray[np.uint8], quality: int = 90) -> bytes:
    """``rgb`` (uint8, height x width x 3) as JPEG bytes, for the browser."""
    ok, data = cv2.imencode(".jpg", rgb[:, :, ::-1], [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:  # pragma: no cover - OpenCV encodes any uint8 RGB image
        raise ImageError("could not encode the image for display")
    return data.tobytes()


def _open(path: Path, preview_width: int) -> tuple[NDArray, int]:
    """The panorama at ``path`` and its reduction: one wider than :data:`LAZY_WIDTH` decoded reduced to what the editor shows."""
    header = image_header(path)
    if header is not None and max(header.width, header.height) > LAZY_WIDTH:
        needed = max(DISPLAY_WIDTH, 2 * preview_width, detect.DETECT_WIDTH)
        reduced = large.plan_read(header, needed).reduce  # a JPEG by libjpeg; another format above STREAM_BYTES in strips
        if reduced > 1:
            return read_image(path, width=needed), reduced
    return read_image(path), 1


def frame_index(video: VideoReader, frame: Any, seconds: Any) -> int:
    """The frame chosen by its index (``frame``) or by its time (``seconds`` from the video's start); 0 by default."""
    count = len(video)
    if frame is not None and seconds is not None:
        raise TypeError("give frame (an index) or time (seconds), not both")
    if seconds is not None:
        if isinstance(seconds, bool) or not isinstance(seconds, (int, float, np.integer, np.floating)) or not np.isfinite(seconds):
            raise TypeError(f"time must be a number of seconds, got {seconds!r}")
        if not 0 <= seconds < count * video.frame_interval:
            raise ValueError(f"time {seconds} s: the video is {count * video.frame_interval:.3f} s long ({count} frames)")
        return min(count - 1, int(np.floor(float(seconds) / video.frame_interval + 1e-6)))
    if frame is None:
        return 0
    if isinstance(frame, bool) or not isinstance(frame, (int, np.integer)):
        raise TypeError(f"frame must be a frame index (an int; time= takes seconds), got {frame!r}")
    if not 0 <= frame < count:
        raise IndexError(f"frame {frame}: the video has {count} frames (0 to {count - 1})")
    return int(frame)


class Source:
    """The panorama a session warps, and its downscaled copies (display, preview, detector), each made once.

    Parameters
    ----------
    image : array or path-like
        A panorama, a panorama file, or a video file (:func:`~omniwidget.io.video.is_video_path`).
    preview_width : int
        Width of the preview (even); the preview is warped from a copy twice as wide.
    frame, time : int, float, optional
        For a video, the frame to show, by index or by seconds from the start.
    """

    def __init__(self, image: NDArray | str | os.PathLike[str], preview_width: int, frame: int | None = None, time: float | None = None) -> None:
        preview_width = whole_number(preview_width, "preview_width", minimum=2, even=True)
        self.video: VideoReader | None = None
        self.frame = 0
        self.reduced = 1  # the working copy is 1 / reduced of the panorama's size (_open)
        self.path: Path | None = None
        if isinstance(image, (str, os.PathLike)):
            self.path = Path(image)
            image = self._read_file(self.path, preview_width, frame, time)
        if self.video is None and (frame is not None or time is not None):
            raise TypeError("frame and time choose a frame of a video; the editor was given an image")
        self.working = check_panorama(image)  # the panorama, or a JPEG's reduced decoding (self.reduced)
        self.working.flags.writeable = False
        self.full_image: NDArray | None = self.working if self.reduced == 1 else None
        self._scaled: dict[int, NDArray] = {}
        self.width = self.working.shape[1] * self.reduced
        self.preview_width = min(preview_width, self.width)
        self.preview_source = self.downscaled(2 * self.preview_width)

    def _read_file(self, path: Path, preview_width: int, frame: int | None, time: float | None) -> NDArray:
        if io_video.is_video_path(path):
            self.video = io_video.VideoReader(path)
            self.frame = frame_index(self.video, frame, time)
            return self.video.read(self.frame)
        image, self.reduced = _open(path, preview_width)
        return image

    @property
    def image(self) -> NDArray:
        """The panorama at full size (read-only); a panorama opened reduced is read whole at the first ask."""
        if self.full_image is None:
            if self.path is None:  # pragma: no cover - only files are opened reduced
                raise ImageError("the panorama's full size is not known")
            image = check_panorama(read_image(self.path), str(self.path))
            if image.shape[1] != self.width:
                raise ImageError(f"{self.path}: the file changed while it was edited ({image.shape[1]} wide, opened {self.width})")
            image.flags.writeable = False
            self.full_image = image
        return self.full_image

    def downscaled(self, width: int) -> NDArray:
        """The panorama at most ``width`` wide, made once per width (display and preview share 2048)."""
        width = min(width, self.width)
        if width not in self._scaled:
            source = self.working if self.working.shape[1] >= width else self.image
            small = source if width == source.shape[1] else cv2.resize(source, (width, width // 2), interpolation=cv2.INTER_AREA)
            self._scaled[width] = small
        return self._scaled[width]

    def display_source(self) -> bytes:
        """The panorama as the browser shows it: a JPEG at most :data:`DISPLAY_WIDTH` wide."""
        return jpeg(display_rgb(self.downscaled(DISPLAY_WIDTH)))

    def frame_of(self, frame: Any, time: Any) -> int:
        """The index of a frame of the video chosen by index or by time (see :meth:`EditingSession.set_frame`)."""
        if self.video is None:
            raise TypeError("the editor shows an image, not a video: it has no frames to choose from")
        if frame is None and time is None:
            raise TypeError("give frame (an index) or time (seconds)")
        return frame_index(self.video, frame, time)

    def read_frame(self, index: int) -> NDArray:
        """Frame ``index`` of the video, checked and read-only."""
        if self.video is None:
            raise TypeError("the editor shows an image, not a video: it has no frames to choose from")
        image = check_panorama(self.video.read(index))
        image.flags.writeable = False
        return image

    def show_frame(self, index: int, image: NDArray) -> None:
        """Make ``image`` (frame ``index``, :meth:`read_frame`) the panorama warped, its copies made anew."""
        self.working = self.full_image = image
        self._scaled = {}
        self.preview_source = self.downscaled(2 * self.preview_width)
        self.frame = index

    def key(self, handles: dict) -> str:
        """The cache key of a result: the handles and, for a video, the frame they are warped on."""
        key = json.dumps(handles, sort_keys=True)
        return key if self.video is None else f"{key}#frame={self.frame}"
