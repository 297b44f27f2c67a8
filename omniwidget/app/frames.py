"""Many frames, one map: the frames of a 360° video from a still camera, warped alike.

The map (for each output pixel, the input ``[lon, lat]`` it shows: ``Result.inverse_map()``,
or a map saved by ``omniwidget warp --map`` and read by :func:`~omniwidget.io.frames.load_map`)
is turned into source pixel coordinates once (:func:`map_coordinates`); each frame is then
only read, resampled (:func:`~omniwidget.raster.warping.remap_panorama`) and written.
:func:`warp_frames` does that on a few threads: OpenCV's decoders, encoders and ``remap``
release the GIL, so reading one frame, resampling another and writing a third overlap.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._files import refuse_overwrites, remove_leftovers
from ..errors import ImageError, OmniwidgetError
from ..io.frames import checked_map
from ..io.images import Fit, read_panorama, write_image
from ..io.metadata import output_metadata, read_metadata
from ..raster.warping import ORDERS, PAD, Order, remap_panorama
from ..sphere import coords

__all__ = ["FrameReport", "FrameSettings", "map_coordinates", "warp_frames"]


def map_coordinates(inverse_map: ArrayLike, src_width: int) -> NDArray[np.float32]:
    """Source pixel coordinates of an inverse map, ready for :func:`~omniwidget.raster.warping.remap_panorama`.

    Parameters
    ----------
    inverse_map : array_like, shape (H, 2H, 2)
        For each output pixel centre, the input ``[lon, lat]`` in degrees it shows.
    src_width : int
        Width of the frames the map is applied to (any even width: the map is in degrees).

    Returns
    -------
    ndarray of float32, shape (H, 2H, 2)
        ``(x, y)`` in the source padded by :data:`~omniwidget.raster.warping.PAD`
        (:func:`~omniwidget.raster.warping.pad_panorama`).

    Raises
    ------
    ImageError
        If the map has the wrong shape or holds non-finite or out-of-range values.
    """
    m = checked_map(inverse_map)
    px = coords.lonlat_to_px(np.asarray(m, np.float64).reshape(-1, 2), src_width).reshape(m.shape)
    px[..., 0] = np.mod(px[..., 0] + 0.5, src_width) - 0.5  # longitudes wrap; the padding covers the rest
    return (px + PAD).astype(np.float32)


@dataclass(frozen=True)
class FrameReport:
    """What :func:`warp_frames` did.

    Attributes
    ----------
    written : tuple of Path
        Outputs written, in the order of the inputs.
    failed : tuple of (Path, str)
        Inputs that could not be warped, and why; their outputs were not written.
    seconds : float
        Wall time of the whole run (reading, resampling, writing).
    """

    written: tuple[Path, ...]
    failed: tuple[tuple[Path, str], ...]
    seconds: float

    @property
    def fps(self) -> float:
        """Frames written per second of wall time."""
        return len(self.written) / self.seconds if self.seconds > 0 else float("inf")


@dataclass(frozen=True)
class FrameSettings:
    """How each frame of :func:`warp_frames` is read, resampled and written.

    Attributes
    ----------
    order : {"nearest", "bilinear", "bicubic"}
    fit : {"pad", "stretch"}, optional
        Make each frame 2:1 first (:func:`~omniwidget.io.images.to_equirectangular`); by
        default a frame that is not 2:1 fails.
    gpano : bool
        Write the Photo Sphere XMP into frames whose input has none (each frame's own
        metadata is always carried: :func:`omniwidget.io.metadata.output_metadata`).
    levelled : bool
        The map levels the frames: their GPano pitch and roll are written 0.

    Raises
    ------
    ValueError
        An ``order`` that is not one of :data:`~omniwidget.raster.warping.ORDERS`.
    """

    order: Order = "bilinear"
    fit: Fit | None = None
    gpano: bool = True
    levelled: bool = False

    def __post_init__(self) -> None:
        if self.order not in ORDERS:
            raise ValueError(f"order must be one of {', '.join(ORDERS)}, got {self.order!r}")


def _warp_one(src: Path, dst: Path, coordinates: NDArray[np.float32], src_shape: tuple[int, int], settings: FrameSettings) -> str | None:
    """Read, resample and write one frame; why it failed, or None."""
    try:
        frame = read_panorama(src, settings.fit)
        if frame.shape[:2] != tuple(src_shape):
            raise ImageError(f"{src}: the frame is {frame.shape[1]} x {frame.shape[0]}, the map is for {src_shape[1]} x {src_shape[0]}")
        warped = remap_panorama(frame, coordinates, settings.order)
        meta = output_metadata(read_metadata(src), warped.shape[1], warped.shape[0], gpano=settings.gpano, levelled=settings.levelled)
        write_image(dst, warped, meta)
    except (OmniwidgetError, OSError) as exc:
        return str(exc)
    return None


def warp_frames(
    inputs: Sequence[str | os.PathLike[str]],
    outputs: Sequence[str | os.PathLike[str]],
    coordinates: NDArray[np.float32],
    src_shape: tuple[int, int],
    settings: FrameSettings | None = None,
    *,
    workers: int | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> FrameReport:
    """Warp many frames by one map: read, resample, write, a few frames at a time.

    Parameters
    ----------
    inputs, outputs : sequences of path-like, the same length
        Each input frame and where its warped frame goes (written whole or not at all).
    coordinates : ndarray of float32, shape (h, w, 2)
        From :func:`map_coordinates` for frames of ``src_shape``.
    src_shape : (int, int)
        ``(height, width)`` every frame must have.
    settings : FrameSettings, optional
        The resampling, the fit and the metadata written (:class:`FrameSettings`' defaults by default).
    workers : int, optional
        Threads; default one per CPU plus one (reading and writing wait on the disk).
    progress : callable, optional
        ``progress(done, total)``, called from the calling thread after each frame.

    Returns
    -------
    FrameReport
        A frame that cannot be read, has another size or cannot be written is listed in
        ``failed`` with the reason; the others are still warped.

    Raises
    ------
    ImageError
        Before any work, if an output names an input or another output (the same path, a
        symbolic or a hard link).
    KeyboardInterrupt
        Passed on once the frames being warped are written (the others are not started);
        no temporary file is left.

    Notes
    -----
    What killed runs left beside the outputs (hidden temporary files no live run holds) is
    removed first, each folder listed once.
    """
    if len(inputs) != len(outputs):
        raise ValueError(f"{len(inputs)} inputs but {len(outputs)} outputs")
    settings = settings or FrameSettings()
    workers = (os.cpu_count() or 1) + 1 if workers is None else max(1, int(workers))
    pairs = [(Path(i), Path(o)) for i, o in zip(inputs, outputs, strict=True)]
    refuse_overwrites([("the input", src) for src, _ in pairs], [("the output", dst) for _, dst in pairs])
    remove_leftovers(*(dst for _, dst in pairs))

    def one(pair: tuple[Path, Path]) -> str | None:
        return _warp_one(*pair, coordinates, src_shape, settings)

    written: list[Path] = []
    failed: list[tuple[Path, str]] = []
    start = time.perf_counter()
    pool = ThreadPoolExecutor(workers)
    try:
        for done, ((src, dst), error) in enumerate(zip(pairs, pool.map(one, pairs), strict=True), start=1):
            if error is None:
                written.append(dst)
            else:
                failed.append((src, error))
            if progress is not None:
                progress(done, len(pairs))
    finally:  # interrupted: the frames not started are dropped, not warped while the process waits to end
        pool.shutdown(wait=True, cancel_futures=True)
    return FrameReport(tuple(written), tuple(failed), time.perf_counter() - start)
