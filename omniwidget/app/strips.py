"""A panorama file warped in strips: the one way the command line and the editor's Save image make a large output.

:func:`strips_of_file` chooses where the panorama's pixels come from (left on disk and read a
patch at a time when :func:`omniwidget.io.large.plan_read` says so, else decoded into memory,
or the array the caller already holds), refuses before decoding what would not fit, runs the
method on the map grid (:func:`omniwidget.raster.strips.warp_in_strips`) and hands back the
:class:`~omniwidget.raster.strips.Strips`, whose strips the caller writes
(:func:`omniwidget.io.images.write_image_strips`) with its own progress.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..document.handles import Handles
from ..errors import ImageError
from ..io.images import Fit, check_fits, check_writable, image_header, read_panorama
from ..io.large import DiskPanorama, open_on_disk, plan_read
from ..raster import strips
from ..raster.strips import Strips
from ..raster.warping import Order

__all__ = ["strips_of_file"]


@contextmanager
def strips_of_file(
    path: str | Path,
    handles: Handles,
    *,
    width: int | None = None,
    order: Order = "bilinear",
    fit: Fit | None = None,
    image: NDArray | None = None,
    output: str | Path | None = None,
) -> Iterator[Strips]:
    """The warp of the panorama file ``path`` by ``handles``, made in strips as they are taken.

    Parameters
    ----------
    path : path-like
        The panorama.
    handles : Handles
    width : int, optional
        Output width (even); default: the panorama's.
    order : {"nearest", "bilinear", "bicubic"}
    fit : {"pad", "stretch"}, optional
        Make a panorama that is not 2:1 so first (:func:`omniwidget.io.images.read_panorama`);
        not for one left on disk.
    image : ndarray, optional
        The panorama already decoded (the editor's): used instead of reading it again,
        unless it is to be left on disk.
    output : path-like, optional
        Where the strips will be written: checked (its format holds the panorama's depth
        and channels) before the method runs.

    Yields
    ------
    Strips
        Its panorama on disk is closed (a temporary decoding removed) when the block ends.

    Raises
    ------
    ImageError
        A panorama whose warp would not fit even so (refused before it is decoded), one left
        on disk that is not 2:1, or an output that cannot hold it.
    """
    path = Path(path)
    header = image_header(path)
    disk: DiskPanorama | None = None
    if header is not None and plan_read(header, width, strips=True).how == "disk":
        if header.width != 2 * header.height:
            raise ImageError(f"{path}: a {header.width} x {header.height} image is not 2:1, and one this large ({header.describe()}) cannot be made 2:1 (--fit) in memory")
        check_fits(path, warp=True, width=width, streamed=True)
        disk = open_on_disk(path, header)
    try:
        source = disk if disk is not None else image if image is not None else read_panorama(path, fit, width=width, warp=True, streamed=True)
        if output is not None:
            check_writable(output, np.empty((0, *source.shape[1:]), source.dtype))
        map_image = read_panorama(path, width=strips.MAP_WIDTH) if disk is not None else None  # counted by check_fits
        yield strips.warp_in_strips(source, handles, width=width, order=order, warn=False, map_image=map_image)
    finally:
        if disk is not None:
            disk.close()
